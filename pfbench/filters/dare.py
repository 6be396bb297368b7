"""The discrete algebraic Riccati equation (DARE) by the generalized Schur method, [RTD] §2.6.

:func:`dare` solves ([RTD], eq. 38)::

    X = A^T X A - A^T X B (R + B^T X B)^-1 B^T X A + Q

for its stabilising solution; :func:`dare_scalar` is the closed form for n = m = 1,
:func:`chapter_riccati_scalar` the formula of the chapter's microcontroller code and
:func:`steady_state_gain` the steady-state Kalman filter built on the DARE ([RTD], eqs. 30, 37).

When it exists. With R > 0 and Q >= 0 the DARE has a (unique) stabilising solution -- one for
which ``A - B K``, ``K = (R + B^T X B)^-1 B^T X A``, has every eigenvalue inside the unit circle --
if and only if (A, B) is stabilisable and (A, Q^1/2) has no unobservable mode ON the unit circle.
Detectability of (A, Q^1/2) (no unobservable mode on or outside the circle) is the textbook
condition for the stabilising solution to also be the unique positive semi-definite one; it is not
needed for existence: a = 2, b = 1, q = 0, r = 1 has the stabilising solution x = 3 (and the
non-stabilising x = 0).

How :func:`dare` makes sure of its answer
    1. the pencil of eqs. 41-42 is balanced by an exact (powers of two) symplectic diagonal
       scaling (the state transformation x -> D x, chosen as in Benner's symplectic balancing);
       it includes the homogeneous scaling X(cQ, cR) = c X(Q, R) of the equation as the case D = tI;
    2. its stable deflating subspace gives X = Z21 Z11^-1 ([RTD] eqs. 43-47);
    3. Newton's method (the third class of DARE solvers named in [RTD] §2.6) refines X in
       defect-correction form;
    4. X is accepted only if its relative residual in eq. 38 is at most :data:`RESIDUAL_TOL` and
       ``A - B K`` is stable. Otherwise a :class:`~pfbench.errors.NumericalError` says why: an
       uncontrollable mode on or outside the unit circle, an unobservable mode of (A, Q) on it, or
       (when neither is found) that no stabilising solution could be computed to the required
       accuracy.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import InputError, NumericalError

__all__ = ["dare", "dare_residual", "dare_scalar", "chapter_riccati_scalar", "steady_state_gain",
           "RESIDUAL_TOL", "PBH_RTOL"]

#: Largest relative residual of eq. 38 (see :func:`dare_residual`) that :func:`dare` accepts. The
#: QZ algorithm is backward stable, so on a well-conditioned problem X = Z21 Z11^-1 already has a
#: relative residual of order n eps cond(Z11), and Newton corrections bring it down to the rounding
#: floor (<= 1.5e-14 on the 300 random systems of the tests, <= 6e-12 over Q/R from 1e-24 to 1e28).
#: 1e-8 (about sqrt(eps)) leaves several orders of magnitude above that floor, yet refuses any X
#: that satisfies eq. 38 to fewer than about eight digits (the 47 %-wrong answer of the unbalanced
#: pencil for Q/R = 1e8 had 9e-2).
RESIDUAL_TOL = 1e-8
#: PBH rank test: [A - lambda I, F] is rank deficient when its smallest singular value is at most
#: PBH_RTOL times its largest. A computed eigenvalue of an uncontrollable mode is off by
#: O(eps ||A|| kappa(lambda)), and so is that smallest singular value; sqrt(eps) ~ 1.5e-8 allows
#: eigenvalue condition numbers up to ~1e8. The test only chooses the error message after the
#: solver has failed, so a borderline value never refuses a solvable problem.
PBH_RTOL = 1e-8
#: At most this many Newton corrections (each costs one Stein equation); refinement stops earlier
#: at a residual of a few eps.
NEWTON_STEPS = 4


# ----------------------------------------------------------------------------- input checks

def as_matrix(a, name: str, func: str = "") -> np.ndarray:
    """``a`` as a float64 matrix; a scalar becomes (1, 1). Raises InputError for ndim > 2."""
    a = np.asarray(a, dtype=np.float64)
    if a.ndim > 2:
        raise InputError(f"{func + ': ' if func else ''}{name} must be a matrix, got shape {a.shape}")
    return np.atleast_2d(a)


def shaped(a, shape: tuple, name: str, func: str = "") -> np.ndarray:
    """``a`` as a float64 array of exactly ``shape`` (a matrix or a vector).

    A flat vector is accepted for a single-column or single-row matrix of the same length (it is
    unambiguous); any other mismatch -- in particular a row given where a column is expected --
    is an InputError naming the expected shape. Nothing is transposed or reshaped silently.
    """
    a = np.asarray(a, dtype=np.float64)
    if a.shape == tuple(shape):
        return a
    if a.ndim <= 1 and len(shape) == 2 and 1 in shape and a.size == shape[0] * shape[1]:
        return a.reshape(shape)
    if len(shape) == 1 and a.size == shape[0] and a.ndim == 2 and 1 in a.shape:
        return a.reshape(shape)
    pre = f"{func}: " if func else ""
    hint = " (a row where a column is expected: pass it as a column)" if (
        len(shape) == 2 and a.ndim == 2 and a.shape == (shape[1], shape[0]) and shape[1] == 1) else ""
    raise InputError(f"{pre}{name} must have shape {tuple(shape)}, got {a.shape}{hint}")


def symmetrize(p: np.ndarray) -> np.ndarray:
    """The symmetric part (p + p^T) / 2."""
    return 0.5 * (p + p.T)


def _check_finite(func: str, **arrays) -> None:
    for name, a in arrays.items():
        if not np.all(np.isfinite(a)):
            raise InputError(f"{func}: {name} contains NaN or inf")


def _dare_inputs(A, B, Q, R):
    A = as_matrix(A, "A", "dare")
    n = A.shape[0]
    if A.shape != (n, n):
        raise InputError(f"dare: A must be square (n, n), got shape {A.shape}")
    B = np.asarray(B, dtype=np.float64)
    if B.ndim <= 1 and B.size == n:
        B = B.reshape(n, 1)
    if B.ndim != 2 or B.shape[0] != n:
        hint = " (a row vector? B must be a column)" if B.ndim == 2 and B.shape == (1, n) and n > 1 else ""
        raise InputError(f"dare: inconsistent shapes: B must be (n, m) with n = {n} rows, "
                         f"got B {B.shape}{hint}")
    m = B.shape[1]
    Q, R = as_matrix(Q, "Q", "dare"), as_matrix(R, "R", "dare")
    if Q.shape != (n, n) or R.shape != (m, m) or m == 0:
        raise InputError(f"dare: inconsistent shapes A {A.shape}, B {B.shape}, Q {Q.shape}, R {R.shape}; "
                         "need A (n, n), B (n, m), Q (n, n), R (m, m), m >= 1")
    _check_finite("dare", A=A, B=B, Q=Q, R=R)
    Q, R = symmetrize(Q), symmetrize(R)
    try:
        L = np.linalg.cholesky(R)
    except np.linalg.LinAlgError:
        raise InputError("dare: R must be symmetric positive definite") from None
    w = np.linalg.eigvalsh(Q)
    if w[0] < -1e-10 * max(abs(w[0]), abs(w[-1])):      # relative: Q may be on any scale
        raise InputError(f"dare: Q must be symmetric positive semi-definite (eigenvalue {w[0]:.3g})")
    return A, B, Q, L


# ----------------------------------------------------------------------------- pieces

def _pencil(A: np.ndarray, Q: np.ndarray, S: np.ndarray):
    """``P_DARE`` (eq. 41) and ``N_DARE`` (eq. 42) of [RTD] §2.6."""
    n = A.shape[0]
    I, O = np.eye(n), np.zeros((n, n))
    return np.block([[A, O], [-Q, I]]), np.block([[I, S], [O, A.T]])


def _symplectic_scaling(A: np.ndarray, Q: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Diagonal d (powers of two) of the state scaling that balances the pencil of eqs. 41-42.

    The row/column sums of ``|P_DARE| + |N_DARE|`` (diagonal removed) are balanced by LAPACK's
    xGEBAL (``scipy.linalg.matrix_balance``); the general scaling diag(2^l1, 2^l2) it returns is
    projected on the symplectic ones diag(D, D^-1), ``D = diag(2^round((l2 - l1) / 2))``, which are
    exactly the state transformations ``A -> D A D^-1``, ``Q -> D^-1 Q D^-1``, ``S -> D S D``,
    ``X -> D^-1 X D^-1`` (Benner's symplectic balancing). Powers of two keep the scaling exact.
    """
    from scipy.linalg import matrix_balance

    n = A.shape[0]
    P, N = _pencil(A, Q, S)
    M = np.abs(P) + np.abs(N)
    np.fill_diagonal(M, 0.0)
    if not M.any():
        return np.ones(n)
    _, (sca, _) = matrix_balance(M, permute=False, separate=True)
    lg = np.log2(sca)
    return 2.0 ** np.round(0.5 * (lg[n:] - lg[:n]))


