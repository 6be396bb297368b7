"""rtd:fig5 -- time-varying Kalman filter on the simulated second-order RTD ([RTD], §4.2.1, §5, Fig. 5)."""
from __future__ import annotations

import numpy as np

from pfbench import plotting
from pfbench.plants import rtd
from pfbench.ranges import POSITIVE, OneOf, at_least
from pfbench.recipes import recipe
from pfbench.verdicts import Reading, close_to, proportion

from ._sweep import swept


def steady_time(t, errcov, rel=0.01):
    """First time after which C P C^T stays within ``rel`` of its final value."""
    off = np.abs(errcov - errcov[-1]) > rel * abs(errcov[-1])
    idx = np.nonzero(off)[0]
    return float(t[idx[-1] + 1]) if idx.size else float(t[0])


#: (Q, R) values the chapter might have used besides the MATLAB example's (2.3, 1): Q/R from 0.023
#: to 23, a decade or two either side of the example, and R a decade either side at Q = 2.3
SWEEP = ((0.023, 1.0), (0.23, 1.0), (23.0, 1.0), (2.3, 0.1), (2.3, 10.0))
#: "approximately 8 s": one significant digit, read as 8 +- 2 s
SETTLE_TOL = 0.25
#: "less than 1 degC in the worst of the cases": every run (rate 100 %); a band of 5 points lets a
#: finite number of runs confirm a rate of 100 % (the chapter gives no count of cases)
RATE_TOL = 0.05


@recipe("rtd:fig5", title="Time-varying KF on the simulated RTD (Fig. 5)", quick_cost="~5 s",
        full_cost="~30 s",
        options={"Q": (float, "process-noise variance of the KF (default 2.3)", at_least(0.0)),
                 "R": (float, "measurement-noise variance (default 1.0)", POSITIVE),
                 "n": (int, "time steps (default 600; the run must reach t = 45 s)",
                       at_least(round(45.0 / rtd.TS) + 1)),
                 "model": (str, "sensor model (default eq52)", OneOf("eq52", "eq54"))})
