"""Permanent magnet synchronous motor (PMSM) drive, [Thesis] §4.1.

Simplified discrete model (thesis eqs. 4.11-4.14, Euler discretisation of eqs. 4.1-4.4)::

    i_a[t+1] = a i_a[t] + b w[t] sin(th[t]) + c u_a[t]
    i_b[t+1] = a i_b[t] - b w[t] cos(th[t]) + c u_b[t]
    w[t+1]   = d w[t] + e (i_b[t] cos(th[t]) - i_a[t] sin(th[t]))
    th[t+1]  = th[t] + dt w[t]                   (wrapped to (-pi, pi])

plus w ~ N(0, Q) (eq. 4.18) and observed currents y = H x + v, v ~ N(0, R) (eq. 4.19).
State x = (i_alpha, i_beta, omega, theta); inputs u = (u_alpha, u_beta).

Parameters (thesis Table 4.1, eq. 4.20-4.21 as recovered in [Recovered]):
a = 0.9898, b = 0.0072, c = 0.0361, d = 1, e = 0.0149, dt = 125 us,
Q = diag(0.0013, 0.0013, 5e-6, 1e-10), R = diag(0.0006, 0.0006).

Prior (thesis §4.4.1): i_a, i_b, omega ~ U(-0.01, 0.01), theta ~ U(-pi, pi).

Voltage cap: eq. 4.15 reads ||u|| <= 100, but §4.3.1 (and eq. 4.65) cap |U| at 10. The cap
``u_max`` is a parameter; the default 10 is the reading that reproduces the thesis figures
(Fig. 4.1 shows currents of a few amperes; with a cap of 100 the PI controller would drive
stationary currents of ~350 A).

Physical constants derived from Table 4.1 for the PI compensation (eqs. 4.34-4.35), in the
units of the simplified model: L_s = dt / c (inductance), psi_pm = b / c (PM flux), since
c = dt/L_s and b = psi_pm dt / L_s.
"""
from __future__ import annotations

import math

import numpy as np
from numba.extending import register_jitable

from . import register
from .base import LOG_2PI, StateSpaceModel

#: Table 4.1 / eqs. 4.20-4.21 ([Recovered])
PMSM_DEFAULTS = dict(a=0.9898, b=0.0072, c=0.0361, d=1.0, e=0.0149, dt=125e-6,
                     q=(0.0013, 0.0013, 5e-6, 1e-10), r=(0.0006, 0.0006), u_max=10.0,
                     prior_halfwidth=0.01)


@register_jitable
def wrap_angle(th):
    """Wrap an angle (scalar) to (-pi, pi]."""
    return th - 2.0 * math.pi * math.ceil((th - math.pi) / (2.0 * math.pi))


@register_jitable
def wrap_angles(th):
    """Wrap an array of angles to (-pi, pi] (vectorised :func:`wrap_angle`)."""
    return th - 2.0 * np.pi * np.ceil((th - np.pi) / (2.0 * np.pi))


@register_jitable
def pmsm_step(x, u, mp, out):
    """Noise-free one-step map g(x, u) of eqs. 4.11-4.14 for one state (scalars, libm math).

    ``mp`` = model parameter array (see :meth:`Pmsm.param_array`); writes into ``out`` (4,).
    theta is *not* wrapped here.
    """
    a, b, c, d, e, dt = mp[0], mp[1], mp[2], mp[3], mp[4], mp[5]
    s = math.sin(x[3])
    co = math.cos(x[3])
    ia, ib, w, th = x[0], x[1], x[2], x[3]
    out[0] = a * ia + b * w * s + c * u[0]
    out[1] = a * ib - b * w * co + c * u[1]
    out[2] = d * w + e * (ib * co - ia * s)
    out[3] = th + dt * w


def jacobian(x, mp) -> np.ndarray:
    """EKF Jacobian A_t = dg/dx at x (thesis eq. 4.26)."""
    a, b, d, e, dt = mp[0], mp[1], mp[3], mp[4], mp[5]
    ia, ib, w, th = (float(v) for v in x[:4])
    s, co = math.sin(th), math.cos(th)
    return np.array([
        [a, 0.0, b * s, b * w * co],
        [0.0, a, -b * co, b * w * s],
        [-e * s, e * co, d, -e * (ia * co + ib * s)],
        [0.0, 0.0, dt, 1.0],
    ])


