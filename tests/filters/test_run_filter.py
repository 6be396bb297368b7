"""run_filter: backends agree, MultiPDF semantics, Kalman limit, unbiased likelihood, bad input."""
import numpy as np
import pytest

import pfbench
from pfbench import kalman, models
from pfbench.errors import PfbenchError

CORE_MODELS = [("ob1", {}), ("ob2", {}), ("ob3", {"version": 1}), ("ob3", {"version": 4}),
               ("ob3", {"version": 5}), ("ob4", {}),
               ("linear_gaussian", {"A": [[0.9, 0.1], [0.0, 0.8]], "C": [[1.0, 0.5]],
                                    "Q": np.eye(2), "R": [[0.5]]})]
METHODS = ("bootstrap", "sir", "sis", "asir", "multipdf")


def _run(model, traj, backend, method, **kw):
    kw.setdefault("n_particles", 120)
    if method == "multipdf":
        kw.setdefault("n_filters", 3)
    return pfbench.run_filter(model, traj.y, traj.u, method=method, backend=backend, seed=7,
                              common_random_numbers=True, **kw)


@pytest.mark.parametrize("name,params", CORE_MODELS, ids=lambda v: str(v))
def test_numpy_and_numba_agree_for_every_method(name, params):
    model = models.get(name, **params)
    traj = model.simulate(40, seed=3)
    for method in METHODS:
        a = _run(model, traj, "numpy", method)
        b = _run(model, traj, "numba", method)
        assert np.max(np.abs(a.estimates - b.estimates)) <= 1e-9, method
        assert np.max(np.abs(a.sub_estimates - b.sub_estimates)) <= 1e-9, method
        assert a.loglik == pytest.approx(b.loglik, rel=1e-10, abs=1e-9), method
        assert a.n_resampled == b.n_resampled


@pytest.mark.parametrize("scheme", pfbench.resampling.SCHEMES)
def test_backends_agree_for_every_resampling_scheme(scheme):
    model = models.get("ob1")
    traj = model.simulate(30, seed=1)
    a = _run(model, traj, "numpy", "sir", resampling=scheme, ess_threshold=2 / 3)
    b = _run(model, traj, "numba", "sir", resampling=scheme, ess_threshold=2 / 3)
    assert np.max(np.abs(a.estimates - b.estimates)) <= 1e-9


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_multipdf_with_one_filter_is_bootstrap(backend):
    model = models.get("ob1")
    traj = model.simulate(50, seed=2)
    for crn in (True, False):
        a = pfbench.run_filter(model, traj.y, method="bootstrap", n_particles=200, backend=backend,
                               seed=4, common_random_numbers=crn)
        b = pfbench.run_filter(model, traj.y, method="multipdf", n_filters=1, n_particles=200,
                               backend=backend, seed=4, common_random_numbers=crn)
        assert np.array_equal(a.estimates, b.estimates)
        assert a.loglik == b.loglik


def test_multipdf_estimate_is_mean_of_sub_filters_and_particle_split():
    model = models.get("ob4")
    traj = model.simulate(30, seed=2)
    r = pfbench.run_filter(model, traj.y, traj.u, method="multipdf", n_particles=100, n_filters=3,
                           backend="numpy", seed=1)
    assert r.sub_estimates.shape == (3, 30, 2)
    assert r.info["n_per_filter"] == 33  # round(100 / 3), [MultiPDF] Alg. 2 step 1
    assert np.allclose(r.estimates, r.sub_estimates.mean(axis=0))


def test_parallel_multipdf_is_deterministic_and_matches_numpy():
    model = models.get("ob1")
    traj = model.simulate(60, seed=5)
    kw = dict(method="multipdf", n_particles=400, n_filters=4, seed=11)
    a = pfbench.run_filter(model, traj.y, backend="numba", **kw)
    b = pfbench.run_filter(model, traj.y, backend="numba", n_threads=1, **kw)
    c = pfbench.run_filter(model, traj.y, backend="numpy", **kw)
    assert np.array_equal(a.sub_estimates, b.sub_estimates)
    assert np.max(np.abs(a.sub_estimates - c.sub_estimates)) <= 1e-9
    # independent streams per sub-filter: the sub-filters differ
    assert not np.allclose(a.sub_estimates[0], a.sub_estimates[1])


