"""Thesis ([Thesis]) chapter 2 figures: SIS degeneracy (Fig. 2.2), SIR (Fig. 2.3), ASIR vs
bootstrap with an outlier (Fig. 2.4 + MSE table), on the example of §2.7.1
(:mod:`pfbench.models.thesis_example`; the observation equation was lost in the extraction,
we use y_t = x_t + v_t).

Estimates, variances, N_eff, MSE and the particle clouds of Figs. 2.2-2.3 (every particle and
weight, ``store_particles=True``) come from :func:`pfbench.run_filter`.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

import pfbench
from pfbench import resampling
from pfbench.models import get
from pfbench.recipes import recipe


def _history(res):
    """Particles (M, n), normalised weights (M, n) and resampling flags (M,) of a one-filter run."""
    return res.extras["particles"][0, :, :, 0], res.extras["weights"][0], res.extras["resampled"][0]


def _cloud_figure(title, tr, X, W, R):
    import matplotlib.pyplot as plt

    M, n = X.shape
    t = np.arange(1, M + 1)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    tt = np.repeat(t, n)
    wmax = W.max(axis=1, keepdims=True)
    ax[0].scatter(tt, X.ravel(), c=(W / wmax).ravel(), cmap="Greys", s=10, vmin=0, vmax=1)
    ax[0].plot(t, tr.x[:, 0], "b-", lw=1, label="true state")
    ax[0].set(xlabel="time step", ylabel="x", title=f"{title}: weighted particles (dark = heavy)")
    ax[0].legend()
    ax[1].plot(tt, X.ravel(), "k.", ms=2)
    ax[1].plot(t, tr.x[:, 0], "b-", lw=1)
    for k in np.flatnonzero(R):
        ax[1].axvline(k + 1, color="tab:blue", lw=0.6, alpha=0.6)
    ax[1].set(xlabel="time step", title="all particles" + (" (blue: resampling)" if R.any() else ""))
    fig.tight_layout()
    return fig


@recipe("thesis:fig2.2", title="SIS degeneracy, 50 particles, horizon 50 (thesis Fig. 2.2)",
        quick_cost="~5 s", full_cost="~5 s",
        options={"particles": (int, "particles (default 50)"), "steps": (int, "time steps (default 50)")})
def fig2_2(ctx):
    n, M = ctx.option("particles", 50, int), ctx.option("steps", 50, int)
    model = get("thesis_example")
    tr = model.simulate(M, seed=ctx.seed)
    res = pfbench.run_filter(model, tr.y, method="sis", n_particles=n, backend=ctx.backend,
                             seed=ctx.seed + 1, common_random_numbers=True, store_particles=True)
    X, W, R = _history(res)
    ctx.write_figure("fig2.2", _cloud_figure("SIS", tr, X, W, R))
    ctx.write_table("fig2.2", pd.DataFrame({"t": np.arange(1, M + 1), "x_true": tr.x[:, 0],
                                            "estimate": res.estimates[:, 0], "ess": res.ess}))
    small = float(np.mean(W[-1] < 1e-3))
    ctx.compare("N_eff at the last step (SIS, run_filter)", ours=float(res.ess[-1]),
                paper="majority of weights tend to zero", unit="particles")
    ctx.compare("share of weights < 1e-3 at the last step", ours=small, paper="majority")
    ctx.compare("N_eff first step -> last step", ours=f"{res.ess[0]:.1f} -> {res.ess[-1]:.2f}",
                paper="decreases (Prop. 1)")


@recipe("thesis:fig2.3", title="SIR, multinomial resampling, N_thres = 25 (thesis Fig. 2.3)",
        quick_cost="~5 s", full_cost="~5 s",
        options={"particles": (int, "particles (default 50)"), "steps": (int, "time steps (default 50)"),
                 "threshold": (float, "resample when N_eff < this many particles (default 25)")})
def fig2_3(ctx):
    n, M = ctx.option("particles", 50, int), ctx.option("steps", 50, int)
    thr = ctx.option("threshold", 25.0, float)
    model = get("thesis_example")
    tr = model.simulate(M, seed=ctx.seed)
    res = pfbench.run_filter(model, tr.y, method="sir", n_particles=n, resampling="multinomial",
                             ess_threshold=thr / n, backend=ctx.backend, seed=ctx.seed + 1,
                             common_random_numbers=True, store_particles=True)
    X, W, R = _history(res)
    sis = pfbench.run_filter(model, tr.y, method="sis", n_particles=n, backend=ctx.backend,
                             seed=ctx.seed + 1, common_random_numbers=True)
    ctx.write_figure("fig2.3", _cloud_figure("SIR", tr, X, W, R))
    ctx.write_table("fig2.3", pd.DataFrame({"t": np.arange(1, M + 1), "x_true": tr.x[:, 0],
                                            "estimate": res.estimates[:, 0], "ess": res.ess}))
    mse = lambda r: float(np.mean((r.estimates[:, 0] - tr.x[:, 0]) ** 2))  # noqa: E731
    ctx.compare("resampling events (run_filter SIR)", ours=res.n_resampled, paper="when N_eff < 25")
    ctx.compare("min N_eff SIR vs SIS", ours=f"{res.ess.min():.1f} vs {sis.ess.min():.2f}",
                paper="SIR overcomes degeneracy")
    ctx.compare("MSE SIR / MSE SIS", ours=mse(res) / mse(sis), paper="< 1 (qualitative)")


def _mse_runs(n_runs, n, M, backend, seed, progress):
    sim = get("thesis_example", outlier_step=5)
    filt = sim.without_outlier()
    rows = []
    for r in progress(range(n_runs), total=n_runs):
        tr = sim.simulate(M, seed=[seed, r])
        row = {"run": r}
        for meth in ("bootstrap", "asir"):
            fr = pfbench.run_filter(filt, tr.y, method=meth, n_particles=n, resampling="multinomial",
                                    backend=backend, seed=np.random.SeedSequence([seed, r, 1]),
                                    common_random_numbers=True)
            row[f"mse_{meth}"] = float(np.mean((fr.estimates[:, 0] - tr.x[:, 0]) ** 2))
        rows.append(row)
    return pd.DataFrame(rows)


@recipe("thesis:fig2.4", title="ASIR vs bootstrap with an outlier w_5 = 0.5 (thesis Fig. 2.4 + MSE)",
        quick_cost="~20 s", full_cost="~40 s",
        options={"particles": (int, "particles (default 50)"), "steps": (int, "time steps (default 20)"),
                 "runs": (int, "Monte Carlo runs of the MSE table (quick 300, full 1000)")})
def fig2_4(ctx):
    import matplotlib.pyplot as plt

    n, M = ctx.option("particles", 50, int), ctx.option("steps", 20, int)
    n_runs = ctx.option("runs", 1000 if ctx.full else 300, int)
    df = _mse_runs(n_runs, n, M, ctx.backend, ctx.seed, ctx.progress)
    ctx.write_table("fig2.4_mse", df)
    mb, ma = df.mse_bootstrap.mean(), df.mse_asir.mean()
    red = 1.0 - ma / mb
    summary = pd.DataFrame({"filter": ["bootstrap", "ASIR"], "mean MSE": [mb, ma],
                            "median MSE": [df.mse_bootstrap.median(), df.mse_asir.median()],
                            "runs": [n_runs, n_runs]})
    ctx.write_table("fig2.4_table", summary)
    # two realisations: the first run (typical) and the run where bootstrap is worst vs ASIR
    sim = get("thesis_example", outlier_step=5)
    filt = sim.without_outlier()
    extreme = int(df.assign(ratio=df.mse_bootstrap / df.mse_asir).ratio.idxmax())
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, r, label in zip(axes, (0, extreme), ("typical (run 0)", f"extreme (run {extreme})")):
        tr = sim.simulate(M, seed=[ctx.seed, r])
        t = np.arange(1, M + 1)
        ax.plot(t, tr.x[:, 0], "k-", lw=1.5, label="true")
        for meth, col in (("bootstrap", "tab:red"), ("asir", "tab:blue")):
            fr = pfbench.run_filter(filt, tr.y, method=meth, n_particles=n, resampling="multinomial",
                                    backend=ctx.backend, seed=np.random.SeedSequence([ctx.seed, r, 1]),
                                    common_random_numbers=True)
            sd = np.sqrt(fr.variances[:, 0])
            ax.plot(t, fr.estimates[:, 0], "--", color=col, label=meth)
            ax.plot(t, fr.estimates[:, 0] - 3 * sd, ":", color=col, lw=0.8)
            ax.plot(t, fr.estimates[:, 0] + 3 * sd, ":", color=col, lw=0.8)
        ax.axvline(6, color="grey", lw=0.5)
        ax.set(xlabel="time step", ylabel="x", title=label)
        ax.legend()
    fig.tight_layout()
    ctx.write_figure("fig2.4", fig)
    ctx.compare("MSE reduction ASIR vs bootstrap (mean over runs)", ours=100 * red, paper=35.0,
                unit="%", note=f"{n_runs} runs, N={n}, multinomial")
    ctx.compare("MSE reduction (median over runs)",
                ours=100 * (1 - df.mse_asir.median() / df.mse_bootstrap.median()), unit="%")
    ctx.compare("runs where ASIR beats bootstrap", ours=100 * float((df.mse_asir < df.mse_bootstrap).mean()),
                unit="%")
    ctx.note("Fig. 2.4: the observation equation of eq. 2.25 was lost in the extraction; we use "
             "y_t = x_t + v_t. The particle count of the thesis is not given; we use N = 50 (the "
             "chapter's other figures). Dotted bounds are estimate +- 3 posterior sd (run_filter does "
             "not return particle ranges). The outlier w_5 = 0.5 enters x^(6); the filters' model has "
             "no outlier.")
