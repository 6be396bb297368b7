"""rtd:fig5 -- time-varying Kalman filter on the simulated second-order RTD ([RTD], §4.2.1, §5, Fig. 5)."""
from __future__ import annotations

import numpy as np

from pfbench.plants import rtd
from pfbench.errors import InputError
from pfbench.recipes import recipe
from pfbench.verdicts import close_to, holds, proportion


def steady_time(t, errcov, rel=0.01):
    """First time after which C P C^T stays within ``rel`` of its final value."""
    off = np.abs(errcov - errcov[-1]) > rel * abs(errcov[-1])
    idx = np.nonzero(off)[0]
    return float(t[idx[-1] + 1]) if idx.size else float(t[0])


@recipe("rtd:fig5", title="Time-varying KF on the simulated RTD (Fig. 5)", quick_cost="~5 s",
        full_cost="~30 s",
        options={"Q": (float, "process-noise variance of the KF (default 2.3)"),
                 "R": (float, "measurement-noise variance (default 1.0)"),
                 "n": (int, "time steps (default 600)"),
                 "model": (str, "sensor model: eq52 (default) or eq54")})
def fig5(ctx):
    import matplotlib.pyplot as plt
    import pandas as pd

    Qu, R = ctx.option("Q", 2.3, float), ctx.option("R", 1.0, float)
    n = ctx.option("n", 600, int)
    which = str(ctx.options.get("model", "eq52"))
    if which not in ("eq52", "eq54"):
        raise InputError("option model must be eq52 or eq54")
    model = rtd.identified_model() if which == "eq52" else rtd.eq54_model()
    d = rtd.simulate_fig5(n=n, Qu=Qu, R=R, seed=ctx.seed, model=model)
    t = d["t"]
    meas_err = d["y_meas"] - d["y_true"]
    est_err = d["y_true"] - d["yest"]
    df = pd.DataFrame({"t_s": t, "u": d["u"], "y_true": d["y_true"], "y_meas": d["y_meas"],
                       "y_est": d["yest"], "meas_err": meas_err, "est_err": est_err,
                       "errcov": d["errcov"]})
    ctx.write_table("fig5", df)

    fig, ax = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    ax[0].plot(t, d["y_true"], color="c", lw=1.5, label="true response y")
    ax[0].plot(t, d["yest"], "r--", lw=1, label="filtered response")
    ax[0].set_ylabel("output [degC]"); ax[0].legend(); ax[0].set_title("(A) true vs filtered")
    ax[1].plot(t, meas_err, "g", lw=0.8, label="measurement error")
    ax[1].plot(t, est_err, "r--", lw=1, label="estimation error")
    ax[1].set_ylabel("error [degC]"); ax[1].legend(); ax[1].set_title("(B) measurement vs estimation error")
    ax[2].plot(t, d["errcov"], "b", lw=1.2)
    ax[2].set_ylabel("errcov = C P C^T"); ax[2].set_xlabel("time [s]")
    ax[2].set_title("(C) error covariance of the time-varying filter")
    fig.suptitle(f"RTD time-varying Kalman filter ({which} model, Q={Qu:g}, R={R:g}, Ts={model.Ts:g} s)")
    fig.tight_layout()
    ctx.write_figure("fig5", fig)

    ts = steady_time(t, d["errcov"])
    ctx.compare("C P C^T steady (within 1 %) after", round(ts, 2), 8.0, unit="s")
    late = t >= 45.0
    if not late.any():
        raise InputError("option n too small: the run must last at least 45 s")
    k45 = int(np.argmax(late))
    ctx.compare("estimation error at t = 45 s (this run)", round(float(est_err[k45]), 4), -0.0948, unit="degC")
    ctx.compare("max |estimation error| for t >= 45 s (this run)", round(float(np.abs(est_err[late]).max()), 3),
                None, unit="degC")
    st = t >= 8.0
    rms_m = float(np.sqrt(np.mean(meas_err[st] ** 2)))
    rms_e = float(np.sqrt(np.mean(est_err[st] ** 2)))
    ctx.compare("RMS measurement error (t >= 8 s)", round(rms_m, 4), None, unit="degC")
    ctx.compare("RMS estimation error (t >= 8 s)", round(rms_e, 4), None, unit="degC")
    ctx.compare("steady C P C^T (time-varying, last step)", round(float(d["errcov"][-1]), 5), None)

    # Monte Carlo over noise realisations: how often is the chapter's "< 1 degC after 45 s" true?
    n_mc = 200 if ctx.full else 30
    worst, at45 = [], []
    for s in ctx.progress(range(n_mc), total=n_mc, desc="rtd:fig5 MC"):
        r = rtd.simulate_fig5(n=n, Qu=Qu, R=R, seed=10_000 + ctx.seed * 1000 + s, model=model)
        e = r["y_true"] - r["yest"]
        worst.append(np.abs(e[late]).max()); at45.append(e[k45])
    worst, at45 = np.array(worst), np.array(at45)
    sd45 = float(at45.std(ddof=1))
    ctx.compare("sd of the error at 45 s over runs", round(sd45, 4), None, unit="degC",
                note="sqrt(steady C P C^T) is the theoretical value")
    where = "[RTD] §5, Fig. 5"
    ctx.claim("the error covariance shows the possibility to predict the state after approximately 8 seconds",
              f"{where}(C)", "time after which C P C^T stays within 1 % of its final value",
              close_to(ts, 8.0, 0.25, why="'approximately 8 s' read as 6-10 s"), paper="8 s")
    k = int(np.sum(worst < 1.0))
    ctx.claim("an error of less than 1 degC in the worst of the cases after 45 seconds (reading: every sample "
              "from 45 s to the end)", f"{where}(A)", "runs whose max |error| over t >= 45 s is < 1 degC",
              proportion(k, n_mc, 1.0, 0.05), paper="always (rate 100 %)",
              note="tolerance 5 points: 'worst of the cases' read as (nearly) every run")
    k1 = int(np.sum(np.abs(at45) < 1.0))
    ctx.claim("an error of less than 1 degC in the worst of the cases after 45 seconds (reading: the error at "
              "t = 45 s)", f"{where}(A)", "runs with |error at t = 45 s| < 1 degC",
              proportion(k1, n_mc, 1.0, 0.05), paper="always (rate 100 %)",
              note="tolerance 5 points: 'worst of the cases' read as (nearly) every run")
    lo, hi = np.quantile(at45, [0.025, 0.975])
    ctx.claim("an error of -0.0948 degC in the best of the cases", f"{where}(A)",
              "the paper's error at 45 s against our spread over runs",
              holds(lo <= -0.0948 <= hi, f"-0.0948 lies in the central 95 % of our errors at 45 s over "
                    f"{n_mc} runs ([{lo:.3f}, {hi:.3f}] degC), i.e. it is a plausible single realisation"),
              paper="-0.0948 degC", note="a single noise realisation of unknown seed and Q, R")
    ctx.write_table("fig5_mc", pd.DataFrame({"run": np.arange(n_mc), "max_abs_err_after_45s": worst,
                                             "err_at_45s": at45}))
    ctx.note(f"fig5: Q={Qu:g} (input noise through B) and R={R:g} are the MATLAB time-varying Kalman example "
             "values the chapter says it modified; the chapter does not state its own. The model is the ZOH "
             "discretisation (Ts=0.1 s) of eq. 52; eq. 54's matrices lost their signs in the extraction and "
             "have complex poles and DC gain 2.23, inconsistent with eq. 52 (use --option model=eq54 to try).")
    ctx.note(f"fig5: C P C^T settles in {ts:.1f} s here; how fast it settles depends on the (unstated) Q, R "
             "and P0 of the chapter.")