def fig5(ctx):
    import pandas as pd

    Qu, R = ctx.option("Q", 2.3, float), ctx.option("R", 1.0, float)
    n = ctx.option("n", 600, int)
    which = ctx.option("model", "eq52")
    model = rtd.identified_model() if which == "eq52" else rtd.eq54_model()
    d = rtd.simulate_fig5(n=n, Qu=Qu, R=R, seed=ctx.seed, model=model)
    t = d["t"]
    late = t >= 45.0
    k45 = int(np.argmax(late))
    meas_err = d["y_meas"] - d["y_true"]
    est_err = d["y_true"] - d["yest"]
    ctx.write_table("fig5", pd.DataFrame({"t_s": t, "u": d["u"], "y_true": d["y_true"], "y_meas": d["y_meas"],
                                          "y_est": d["yest"], "meas_err": meas_err, "est_err": est_err,
                                          "errcov": d["errcov"]}))

    # Monte Carlo over noise realisations, at the defaults and at each (Q, R) of the sweep
    n_mc = 200 if ctx.full else 30
    seeds = [10_000 + ctx.seed * 1000 + s for s in range(n_mc)]
    rows = []
    for q, r in ((Qu, R),) + tuple(p for p in SWEEP if p != (Qu, R)):
        mc = rtd.fig5_runs(n=n, Qu=q, R=r, seeds=seeds, model=model)
        e = mc["y_true"] - mc["yest"]
        rows.append({"Q": q, "R": r, "settle_1pct_s": steady_time(t, mc["errcov"], 0.01),
                     "settle_0.1pct_s": steady_time(t, mc["errcov"], 0.001),
                     "settle_5pct_s": steady_time(t, mc["errcov"], 0.05),
                     "runs": n_mc, "k_every_below_1": int(np.sum(np.abs(e[:, late]).max(axis=1) < 1.0)),
                     "k_at45_below_1": int(np.sum(np.abs(e[:, k45]) < 1.0)),
                     "sd_steady": float(np.sqrt(mc["errcov"][-1])),
                     "_worst": np.abs(e[:, late]).max(axis=1), "_at45": e[:, k45]})
    base, sweep = rows[0], rows[1:]
    ctx.write_table("fig5_mc", pd.DataFrame({"run": np.arange(n_mc), "max_abs_err_after_45s": base["_worst"],
                                             "err_at_45s": base["_at45"]}))
    ctx.write_table("fig5_sweep", pd.DataFrame([{k: v for k, v in row.items() if not k.startswith("_")}
                                                for row in rows]))

    ts = steady_time(t, d["errcov"])
    _figure(ctx, d, t, meas_err, est_err, ts, rows, which, model, Qu, R)

    ctx.compare("C P C^T steady (within 1 %) after", round(ts, 2), 8.0, unit="s")
    ctx.compare("estimation error at t = 45 s (this run)", round(float(est_err[k45]), 4), -0.0948, unit="degC")
    ctx.compare("max |estimation error| for t >= 45 s (this run)", round(float(np.abs(est_err[late]).max()), 3),
                None, unit="degC")
    st = t >= 8.0
    ctx.compare("RMS measurement error (t >= 8 s)", round(float(np.sqrt(np.mean(meas_err[st] ** 2))), 4), None,
                unit="degC")
    ctx.compare("RMS estimation error (t >= 8 s)", round(float(np.sqrt(np.mean(est_err[st] ** 2))), 4), None,
                unit="degC")
    ctx.compare("steady C P C^T (time-varying, last step)", round(float(d["errcov"][-1]), 5), None)
    ctx.compare("sd of the error at 45 s over runs", round(float(base["_at45"].std(ddof=1)), 4), None, unit="degC",
                note="sqrt(steady C P C^T) is the theoretical value")
    for row in sweep:
        ctx.compare(f"sweep Q={row['Q']:g}, R={row['R']:g}: C P C^T steady (1 %) after", row["settle_1pct_s"], 8.0,
                    unit="s")
        ctx.compare(f"sweep Q={row['Q']:g}, R={row['R']:g}: runs with max |error| < 1 degC after 45 s",
                    round(row["k_every_below_1"] / n_mc, 3), 1.0, note=f"{n_mc} runs")

    where = "[RTD] §5, Fig. 5"
    why_t = f"'approximately 8 s' has one significant digit: 8 ± {SETTLE_TOL * 8:g} s"

    def settle(row, key="settle_1pct_s"):
        return close_to(row[key], 8.0, SETTLE_TOL, why=why_t)

    sweep_t = [Reading(f"Q={row['Q']:g}, R={row['R']:g}", "time after which C P C^T stays within 1 % of its final "
                       "value", settle(row)) for row in sweep]
    sweep_t += [Reading(f"steady state read as within {lab} (Q={Qu:g}, R={R:g})", f"time after which C P C^T stays "
                        f"within {lab} of its final value", settle(base, key))
                for lab, key in (("0.1 %", "settle_0.1pct_s"), ("5 %", "settle_5pct_s"))]
    out, others = swept(settle(base), sweep_t, "Q, R (and the steady-state threshold)")
    ctx.claim("As it can be seen, we have the possibility to predict the state after approximately 8 seconds",
              f"{where}(C)", "time after which C P C^T stays within 1 % of its final value (P0 = B Q B^T as in "
              "the chapter's code)", out, paper="≈ 8 s",
              reading=("'steady state' read as C P C^T within 1 % of its final value, at the MATLAB example's "
                       f"Q = {Qu:g}, R = {R:g}; the other thresholds and (Q, R) beneath") if others else "",
              others=others)

    def rate(row, key):
        return proportion(row[key], row["runs"], 1.0, RATE_TOL)

    readings = (("k_every_below_1", "runs whose max |error| over t >= 45 s is < 1 degC"),
                ("k_at45_below_1", "runs with |error at t = 45 s| < 1 degC"))
    res = []
    for key, quantity in readings:
        sw = [Reading(f"Q={row['Q']:g}, R={row['R']:g}", quantity, rate(row, key)) for row in sweep]
        res.append(swept(rate(base, key), sw, "noise levels Q, R"))
    (out_every, sw_every), (out_45, _) = res
    ctx.claim("Also, we show the evolution of the estimated temperature response showing an error of −0.0948°C in "
              "the best of the cases and less than 1°C in the worst of the cases after 45 seconds", f"{where}(A)",
              readings[0][1], out_every, paper="every case < 1 degC after 45 s; best case -0.0948 degC",
              reading=("'the worst of the cases after 45 seconds' = the largest error of every run from 45 s to the "
                       "end: 'worst' ranges over the cases, 'after' over the time"),
              others=[Reading("the error at t = 45 s only, in every run", readings[1][1], out_45)] + sw_every,
              note=(f"rate over {n_mc} runs, band 100 % - {RATE_TOL:.0%} (the chapter gives no count of cases). "
                    "The -0.0948 degC of 'the best of the cases' is one realisation of unknown seed and noise "
                    "levels: shown as a comparison, not scored."))
    ctx.note(f"fig5: Q={Qu:g} (input noise through B) and R={R:g} are the MATLAB time-varying Kalman example "
             "values the chapter says it modified; the chapter does not state its own, so each claim is also "
             f"computed at (Q, R) = {', '.join(f'({q:g}, {r:g})' for q, r in SWEEP)} (fig5_sweep.csv) and scored "
             "only where every one gives the same verdict. The model is the ZOH discretisation (Ts=0.1 s) of "
             "eq. 52; eq. 54's matrices lost their signs in the extraction and have complex poles and DC gain "
             "2.23, inconsistent with eq. 52 (use --option model=eq54 to try).")
    longest = max(row[k] for row in rows for k in ("settle_1pct_s", "settle_0.1pct_s", "settle_5pct_s"))
    ctx.note(f"fig5: C P C^T settles in {ts:.1f} s here, and within {longest:.1f} s at every (Q, R) of the sweep "
             "and every threshold: with the chapter's P0 = B Q B^T the Riccati recursion starts near its fixed "
             "point.")


