"""Ob2: five states, fifteen outputs ([MultiPDF] §4).

    x_i^(k+1) = 0.5 x_i^(k) + v_i,                                       v_i ~ N(0, 1)
    y_i      = 4 x_i + x_{i+1} / (1 + x_{i+2}^2) + 0.2 sin(x_{i+2} x_{i+3}) + n_i,   var 6
    y_{i+5}  = 4 x_i + x_{i+1} / (1 + x_{i+2}^2) + n_{i+5},                          var 4
    y_{i+10} = 2 x_i + 0.5 (x_{i+1} + x_{i+2}) + n_{i+10},                           var 1
    indices cyclic (x_i = x_{i+5}); x^(0) = 0.
"""
from __future__ import annotations

import numpy as np

from . import register
from numba.extending import register_jitable

from .base import (StateSpaceModel, central_difference_points, difference_column, gaussian_loglik_diag,
                   scaled_identities)


@register_jitable
def ob2_h(x):
    """Noise-free measurement function of Ob2, (n, 5) -> (n, 15)."""
    n = x.shape[0]
    h = np.empty((n, 15))
    for i in range(5):
        x1 = x[:, i]
        x2 = x[:, (i + 1) % 5]
        x3 = x[:, (i + 2) % 5]
        x4 = x[:, (i + 3) % 5]
        common = 4.0 * x1 + x2 / (1.0 + x3 * x3)
        h[:, i] = common + 0.2 * np.sin(x3 * x4)
        h[:, i + 5] = common
        h[:, i + 10] = 2.0 * x1 + 0.5 * (x2 + x3)
    return h


@register("ob2")
class Ob2(StateSpaceModel):
    n_x, n_y, n_u, n_noise = 5, 15, 0, 5
    state_names = tuple(f"x{i}" for i in range(1, 6))

    def __init__(self, q: float = 1.0, r=(6.0, 4.0, 1.0), a: float = 0.5):
        r = np.asarray(r, dtype=np.float64)
        if q <= 0 or r.shape != (3,) or np.any(r <= 0):
            raise ValueError("ob2 needs a variance q > 0 and three variances r > 0 (one per group of five outputs)")
        self.q, self.a = float(q), float(a)
        self.r = np.repeat(r, 5)

    def params(self):
        return (np.sqrt(self.q), self.r, self.a)

    @staticmethod
    def initial(rng, n, p):
        return np.zeros((n, 5))

    @staticmethod
    def transition(x, u, t, noise, p):
        return p[2] * x + p[0] * noise

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        return gaussian_loglik_diag(y - ob2_h(x), p[1])

    @staticmethod
    def observe(x, u, t, noise, p):
        return ob2_h(x) + np.sqrt(p[1]) * noise

    # ----- linear-Gaussian structure (method="mpf"/"kalman"): every state is linear ---------
    #: x_t = a x_{t-1} + v is linear in every state, so the MPF is one EKF copy ([MultiPDF] §5)
    linear_states = (0, 1, 2, 3, 4)

    @staticmethod
    def cl_transition(xn, u, t, p):
        n = xn.shape[0]
        return np.zeros((n, 0)), np.zeros((n, 0, 5)), np.zeros((n, 5)), scaled_identities(n, 5, p[2])

    @staticmethod
    def cl_observation(xn, xl, u, t, p):
        """h at ``xl`` and its Jacobian by central differences (the EKF of [MultiPDF] §5)."""
        C = np.empty((xl.shape[0], 15, 5))
        for a in range(5):
            xp, xm, two_eps = central_difference_points(xl, a)
            difference_column(C, a, ob2_h(xp), ob2_h(xm), two_eps)
        return ob2_h(xl), C

    def cl_noise(self):
        return self.q * np.eye(5), np.diag(self.r)

    def cl_prior(self):
        return np.zeros(5), np.zeros((5, 5))  # x^(0) = 0 exactly
