"""Tests of pfbench.kalman: KF vs filterpy and brute force, EKF, the [RTD] loops, FilterResult
contents. The DARE is tested in test_dare.py."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from pfbench import kalman
from pfbench.errors import InputError, PfbenchError, UnsupportedError
from pfbench.filters.result import FilterResult
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
        np.testing.assert_allclose(res.extras["pred_means"][t], kf.x.ravel(), rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.extras["pred_covs"][t], kf.P, rtol=0, atol=1e-10)
        kf.update(y[t].reshape(-1, 1))
        np.testing.assert_allclose(res.estimates[t], kf.x.ravel(), rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.covariances[t], kf.P, rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.extras["gains"][t], kf.K, rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.extras["innovations"][t], kf.y.ravel(), rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.extras["innovation_covs"][t], kf.S, rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.loglik_increments[t], kf.log_likelihood, rtol=1e-10, atol=1e-10)


def _brute_force_loglik(A, C, Q, R, x0, P0, y, B=None, D=None, u=None):
    """log N(vec y; mu, Sigma) of the stacked observations (dense joint Gaussian)."""
    M, n_y = y.shape
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
    np.testing.assert_array_equal(res.estimates, ref.estimates)
    assert res.loglik == ref.loglik
    with pytest.raises(InputError):
        kalman.filter_model(model, tr.y)
    with pytest.raises(UnsupportedError):
        kalman.filter_model(object(), tr.y)
    # the simulated trajectory must be consistent with the filter: normalised innovations ~ N(0, 1)
    model2 = LinearGaussian(A=A, C=C, Q=Q, R=R, x0=x0, P0=P0)
    tr2 = model2.simulate(2000, seed=11)
    r2 = kalman.filter_model(model2, tr2.y)
    ex = r2.extras
    z = np.concatenate([np.linalg.solve(np.linalg.cholesky(S), e) for S, e in zip(ex["innovation_covs"], ex["innovations"])])
    # mean of 4000 N(0,1): |mean| < 4/sqrt(4000); variance within 4 sd of chi2 (sd ~ sqrt(2/4000))
    assert abs(z.mean()) < 4 / np.sqrt(z.size)
    assert abs(z.var() - 1.0) < 4 * np.sqrt(2.0 / z.size)


def test_kf_bad_shapes():
    args = (np.eye(2), np.ones((1, 2)), np.eye(2), np.eye(1), np.zeros(2), np.eye(2))
    with pytest.raises(InputError, match="shapes"):
        kalman.kalman_filter(np.eye(2), np.ones((1, 3)), *args[2:], np.zeros((5, 1)))
    with pytest.raises(InputError, match="y must have shape"):
        kalman.kalman_filter(*args, np.zeros((5, 2)))
    # nothing is reshaped or transposed silently: B given as a row, y flat with n_y = 2, B without u
    with pytest.raises(InputError, match="B must have shape"):
        kalman.kalman_filter(*args, np.zeros((5, 1)), B=np.ones((1, 2)), u=np.zeros((5, 2)))
    with pytest.raises(InputError, match="y must have shape"):
        kalman.kalman_filter(np.eye(2), np.eye(2), np.eye(2), np.eye(2), np.zeros(2), np.eye(2), np.zeros(10))
    with pytest.raises(InputError, match="need both u"):
        kalman.kalman_filter(*args, np.zeros((5, 1)), B=np.ones((2, 1)))
    with pytest.raises(PfbenchError, match="not positive definite"):
        kalman.kalman_filter(*args[:3], -np.eye(1), *args[4:], np.zeros((5, 1)))


# ----------------------------------------------------------------------------- EKF

def test_ekf_equals_kf_on_linear_model():
    rng = np.random.default_rng(21)
    A, C, Q, R, x0, P0, B, _ = random_system(rng, 3, 2, 1)
    M = 30
    y = rng.standard_normal((M, 2)); u = rng.standard_normal((M, 1))
    ref = kalman.kalman_filter(A, C, Q, R, x0, P0, y, B=B, u=u)
    res = kalman.ekf(lambda x, u, t: A @ x + B @ u, lambda x, u, t: A, lambda x, u, t: C @ x,
                     lambda x, u, t: C, Q, R, x0, P0, y, u=u)
    np.testing.assert_allclose(res.estimates, ref.estimates, atol=1e-12)
    np.testing.assert_allclose(res.covariances, ref.covariances, atol=1e-12)
    for key in kalman.KALMAN_EXTRAS:
        np.testing.assert_allclose(res.extras[key], ref.extras[key], atol=1e-12)
    assert res.loglik == pytest.approx(ref.loglik, rel=1e-12)
    assert res.info["filter"] == "ekf" and ref.info["filter"] == "kf"


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


# ----------------------------------------------------------------------------- chapter loops

def test_time_varying_kf_matches_filterpy_update_then_predict():
    from filterpy.kalman import KalmanFilter

    rng = np.random.default_rng(17)
    A, C, Q, R, x0, P0, B, _ = random_system(rng, 2, 1, 1)
    n = 60
    y = rng.standard_normal(n); u = rng.standard_normal((n, 1))
    res = kalman.time_varying_kf(A, B, C, Q, R, u, y, x0=x0, P0=P0)
    ex = res.extras
    kf = KalmanFilter(dim_x=2, dim_z=1, dim_u=1)
    kf.x = x0.reshape(-1, 1).copy(); kf.P = P0.copy(); kf.F = A; kf.H = C; kf.Q = Q; kf.R = R; kf.B = B
    for i in range(n):
        np.testing.assert_allclose(ex["pred_means"][i], kf.x.ravel(), atol=1e-10)
        np.testing.assert_allclose(ex["pred_covs"][i], kf.P, atol=1e-10)
        kf.update(np.array([[y[i]]]))
        np.testing.assert_allclose(res.estimates[i], kf.x.ravel(), atol=1e-10)
        np.testing.assert_allclose(res.covariances[i], kf.P, atol=1e-10)
        np.testing.assert_allclose(ex["yest"][i], C @ kf.x.ravel(), atol=1e-10)
        assert ex["errcov"][i, 0, 0] == pytest.approx((C @ kf.P @ C.T)[0, 0], abs=1e-10)
        # the Gaussian innovation log-likelihood of the chapter's loop
        assert res.loglik_increments[i] == pytest.approx(kf.log_likelihood, rel=1e-10, abs=1e-10)
        kf.predict(u=u[i].reshape(-1, 1))
        np.testing.assert_allclose(ex["x_pred"][i], kf.x.ravel(), atol=1e-10)
        np.testing.assert_allclose(ex["ypred"][i], C @ kf.x.ravel(), atol=1e-10)


@pytest.mark.parametrize("n_y", [1, 2])
def test_steady_state_kf_is_limit_of_time_varying(n_y):
    """The DARE solution is the fixed point of the covariance recursion ([RTD] eq. 37): after 400
    steps of a stable system (spectral radius 0.95, so 0.95^800 ~ 1e-18 of the initial transient
    remains in P) the time-varying gain and covariances equal the steady-state ones to rounding."""
    rng = np.random.default_rng(23 + n_y)
    A, C, Q, R, x0, P0, B, _ = random_system(rng, 3, n_y, 1)
    n = 400
    y = rng.standard_normal((n, n_y)); u = rng.standard_normal((n, 1))
    P_prior, P_post, M = kalman.steady_state_gain(A, C, Q, R)
    tv = kalman.time_varying_kf(A, B, C, Q, R, u, y, x0=x0, P0=P0)
    np.testing.assert_allclose(tv.extras["gains"][-1], M, atol=1e-10)
    np.testing.assert_allclose(tv.covariances[-1], P_post, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(tv.extras["pred_covs"][-1], P_prior, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(tv.extras["errcov"][-1], C @ P_post @ C.T, rtol=1e-9, atol=1e-12)
    # started at the steady-state prior, the time-varying filter *is* the steady-state filter
    tv2 = kalman.time_varying_kf(A, B, C, Q, R, u, y, x0=x0, P0=P_prior)
    ss = kalman.steady_state_kf(A, B, C, Q, R, u, y, x0=x0)
    np.testing.assert_allclose(tv2.estimates, ss.estimates, atol=1e-9)
    np.testing.assert_allclose(tv2.covariances, ss.covariances, atol=1e-9)
    for key in kalman.KALMAN_EXTRAS + kalman.CHAPTER_EXTRAS:
        np.testing.assert_allclose(tv2.extras[key], ss.extras[key], atol=1e-9, err_msg=key)
    np.testing.assert_allclose(tv2.loglik_increments, ss.loglik_increments, rtol=1e-9, atol=1e-9)


# ----------------------------------------------------------------------------- FilterResult

def _all_filters():
    rng = np.random.default_rng(41)
    A, C, Q, R, x0, P0, B, D = random_system(rng, 3, 2, 1)
    M = 25
    y = rng.standard_normal((M, 2)); u = rng.standard_normal((M, 1))
    lin = (lambda x, u, t: A @ x + B @ u, lambda x, u, t: A, lambda x, u, t: C @ x, lambda x, u, t: C)
    return M, {
        "kf": kalman.kalman_filter(A, C, Q, R, x0, P0, y, B=B, D=D, u=u),
        "ekf": kalman.ekf(*lin, Q, R, x0, P0, y, u=u),
        "time_varying_kf": kalman.time_varying_kf(A, B, C, Q, R, u, y, x0=x0, P0=P0),
        "steady_state_kf": kalman.steady_state_kf(A, B, C, Q, R, u, y, x0=x0),
    }


def test_every_kalman_filter_returns_a_filter_result():
    """The one result type: catches a filter that returns anything else, variances that are not the
    diagonal of its filtered covariances, increments that do not sum to the log-likelihood, or a
    documented extras key missing or of the wrong shape."""
    M, results = _all_filters()
    n_x, n_y = 3, 2
    shapes = {"pred_means": (M, n_x), "pred_covs": (M, n_x, n_x), "innovations": (M, n_y),
              "innovation_covs": (M, n_y, n_y), "gains": (M, n_x, n_y), "x_pred": (M, n_x),
              "yest": (M, n_y), "ypred": (M, n_y), "errcov": (M, n_y, n_y)}
    for name, r in results.items():
        assert isinstance(r, FilterResult)
        assert r.method == "kalman" and r.info["filter"] == name
        assert r.n_particles == 0 and r.n_resampled == 0 and r.n_filters == 1
        assert r.estimates.shape == (M, n_x) and r.covariances.shape == (M, n_x, n_x)
        np.testing.assert_array_equal(r.variances, np.diagonal(r.covariances, axis1=1, axis2=2))
        assert r.ess.shape == (M,) and np.all(np.isnan(r.ess))
        assert r.degenerate.shape == (M,) and not r.degenerate.any()
        assert r.elapsed_s >= 0.0
        assert r.loglik_increments.shape == (M,) and np.all(np.isfinite(r.loglik_increments))
        assert r.loglik == pytest.approx(r.loglik_increments.sum(), rel=1e-14)
        loop = name in ("time_varying_kf", "steady_state_kf")
        keys = kalman.KALMAN_EXTRAS + (kalman.CHAPTER_EXTRAS if loop else ())
        for key in keys:
            assert r.extras[key].shape == shapes[key], (name, key)
        # innovations are y minus the prediction, with covariance S = C P[t|t-1] C^T + R
        S = r.extras["innovation_covs"]
        np.testing.assert_allclose(r.loglik_increments,
                                   [kalman.gaussian_logpdf(e, s) for e, s in zip(r.extras["innovations"], S)],
                                   rtol=1e-12)