def _figure(ctx, d, t, meas_err, est_err, ts, rows, which, model, Qu, R):
    fig, ax = plotting.subplots(2, 2, figsize=(11, 7.5))
    a, b, c, e = ax[0, 0], ax[0, 1], ax[1, 0], ax[1, 1]
    a.plot(t, d["y_true"], color="c", lw=1.5, label="true response y")
    a.plot(t, d["yest"], color=plotting.OURS, ls="--", lw=1, label="filtered response (ours)")
    plotting.label(a, "time [s]", "output [degC]", "(A) true vs filtered")
    a.legend(loc="lower right")
    b.plot(t, meas_err, color=plotting.OTHER, lw=0.6, label="measurement error")
    b.plot(t, est_err, color=plotting.OURS, lw=1, label="estimation error (ours)")
    b.plot([45.0], [-0.0948], "s", color=plotting.PAPER, ms=6, label="paper: -0.0948 degC (best case)")
    b.hlines([-1.0, 1.0], 45.0, t[-1], colors=plotting.PAPER, linestyles="--", lw=1,
             label="paper: |error| < 1 degC after 45 s")
    plotting.label(b, "time [s]", "error [degC]", "(B) measurement vs estimation error")
    b.legend(loc="lower right", fontsize=7)
    c.plot(t, d["errcov"], color=plotting.OURS, lw=1.2, label=f"C P C^T (ours; 1 % steady after {ts:.1f} s)")
    plotting.paper_value(c, 8.0, "paper: steady after ≈ 8 s", axis="x")
    plotting.label(c, "time [s]", "errcov = C P C^T [degC^2]", "(C) error covariance of the time-varying filter")
    c.legend(loc="upper right")
    qr = np.array([row["Q"] / row["R"] for row in rows])
    o = np.argsort(qr)
    for key, mk, lab in (("settle_1pct_s", "o", "within 1 %"), ("settle_0.1pct_s", "^", "within 0.1 %"),
                         ("settle_5pct_s", "v", "within 5 %")):
        e.plot(qr[o], np.array([row[key] for row in rows])[o], marker=mk, ls="-", label=f"ours: C P C^T {lab}")
    e.set_xscale("log")
    plotting.paper_value(e, 8.0, "paper: ≈ 8 s")
    e.axhspan(8.0 * (1 - SETTLE_TOL), 8.0 * (1 + SETTLE_TOL), color=plotting.PAPER, alpha=0.1,
              label="band of 'approximately 8 s'")
    plotting.label(e, "Q/R of the sweep [-]", "time to steady state [s]", "(D) settling time over the (Q, R) sweep")
    e.legend(loc="center right", fontsize=7)
    fig.suptitle(f"RTD time-varying Kalman filter ({which} model, Q={Qu:g}, R={R:g}, Ts={model.Ts:g} s)")
    ctx.write_figure("fig5", fig)
