"""[Embedded] §5.2, §5.3, §6 and Appendix A: PF estimation in the heating/cooling chamber.

Without ``--data`` every experiment runs on the simulated chamber (:mod:`pfbench.plants.chamber`, a plant
that is *not* the filter's model); with ``--data log.csv`` the same estimators run on the given log
(every experiment of the recipe uses that one log; no truth, so only eq. 13 errors).

Estimators (bootstrap PF, systematic resampling, [Embedded] Alg. 1):
  y_hat_m1: ``thermal_inertial`` (eq. 10, jump system, mode from the log), var_v / var_n per test
            (figs 6-10: sigma_v^2 = 0.010, sigma_n^2 = 0.005 -- the Table A2 setting of B-1/B2-1/B3-1);
  y_hat_m2: ``thermal_rate`` (eq. 12), sigma_v1^2 = 1e-6, sigma_v2^2 = 0, sigma_n^2 = 0.0225.
Errors: eps(k) = y(k) - y_hat(k) (eq. 13, against the quantised measurement, as the paper) and,
in simulation only, e_true(k) = T_true(k) - y_hat(k) against the true (unquantised) sensor temperature.
Metrics are averaged over several PF seeds (quick 3, full 20) on one plant run per experiment.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pandas as pd

from pfbench.plants import chamber
from pfbench.ranges import COUNT
from pfbench.plants.datalog import read_log
from pfbench.filters import run_filter
from pfbench.models import get as get_model
from pfbench.models.thermal import _mode_inputs
from pfbench.recipes import recipe
from pfbench import plotting
from pfbench.verdicts import (CONSTRUCTION, Reading, direction, holds, in_band, no_dependence,
                              not_reproducible)

VAR_V, VAR_N = 0.010, 0.005          # Table A2 setting (figs 6-10)
FIG_RUNS = {  # fig: (paper test, N_p, ambient degC); ambient from §5.2 (fig 6: ~19.3, figs 7-8: ~19.6)
    "fig6": ("B-1", 1000, 19.3),
    "fig7": ("B2-1", 500, 19.6),
    "fig8": ("B3-1", 100, 19.6),
}
# Table A1 (N_p = 1000): (sigma_v^2, sigma_n^2) rows x 22.0 / 22.5 / 23.0 degC (A / B / C)
TABLE_A1 = [((0.010, 0.005), "1"), ((0.005, 0.005), "2"), ((0.001, 0.010), "3"), ((0.001, 0.001), "4"),
            ((1.000, 0.100), "5"), ((0.100, 1.000), "6")]
TEMPS = {"A": 22.0, "B": 22.5, "C": 23.0}
# Table A2 (sigma_v^2 = 0.010, sigma_n^2 = 0.005): N_p -> test-name suffix
TABLE_A2 = {100: "3-1", 500: "2-1", 1000: "-1"}


#: the --option keys every chamber recipe reads (all of them also take --data log.csv)
OPTIONS = {"pf_seeds": (int, "PF seeds averaged per experiment (quick 3, full 20)", COUNT)}


def _n_seeds(ctx) -> int:
    return ctx.option("pf_seeds", 20 if ctx.full else 3, int)


def _ambient_for(test: str) -> float:
    """Room temperature of each simulated experiment: the B-1 / B2-1 / B3-1 runs use §5.2's values."""
    return {"B-1": 19.3, "B2-1": 19.6, "B3-1": 19.6}.get(test, 19.5)


def _plant_seed(ctx, test: str) -> int:
    return (int(ctx.seed) * 7919 + sum(ord(c) * 31 ** i for i, c in enumerate(test))) % (2 ** 31)


@lru_cache(maxsize=64)
def _sim_heating_cooling(set_temp: float, ambient: float, seed: int):
    return chamber.heating_cooling(set_temp, ambient=ambient, seed=seed, tail_s=60)


def _experiment(ctx, kind: str, test: str, set_temp: float = 22.5) -> dict:
    """Columns of one experiment: the user's log (ctx.data) or a fresh simulation."""
    if ctx.data:
        cols = read_log(ctx.data, required=("time_s", "y", "u1", "u2"))
        cols = dict(cols)
        cols.setdefault("t_out", np.full_like(cols["y"], np.nan))
        cols["truth"] = np.full_like(cols["y"], np.nan)
        return cols
    if kind == "heating_normal":
        run = chamber.heating_normal(seed=_plant_seed(ctx, test))
    else:
        run = _sim_heating_cooling(float(set_temp), _ambient_for(test), _plant_seed(ctx, test))
    cols = run.columns()
    cols["truth"] = run.truth
    cols["air"] = run.air
    cols["info"] = run.info
    return cols


def _estimate(ctx, cols, n_p: int, seed: int, var_v: float = VAR_V, var_n: float = VAR_N,
              which=("m1", "m2")) -> dict:
    """Run the bootstrap PF with model (10) and/or (12) on one log; returns y_hat per model."""
    y = np.ascontiguousarray(cols["y"], dtype=np.float64).reshape(-1, 1)
    out = {}
    if "m1" in which:
        m1 = get_model("thermal_inertial", y0=float(y[0, 0]), var_v1=var_v, var_n=var_n)
        r = run_filter(m1, y, _mode_inputs(cols), method="bootstrap", n_particles=n_p,
                       backend=ctx.backend, seed=seed)
        out["m1"] = r.estimates[:, 0]
    if "m2" in which:
        m2 = get_model("thermal_rate", y0=float(y[0, 0]))
        r = run_filter(m2, y, None, method="bootstrap", n_particles=n_p, backend=ctx.backend, seed=seed)
        out["m2"] = r.estimates[:, 0]
    return out


