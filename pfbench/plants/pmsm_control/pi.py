"""PI control of the PMSM in the d-q frame ([Thesis], thesis §4.3.1, eqs. 4.27-4.39).

    i_d = i_a cos th + i_b sin th,  i_q = i_b cos th - i_a sin th            (4.27-4.28)
    i_q_ref = PI(w_ref - w, P_w, I_w)                                       (4.29)
    PI(e, P, I) = P e + I (S_{t-1} + e),  S_t = S_{t-1} + e                 (4.30-4.31)
    u_d = PI(-i_d, P_u, I_u),  u_q = PI(i_q_ref - i_q, P_u, I_u)            (4.32-4.33)
    u_d -= L_s w i_q,  u_q += psi_pm w                                      (4.34-4.35)
    u_a = |U| cos(phi), u_b = |U| sin(phi), |U| = sqrt(u_d^2 + u_q^2),
    phi = atan2(u_q, u_d) + th  (eq. 4.38 written with the quadrant fix), |U| capped at u_max.

Gains (eq. 4.39): P_w = 3, I_w = 0.00375, P_u = 20, I_u = 0.5. L_s = dt / c and
psi_pm = b / c are the physical constants implied by Table 4.1 (see :mod:`pfbench.models.pmsm`).
The controller sees the measured currents and the estimated (omega, theta).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba.extending import register_jitable

# controller parameter array layout (``cp``)
CP_PW, CP_IW, CP_PU, CP_IU, CP_LS, CP_PSI, CP_UMAX, CP_GAMMA = range(8)
CP_SIZE = 8


@dataclass
class PIGains:
    """PI gains of eq. 4.39 and the voltage cap; ``gamma`` is the input weight of the loss
    (eq. 4.16-4.17, also used by the cautious controller)."""

    p_omega: float = 3.0
    i_omega: float = 0.00375
    p_u: float = 20.0
    i_u: float = 0.5
    u_max: float = 10.0
    gamma: float = 0.1

    def array(self, model) -> np.ndarray:
        cp = np.zeros(CP_SIZE)
        cp[CP_PW], cp[CP_IW], cp[CP_PU], cp[CP_IU] = self.p_omega, self.i_omega, self.p_u, self.i_u
        cp[CP_LS] = model.inductance
        cp[CP_PSI] = model.flux
        cp[CP_UMAX] = self.u_max
        cp[CP_GAMMA] = self.gamma
        return cp


@register_jitable
def pi_update(e, p, i, s_prev):
    """Eqs. 4.30-4.31: returns (P e + I (S_{t-1} + e), S_t)."""
    s = s_prev + e
    return p * e + i * s, s


@register_jitable
def pi_dq_control(ia, ib, w, th, w_ref, integ, cp, out):
    """PI voltages (u_a, u_b) into ``out`` (2,); ``integ`` (3,) = sums S of the three PIs."""
    co = math.cos(th)
    s = math.sin(th)
    i_d = ia * co + ib * s
    i_q = ib * co - ia * s
    iq_ref, integ[0] = pi_update(w_ref - w, cp[CP_PW], cp[CP_IW], integ[0])
    u_d, integ[1] = pi_update(-i_d, cp[CP_PU], cp[CP_IU], integ[1])
    u_q, integ[2] = pi_update(iq_ref - i_q, cp[CP_PU], cp[CP_IU], integ[2])
    u_d = u_d - cp[CP_LS] * w * i_q
    u_q = u_q + cp[CP_PSI] * w
    mag = math.sqrt(u_d * u_d + u_q * u_q)
    phi = math.atan2(u_q, u_d) + th
    if mag > cp[CP_UMAX]:
        mag = cp[CP_UMAX]
    out[0] = mag * math.cos(phi)
    out[1] = mag * math.sin(phi)
