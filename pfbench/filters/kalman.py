"""Kalman filters (linear, extended, steady-state) and the discrete algebraic Riccati equation.

Conventions (identical to :class:`pfbench.models.linear_gaussian.LinearGaussian`)::

    x^(0) ~ N(x0, P0)
    for t = 0..M-1:
        x_t = A x_{t-1} + B u[t] + w_t,   w_t ~ N(0, Q)        (predict)
        y_t = C x_t     + D u[t] + v_t,   v_t ~ N(0, R)        (update)

References
----------
[Thesis], eqs. 2.29-2.33 (Kalman filter) and 2.36-2.38 (extended Kalman filter);
[RTD] (rtd), §2.6 eqs. 41-42 (DARE by the generalized Schur method) and §4.2.1 (time-varying KF).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import PfbenchError

LOG_2PI = float(np.log(2.0 * np.pi))

__all__ = [
    "KalmanResult", "kalman_filter", "filter_model", "ekf_predict", "ekf_update", "ekf",
    "gaussian_logpdf", "dare", "dare_scalar", "chapter_riccati_scalar", "steady_state_gain",
    "time_varying_kf", "steady_state_kf", "RecursiveKFResult",
]


@dataclass
class KalmanResult:
    """Output of :func:`kalman_filter` / :func:`ekf`.

    Attributes
    ----------
    means : (M, n_x) filtered means E[x_t | y_0..y_t]
    covs : (M, n_x, n_x) filtered covariances
    pred_means : (M, n_x) one-step predicted means E[x_t | y_0..y_{t-1}]
    pred_covs : (M, n_x, n_x) predicted covariances
    loglik : float, log p(y_0..y_{M-1}) (exact for the linear filter)
    loglik_increments : (M,) log p(y_t | y_0..y_{t-1})
    innovations : (M, n_y) y_t - E[y_t | y_0..y_{t-1}]
    innovation_covs : (M, n_y, n_y)
    gains : (M, n_x, n_y) Kalman gains
    """

    means: np.ndarray
    covs: np.ndarray
    pred_means: np.ndarray
    pred_covs: np.ndarray
    loglik: float
    loglik_increments: np.ndarray
    innovations: np.ndarray
    innovation_covs: np.ndarray
    gains: np.ndarray


def _m2(a, name: str) -> np.ndarray:
    a = np.atleast_2d(np.asarray(a, dtype=np.float64))
    if a.ndim != 2:
        raise PfbenchError(f"{name} must be a matrix, got shape {a.shape}")
    return a


def _sym(p: np.ndarray) -> np.ndarray:
    return 0.5 * (p + p.T)


def gaussian_logpdf(r: np.ndarray, S: np.ndarray) -> float:
    """log N(r; 0, S) via a Cholesky factor of S (S symmetric positive definite)."""
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError as exc:
        raise PfbenchError("innovation covariance is not positive definite") from exc
    z = np.linalg.solve(L, r)
    return float(-0.5 * (z @ z) - np.sum(np.log(np.diag(L))) - 0.5 * r.shape[0] * LOG_2PI)


def _update(xp, Pp, y, C, R, yhat):
    """Measurement update ([Thesis], eqs. 2.31-2.33) in Joseph form for symmetry/PSD."""
    S = _sym(C @ Pp @ C.T + R)
    PCt = Pp @ C.T
    try:
        K = np.linalg.solve(S, PCt.T).T  # K = P C^T S^-1 (eq. 2.31)
    except np.linalg.LinAlgError as exc:
        raise PfbenchError("innovation covariance is singular") from exc
    r = y - yhat
    x = xp + K @ r                                   # eq. 2.32
    IKC = np.eye(xp.shape[0]) - K @ C
    P = _sym(IKC @ Pp @ IKC.T + K @ R @ K.T)         # eq. 2.33 (Joseph form, same value)
    return x, P, r, S, K


def kalman_filter(A, C, Q, R, x0, P0, y, *, B=None, D=None, u=None) -> KalmanResult:
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
    y : array_like, (M, n_y) or (M,)
        Observations y_0..y_{M-1}.
    B, D : array_like, optional
        Input matrices (n_x, n_u), (n_y, n_u).
    u : array_like, optional
        Inputs (M, n_u); u[t] enters both the transition into x_t and the observation y_t.

    Returns
    -------
    KalmanResult
    """
    A, C, Q, R, P0 = (_m2(a, n) for a, n in ((A, "A"), (C, "C"), (Q, "Q"), (R, "R"), (P0, "P0")))
    n_x, n_y = A.shape[0], C.shape[0]
    if A.shape != (n_x, n_x) or C.shape[1] != n_x or Q.shape != (n_x, n_x) or R.shape != (n_y, n_y):
        raise PfbenchError("inconsistent shapes: A (n_x,n_x), C (n_y,n_x), Q (n_x,n_x), R (n_y,n_y)")
    x0 = np.asarray(x0, dtype=np.float64).reshape(n_x)
    y = np.asarray(y, dtype=np.float64)
    if y.ndim == 1:
        y = y.reshape(-1, n_y)
    if y.ndim != 2 or y.shape[1] != n_y:
        raise PfbenchError(f"y must have shape (M, {n_y}), got {y.shape}")
    M = y.shape[0]
    has_u = u is not None and (B is not None or D is not None)
    if has_u:
        u = np.asarray(u, dtype=np.float64).reshape(M, -1)
        n_u = u.shape[1]
        B = np.zeros((n_x, n_u)) if B is None else _m2(B, "B").reshape(n_x, n_u)
        D = np.zeros((n_y, n_u)) if D is None else _m2(D, "D").reshape(n_y, n_u)

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
        Pp = _sym(A @ P @ A.T + Q)                   # eq. 2.30
        x, P, r, S, K = _update(xp, Pp, y[t], C, R, C @ xp + yhat_off)
        pm[t], pc[t], means[t], covs[t] = xp, Pp, x, P
        innov[t], Ss[t], gains[t] = r, S, K
        inc[t] = gaussian_logpdf(r, S)
    return KalmanResult(means, covs, pm, pc, float(inc.sum()), inc, innov, Ss, gains)


