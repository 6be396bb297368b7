"""Resampling schemes: unbiasedness, variance ordering, determinism, backend equality."""
import numpy as np
import pytest

from pfbench import resampling
from pfbench.backends import numba_resampling

#: every scheme but those that draw nothing (a new scheme is tested here without a list to edit)
RANDOM_SCHEMES = tuple(s for s in resampling.SCHEMES if s != "residual_deterministic")


def _weights(n=20, seed=0):
    w = np.random.default_rng(seed).gamma(0.5, size=n)
    return w / w.sum()


@pytest.mark.parametrize("scheme", RANDOM_SCHEMES)
def test_offspring_counts_unbiased(scheme):
    """E[N_i] = N w_i for every scheme. Mean over R replications has sd <= sqrt(N w (1-w) / R)
    (the multinomial variance bounds the variance of the other schemes here: a new scheme whose
    offspring variance can exceed it needs its own bound); we allow 5 of those (|z| > 5: p < 6e-7)."""
    n, reps = 20, 4000
    w = _weights(n)
    rng = np.random.default_rng(1)
    counts = np.zeros((reps, n))
    for r in range(reps):
        counts[r] = np.bincount(resampling.resample(scheme, w, rng), minlength=n)
    assert np.all(counts.sum(axis=1) == n)
    mean = counts.mean(axis=0)
    sd = np.sqrt(n * w * (1 - w) / reps)
    assert np.all(np.abs(mean - n * w) <= 5 * sd + 1e-12)


def test_variance_ordering():
    """Offspring-count variance: systematic, stratified, residual <= multinomial = N w (1 - w)."""
    n, reps = 20, 4000
    w = _weights(n, seed=3)
    var = {}
    for scheme in RANDOM_SCHEMES:
        rng = np.random.default_rng(2)
        c = np.array([np.bincount(resampling.resample(scheme, w, rng), minlength=n) for _ in range(reps)])
        var[scheme] = c.var(axis=0).sum()
    multinomial_theory = (n * w * (1 - w)).sum()
    # sample variance of the multinomial counts within 10 % of theory (reps = 4000: sd ~ 2 %)
    assert abs(var["multinomial"] / multinomial_theory - 1) < 0.1
    for scheme in ("systematic", "stratified", "residual"):
        assert var[scheme] < var["multinomial"]
    assert var["systematic"] <= var["stratified"]


def test_residual_deterministic_is_deterministic_and_draws_nothing():
    """Deterministic remainder: not unbiased by design (N_i in {floor, ceil} of N w_i)."""
    w = _weights(50, seed=4)
    rng = np.random.default_rng(5)
    state = rng.bit_generator.state
    a = resampling.residual_deterministic(w, rng)
    b = resampling.residual_deterministic(w, rng)
    assert np.array_equal(a, b)
    assert rng.bit_generator.state == state
    counts = np.bincount(a, minlength=50)
    assert np.all(counts >= np.floor(50 * w)) and np.all(counts <= np.floor(50 * w) + 1)


def test_residual_deterministic_gives_remainder_to_largest_residuals():
    w = np.array([0.45, 0.35, 0.2])  # N w = 1.35, 1.05, 0.6 -> floor 1, 1, 0; R = 1 -> goes to index 2
    assert resampling.residual_deterministic(w).tolist() == [0, 1, 2]


@pytest.mark.parametrize("scheme", resampling.SCHEMES)
def test_numba_equals_numpy(scheme):
    for seed in range(5):
        w = _weights(200, seed)
        a = resampling.resample(scheme, w, np.random.default_rng(seed))
        b = numba_resampling.resample(scheme, w, np.random.default_rng(seed))
        assert np.array_equal(a, b)


@pytest.mark.parametrize("scheme", [*resampling.SCHEMES, "unknown"])
def test_numba_any_scheme_runs_the_kernel_of_the_code_it_is_given(scheme):
    """``any_scheme`` (the kernel of callers that choose the scheme at run time) gives the NumPy
    scheme's indices for every code, and raises for a code it has no branch for. Catches a branch
    that runs another scheme (a new scheme falling through to residual, residual and its
    deterministic variant swapped)."""
    w = _weights(200, 3)
    cdf = np.cumsum(w)
    idx = np.empty(w.size, np.int64)
    if scheme == "unknown":
        with pytest.raises(ValueError, match="without a kernel"):
            numba_resampling.any_scheme(len(resampling.Scheme), w, cdf, np.random.default_rng(3), idx)
        return
    numba_resampling.any_scheme(int(resampling.Scheme.parse(scheme)), w, cdf, np.random.default_rng(3), idx)
    assert np.array_equal(idx, resampling.resample(scheme, w, np.random.default_rng(3)))


def test_unnormalised_weights_accepted():
    w = _weights(30, seed=7)
    rng1, rng2 = np.random.default_rng(0), np.random.default_rng(0)
    assert np.array_equal(resampling.systematic(w, rng1), resampling.systematic(1e-300 * w, rng2))


@pytest.mark.parametrize("bad", [np.array([]), np.array([0.0, 0.0]), np.array([1.0, np.nan]),
                                 np.array([1.0, -0.5])])