def test_float32_runs_and_stays_close_to_float64():
    """float32 storage changes rounding only, so after a few resampling flips a float32 run is just
    another Monte Carlo realisation of the same filter. Per trajectory s, d_s = aRMSE_32 - aRMSE_64
    (same seed) must look like the difference between two float64 runs with different seeds,
    e_s = aRMSE_64(seed a) - aRMSE_64(seed b): |mean d| < 4 sd(e) / sqrt(S) (4 standard errors).
    Catches a float32 path that is biased (e.g. arithmetic that loses the likelihood's precision)."""
    model = models.get("ob1")
    d, e = [], []
    for s in range(8):
        traj = model.simulate(150, seed=s)
        run = lambda dtype, seed: pfbench.metrics.armse(pfbench.run_filter(  # noqa: E731
            model, traj.y, method="bootstrap", n_particles=300, backend="numba", dtype=dtype,
            seed=seed).estimates, traj.x)
        a64, b64, a32 = run("float64", s), run("float64", s + 100), run("float32", s)
        assert np.isfinite(a32)
        d.append(a32 - a64)
        e.append(a64 - b64)
    assert abs(np.mean(d)) < 4 * np.std(e, ddof=1) / np.sqrt(len(e))


# --------------------------------------------------------------------------- Kalman limit
def _lg_model():
    return models.get("linear_gaussian", A=[[0.9]], C=[[1.0]], Q=[[1.0]], R=[[1.0]], x0=[0.0], P0=[[1.0]])


def test_bootstrap_converges_to_kalman_posterior_mean():
    """|PF mean - KF mean| is Monte Carlo error with variance c / N_p, so the mean squared error at
    N = 100 is 16x the one at N = 1600: log(RMSE_100 / RMSE_1600) = log 4. Its standard error comes
    from the per-seed mean squared errors (S = 20 independent trajectories and PF seeds) by the delta
    method, se(log mean m) = sd(m) / (mean(m) sqrt(S)) and the half for the square root; we allow 4
    of them. Catches a filter whose error does not shrink like 1/sqrt(N) (e.g. a biased weighting, or
    resampling that loses particles)."""
    model = _lg_model()
    per_seed = {}
    for n in (100, 1600):
        m = []
        for seed in range(20):
            traj = model.simulate(50, seed=100 + seed)
            kf = kalman.filter_model(model, traj.y)
            r = pfbench.run_filter(model, traj.y, method="bootstrap", n_particles=n, backend="numba",
                                   seed=seed)
            m.append(np.mean((r.estimates[:, 0] - kf.estimates[:, 0]) ** 2))
        per_seed[n] = np.array(m)
    log_ratio = 0.5 * np.log(per_seed[100].mean() / per_seed[1600].mean())
    se = 0.5 * np.sqrt(sum(v.var(ddof=1) / (v.mean() ** 2 * v.size) for v in per_seed.values()))
    assert abs(log_ratio - np.log(4.0)) < 4 * se, (log_ratio, se)


def test_pf_likelihood_is_unbiased():
    """E[p_hat(y)] = p(y): mean of exp(loglik_hat - loglik_KF) over 300 seeds within 3 standard
    errors of 1 (the estimator is unbiased in linear scale, not in log scale)."""
    model = _lg_model()
    traj = model.simulate(20, seed=9)
    exact = kalman.filter_model(model, traj.y).loglik
    ratios = np.array([np.exp(pfbench.run_filter(model, traj.y, method="bootstrap", n_particles=100,
                                                 backend="numba", seed=s).loglik - exact)
                       for s in range(300)])
    se = ratios.std(ddof=1) / np.sqrt(ratios.size)
    assert abs(ratios.mean() - 1.0) < 3 * se


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_asir_counts_the_resampling_of_its_first_stage(backend):
    """ASIR resamples once every step, in its first stage ([Thesis] Alg. 6); its second stage never
    does. Catches a count of the second stage only (0 resamplings reported)."""
    model = models.get("ob1")
    traj = model.simulate(20, seed=1)
    r = pfbench.run_filter(model, traj.y, method="asir", n_particles=100, backend=backend, seed=1)
    assert r.n_resampled == 20 and r.extras["resampled"].all()


def test_asir_and_multipdf_likelihoods_are_unbiased():
    model = _lg_model()
    traj = model.simulate(15, seed=10)
    exact = kalman.filter_model(model, traj.y).loglik
    for kw in (dict(method="asir"), dict(method="multipdf", n_filters=3)):
        ratios = np.array([np.exp(pfbench.run_filter(model, traj.y, n_particles=90, backend="numba",
                                                     seed=s, **kw).loglik - exact) for s in range(300)])
        se = ratios.std(ddof=1) / np.sqrt(ratios.size)
        assert abs(ratios.mean() - 1.0) < 3 * se, kw


