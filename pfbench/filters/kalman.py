"""Kalman filters (linear, extended, the [RTD] time-varying and steady-state loops).

Conventions (identical to :class:`pfbench.models.linear_gaussian.LinearGaussian`)::

    x^(0) ~ N(x0, P0)
    for t = 0..M-1:
        x_t = A x_{t-1} + B u[t] + w_t,   w_t ~ N(0, Q)        (predict)
        y_t = C x_t     + D u[t] + v_t,   v_t ~ N(0, R)        (update)

Every filter here returns a :class:`~pfbench.filters.result.FilterResult` with ``method="kalman"``,
``info["filter"]`` naming the filter (``"kf"``, ``"ekf"``, ``"time_varying_kf"``,
``"steady_state_kf"``), ``estimates`` = filtered means E[x_t | y_0..y_t], ``covariances`` = filtered
covariances, ``variances`` = their diagonals, the Gaussian innovation log-likelihood
(``loglik_increments[t] = log N(y_t; E[y_t | y_0..y_t-1], S_t)``, exact for the linear filters, the
usual Gaussian approximation for the EKF), ``ess`` NaN, ``n_resampled`` 0, ``n_particles`` 0 and
these ``extras`` (M steps, n_x states, n_y outputs):

==================  ===============  =====================================================
``pred_means``      (M, n_x)         E[x_t | y_0..y_t-1], the mean the update at t starts from
``pred_covs``       (M, n_x, n_x)    its covariance P[t|t-1]
``innovations``     (M, n_y)         y_t - E[y_t | y_0..y_t-1]
``innovation_covs`` (M, n_y, n_y)    S_t = C P[t|t-1] C^T + R
``gains``           (M, n_x, n_y)    K_t = P[t|t-1] C^T S_t^-1 (the chapter's M[n])
==================  ===============  =====================================================

The [RTD] loops (:func:`time_varying_kf`, :func:`steady_state_kf`) add the chapter's names:
``x_pred`` (M, n_x) x[n+1|n] (after the time update of step n), ``yest`` (M, n_y) C x[n|n],
``ypred`` (M, n_y) C x[n+1|n] (the one-step predictor) and ``errcov`` (M, n_y, n_y) C P[n|n] C^T.

The DARE and the steady-state gain live in :mod:`pfbench.filters.dare`.

References
----------
[Thesis], eqs. 2.29-2.33 (Kalman filter) and 2.36-2.38 (extended Kalman filter);
[RTD], §4.2.1 (time-varying KF), §2.6 and eqs. 30, 37 (steady-state KF from the DARE).
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

from ..errors import InputError, NumericalError, UnsupportedError
from .dare import as_matrix, shaped, steady_state_gain, symmetrize
from .result import FilterResult

LOG_2PI = float(np.log(2.0 * np.pi))

__all__ = [
    "kalman_filter", "filter_model", "ekf_predict", "ekf_update", "ekf", "gaussian_logpdf",
    "time_varying_kf", "steady_state_kf", "KALMAN_EXTRAS", "CHAPTER_EXTRAS",
]

#: ``extras`` keys of every Kalman-family :class:`FilterResult` (see the module docstring).
KALMAN_EXTRAS = ("pred_means", "pred_covs", "innovations", "innovation_covs", "gains")
#: further ``extras`` keys of the [RTD] loops, with the chapter's names.
CHAPTER_EXTRAS = ("x_pred", "yest", "ypred", "errcov")


def gaussian_logpdf(r, S):
    """log N(r; 0, S) via a Cholesky factor of S (symmetric positive definite).

    ``r`` (n_y,) gives a float; ``r`` (k, n_y) gives the (k,) log-densities of k vectors under the
    same S.
    """
    r = np.asarray(r, dtype=np.float64)
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError as exc:
        raise NumericalError("innovation covariance C P C^T + R is not positive definite") from exc
    from scipy.linalg import solve_triangular

    z = solve_triangular(L, r.T, lower=True)                # (n_y,) or (n_y, k)
    out = -0.5 * np.sum(z * z, axis=0) - np.sum(np.log(np.diag(L))) - 0.5 * L.shape[0] * LOG_2PI
    return float(out) if r.ndim == 1 else out


def _update(xp, Pp, y, C, R, yhat):
    """Measurement update ([Thesis], eqs. 2.31-2.33) in Joseph form for symmetry/PSD."""
    S = symmetrize(C @ Pp @ C.T + R)
    PCt = Pp @ C.T
    try:
        K = np.linalg.solve(S, PCt.T).T  # K = P C^T S^-1 (eq. 2.31)
    except np.linalg.LinAlgError as exc:
        raise NumericalError("innovation covariance C P C^T + R is singular") from exc
    r = y - yhat
    x = xp + K @ r                                   # eq. 2.32
    IKC = np.eye(xp.shape[0]) - K @ C
    P = symmetrize(IKC @ Pp @ IKC.T + K @ R @ K.T)   # eq. 2.33 (Joseph form, same value)
    return x, P, r, S, K


def _result(name: str, means, covs, inc, extras: dict, elapsed: float) -> FilterResult:
    """The :class:`FilterResult` of a Kalman-family filter (see the module docstring)."""
    M = means.shape[0]
    return FilterResult(
        estimates=means, variances=np.diagonal(covs, axis1=1, axis2=2).copy(), loglik=float(inc.sum()),
        loglik_increments=inc, ess=np.full(M, np.nan), n_resampled=0, degenerate=np.zeros(M, dtype=bool),
        elapsed_s=elapsed, method="kalman", backend="numpy", dtype="float64", n_particles=0,
        n_filters=1, covariances=covs, extras=extras, info={"filter": name})


def _observations(y, n_y: int, func: str) -> np.ndarray:
    """y as (M, n_y): a flat vector only when n_y = 1."""
    y = np.asarray(y, dtype=np.float64)
    if y.ndim == 1 and n_y == 1:
        y = y.reshape(-1, 1)
    if y.ndim != 2 or y.shape[1] != n_y or y.shape[0] < 1:
        raise InputError(f"{func}: y must have shape (M, {n_y}), got {y.shape}")
    return y


def _inputs(u, M: int, n_u: int, func: str) -> np.ndarray:
    """u as (M, n_u): a flat vector only when n_u = 1."""
    u = np.asarray(u, dtype=np.float64)
    if u.ndim == 1 and n_u == 1:
        u = u.reshape(-1, 1)
    if u.shape != (M, n_u):
        raise InputError(f"{func}: u must have shape ({M}, {n_u}), got {u.shape}")
    return u


def _system(A, C, Q, R, func: str):
    A, C, Q, R = (as_matrix(a, n, func) for a, n in ((A, "A"), (C, "C"), (Q, "Q"), (R, "R")))
    n_x, n_y = A.shape[0], C.shape[0]
    if A.shape != (n_x, n_x) or C.shape[1] != n_x or Q.shape != (n_x, n_x) or R.shape != (n_y, n_y):
        raise InputError(f"{func}: inconsistent shapes A {A.shape}, C {C.shape}, Q {Q.shape}, R {R.shape}; "
                         "need A (n_x, n_x), C (n_y, n_x), Q (n_x, n_x), R (n_y, n_y)")
    return A, C, Q, R


def _n_inputs(B, D) -> int:
    for m in (B, D):
        if m is not None:
            m = np.asarray(m)
            return 1 if m.ndim <= 1 else int(m.shape[1])
    return 0


def kalman_filter(A, C, Q, R, x0, P0, y, *, B=None, D=None, u=None) -> FilterResult:
    """Linear Kalman filter with the exact log-likelihood.

    Implements [Thesis], eqs. 2.29-2.33: prediction ``x_{t|t-1} = A x_{t-1} + B u_t`` (2.29),
    ``P_{t|t-1} = A P A^T + Q`` (2.30), gain ``K = P C^T (C P C^T + R)^-1`` (2.31), and the update
    of mean (2.32) and covariance (2.33). The log-likelihood increments are
    ``log N(y_t; C x_{t|t-1} + D u_t, C P_{t|t-1} C^T + R)``.

    Parameters
    ----------
    A, C, Q, R : array_like
        System matrices (n_x, n_x), (n_y, n_x), (n_x, n_x), (n_y, n_y).
    x0, P0 : array_like
        Mean (n_x,) and covariance (n_x, n_x) of x^(0) (before the first prediction).
    y : array_like, (M, n_y) (or (M,) when n_y = 1)
        Observations y_0..y_{M-1}.
    B, D : array_like, optional
        Input matrices (n_x, n_u), (n_y, n_u); need ``u``.
    u : array_like, optional
        Inputs (M, n_u); u[t] enters both the transition into x_t and the observation y_t. Needs
        ``B`` or ``D``.

    Returns
    -------
    FilterResult
        ``info["filter"] == "kf"``; extras :data:`KALMAN_EXTRAS`.
    """
    func = "kalman_filter"
    A, C, Q, R = _system(A, C, Q, R, func)
    n_x, n_y = A.shape[0], C.shape[0]
    x0 = shaped(x0, (n_x,), "x0", func)
    P0 = shaped(P0, (n_x, n_x), "P0", func)
    y = _observations(y, n_y, func)
    M = y.shape[0]
    has_u = u is not None
    if has_u != (B is not None or D is not None):
        raise InputError(f"{func}: inputs need both u and an input matrix (B and/or D)")
    if has_u:
        n_u = _n_inputs(B, D)
        u = _inputs(u, M, n_u, func)
        B = np.zeros((n_x, n_u)) if B is None else shaped(B, (n_x, n_u), "B", func)
        D = np.zeros((n_y, n_u)) if D is None else shaped(D, (n_y, n_u), "D", func)

    t0 = time.perf_counter()
    means = np.empty((M, n_x)); covs = np.empty((M, n_x, n_x))
    pm = np.empty((M, n_x)); pc = np.empty((M, n_x, n_x))
    inc = np.empty(M); innov = np.empty((M, n_y)); Ss = np.empty((M, n_y, n_y))
    gains = np.empty((M, n_x, n_y))
    x, P = x0.copy(), P0.copy()
    for t in range(M):
        xp = A @ x                                   # eq. 2.29
        yhat_off = np.zeros(n_y)
        if has_u:
            xp = xp + B @ u[t]
            yhat_off = D @ u[t]
        Pp = symmetrize(A @ P @ A.T + Q)             # eq. 2.30
        x, P, r, S, K = _update(xp, Pp, y[t], C, R, C @ xp + yhat_off)
        pm[t], pc[t], means[t], covs[t] = xp, Pp, x, P
        innov[t], Ss[t], gains[t] = r, S, K
        inc[t] = gaussian_logpdf(r, S)
    extras = dict(pred_means=pm, pred_covs=pc, innovations=innov, innovation_covs=Ss, gains=gains)
    return _result("kf", means, covs, inc, extras, time.perf_counter() - t0)


def filter_model(model, y, u=None) -> FilterResult:
    """Run :func:`kalman_filter` on a :class:`~pfbench.models.linear_gaussian.LinearGaussian` model
    (any model with the attributes A, C, Q, R, x0, P0 and, with inputs, B and D)."""
    missing = [a for a in ("A", "C", "Q", "R", "x0", "P0") if not hasattr(model, a)]
    if missing:
        raise UnsupportedError(f"filter_model needs a linear-Gaussian model (attributes A, C, Q, R, x0, "
                               f"P0); {type(model).__name__} lacks {', '.join(missing)}")
    n_u = int(getattr(model, "n_u", 0))
    if n_u and u is None:
        raise InputError(f"this model has inputs: pass u (M, {n_u})")
    return kalman_filter(model.A, model.C, model.Q, model.R, model.x0, model.P0, y,
                         B=model.B if n_u else None, D=model.D if n_u else None,
                         u=u if n_u else None)


# ----------------------------------------------------------------------------- EKF

def ekf_predict(x, P, f: Callable, F_jac: Callable, Q, u=None, t: int = 0):
    """EKF time update ([Thesis], eqs. 2.36 and 2.38).

    ``x_{t|t-1} = f(x_{t-1}, u_t, t)``, ``P_{t|t-1} = F P F^T + Q`` with ``F = df/dx`` at x_{t-1}
    (eq. 2.36). f and F_jac take (x, u, t) for one state vector.

    Returns
    -------
    (x_pred, P_pred)
    """
    x = np.asarray(x, dtype=np.float64)
    F = np.atleast_2d(np.asarray(F_jac(x, u, t), dtype=np.float64))
    xp = np.asarray(f(x, u, t), dtype=np.float64).reshape(x.shape)
    Q = as_matrix(Q, "Q", "ekf_predict")
    if Q.shape != F.shape:
        raise InputError(f"ekf_predict: Q must have the shape of the Jacobian {F.shape}, got {Q.shape}")
    Pp = symmetrize(F @ np.asarray(P, dtype=np.float64) @ F.T + Q)
    return xp, Pp


def _ekf_update(x, P, y, h: Callable, H_jac: Callable, R, u=None, t: int = 0):
    """:func:`ekf_update` that also returns the gain: (x, P, innovation, innovation_cov, K)."""
    x = np.asarray(x, dtype=np.float64)
    P = np.asarray(P, dtype=np.float64)
    H = np.atleast_2d(np.asarray(H_jac(x, u, t), dtype=np.float64))
    yhat = np.atleast_1d(np.asarray(h(x, u, t), dtype=np.float64))
    y = np.atleast_1d(np.asarray(y, dtype=np.float64))
    return _update(x, P, y, H, as_matrix(R, "R", "ekf_update"), yhat)


def ekf_update(x, P, y, h: Callable, H_jac: Callable, R, u=None, t: int = 0):
    """EKF measurement update ([Thesis], eq. 2.37 linearisation + eqs. 2.31-2.33).

    ``H = dh/dx`` at the predicted state (eq. 2.37), ``K = P H^T (H P H^T + R)^-1``,
    ``x = x + K (y - h(x))``, ``P = (I - K H) P`` (Joseph form).

    Returns
    -------
    (x, P, innovation, innovation_cov)
    """
    return _ekf_update(x, P, y, h, H_jac, R, u, t)[:4]


def ekf(f, F_jac, h, H_jac, Q, R, x0, P0, y, u=None) -> FilterResult:
    """Extended Kalman filter ([Thesis], eqs. 2.36-2.38) built on :func:`ekf_predict` /
    :func:`ekf_update`; same time convention as :func:`kalman_filter`.

    ``loglik`` is the Gaussian approximation sum_t log N(innovation_t; 0, S_t).

    Returns
    -------
    FilterResult
        ``info["filter"] == "ekf"``; extras :data:`KALMAN_EXTRAS`.
    """
    func = "ekf"
    x = np.asarray(x0, dtype=np.float64).ravel().copy()
    n_x = x.shape[0]
    P = shaped(P0, (n_x, n_x), "P0", func).copy()
    Q = shaped(Q, (n_x, n_x), "Q", func) if np.ndim(Q) else as_matrix(Q, "Q", func)
    if Q.shape != (n_x, n_x):
        raise InputError(f"{func}: Q must have shape ({n_x}, {n_x}), got {Q.shape}")
    R = as_matrix(R, "R", func)
    n_y = R.shape[0]
    if R.shape != (n_y, n_y):
        raise InputError(f"{func}: R must be square (n_y, n_y), got {R.shape}")
    y = _observations(y, n_y, func)
    M = y.shape[0]
    if u is not None:
        u = np.asarray(u, dtype=np.float64)
        u = _inputs(u, M, 1 if u.ndim == 1 else u.shape[-1], func)
    t0 = time.perf_counter()
    means = np.empty((M, n_x)); covs = np.empty((M, n_x, n_x))
    pm = np.empty((M, n_x)); pc = np.empty((M, n_x, n_x))
    inc = np.empty(M); innov = np.empty((M, n_y)); Ss = np.empty((M, n_y, n_y))
    gains = np.empty((M, n_x, n_y))
    for t in range(M):
        ut = None if u is None else u[t]
        xp, Pp = ekf_predict(x, P, f, F_jac, Q, ut, t)
        x, P, r, S, K = _ekf_update(xp, Pp, y[t], h, H_jac, R, ut, t)
        pm[t], pc[t], means[t], covs[t] = xp, Pp, x, P
        innov[t], Ss[t], gains[t] = r, S, K
        inc[t] = gaussian_logpdf(r, S)
    extras = dict(pred_means=pm, pred_covs=pc, innovations=innov, innovation_covs=Ss, gains=gains)
    return _result("ekf", means, covs, inc, extras, time.perf_counter() - t0)


# ----------------------------------------------------------------------------- [RTD] loops

def _prep_loop(A, B, C, Q, R, u, y, x0, func):
    A, C, Q, R = _system(A, C, Q, R, func)
    n_x, n_y = A.shape[0], C.shape[0]
    y = _observations(y, n_y, func)
    n = y.shape[0]
    if B is None:
        if u is not None:
            raise InputError(f"{func}: u given without B")
        B = np.zeros((n_x, 1)); u = np.zeros((n, 1))
    else:
        B = np.asarray(B, dtype=np.float64)
        B = shaped(B, (n_x, 1 if B.ndim <= 1 else B.shape[1]), "B", func)
        u = np.zeros((n, B.shape[1])) if u is None else _inputs(u, n, B.shape[1], func)
    x = np.zeros(n_x) if x0 is None else shaped(x0, (n_x,), "x0", func).copy()
    return A, B, C, Q, R, u, y, x


def time_varying_kf(A, B, C, Q, R, u, y, *, x0=None, P0=None) -> FilterResult:
    """Time-varying Kalman filter, the loop of [RTD] §4.2.1 (measurement update, then time update).

    For i = 0..n-1::

        M  = P C^T (C P C^T + R)^-1            (eq. 20)
        x  = x + M (y_i - C x)      P = (I - M C) P        (x[n|n], P[n|n]; eqs. 12, 21)
        yest_i = C x,  errcov_i = C P C^T
        x  = A x + B u_i            P = A P A^T + Q        (x[n+1|n], P[n+1|n]; eqs. 22, 25)

    Parameters
    ----------
    A, B, C : (n_x, n_x), (n_x, n_u) (or None: no input), (n_y, n_x).
    Q : (n_x, n_x) state process-noise covariance (the chapter uses ``B Qu B^T`` with a scalar input
        noise Qu). P0 defaults to Q (the chapter's ``Ptv = B*Q*B'``), x0 to zeros.
    R : (n_y, n_y).
    u : (n, n_u) inputs (zeros if None); y : (n, n_y) readings (flat when n_y = 1).

    Returns
    -------
    FilterResult
        ``info["filter"] == "time_varying_kf"``; ``estimates`` x[n|n]; extras
        :data:`KALMAN_EXTRAS` (pred_* = x[n|n-1], P[n|n-1] before the update) and
        :data:`CHAPTER_EXTRAS`. The log-likelihood is that of the innovations
        ``y_i - C x[i|i-1] ~ N(0, C P[i|i-1] C^T + R)``.
    """
    func = "time_varying_kf"
    A, B, C, Q, R, u, y, x = _prep_loop(A, B, C, Q, R, u, y, x0, func)
    n, n_x, n_y = y.shape[0], A.shape[0], C.shape[0]
    P = Q.copy() if P0 is None else shaped(P0, (n_x, n_x), "P0", func).copy()
    t0 = time.perf_counter()
    xf = np.empty((n, n_x)); xp = np.empty((n, n_x)); Pf = np.empty((n, n_x, n_x))
    pm = np.empty((n, n_x)); pc = np.empty((n, n_x, n_x))
    innov = np.empty((n, n_y)); Ss = np.empty((n, n_y, n_y)); gains = np.empty((n, n_x, n_y))
    errcov = np.empty((n, n_y, n_y)); inc = np.empty(n)
    I = np.eye(n_x)
    for i in range(n):
        pm[i], pc[i] = x, P
        S = C @ P @ C.T + R
        Mn = np.linalg.solve(S, C @ P).T                          # eq. 20
        r = y[i] - C @ x
        x = x + Mn @ r
        P = symmetrize((I - Mn @ C) @ P)                          # eq. 21
        xf[i], Pf[i] = x, P
        errcov[i] = C @ P @ C.T
        innov[i], Ss[i], gains[i] = r, S, Mn
        inc[i] = gaussian_logpdf(r, symmetrize(S))
        x = A @ x + B @ u[i]                                      # eq. 22
        P = symmetrize(A @ P @ A.T + Q)                           # eq. 25
        xp[i] = x
    extras = dict(pred_means=pm, pred_covs=pc, innovations=innov, innovation_covs=Ss, gains=gains,
                  x_pred=xp, yest=xf @ C.T, ypred=xp @ C.T, errcov=errcov)
    return _result(func, xf, Pf, inc, extras, time.perf_counter() - t0)


def steady_state_kf(A, B, C, Q, R, u, y, *, x0=None) -> FilterResult:
    """Steady-state Kalman filter with the DARE gain ([RTD] §4.2.1 second loop / §6.1 ``x_inf``).

    Same loop as :func:`time_varying_kf` with the constant gain ``M_inf`` and covariances
    ``P[n|n-1] = P_inf``, ``P[n|n]`` of :func:`~pfbench.filters.dare.steady_state_gain`
    (``errcov`` is the constant ``C P[n|n] C^T``; the log-likelihood uses the constant
    ``S = C P_inf C^T + R``).

    Returns
    -------
    FilterResult
        ``info["filter"] == "steady_state_kf"``; extras as :func:`time_varying_kf`.
    """
    func = "steady_state_kf"
    A, B, C, Q, R, u, y, x = _prep_loop(A, B, C, Q, R, u, y, x0, func)
    P_prior, P_post, M = steady_state_gain(A, C, Q, R)
    n, n_x, n_y = y.shape[0], A.shape[0], C.shape[0]
    t0 = time.perf_counter()
    xf = np.empty((n, n_x)); xp = np.empty((n, n_x)); pm = np.empty((n, n_x))
    innov = np.empty((n, n_y))
    for i in range(n):
        pm[i] = x
        r = y[i] - C @ x
        x = x + M @ r
        xf[i] = x
        innov[i] = r
        x = A @ x + B @ u[i]
        xp[i] = x
    S = symmetrize(C @ P_prior @ C.T + R)
    inc = np.atleast_1d(gaussian_logpdf(innov, S))
    rep = lambda a: np.broadcast_to(a, (n,) + a.shape).copy()  # noqa: E731
    extras = dict(pred_means=pm, pred_covs=rep(P_prior), innovations=innov, innovation_covs=rep(S),
                  gains=rep(M), x_pred=xp, yest=xf @ C.T, ypred=xp @ C.T, errcov=rep(C @ P_post @ C.T))
    return _result(func, xf, rep(P_post), inc, extras, time.perf_counter() - t0)
