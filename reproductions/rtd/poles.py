"""rtd:poles -- poles, RC constant, DARE solution and steady-state gain ([RTD], §2.6, §4, §6)."""
from __future__ import annotations

import numpy as np

from pfbench import kalman
from pfbench.plants import rtd
from pfbench.recipes import recipe


@recipe("rtd:poles", title="RTD poles, RC fit, DARE solution and steady-state gain", quick_cost="~2 s",
        full_cost="~2 s")
def poles(ctx):
    import pandas as pd
    import scipy.linalg as sl

    rows = []

    def add(quantity, ours, paper=None, unit="", note=""):
        rows.append({"quantity": quantity, "ours": ours, "paper": paper, "unit": unit, "note": note})
        ctx.compare(quantity, ours, paper, unit=unit, note=note)

    p = rtd.tf_poles()
    add("eq. 52 pole 1 (roots of s^2 + 2.488 s + 0.1695)", round(float(p[0]), 5), rtd.PAPER_POLES[0], "1/s")
    add("eq. 52 pole 2", round(float(p[1]), 5), rtd.PAPER_POLES[1], "1/s")
    m = rtd.identified_model()
    zp = np.sort(m.poles_z.real)
    add("discrete pole 1 (ZOH, Ts = 0.1 s)", round(float(zp[0]), 5), None, "", "exp(-2.4179 Ts)")
    add("discrete pole 2 (ZOH, Ts = 0.1 s)", round(float(zp[1]), 5), None, "", "exp(-0.0701 Ts)")
    add("eq. 52 DC gain 0.1711/0.1695", round(m.dc_gain, 5), None)
    e54 = rtd.eq54_model()
    ev = e54.poles_z
    add("eq. 54 A eigenvalue modulus (sign choice A21<0)", round(float(np.abs(ev[0])), 5), None, "",
        f"eigenvalues {ev[0]:.4f}, {ev[1]:.4f}: complex, not the real poles of eq. 52")
    add("eq. 54 DC gain C (I-A)^-1 B", round(e54.dc_gain, 4), None, "", "signs lost in the extraction")

    # RC constant fitted from a simulated noisy step (the chapter gives no value)
    t, u, y_true, y = rtd.simulate_bath(seed=ctx.seed)
    up = (t >= 5.0) & (t < 65.0)
    fit = rtd.fit_rc_step(t[up], y[up], y_final=38.0, y_start=25.0, frac=(0.1, 0.9))
    add("RC time constant fitted (eqs. 55-56, simulated step 25->38 degC)", round(fit.tau, 4), None, "s",
        f"{fit.n_points} points between 10 % and 90 % of the step; fast-pole time constant 1/2.4179 = 0.414 s")

    # DARE of the filter (eq. 37) for the Fig. 5 set-up: Q = B Qu B^T, R
    Qu, R = 2.3, 1.0
    Qx = Qu * (m.B @ m.B.T)
    P_prior, P_post, M = kalman.steady_state_gain(m.A, m.C, Qx, [[R]])
    P_scipy = sl.solve_discrete_are(m.A.T, m.C.T, Qx, np.array([[R]]))
    add("DARE P_inf[0,0] (generalized Schur, Fig. 5 Q=2.3, R=1)", float(P_prior[0, 0]), None)
    add("DARE P_inf[1,1]", float(P_prior[1, 1]), None)
    add("DARE max |ours - scipy solve_discrete_are|", float(np.abs(P_prior - P_scipy).max()), None)
    add("steady-state gain M_inf[0]", float(M[0, 0]), None)
    add("steady-state gain M_inf[1]", float(M[1, 0]), None)
    add("steady-state C P[n|n] C^T", float((m.C @ P_post @ m.C.T)[0, 0]), None)
    d = rtd.simulate_fig5(n=600, Qu=Qu, R=R, seed=ctx.seed)
    add("time-varying C P C^T at the last step (Fig. 5 loop)", float(d["errcov"][-1]), None, "",
        "must equal the steady-state value above")

    # first-order RC filter: chapter's closed form vs the discrete scalar DARE
    rc = rtd.rc_model(fit.tau, gain=rtd.AMP_GAIN)
    a, b, c = rc.A[0, 0], rc.B[0, 0], rc.C[0, 0]
    q_rc, r_rc = 1.0, 1.0
    p_closed = kalman.dare_scalar(a, c, q_rc * b * b, r_rc)
    p_general = float(kalman.dare([[a]], [[c]], [[q_rc * b * b]], [[r_rc]])[0, 0])
    add("RC (C = 260): scalar DARE closed form", p_closed, None, "", "Q = 1 through B, R = 1 (counts^2)")
    add("RC (C = 260): general generalized-Schur DARE", p_general, None)
    F = -1.0 / fit.tau
    add("RC: chapter's Arduino formula (sqrt(H^2QR+F^2R^2)+FR)/H^2", kalman.chapter_riccati_scalar(F, c, q_rc, r_rc),
        None, "", "continuous-time ARE root with F=-1/tau; not the discrete DARE")
    ctx.write_table("poles", pd.DataFrame(rows))
    ctx.note("poles: the chapter prints no numbers for the DARE solution, the gain or the RC constant, so only "
             "the poles have a paper value; the chapter's Arduino Riccati formula is the continuous-time scalar "
             "ARE root, which differs from the discrete DARE it feeds into the discrete loop.")
