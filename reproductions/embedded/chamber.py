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
from pfbench.plants.datalog import read_log
from pfbench.filters import run_filter
from pfbench.models import get as get_model
from pfbench.models.thermal import _mode_inputs
from pfbench.recipes import recipe
from pfbench.verdicts import direction, holds, not_reproducible

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
OPTIONS = {"pf_seeds": (int, "PF seeds averaged per experiment (quick 3, full 20)")}


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


def _m2_beats_m1(ctx, acc: dict, test: str, n_p: int, key: str = "rms_eps") -> None:
    """[Embedded] §5.2 / Fig. 9: model (12) has the lower estimation error (13) than model (10)."""
    d = _per_seed(acc, "m1", key) - _per_seed(acc, "m2", key)
    what = "eq. 13 error vs the measurement" if key == "rms_eps" else "error vs the true sensor temperature"
    ctx.claim(f"{test} (N_p = {n_p}): model (12) estimates with a lower error than model (10) "
              "(\"reduced errors for the y_m2 chart\")", "[Embedded] §5.2, Fig. 9",
              f"RMS {what}: m1 - m2, per PF seed (one plant run)",
              direction(d, +1, what="RMS m1 - RMS m2"), paper="> 0 (m2 lower)")


def _series(cols, est) -> pd.DataFrame:
    return pd.DataFrame({"time_s": cols["time_s"], "y": cols["y"], "u1": cols["u1"], "u2": cols["u2"],
                         "t_out": cols["t_out"], "mode": _mode_inputs(cols)[:, 2],
                         "y_hat_m1": est["m1"], "y_hat_m2": est["m2"], "truth": cols["truth"]})


def _figure(df: pd.DataFrame, title: str):
    """Paper layout: temperatures (measured red, y_hat_m1 blue, y_hat_m2 black, outdoor gray) over
    inputs u1, u2; an inset zooms on the mode switch (the paper's rectangles)."""
    import matplotlib.pyplot as plt

    fig, (ax, axu) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    t = df["time_s"].to_numpy()
    ax.step(t, df["y"], where="post", color="red", lw=1.0, label="measured y")
    ax.plot(t, df["y_hat_m1"], color="blue", lw=1.0, label=r"$\hat y_{m1}$ (eq. 10)")
    ax.plot(t, df["y_hat_m2"], color="black", lw=1.0, label=r"$\hat y_{m2}$ (eq. 12)")
    if np.any(np.isfinite(df["t_out"])):
        ax.step(t, df["t_out"], where="post", color="gray", lw=1.0, label="outdoor")
    ax.set_ylabel("temperature [°C]")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
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
        ax.indicate_inset_zoom(ins, edgecolor="0.4")
    axu.plot(t, df["u1"], color="tab:orange", label="u1 heater [%]")
    axu.plot(t, df["u2"], color="tab:green", label="u2 fan [%]")
    axu.set_ylim(-5, 105)
    axu.set_xlabel("time [s]")
    axu.set_ylabel("input [%]")
    axu.grid(alpha=0.3)
    axu.legend(loc="center right", fontsize=8)
    fig.tight_layout()
    return fig


