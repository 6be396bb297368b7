"""Cautious control (CC) and certainty equivalence control (CEC) of the PMSM
([Thesis], thesis §4.3.2-4.3.3, eqs. 4.50-4.65).

CC minimises the expected n-step loss (eq. 4.50)
    J = u_t' Gamma u_t + E sum_{k=1}^{n} (x_{t+k} - xbar_{t+k})' Xi (x_{t+k} - xbar_{t+k})
with u_t acting only at t (eq. 4.51-4.52). With the approximation of eq. 4.57 (frozen theta,
no induced voltage in the current equations) the k-step matrix is (eq. 4.58)
    Atilde^k = [[a^k, 0, 0, 0], [0, a^k, 0, 0], [-e S_k sin th, e S_k cos th, d^k, 0], [0, 0, 0, 1]],
    S_k = sum_{l=0}^{k-1} a^l d^{k-1-l} = (d^k - a^k) / (d - a)   (eq. 4.59; S_k = k for a = d).
Since Xi = diag(0, 0, 1, 0), u_t reaches omega_{t+k} through the omega row of Atilde^{k-1} C,
c e S_{k-1} (-sin th, cos th), and the free response is e S_k i_q + d^k omega. Setting the
gradient to zero (eq. 4.53) gives u_t = -(Gamma + Sigma_n)^-1 Lambda_n' (eq. 4.56, the sign
lost in the extraction restored), with

    Lambda_n = c e E[ (e i_q delta_n + omega eps_n - rho_t) (-sin th, cos th) ]     (eq. 4.60)
    Sigma_n  = gamma_n E[ (-sin th, cos th)' (-sin th, cos th) ]                    (eq. 4.61)
    gamma_n = c^2 e^2 sum_k S_{k-1}^2,  delta_n = sum_k S_{k-1} S_k,  eps_n = sum_k S_{k-1} d^k,
    rho_t = sum_k S_{k-1} omega_ref_{t+k}                                           (eqs. 4.62-4.63)

(the constants are computed offline, :func:`cc_constants`). Expectations are weighted sums over
the particles; CEC (§4.3.3) replaces the distribution by one point (mean, sample or maximum).
An action whose norm exceeds u_max is scaled to the cap (eq. 4.65). Horizon n = 80 (0.01 s).
"""
from __future__ import annotations

import math

import numpy as np
from numba.extending import register_jitable

from .pi import CP_GAMMA, CP_UMAX


def cc_constants(mp, n: int = 80):
    """(consts, S): consts = [gamma_n, delta_n, eps_n, n]; S = [S_0, ..., S_n] (eq. 4.59)."""
    a, c, d, e = float(mp[0]), float(mp[2]), float(mp[3]), float(mp[4])
    n = int(n)
    if n < 1:
        raise ValueError("horizon n must be >= 1")
    S = np.zeros(n + 1)
    for k in range(1, n + 1):          # S_k = a S_{k-1} + d^{k-1}, exact for a == d as well
        S[k] = a * S[k - 1] + d ** (k - 1)
    k = np.arange(1, n + 1)
    gamma_n = (c * e) ** 2 * np.sum(S[k - 1] ** 2)
    delta_n = np.sum(S[k - 1] * S[k])
    eps_n = np.sum(S[k - 1] * d ** k)
    return np.array([gamma_n, delta_n, eps_n, float(n)]), S


@register_jitable
def cautious_control(ia, ib, om, th, wn, w_ref, t, consts, S, mp, cp, out):
    """CC action (eq. 4.56 with 4.60-4.61) into ``out`` (2,) from weighted particles
    (om, th, wn); with a single particle of weight 1 this is CEC."""
    c = mp[2]
    e = mp[4]
    gam_n, delta_n, eps_n = consts[0], consts[1], consts[2]
    n = int(consts[3])
    M = w_ref.shape[0]
    rho = 0.0
    for k in range(1, n + 1):
        j = t + k
        if j > M - 1:
            j = M - 1
        rho += S[k - 1] * w_ref[j]
    l0 = 0.0
    l1 = 0.0
    m00 = 0.0
    m01 = 0.0
    m11 = 0.0
    for i in range(om.shape[0]):
        s = math.sin(th[i])
        co = math.cos(th[i])
        iq = ib * co - ia * s
        f = e * iq * delta_n + om[i] * eps_n - rho
        l0 += wn[i] * (-s) * f
        l1 += wn[i] * co * f
        m00 += wn[i] * s * s
        m01 += wn[i] * (-s) * co
        m11 += wn[i] * co * co
    l0 *= c * e
    l1 *= c * e
    g = cp[CP_GAMMA]
    a00 = g + gam_n * m00
    a01 = gam_n * m01
    a11 = g + gam_n * m11
    det = a00 * a11 - a01 * a01
    u0 = -(a11 * l0 - a01 * l1) / det
    u1 = -(-a01 * l0 + a00 * l1) / det
    nrm = math.sqrt(u0 * u0 + u1 * u1)
    if nrm > cp[CP_UMAX]:
        u0 *= cp[CP_UMAX] / nrm
        u1 *= cp[CP_UMAX] / nrm
    out[0] = u0
    out[1] = u1
