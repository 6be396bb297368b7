"""A general linear-Gaussian model, the reference for Kalman checks.

    x_t = A x_{t-1} + B u_t + w,  w ~ N(0, Q);   y_t = C x_t + D u_t + v,  v ~ N(0, R)
    x^(0) ~ N(x0, P0)

Its linear-Gaussian structure (``method="mpf"``/``"kalman"``): by default every state is in x^l,
so the marginalized PF is the exact Kalman filter; ``linear_states`` = a subset declares the
other states as x^n (particles) instead, e.g. to test the MPF against the exact KF.
"""
from __future__ import annotations

import numpy as np

from . import register
from numba.extending import register_jitable

from ..errors import InputError, UnsupportedError
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
    """Parameters: A (n_x, n_x), C (n_y, n_x), Q, R, x0, P0, optional B (n_x, n_u), D (n_y, n_u);
    ``linear_states``: the states declared linear-Gaussian (x^l) for the MPF (default: all)."""

    def __init__(self, A=((0.9,),), C=((1.0,),), Q=((1.0,),), R=((1.0,),), x0=None, P0=None,
                 B=None, D=None, linear_states=None):
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
        ls = tuple(range(self.n_x)) if linear_states is None else tuple(int(i) for i in linear_states)
        if not ls or len(set(ls)) != len(ls) or min(ls) < 0 or max(ls) >= self.n_x:
            raise InputError(f"linear_states must be distinct indices in 0..{self.n_x - 1}, "
                             f"got {linear_states!r}")
        self.linear_states = ls
        self._idx_l = np.array(ls, dtype=np.int64)
        self._idx_n = np.array([i for i in range(self.n_x) if i not in ls], dtype=np.int64)

    def params(self):
        c = np.ascontiguousarray
        return (c(self.A.T), c(self.C.T), c(self.LQ.T), c(self.LP0.T), self.x0, c(self.Rinv),
                self.logdetR, c(self.B.T), c(self.D.T), c(self.LR.T), self._idx_n, self._idx_l,
                np.arange(self.n_y, dtype=np.int64))

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

    # ----- linear-Gaussian structure (method="mpf"/"kalman") ------------------------------
    #: x^n = the other states, split with p[10] (x^n indices), p[11] (x^l indices), p[12] (0..n_y-1)
    @staticmethod
    def cl_transition(xn, u, t, p):
        """f^n = A_nn x^n + B_n u, A^n = A_nl, f^l = A_ln x^n + B_l u, A^l = A_ll."""
        n = xn.shape[0]
        return (_affine(xn, p[0], p[10], p[10], u, p[7]), _block(p[0], p[10], p[11], n),
                _affine(xn, p[0], p[11], p[10], u, p[7]), _block(p[0], p[11], p[11], n))

    @staticmethod
    def cl_observation(xn, xl, u, t, p):
        """h = C_n x^n + D u + C_l xl and C = C_l (exact: y is linear)."""
        h = _affine(xn, p[1], p[12], p[10], u, p[8])
        for k in range(h.shape[1]):
            for b in range(xl.shape[1]):
                h[:, k] += p[1][p[11][b], k] * xl[:, b]
        return h, _block(p[1], p[12], p[11], xn.shape[0])

    def cl_noise(self):
        return self.Q, self.R

    def cl_prior(self):
        li, ni = self._idx_l, self._idx_n
        if np.any(self.P0[np.ix_(ni, li)] != 0.0):
            raise UnsupportedError("the marginalized PF needs x^l independent of x^n at t = 0: P0 must "
                                   "have no cross-covariance between linear_states and the others")
        return self.x0[li].copy(), self.P0[np.ix_(li, li)].copy()


@register_jitable
def _affine(x, Mt, rows, cols, u, Nt):
    """out[:, a] = sum_b M[rows[a], cols[b]] x[:, b] + sum_k N[rows[a], k] u[k], for particles x
    (n, len(cols)); ``Mt``, ``Nt`` are M and N transposed (as in ``params``)."""
    out = np.zeros((x.shape[0], rows.shape[0]))
    for a in range(rows.shape[0]):
        for b in range(cols.shape[0]):
            out[:, a] += Mt[cols[b], rows[a]] * x[:, b]
        for k in range(u.shape[0]):
            out[:, a] += Nt[k, rows[a]] * u[k]
    return out


@register_jitable
def _block(Mt, rows, cols, n):
    """M[rows][:, cols] for each of n particles, (n, len(rows), len(cols)); ``Mt`` is M transposed."""
    out = np.empty((n, rows.shape[0], cols.shape[0]))
    for a in range(rows.shape[0]):
        for b in range(cols.shape[0]):
            out[:, a, b] = Mt[cols[b], rows[a]]
    return out