def filter_model(model, y, u=None) -> KalmanResult:
    """Run :func:`kalman_filter` on a :class:`~pfbench.models.linear_gaussian.LinearGaussian` model."""
    n_u = int(getattr(model, "n_u", 0))
    if n_u and u is None:
        raise PfbenchError("this model has inputs: pass u (M, n_u)")
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
    Pp = _sym(F @ np.asarray(P, dtype=np.float64) @ F.T + _m2(Q, "Q"))
    return xp, Pp


def ekf_update(x, P, y, h: Callable, H_jac: Callable, R, u=None, t: int = 0):
    """EKF measurement update ([Thesis], eq. 2.37 linearisation + eqs. 2.31-2.33).

    ``H = dh/dx`` at the predicted state (eq. 2.37), ``K = P H^T (H P H^T + R)^-1``,
    ``x = x + K (y - h(x))``, ``P = (I - K H) P`` (Joseph form).

    Returns
    -------
    (x, P, innovation, innovation_cov)
    """
    x = np.asarray(x, dtype=np.float64)
    P = np.asarray(P, dtype=np.float64)
    H = np.atleast_2d(np.asarray(H_jac(x, u, t), dtype=np.float64))
    yhat = np.atleast_1d(np.asarray(h(x, u, t), dtype=np.float64))
    y = np.atleast_1d(np.asarray(y, dtype=np.float64))
    xn, Pn, r, S, _ = _update(x, P, y, H, _m2(R, "R"), yhat)
    return xn, Pn, r, S


