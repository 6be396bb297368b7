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

Guided filtering (``method="guided"``), two forms:

* ``pmsm``: the full 4-state model with the locally optimal proposal, Gaussian because the noise
  is additive and y = H x + v (eqs. 4.22-4.25, via :func:`pfbench.filters.guided.optimal_gaussian_proposal`);
* ``pmsm_reduced`` (:class:`PmsmReduced`): the model of the thesis SMC (§4.2.1), whose particles
  carry only the unobservable (omega, theta) while the measured currents stand in for the current
  states ("observed currents used directly"); its inputs carry (u_{t-1}, y_{t-1}).
"""
from __future__ import annotations

import math

import numpy as np
from numba.extending import register_jitable

from ..errors import InputError, UnsupportedError
from ..filters.guided import (optimal_gaussian_log_predictive, optimal_gaussian_params,
                              optimal_gaussian_proposal)
from . import register
from .base import LOG_2PI, StateSpaceModel, Trajectory

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


@register_jitable
def pmsm_mean(x, u, mp):
    """Noise-free map g(x, u) of eqs. 4.11-4.14 for particles ``x`` (n, 4): float64 (n, 4), theta
    *not* wrapped (the vectorised :func:`pmsm_step`)."""
    a, b, c, d, e, dt = mp[0], mp[1], mp[2], mp[3], mp[4], mp[5]
    s = np.sin(x[:, 3])
    co = np.cos(x[:, 3])
    out = np.empty((x.shape[0], 4))
    out[:, 0] = a * x[:, 0] + b * x[:, 2] * s + c * u[0]
    out[:, 1] = a * x[:, 1] - b * x[:, 2] * co + c * u[1]
    out[:, 2] = d * x[:, 2] + e * (x[:, 1] * co - x[:, 0] * s)
    out[:, 3] = x[:, 3] + dt * x[:, 2]
    return out


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

    #: method="guided": the locally optimal proposal (eqs. 4.22-4.25)
    proposal_kind = "optimal"
    n_proposal_noise = 4
    #: y = H x + v: the currents are measured (eq. 4.19)
    H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])

    def params(self):
        return (self.param_array(), np.sqrt(self.q), np.sqrt(self.r),
                optimal_gaussian_params(np.diag(self.q), self.H, np.diag(self.r)))

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
        out = pmsm_mean(x, u, p[0]) + noise * p[1]
        out[:, 3] = wrap_angles(out[:, 3])
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

    @staticmethod
    def proposal(x_prev, y, u, t, noise, p):
        """x_t ~ p(x_t | x_{t-1}, y_t) = N(m_t, S) (eqs. 4.22-4.24), theta wrapped."""
        x = optimal_gaussian_proposal(pmsm_mean(x_prev, u, p[0]), y, noise, p[3])
        x[:, 3] = wrap_angles(x[:, 3])
        return x

    @staticmethod
    def predictive_log_likelihood(y, x_prev, u, t, p):
        """log p(y_t | x_{t-1}) = log N(y_t; H g(x_{t-1}, u), R + H Q H') (eq. 4.25)."""
        return optimal_gaussian_log_predictive(pmsm_mean(x_prev, u, p[0]), y, p[3])


# --------------------------------------------------------------------------- the thesis SMC's model
#: Default inflated theta process variance of the thesis SMC (§4.2.1: "we use sigma_theta^2 = 10^-?
#: instead of true 10^-10"; the exponent was lost in the extraction). 1e-6 is std 1e-3 rad per
#: step, ~1 electrical degree over 17 steps; it is a parameter (``q_theta_filter``).
Q_THETA_FILTER = 1e-6
#: theta priors of :class:`PmsmReduced` (codes used inside ``initial``)
THETA_PRIORS = {"equidistant": 0, "uniform": 1, "gaussian": 2}


@register_jitable
def _reduced_transition(x, u, noise, p):
    """(omega, theta) step of eqs. 4.13-4.14 with the measured currents y_{t-1} = u[2:4] in place
    of i_{t-1}, the filter's process noise sqrt(q_w) z_0, sqrt(q_theta_filter) z_1; theta wrapped."""
    mp, fp = p[0], p[1]
    d, e, dt = mp[3], mp[4], mp[5]
    om = x[:, 0]
    th = x[:, 1]
    s = np.sin(th)
    co = np.cos(th)
    out = np.empty((x.shape[0], 2))
    out[:, 0] = d * om + e * (u[3] * co - u[2] * s) + fp[0] * noise[:, 0]
    out[:, 1] = wrap_angles(th + dt * om + fp[1] * noise[:, 1])
    return out


@register("pmsm_reduced")
class PmsmReduced(StateSpaceModel):
    """The model of the thesis SMC ([Thesis] §4.2.1, Table 4.2), for ``method="guided"``.

    The particles carry only the unobservable x_t = (omega_t, theta_t); the currents are the
    measured ones ("observed currents used directly"), so with inputs
    u_t = (u_alpha_{t-1}, u_beta_{t-1}, y_alpha_{t-1}, y_beta_{t-1})::

        omega_t = d omega_{t-1} + e (y_beta_{t-1} cos theta_{t-1} - y_alpha_{t-1} sin theta_{t-1}) + w_w
        theta_t = wrap(theta_{t-1} + dt omega_{t-1} + w_th),  w_th ~ N(0, q_theta_filter)
        y_t     = a y_{t-1} + b omega_{t-1} (sin, -cos)(theta_{t-1}) + c u_{t-1} + w_i + v

    y_t depends on x_{t-1} only, and (w_i, v) are independent of (w_w, w_th), so the locally optimal
    proposal p(x_t | x_{t-1}, y_t) is the transition above and its weight is
    p(y_t | x_{t-1}) = N(y_t; a y_{t-1} + b omega (sin, -cos) theta + c u_{t-1}, R + diag(Q_ia, Q_ib))
    (eq. 4.25 with H having zero columns for (omega, theta)). There is no p(y_t | x_t), so this
    model runs ``method="guided"`` only (the other methods raise UnsupportedError).

    Parameters
    ----------
    q_theta_filter : the filter's (inflated) theta process variance (default :data:`Q_THETA_FILTER`).
    theta_prior : ``equidistant`` (theta_i = -pi + 2 pi (i + 1/2) / N, thesis §4.4.4), ``uniform``
        (U(-pi, pi)) or ``gaussian`` (N(theta_mu, theta_sd^2), wrapped; used for Fig. 4.6).
        omega ~ U(-h, h) with h the plant's ``prior_halfwidth``; draw order: N uniforms for omega,
        then N uniforms (uniform) or N normals (gaussian) for theta.
    theta_mu, theta_sd : the Gaussian prior's mean and standard deviation.
    **pmsm : parameters of the plant :class:`Pmsm` (a, ..., q, r, prior_halfwidth, ...).
    """

    n_x, n_y, n_u, n_noise = 2, 2, 4, 2
    state_names = ("omega", "theta")
    proposal_kind = "optimal"
    n_proposal_noise = 2

    def __init__(self, q_theta_filter=Q_THETA_FILTER, theta_prior="equidistant", theta_mu=0.0,
                 theta_sd=1.0, **pmsm):
        if theta_prior not in THETA_PRIORS:
            raise InputError(f"unknown theta_prior {theta_prior!r}; choose one of {', '.join(THETA_PRIORS)}")
        if not float(q_theta_filter) >= 0.0 or not float(theta_sd) >= 0.0:
            raise InputError("q_theta_filter and theta_sd must be >= 0")
        self.pmsm = Pmsm(**pmsm)
        self.q_theta_filter = float(q_theta_filter)
        self.theta_prior = theta_prior
        self.theta_mu = float(theta_mu)
        self.theta_sd = float(theta_sd)

    def params(self):
        """(plant parameter array (:meth:`Pmsm.param_array`), filter array [sqrt(q_w),
        sqrt(q_theta_filter), r_a + q_ia, r_b + q_ib, theta prior code, theta_mu, theta_sd])."""
        m = self.pmsm
        fp = np.array([np.sqrt(m.q[2]), np.sqrt(self.q_theta_filter), m.r[0] + m.q[0], m.r[1] + m.q[1],
                       THETA_PRIORS[self.theta_prior], self.theta_mu, self.theta_sd])
        return (m.param_array(), fp)

    @staticmethod
    def reduce(y, u):
        """Data of the full model (y (M, 2), ``Pmsm.simulate`` inputs u (M, 2) with
        x_t = g(x_{t-1}, u[t])) as data of this model: (y[1:], inputs (M-1, 4)), row k =
        (u[k+1], y[k]); the estimates then belong to steps 1..M-1."""
        y = np.asarray(y, dtype=np.float64)
        u = np.asarray(u, dtype=np.float64)
        if y.ndim != 2 or y.shape[1] != 2 or u.shape != y.shape or y.shape[0] < 2:
            raise InputError(f"y and u must both have shape (M >= 2, 2), got {y.shape} and {u.shape}")
        return y[1:].copy(), np.ascontiguousarray(np.hstack([u[1:], y[:-1]]))

    def simulate(self, n_steps, seed=0):
        """Simulate the full plant (:meth:`Pmsm.simulate`, n_steps + 1 steps) and reduce it: x are
        the true (omega, theta) of steps 1..n_steps, x0 those of step 0 (see :meth:`reduce`)."""
        tr = self.pmsm.simulate(int(n_steps) + 1, seed=seed)
        y, u = self.reduce(tr.y, tr.u)
        return Trajectory(x=tr.x[1:, 2:].copy(), y=y, u=u, x0=tr.x[0, 2:].copy())

    @staticmethod
    def initial(rng, n, p):
        mp, fp = p[0], p[1]
        x = np.empty((n, 2))
        z = rng.random(n)
        x[:, 0] = mp[13] * (2.0 * z - 1.0)
        mode = int(fp[4])
        if mode == 0:
            x[:, 1] = -np.pi + 2.0 * np.pi * (np.arange(n) + 0.5) / n
        elif mode == 1:
            z2 = rng.random(n)
            x[:, 1] = np.pi * (2.0 * z2 - 1.0)
        else:
            z2 = rng.standard_normal(n)
            x[:, 1] = wrap_angles(fp[5] + fp[6] * z2)
        return x

    @staticmethod
    def transition(x, u, t, noise, p):
        return _reduced_transition(x, u, noise, p)

    @staticmethod
    def proposal(x_prev, y, u, t, noise, p):
        """The locally optimal proposal = the transition (see the class docstring)."""
        return _reduced_transition(x_prev, u, noise, p)

    @staticmethod
    def predictive_log_likelihood(y, x_prev, u, t, p):
        """log p(y_t | x_{t-1}) (eq. 4.25 for the reduced state; see the class docstring)."""
        mp, fp = p[0], p[1]
        a, b, c = mp[0], mp[1], mp[2]
        va, vb = fp[2], fp[3]
        s = np.sin(x_prev[:, 1])
        co = np.cos(x_prev[:, 1])
        ra = y[0] - (a * u[2] + b * x_prev[:, 0] * s + c * u[0])
        rb = y[1] - (a * u[3] - b * x_prev[:, 0] * co + c * u[1])
        const = -0.5 * (2.0 * LOG_2PI + np.log(va) + np.log(vb))
        return const - 0.5 * (ra * ra / va + rb * rb / vb)

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        """Not defined: y_t depends on x_{t-1}, not on x_t (use method="guided")."""
        if x.shape[0] >= 0:  # always; keeps the return type an array for numba
            raise UnsupportedError("pmsm_reduced has no p(y_t | x_t) (y_t depends on x_{t-1}); "
                                   "use method='guided'")
        return np.zeros(x.shape[0])

    @staticmethod
    def observe(x, u, t, noise, p):
        """Not defined (y_t depends on x_{t-1}); :meth:`simulate` simulates the full plant."""
        if x.shape[0] >= 0:
            raise UnsupportedError("pmsm_reduced cannot simulate measurements from (omega, theta); "
                                   "use PmsmReduced.simulate (full plant, reduced)")
        return np.zeros((x.shape[0], 2))
