"""Ob3, versions 1-5: a four-node network object ([MultiPDF] §4, "Ob403" of its ref. [45]).

    x_i^(k+1) = 0.9 x_i^(k) + v_i,        v_i ~ N(0, 1),  i = 1..4
    y_i       = h_i(x, mu) + n_i,          n ~ N(0, 1)
    y_ij      = h_ij(x, mu) + n_ij
    x_i^(0) ~ U[-1, 1];  mu_14 = mu_41 = 0, all other mu_ij = 1.

Choice (the extraction does not say which pairs (i, j) are measured): ``pairs="connected"``
(default) measures y_ij for i != j with mu_ij != 0, as line flows of a network (4 + 10 = 14
outputs); ``pairs="all"`` measures every i != j (4 + 12 = 16 outputs).
"""
from __future__ import annotations

import numpy as np
from numba.extending import register_jitable

from ..errors import InputError
from . import register
from .base import (StateSpaceModel, central_difference_points, difference_column, gaussian_loglik_diag,
                   scaled_identities)


@register_jitable
def ob3_h(x, version, mu, pi, pj):
    """Noise-free outputs of Ob3 version ``version``; pairs (pi[m], pj[m]) give the y_ij."""
    n = x.shape[0]
    n_pairs = pi.shape[0]
    h = np.empty((n, 4 + n_pairs))
    for i in range(4):
        xi = x[:, i]
        acc = np.zeros(n)
        if version == 1:
            acc += xi
        elif version == 2:
            acc += 1.0
            for j in range(4):
                if mu[i, j] != 0.0:
                    acc *= x[:, j] * mu[i, j]
        elif version == 3:
            acc += xi
            for j in range(4):
                if j != i and mu[i, j] != 0.0:
                    acc += x[:, j]
        elif version == 4:
            for j in range(4):
                if mu[i, j] != 0.0:
                    xj = x[:, j]
                    acc += xi * xj * mu[i, j] * np.sin(xi - xj - mu[i, j])
        else:
            for j in range(4):
                if j != i:
                    xj = x[:, j]
                    acc += xj * mu[i, j] * np.cos((xi - xj) / np.log(1.01 + np.abs(xj * mu[i, j])))
            acc *= xi
        h[:, i] = acc
    for m in range(n_pairs):
        i = pi[m]
        j = pj[m]
        xi = x[:, i]
        xj = x[:, j]
        if version == 1:
            h[:, 4 + m] = xi - xj
        elif version == 2:
            h[:, 4 + m] = xi * xj
        elif version == 3:
            h[:, 4 + m] = xi + xj * np.sin((xi + xj) * xj)
        elif version == 4:
            h[:, 4 + m] = xi * xi - xi * xj * mu[i, j] * np.cos(xi - xj - mu[i, j])
        else:
            a = np.log2(0.01 + np.abs(xi * xj))
            b = -0.1 * (xi + xj) ** 2 + 2.0
            h[:, 4 + m] = np.maximum(xi + xj, xi * xj) / (0.01 + np.minimum(a, b))
    return h


@register("ob3")
class Ob3(StateSpaceModel):
    """Ob3 ([MultiPDF] §4) with ``version`` in 1..5."""

    n_x, n_u, n_noise = 4, 0, 4
    state_names = ("x1", "x2", "x3", "x4")

    def __init__(self, version: int = 1, pairs: str = "connected", q: float = 1.0, r: float = 1.0,
                 a: float = 0.9):
        if int(version) not in (1, 2, 3, 4, 5):
            raise InputError("version must be 1..5")
        if pairs not in ("connected", "all"):
            raise InputError("pairs must be 'connected' or 'all'")
        if q <= 0 or r <= 0:
            raise InputError("variances q and r must be positive")
        self.version, self.pairs = int(version), pairs
        self.q, self.r, self.a = float(q), float(r), float(a)
        self.mu = np.ones((4, 4))
        self.mu[0, 3] = self.mu[3, 0] = 0.0
        ij = [(i, j) for i in range(4) for j in range(4)
              if i != j and (pairs == "all" or self.mu[i, j] != 0.0)]
        self.pi = np.array([i for i, _ in ij], dtype=np.int64)
        self.pj = np.array([j for _, j in ij], dtype=np.int64)
        self.n_y = 4 + len(ij)

    def params(self):
        return (np.sqrt(self.q), np.full(self.n_y, self.r), self.a, self.version, self.mu,
                self.pi, self.pj)

    @staticmethod
    def initial(rng, n, p):
        return rng.uniform(-1.0, 1.0, (n, 4))

    @staticmethod
    def transition(x, u, t, noise, p):
        return p[2] * x + p[0] * noise

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        return gaussian_loglik_diag(y - ob3_h(x, p[3], p[4], p[5], p[6]), p[1])

    @staticmethod
    def observe(x, u, t, noise, p):
        return ob3_h(x, p[3], p[4], p[5], p[6]) + np.sqrt(p[1]) * noise

    # ----- linear-Gaussian structure (method="mpf"/"kalman"): every state is linear ---------
    #: x_t = a x_{t-1} + v is linear in every state, so the MPF is one EKF copy ([MultiPDF] §5)
    linear_states = (0, 1, 2, 3)

    @staticmethod
    def cl_transition(xn, u, t, p):
        n = xn.shape[0]
        return np.zeros((n, 0)), np.zeros((n, 0, 4)), np.zeros((n, 4)), scaled_identities(n, 4, p[2])

    @staticmethod
    def cl_observation(xn, xl, u, t, p):
        """h at ``xl`` and its Jacobian by central differences (the EKF of [MultiPDF] §5)."""
        h = ob3_h(xl, p[3], p[4], p[5], p[6])
        C = np.empty((xl.shape[0], h.shape[1], 4))
        for a in range(4):
            xp, xm, two_eps = central_difference_points(xl, a)
            difference_column(C, a, ob3_h(xp, p[3], p[4], p[5], p[6]), ob3_h(xm, p[3], p[4], p[5], p[6]), two_eps)
        return h, C

    def cl_noise(self):
        return self.q * np.eye(4), self.r * np.eye(self.n_y)

    def cl_prior(self):
        return np.zeros(4), np.eye(4) / 3.0  # x^(0) ~ U[-1, 1]: mean 0, variance 1/3
