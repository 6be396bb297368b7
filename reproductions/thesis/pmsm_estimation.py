"""Thesis ([Thesis]) §4.4.2: EKF vs SMC on one start-up realisation (Figs. 4.1-4.4) and the
estimation quality vs the prior's theta offset (Fig. 4.6).

Scenario (§4.4.1): omega_ref ramps 0 -> 10 rad/s in 0.1 s and holds 0.1 s (1600 steps of
125 us), x^(0) from the prior, PI control on the posterior mean (§4.4.2). SMC: the reduced PMSM
model's optimal proposal + the generic guided filter, 60 particles, threshold 12, deterministic
residual resampling (:mod:`pfbench.plants.pmsm_control.smc`); EKF: Jacobian eq. 4.26.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import pandas as pd

from pfbench.plants.pmsm_control.closed_loop import LoopConfig, run_batch, run_once
from pfbench.plants.pmsm_control.smc import step_time_us
from pfbench.recipes import recipe

DT = 125e-6
FIG44_TIMES = (0.0, 0.009, 0.019, 0.028, 0.038, 0.047, 0.056, 0.066, 0.075)


@lru_cache(maxsize=4)
def _realisation(seed: int, run: int, backend: str, point: str = "mean"):
    smc = run_once(LoopConfig(point=point, backend=backend, store_particles=True), seed, run)
    ekf = run_once(LoopConfig(estimator="ekf", backend=backend), seed, run)
    return smc, ekf


def _wrap(a):
    return np.angle(np.exp(1j * np.asarray(a)))


def _common(ctx):
    run = ctx.option("run", 0, int)
    smc, ekf = _realisation(ctx.seed, run, ctx.backend)
    return run, smc, ekf


@recipe("thesis:fig4.1", title="Currents in the start-up, EKF vs SMC (thesis Fig. 4.1)",
        quick_cost="~10 s", full_cost="~10 s", options={"run": (int, "which realisation (default 0)")})
def fig4_1(ctx):
    import matplotlib.pyplot as plt

    run, smc, ekf = _common(ctx)
    t = np.arange(smc["x"].shape[0]) * DT
    fig, ax = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for a, o, name in zip(ax, (smc, ekf), ("SMC", "EKF")):
        a.plot(t, o["x"][:, 0], label="i_alpha")
        a.plot(t, o["x"][:, 1], label="i_beta")
        a.set(xlabel="Time [s]", title=f"{name} in the loop (PI on the mean)")
        a.legend()
    ax[0].set_ylabel("current [A]")
    fig.tight_layout()
    ctx.write_figure("fig4.1", fig)
    ctx.write_table("fig4.1", pd.DataFrame({
        "t": t, "smc_i_alpha": smc["x"][:, 0], "smc_i_beta": smc["x"][:, 1],
        "ekf_i_alpha": ekf["x"][:, 0], "ekf_i_beta": ekf["x"][:, 1]}))
    peak = lambda o: float(np.abs(o["x"][:, :2]).max())  # noqa: E731
    ctx.compare("peak |current| SMC / EKF", ours=f"{peak(smc):.2f} / {peak(ekf):.2f}", unit="A",
                paper="EKF: relatively small currents; SMC larger")
    k = int(np.argmax(np.abs(smc["x"][:, :2]).max(axis=1)))
    conv = _convergence_time(smc)
    ctx.compare("time of SMC peak current vs SMC convergence time",
                ours=f"{k * DT:.3f} s vs {conv:.3f} s", paper="highest currents just after SMC converges")
    ctx.note(f"Figs. 4.1-4.4 show realisation run={run} (seed {ctx.seed}); any run can be chosen with "
             "--option run=K. The thesis does not give its realisation.")


def _convergence_time(o, tol=0.3):
    """First time after which the theta estimate stays within ``tol`` rad of the truth."""
    err = np.abs(_wrap(o["est"][:, 1] - o["x"][:, 3]))
    bad = np.flatnonzero(err > tol)
    return float(((bad[-1] + 1) if bad.size else 0) * DT)


@recipe("thesis:fig4.2", title="omega and theta, EKF vs SMC with bounds (thesis Fig. 4.2)",
        quick_cost="~10 s", full_cost="~10 s", options={"run": (int, "which realisation (default 0)")})
def fig4_2(ctx):
    import matplotlib.pyplot as plt

    run, smc, ekf = _common(ctx)
    t = np.arange(smc["x"].shape[0]) * DT
    fig, ax = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    for j, (o, name) in enumerate(((smc, "SMC"), (ekf, "EKF"))):
        a = ax[0, j]
        a.plot(t, o["x"][:, 2], "k-", label="true omega")
        a.plot(t, o["est"][:, 0], "r--", label="estimate")
        a.plot(t, o["omega_ref"], color="grey", lw=0.6, label="reference")
        if name == "SMC":
            lo, hi = o["spread"][:, 0], o["spread"][:, 1]
        else:
            lo, hi = o["est"][:, 0] - 2 * o["sd"][:, 0], o["est"][:, 0] + 2 * o["sd"][:, 0]
        a.plot(t, lo, "r:", lw=0.7)
        a.plot(t, hi, "r:", lw=0.7)
        a.set(title=f"{name}: omega [rad/s]" + (" (bounds: particle range)" if name == "SMC" else
                                                 " (bounds: +-2 sd)"))
        a.legend(fontsize=8)
        b = ax[1, j]
        b.plot(t, o["x"][:, 3], "k.", ms=1, label="true theta")
        b.plot(t, o["est"][:, 1], "r.", ms=1, label="estimate")
        half = o["spread"][:, 2] if name == "SMC" else 2 * o["sd"][:, 1]
        b.plot(t, _wrap(o["est"][:, 1] - half), "m,", alpha=0.5)
        b.plot(t, _wrap(o["est"][:, 1] + half), "m,", alpha=0.5)
        b.set(title=f"{name}: theta [rad] (wrapped)", xlabel="Time [s]", ylim=(-3.3, 3.3))
        b.legend(fontsize=8, markerscale=8)
    fig.tight_layout()
    ctx.write_figure("fig4.2", fig)
    ctx.write_table("fig4.2", pd.DataFrame({
        "t": t, "omega": smc["x"][:, 2], "theta": smc["x"][:, 3], "smc_omega": smc["est"][:, 0],
        "smc_theta": smc["est"][:, 1], "smc_omega_min": smc["spread"][:, 0],
        "smc_omega_max": smc["spread"][:, 1], "ekf_run_omega": ekf["x"][:, 2],
        "ekf_run_theta": ekf["x"][:, 3], "ekf_omega": ekf["est"][:, 0], "ekf_theta": ekf["est"][:, 1],
        "ekf_omega_sd": ekf["sd"][:, 0], "ekf_theta_sd": ekf["sd"][:, 1]}))
    k = 400
    for o, name in ((smc, "SMC"), (ekf, "EKF")):
        ctx.compare(f"{name}: final omega (true) / theta error, last 0.05 s",
                    ours=f"{o['x'][-k:, 2].mean():.2f} rad/s / "
                         f"{np.abs(_wrap(o['est'][-k:, 1] - o['x'][-k:, 3])).mean():.2f} rad",
                    paper="SMC converges; EKF theta pi off, turns the wrong way")
        ctx.compare(f"{name}: estimation failed (our definition)", ours=bool(o["failed"]),
                    paper="False" if name == "SMC" else "True")
    ctx.compare("SMC step time, N=60, mean estimate (numba)", ours=step_time_us(point="mean"),
                paper="must fit 125 us", unit="us")


@recipe("thesis:fig4.3", title="SMC posterior of omega and theta over time (thesis Fig. 4.3)",
        quick_cost="~10 s", full_cost="~10 s",
        options={"run": (int, "which realisation (default 0)"),
                 "t_end": (float, "end of the plotted window in s (default 0.1)")})
def fig4_3(ctx):
    import matplotlib.pyplot as plt

    run, smc, _ = _common(ctx)
    M = smc["x"].shape[0]
    t_end = min(M, int(round(ctx.option("t_end", 0.1, float) / DT)))
    t = np.arange(t_end) * DT
    ob = np.linspace(-20, 20, 161)
    tb = np.linspace(-math.pi, math.pi, 121)
    Hw = np.empty((t_end, ob.size - 1))
    Ht = np.empty((t_end, tb.size - 1))
    for k in range(t_end):
        Hw[k] = np.histogram(smc["hist_omega"][k], ob, weights=smc["hist_w"][k])[0]
        Ht[k] = np.histogram(smc["hist_theta"][k], tb, weights=smc["hist_w"][k])[0]
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for a, H, edges, truth, name in ((ax[0], Hw, ob, smc["x"][:t_end, 2], "omega [rad/s]"),
                                     (ax[1], Ht, tb, smc["x"][:t_end, 3], "theta [rad]")):
        a.imshow(np.sqrt(H.T), origin="lower", aspect="auto", cmap="Greys",
                 extent=(0, t[-1], edges[0], edges[-1]))
        a.plot(t, truth, "b,", label="true")
        a.set(xlabel="Time [s]", ylabel=name, title=f"posterior of {name.split()[0]} (sqrt scale)")
    fig.tight_layout()
    ctx.write_figure("fig4.3", fig)
    # bimodality: posterior mass near theta_true + pi, per time
    far = np.array([np.sum(smc["hist_w"][k] * (np.abs(_wrap(smc["hist_theta"][k] - smc["x"][k, 3]))
                                               > math.pi / 2)) for k in range(M)])
    ctx.write_table("fig4.3", pd.DataFrame({"t": np.arange(M) * DT, "mass_far_from_truth": far,
                                            "ess": smc["ess"], "resampled": smc["resampled"]}))
    early = far[int(0.005 / DT):int(0.03 / DT)]
    ctx.compare("posterior mass > pi/2 from true theta, 5-30 ms (mean)", ours=float(early.mean()),
                paper="far from Gaussian, two modes in the first 0.1 s")
    ctx.compare("time at which that mass first stays < 5 %",
                ours=float((np.flatnonzero(far > 0.05)[-1] + 1) * DT) if (far > 0.05).any() else 0.0,
                unit="s", paper="Gaussian after convergence")
    ctx.compare("resampling events in the run", ours=int(smc["resampled"].sum()),
                paper="visible as sharp edges")


@recipe("thesis:fig4.4", title="SMC joint density of (omega, theta) at listed times (thesis Fig. 4.4)",
        quick_cost="~10 s", full_cost="~10 s", options={"run": (int, "which realisation (default 0)")})
def fig4_4(ctx):
    import matplotlib.pyplot as plt

    run, smc, _ = _common(ctx)
    fig, axes = plt.subplots(3, 3, figsize=(11, 9), sharex=True, sharey=True)
    rows = []
    for a, ts in zip(axes.ravel(), FIG44_TIMES):
        k = min(int(round(ts / DT)), smc["x"].shape[0] - 1)
        om, th, w = smc["hist_omega"][k], smc["hist_theta"][k], smc["hist_w"][k]
        a.scatter(om, th, s=300 * w + 2, c=w, cmap="Greys", vmin=0, vmax=max(w.max(), 1e-12),
                  edgecolors="k", linewidths=0.2)
        a.plot(smc["x"][k, 2], smc["x"][k, 3], "b+", ms=12, mew=2)
        a.set(title=f"t={ts:.3f}s", xlim=(-20, 20), ylim=(-math.pi, math.pi))
        # modes: cluster the weighted theta particles into "near truth" / "pi away"
        near = np.abs(_wrap(th - smc["x"][k, 3])) <= math.pi / 2
        rows.append({"t": ts, "mass_near_truth": float(w[near].sum()),
                     "mass_pi_away": float(w[~near].sum()),
                     "omega_mean_near": float(np.sum(w[near] * om[near]) / max(w[near].sum(), 1e-300)),
                     "omega_mean_far": float(np.sum(w[~near] * om[~near]) / max(w[~near].sum(), 1e-300))})
    for a in axes[-1]:
        a.set_xlabel("omega [rad/s]")
    for a in axes[:, 0]:
        a.set_ylabel("theta [rad]")
    fig.tight_layout()
    ctx.write_figure("fig4.4", fig)
    df = pd.DataFrame(rows)
    ctx.write_table("fig4.4", df)
    bimodal = df[(df.mass_near_truth > 0.05) & (df.mass_pi_away > 0.05)]
    ctx.compare("listed times with two modes (each > 5 % mass)",
                ours=", ".join(f"{v:.3f}" for v in bimodal.t) or "none",
                paper="multi-modal in the initial steps, modes cut out by resampling")


@recipe("thesis:fig4.6", title="Estimation quality vs the prior's theta offset, EKF vs SMC (thesis Fig. 4.6)",
        quick_cost="~40 s", full_cost="~2 min",
        options={"runs": (int, "runs per offset and estimator (default 10)"),
                 "points": (int, "theta offsets in [0, pi] (quick 5, full 13)"),
                 "prior_sd": (float, "prior standard deviation of theta (default 1.0)")})
def fig4_6(ctx):
    import matplotlib.pyplot as plt

    n_runs = ctx.option("runs", 10, int)
    n_pts = ctx.option("points", 13 if ctx.full else 5, int)
    sd = ctx.option("prior_sd", 1.0, float)
    offsets = np.linspace(0, math.pi, n_pts)
    rows = []
    for off in ctx.progress(offsets, total=n_pts):
        for est in ("smc", "ekf"):
            cfg = LoopConfig(estimator=est, theta_offset=float(off), theta_prior_sd=sd,
                             backend=ctx.backend)
            r = run_batch(cfg, n_runs, seed=ctx.seed, workers=1 if est == "ekf" else None)
            rows.append({"offset": off, "estimator": est, "theta_err": r["theta_err"].mean(),
                         "omega_err": r["omega_err"].mean(), "failure_rate": r["failed"].mean(),
                         "mean_loss": r["loss"].mean(), "runs": n_runs})
    df = pd.DataFrame(rows)
    ctx.write_table("fig4.6", df)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for est, col in (("smc", "tab:blue"), ("ekf", "tab:red")):
        d = df[df.estimator == est]
        ax[0].plot(d.offset, d.theta_err, "o-", color=col, label=est.upper())
        ax[1].plot(d.offset, 100 * d.failure_rate, "o-", color=col, label=est.upper())
    ax[0].set(xlabel="prior theta offset [rad]", ylabel="mean |theta error|, last 0.05 s [rad]")
    ax[1].set(xlabel="prior theta offset [rad]", ylabel="failures [%]")
    for a in ax:
        a.legend()
    fig.suptitle(f"averages over {n_runs} runs per point, prior sd {sd} rad")
    fig.tight_layout()
    ctx.write_figure("fig4.6", fig)
    s, e = df[df.estimator == "smc"], df[df.estimator == "ekf"]
    ctx.compare("EKF theta error at offset 0 / pi", ours=f"{e.theta_err.iloc[0]:.2f} / {e.theta_err.iloc[-1]:.2f}",
                unit="rad", paper="good near 0, fails for large offsets")
    ctx.compare("SMC theta error at offset 0 / pi", ours=f"{s.theta_err.iloc[0]:.2f} / {s.theta_err.iloc[-1]:.2f}",
                unit="rad", paper="no significant dependence")
    ctx.note(f"Fig. 4.6: the thesis does not state the prior used for this figure. Both filters get a "
             f"Gaussian theta prior N(theta_0 + offset, {sd}^2) (wrapped; SMC particles drawn from it); "
             "'quality' is the mean |theta error| over the final 0.05 s; PI on the posterior mean.")