def _errors(cols, yhat) -> dict:
    eps = cols["y"] - yhat
    d = {"rms_eps": float(np.sqrt(np.mean(eps ** 2))), "max_eps": float(np.max(np.abs(eps)))}
    tr = cols["truth"]
    if np.all(np.isfinite(tr)):
        e = tr - yhat
        d.update(rms_true=float(np.sqrt(np.mean(e ** 2))), max_true=float(np.max(np.abs(e))))
    else:
        d.update(rms_true=np.nan, max_true=np.nan)
    return d


def _metrics(ctx, cols, n_p, var_v=VAR_V, var_n=VAR_N, which=("m1", "m2")) -> tuple[dict, dict, dict]:
    """(metrics averaged over PF seeds, estimates of the first seed, per-seed metrics) per model."""
    acc: dict = {m: [] for m in which}
    first = None
    for s in range(_n_seeds(ctx)):
        est = _estimate(ctx, cols, n_p, seed=int(ctx.seed) * 1000 + s, var_v=var_v, var_n=var_n, which=which)
        first = first or est
        for m in which:
            acc[m].append(_errors(cols, est[m]))
    mean = {m: {k: float(np.mean([a[k] for a in acc[m]])) for k in acc[m][0]} for m in which}
    return mean, first, acc


def _per_seed(acc: dict, m: str, key: str) -> np.ndarray:
    return np.array([a[key] for a in acc[m]], dtype=float)


def _series(cols, est) -> pd.DataFrame:
    return pd.DataFrame({"time_s": cols["time_s"], "y": cols["y"], "u1": cols["u1"], "u2": cols["u2"],
                         "t_out": cols["t_out"], "mode": _mode_inputs(cols)[:, 2],
                         "y_hat_m1": est["m1"], "y_hat_m2": est["m2"], "truth": cols["truth"]})


