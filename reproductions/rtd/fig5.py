"""rtd:fig5 -- time-varying Kalman filter on the simulated second-order RTD ([RTD], §4.2.1, §5, Fig. 5)."""
from __future__ import annotations

import numpy as np

from pfbench.plants import rtd
from pfbench.errors import InputError
from pfbench.recipes import recipe


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
    late = t >= 45.0
    if not late.any():
        raise InputError("option n too small: the run must last at least 45 s")
    k45 = int(np.argmax(late))
    ctx.compare("C P C^T steady (within 1 %) after", round(ts, 2), 8.0, unit="s",
                note="chapter: 'predict the state after approximately 8 seconds'")
    ctx.compare("estimation error at t = 45 s", round(float(est_err[k45]), 4), -0.0948, unit="degC",
                note="one noisy realisation; chapter's 'best case'")
    ctx.compare("max |estimation error| for t >= 45 s", round(float(np.abs(est_err[late]).max()), 3), 1.0,
                unit="degC", note="chapter: 'less than 1 degC in the worst case' (a bound)")
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
    ctx.compare(f"runs with max |est. error| < 1 degC after 45 s ({n_mc} runs)",
                round(float(np.mean(worst < 1.0)), 3), None, unit="fraction")
    ctx.compare("sd of the error at 45 s over runs", round(float(at45.std(ddof=1)), 4), None, unit="degC",
                note="sqrt(steady C P C^T) is the theoretical value")
    ctx.write_table("fig5_mc", pd.DataFrame({"run": np.arange(n_mc), "max_abs_err_after_45s": worst,
                                             "err_at_45s": at45}))
    ctx.note(f"fig5: Q={Qu:g} (input noise through B) and R={R:g} are the MATLAB time-varying Kalman example "
             "values the chapter says it modified; the chapter does not state its own. The model is the ZOH "
             "discretisation (Ts=0.1 s) of eq. 52; eq. 54's matrices lost their signs in the extraction and "
             "have complex poles and DC gain 2.23, inconsistent with eq. 52 (use --option model=eq54 to try).")
    if ts < 4.0:
        ctx.note(f"fig5: C P C^T converges in {ts:.1f} s here, not ~8 s: with these Q, R the filter's "
                 "covariance settles within a few samples; the chapter's 8 s likely reflects its (unstated) "
                 "Q/R and model, or the estimate (not the covariance) settling.")
