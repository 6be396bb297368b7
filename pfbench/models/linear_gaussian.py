"""A general linear-Gaussian model, the reference for Kalman checks.

    x_t = A x_{t-1} + B u_t + w,  w ~ N(0, Q);   y_t = C x_t + D u_t + v,  v ~ N(0, R)
    x^(0) ~ N(x0, P0)
"""
from __future__ import annotations

import numpy as np

from . import register
from .base import LOG_2PI, StateSpaceModel


def _chol_psd(m: np.ndarray) -> np.ndarray:
    """Cholesky factor of a symmetric PSD matrix (zero rows/cols allowed)."""
    m = np.atleast_2d(np.asarray(m, dtype=np.float64))
    w, v = np.linalg.eigh(0.5 * (m + m.T))
    if w.min() < -1e-12 * max(1.0, abs(w).max()):
        raise ValueError("covariance matrix is not positive semi-definite")
    return v * np.sqrt(np.clip(w, 0.0, None))


@register("linear_gaussian")
class LinearGaussian(StateSpaceModel):
    """Parameters: A (n_x, n_x), C (n_y, n_x), Q, R, x0, P0, optional B (n_x, n_u), D (n_y, n_u)."""

    def __init__(self, A=((0.9,),), C=((1.0,),), Q=((1.0,),), R=((1.0,),), x0=None, P0=None,
                 B=None, D=None):
        f = lambda a: np.atleast_2d(np.asarray(a, dtype=np.float64))  # noqa: E731
        self.A, self.C, self.Q, self.R = f(A), f(C), f(Q), f(R)
        self.n_x = self.A.shape[0]
        self.n_y = self.C.shape[0]
        if self.A.shape != (self.n_x, self.n_x) or self.C.shape[1] != self.n_x:
            raise ValueError("A must be (n_x, n_x) and C (n_y, n_x)")
        if self.Q.shape != (self.n_x, self.n_x) or self.R.shape != (self.n_y, self.n_y):
            raise ValueError("Q must be (n_x, n_x) and R (n_y, n_y)")
        self.x0 = np.zeros(self.n_x) if x0 is None else np.asarray(x0, dtype=np.float64).reshape(self.n_x)
        self.P0 = np.eye(self.n_x) if P0 is None else f(P0)
        self.n_u = 0 if B is None else f(B).shape[1]
        self.B = np.zeros((self.n_x, self.n_u)) if B is None else f(B)
        self.D = np.zeros((self.n_y, self.n_u)) if D is None else f(D)
        self.n_noise = self.n_x
        self.LQ, self.LP0 = _chol_psd(self.Q), _chol_psd(self.P0)
        self.LR = _chol_psd(self.R)
        self.Rinv = np.linalg.inv(self.R)
        self.logdetR = float(np.linalg.slogdet(self.R)[1])

    def params(self):
        c = np.ascontiguousarray
        return (c(self.A.T), c(self.C.T), c(self.LQ.T), c(self.LP0.T), self.x0, c(self.Rinv),
                self.logdetR, c(self.B.T), c(self.D.T), c(self.LR.T))

    def inputs(self, rng, n_steps):
        return rng.standard_normal((n_steps, self.n_u)) if self.n_u else None

    @staticmethod
    def initial(rng, n, p):
        return p[4] + rng.standard_normal((n, p[4].shape[0])) @ p[3]

    @staticmethod
    def transition(x, u, t, noise, p):
        out = np.ascontiguousarray(x) @ p[0] + noise @ p[2]
        if u.shape[0] > 0:
            out += u @ p[7]
        return out

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        resid = y - np.ascontiguousarray(x) @ p[1]
        if u.shape[0] > 0:
            resid -= u @ p[8]
        quad = np.sum((resid @ p[5]) * resid, axis=1)
        return -0.5 * quad - 0.5 * (y.shape[0] * LOG_2PI + p[6])

    @staticmethod
    def observe(x, u, t, noise, p):
        out = np.ascontiguousarray(x) @ p[1] + noise @ p[9]
        if u.shape[0] > 0:
            out += u @ p[8]
        return out
