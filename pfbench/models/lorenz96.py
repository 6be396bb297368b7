"""Lorenz-96 ([Lorenz1996]) with additive noise, a high-dimensional benchmark on which bootstrap
particle filters collapse (their weights degenerate as the dimension d grows, [Snyder2008])::

    dx_i/dt = (x_{i+1} - x_{i-2}) x_{i-1} - x_i + F        (indices mod d)
    x_t = RK4_dt(x_{t-1}) + sqrt(q) w_t,   w_t ~ N(0, I_d)   (one classical RK4 step of length dt)
    y_t = x_t[0::stride] + e_t,            e_t ~ N(0, r I)
    x^(0) ~ N(m0, s0^2 I_d)

Defaults: d = 20, F = 8 (chaotic), dt = 0.05, q = 0.01, r = 1, stride = 1 (every component
observed), m0 = 0, s0 = 2 (a broad prior, not the climatology).
"""
from __future__ import annotations

import numpy as np
from numba.extending import register_jitable

from ..errors import InputError
from . import register
from .base import LOG_2PI, StateSpaceModel


@register_jitable
def lorenz96_rhs(x, F):
    """The Lorenz-96 vector field per particle, for x (n, d)."""
    d = x.shape[1]
    out = np.empty_like(x)
    for i in range(d):
        out[:, i] = (x[:, (i + 1) % d] - x[:, (i - 2) % d]) * x[:, (i - 1) % d] - x[:, i] + F
    return out


@register("lorenz96")
class Lorenz96(StateSpaceModel):
    """Parameters ``d`` (dimension, >= 4), ``F``, ``dt``, ``q``, ``r``, ``stride`` (observe every
    stride-th component), ``m0``, ``s0``."""

    n_u = 0

    def __init__(self, d: int = 20, F: float = 8.0, dt: float = 0.05, q: float = 0.01,
                 r: float = 1.0, stride: int = 1, m0: float = 0.0, s0: float = 2.0):
        if int(d) < 4 or int(stride) < 1 or int(stride) > int(d):
            raise InputError("lorenz96 needs d >= 4 and 1 <= stride <= d")
        if dt <= 0 or q <= 0 or r <= 0 or s0 < 0:
            raise InputError("lorenz96 needs dt, q, r > 0 and s0 >= 0")
        self.d, self.F, self.dt, self.q, self.r = int(d), float(F), float(dt), float(q), float(r)
        self.stride, self.m0, self.s0 = int(stride), float(m0), float(s0)
        self.n_x = self.n_noise = self.d
        self.n_y = len(range(0, self.d, self.stride))

    def params(self):
        return (self.F, self.dt, np.sqrt(self.q), self.r, self.stride, self.m0, self.s0, self.d)

    @staticmethod
    def initial(rng, n, p):
        return p[5] + p[6] * rng.standard_normal((n, p[7]))

    @staticmethod
    def transition(x, u, t, noise, p):
        F, dt = p[0], p[1]
        k1 = lorenz96_rhs(x, F)
        k2 = lorenz96_rhs(x + 0.5 * dt * k1, F)
        k3 = lorenz96_rhs(x + 0.5 * dt * k2, F)
        k4 = lorenz96_rhs(x + dt * k3, F)
        return x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4) + p[2] * noise

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        out = np.zeros(x.shape[0])
        s = p[4]
        for k in range(y.shape[0]):
            r = y[k] - x[:, k * s]
            out += r * r
        return -0.5 * out / p[3] - 0.5 * y.shape[0] * (LOG_2PI + np.log(p[3]))

    @staticmethod
    def observe(x, u, t, noise, p):
        s = p[4]
        m = noise.shape[1]
        out = np.empty((x.shape[0], m))
        for k in range(m):
            out[:, k] = x[:, k * s] + np.sqrt(p[3]) * noise[:, k]
        return out