def _figure(df: pd.DataFrame, title: str):
    """Paper layout: temperatures (measured red, y_hat_m1 blue, y_hat_m2 black, outdoor gray) over
    inputs u1, u2; an inset zooms on the first mode switch (the paper's rectangles). The paper's
    figures are plots of its own measured runs: there is no published curve to draw beside ours."""
    fig, (ax, axu) = plotting.subplots(2, 1, figsize=(8, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    t = df["time_s"].to_numpy()
    ax.step(t, df["y"], where="post", color="red", lw=1.0, label="measured y (simulated DS18B20)")
    ax.plot(t, df["y_hat_m1"], color="blue", lw=1.0, label=r"$\hat y_{m1}$ (eq. 10)")
    ax.plot(t, df["y_hat_m2"], color="black", lw=1.0, label=r"$\hat y_{m2}$ (eq. 12)")
    if np.any(np.isfinite(df["t_out"])):
        ax.step(t, df["t_out"], where="post", color="gray", lw=1.0, label="outdoor")
    plotting.label(ax, "time [s]", "temperature [°C]", title)
    ax.legend(loc="upper left")
    mode = df["mode"].to_numpy()
    sw = np.flatnonzero(np.diff(mode) != 0)
    if sw.size:
        k = int(sw[0])
        lo, hi = max(0, k - 40), min(len(t) - 1, k + 80)
        ins = ax.inset_axes([0.68, 0.5, 0.3, 0.42])
        sl = slice(lo, hi + 1)
        ins.step(t[sl], df["y"].to_numpy()[sl], where="post", color="red", lw=0.8)
        ins.plot(t[sl], df["y_hat_m1"].to_numpy()[sl], color="blue", lw=0.8)
        ins.plot(t[sl], df["y_hat_m2"].to_numpy()[sl], color="black", lw=0.8)
        ins.tick_params(labelsize=6)
        ins.set_title("zoom: first mode switch (time [s], °C)", fontsize=6)
        ax.indicate_inset_zoom(ins, edgecolor="0.4")
    axu.plot(t, df["u1"], color="tab:orange", label="u1 heater")
    axu.plot(t, df["u2"], color="tab:green", label="u2 fan")
    axu.set_ylim(-5, 105)
    plotting.label(axu, "time [s]", "input [% PWM]")
    axu.legend(loc="center right")
    return fig


def _heating_time(cols) -> float | None:
    info = cols.get("info") or {}
    k = info.get("k_switch")
    return None if k is None else float(cols["time_s"][k])


#: the mixing-bump sentence of [Embedded] §5.2, scored once (in fig6; fig7/fig8 show their bump as a comparison)
BUMP_CLAIM = ("When u2 jumps to 100 % and u1 to 0 %, the air mixing causes a sudden increase of the air "
              "temperature around the thermometer")
#: half a DS18B20 step: the rounding error the quantised measurement itself carries (±0.031 °C)
HALF_STEP = chamber.RESOLUTION / 2


def _heating_cooling_fig(ctx, fig: str) -> None:
    test, n_p, ambient = FIG_RUNS[fig]
    cols = _experiment(ctx, "heating_cooling", test, 22.5)
    mean, est, acc = _metrics(ctx, cols, n_p)
    df = _series(cols, est)
    ctx.write_table(fig, df)
    src = f"log {ctx.data.name}" if ctx.data else f"simulated chamber, room {ambient} °C"
    ctx.write_figure(fig, _figure(df, f"Heating/cooling to 22.5 °C, N_p = {n_p} ({test}; {src})"))
    ctx.write_table(f"{fig}_errors", pd.DataFrame([{"model": m, "n_particles": n_p, **v} for m, v in mean.items()]))
    for m, v in mean.items():
        ctx.compare(f"{test} N_p={n_p}: RMS eps {m} (eq. 13, vs measurement)", ours=v["rms_eps"], unit="°C",
                    paper="not tabulated (figures only)")
        if np.isfinite(v["rms_true"]):
            ctx.compare(f"{test} N_p={n_p}: RMS error {m} vs true sensor temperature", ours=v["rms_true"], unit="°C")
    ctx.extra["per_seed"] = acc
    # the Fig. 9 sentence ("reduced errors for the y_m2 chart") is scored once, in fig9, with its readings
    ht = _heating_time(cols)
    if ht is not None:
        ctx.compare(f"{test}: heating time to 22.5 °C (room {ambient} °C)", ours=ht, unit="s",
                    paper="Fig. 6 (room ~19.3) heats longer than Figs. 7-8 (room ~19.6)")
        ctx.extra["heating_time_s"] = ht
        run = _sim_heating_cooling(22.5, _ambient_for(test), _plant_seed(ctx, test))
        bump = chamber.mixing_bump(run)
        ctx.extra["mixing_bump"] = bump
        ctx.compare(f"{test}: rise after the fan jumps to 100 % (mixing bump), air / sensor / measured",
                    ours=f"{bump['air']:.4f} / {bump['sensor']:.4f} / {bump['measured']:.4f}", unit="°C",
                    paper="sudden increase around the thermometer at the start of cooling (§5.2)")
        if fig == "fig6":
            ctx.claim(BUMP_CLAIM, "[Embedded] §5.2", "rise of y after the switch (60 s)",
                      not_reproducible("a property of the authors' chamber airflow, which the paper does not describe; "
                                       f"our plant's bump at the sensor ({bump['sensor']:.3f} °C) is below the "
                                       f"{chamber.RESOLUTION} °C sensor step (see pfbench.plants.chamber)"),
                      paper="a visible rise")
    elif ctx.data and fig == "fig6":
        ctx.claim(BUMP_CLAIM, "[Embedded] §5.2", "rise of y after the switch",
                  not_reproducible("a user log carries no switch marker this recipe can trust"))
    ctx.extra["metrics"] = mean


@recipe("embedded:fig6", aliases=("fig6",), title="Heating/cooling, N_p = 1000 (Fig. 6, test B-1)",
        quick_cost="~20 s", full_cost="~1 min", options=OPTIONS, reads_data=True)
def fig6(ctx):
    _heating_cooling_fig(ctx, "fig6")
    claim = ("The system warmed up to the set temperature longer in Fig. 6 than in Figs. 7-8 (ambient ~19.3 vs "
             "~19.6 °C)")
    if ctx.data:
        ctx.claim(claim, "[Embedded] §5.2, Figs. 6-8", "heating time to 22.5 °C",
                  not_reproducible("needs the Fig. 7 run beside the user's log"))
    else:
        t6 = ctx.extra["heating_time_s"]
        t7 = _heating_time(_experiment(ctx, "heating_cooling", FIG_RUNS["fig7"][0], 22.5))
        ctx.extra["heating_time_fig7_s"] = t7
        ctx.compare("heating time to 22.5 °C: fig6 (room 19.3 °C) / fig7 (room 19.6 °C)", ours=f"{t6:.0f} / {t7:.0f}",
                    unit="s", paper="fig6 longer")
        ctx.claim(claim, "[Embedded] §5.2, Figs. 6-8", "heating time to 22.5 °C: fig6 (room 19.3) vs fig7 (room 19.6)",
                  holds(t6 > t7, f"simulated plant: {t6:.0f} s at 19.3 °C vs {t7:.0f} s at 19.6 °C; the first "
                                 "longer"), paper="fig6 longer",
                  kind=CONSTRUCTION,
                  note=(f"fixed by the simulated plant ({t6:.0f} s at 19.3 °C vs {t7:.0f} s at 19.6 °C): starting "
                        "0.3 °C colder, any plant with the same heating dynamics needs longer to reach 22.5 °C; the "
                        "paper's explanation (a larger time constant at the lower room temperature) concerns its "
                        "chamber, which we do not have"))


@recipe("embedded:fig7", aliases=("fig7",), title="Heating/cooling, N_p = 500 (Fig. 7, test B2-1)",
        quick_cost="~20 s", full_cost="~1 min", options=OPTIONS, reads_data=True)
def fig7(ctx):
    _heating_cooling_fig(ctx, "fig7")


@recipe("embedded:fig8", aliases=("fig8",), title="Heating/cooling, N_p = 100 (Fig. 8, test B3-1)",
        quick_cost="~20 s", full_cost="~1 min", options=OPTIONS, reads_data=True)
def fig8(ctx):
    _heating_cooling_fig(ctx, "fig8")


#: the Fig. 9 sentence of [Embedded] §5.2, scored once (here)
FIG9_CLAIM = ("One can confirm the conclusions drawn regarding the reduced errors for the y_m2 chart "
              "(see Figure 9)")
FIG9_PRIMARY = ("the literal reading: the y_m2 chart (model (12)) shows the reduced errors, i.e. (12) has the "
                "lower eq. 13 error than model (10), mean over the B-1, B2-1 and B3-1 runs. The paragraph before "
                "says (10) 'primarily follows the measured signal' while (12) 'increases slowly', and 'the "
                "conclusions drawn' may be its other sentence ('For Equation (12), the estimation also works "
                "correctly when the number of particles is reduced'): that reading is a sensitivity row")
#: "works correctly when the number of particles is reduced": its eq. 13 error within this fraction of
#: the error at N_p = 1000 (our reading; the half sensor step used before was 68 % of the error itself)
FIG9_SAME = 0.10


@recipe("embedded:fig9", aliases=("fig9",), title="Estimation errors eps(k) of B1, B2-1, B3-1 (Fig. 9)",
        quick_cost="~30 s", full_cost="~2 min", options=OPTIONS, reads_data=True)
def fig9(ctx):
    fig, axes = plotting.subplots(3, 1, figsize=(8, 7.5), sharex=False)
    frames, rows, accs, logs = [], [], {}, {}
    for ax, (name, (test, n_p, _amb)) in zip(axes, FIG_RUNS.items()):
        cols = _experiment(ctx, "heating_cooling", test, 22.5)
        mean, est, acc = _metrics(ctx, cols, n_p)
        accs[test], logs[test] = acc, cols
        t = cols["time_s"]
        e1, e2 = cols["y"] - est["m1"], cols["y"] - est["m2"]
        frames.append(pd.DataFrame({"test": test, "n_particles": n_p, "time_s": t, "eps_m1": e1, "eps_m2": e2}))
        for m in ("m1", "m2"):
            rows.append({"test": test, "n_particles": n_p, "model": m, **mean[m]})
        ax.plot(t, e1, color="red", lw=0.8, label="model (10)")
        ax.plot(t, e2, color="blue", lw=0.8, label="model (12)")
        ax.axhspan(-HALF_STEP, HALF_STEP, color="0.85", zorder=0, label="± half a sensor step (0.031 °C)")
        plotting.label(ax, "time [s]", r"$\epsilon(k) = y - \hat y$ [°C]", f"{test} (N_p = {n_p}), first PF seed")
        ax.legend(loc="lower left", ncol=3, fontsize=7)
    fig.suptitle("Fig. 9: eq. 13 errors of models (10) and (12) on our runs (the paper's own runs are not published)")
    ctx.write_table("fig9", pd.concat(frames, ignore_index=True))
    err = pd.DataFrame(rows)
    ctx.write_figure("fig9", fig)
    for test, g in err.groupby("test", sort=False):
        r1 = float(g.loc[g.model == "m1", "rms_eps"].iloc[0])
        r2 = float(g.loc[g.model == "m2", "rms_eps"].iloc[0])
        ctx.compare(f"{test}: RMS eps m1 / m2", ours=f"{r1:.4f} / {r2:.4f}", unit="°C",
                    paper="not tabulated (Fig. 9 plots eps)")
    # primary reading: model (12) on ONE log (B-1) at N_p = 1000 and at N_p = 100, paired by PF seed
    b1 = logs["B-1"]
    small = {"rms_eps": [], "rms_true": []}
    for s in range(_n_seeds(ctx)):
        e = _estimate(ctx, b1, 100, seed=int(ctx.seed) * 1000 + s, which=("m2",))["m2"]
        d = _errors(b1, e)
        for k in small:
            small[k].append(d[k])
    m2_1000 = _per_seed(accs["B-1"], "m2", "rms_eps")
    m2_100 = np.asarray(small["rms_eps"])
    rows.append({"test": "B-1 log at N_p = 100", "n_particles": 100, "model": "m2",
                 "rms_eps": float(m2_100.mean()), "rms_true": float(np.mean(small["rms_true"]))})
    ctx.write_table("fig9_errors", pd.DataFrame(rows))
    ctx.compare("model (12) on the B-1 log: RMS eps at N_p = 1000 / 100", ours=f"{m2_1000.mean():.4f} / "
                f"{m2_100.mean():.4f}", unit="°C", paper="works correctly when N_p is reduced (§5.2)")
    margin = FIG9_SAME * float(m2_1000.mean())
    pooled = {k: np.mean([_per_seed(accs[t], "m1", k) - _per_seed(accs[t], "m2", k) for t in accs], axis=0)
              for k in ("rms_eps", "rms_true")}
    primary = direction(pooled["rms_eps"], +1, what="RMS eps m1 - m2")
    others = [
        Reading(f"model (12) keeps its eq. 13 error when N_p is reduced (1000 -> 100), same log: within "
                f"{FIG9_SAME:.0%} of its error at N_p = 1000", "RMS eps of (12), N_p = 100 - N_p = 1000, per PF seed",
                no_dependence(m2_100 - m2_1000, margin, what="RMS eps of (12), N_p = 100 - N_p = 1000 (same log)")),
        Reading("as the row above across the paper's experiments: (12) in B3-1 (N_p = 100) vs B-1 (N_p = 1000), "
                "two different runs", "RMS eps of (12), B3-1 - B-1, per PF seed",
                no_dependence(_per_seed(accs["B3-1"], "m2", "rms_eps") - m2_1000, margin,
                              what="RMS eps of (12), B3-1 - B-1")),
    ]
    if np.all(np.isfinite(pooled["rms_true"])):
        others.append(Reading("model (12) has the lower error against the true (unquantised) sensor temperature "
                              "(simulation only)", "RMS error vs truth m1 - m2, mean over the three runs, per PF seed",
                              direction(pooled["rms_true"], +1, what="RMS true error m1 - m2")))
    floor = chamber.RESOLUTION / np.sqrt(12.0)  # RMS of the quantisation error of a smooth estimate
    r1 = float(np.mean([_per_seed(accs[t], "m1", "rms_eps").mean() for t in accs]))
    ctx.claim(FIG9_CLAIM, "[Embedded] §5.2, Fig. 9",
              "RMS eq. 13 error of model (10) minus that of model (12), mean over B-1/B2-1/B3-1, per PF seed [°C]",
              primary, paper="> 0 (the y_m2 chart has the reduced errors)", reading=FIG9_PRIMARY, others=others,
              kind=CONSTRUCTION,
              note=f"by construction: with Table A2's sigma_v^2 = 0.010 on both states, model (10)'s estimate nearly "
                   f"copies the measurement (its RMS eq. 13 error {r1:.4f} °C), while model (12) (sigma_v1^2 = 1e-6) "
                   f"smooths it, and against the sensor's {chamber.RESOLUTION} °C staircase a smooth estimate's error "
                   f"cannot fall below a step / sqrt(12) = {floor:.4f} °C: the paper's settings, not the filter, decide "
                   f"which error is the smaller. The N_p-reduction rows' equivalence margin is ±{margin:.4g} °C, "
                   f"{FIG9_SAME:.0%} of (12)'s error at N_p = 1000 (our reading of 'works correctly')")
    ctx.extra["errors"] = rows
    ctx.note("Fig. 9: with the Table A2 setting (sigma_v^2 = 0.010 on both states of eq. 10) model (10) is nearly a "
             "copy of the measurement, so its eq. 13 error is the smaller one, while model (12) (sigma_v1^2 = 1e-6) is "
             "smooth and lags when the mode switches; this is what the paper's text says of the two models. The Fig. 9 "
             "sentence's literal reading ((12) has the lower error) is therefore decided by those settings (a claim "
             "by construction, not a finding); the paper's preceding conclusion (model (12) keeps working with fewer "
             "particles) is a sensitivity row beneath it.")


@recipe("embedded:fig10", aliases=("fig10",), title="Heating/normal two-position control, N_p = 1000 (Fig. 10)",
        quick_cost="~20 s", full_cost="~1 min", options=OPTIONS, reads_data=True)
def fig10(ctx):
    cols = _experiment(ctx, "heating_normal", "HN", 21.5)
    mean, est, acc = _metrics(ctx, cols, 1000)
    df = _series(cols, est)
    ctx.write_table("fig10", df)
    src = f"log {ctx.data.name}" if ctx.data else "simulated chamber"
    ctx.write_figure("fig10", _figure(df, f"Heating/normal, 21.5 ± 0.26 °C, u1 90/10 %, N_p = 1000 ({src})"))
    n_sw = int(np.sum(np.diff(df["mode"].to_numpy()) != 0))
    ctx.compare("mode switches in the run (PF parameter set switched each time)", ours=n_sw,
                paper="switching more often than in heating/cooling (§5.3)")
    for m, v in mean.items():
        ctx.compare(f"heating/normal: RMS eps {m}", ours=v["rms_eps"], unit="°C",
                    paper="accurate tracking of the measurement (§5.3)")
        if np.isfinite(v["rms_true"]):
            ctx.compare(f"heating/normal: RMS error {m} vs true temperature", ours=v["rms_true"], unit="°C")
    ctx.write_table("fig10_errors", pd.DataFrame([{"model": m, **v} for m, v in mean.items()]))
    ctx.claim("Switching between models takes place more often than in the heating/cooling test (one switch)",
              "[Embedded] §5.3, Fig. 10", "mode switches in the run",
              holds(n_sw > 1, f"{n_sw} mode switches in the log; more than the heating/cooling test's 1"),
              paper="> 1", kind=CONSTRUCTION,
              note="the heating/cooling scenario switches once by definition, and two-position control with "
                   "hysteresis switches at every crossing of the band, whatever the filter: the count is set by "
                   "the (simulated) plant and the controller, not tested by the PF")
    r1, r2 = _per_seed(acc, "m1", "rms_eps"), _per_seed(acc, "m2", "rms_eps")
    why = f"one DS18B20 step ({chamber.RESOLUTION} °C), the measurement accuracy the paper states (§3)"
    ctx.claim("The estimate accurately tracks the measurement signal despite the frequent switching",
              "[Embedded] §5.3, Fig. 10", "RMS eq. 13 error of the worse of models (10) and (12), per PF seed [°C]",
              in_band(np.maximum(r1, r2), 0.0, chamber.RESOLUTION, what="RMS eps (worse model)", why=why),
              paper="< one sensor step (our reading of 'accurate')",
              reading="both estimates that Fig. 10 plots track the measurement (the worse of the two decides): the "
                      "sentence speaks of 'the estimate' and the figure shows both",
              others=[Reading("model (10) only: by construction, since with sigma_v^2 = 0.010 on both states "
                              "(Table A2) its estimate nearly copies the measurement (see the Fig. 9 note)",
                              "RMS eps of model (10), per PF seed",
                              in_band(r1, 0.0, chamber.RESOLUTION, what="RMS eps (10)", why=why)),
                      Reading("model (12) only", "RMS eps of model (12), per PF seed",
                              in_band(r2, 0.0, chamber.RESOLUTION, what="RMS eps (12)", why=why))])
    ctx.extra["metrics"] = mean
    ctx.extra["mode_switches"] = n_sw


# ----------------------------------------------------------------------------- Appendix A
def appendix_tests() -> list[dict]:
    """Every test of Tables A1 and A2: name, temperature, N_p, sigma_v^2, sigma_n^2, table."""
    tests = []
    for (vv, vn), suffix in TABLE_A1:
        for g, temp in TEMPS.items():
            if suffix in ("5", "6") and g != "A":
                continue  # '—' in Table A1
            tests.append({"test": f"{g}-{suffix}", "table": "A1", "set_temp": temp, "n_particles": 1000,
                          "var_v": vv, "var_n": vn})
    for n_p, suffix in TABLE_A2.items():
        if n_p == 1000:
            continue  # A-1/B-1/C-1 are already in Table A1
        for g, temp in TEMPS.items():
            tests.append({"test": f"{g}{suffix}", "table": "A2", "set_temp": temp, "n_particles": n_p,
                          "var_v": VAR_V, "var_n": VAR_N})
    return tests


_GRID_CACHE: dict = {}  # tableA1 / tableA2 / figA1 share one grid run per process


def _grid(ctx) -> tuple[pd.DataFrame, dict, dict]:
    """Run the Appendix A grid with model (10) (the paper's Appendix uses eq. 10 only): the table,
    per test (log, first-seed estimate), per test the per-PF-seed RMS errors."""
    key = (int(ctx.seed), bool(ctx.full), ctx.backend, str(ctx.data), _n_seeds(ctx))
    if key in _GRID_CACHE:
        return _GRID_CACHE[key]
    rows, series, seeds = [], {}, {}
    tests = appendix_tests()
    for spec in ctx.progress(tests, total=len(tests), desc="Appendix A grid"):
        name = "B-1" if spec["test"] == "B-1" else spec["test"]
        cols = _experiment(ctx, "heating_cooling", name, spec["set_temp"])
        mean, est, acc = _metrics(ctx, cols, spec["n_particles"], spec["var_v"], spec["var_n"], which=("m1",))
        rows.append({**spec, **mean["m1"], "n_steps": len(cols["y"])})
        seeds[spec["test"]] = {k: _per_seed(acc, "m1", k) for k in ("rms_true", "rms_eps")}
        series[spec["test"]] = (cols, est["m1"])
    df = pd.DataFrame(rows)
    _GRID_CACHE[key] = (df, series, seeds)
    return df, series, seeds


def _metric(df: pd.DataFrame) -> str:
    """Error the Appendix A claims use: vs the simulated truth when there is one, else eq. 13."""
    return "rms_true" if np.all(np.isfinite(df["rms_true"])) else "rms_eps"


def _seed_mean(seeds: dict, tests, metric: str) -> np.ndarray:
    """Per PF seed, the mean RMS error over ``tests``."""
    return np.mean([seeds[t][metric] for t in tests], axis=0)


def _grid_claims(ctx, df: pd.DataFrame, seeds: dict) -> None:
    """Table A1 claims of [Embedded] §6 (variances), decided from per-PF-seed errors."""
    a1 = df[df.table == "A1"]
    metric = _metric(df)
    other = "rms_true" if metric == "rms_true" else None   # the truth exists only in simulation
    good = a1[~a1.test.str.endswith(("-5", "-6"))]
    bad = a1[a1.test.str.endswith(("-5", "-6"))]
    for _, r in bad.iterrows():
        ctx.compare(f"{r.test} (σv²={r.var_v}, σn²={r.var_n}): RMS eps (eq. 13, vs measurement)", ours=float(r.rms_eps),
                    unit="°C", paper="worse than tests 1-4 (§6, Fig. A1)",
                    note=f"worst of tests 1-4: {float(good.rms_eps.max()):.4f}")
        if other:
            ctx.compare(f"{r.test}: RMS error vs true sensor temperature", ours=float(r.rms_true), unit="°C",
                        paper="worse than tests 1-4", note=f"worst of tests 1-4: {float(good.rms_true.max()):.4f}")

    def worse(test, key, margin):
        """Worse than every correct setting by more than ``margin``: for "cannot match the measurements",
        half a sensor step, the rounding the measurement itself carries (a smaller excess cannot be seen
        on Fig. A1's plots; one of 0.002 °C, 3 % of a step, agreed)."""
        worst = np.max([seeds[t][key] for t in good.test], axis=0)
        return direction(seeds[test][key] - worst - margin, +1, what=f"{test} - worst of tests 1-4 ({key})"
                         + (" - half a sensor step" if margin else ""))

    for test, what, margin in (("A-5", "If σv² is too high (A-5, σv² = 1.0), particles may not be able to match "
                                       "the actual measurements", HALF_STEP),
                               ("A-6", "An overly high σn² (A-6, σn² = 1.0) limits the confidence in the measurement "
                                       "in favour of the model", 0.0)):
        excess = f" minus half a sensor step ({HALF_STEP:.4g} °C)" if margin else ""
        if test not in seeds:
            continue
        others = []
        if other:
            others.append(Reading("worse against the true (unquantised) sensor temperature (simulation only)",
                                  f"RMS error vs truth of {test} minus the worst of A/B/C-1..4{excess}, per PF seed",
                                  worse(test, "rms_true", margin)))
        ctx.claim(what, "[Embedded] §6, Table A1, Fig. A1",
                  f"RMS eq. 13 error of {test} minus the worst of A/B/C-1..4{excess}, per PF seed [°C]",
                  worse(test, "rms_eps", margin),
                  paper="> 0 (worse than every correct setting" + (", visibly)" if margin else ")"),
                  reading="worse eq. 13 error (estimate vs the measurement), the sentence speaks of matching the "
                          "measurements and Fig. A1 plots estimate against measurement" if others else "",
                  others=others)
    lo_v = [t for t in good.test if t.endswith(("-3", "-4"))]     # sigma_v^2 = 0.001
    hi_v = [t for t in good.test if t.endswith(("-1", "-2"))]     # sigma_v^2 = 0.010 / 0.005
    d_v = _seed_mean(seeds, hi_v, metric) - _seed_mean(seeds, lo_v, metric)
    ctx.compare(f"mean RMS error ({metric}) tests 1-2 (σv² 0.010/0.005) - tests 3-4 (σv² 0.001)",
                ours=float(np.mean(d_v)), unit="°C", paper="> 0 (lower σv² better, §6)")
    ctx.claim("Better results with the lower process-noise variance (σv² = 0.001, tests 3-4) than with "
              "σv² = 0.010/0.005 (tests 1-2), which proves that the model is well fitted", "[Embedded] §6, Fig. A1d,e",
              f"mean RMS error ({metric}) of tests 1-2 minus tests 3-4 over A/B/C",
              not_reproducible("which process-noise variance is best is set by how well eq. 10 fits the plant; the "
                               "paper's statement is about its chamber, ours is a simulated plant whose mismatch to "
                               f"eq. 10 we chose (our difference, {np.mean(d_v):+.4f} °C, is shown as a comparison)"),
              paper="> 0")
    # "sigma_n^2 comparable to the resolution": computed for both readings over the correct settings (tests 1-4),
    # shown as comparisons; not scored (the best sigma_n^2 is set by the plant's noise and mismatch, both guessed)
    res = chamber.RESOLUTION
    by_vn = good.groupby("var_n")[metric].mean()
    best_vn = float(by_vn.idxmin())
    grid = np.array(sorted(good.var_n.unique()), dtype=float)
    ctx.compare("σn² of tests 1-4 with the lowest mean RMS error", ours=best_vn, paper="comparable to the resolution",
                note=f"metric {metric}; " + ", ".join(f"σn²={k:g}: {v:.4f}" for k, v in by_vn.items())
                     + "; σn² 0.010 occurs only with σv² 0.001 (test 3), so the ranking is confounded as in the paper's table")
    for reading, target in (("σn ≈ resolution (σn² ≈ 0.0039)", res ** 2), ("σn² ≈ resolution (0.0625)", res)):
        near = float(grid[np.argmin(np.abs(np.log(grid / target)))])
        ctx.compare(f"grid σn² of tests 1-4 nearest the reading {reading}", ours=near, paper=best_vn,
                    note="'paper' column: our best σn² of tests 1-4")
    ctx.claim("In each test case, the best effects were observed for σn² comparable to the resolution of the "
              "measuring device", "[Embedded] §6, Table A1", "σn² of tests 1-4 with the lowest mean RMS error",
              not_reproducible("the best measurement-noise setting is set by the real sensor's noise and the model's "
                               "mismatch to the real chamber; our plant's analogue noise (0.01 °C) and mismatch are "
                               f"guesses, so our best σn² ({best_vn:g}, see comparisons, both readings) tests neither"),
              paper="σn² ~ resolution")
    if metric == "rms_true":
        ctx.note("Appendix A errors are reported both against the measurement (eq. 13, rms_eps/max_eps, as the paper "
                 "plots) and against the simulated true (unquantised) sensor temperature (rms_true/max_true); claims "
                 "about matching the measurements use eq. 13 and show the truth as a sensitivity row, claims about "
                 "estimation quality use the truth.")


def _np_claim(ctx, df: pd.DataFrame, seeds: dict) -> None:
    """[Embedded] §5.2: model (10) needs a sufficiently large N_p (Table A2): one sentence, one finding."""
    metric = _metric(df)
    a2 = df[(df.table == "A2") | df.test.isin(["A-1", "B-1", "C-1"])]
    by_np = a2.groupby("n_particles")[metric].mean()
    ctx.compare("mean RMS error by N_p (σv²=0.010, σn²=0.005)",
                ours=", ".join(f"N_p={int(k)}: {v:.4f}" for k, v in by_np.items()),
                paper="model (10) needs a sufficiently large N_p (§5.2, §6)")
    tests = {n: list(a2[a2.n_particles == n].test) for n in (100, 500, 1000)}

    def diff(small, key):
        return direction(_seed_mean(seeds, tests[small], key) - _seed_mean(seeds, tests[1000], key), +1,
                         what=f"N_p={small} - N_p=1000 ({key})")

    others = [Reading("N_p = 500 worse than N_p = 1000", f"mean RMS error ({metric}), N_p = 500 minus 1000",
                      diff(500, metric))]
    if metric == "rms_true":
        others.append(Reading("N_p = 100 worse than N_p = 1000 in eq. 13 error (vs the measurement)",
                              "mean RMS eps, N_p = 100 minus 1000", diff(100, "rms_eps")))
    ctx.claim("In the case of model (10), a sufficiently large number of particles is needed for a correct estimation",
              "[Embedded] §5.2, Table A2", f"mean RMS error ({metric}) over A/B/C, N_p = 100 minus 1000, per PF seed",
              diff(100, metric), paper="> 0",
              reading="the smallest N_p of Table A2 (100) estimates worse than the largest (1000): the sentence "
                      "contrasts too few particles with enough, and Table A2's extremes are the paper's test of it",
              others=others,
              note="§6 repeats the statement ('a sufficiently large number of particles is needed'); scored once")


def _operating_points_claim(ctx, df: pd.DataFrame, seeds: dict) -> None:
    """[Embedded] §6: the estimate follows the measurements at the different set temperatures (Fig. A1a,j)."""
    tests = [t for t in df[df.table == "A1"].test if not t.endswith(("-5", "-6"))]
    why = f"one DS18B20 step ({chamber.RESOLUTION} °C), the measurement accuracy the paper states (§3)"

    def worst(key):
        return in_band(np.max([seeds[t][key] for t in tests], axis=0), 0.0, chamber.RESOLUTION,
                       what=f"worst RMS error ({key}) over tests 1-4", why=why)

    others = []
    if _metric(df) == "rms_true":
        others.append(Reading("against the true (unquantised) sensor temperature (simulation only)",
                              "worst RMS error vs truth over A/B/C-1..4, per PF seed", worst("rms_true")))
    ctx.claim("Good adjustment of the estimate to the measurements at the different temperature values (operating "
              "points) with the correct settings (tests 1-4)", "[Embedded] §6, Fig. A1a,j",
              "worst RMS eq. 13 error over A/B/C-1..4, per PF seed [°C]", worst("rms_eps"),
              paper="< one sensor step (our reading of 'good adjustment')",
              reading="eq. 13 error (estimate vs the measurement): the sentence speaks of adjustment to the "
                      "measurements" if others else "", others=others)


@recipe("embedded:tableA1", aliases=("tableA1",), title="Appendix A Table A1: σv²/σn² grid, N_p = 1000",
        quick_cost="~1 min", full_cost="~5 min", options=OPTIONS, reads_data=True)
def tableA1(ctx):
    df, _, seeds = _grid(ctx)
    out = df[df.table == "A1"].reset_index(drop=True)
    ctx.write_table("tableA1", out)
    _grid_claims(ctx, df, seeds)


@recipe("embedded:tableA2", aliases=("tableA2",), title="Appendix A Table A2: N_p = 100/500/1000 at σv²=0.010, σn²=0.005",
        quick_cost="~1 min", full_cost="~5 min", options=OPTIONS, reads_data=True)
def tableA2(ctx):
    df, _, seeds = _grid(ctx)
    out = df[(df.table == "A2") | df.test.isin(["A-1", "B-1", "C-1"])].sort_values(["set_temp", "n_particles"])
    ctx.write_table("tableA2", out.reset_index(drop=True))
    metric = _metric(df)
    for temp, g in out.groupby("set_temp"):
        ctx.compare(f"{temp} °C: RMS error ({metric}) N_p=100/500/1000",
                    ours=" / ".join(f"{v:.4f}" for v in g.sort_values("n_particles")[metric]), unit="°C",
                    paper="larger N_p better for model (10)")
    _np_claim(ctx, df, seeds)


@recipe("embedded:figA1", aliases=("figA1",), title="Appendix A Fig. A1: one panel per test",
        quick_cost="~1 min", full_cost="~5 min", options=OPTIONS, reads_data=True)
def figA1(ctx):
    df, series, seeds = _grid(ctx)
    names = list(df.test)
    ncol = 4
    nrow = int(np.ceil(len(names) / ncol))
    fig, axes = plotting.subplots(nrow, ncol, figsize=(3.3 * ncol, 2.5 * nrow), squeeze=False)
    rows = []
    for i, (ax, name) in enumerate(zip(axes.flat, names)):
        cols, yhat = series[name]
        t = cols["time_s"]
        ax.step(t, cols["y"], where="post", color="red", lw=0.7, label="measured y")
        ax.plot(t, yhat, color="blue", lw=0.7, label=r"$\hat y_{m1}$ (eq. 10)")
        r = df[df.test == name].iloc[0]
        plotting.label(ax, "time [s]", "temperature [°C]",
                       f"{name}: set {r.set_temp:g} °C, σv²={r.var_v:g}, σn²={r.var_n:g}, N_p={int(r.n_particles)}")
        ax.title.set_fontsize(7)
        if i == 0:
            ax.legend(loc="lower right", fontsize=6)
        rows.append(pd.DataFrame({"test": name, "time_s": t, "y": cols["y"], "y_hat_m1": yhat,
                                  "truth": cols["truth"]}))
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    src = f"log {ctx.data.name}" if ctx.data else "simulated chamber, heating then cooling to the set temperature"
    fig.suptitle(f"Fig. A1: every test of Tables A1/A2 with model (10), first PF seed ({src}); "
                 "A/B/C = set 22.0/22.5/23.0 °C")
    ctx.write_figure("figA1", fig)
    ctx.write_table("figA1", pd.concat(rows, ignore_index=True))
    ctx.write_table("figA1_errors", df)
    _operating_points_claim(ctx, df, seeds)
