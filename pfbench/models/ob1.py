"""Ob1: the univariate nonstationary growth model ([Embedded] eq. 6 = [MultiPDF] Ob1).

    x^(k+1) = 0.5 x^(k) + 25 x^(k) / (1 + x^(k)^2) + 8 cos(1.2 k) + v^(k),   v ~ N(0, 10)
    y^(k)   = x^(k)^2 / 20 + n^(k),                                           n ~ N(0, 1)
    x^(0)   = 0.1

``N(0; 10)`` in the papers is read as variance 10 (the usual form of this benchmark).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import register
from .base import LOG_2PI, StateSpaceModel


@register("ob1")
class Ob1(StateSpaceModel):
    """Ob1 ([MultiPDF] §4; [Embedded] eq. 6). Parameters: ``q`` = var(v), ``r`` = var(n), ``x0``."""

    n_x, n_y, n_u, n_noise = 1, 1, 0, 1
    state_names = ("x",)

    def __init__(self, q: float = 10.0, r: float = 1.0, x0: float = 0.1):
        if q <= 0 or r <= 0:
            raise InputError("variances q and r must be positive")
        self.q, self.r, self.x0 = float(q), float(r), float(x0)

    def params(self):
        return (np.sqrt(self.q), self.r, self.x0)

    @staticmethod
    def initial(rng, n, p):
        return np.full((n, 1), p[2])

    @staticmethod
    def transition(x, u, t, noise, p):
        return 0.5 * x + 25.0 * x / (1.0 + x * x) + 8.0 * np.cos(1.2 * t) + p[0] * noise

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        xx = x[:, 0]
        r = y[0] - xx * xx / 20.0
        return -0.5 * r * r / p[1] - 0.5 * (LOG_2PI + np.log(p[1]))

    @staticmethod
    def observe(x, u, t, noise, p):
        return x * x / 20.0 + np.sqrt(p[1]) * noise
