"""The univariate stochastic-volatility model ([KSC1998] eq. 1; the `particles` library's
``StochVol``), the classic real-data benchmark of SMC (task ``sv-gbpusd``)::

    x_t = mu + rho (x_{t-1} - mu) + sigma v_t,      v_t ~ N(0, 1)
    y_t | x_t ~ N(0, exp(x_t))                       (y: daily log-returns in per cent)
    x^(0) ~ N(mu, sigma^2 / (1 - rho^2))             (the stationary law)

The prior is the stationary law, so x_0 = transition(x^(0)) has the same law and pfbench's time
convention (the first measurement sees x_0, one step after the prior) gives the same likelihood
as the `particles` library's (whose first measurement sees X_0). Defaults mu = -1.02, rho =
0.9702, sigma = 0.178 are the values `particles` uses, which it attributes to [PittShephard1999].
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import register
from .base import LOG_2PI, StateSpaceModel


@register("stochastic_volatility")
class StochasticVolatility(StateSpaceModel):
    """Parameters ``mu`` (mean log-variance), ``rho`` (persistence, |rho| < 1), ``sigma`` (sd of
    the log-variance innovations)."""

    n_x, n_y, n_u, n_noise = 1, 1, 0, 1
    state_names = ("log-variance",)

    def __init__(self, mu: float = -1.02, rho: float = 0.9702, sigma: float = 0.178):
        if not abs(rho) < 1 or sigma <= 0:
            raise InputError("stochastic_volatility needs |rho| < 1 and sigma > 0")
        self.mu, self.rho, self.sigma = float(mu), float(rho), float(sigma)

    def params(self):
        return (self.mu, self.rho, self.sigma, self.sigma / np.sqrt(1.0 - self.rho ** 2))

    @staticmethod
    def initial(rng, n, p):
        return p[0] + p[3] * rng.standard_normal((n, 1))

    @staticmethod
    def transition(x, u, t, noise, p):
        return p[0] + p[1] * (x - p[0]) + p[2] * noise

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        xx = x[:, 0]
        return -0.5 * (LOG_2PI + xx + y[0] * y[0] * np.exp(-xx))

    @staticmethod
    def observe(x, u, t, noise, p):
        return np.exp(0.5 * x) * noise
