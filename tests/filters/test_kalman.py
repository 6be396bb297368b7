"""Tests of pfbench.kalman: KF vs filterpy and brute force, EKF, DARE vs scipy, scalar closed forms."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sl
from scipy.stats import multivariate_normal

from pfbench import kalman
from pfbench.errors import PfbenchError
from pfbench.models.linear_gaussian import LinearGaussian


def random_system(rng, n_x, n_y, n_u=0):
    A = rng.standard_normal((n_x, n_x))
    A *= 0.95 / max(1e-9, np.abs(np.linalg.eigvals(A)).max())
    C = rng.standard_normal((n_y, n_x))
    G = rng.standard_normal((n_x, n_x)); Q = 0.3 * G @ G.T + 0.05 * np.eye(n_x)
    H = rng.standard_normal((n_y, n_y)); R = 0.5 * H @ H.T + 0.1 * np.eye(n_y)
    x0 = rng.standard_normal(n_x)
    L = rng.standard_normal((n_x, n_x)); P0 = L @ L.T + 0.1 * np.eye(n_x)
    B = rng.standard_normal((n_x, n_u)) if n_u else None
    D = rng.standard_normal((n_y, n_u)) if n_u else None
    return A, C, Q, R, x0, P0, B, D


# ----------------------------------------------------------------------------- linear KF

@pytest.mark.parametrize("n_x,n_y,n_u", [(1, 1, 0), (2, 1, 1), (3, 2, 2), (4, 3, 0)])
def test_kf_matches_filterpy(n_x, n_y, n_u):
    from filterpy.kalman import KalmanFilter

    rng = np.random.default_rng(100 + 10 * n_x + n_y)
    A, C, Q, R, x0, P0, B, _ = random_system(rng, n_x, n_y, n_u)
    M = 80
    y = rng.standard_normal((M, n_y)) * 2.0
    u = rng.standard_normal((M, n_u)) if n_u else None
    res = kalman.kalman_filter(A, C, Q, R, x0, P0, y, B=B, u=u)

    kf = KalmanFilter(dim_x=n_x, dim_z=n_y, dim_u=n_u)
    kf.x = x0.reshape(-1, 1).copy(); kf.P = P0.copy(); kf.F = A; kf.H = C; kf.Q = Q; kf.R = R
    if n_u:
        kf.B = B
    for t in range(M):
        kf.predict(u=u[t].reshape(-1, 1) if n_u else None)
        np.testing.assert_allclose(res.pred_means[t], kf.x.ravel(), rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.pred_covs[t], kf.P, rtol=0, atol=1e-10)
        kf.update(y[t].reshape(-1, 1))
        np.testing.assert_allclose(res.means[t], kf.x.ravel(), rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.covs[t], kf.P, rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.loglik_increments[t], kf.log_likelihood, rtol=1e-10, atol=1e-10)


def _brute_force_loglik(A, C, Q, R, x0, P0, y, B=None, D=None, u=None):
    """log N(vec y; mu, Sigma) of the stacked observations (dense joint Gaussian)."""
    M, n_y = y.shape
    n_x = A.shape[0]
    means, V = [], []
    m, P = x0, P0
    for t in range(M):
        m = A @ m + (B @ u[t] if u is not None else 0.0)
        P = A @ P @ A.T + Q
        means.append(m); V.append(P)
    mu = np.concatenate([C @ means[t] + (D @ u[t] if u is not None else 0.0) for t in range(M)])
    S = np.zeros((M * n_y, M * n_y))
    for t in range(M):
        for s in range(t + 1):
            cxx = np.linalg.matrix_power(A, t - s) @ V[s]          # Cov(x_t, x_s), t >= s
            blk = C @ cxx @ C.T + (R if s == t else 0.0)
            S[t * n_y:(t + 1) * n_y, s * n_y:(s + 1) * n_y] = blk
            S[s * n_y:(s + 1) * n_y, t * n_y:(t + 1) * n_y] = blk.T
    return multivariate_normal(mean=mu, cov=S).logpdf(y.ravel())


@pytest.mark.parametrize("n_u", [0, 2])
def test_kf_loglik_matches_dense_gaussian(n_u):
    rng = np.random.default_rng(7 + n_u)
    A, C, Q, R, x0, P0, B, D = random_system(rng, 2, 2, n_u)
    M = 6
    y = rng.standard_normal((M, 2))
    u = rng.standard_normal((M, n_u)) if n_u else None
    res = kalman.kalman_filter(A, C, Q, R, x0, P0, y, B=B, D=D, u=u)
    ref = _brute_force_loglik(A, C, Q, R, x0, P0, y, B, D, u)
    assert res.loglik == pytest.approx(ref, rel=1e-10, abs=1e-10)
    assert res.loglik == pytest.approx(res.loglik_increments.sum(), rel=1e-14)


def test_filter_model_uses_linear_gaussian_convention():
    rng = np.random.default_rng(3)
    A, C, Q, R, x0, P0, B, D = random_system(rng, 3, 2, 1)
    model = LinearGaussian(A=A, C=C, Q=Q, R=R, x0=x0, P0=P0, B=B, D=D)
    tr = model.simulate(40, seed=5)
    res = kalman.filter_model(model, tr.y, tr.u)
    ref = kalman.kalman_filter(A, C, Q, R, x0, P0, tr.y, B=B, D=D, u=tr.u)
    np.testing.assert_array_equal(res.means, ref.means)
    assert res.loglik == ref.loglik
    with pytest.raises(PfbenchError):
        kalman.filter_model(model, tr.y)
    # the simulated trajectory must be consistent with the filter: normalised innovations ~ N(0, 1)
    model2 = LinearGaussian(A=A, C=C, Q=Q, R=R, x0=x0, P0=P0)
    tr2 = model2.simulate(2000, seed=11)
    r2 = kalman.filter_model(model2, tr2.y)
    z = np.concatenate([np.linalg.solve(np.linalg.cholesky(S), e) for S, e in zip(r2.innovation_covs, r2.innovations)])
    # mean of 4000 N(0,1): |mean| < 4/sqrt(4000); variance within 4 sd of chi2 (sd ~ sqrt(2/4000))
    assert abs(z.mean()) < 4 / np.sqrt(z.size)
    assert abs(z.var() - 1.0) < 4 * np.sqrt(2.0 / z.size)


def test_kf_bad_shapes():
    with pytest.raises(PfbenchError):
        kalman.kalman_filter(np.eye(2), np.ones((1, 3)), np.eye(2), np.eye(1), np.zeros(2), np.eye(2), np.zeros((5, 1)))
    with pytest.raises(PfbenchError):
        kalman.kalman_filter(np.eye(2), np.ones((1, 2)), np.eye(2), np.eye(1), np.zeros(2), np.eye(2), np.zeros((5, 2)))


# ----------------------------------------------------------------------------- EKF

def test_ekf_equals_kf_on_linear_model():
    rng = np.random.default_rng(21)
    A, C, Q, R, x0, P0, B, _ = random_system(rng, 3, 2, 1)
    M = 30
    y = rng.standard_normal((M, 2)); u = rng.standard_normal((M, 1))
    ref = kalman.kalman_filter(A, C, Q, R, x0, P0, y, B=B, u=u)
    res = kalman.ekf(lambda x, u, t: A @ x + B @ u, lambda x, u, t: A, lambda x, u, t: C @ x,
                     lambda x, u, t: C, Q, R, x0, P0, y, u=u)
    np.testing.assert_allclose(res.means, ref.means, atol=1e-12)
    np.testing.assert_allclose(res.covs, ref.covs, atol=1e-12)
    assert res.loglik == pytest.approx(ref.loglik, rel=1e-12)


def test_ekf_step_by_hand():
    # x' = sin(x) + w, y = x^2 + v: one predict + update written out ([Thesis], eqs. 2.36-2.38)
    x, P, Q, R, y = 0.7, 0.2, 0.05, 0.1, 0.9
    xp, Pp = kalman.ekf_predict(np.array([x]), np.array([[P]]), lambda x, u, t: np.sin(x),
                                lambda x, u, t: np.array([[np.cos(x[0])]]), [[Q]])
    assert xp[0] == pytest.approx(np.sin(x)) and Pp[0, 0] == pytest.approx(np.cos(x) ** 2 * P + Q)
    xn, Pn, r, S = kalman.ekf_update(xp, Pp, [y], lambda x, u, t: x ** 2, lambda x, u, t: np.array([[2 * x[0]]]), [[R]])
    H = 2 * xp[0]
    K = Pp[0, 0] * H / (H * H * Pp[0, 0] + R)
    assert S[0, 0] == pytest.approx(H * H * Pp[0, 0] + R)
    assert r[0] == pytest.approx(y - xp[0] ** 2)
    assert xn[0] == pytest.approx(xp[0] + K * (y - xp[0] ** 2))
    assert Pn[0, 0] == pytest.approx((1 - K * H) * Pp[0, 0])


# ----------------------------------------------------------------------------- DARE

def _dare_residual(X, A, B, Q, R):
    G = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
    return A.T @ X @ A - A.T @ X @ B @ G + Q - X


def test_dare_matches_scipy_on_random_systems():
    rng = np.random.default_rng(2024)
    worst = 0.0
    for k in range(300):
        n, m = int(rng.integers(1, 7)), int(rng.integers(1, 4))
        A = rng.standard_normal((n, n)) * (1.3 if k % 3 == 0 else 0.7)   # a third of them open-loop unstable
        B = rng.standard_normal((n, m))
        G = rng.standard_normal((n, n)); Q = G @ G.T + (0.0 if k % 5 == 0 else 0.01) * np.eye(n)
        H = rng.standard_normal((m, m)); R = H @ H.T + 0.1 * np.eye(m)
        X = kalman.dare(A, B, Q, R)
        Xs = sl.solve_discrete_are(A, B, Q, R)
        scale = max(1.0, np.abs(Xs).max())
        worst = max(worst, np.abs(X - Xs).max() / scale)
        assert np.abs(_dare_residual(X, A, B, Q, R)).max() <= 1e-8 * scale * max(1.0, np.abs(A).max() ** 2)
        # stabilising: closed-loop A - B K inside the unit circle; symmetric PSD
        K = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
        assert np.abs(np.linalg.eigvals(A - B @ K)).max() < 1.0
        assert np.allclose(X, X.T, atol=0)
        assert np.linalg.eigvalsh(X).min() >= -1e-9 * scale
    assert worst < 1e-7


@pytest.mark.parametrize("args,msg", [
    ((np.array([[2.0]]), np.array([[0.0]]), np.eye(1), np.eye(1)), "not stabilisable"),
    ((np.diag([0.5, 1.0]), np.array([[1.0], [0.0]]), np.eye(2), np.eye(1)), "not stabilisable"),
    ((np.array([[1.0]]), np.array([[1.0]]), np.zeros((1, 1)), np.eye(1)), "not detectable"),
    ((np.eye(1), np.eye(1), np.eye(1), -np.eye(1)), "positive definite"),
    ((np.eye(2), np.eye(1), np.eye(2), np.eye(1)), "shapes"),
    ((np.eye(2), np.ones((2, 1)), -np.eye(2), np.eye(1)), "semi-definite"),
])
def test_dare_error_cases(args, msg):
    with pytest.raises(PfbenchError, match=msg):
        kalman.dare(*args)


def test_dare_unit_circle_pencil_error():
    # rotation (|lambda| = 1) with no control and no state weight: pencil eigenvalues on the unit circle
    c, s = np.cos(0.3), np.sin(0.3)
    A = np.array([[c, -s], [s, c]])
    with pytest.raises(PfbenchError, match="unit circle"):
        kalman.dare(A, np.array([[1.0], [0.0]]), np.zeros((2, 2)), np.eye(1), check=False)
    with pytest.raises(PfbenchError, match="unit circle"):
        kalman.dare(np.eye(1), np.zeros((1, 1)), np.eye(1), np.eye(1), check=False)


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
    with pytest.raises(PfbenchError):
        kalman.dare_scalar(1.5, 0.0, 1.0, 1.0)


def test_chapter_formula_is_continuous_time_riccati():
    rng = np.random.default_rng(9)
    for _ in range(50):
        F = rng.uniform(-3, 1); H = rng.uniform(0.5, 300); Q = rng.uniform(0.01, 3); R = rng.uniform(0.01, 3)
        p = kalman.chapter_riccati_scalar(F, H, Q, R)
        assert p == pytest.approx(sl.solve_continuous_are([[F]], [[H]], [[Q]], [[R]])[0, 0], rel=1e-9)


# ----------------------------------------------------------------------------- chapter loops

def test_time_varying_kf_matches_filterpy_update_then_predict():
    from filterpy.kalman import KalmanFilter

    rng = np.random.default_rng(17)
    A, C, Q, R, x0, P0, B, _ = random_system(rng, 2, 1, 1)
    n = 60
    y = rng.standard_normal(n); u = rng.standard_normal((n, 1))
    res = kalman.time_varying_kf(A, B, C, Q, R, u, y, x0=x0, P0=P0)
    kf = KalmanFilter(dim_x=2, dim_z=1, dim_u=1)
    kf.x = x0.reshape(-1, 1).copy(); kf.P = P0.copy(); kf.F = A; kf.H = C; kf.Q = Q; kf.R = R; kf.B = B
    for i in range(n):
        kf.update(np.array([[y[i]]]))
        np.testing.assert_allclose(res.x_filt[i], kf.x.ravel(), atol=1e-10)
        assert res.errcov[i] == pytest.approx((C @ kf.P @ C.T)[0, 0], abs=1e-10)
        kf.predict(u=u[i].reshape(-1, 1))
        np.testing.assert_allclose(res.x_pred[i], kf.x.ravel(), atol=1e-10)


def test_steady_state_kf_is_limit_of_time_varying():
    rng = np.random.default_rng(23)
    A, C, Q, R, x0, P0, B, _ = random_system(rng, 3, 1, 1)
    n = 400
    y = rng.standard_normal(n); u = rng.standard_normal((n, 1))
    P_prior, P_post, M = kalman.steady_state_gain(A, C, Q, R)
    tv = kalman.time_varying_kf(A, B, C, Q, R, u, y, x0=x0, P0=P0)
    np.testing.assert_allclose(tv.gains[-1], M, atol=1e-10)
    assert tv.errcov[-1] == pytest.approx((C @ P_post @ C.T)[0, 0], rel=1e-9)
    # started at the steady-state prior, the time-varying filter *is* the steady-state filter
    tv2 = kalman.time_varying_kf(A, B, C, Q, R, u, y, x0=x0, P0=P_prior)
    ss = kalman.steady_state_kf(A, B, C, Q, R, u, y, x0=x0)
    np.testing.assert_allclose(tv2.x_filt, ss.x_filt, atol=1e-9)
    np.testing.assert_allclose(tv2.ypred, ss.ypred, atol=1e-9)
