"""Ob4: two states with a known random input ([MultiPDF] §4).

    x_1^(k+1) = 0.5 (x_1^2)^(1/3) + 0.01 x_2 + 0.2 u + v_1
    x_2^(k+1) = 0.5 (x_2^2)^(1/3) + 0.01 x_1 + 0.2 u + v_2,      v ~ N(0, 1)
    y_1 = 2 x_1^2 + 0.004 x_2 + n_1,  y_2 = 2 x_2^2 + 0.004 x_1 + n_2,   n ~ N(0, 1)
    u ~ U[-1, 1] (known to the filter), x^(0) = [0.1, 0.1].

Choice: the paper writes one symbol v (and n) for both rows; we read them as independent
draws per component (``shared_noise=False``); ``shared_noise=True`` uses one draw for both.
"""
from __future__ import annotations

import numpy as np

from . import register
from numba.extending import register_jitable

from .base import StateSpaceModel, gaussian_loglik_diag


@register_jitable
def ob4_h(x):
    """Noise-free outputs y1 = 2 x1^2 + 0.004 x2, y2 = 2 x2^2 + 0.004 x1."""
    x1 = x[:, 0]
    x2 = x[:, 1]
    h = np.empty((x.shape[0], 2))
    h[:, 0] = 2.0 * x1 * x1 + 0.004 * x2
    h[:, 1] = 2.0 * x2 * x2 + 0.004 * x1
    return h


@register("ob4")
class Ob4(StateSpaceModel):
    n_x, n_y, n_u, n_noise = 2, 2, 1, 2
    state_names = ("x1", "x2")

    def __init__(self, q: float = 1.0, r: float = 1.0, shared_noise: bool = False,
                 x0=(0.1, 0.1)):
        if q <= 0 or r <= 0:
            raise ValueError("variances q and r must be positive")
        self.q, self.r, self.shared = float(q), float(r), bool(shared_noise)
        self.x0 = np.asarray(x0, dtype=np.float64)

    def params(self):
        return (np.sqrt(self.q), np.full(2, self.r), int(self.shared), self.x0)

    def inputs(self, rng, n_steps):
        return rng.uniform(-1.0, 1.0, (n_steps, 1))

    @staticmethod
    def initial(rng, n, p):
        out = np.empty((n, 2))
        out[:, 0] = p[3][0]
        out[:, 1] = p[3][1]
        return out

    @staticmethod
    def transition(x, u, t, noise, p):
        x1 = x[:, 0]
        x2 = x[:, 1]
        out = np.empty_like(x)
        v2 = noise[:, 0] if p[2] else noise[:, 1]
        out[:, 0] = 0.5 * np.cbrt(x1 * x1) + 0.01 * x2 + 0.2 * u[0] + p[0] * noise[:, 0]
        out[:, 1] = 0.5 * np.cbrt(x2 * x2) + 0.01 * x1 + 0.2 * u[0] + p[0] * v2
        return out

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        return gaussian_loglik_diag(y - ob4_h(x), p[1])

    @staticmethod
    def observe(x, u, t, noise, p):
        return ob4_h(x) + np.sqrt(p[1]) * noise
