"""The guided filter ([Doucet2000]; [Thesis] §4.2.1): the Gaussian locally optimal proposal, both
backends, the Kalman limit, unbiased likelihood, a user model's own proposal, unsupported models."""
import math

import numpy as np
import pytest

import pfbench
from pfbench import kalman, models
from pfbench.errors import InputError, UnsupportedError
from pfbench.filters.guided import (optimal_gaussian_log_predictive, optimal_gaussian_moments,
                                    optimal_gaussian_params, optimal_gaussian_proposal, run_guided)
from pfbench.models.base import LOG_2PI, StateSpaceModel
from pfbench.models.pmsm import Pmsm, PmsmReduced, pmsm_mean


# --------------------------------------------------------------------------- test models
class LG(StateSpaceModel):
    """x_t = A x_{t-1} + w, w ~ N(0, Q); y_t = C x_t + v, v ~ N(0, R); x^(0) ~ N(x0, P0)."""

    def __init__(self, A=((0.9,),), C=((1.0,),), Q=((1.0,),), R=((0.1,),), x0=(0.0,), P0=((1.0,),)):
        f = lambda a: np.atleast_2d(np.asarray(a, dtype=np.float64))  # noqa: E731
        self.A, self.C, self.Q, self.R, self.P0 = f(A), f(C), f(Q), f(R), f(P0)
        self.x0 = np.asarray(x0, dtype=np.float64).reshape(-1)
        self.n_x, self.n_y = self.A.shape[0], self.C.shape[0]
        self.n_noise = self.n_x

    def params(self):
        c = np.ascontiguousarray
        return (c(self.A.T), c(self.C.T), c(np.linalg.cholesky(self.Q).T),
                c(np.linalg.cholesky(self.P0).T), self.x0, c(np.linalg.inv(self.R)),
                float(np.linalg.slogdet(self.R)[1]), c(np.linalg.cholesky(self.R).T),
                optimal_gaussian_params(self.Q, self.C, self.R))

    def kalman(self, y):
        return kalman.kalman_filter(self.A, self.C, self.Q, self.R, self.x0, self.P0, y)

    @staticmethod
    def initial(rng, n, p):
        return p[4] + rng.standard_normal((n, p[4].shape[0])) @ p[3]

    @staticmethod
    def transition(x, u, t, noise, p):
        return np.ascontiguousarray(x) @ p[0] + noise @ p[2]

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        r = y - np.ascontiguousarray(x) @ p[1]
        return -0.5 * np.sum((r @ p[5]) * r, axis=1) - 0.5 * (y.shape[0] * LOG_2PI + p[6])

    @staticmethod
    def observe(x, u, t, noise, p):
        return np.ascontiguousarray(x) @ p[1] + noise @ p[7]


class LGOptimal(LG):
    """The locally optimal proposal from the reusable Gaussian helpers (float32 particles are cast:
    numba's ``@`` needs equal dtypes)."""

    proposal_kind = "optimal"

    @staticmethod
    def proposal(x_prev, y, u, t, noise, p):
        return optimal_gaussian_proposal(x_prev.astype(np.float64) @ p[0], y, noise, p[8])

    @staticmethod
    def predictive_log_likelihood(y, x_prev, u, t, p):
        return optimal_gaussian_log_predictive(x_prev.astype(np.float64) @ p[0], y, p[8])


class LGOwnProposal(LG):
    """A user's own (not optimal) proposal, 1-D: q(x_t | x_{t-1}, y_t) = N((a x_{t-1} + y_t) / 2, Q)."""

    proposal_kind = "proposal"
    n_proposal_noise = 1

    @staticmethod
    def proposal(x_prev, y, u, t, noise, p):
        a, sq = p[0][0, 0], p[2][0, 0]
        return 0.5 * (a * x_prev + y[0]) + sq * noise

    @staticmethod
    def proposal_log_weight(x, x_prev, y, u, t, p):
        a, sq = p[0][0, 0], p[2][0, 0]
        prior = a * x_prev[:, 0]
        d_p = x[:, 0] - prior
        d_q = x[:, 0] - 0.5 * (prior + y[0])
        d_y = y[0] - x[:, 0]
        # log p(y|x) + log p(x|x_prev) - log q(x|x_prev, y); p and q share the variance Q
        return (-0.5 * d_y * d_y * p[5][0, 0] - 0.5 * (LOG_2PI + p[6])
                - 0.5 * (d_p * d_p - d_q * d_q) / (sq * sq))