def _residual(X, A, Bn, Q):
    """eq. 38 with normalised input ``Bn = B R^-1/2`` (R -> I): residual, its relative size, gain."""
    BtX = Bn.T @ X
    BtXA = BtX @ A
    G = np.linalg.solve(np.eye(Bn.shape[1]) + BtX @ Bn, BtXA)           # K = (R + B^T X B)^-1 B^T X A
    res = symmetrize(Q + A.T @ X @ A - BtXA.T @ G - X)
    absA = np.abs(A)
    # every term at its rounding-error scale (|A|^T |X| |A| bounds the error of computing A^T X A)
    scale = (np.linalg.norm(Q) + np.linalg.norm(X) + np.linalg.norm(absA.T @ np.abs(X) @ absA)
             + np.linalg.norm(np.abs(BtXA).T @ np.abs(G)))
    rel = float(np.linalg.norm(res) / scale) if scale > 0 else 0.0
    return res, rel, G


def _spectral_radius(M: np.ndarray) -> float:
    return float(np.abs(np.linalg.eigvals(M)).max()) if M.size else 0.0


def _refine(X, A, Bn, Q):
    """Newton's method for eq. 38 in defect-correction form: with the closed loop
    ``A_k = A - B K(X)`` solve the Stein equation ``A_k^T D A_k - D + Res(X) = 0`` and set
    ``X <- X + D``. From a stabilising X every iterate is stabilising and the residual falls
    quadratically down to the rounding floor, around which it then wanders; the best of at most
    :data:`NEWTON_STEPS` iterates is returned as (X, relative residual, K)."""
    from scipy.linalg import LinAlgWarning, solve_discrete_lyapunov

    res, rel, G = _residual(X, A, Bn, Q)
    best = (X, rel, G)
    for _ in range(NEWTON_STEPS):
        if rel <= 4 * np.finfo(float).eps:
            break
        Ak = A - Bn @ G
        if not _spectral_radius(Ak) < 1.0:
            break
        try:
            with warnings.catch_warnings():   # an ill-conditioned Stein equation: the check decides
                warnings.simplefilter("ignore", LinAlgWarning)
                X = symmetrize(X + solve_discrete_lyapunov(Ak.T, res))
        except (np.linalg.LinAlgError, ValueError):
            break
        if not np.all(np.isfinite(X)):
            break
        res, rel, G = _residual(X, A, Bn, Q)
        if rel < best[1]:
            best = (X, rel, G)
    return best


