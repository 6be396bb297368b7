"""rtd:fig2 / rtd:fig3 / rtd:fig4 -- the identified model of [RTD] §4.1: step response to the 38 degC
input (Fig. 2), Bode diagram of the eq. 52 transfer function (Fig. 3) and model vs measured step
response (Fig. 4). The measured data of Figs. 2 and 4 are not published: only the model curves are
reproduced, and each figure says so."""
from __future__ import annotations

import numpy as np

from pfbench import plotting
from pfbench.plants import rtd
from pfbench.ranges import at_least
from pfbench.recipes import recipe
from pfbench.verdicts import SETUP, holds, not_reproducible

LOST = "measured data of [RTD] lost (not published): model curves only"
WHERE_ID = "[RTD] §4.1"


def _lost(ax):
    """The text annotation every model-only figure carries."""
    ax.text(0.5, 0.5, LOST, transform=ax.transAxes, ha="center", va="center", fontsize=11, color="0.35",
            bbox=dict(boxstyle="round", fc="lightyellow", ec="0.6"))


OPTIONS = {"t_end": (float, f"simulated time, s (default 60; at least one sample, {rtd.TS:g} s)",
                     at_least(rtd.TS))}


def _step_curves(t_end: float):
    """Eq. 52 (continuous, and ZOH at Ts) and eq. 54 (N4SID, as extracted) responses to the 38 degC step."""
    t = np.arange(0.0, t_end + 1e-9, rtd.TS)
    y52 = rtd.tf_step(t, rtd.U_STEP)
    u = np.full(t.size, rtd.U_STEP)
    y52d = rtd.identified_model().simulate(u)
    y54 = rtd.eq54_model().simulate(u)
    return t, u, y52, y52d, y54


def _is_two_real_lags(y) -> bool:
    """The computed test of 'second order, two first-order systems in series' for a step response:
    both poles of eq. 52 real and negative and the response monotone (no overshoot/oscillation)."""
    p = np.roots(rtd.TF_DEN)
    return bool(np.all(np.abs(p.imag) == 0) and np.all(p.real < 0) and np.all(np.diff(y) >= -1e-12))


@recipe("rtd:fig2", title="Identified model: step response to the 38 degC input (Fig. 2, model only)",
        quick_cost="~2 s", full_cost="~2 s", options=OPTIONS)
def fig2(ctx):
    import pandas as pd

    t, u, y52, y52d, _ = _step_curves(ctx.option("t_end", 60.0, float))
    ctx.write_table("fig2", pd.DataFrame({"t_s": t, "u_degC": u, "y_eq52": y52, "y_eq52_zoh": y52d}))
    fig, ax = plotting.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax[0].plot(t, u, "k", lw=1.2, label="input u (constant 38 degC)")
    plotting.paper_value(ax[0], rtd.U_STEP, "paper: input set to 38 degC")
    plotting.label(ax[0], "time [s]", "input [degC]")
    ax[0].legend(loc="lower right")
    ax[1].plot(t, y52, color=plotting.OURS, lw=1.5, label="eq. 52 model (continuous step response)")
    ax[1].plot(t, y52d, color=plotting.OTHER, ls="--", lw=1, label=f"eq. 52, ZOH Ts = {rtd.TS:g} s")
    plotting.label(ax[1], "time [s]", "model output [degC]")
    ax[1].legend(loc="lower right")
    _lost(ax[1])
    fig.suptitle("RTD identification: input-output model for a 38 degC step (model curves)")
    ctx.write_figure("fig2", fig)
    ctx.compare("final value of the model step response (38 x 0.1711/0.1695)", round(float(y52[-1]), 4), None,
                unit="output units", note=f"at t = {t[-1]:g} s; the slow pole -0.0701 has not fully settled")
    where = f"{WHERE_ID}, Fig. 2"
    ctx.claim("The output, the step response, is that of the second order system as can be seen in the bode plot "
              "shown in Figure 3", where, "the measured step response of the identification experiment",
              not_reproducible("the measured input-output data of the identification are not published (Figs. 2 "
                               "and 4 show them); what can be computed is the chapter's own model, shown below as "
                               "a setup check"), paper="second order")
    ctx.claim("the eq. 52 model's step response to 38 degC is that of two first-order lags in series", where,
              "model step response: two real negative poles and monotone",
              holds(_is_two_real_lags(y52), "eq. 52 has two real negative poles and its step response "
                    "to 38 degC is monotone (two first-order lags in series, as [RTD] §6 says)"),
              paper="second order", kind=SETUP, note="a property of the chapter's eq. 52, which the recipes use")


@recipe("rtd:fig3", title="Bode diagram of the eq. 52 transfer function (Fig. 3)", quick_cost="~2 s",
        full_cost="~2 s")
