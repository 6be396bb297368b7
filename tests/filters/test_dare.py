"""Tests of pfbench.filters.dare: the DARE ([RTD] eqs. 38, 41-42) vs scipy, its failure modes and
the scalar closed forms. Each defect test names the bug it catches."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sl

from pfbench import kalman
from pfbench.errors import InputError, NumericalError, PfbenchError
from pfbench.filters import dare as dare_module

# the system of the audit: one input, an unstable mode (1.1) and a stable one (0.7)
A2 = np.array([[1.1, 0.2], [0.0, 0.7]])
B2 = np.array([[1.0], [1.0]])


def _dare_residual(X, A, B, Q, R):
    G = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
    return A.T @ X @ A - A.T @ X @ B @ G + Q - X


def _random_problem(rng, k, n=None):
    n = int(rng.integers(1, 7)) if n is None else n
    m = int(rng.integers(1, 4))
    A = rng.standard_normal((n, n)) * (1.3 if k % 3 == 0 else 0.7)   # a third of them open-loop unstable
    B = rng.standard_normal((n, m))
    G = rng.standard_normal((n, n)); Q = G @ G.T + (0.0 if k % 5 == 0 else 0.01) * np.eye(n)
    H = rng.standard_normal((m, m)); R = H @ H.T + 0.1 * np.eye(m)
    return A, B, Q, R


def _rel(X, ref):
    return np.abs(X - ref).max() / np.abs(ref).max()


def test_dare_matches_scipy_on_random_systems():
    rng = np.random.default_rng(2024)
    worst = 0.0
    for k in range(300):
        A, B, Q, R = _random_problem(rng, k)
        X = kalman.dare(A, B, Q, R)
        Xs = sl.solve_discrete_are(A, B, Q, R)
        scale = max(1.0, np.abs(Xs).max())
        worst = max(worst, np.abs(X - Xs).max() / scale)
        assert np.abs(_dare_residual(X, A, B, Q, R)).max() <= 1e-8 * scale * max(1.0, np.abs(A).max() ** 2)
        assert kalman.dare_residual(X, A, B, Q, R) <= dare_module.RESIDUAL_TOL
        # stabilising: closed-loop A - B K inside the unit circle; symmetric PSD
        K = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
        assert np.abs(np.linalg.eigvals(A - B @ K)).max() < 1.0
        assert np.allclose(X, X.T, atol=0)
        assert np.linalg.eigvalsh(X).min() >= -1e-9 * scale
    assert worst < 1e-7


# ----------------------------------------------------------------------------- audit defects

@pytest.mark.parametrize("q", [1e8, 1e9, 1e12, 1e-8])
def test_dare_large_and_small_q_over_r(q):
    """Bug: without balancing the pencil of eqs. 41-42 gave a 47 % wrong X for Q/R = 1e8 (no error)
    and let scipy's ValueError out of ordqz for Q/R = 1e9; without Newton refinement Q/R = 1e12 is
    off by 6e-5. scipy's own relative residual on these cases is <= 4e-14, so it is the reference
    for q >= 1; for q = 1e-8 scipy's residual is 1.5e-4, so the reference there is the homogeneity
    X(cQ, cR) = c X(Q, R) with the well-scaled problem q = 1, r = 1e8."""
    Q, R = q * np.eye(2), np.eye(1)
    X = kalman.dare(A2, B2, Q, R)
    if q >= 1.0:
        assert _rel(X, sl.solve_discrete_are(A2, B2, Q, R)) < 1e-9
    else:
        X1 = kalman.dare(A2, B2, np.eye(2), np.eye(1) / q)
        assert _rel(X, q * X1) < 1e-9
    # homogeneity of the DARE: X(cQ, cR) = c X(Q, R) (c = 1/q brings the problem to Q = I)
    assert _rel(X, q * kalman.dare(A2, B2, np.eye(2), R / q)) < 1e-9
    assert kalman.dare_residual(X, A2, B2, Q, R) < 1e-14


@pytest.mark.parametrize("q", [10.0 ** k for k in range(-12, 17, 2)])
@pytest.mark.parametrize("r", [1e-12, 1e-6, 1.0, 1e6, 1e12])
def test_dare_raises_only_pfbench_errors(q, r):
    """Bug: finite inputs let raw scipy/numpy exceptions escape (ValueError from ordqz at Q = 1e9).
    Every outcome must be a verified X or a PfbenchError."""
    try:
        X = kalman.dare(A2, B2, q * np.eye(2), r * np.eye(1))
    except PfbenchError as exc:
        assert isinstance(exc, NumericalError)
        return
    assert kalman.dare_residual(X, A2, B2, q * np.eye(2), r * np.eye(1)) <= dare_module.RESIDUAL_TOL


def test_dare_ill_conditioned_message():
    """Bug: Q = 1e8, R = 1e-8 (||Q|| ||B R^-1 B^T|| ~ 1/eps: the pencil cannot separate its
    eigenvalues) said only '3 stable pencil eigenvalues instead of 2'. It must say that no
    stabilising solution was found to the required accuracy because the problem is ill-conditioned."""
    with pytest.raises(NumericalError, match="required accuracy.*ill-conditioned"):
        kalman.dare(A2, B2, 1e8 * np.eye(2), 1e-8 * np.eye(1))


def test_dare_residual_check_refuses_inaccurate_solutions(monkeypatch):
    """The residual check of eq. 38 is the last line of defence: with the refinement switched off,
    the unbalanced pencil's 47 %-wrong X for Q/R = 1e8 (relative residual 9e-2) and the balanced
    pencil's X for Q/R = 1e12 (6e-5 wrong, residual 1e-5) must both be refused, not returned.
    Catches a removed or loosened residual check."""
    monkeypatch.setattr(dare_module, "NEWTON_STEPS", 0)
    with pytest.raises(NumericalError, match="residual"):
        kalman.dare(A2, B2, 1e8 * np.eye(2), np.eye(1), balance=False)
    with pytest.raises(NumericalError, match="residual"):
        kalman.dare(A2, B2, 1e12 * np.eye(2), np.eye(1))
    # and the same problems well conditioned enough for the raw Schur solution still pass
    X = kalman.dare(A2, B2, 1e4 * np.eye(2), np.eye(1))
    assert _rel(X, sl.solve_discrete_are(A2, B2, 1e4 * np.eye(2), np.eye(1))) < 1e-8


def test_dare_refuses_a_non_stabilising_solution(monkeypatch):
    """eq. 38 has other solutions than the stabilising one: a = 2, b = 1, q = 0, r = 1 is also solved
    by x = 0 (closed loop a = 2). Ordering the pencil the wrong way round (outside the unit circle
    first) yields it with a zero residual; the closed-loop check must refuse it. Catches a removed
    stability check."""
    import scipy.linalg

    ordqz = scipy.linalg.ordqz
    monkeypatch.setattr(scipy.linalg, "ordqz",
                        lambda P, N, sort, output: ordqz(P, N, sort="ouc", output=output))
    with pytest.raises(NumericalError, match="spectral radius"):
        kalman.dare([[2.0]], [[1.0]], [[0.0]], [[1.0]])


def test_dare_badly_scaled_coordinates():
    """Bug: the PBH controllability tolerance was scaled twice (1e-9 * max|A| * max(1, sv_max)), so
    controllable pairs in badly scaled coordinates were refused as 'not stabilisable' (most random
    systems under T = diag(1e-3, 1, 1e3)). The same problem in coordinates x' = T x has the solution
    X' = T^-T X T^-1, i.e. T^T X' T = X."""
    T = np.diag([1e-3, 1.0, 1e3])
    Ti = np.diag(1.0 / np.diag(T))
    rng = np.random.default_rng(77)
    for k in range(60):
        A, B, Q, R = _random_problem(rng, k, n=3)
        X = sl.solve_discrete_are(A, B, Q, R)
        Xp = kalman.dare(T @ A @ Ti, T @ B, Ti.T @ Q @ Ti, R)
        assert _rel(T.T @ Xp @ T, X) < 1e-6


def test_dare_q_zero_unstable_a_has_stabilising_solution():
    """Bug: detectability of (A, Q) was required, but only unobservable modes ON the unit circle
    prevent a stabilising solution. a = 2, b = 1, q = 0, r = 1: x = r (a^2 - 1) / b^2 = 3."""
    assert kalman.dare([[2.0]], [[1.0]], [[0.0]], [[1.0]])[0, 0] == pytest.approx(3.0, rel=1e-12)
    assert kalman.dare_scalar(2.0, 1.0, 0.0, 1.0) == pytest.approx(3.0, rel=1e-12)
    assert sl.solve_discrete_are([[2.0]], [[1.0]], [[0.0]], [[1.0]])[0, 0] == pytest.approx(3.0, rel=1e-12)
    # a matrix case: Q = 0 with one unstable and one stable mode
    Q0 = np.zeros((2, 2))
    X = kalman.dare(A2, B2, Q0, np.eye(1))
    assert _rel(X, sl.solve_discrete_are(A2, B2, Q0, np.eye(1))) < 1e-9
    K = np.linalg.solve(np.eye(1) + B2.T @ X @ B2, B2.T @ X @ A2)
    assert np.abs(np.linalg.eigvals(A2 - B2 @ K)).max() < 1.0
    rng = np.random.default_rng(8)
    for _ in range(50):
        a, b, r = rng.uniform(1.05, 3.0) * rng.choice([-1, 1]), rng.uniform(0.2, 3.0), rng.uniform(0.1, 3.0)
        x = kalman.dare([[a]], [[b]], [[0.0]], [[r]])[0, 0]
        assert x == pytest.approx(kalman.dare_scalar(a, b, 0.0, r), rel=1e-10)
        assert x == pytest.approx(r * (a * a - 1.0) / (b * b), rel=1e-10)


def test_dare_rejects_row_b():
    """Bug: B given as a (1, n) row was transposed silently."""
    with pytest.raises(InputError, match="shape"):
        kalman.dare(0.5 * np.eye(2), np.ones((1, 2)), np.eye(2), np.eye(1))
    # a flat vector of length n is unambiguous: one column
    np.testing.assert_array_equal(kalman.dare(A2, np.ones(2), np.eye(2), np.eye(1)),
                                  kalman.dare(A2, np.ones((2, 1)), np.eye(2), np.eye(1)))


# ----------------------------------------------------------------------------- error cases

@pytest.mark.parametrize("args,exc,msg", [
    ((np.array([[2.0]]), np.array([[0.0]]), np.eye(1), np.eye(1)), NumericalError, "not stabilisable"),
    ((np.diag([0.5, 1.0]), np.array([[1.0], [0.0]]), np.eye(2), np.eye(1)), NumericalError, "not stabilisable"),
    ((np.diag([0.5, 1.5]), np.array([[1.0], [0.0]]), np.eye(2), np.eye(1)), NumericalError, "not stabilisable"),
    ((np.array([[1.0]]), np.array([[1.0]]), np.zeros((1, 1)), np.eye(1)), NumericalError,
     "not detectable on the unit circle"),
    ((np.eye(1), np.eye(1), np.eye(1), -np.eye(1)), InputError, "positive definite"),
    ((np.eye(2), np.eye(1), np.eye(2), np.eye(1)), InputError, "shapes"),
    ((np.eye(2), np.ones((2, 1)), -np.eye(2), np.eye(1)), InputError, "semi-definite"),
    ((np.eye(2) * np.nan, np.ones((2, 1)), np.eye(2), np.eye(1)), InputError, "NaN"),
])
def test_dare_error_cases(args, exc, msg):
    with pytest.raises(exc, match=msg):
        kalman.dare(*args)


def test_dare_unit_circle_modes():
    # a rotation (|lambda| = 1) controlled but with no state weight: the pencil has eigenvalues on
    # the unit circle, unobservable modes of (A, Q) there
    c, s = np.cos(0.3), np.sin(0.3)
    A = np.array([[c, -s], [s, c]])
    with pytest.raises(NumericalError, match="unit circle"):
        kalman.dare(A, np.array([[1.0], [0.0]]), np.zeros((2, 2)), np.eye(1))
    # the same rotation observed through Q is fine (scipy agrees)
    X = kalman.dare(A, np.array([[1.0], [0.0]]), np.eye(2), np.eye(1))
    assert _rel(X, sl.solve_discrete_are(A, np.array([[1.0], [0.0]]), np.eye(2), np.eye(1))) < 1e-10


def test_dare_scalar_closed_form_matches_general():
    rng = np.random.default_rng(5)
    for _ in range(200):
        a = rng.uniform(-2.0, 2.0); b = rng.uniform(-3.0, 3.0)
        q = rng.uniform(0.01, 5.0); r = rng.uniform(0.01, 5.0)
        x = kalman.dare_scalar(a, b, q, r)
        X = kalman.dare([[a]], [[b]], [[q]], [[r]])[0, 0]
        assert x == pytest.approx(X, rel=1e-9, abs=1e-12)
        assert x == pytest.approx(sl.solve_discrete_are([[a]], [[b]], [[q]], [[r]])[0, 0], rel=1e-9)
    assert kalman.dare_scalar(0.5, 0.0, 1.0, 1.0) == pytest.approx(1.0 / 0.75)
    # large c = 260 (the chapter's amplifier gain) with tiny q: no cancellation
    assert kalman.dare_scalar(0.9, 260.0, 1e-6, 1.0) == pytest.approx(
        kalman.dare([[0.9]], [[260.0]], [[1e-6]], [[1.0]])[0, 0], rel=1e-9)
    with pytest.raises(NumericalError):
        kalman.dare_scalar(1.5, 0.0, 1.0, 1.0)
    with pytest.raises(NumericalError):
        kalman.dare_scalar(1.0, 1.0, 0.0, 1.0)
    with pytest.raises(InputError):
        kalman.dare_scalar(0.5, 1.0, 1.0, 0.0)


def test_chapter_formula_is_continuous_time_riccati():
    rng = np.random.default_rng(9)
    for _ in range(50):
        F = rng.uniform(-3, 1); H = rng.uniform(0.5, 300); Q = rng.uniform(0.01, 3); R = rng.uniform(0.01, 3)
        p = kalman.chapter_riccati_scalar(F, H, Q, R)
        assert p == pytest.approx(sl.solve_continuous_are([[F]], [[H]], [[Q]], [[R]])[0, 0], rel=1e-9)
    with pytest.raises(InputError):
        kalman.chapter_riccati_scalar(-1.0, 0.0, 1.0, 1.0)


def test_steady_state_gain_is_the_kalman_fixed_point():
    """P_prior solves P = A (P - P C^T S^-1 C P) A^T + Q ([RTD] eq. 37); M and P_post follow."""
    rng = np.random.default_rng(31)
    A, C = rng.standard_normal((3, 3)) * 0.8, rng.standard_normal((2, 3))
    G = rng.standard_normal((3, 3)); Q = G @ G.T + 0.1 * np.eye(3); R = np.diag([0.5, 2.0])
    P, P_post, M = kalman.steady_state_gain(A, C, Q, R)
    S = C @ P @ C.T + R
    np.testing.assert_allclose(M, P @ C.T @ np.linalg.inv(S), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(P_post, P - M @ S @ M.T, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(A @ P_post @ A.T + Q, P, rtol=1e-10, atol=1e-12)
    with pytest.raises(InputError):
        kalman.steady_state_gain(A, C[:, :2], Q, R)