# --------------------------------------------------------------------------- numerical trouble
def test_outlier_underflow_keeps_finite_weights():
    """An outlier y = 1e4 on Ob1 makes every likelihood underflow in linear scale (exp(-5e7));
    log-sum-exp keeps normalised weights, so nothing degenerates and estimates stay finite."""
    model = models.get("ob1")
    traj = model.simulate(30, seed=1)
    y = traj.y.copy()
    y[10] = 1e4
    for backend in ("numpy", "numba"):
        r = pfbench.run_filter(model, y, method="bootstrap", n_particles=200, backend=backend, seed=1)
        assert np.all(np.isfinite(r.estimates))
        assert not r.degenerate.any()
        assert np.isfinite(r.loglik)


def test_all_zero_likelihood_step_is_flagged_and_filter_recovers():
    model = models.get("ob1")
    traj = model.simulate(30, seed=1)
    y = traj.y.copy()
    y[10] = 1e200  # (y - x^2/20)^2 overflows to inf -> loglik -inf for every particle
    for backend in ("numpy", "numba"):
        r = pfbench.run_filter(model, y, method="bootstrap", n_particles=200, backend=backend, seed=1)
        assert r.degenerate[10] and r.degenerate.sum() == 1
        assert np.all(np.isfinite(r.estimates))
        assert r.loglik == -np.inf
        # after the bad step the filter tracks again
        assert pfbench.metrics.armse(r.estimates[15:], traj.x[15:]) < 10


@pytest.mark.parametrize("name,method,kw", [("ob1", "bootstrap", {}), ("ob1", "sir", {}),
                                            ("ob1", "multipdf", {"n_filters": 2}), ("ob5", "mpf", {}),
                                            ("pmsm_reduced", "guided", {})])
def test_a_degenerate_step_reports_no_effective_particles(name, method, kw):
    """The step where every likelihood was zero reports N_eff = 0, the others a positive N_eff; a
    Kalman filter's N_eff stays NaN (no particles). Catches a filter family whose result reports the
    kept weights' N_eff (N_p for a bootstrap filter), or a Kalman filter reporting 0."""
    model = models.get(name)
    traj = model.simulate(30, seed=1)
    y = traj.y.copy()
    y[10] = 1e200
    with np.errstate(all="ignore"):
        r = pfbench.run_filter(model, y, traj.u, method=method, n_particles=200, backend="numpy", seed=1, **kw)
    assert r.degenerate.nonzero()[0].tolist() == [10]
    assert r.ess[10] == 0 and np.all(np.delete(r.ess, 10) > 0)
    if name == "ob5":
        model = models.get("linear_gaussian")
        y = model.simulate(30, seed=1).y
        y[10] = 1e200
        with np.errstate(all="ignore"):
            r = pfbench.run_filter(model, y, method="kalman", backend="numpy")
        assert r.degenerate.any() and np.isnan(r.ess).all()


def test_nan_log_likelihoods_are_counted_alike_on_both_backends(log_of_state_file):
    """The log-likelihoods a model returns as NaN (here: log of a negative state) are counted per
    step, by each stream block and summed (N_p = 600 in blocks of at most 128), the same on both
    backends; every method's count is exactly its stored particles below 0 (over MultiPDF's
    sub-filters, also pooled on two threads), ASIR's (two stages) the same on both backends; a model
    without them counts 0. Catches an uncounted backend, stage, block or sub-filter."""
    (name,) = models.load_files([log_of_state_file("counted_log_of_state")])
    model = models.get(name)
    y = model.simulate(15, seed=2).y
    got = {}
    for kw in (dict(method="bootstrap"), dict(method="sis"), dict(method="asir"),
               dict(method="multipdf", n_filters=2), dict(method="multipdf", n_filters=2, n_threads=2)):
        kw = {"n_threads": 1, **kw}
        for backend in ("numpy", "numba"):
            r = pfbench.run_filter(model, y, n_particles=600, backend=backend, seed=4, _block=128,
                                   store_particles=True, **kw)
            got[tuple(kw.values()), backend] = {k: v for k, v in r.info.items() if "invalid" in k}
            if kw["method"] != "asir":  # ASIR also weighs its first stage at states it does not store
                below = (r.extras["particles"][..., 0] < 0).sum(axis=(0, 2))   # per step, all sub-filters
                assert r.info["invalid_log_likelihoods"] == below.sum() > 0, kw
                assert r.info["first_invalid_step"] == np.flatnonzero(below)[0]
        assert got[tuple(kw.values()), "numpy"] == got[tuple(kw.values()), "numba"], got
    r = pfbench.run_filter(models.get("ob1"), models.get("ob1").simulate(15, seed=2).y, n_particles=100)
    assert r.info["invalid_log_likelihoods"] == 0 and "first_invalid_step" not in r.info


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_nan_measurement_names_the_step(bad):
    model = models.get("ob1")
    traj = model.simulate(20, seed=1)
    y = traj.y.copy()
    y[7] = bad
    with pytest.raises(ValueError, match="step 7"):
        pfbench.run_filter(model, y, method="bootstrap", n_particles=10, backend="numpy")