def _pbh_deficient(A: np.ndarray, F: np.ndarray, lam: complex) -> bool:
    """PBH test: is ``[A - lam I, F]`` rank deficient (relative tolerance :data:`PBH_RTOL`)?"""
    n = A.shape[0]
    sv = np.linalg.svd(np.hstack([A - lam * np.eye(n), F.astype(complex)]), compute_uv=False)
    return bool(sv[0] == 0.0 or sv[n - 1] <= PBH_RTOL * sv[0])


def _no_solution(reason: str, A, Bn, Q, tol: float) -> NumericalError:
    """The error for a failed solve: the structural cause if the PBH tests find one, else ``reason``."""
    lams = np.linalg.eigvals(A)
    for lam in lams:
        if abs(lam) >= 1.0 - tol and _pbh_deficient(A, Bn, lam):
            return NumericalError(f"dare: no stabilising solution: (A, B) is not stabilisable "
                                  f"(uncontrollable mode at {complex(lam):.6g})")
    w, V = np.linalg.eigh(Q)
    Qh = V * np.sqrt(np.clip(w, 0.0, None))                           # Q = Qh Qh^T
    for lam in lams:
        if abs(abs(lam) - 1.0) <= tol and _pbh_deficient(A.T, Qh, lam):
            return NumericalError(f"dare: no stabilising solution: (A, Q) is not detectable on the unit "
                                  f"circle (unobservable mode at {complex(lam):.6g})")
    return NumericalError(f"dare: no stabilising solution found to the required accuracy: {reason}")


