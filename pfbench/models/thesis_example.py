"""The illustrative example of [Thesis] §2.7.1, used by Figs. 2.2-2.4.

    x_t = 1.2 x_{t-1} + w_{t-1},   w ~ N(0, sigma_w^2),   x_0 ~ N(0, sigma_0^2)
    y_t = x_t + v_t,               v ~ N(0, sigma_v^2)

sigma_w = 0.01, sigma_v = 0.05, sigma_0 = 0.001 (thesis eq. 2.25). The extraction lost the
observation equation; we use the direct observation y_t = x_t + v_t (documented choice).

Outlier: the thesis simulates w_5 = 0.5 (paper step 5, i.e. x^(6) = 1.2 x^(5) + 0.5). With the
pfbench convention x_t = transition(x_{t-1}, u[t], t, ...) and paper k = t + 1, w_{k-1} enters
at k, so w_5 is used at t = 5: ``outlier_step=5`` replaces the process noise of that step by
``outlier_value``. The *simulating* model carries the outlier; filters use a model with
``outlier_step=-1`` (they do not know about it).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import register
from .base import LOG_2PI, StateSpaceModel


@register("thesis_example")
class ThesisExample(StateSpaceModel):
    """[Thesis] eq. 2.25. Parameters: growth (1.2), sigma_w, sigma_v, sigma_0, outlier_step
    (-1 = none), outlier_value."""

    n_x, n_y, n_u, n_noise = 1, 1, 0, 1
    state_names = ("x",)

    def __init__(self, growth=1.2, sigma_w=0.01, sigma_v=0.05, sigma_0=0.001, outlier_step=-1,
                 outlier_value=0.5):
        self.growth, self.sigma_w, self.sigma_v, self.sigma_0 = (
            float(growth), float(sigma_w), float(sigma_v), float(sigma_0))
        if min(self.sigma_w, self.sigma_v, self.sigma_0) < 0 or self.sigma_v == 0:
            raise InputError("standard deviations must be >= 0 (sigma_v > 0)")
        self.outlier_step = int(outlier_step)
        self.outlier_value = float(outlier_value)

    def without_outlier(self) -> "ThesisExample":
        return ThesisExample(self.growth, self.sigma_w, self.sigma_v, self.sigma_0, -1)

    def params(self):
        return (self.growth, self.sigma_w, self.sigma_v, self.sigma_0, self.outlier_step,
                self.outlier_value)

    @staticmethod
    def initial(rng, n, p):
        return p[3] * rng.standard_normal((n, 1))

    @staticmethod
    def transition(x, u, t, noise, p):
        if t == p[4]:
            return p[0] * x + p[5] + 0.0 * noise
        return p[0] * x + p[1] * noise

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        r = (y[0] - x[:, 0]) / p[2]
        return -0.5 * r * r - np.log(p[2]) - 0.5 * LOG_2PI

    @staticmethod
    def observe(x, u, t, noise, p):
        return x + p[2] * noise