@pytest.mark.parametrize("kw,msg", [
    (dict(n_particles=0), "n_particles"),
    (dict(n_particles=10, n_filters=0, method="multipdf"), "n_filters"),
    (dict(n_particles=10, n_filters=11, method="multipdf"), "cannot exceed"),
    (dict(n_particles=10, method="nope"), "unknown method"),
    (dict(n_particles=10, backend="gpu"), "unknown backend"),
    (dict(n_particles=10, dtype="float16"), "unknown dtype"),
    (dict(n_particles=10, resampling="magic"), "unknown resampling"),
    (dict(n_particles=10, n_filters=2), "multipdf"),
    # accepted, and ignored or misread, from Python
    (dict(n_particles=True), "n_particles must be an integer"),              # ran with 1 particle
    (dict(n_particles=10, n_threads=0), "n_threads must be an integer >= 1"),
    (dict(n_particles=10, n_threads=1.5), "n_threads must be an integer >= 1"),
    (dict(n_particles=10, method="sir", ess_threshold=True), "ess_threshold must be a number"),  # was 1.0
    (dict(n_particles=10, common_random_numbers="no"), "common_random_numbers must be True or False"),
    (dict(n_particles=10, store_particles="no"), "store_particles must be True or False"),
    (dict(method="kalman", dtype="bogus"), "unknown dtype"),                  # the Kalman filter ignored them
    (dict(method="kalman", resampling="bogus"), "unknown resampling"),
    (dict(n_particles=10, seed=-1), "seed must be a non-negative integer, a sequence of them or a"),
])
def test_bad_arguments(kw, msg):
    model = models.get("ob1")
    traj = model.simulate(5, seed=1)
    kw.setdefault("method", "bootstrap")
    with pytest.raises(PfbenchError, match=msg):
        pfbench.run_filter(model, traj.y, **kw)


def test_wrong_shapes():
    model = models.get("ob4")
    traj = model.simulate(5, seed=1)
    with pytest.raises(ValueError, match="inputs u"):
        pfbench.run_filter(model, traj.y, None, method="bootstrap", n_particles=10, backend="numpy")
    with pytest.raises(ValueError, match="y must have shape"):
        pfbench.run_filter(model, traj.y[:, :1], traj.u, method="bootstrap", n_particles=10)
    # a flat y for two outputs: reshaped to one step (when it had two values) or named by its new shape
    for flat in (traj.y[:, 0], traj.y[0]):
        with pytest.raises(ValueError, match=rf"y must have shape \(n_steps, 2\), got \({flat.size},\)"):
            pfbench.run_filter(model, flat, traj.u[:1], n_particles=10, backend="numpy")
    with pytest.raises(ValueError, match="y has no steps"):
        pfbench.run_filter(model, traj.y[:0], traj.u[:0], n_particles=10, backend="numpy")
    ob1 = models.get("ob1")
    with pytest.raises(ValueError, match="model 'ob1' takes no inputs: pass u=None"):
        pfbench.run_filter(ob1, traj.y[:, :1], traj.u, n_particles=10, backend="numpy")


def test_numpy_dtypes_are_taken_by_name():
    """dtype=np.float32 was "unknown dtype <class 'numpy.float32'>"; np.dtype('float32') ran but left
    a dtype object in the result. Catches the name not normalised."""
    model = models.get("ob1")
    traj = model.simulate(5, seed=1)
    for dtype in (np.float32, np.dtype("float32"), "float32"):
        res = pfbench.run_filter(model, traj.y, n_particles=10, backend="numpy", dtype=dtype)
        assert res.dtype == "float32" and isinstance(res.dtype, str)


def test_a_result_prints_in_one_line_and_names_its_columns():
    """The dataclass repr printed every array (50 000 characters for M = 300), and a single name
    was split into letters. Catches either back."""
    model = models.get("ob1")
    res = pfbench.run_filter(model, model.simulate(300, seed=1).y, n_particles=10, backend="numpy")
    assert len(repr(res)) < 300 and repr(res).startswith("FilterResult(method='bootstrap'")
    assert list(res.to_dataframe("pos").columns[1:3]) == ["pos", "pos_var"]
    assert list(res.to_dataframe().columns[1:3]) == ["x", "x_var"]   # ob1's state_names, by default
    ob3 = models.get("ob3")
    res3 = pfbench.run_filter(ob3, ob3.simulate(3, seed=1).y, n_particles=10, backend="numpy")
    assert list(res3.to_dataframe().columns[1::2][:4]) == list(ob3.state_names)   # were x0..x3
    with pytest.raises(ValueError, match="2 names for 1 states"):
        res.to_dataframe(["a", "b"])