def _heating_time(cols) -> float | None:
    info = cols.get("info") or {}
    k = info.get("k_switch")
    return None if k is None else float(cols["time_s"][k])


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
    # fig9 records the claim on the paper's eq. 13 errors; here, on a simulation, the same claim against the
    # true sensor temperature (which model estimates the temperature better), on a log the eq. 13 version
    _m2_beats_m1(ctx, acc, test, n_p, key="rms_true" if np.all(np.isfinite(cols["truth"])) else "rms_eps")
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
        ctx.claim("When u2 jumps to 100 % and u1 to 0 %, the air mixing causes a sudden increase of the air "
                  "temperature around the thermometer", "[Embedded] §5.2", "rise of y after the switch (60 s)",
                  not_reproducible("a property of the authors' chamber airflow, which the paper does not describe; "
                                   f"our plant's bump at the sensor ({bump['sensor']:.3f} °C) is below the "
                                   f"{chamber.RESOLUTION} °C sensor step (see pfbench.plants.chamber)"),
                  paper="a visible rise")
    elif ctx.data:
        ctx.claim("When u2 jumps to 100 % and u1 to 0 %, the air mixing causes a sudden increase of the air "
                  "temperature around the thermometer", "[Embedded] §5.2", "rise of y after the switch",
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
        ctx.claim(claim, "[Embedded] §5.2, Figs. 6-8", "heating time to 22.5 °C: fig6 (room 19.3) - fig7 (room 19.6)",
                  holds(t6 > t7, f"simulated plant runs: {t6:.0f} s at 19.3 °C vs {t7:.0f} s at 19.6 °C; "
                                 "agree if the first is longer"), paper="fig6 longer")
        ctx.note("Fig. 6 vs Figs. 7-8: the paper attributes Fig. 6's longer heating to the lower room temperature "
                 "(19.3 vs 19.6 °C); in our plant the time to 22.5 °C is longer at 19.3 °C simply because the "
                 "required rise is larger (see the heating times of fig6/fig7).")


@recipe("embedded:fig7", aliases=("fig7",), title="Heating/cooling, N_p = 500 (Fig. 7, test B2-1)",
        quick_cost="~20 s", full_cost="~1 min", options=OPTIONS, reads_data=True)
def fig7(ctx):
    _heating_cooling_fig(ctx, "fig7")


@recipe("embedded:fig8", aliases=("fig8",), title="Heating/cooling, N_p = 100 (Fig. 8, test B3-1)",
        quick_cost="~20 s", full_cost="~1 min", options=OPTIONS, reads_data=True)
def fig8(ctx):
    _heating_cooling_fig(ctx, "fig8")


@recipe("embedded:fig9", aliases=("fig9",), title="Estimation errors eps(k) of B1, B2-1, B3-1 (Fig. 9)",
        quick_cost="~30 s", full_cost="~2 min", options=OPTIONS, reads_data=True)
def fig9(ctx):
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=False)
    frames, rows = [], []
    for ax, (name, (test, n_p, _amb)) in zip(axes, FIG_RUNS.items()):
        cols = _experiment(ctx, "heating_cooling", test, 22.5)
        mean, est, acc = _metrics(ctx, cols, n_p)
        _m2_beats_m1(ctx, acc, test, n_p)
        t = cols["time_s"]
        e1, e2 = cols["y"] - est["m1"], cols["y"] - est["m2"]
        frames.append(pd.DataFrame({"test": test, "n_particles": n_p, "time_s": t, "eps_m1": e1, "eps_m2": e2}))
        for m in ("m1", "m2"):
            rows.append({"test": test, "n_particles": n_p, "model": m, **mean[m]})
        ax.plot(t, e1, color="red", lw=0.8, label="model (10)")
        ax.plot(t, e2, color="blue", lw=0.8, label="model (12)")
        ax.set_title(f"{test} (N_p = {n_p})", fontsize=9)
        ax.set_ylabel(r"$\epsilon(k)$ [°C]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    ctx.write_table("fig9", pd.concat(frames, ignore_index=True))
    err = pd.DataFrame(rows)
    ctx.write_table("fig9_errors", err)
    ctx.write_figure("fig9", fig)
    for test, g in err.groupby("test", sort=False):
        r1 = float(g.loc[g.model == "m1", "rms_eps"].iloc[0])
        r2 = float(g.loc[g.model == "m2", "rms_eps"].iloc[0])
        ctx.compare(f"{test}: RMS eps m1 / m2", ours=f"{r1:.4f} / {r2:.4f}", unit="°C", paper="m2 lower (Fig. 9)")
    ctx.extra["errors"] = rows
    ctx.note("Fig. 9: with the Table A2 setting (sigma_v^2 = 0.010 on both states of eq. 10) model (10) is nearly a "
             "copy of the measurement, so its eq. 13 error is the smaller one, while model (12) (sigma_v1^2 = 1e-6) is "
             "smooth and lags when the mode switches (see the claims for the ranking our runs give).")


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
              holds(n_sw > 1, f"{n_sw} mode switches in the log; agree if more than the heating/cooling test's 1"),
              paper="> 1")
    for m, label in (("m1", "model (10)"), ("m2", "model (12)")):
        r = _per_seed(acc, m, "rms_eps")
        ctx.claim(f"The estimate accurately tracks the measurement signal despite the frequent switching ({label})",
                  "[Embedded] §5.3, Fig. 10", f"RMS eq. 13 error of {label} minus one sensor step (0.0625 °C), per PF seed",
                  direction(r - chamber.RESOLUTION, -1, what="RMS eps - 0.0625 °C"),
                  paper="< one sensor step (our reading of 'accurate')")
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
    good = a1[~a1.test.str.endswith(("-5", "-6"))]
    bad = a1[a1.test.str.endswith(("-5", "-6"))]
    worst_good = float(good[metric].max())
    for _, r in bad.iterrows():
        ctx.compare(f"{r.test} (σv²={r.var_v}, σn²={r.var_n}): RMS error ({metric})", ours=float(r[metric]),
                    unit="°C", paper="worse than A-1..A-4 (§6, Fig. A1)", note=f"worst of tests 1-4: {worst_good:.4f}")
    for _, r in bad.iterrows():
        ctx.compare(f"{r.test}: RMS eps (vs measurement)", ours=float(r.rms_eps), unit="°C",
                    paper="worse than A-1..A-4", note=f"best of 1-4: {float(good.rms_eps.min()):.4f}")
    worst_good_seed = np.max([seeds[t][metric] for t in good.test], axis=0)
    for test, what, where in (("A-5", "σv² too high (σv² = 1.0): particles cannot match the measurements",
                               "[Embedded] §6"),
                              ("A-6", "σn² too high (σn² = 1.0): confidence in the measurement is lost",
                               "[Embedded] §6")):
        if test in seeds:
            ctx.claim(f"{what}; worse than every setting of tests 1-4", where + ", Table A1, Fig. A1",
                      f"RMS error ({metric}) of {test} minus the worst of A/B/C-1..4, per PF seed",
                      direction(seeds[test][metric] - worst_good_seed, +1, what=f"{test} - worst of tests 1-4"),
                      paper="> 0")
    lo_v = [t for t in good.test if t.endswith(("-3", "-4"))]     # sigma_v^2 = 0.001
    hi_v = [t for t in good.test if t.endswith(("-1", "-2"))]     # sigma_v^2 = 0.010 / 0.005
    ctx.claim("Better results with the lower process-noise variance (σv² = 0.001, tests 3-4) than with "
              "σv² = 0.010/0.005 (tests 1-2)", "[Embedded] §6, Fig. A1d,e",
              f"mean RMS error ({metric}) of tests 1-2 minus tests 3-4 over A/B/C, per PF seed",
              direction(_seed_mean(seeds, hi_v, metric) - _seed_mean(seeds, lo_v, metric), +1,
                        what="tests 1-2 - tests 3-4"),
              paper="> 0", note="tests 3-4 also change σn² (0.010 / 0.001), so the comparison is confounded "
                                "as in the paper's table")
    by_vn = a1.groupby("var_n")[metric].mean()
    best_vn = float(by_vn.idxmin())
    res = chamber.RESOLUTION
    ctx.compare("σn² with the lowest mean RMS error over Table A1", ours=best_vn, paper="comparable to the resolution",
                note=f"σn = {np.sqrt(best_vn):.3f} °C vs resolution {res} °C; metric {metric}; "
                     + ", ".join(f"σn²={k:g}: {v:.4f}" for k, v in by_vn.items()))
    # "sigma_n^2 comparable to the resolution" has two readings; the grid value nearest (log scale) to each:
    grid = np.array(sorted(a1.var_n.unique()), dtype=float)
    for reading, target in (("σn ≈ resolution (σn² ≈ 0.0039)", res ** 2), ("σn² ≈ resolution (0.0625)", res)):
        near = float(grid[np.argmin(np.abs(np.log(grid / target)))])
        ctx.claim("The best effects were observed for σn² comparable to the resolution of the measuring device "
                  f"(reading: {reading})", "[Embedded] §6, Table A1", "σn² of Table A1 with the lowest mean RMS error",
                  holds(best_vn == near, f"best σn² over Table A1 (mean {metric} over tests and PF seeds) is "
                                         f"{best_vn:g}; agree if it is the grid value nearest {target:.4g}, i.e. {near:g}"),
                  paper=near)
    if metric == "rms_true":
        ctx.note("Appendix A errors are reported both against the measurement (eq. 13, rms_eps/max_eps, as the paper "
                 "plots) and against the simulated true (unquantised) sensor temperature (rms_true/max_true); claims use the latter "
                 "because an estimate that copies the quantised measurement would score eps = 0.")