def ekf(f, F_jac, h, H_jac, Q, R, x0, P0, y, u=None) -> KalmanResult:
    """Extended Kalman filter ([Thesis], eqs. 2.36-2.38) built on :func:`ekf_predict` /
    :func:`ekf_update`; same time convention as :func:`kalman_filter`.

    ``loglik`` is the Gaussian approximation sum_t log N(innovation_t; 0, S_t).
    """
    x = np.asarray(x0, dtype=np.float64).ravel().copy()
    P = _m2(P0, "P0").copy()
    n_x = x.shape[0]
    R = _m2(R, "R")
    n_y = R.shape[0]
    y = np.asarray(y, dtype=np.float64).reshape(-1, n_y)
    M = y.shape[0]
    if u is not None:
        u = np.asarray(u, dtype=np.float64).reshape(M, -1)
    means = np.empty((M, n_x)); covs = np.empty((M, n_x, n_x))
    pm = np.empty((M, n_x)); pc = np.empty((M, n_x, n_x))
    inc = np.empty(M); innov = np.empty((M, n_y)); Ss = np.empty((M, n_y, n_y))
    gains = np.empty((M, n_x, n_y))
    for t in range(M):
        ut = None if u is None else u[t]
        xp, Pp = ekf_predict(x, P, f, F_jac, Q, ut, t)
        H = np.atleast_2d(np.asarray(H_jac(xp, ut, t), dtype=np.float64))
        x, P, r, S = ekf_update(xp, Pp, y[t], h, H_jac, R, ut, t)
        pm[t], pc[t], means[t], covs[t] = xp, Pp, x, P
        innov[t], Ss[t] = r, S
        gains[t] = np.linalg.solve(S, (Pp @ H.T).T).T
        inc[t] = gaussian_logpdf(r, S)
    return KalmanResult(means, covs, pm, pc, float(inc.sum()), inc, innov, Ss, gains)


# ----------------------------------------------------------------------------- DARE

def _pbh_uncontrollable(A: np.ndarray, B: np.ndarray, tol: float) -> list:
    """Eigenvalues of A with |lambda| >= 1 - tol that fail the PBH rank test rank[A - lI, B] = n."""
    n = A.shape[0]
    bad = []
    for lam in np.linalg.eigvals(A):
        if abs(lam) < 1.0 - tol:
            continue
        Mx = np.hstack([A - lam * np.eye(n), B.astype(complex)])
        sv = np.linalg.svd(Mx, compute_uv=False)
        if sv.shape[0] < n or sv[n - 1] <= tol * max(1.0, sv[0]):
            bad.append(complex(lam))
    return bad


