"""Bearings-only tracking ([Gordon1993] §4.2), the example of the paper that introduced the
bootstrap filter: a target moving at near-constant velocity in the plane, seen from an observer
at the origin through its bearing only::

    x = (p_x, v_x, p_y, v_y);   x_t = F x_{t-1} + G w_t,   w_t ~ N(0, q I_2)
    F = [[1,1,0,0],[0,1,0,0],[0,0,1,1],[0,0,0,1]],  G = [[0.5,0],[1,0],[0,0.5],[0,1]]
    y_t = atan2(p_y, p_x) + e_t,   e_t ~ N(0, r)
    x^(0) ~ N(m0, diag(s0^2))

Defaults from [Gordon1993]: sqrt(q) = 0.001, sqrt(r) = 0.005, m0 = (-0.05, 0.001, 0.7, -0.055),
s0 = (0.5, 0.005, 0.3, 0.01) (the paper's prior standard deviations around the initial state;
here m0 is also the prior mean). The bearing residual is wrapped to (-pi, pi].
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import register
from .base import LOG_2PI, StateSpaceModel


@register("bearings_only")
class BearingsOnly(StateSpaceModel):
    """Parameters ``q``, ``r`` (variances of w and e), ``m0`` and ``s0`` (prior mean and sds, 4 each)."""

    n_x, n_y, n_u, n_noise = 4, 1, 0, 2
    state_names = ("p_x", "v_x", "p_y", "v_y")

    def __init__(self, q: float = 1e-6, r: float = 2.5e-5, m0=(-0.05, 0.001, 0.7, -0.055),
                 s0=(0.5, 0.005, 0.3, 0.01)):
        if q <= 0 or r <= 0:
            raise InputError("bearings_only needs variances q > 0 and r > 0")
        self.q, self.r = float(q), float(r)
        self.m0 = np.asarray(m0, dtype=np.float64).reshape(-1)
        self.s0 = np.asarray(s0, dtype=np.float64).reshape(-1)
        if self.m0.shape != (4,) or self.s0.shape != (4,) or np.any(self.s0 < 0):
            raise InputError("bearings_only: m0 and s0 need 4 entries each (s0 >= 0)")

    def params(self):
        return (np.sqrt(self.q), self.r, self.m0, self.s0)

    @staticmethod
    def initial(rng, n, p):
        return p[2] + p[3] * rng.standard_normal((n, 4))

    @staticmethod
    def transition(x, u, t, noise, p):
        out = np.empty_like(x)
        out[:, 0] = x[:, 0] + x[:, 1] + 0.5 * p[0] * noise[:, 0]
        out[:, 1] = x[:, 1] + p[0] * noise[:, 0]
        out[:, 2] = x[:, 2] + x[:, 3] + 0.5 * p[0] * noise[:, 1]
        out[:, 3] = x[:, 3] + p[0] * noise[:, 1]
        return out

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        d = y[0] - np.arctan2(x[:, 2], x[:, 0])
        d = np.arctan2(np.sin(d), np.cos(d))
        return -0.5 * d * d / p[1] - 0.5 * (LOG_2PI + np.log(p[1]))

    @staticmethod
    def observe(x, u, t, noise, p):
        out = np.empty((x.shape[0], 1))
        out[:, 0] = np.arctan2(x[:, 2], x[:, 0]) + np.sqrt(p[1]) * noise[:, 0]
        return out