def _np_claim(ctx, df: pd.DataFrame, seeds: dict) -> None:
    """[Embedded] §5.2/§6: model (10) needs a sufficiently large N_p (Table A2)."""
    metric = _metric(df)
    a2 = df[(df.table == "A2") | df.test.isin(["A-1", "B-1", "C-1"])]
    by_np = a2.groupby("n_particles")[metric].mean()
    ctx.compare("mean RMS error by N_p (σv²=0.010, σn²=0.005)",
                ours=", ".join(f"N_p={int(k)}: {v:.4f}" for k, v in by_np.items()),
                paper="model (10) needs a sufficiently large N_p (§5.2, §6)")
    tests = {n: list(a2[a2.n_particles == n].test) for n in (100, 500, 1000)}
    for small in (100, 500):
        ctx.claim(f"Model (10) needs a sufficiently large number of particles: N_p = {small} worse than N_p = 1000",
                  "[Embedded] §5.2, §6, Table A2", f"mean RMS error ({metric}) over A/B/C, N_p = {small} minus 1000, "
                  "per PF seed", direction(_seed_mean(seeds, tests[small], metric) - _seed_mean(seeds, tests[1000], metric),
                                           +1, what=f"N_p={small} - N_p=1000"), paper="> 0")


def _operating_points_claim(ctx, df: pd.DataFrame, seeds: dict) -> None:
    """[Embedded] §6: the estimate follows the measurements at the different set temperatures (Fig. A1a,j)."""
    metric = _metric(df)
    tests = [t for t in df[df.table == "A1"].test if not t.endswith(("-5", "-6"))]
    worst = np.max([seeds[t][metric] for t in tests], axis=0)
    ctx.claim("Good adjustment of the estimate to the measurements at the different temperature values (operating "
              "points) with the correct settings (tests 1-4)", "[Embedded] §6, Fig. A1a,j",
              f"worst RMS error ({metric}) over A/B/C-1..4 minus one sensor step (0.0625 °C), per PF seed",
              direction(worst - chamber.RESOLUTION, -1, what="worst RMS - 0.0625 °C"),
              paper="< one sensor step (our reading of 'good adjustment')")


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
    import matplotlib.pyplot as plt

    df, series, seeds = _grid(ctx)
    names = list(df.test)
    ncol = 4
    nrow = int(np.ceil(len(names) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.2 * ncol, 2.2 * nrow), squeeze=False)
    rows = []
    for ax, name in zip(axes.flat, names):
        cols, yhat = series[name]
        t = cols["time_s"]
        ax.step(t, cols["y"], where="post", color="red", lw=0.7)
        ax.plot(t, yhat, color="blue", lw=0.7)
        r = df[df.test == name].iloc[0]
        ax.set_title(f"{name}: σv²={r.var_v:g}, σn²={r.var_n:g}, N_p={int(r.n_particles)}", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.grid(alpha=0.3)
        rows.append(pd.DataFrame({"test": name, "time_s": t, "y": cols["y"], "y_hat_m1": yhat,
                                  "truth": cols["truth"]}))
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    fig.tight_layout()
    ctx.write_figure("figA1", fig)
    ctx.write_table("figA1", pd.concat(rows, ignore_index=True))
    ctx.write_table("figA1_errors", df)
    _operating_points_claim(ctx, df, seeds)