# ----------------------------------------------------------------------------- the solver

def dare(A, B, Q, R, *, unit_circle_tol: float = 1e-7, balance: bool = True) -> np.ndarray:
    """Stabilising solution of the discrete algebraic Riccati equation by the generalized Schur method.

    Solves ([RTD], eq. 38)::

        X = A^T X A - A^T X B (R + B^T X B)^-1 B^T X A + Q

    following §2.6 of [RTD]: with ``S = B R^-1 B^T`` (eq. 40) form the symplectic pencil
    ``P_DARE - lambda N_DARE`` with ``P_DARE = [[A, 0], [-Q, I]]`` (eq. 41) and
    ``N_DARE = [[I, S], [0, A^T]]`` (eq. 42); bring it to generalized real Schur form by the QZ
    algorithm and reorder so that the n eigenvalues inside the unit circle come first
    (eqs. 43-46, ``scipy.linalg.ordqz(..., sort='iuc')``); with ``Z = [[Z11, Z12], [Z21, Z22]]``
    (eq. 47) the solution is ``X = Z21 Z11^-1``. The pencil is balanced first and X is refined by
    Newton's method and verified (see the module docstring): an X that does not satisfy eq. 38 to
    :data:`RESIDUAL_TOL` or is not stabilising is never returned.

    For the Kalman filter of ``x' = A x + w, y = C x + v`` call ``dare(A.T, C.T, Q, R)``: X is then the
    steady-state *prior* error covariance P[n|n-1] ([RTD], eq. 37).

    Parameters
    ----------
    A : (n, n); B : (n, m) (a flat vector of length n is one column; a (1, n) row is refused);
    Q : (n, n) symmetric PSD; R : (m, m) symmetric positive definite (the symmetric parts of Q and R
        are used).
    unit_circle_tol : float
        Pencil eigenvalues with ``| |lambda| - 1 | <= unit_circle_tol`` count as on the unit circle;
        the same tolerance selects the modes the PBH diagnostics examine.
    balance : bool
        Balance the pencil (default). Turn off only to study what the balancing buys.

    Returns
    -------
    X : (n, n) symmetric stabilising solution.

    Raises
    ------
    InputError
        Bad shapes, NaN/inf, R not positive definite, Q not positive semi-definite.
    NumericalError
        No stabilising solution: (A, B) not stabilisable, an unobservable mode of (A, Q) on the
        unit circle, or the problem too ill-conditioned to solve to :data:`RESIDUAL_TOL`.
    """
    from scipy.linalg import ordqz, solve_triangular

    A, B, Q, L = _dare_inputs(A, B, Q, R)
    n = A.shape[0]
    Bn = solve_triangular(L, B.T, lower=True).T                       # B R^-1/2
    S = symmetrize(Bn @ Bn.T)                                         # eq. 40: S = B R^-1 B^T
    d = _symplectic_scaling(A, Q, S) if balance else np.ones(n)
    dd = d[:, None] * d[None, :]
    A = A * (d[:, None] / d[None, :])                                 # D A D^-1
    Bn, Q, S = Bn * d[:, None], Q / dd, S * dd                        # D B, D^-1 Q D^-1, D S D

    P_dare, N_dare = _pencil(A, Q, S)                                 # eqs. 41-42
    try:
        _, _, alpha, beta, _, Z = ordqz(P_dare, N_dare, sort="iuc", output="real")  # eqs. 43-46
    except (ValueError, np.linalg.LinAlgError) as exc:                # LAPACK reordering failure
        raise _no_solution(f"the QZ reordering of the pencil (eqs. 45-46) failed ({exc})",
                           A, Bn, Q, unit_circle_tol) from None
    mod_a, mod_b = np.abs(alpha), np.abs(beta)
    if np.any((mod_a == 0) & (mod_b == 0)):
        raise _no_solution("the pencil of eqs. 41-42 is singular", A, Bn, Q, unit_circle_tol)
    on_circle = np.abs(mod_a - mod_b) <= unit_circle_tol * np.maximum(mod_a, mod_b)
    if np.any(on_circle):
        lam = alpha[on_circle][0] / beta[on_circle][0]
        raise _no_solution(f"the pencil has an eigenvalue on the unit circle ({lam:.6g})",
                           A, Bn, Q, unit_circle_tol)
    n_stable = int(np.sum(mod_a < mod_b))
    if n_stable != n:
        ratio = np.linalg.norm(Q) * np.linalg.norm(S)
        raise _no_solution(f"{n_stable} of the {2 * n} pencil eigenvalues were computed inside the "
                           f"unit circle instead of {n}: the pencil of eqs. 41-42 is too ill-conditioned "
                           f"(||Q|| ||B R^-1 B^T|| = {ratio:.1e})", A, Bn, Q, unit_circle_tol)
    Z11, Z21 = Z[:n, :n], Z[n:, :n]                                   # eq. 47
    if np.linalg.cond(Z11) * np.finfo(float).eps >= 1.0:
        raise _no_solution("Z11 of eq. 47 is singular", A, Bn, Q, unit_circle_tol)
    X = symmetrize(np.linalg.solve(Z11.T, Z21.T).T)                   # X = Z21 Z11^-1
    try:
        if not np.all(np.isfinite(X)):
            raise np.linalg.LinAlgError("X = Z21 Z11^-1 is not finite")
        X, rel, G = _refine(X, A, Bn, Q)
        if not rel <= RESIDUAL_TOL:
            raise _no_solution(f"relative residual of eq. 38 is {rel:.1e} > {RESIDUAL_TOL:g}",
                               A, Bn, Q, unit_circle_tol)
        rho = _spectral_radius(A - Bn @ G)
    except np.linalg.LinAlgError as exc:                              # R + B^T X B singular, ...
        raise _no_solution(str(exc), A, Bn, Q, unit_circle_tol) from None
    if not rho < 1.0:
        raise _no_solution(f"the closed loop A - B K has spectral radius {rho:.6g} >= 1",
                           A, Bn, Q, unit_circle_tol)
    return symmetrize(X * dd)                                         # D X~ D (exact)