LG2 = dict(A=[[0.9, 0.2], [0.0, 0.7]], C=[[1.0, 0.5]], Q=[[1.0, 0.3], [0.3, 0.5]], R=[[0.2]],
           x0=[0.0, 0.0], P0=np.eye(2))


# --------------------------------------------------------------------------- the Gaussian optimal proposal
def test_gain_form_equals_information_form():
    """optimal_gaussian_params (gain form, used by the filter) against the information form of
    [Thesis] eqs. 4.22-4.25 on a dense, correlated case: exact algebra, so round-off tolerance.
    Catches a wrong gain, covariance or predictive variance."""
    rng = np.random.default_rng(0)
    B = rng.normal(size=(3, 3))
    Q = B @ B.T + 0.1 * np.eye(3)
    H = rng.normal(size=(2, 3))
    R = np.array([[0.3, 0.1], [0.1, 0.2]])
    f, y = rng.normal(size=3), rng.normal(size=2)
    m, S, ll = optimal_gaussian_moments(f, y, Q, H, R)
    g = optimal_gaussian_params(Q, H, R)
    assert np.allclose(g[2].T @ g[2], S, atol=1e-12)                                 # L L' = S
    assert np.allclose(optimal_gaussian_proposal(f[None], y, np.zeros((1, 3)), g)[0], m, atol=1e-12)
    assert optimal_gaussian_log_predictive(f[None], y, g)[0] == pytest.approx(ll, abs=1e-12)


def test_optimal_proposal_matches_brute_force_importance_sampling():
    """PMSM ([Thesis] eqs. 4.22-4.25): draw x_t from the transition prior, weight by p(y_t | x_t);
    the weighted mean/variance must match m_t, S and the mean weight p(y_t | x_{t-1}); and the
    sampler of the pmsm model must draw N(m_t, S). K = 400k draws: 5 Monte Carlo standard errors
    (mean: sd / sqrt(ESS); variance of a normal sample: sqrt(2 / K) relative)."""
    m = Pmsm()
    p = m.params()
    x_prev = np.array([0.4, -0.3, 6.0, 0.8])
    u = np.array([3.0, 1.0])
    f = pmsm_mean(x_prev[None], u, p[0])[0]
    y = f[:2] + np.array([0.03, -0.02])
    mom, S, ll = optimal_gaussian_moments(f, y, np.diag(m.q), Pmsm.H, np.diag(m.r))
    rng = np.random.default_rng(0)
    K = 400_000
    xs = f + rng.standard_normal((K, 4)) * np.sqrt(m.q)
    lik = np.exp(m.log_likelihood(y, xs, u, 0, p))
    assert abs(lik.mean() - math.exp(ll)) < 5 * lik.std() / math.sqrt(K)
    w = lik / lik.sum()
    mean = w @ xs
    ess = 1 / np.sum(w * w)
    for k in range(4):
        assert abs(mean[k] - mom[k]) < 5 * math.sqrt(S[k, k] / ess)
    assert w @ (xs[:, 0] - mean[0]) ** 2 == pytest.approx(S[0, 0], rel=0.02)
    # the model's own functions: predictive density and the sampler (theta far from the wrap)
    assert Pmsm.predictive_log_likelihood(y, x_prev[None], u, 0, p)[0] == pytest.approx(ll, abs=1e-12)
    draws = Pmsm.proposal(np.repeat(x_prev[None], K, 0), y, u, 0, rng.standard_normal((K, 4)), p)
    se = np.sqrt(np.diag(S) / K)
    assert np.all(np.abs(draws.mean(axis=0) - mom) < 5 * se)
    assert np.allclose(draws.var(axis=0), np.diag(S), rtol=5 * math.sqrt(2 / K))