def dare(A, B, Q, R, *, unit_circle_tol: float = 1e-7, check: bool = True) -> np.ndarray:
    """Stabilising solution of the discrete algebraic Riccati equation by the generalized Schur method.

    Solves ([RTD], eq. 38)::

        X = A^T X A - A^T X B (R + B^T X B)^-1 B^T X A + Q

    following §2.6 of [RTD]: with ``S = B R^-1 B^T`` (eq. 40) form the symplectic pencil
    ``P_DARE - lambda N_DARE`` with ``P_DARE = [[A, 0], [-Q, I]]`` (eq. 41) and
    ``N_DARE = [[I, S], [0, A^T]]`` (eq. 42); bring it to generalized real Schur form by the QZ
    algorithm and reorder so that the n eigenvalues inside the unit circle come first
    (eqs. 43-46, ``scipy.linalg.ordqz(..., sort='iuc')``); with ``Z = [[Z11, Z12], [Z21, Z22]]``
    (eq. 47) the solution is ``X = Z21 Z11^-1``.

    For the Kalman filter of ``x' = A x + w, y = C x + v`` call ``dare(A.T, C.T, Q, R)``: X is then the
    steady-state *prior* error covariance P[n|n-1] ([RTD], eq. 37).

    Parameters
    ----------
    A : (n, n), B : (n, m), Q : (n, n) symmetric PSD, R : (m, m) symmetric positive definite.
    unit_circle_tol : float
        Pencil eigenvalues with ``| |lambda| - 1 | <= unit_circle_tol`` count as on the unit circle.
    check : bool
        Run the PBH stabilisability / detectability tests first (clear error messages).

    Returns
    -------
    X : (n, n) symmetric stabilising solution.

    Raises
    ------
    PfbenchError
        Bad shapes, R not positive definite, (A, B) not stabilisable, (A, Q) not detectable, pencil
        eigenvalues on the unit circle, or a singular Z11.
    """
    from scipy.linalg import ordqz

    A, B, Q, R = _m2(A, "A"), _m2(B, "B"), _m2(Q, "Q"), _m2(R, "R")
    n = A.shape[0]
    if B.shape[0] != n and B.shape == (1, n):
        B = B.T
    m = B.shape[1]
    if A.shape != (n, n) or B.shape != (n, m) or Q.shape != (n, n) or R.shape != (m, m):
        raise PfbenchError(f"dare: inconsistent shapes A {A.shape}, B {B.shape}, Q {Q.shape}, R {R.shape}")
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B)) and np.all(np.isfinite(Q))
            and np.all(np.isfinite(R))):
        raise PfbenchError("dare: matrices contain NaN or inf")
    Q, R = _sym(Q), _sym(R)
    try:
        np.linalg.cholesky(R)
    except np.linalg.LinAlgError:
        raise PfbenchError("dare: R must be symmetric positive definite") from None
    if np.linalg.eigvalsh(Q).min() < -1e-10 * max(1.0, np.abs(Q).max()):
        raise PfbenchError("dare: Q must be symmetric positive semi-definite")
    if check:
        scale = max(1.0, np.abs(A).max())
        bad = _pbh_uncontrollable(A, B, 1e-9 * scale)
        if bad:
            raise PfbenchError(f"dare: (A, B) is not stabilisable (uncontrollable mode at {bad[0]:.6g})")
        w, V = np.linalg.eigh(Q)
        Qh = V * np.sqrt(np.clip(w, 0.0, None))  # Q = Qh Qh^T
        bad = _pbh_uncontrollable(A.T, Qh, 1e-9 * scale)
        if bad:
            raise PfbenchError(f"dare: (A, Q) is not detectable (unobservable mode at {bad[0]:.6g})")

    S = B @ np.linalg.solve(R, B.T)                                   # eq. 40
    I, O = np.eye(n), np.zeros((n, n))
    P_dare = np.block([[A, O], [-Q, I]])                              # eq. 41
    N_dare = np.block([[I, S], [O, A.T]])                             # eq. 42
    _, _, alpha, beta, _, Z = ordqz(P_dare, N_dare, sort="iuc", output="real")  # eqs. 43-46
    mod_a, mod_b = np.abs(alpha), np.abs(beta)
    if np.any((mod_a == 0) & (mod_b == 0)):
        raise PfbenchError("dare: the pencil is singular (no unique solution)")
    on_circle = np.abs(mod_a - mod_b) <= unit_circle_tol * np.maximum(mod_a, mod_b)
    if np.any(on_circle):
        lam = alpha[on_circle][0] / beta[on_circle][0]
        raise PfbenchError(f"dare: the pencil has an eigenvalue on the unit circle ({lam:.6g}); "
                           "the system is not stabilisable/detectable on the unit circle")
    n_stable = int(np.sum(mod_a < mod_b))
    if n_stable != n:
        raise PfbenchError(f"dare: {n_stable} stable pencil eigenvalues instead of {n}")
    Z11, Z21 = Z[:n, :n], Z[n:, :n]                                   # eq. 47
    if np.linalg.cond(Z11) > 1e12:
        raise PfbenchError("dare: Z11 is singular; no stabilising solution")
    X = np.linalg.solve(Z11.T, Z21.T).T                               # X = Z21 Z11^-1
    return _sym(X)