@register("pmsm")
class Pmsm(StateSpaceModel):
    """PMSM drive in the stationary frame ([Thesis] eqs. 4.11-4.21); see the module docstring.

    Parameters
    ----------
    a, b, c, d, e, dt : Table 4.1 substitutions.
    q : diagonal of Q (eq. 4.20), r : diagonal of R (eq. 4.21).
    u_max : voltage norm cap (|U| <= u_max; default 10, §4.3.1).
    prior_halfwidth : half-width of the uniform prior of the currents and the speed (0.01).
    open_loop_amplitude, open_loop_frequency : the open-loop input of :meth:`inputs` (a rotating
        voltage vector of this amplitude and electrical frequency in Hz) used by ``simulate``.
    """

    n_x, n_y, n_u, n_noise = 4, 2, 2, 4
    state_names = ("i_alpha", "i_beta", "omega", "theta")

    def __init__(self, a=0.9898, b=0.0072, c=0.0361, d=1.0, e=0.0149, dt=125e-6,
                 q=(0.0013, 0.0013, 5e-6, 1e-10), r=(0.0006, 0.0006), u_max=10.0,
                 prior_halfwidth=0.01, open_loop_amplitude=2.0, open_loop_frequency=2.0):
        self.a, self.b, self.c, self.d, self.e, self.dt = (float(v) for v in (a, b, c, d, e, dt))
        self.q = np.asarray(q, dtype=np.float64).reshape(4)
        self.r = np.asarray(r, dtype=np.float64).reshape(2)
        if (self.q < 0).any() or (self.r <= 0).any() or self.dt <= 0:
            raise ValueError("q must be >= 0, r > 0 and dt > 0")
        self.u_max = float(u_max)
        self.prior_halfwidth = float(prior_halfwidth)
        self.open_loop_amplitude = float(open_loop_amplitude)
        self.open_loop_frequency = float(open_loop_frequency)

    # derived physical constants for the PI compensation (eqs. 4.34-4.35)
    @property
    def inductance(self) -> float:
        return self.dt / self.c

    @property
    def flux(self) -> float:
        return self.b / self.c

    def param_array(self) -> np.ndarray:
        """Flat float64 array used by the closed-loop kernels:
        [a, b, c, d, e, dt, q_ia, q_ib, q_w, q_th, r_a, r_b, u_max, prior_halfwidth]."""
        return np.array([self.a, self.b, self.c, self.d, self.e, self.dt, *self.q, *self.r,
                         self.u_max, self.prior_halfwidth])

    def params(self):
        return (self.param_array(), np.sqrt(self.q), np.sqrt(self.r))

    def inputs(self, rng, n_steps):
        t = np.arange(n_steps) * self.dt
        ph = 2 * np.pi * self.open_loop_frequency * t
        return self.open_loop_amplitude * np.column_stack([np.cos(ph), np.sin(ph)])

    @staticmethod
    def initial(rng, n, p):
        mp = p[0]
        hw = mp[13]
        x = np.empty((n, 4))
        z = rng.random((n, 4))
        x[:, 0] = hw * (2.0 * z[:, 0] - 1.0)
        x[:, 1] = hw * (2.0 * z[:, 1] - 1.0)
        x[:, 2] = hw * (2.0 * z[:, 2] - 1.0)
        x[:, 3] = np.pi * (2.0 * z[:, 3] - 1.0)
        return x

    @staticmethod
    def transition(x, u, t, noise, p):
        mp, sq = p[0], p[1]
        a, b, c, d, e, dt = mp[0], mp[1], mp[2], mp[3], mp[4], mp[5]
        s = np.sin(x[:, 3])
        co = np.cos(x[:, 3])
        out = np.empty_like(x)
        out[:, 0] = a * x[:, 0] + b * x[:, 2] * s + c * u[0] + sq[0] * noise[:, 0]
        out[:, 1] = a * x[:, 1] - b * x[:, 2] * co + c * u[1] + sq[1] * noise[:, 1]
        out[:, 2] = d * x[:, 2] + e * (x[:, 1] * co - x[:, 0] * s) + sq[2] * noise[:, 2]
        out[:, 3] = wrap_angles(x[:, 3] + dt * x[:, 2] + sq[3] * noise[:, 3])
        return out

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        mp = p[0]
        ra, rb = mp[10], mp[11]
        r0 = y[0] - x[:, 0]
        r1 = y[1] - x[:, 1]
        return (-0.5 * (r0 * r0 / ra + r1 * r1 / rb)
                - 0.5 * (2.0 * LOG_2PI + np.log(ra) + np.log(rb)))

    @staticmethod
    def observe(x, u, t, noise, p):
        sr = p[2]
        out = np.empty((x.shape[0], 2))
        out[:, 0] = x[:, 0] + sr[0] * noise[:, 0]
        out[:, 1] = x[:, 1] + sr[1] * noise[:, 1]
        return out