def dare_residual(X, A, B, Q, R, *, balance: bool = True) -> float:
    """Relative residual of eq. 38 at X, the quantity :func:`dare` checks against
    :data:`RESIDUAL_TOL`: ``||Res||_F`` over the sum of the Frobenius norms of ``Q``, ``X``,
    ``|A|^T |X| |A|`` and ``|A^T X B| |K|`` (the scales at which each term is rounded), evaluated
    with the input normalised to ``R = I`` and, with ``balance``, in the balanced coordinates
    :func:`dare` works in (an exact power-of-two scaling, so the value describes the same X).
    """
    from scipy.linalg import solve_triangular

    A, B, Q, L = _dare_inputs(A, B, Q, R)
    X = symmetrize(shaped(X, A.shape, "X", "dare_residual"))
    Bn = solve_triangular(L, B.T, lower=True).T
    d = _symplectic_scaling(A, Q, symmetrize(Bn @ Bn.T)) if balance else np.ones(A.shape[0])
    dd = d[:, None] * d[None, :]
    return _residual(X / dd, A * (d[:, None] / d[None, :]), Bn * d[:, None], Q / dd)[1]


def dare_scalar(a: float, b: float, q: float, r: float) -> float:
    """Closed-form stabilising solution of the scalar DARE ([RTD], eq. 38 with n = m = 1).

    ``x = a^2 x - a^2 b^2 x^2 / (r + b^2 x) + q`` is the quadratic
    ``b^2 x^2 + (r (1 - a^2) - q b^2) x - q r = 0``; its larger root is the stabilising one
    (closed loop ``a r / (r + b^2 x)``). With q = 0 and |a| > 1 that is ``r (a^2 - 1) / b^2``.
    For the Kalman filter of a first-order model pass ``b = c`` (output gain).
    """
    a, b, q, r = float(a), float(b), float(q), float(r)
    if not all(np.isfinite(v) for v in (a, b, q, r)):
        raise InputError("dare_scalar: a, b, q, r must be finite")
    if r <= 0 or q < 0:
        raise InputError(f"dare_scalar: need r > 0 and q >= 0, got r = {r:g}, q = {q:g}")
    if b == 0.0:
        if abs(a) >= 1.0:
            raise NumericalError("dare_scalar: no stabilising solution: b = 0 and |a| >= 1 "
                                 "(not stabilisable)")
        return q / (1.0 - a * a)
    if q == 0.0 and abs(abs(a) - 1.0) < 1e-12:
        raise NumericalError("dare_scalar: no stabilising solution: |a| = 1 with q = 0 "
                             "(unobservable mode on the unit circle)")
    p = r * (1.0 - a * a) - q * b * b
    disc = p * p + 4.0 * b * b * q * r
    # numerically stable larger root of b^2 x^2 + p x - q r = 0
    if p >= 0:
        den = p + np.sqrt(disc)
        return float(2.0 * q * r / den) if den > 0 else 0.0
    return float((-p + np.sqrt(disc)) / (2.0 * b * b))