def dare_scalar(a: float, b: float, q: float, r: float) -> float:
    """Closed-form stabilising solution of the scalar DARE ([RTD], eq. 38 with n = m = 1).

    ``x = a^2 x - a^2 b^2 x^2 / (r + b^2 x) + q`` is the quadratic
    ``b^2 x^2 + (r (1 - a^2) - q b^2) x - q r = 0`` whose non-negative root is returned.
    For the Kalman filter of a first-order model pass ``b = c`` (output gain).
    """
    a, b, q, r = float(a), float(b), float(q), float(r)
    if r <= 0 or q < 0:
        raise PfbenchError("dare_scalar: need r > 0 and q >= 0")
    if b == 0.0:
        if abs(a) >= 1.0:
            raise PfbenchError("dare_scalar: b = 0 and |a| >= 1: not stabilisable")
        return q / (1.0 - a * a)
    p = r * (1.0 - a * a) - q * b * b
    disc = p * p + 4.0 * b * b * q * r
    if q == 0.0 and abs(a) >= 1.0 and abs(abs(a) - 1.0) < 1e-12:
        raise PfbenchError("dare_scalar: mode on the unit circle with q = 0: not detectable")
    # numerically stable root of b^2 x^2 + p x - q r = 0
    if p >= 0:
        return float(2.0 * q * r / (p + np.sqrt(disc))) if (p + np.sqrt(disc)) > 0 else 0.0
    return float((-p + np.sqrt(disc)) / (2.0 * b * b))


def chapter_riccati_scalar(F: float, H: float, Q: float, R: float) -> float:
    """The closed form used by the chapter's microcontroller code ([RTD], §6.1).

    ``P_inf = (sqrt(H^2 Q R + F^2 R^2) + F R) / H^2`` with ``F = -Bc`` (RC rate) and ``H = 260``.
    This is the positive root of the *continuous-time* scalar Riccati equation
    ``2 F P - P^2 H^2 / R + Q = 0`` (checked against ``scipy.linalg.solve_continuous_are`` in the
    tests); the discrete-time counterpart is :func:`dare_scalar`.
    """
    F, H, Q, R = float(F), float(H), float(Q), float(R)
    if H == 0 or R <= 0 or Q < 0:
        raise PfbenchError("chapter_riccati_scalar: need H != 0, R > 0, Q >= 0")
    return (np.sqrt(H * H * Q * R + F * F * R * R) + F * R) / (H * H)


def steady_state_gain(A, C, Q, R):
    """Steady-state Kalman filter from the DARE ([RTD], eqs. 30, 37).

    Returns
    -------
    (P_prior, P_post, M) with ``P_prior = dare(A^T, C^T, Q, R)`` (P[n|n-1]),
    ``M = P_prior C^T (C P_prior C^T + R)^-1`` (measurement-update gain, the chapter's M_inf) and
    ``P_post = (I - M C) P_prior`` (P[n|n]). The predictor gain is ``A M``.
    """
    A, C, Q, R = _m2(A, "A"), _m2(C, "C"), _m2(Q, "Q"), _m2(R, "R")
    P = dare(A.T, C.T, Q, R)
    S = C @ P @ C.T + R
    M = np.linalg.solve(S, C @ P).T
    P_post = _sym((np.eye(A.shape[0]) - M @ C) @ P)
    return P, P_post, M


@dataclass
class RecursiveKFResult:
    """Output of :func:`time_varying_kf` / :func:`steady_state_kf` (chapter's variable names).

    x_filt (n, n_x) x[n|n]; x_pred (n, n_x) x[n+1|n]; yest (n,) C x[n|n] (yetv);
    ypred (n,) C x[n+1|n] (the one-step predictor); errcov (n,) C P[n|n] C^T; gains (n, n_x, n_y).
    """

    x_filt: np.ndarray
    x_pred: np.ndarray
    yest: np.ndarray
    ypred: np.ndarray
    errcov: np.ndarray
    gains: np.ndarray