def fig3(ctx):
    import pandas as pd

    w, mag, phase = rtd.tf_bode()
    ctx.write_table("fig3", pd.DataFrame({"w_rad_s": w, "magnitude_dB": mag, "phase_deg": phase}))
    poles, zero = rtd.tf_poles(), float(np.roots(rtd.TF_NUM)[0])
    # high-frequency slope over the last decade, and the largest phase lag
    hi = w >= w[-1] / 10.0
    slope = float(np.polyfit(np.log10(w[hi]), mag[hi], 1)[0])
    lag = float(-phase.min())

    fig, ax = plotting.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    ax[0].semilogx(w, mag, color=plotting.OURS, lw=1.5, label="eq. 52 (ours, from the printed coefficients)")
    # reference slopes through the magnitude at the fast pole: what a first- and a second-order lag give
    w0 = -poles[0]
    m0 = float(np.interp(np.log10(w0), np.log10(w), mag))
    ww = w[w >= w0]
    ax[0].semilogx(ww, m0 - 20 * np.log10(ww / w0), color="0.5", ls=":", label="-20 dB/decade (first-order lag)")
    ax[0].semilogx(ww, m0 - 40 * np.log10(ww / w0), color="0.3", ls="-.", label="-40 dB/decade (second-order lag)")
    plotting.label(ax[0], "frequency [rad/s]", "magnitude [dB]")
    ax[1].semilogx(w, phase, color=plotting.OURS, lw=1.5, label="eq. 52 phase")
    ax[1].axhline(-180.0, color="0.3", ls="-.", lw=1, label="-180 deg (second-order lag limit)")
    plotting.label(ax[1], "frequency [rad/s]", "phase [deg]")
    for k, a in enumerate(ax):
        for j, pp in enumerate(rtd.PAPER_POLES):
            plotting.paper_value(a, -pp, "paper: poles -2.4179, -0.0701 (§6)" if (j == 0 and k == 0) else None,
                                 axis="x")
        a.axvline(-zero, color=plotting.OTHER, ls=":", lw=1, label=f"zero of eq. 52 ({zero:.4f})" if k == 0 else None)
        a.legend(loc="lower left", fontsize=7)
    ax[0].set_title("G(s) = (2.278 s + 0.1711) / (s^2 + 2.488 s + 0.1695); the paper's diagram itself is not in "
                    "the text", fontsize=9)
    ctx.write_figure("fig3", fig)

    ctx.compare("DC gain", round(float(mag[0]), 4), None, unit="dB", note="20 log10(0.1711/0.1695)")
    ctx.compare("high-frequency magnitude slope (last decade)", round(slope, 2), None, unit="dB/decade")
    ctx.compare("largest phase lag", round(lag, 2), None, unit="deg")
    ctx.compare("zero of eq. 52", round(zero, 5), None, unit="1/s",
                note=f"slow pole {poles[1]:.4f}: near pole-zero cancellation")
    where = f"{WHERE_ID}, eq. 52, Fig. 3"
    ctx.claim("Bode diagram indicating the system is a second order system as described by the system transfer "
              "function (the transfer function of eq. 52 is second order)", where,
              "denominator degree and its roots",
              holds(len(rtd.TF_DEN) - 1 == 2 and bool(np.all(np.isreal(np.roots(rtd.TF_DEN)))),
                    "the eq. 52 denominator has degree 2 with two real roots"), paper="second order", kind=SETUP,
              note="reads the degree of the chapter's own denominator: a property of the equation the recipes use, "
                   "not a result that the data could contradict")
    ctx.claim("what the Bode diagram of eq. 52 shows", where,
              "high-frequency slope of the Bode magnitude and largest phase lag",
              holds(abs(slope + 20.0) <= 2.0 and lag < 90.0,
                    f"eq. 52 has relative degree 1 (first-order numerator): its magnitude ends at -20 dB/decade "
                    f"(ours {slope:.1f}, within 2 dB/decade) and its phase lag stays below 90 deg (ours {lag:.1f})"),
              paper="second order (caption)", kind=SETUP,
              note=f"no plot of eq. 52 can show the -40 dB/decade or the 180 deg of a second-order lag: the "
                   f"numerator is first order and its zero ({zero:.4f}) nearly cancels the slow pole "
                   f"({poles[1]:.4f}); the caption's 'second order' rests on the denominator (setup check above), "
                   "so the roll-off is shown, not scored against it")


@recipe("rtd:fig4", title="Model step responses of the identified models (Fig. 4, model only)",
        quick_cost="~2 s", full_cost="~2 s", options=OPTIONS)
def fig4(ctx):
    import pandas as pd

    t, u, y52, y52d, y54 = _step_curves(ctx.option("t_end", 60.0, float))
    ctx.write_table("fig4", pd.DataFrame({"t_s": t, "u_degC": u, "y_eq52": y52, "y_eq52_zoh": y52d,
                                          "y_eq54": y54}))
    fig, ax = plotting.subplots(figsize=(8, 5))
    ax.plot(t, y52, color=plotting.OURS, lw=1.5, label="eq. 52 transfer function")
    ax.plot(t, y54, color=plotting.OTHER, ls="-.", lw=1.2,
            label=f"eq. 54 N4SID model as extracted (A21 < 0, Ts = {rtd.TS:g} s)")
    plotting.label(ax, "time [s]", "model output [degC]")
    ax.legend(loc="lower right", fontsize=8)
    _lost(ax)
    ax.set_title("RTD identified models: step responses to 38 degC (measured curve lost; paper's fit 90.27 %)")
    ctx.write_figure("fig4", fig)
    ctx.compare("eq. 52 model output at the end", round(float(y52[-1]), 3), None, note=f"t = {t[-1]:g} s")
    ctx.compare("eq. 54 model output at the end", round(float(y54[-1]), 3), None,
                note="DC gain 2.23: the extracted eq. 54 is not consistent with eq. 52 (signs lost)")
    ctx.compare("largest |eq. 52 - eq. 54| over the run", round(float(np.abs(y52d - y54).max()), 3), None)
    why = "the measured step response of the identification is not published, so the fit cannot be recomputed"
    ctx.claim("Fit to estimation data: 90.27% (prediction focus) with FPE: 0.4532 and MSE: 0.2292",
              f"{WHERE_ID}, eq. 54 and Fig. 4", "NRMSE fit, FPE and MSE of the N4SID model on the measured step "
              "response", not_reproducible(why), paper="fit 90.27 %, FPE 0.4532, MSE 0.2292",
              note="the Fig. 4 caption repeats the 90.27 %: one sentence, one finding")