def chapter_riccati_scalar(F: float, H: float, Q: float, R: float) -> float:
    """The closed form used by the chapter's microcontroller code ([RTD], §6.1).

    ``P_inf = (sqrt(H^2 Q R + F^2 R^2) + F R) / H^2`` with ``F = -Bc`` (RC rate) and ``H = 260``.
    This is the positive root of the *continuous-time* scalar Riccati equation
    ``2 F P - P^2 H^2 / R + Q = 0`` (checked against ``scipy.linalg.solve_continuous_are`` in the
    tests); the discrete-time counterpart is :func:`dare_scalar`.
    """
    F, H, Q, R = float(F), float(H), float(Q), float(R)
    if not all(np.isfinite(v) for v in (F, H, Q, R)) or H == 0 or R <= 0 or Q < 0:
        raise InputError("chapter_riccati_scalar: need finite values with H != 0, R > 0, Q >= 0")
    return (np.sqrt(H * H * Q * R + F * F * R * R) + F * R) / (H * H)


def steady_state_gain(A, C, Q, R):
    """Steady-state Kalman filter from the DARE ([RTD], eqs. 30, 37).

    Returns
    -------
    (P_prior, P_post, M) with ``P_prior = dare(A^T, C^T, Q, R)`` (P[n|n-1]),
    ``M = P_prior C^T (C P_prior C^T + R)^-1`` (measurement-update gain, the chapter's M_inf) and
    ``P_post = (I - M C) P_prior`` (P[n|n]). The predictor gain is ``A M``.
    """
    A = as_matrix(A, "A", "steady_state_gain")
    n_x = A.shape[0]
    C = as_matrix(C, "C", "steady_state_gain")
    if C.shape[1] != n_x:
        raise InputError(f"steady_state_gain: C must be (n_y, {n_x}), got {C.shape}")
    P = dare(A.T, C.T, Q, R)
    R = as_matrix(R, "R", "steady_state_gain")
    S = C @ P @ C.T + R
    M = np.linalg.solve(S, C @ P).T
    P_post = symmetrize((np.eye(n_x) - M @ C) @ P)
    return P, P_post, M