def test_bad_weights_rejected(bad):
    with pytest.raises(ValueError):
        resampling.systematic(bad, np.random.default_rng(0))


def test_unknown_scheme():
    with pytest.raises(ValueError, match="unknown resampling scheme"):
        resampling.get("nope")


def test_h_opt_matches_closed_form_1d():
    # n_x = 1: c_1 = 2, A = (8/2 * 5 * 2 sqrt(pi))^(1/5)
    a = (4 * 5 * 2 * np.sqrt(np.pi)) ** 0.2
    assert resampling.h_opt(1000, 1) == pytest.approx(a * 1000 ** -0.2)


def test_epanechnikov_moments():
    """1-D Epanechnikov kernel: support [-1, 1], mean 0, variance 1/5; n_x-D: E||e||^2 = n/(n+4)."""
    rng = np.random.default_rng(0)
    e = resampling.epanechnikov(rng, 200_000, 1)[:, 0]
    assert np.all(np.abs(e) <= 1)
    assert abs(e.mean()) < 5 * np.sqrt(0.2 / e.size)
    assert e.var() == pytest.approx(0.2, rel=0.02)
    e3 = resampling.epanechnikov(rng, 200_000, 3)
    assert np.mean(np.sum(e3 ** 2, axis=1)) == pytest.approx(3 / 7, rel=0.02)


def test_regularized_jitter_is_epanechnikov_scaled_by_h_and_the_covariance():
    """x_i* = x_{a_i} + h D eps_i ([Thesis] Alg. 4): recover the jitter d_i = x_i* - x_{a_i} (the
    ancestors a_i come from replaying the scheme's draws, which come first) and whiten it with the
    weighted covariance D D^T and h = h_opt. Then z_i = D^-1 d_i / h must be Epanechnikov draws: inside
    the unit ball, mean 0, E[z z^T] = I / (n_x + 4). With N = 20000 the standard error of each
    second moment is sqrt(Var(z_a^2) / N) < sqrt(E z_a^4 / N) <= sqrt(1/N) = 0.007, so 0.03 is > 4 se.
    Catches: a bandwidth that is not h_opt (1e-12 gives z ~ 0; 2 h_opt gives 4x the moments), a
    jitter not scaled by the covariance factor, a kernel other than Epanechnikov (Gaussian leaves the
    ball), and a jitter applied to the wrong ancestors."""
    n, n_x = 20000, 2
    rng = np.random.default_rng(1)
    x = rng.normal(2.0, 1.0, (n, n_x)) @ np.array([[1.0, 0.6], [0.0, 0.5]])
    w = rng.random(n)
    out = resampling.regularized(x, w, np.random.default_rng(2))
    anc = resampling.systematic(w, np.random.default_rng(2))
    d = out - x[anc]
    wn = w / w.sum()
    mean = wn @ x
    cov = ((x - mean) * wn[:, None]).T @ (x - mean)
    z = np.linalg.solve(np.linalg.cholesky(cov), d.T).T / resampling.h_opt(n, n_x)
    # D is a symmetric square root, the Cholesky factor another one: they differ by a rotation, which
    # leaves the norm and E[z z^T] = I / (n_x + 4) unchanged
    assert np.max(np.linalg.norm(z, axis=1)) <= 1.0 + 1e-9
    assert np.all(np.abs(z.mean(axis=0)) < 0.03)
    np.testing.assert_allclose(z.T @ z / n, np.eye(n_x) / (n_x + 4), atol=0.03)


@pytest.mark.parametrize("scheme", ["residual", "residual_deterministic"])
def test_residual_with_subnormal_total_weight(scheme):
    """Weights summing to a subnormal number: N / total overflows to inf unless the weights are
    normalised first (then the numba path returned uninitialised indices). Both backends must give
    valid, identical indices with the offspring of the normalised weights."""
    w = np.array([1.0, 3.0, 0.0, 4.0]) * 1e-320          # total 8e-320 < 2.2e-308
    a = resampling.resample(scheme, w, np.random.default_rng(0))
    b = numba_resampling.resample(scheme, w, np.random.default_rng(0))
    assert np.array_equal(a, b)
    counts = np.bincount(a, minlength=4)
    # N w = (0.5, 1.5, 0, 2): floors (0, 1, 0, 2), one remainder particle to index 0 or 1
    assert counts.sum() == 4 and counts[2] == 0 and counts[3] == 2 and counts[0] + counts[1] == 2


@pytest.mark.parametrize("n", [1, 2, 7, 64, 257])
def test_numba_decreasing_order_is_the_stable_argsort(n):
    # The written-out merge sort behind residual_deterministic must equal NumPy's stable argsort of
    # -v, ties (frequent here: values on a coarse grid, and +-0.0) by the lower index. Mutation
    # caught: `>=` instead of `>` in the merge (unstable), or a merge that drops the tail of a run.
    rng = np.random.default_rng(n)
    v = np.round(rng.random(n) * 4) / 4
    v[::5] = -0.0
    got = numba_resampling._decreasing_order(v)
    assert np.array_equal(got, np.argsort(-v, kind="mergesort"))