# --------------------------------------------------------------------------- backends
@pytest.mark.parametrize("model,threshold", [
    (LGOptimal(**LG2), 0.7), (LGOwnProposal(), 0.2), (PmsmReduced(open_loop_amplitude=5.0), 0.7),
    pytest.param(Pmsm(open_loop_amplitude=5.0), 0.7, marks=pytest.mark.slow)],  # ~8 s compile
    ids=["lg_optimal", "own_proposal", "pmsm_reduced", "pmsm"])
def test_numpy_and_numba_agree(model, threshold):
    """Same seed, same random numbers: the backends agree to round-off, with and without
    resampling at a step (thresholds chosen so that both happen)."""
    tr = model.simulate(60, seed=3)
    kw = dict(method="guided", n_particles=80, seed=5, ess_threshold=threshold)
    a = pfbench.run_filter(model, tr.y, tr.u, backend="numpy", **kw)
    b = pfbench.run_filter(model, tr.y, tr.u, backend="numba", **kw)
    assert 0 < a.n_resampled < 60
    assert np.max(np.abs(a.estimates - b.estimates)) <= 1e-9
    assert np.max(np.abs(a.variances - b.variances)) <= 1e-9
    assert a.loglik == pytest.approx(b.loglik, rel=1e-10, abs=1e-9)
    assert np.array_equal(a.extras["resampled"], b.extras["resampled"])
    assert np.allclose(a.ess, b.ess, rtol=1e-10)
    assert a.method == "guided" and a.loglik_increments.sum() == pytest.approx(a.loglik)


@pytest.mark.parametrize("scheme", pfbench.resampling.SCHEMES)
def test_backends_agree_for_every_resampling_scheme(scheme):
    model = LGOptimal(**LG2)
    tr = model.simulate(30, seed=1)
    kw = dict(method="guided", n_particles=50, seed=2, resampling=scheme, ess_threshold=0.9)
    a = pfbench.run_filter(model, tr.y, backend="numpy", **kw)
    b = pfbench.run_filter(model, tr.y, backend="numba", **kw)
    assert a.n_resampled > 0
    assert np.max(np.abs(a.estimates - b.estimates)) <= 1e-9


def test_float32_particles_run():
    """float32 particle storage (NumPy backend: a numba float32 kernel would cost a second compile)."""
    model = LGOptimal(**LG2)
    tr = model.simulate(40, seed=1)
    r64 = pfbench.run_filter(model, tr.y, method="guided", n_particles=500, backend="numpy", seed=1)
    r32 = pfbench.run_filter(model, tr.y, method="guided", n_particles=500, backend="numpy", seed=1,
                             dtype="float32")
    assert r32.dtype == "float32" and np.all(np.isfinite(r32.estimates))
    # float32 storage rounds each particle to ~1e-7 relative; the posterior sd is ~0.4, so the two
    # runs stay well within a Monte Carlo error (sd / sqrt(N) ~ 0.02) of each other
    assert np.max(np.abs(r32.estimates - r64.estimates)) < 0.1