def _prep_loop(A, B, C, Q, R, u, y, x0):
    A, C, Q, R = _m2(A, "A"), _m2(C, "C"), _m2(Q, "Q"), _m2(R, "R")
    n_x, n_y = A.shape[0], C.shape[0]
    y = np.asarray(y, dtype=np.float64).reshape(-1, n_y)
    n = y.shape[0]
    if B is None:
        B = np.zeros((n_x, 1)); u = np.zeros((n, 1))
    else:
        B = np.asarray(B, dtype=np.float64).reshape(n_x, -1)
        u = np.zeros((n, B.shape[1])) if u is None else np.asarray(u, dtype=np.float64).reshape(n, -1)
    x = np.zeros(n_x) if x0 is None else np.asarray(x0, dtype=np.float64).reshape(n_x).copy()
    return A, B, C, Q, R, u, y, x


def time_varying_kf(A, B, C, Q, R, u, y, *, x0=None, P0=None) -> RecursiveKFResult:
    """Time-varying Kalman filter, the loop of [RTD] §4.2.1 (measurement update, then time update).

    For i = 0..n-1::

        M  = P C^T (C P C^T + R)^-1            (eq. 20)
        x  = x + M (y_i - C x)      P = (I - M C) P        (x[n|n], P[n|n]; eqs. 12, 21)
        yest_i = C x,  errcov_i = C P C^T
        x  = A x + B u_i            P = A P A^T + Q        (x[n+1|n], P[n+1|n]; eqs. 22, 25)

    Parameters
    ----------
    Q : (n_x, n_x) state process-noise covariance (the chapter uses ``B Qu B^T`` with a scalar input
        noise Qu). P0 defaults to Q (the chapter's ``Ptv = B*Q*B'``), x0 to zeros.
    """
    A, B, C, Q, R, u, y, x = _prep_loop(A, B, C, Q, R, u, y, x0)
    n, n_x, n_y = y.shape[0], A.shape[0], C.shape[0]
    P = Q.copy() if P0 is None else _m2(P0, "P0").copy()
    xf = np.empty((n, n_x)); xp = np.empty((n, n_x)); gains = np.empty((n, n_x, n_y))
    errcov = np.empty(n)
    I = np.eye(n_x)
    for i in range(n):
        Mn = np.linalg.solve(C @ P @ C.T + R, C @ P).T
        x = x + Mn @ (y[i] - C @ x)
        P = _sym((I - Mn @ C) @ P)
        xf[i] = x
        errcov[i] = (C @ P @ C.T)[0, 0]
        gains[i] = Mn
        x = A @ x + B @ u[i]
        P = _sym(A @ P @ A.T + Q)
        xp[i] = x
    return RecursiveKFResult(xf, xp, xf @ C[0], xp @ C[0], errcov, gains)


def steady_state_kf(A, B, C, Q, R, u, y, *, x0=None) -> RecursiveKFResult:
    """Steady-state Kalman filter with the DARE gain ([RTD] §4.2.1 second loop / §6.1 ``x_inf``).

    Same loop as :func:`time_varying_kf` with the constant gain ``M_inf`` of
    :func:`steady_state_gain`; ``errcov`` is the constant ``C P[n|n] C^T``.
    """
    A, B, C, Q, R, u, y, x = _prep_loop(A, B, C, Q, R, u, y, x0)
    _, P_post, M = steady_state_gain(A, C, Q, R)
    n, n_x = y.shape[0], A.shape[0]
    xf = np.empty((n, n_x)); xp = np.empty((n, n_x))
    for i in range(n):
        x = x + M @ (y[i] - C @ x)
        xf[i] = x
        x = A @ x + B @ u[i]
        xp[i] = x
    errcov = np.full(n, (C @ P_post @ C.T)[0, 0])
    return RecursiveKFResult(xf, xp, xf @ C[0], xp @ C[0], errcov,
                             np.broadcast_to(M, (n,) + M.shape).copy())