# --------------------------------------------------------------------------- statistics
@pytest.mark.parametrize("cls", [LGOptimal, LGOwnProposal])
def test_converges_to_kalman_posterior_mean(cls):
    """|PF mean - KF mean|^2 is Monte Carlo error with mean c / N_p, so the mean squared error at
    N = 100 is 16x the one at N = 1600: log(RMSE_100 / RMSE_1600) = log 4, with the standard error
    of the delta method over S = 20 independent trajectories and seeds (as in test_run_filter); 4 of
    them allowed. Catches a guided filter whose error does not vanish (e.g. a wrong weight: the
    filter then converges to something else and the ratio goes to 1)."""
    model = cls()
    per_seed = {}
    for n in (100, 1600):
        m = []
        for seed in range(20):
            tr = model.simulate(50, seed=100 + seed)
            kf = model.kalman(tr.y)
            r = pfbench.run_filter(model, tr.y, method="guided", n_particles=n, backend="numpy", seed=seed)
            m.append(np.mean((r.estimates[:, 0] - kf.estimates[:, 0]) ** 2))
        per_seed[n] = np.array(m)
    log_ratio = 0.5 * np.log(per_seed[100].mean() / per_seed[1600].mean())
    se = 0.5 * np.sqrt(sum(v.var(ddof=1) / (v.mean() ** 2 * v.size) for v in per_seed.values()))
    assert abs(log_ratio - np.log(4.0)) < 4 * se, (log_ratio, se)


def test_likelihood_is_unbiased_and_less_variable_than_bootstrap():
    """E[p_hat(y)] = p(y) for both proposals: mean of exp(loglik_hat - loglik_KF) over 300 seeds
    within 3 standard errors of 1. With an informative measurement (R = Q / 10) the optimal proposal
    must have a smaller variance of loglik_hat than the bootstrap filter at equal N_p: if the two
    variances were equal, a sample-variance ratio above 2 with 300 + 300 runs would have probability
    < 1e-8 (F(299, 299)); theory predicts a ratio of 100s here. Catches a biased weight and a guided
    filter that ignores y_t in its proposal."""
    model = LGOptimal()
    tr = model.simulate(20, seed=9)
    exact = model.kalman(tr.y).loglik
    lls = {}
    for name, m, method in (("optimal", model, "guided"), ("own", LGOwnProposal(), "guided"),
                            ("bootstrap", model, "bootstrap")):
        lls[name] = np.array([pfbench.run_filter(m, tr.y, method=method, n_particles=50,
                                                 backend="numpy", seed=s).loglik for s in range(300)])
    for name in ("optimal", "own"):
        ratios = np.exp(lls[name] - exact)
        se = ratios.std(ddof=1) / np.sqrt(ratios.size)
        assert abs(ratios.mean() - 1.0) < 3 * se, name
    assert lls["bootstrap"].var(ddof=1) > 2 * lls["optimal"].var(ddof=1)


# --------------------------------------------------------------------------- results and errors
def test_result_fields_and_ess_threshold_is_a_fraction():
    model = LGOptimal()
    tr = model.simulate(30, seed=1)
    r = run_guided(model, tr.y, n_particles=40, backend="numpy", ess_threshold=1.0, seed=0)
    assert r.estimates.shape == (30, 1) and r.ess.shape == (30,)
    assert r.extras["resampled"].dtype == bool and r.n_resampled == r.extras["resampled"].sum()
    assert r.info["ess_threshold"] == 40.0 and r.info["proposal_kind"] == "optimal"
    assert np.all((r.ess >= 1) & (r.ess <= 40 + 1e-9))
    with pytest.raises(InputError, match="fraction"):
        run_guided(model, tr.y, n_particles=40, ess_threshold=12)


def test_models_without_a_proposal_are_unsupported():
    ob1 = models.get("ob1")
    tr = ob1.simulate(5, seed=1)
    with pytest.raises(UnsupportedError, match="declares no proposal"):
        pfbench.run_filter(ob1, tr.y, method="guided", n_particles=10, backend="numpy")

    class HalfDone(LG):
        proposal_kind = "proposal"

        @staticmethod
        def proposal(x_prev, y, u, t, noise, p):
            return x_prev + noise

    with pytest.raises(UnsupportedError, match="proposal_log_weight"):
        run_guided(HalfDone(), tr.y, n_particles=10)

    class Typo(LG):
        proposal_kind = "optimall"

    with pytest.raises(UnsupportedError, match="proposal_kind"):
        run_guided(Typo(), tr.y, n_particles=10)
