"""The array-namespace kernel (backend ``cupy``) on NumPy (``xp-numpy``), and on a GPU when there is one.

The CPU tests run the very code the GPU runs, with ``xp = numpy``; the GPU tests at the end skip
with the reason when CuPy or a device is missing.
"""
import subprocess
import sys

import numpy as np
import pytest

import pfbench
from pfbench import models, resampling
from pfbench.backends import array_backend as ab
from pfbench.backends import cupy_backend, trace
from pfbench.errors import InputError


def _lg():
    return models.get("linear_gaussian", A=[[0.9]], C=[[1.0]], Q=[[1.0]], R=[[1.0]])


def test_philox_words_are_numpys_philox():
    # mutation caught: a wrong multiplier, key bump or word order in philox4x64
    key = (0x0123456789ABCDEF, 0xFEDCBA9876543210)
    got = ab.philox4x64(np, np.arange(5, 9, dtype=np.uint64), 3, 7, 11, key)
    for i, c0 in enumerate(range(5, 9)):
        bg = np.random.Philox(counter=np.array([c0 - 1, 3, 7, 11], dtype=np.uint64),
                               key=np.array(key, dtype=np.uint64))
        assert [int(w[i]) for w in got] == [int(v) for v in bg.random_raw(4)]


def test_normals_and_uniforms_are_standard():
    # mutation caught: Box-Muller without the radius, a uniform from the wrong bits, a counter
    # that ignores the sub-filter (rows would repeat)
    z = ab.normals(np, (1, 2), 4, 50_000, 3, 3)
    assert z.shape == (200_000, 3)
    assert abs(z.mean()) < 5 / np.sqrt(z.size) and abs(z.var() - 1) < 5 * np.sqrt(2 / z.size)
    assert abs(np.mean(z[:, 0] * z[:, 1])) < 5 / np.sqrt(len(z))
    assert abs(np.mean(np.abs(z)) - np.sqrt(2 / np.pi)) < 0.005
    rows = z[:, 0].reshape(4, -1)
    assert not np.allclose(rows[0], rows[1])
    u = ab.uniforms(np, (1, 2), 2, 100_000, 0)
    assert 0 <= u.min() and u.max() < 1 and abs(u.mean() - 0.5) < 0.005


@pytest.mark.parametrize("scheme", ["systematic", "stratified"])
def test_ancestors_equal_pfbench_resampling_given_the_same_uniforms(scheme):
    # mutation caught: searchsorted side="left", positions without the total, a missing clamp
    rng = np.random.default_rng(0)
    w = rng.random(1000) ** 4
    w[100:300] = 0.0
    state = np.random.default_rng(9)
    want = resampling.get(scheme)(w, state)
    gen = np.random.default_rng(9)
    u = np.array([[gen.random()]]) if scheme == "systematic" else gen.random(1000)[None, :]
    got = ab.ancestors(np, np.cumsum(w)[None, :], u, 0)
    assert np.array_equal(got, want)


def test_pf_mean_converges_to_the_kalman_mean_on_the_linear_gaussian_model():
    # mutation caught: unweighted means, weights from the wrong rows, noise not rounded / scaled
    model = _lg()
    traj = model.simulate(30, seed=4)
    kf = pfbench.run_filter(model, traj.y, method="kalman", backend="numpy")
    for dtype in ("float64", "float32"):
        pf = pfbench.run_filter(model, traj.y, method="bootstrap", n_particles=20_000, backend="xp-numpy",
                                dtype=dtype, seed=1)
        se = np.sqrt(kf.variances[:, 0] / pf.ess)  # Monte Carlo standard error of a weighted mean
        assert np.max(np.abs(pf.estimates[:, 0] - kf.estimates[:, 0]) / se) < 6
        assert np.allclose(pf.variances[:, 0], kf.variances[:, 0], rtol=0.1)


def test_loglik_is_unbiased_against_the_exact_value():
    # the likelihood estimate (not its log) is unbiased: mean of exp(loglik - exact) is 1
    # mutation caught: the -log N_p of uniform weights dropped, the max m not added back
    model = _lg()
    traj = model.simulate(15, seed=2)
    exact = pfbench.run_filter(model, traj.y, method="kalman", backend="numpy").loglik
    r = np.exp([pfbench.run_filter(model, traj.y, method="bootstrap", n_particles=300, backend="xp-numpy",
                                   seed=s).loglik - exact for s in range(60)])
    assert abs(r.mean() - 1) < 4 * r.std(ddof=1) / np.sqrt(len(r)) + 1e-3
    assert 0.3 < r.mean() < 3


def test_multipdf_batch_rows_are_independent_filters():
    # mutation caught: a draw counter without the sub-filter index (identical sub-filters), an
    # estimate that is not the mean of the rows
    model = models.get("ob1")
    traj = model.simulate(25, seed=3)
    mp = pfbench.run_filter(model, traj.y, method="multipdf", n_particles=1500, n_filters=3,
                            backend="xp-numpy", seed=5)
    bs = pfbench.run_filter(model, traj.y, method="bootstrap", n_particles=500, backend="xp-numpy", seed=5)
    assert np.allclose(mp.sub_estimates[0], bs.estimates, rtol=1e-12, atol=1e-12)
    assert not np.allclose(mp.sub_estimates[0], mp.sub_estimates[1])
    assert np.allclose(mp.estimates, mp.sub_estimates.mean(axis=0))
    assert mp.n_resampled == 3 * 25


def test_ess_weights_and_resampling_decisions():
    # mutation caught: SIR resampling on N_eff > threshold, SIS resampling, ESS not 1 / sum w^2
    model = models.get("ob1")
    traj = model.simulate(40, seed=6)
    n = 2000
    for method, want in (("bootstrap", 40), ("sis", 0)):
        r = pfbench.run_filter(model, traj.y, method=method, n_particles=n, backend="xp-numpy", seed=2)
        assert r.n_resampled == want
        assert np.all((r.ess >= 1 - 1e-9) & (r.ess <= n * (1 + 1e-12)))
    sir = pfbench.run_filter(model, traj.y, method="sir", n_particles=n, backend="xp-numpy", seed=2,
                             ess_threshold=0.5)
    assert np.array_equal(sir.extras["resampled"][0], sir.sub_ess[0] < 0.5 * n)
    assert 0 < sir.n_resampled < 40
    # the weighting on its own: ESS of known weights
    ll = np.array([[0.0, 0.0, np.log(2.0), -np.inf]])
    x = np.arange(4.0).reshape(1, 4, 1)
    cdf, total, m, mean, var, ess, dg = ab.weigh(np, x, ll, None)
    assert ess[0] == pytest.approx(16 / 6) and mean[0, 0] == pytest.approx(5 / 4)
    assert var[0, 0] == pytest.approx((1 * 25 + 1 * 1 + 2 * 9) / 16 / 4) and not dg[0]


def test_degenerate_step_keeps_the_weights_and_gives_minus_inf():
    model = models.get("ob1")
    traj = model.simulate(10, seed=1)
    y = traj.y.copy()
    y[4] = 1e200  # every likelihood underflows to zero
    r = pfbench.run_filter(model, y, method="sir", n_particles=300, backend="xp-numpy", seed=0)
    assert r.degenerate[4] and r.degenerate.sum() == 1 and r.loglik == -np.inf
    assert np.isfinite(r.estimates).all()


def test_unsupported_settings_are_one_line_errors():
    model = models.get("ob1")
    y = model.simulate(5, seed=0).y
    for kw in (dict(method="asir"), dict(resampling="residual"), dict(store_particles=True),
               dict(method="mpf")):
        with pytest.raises(InputError, match="xp-numpy"if "store" in str(kw) or "asir" in str(kw)
                           or "residual" in str(kw) else "particle methods"):
            pfbench.run_filter(model, y, n_particles=50, backend="xp-numpy", **kw)


def test_probe_names_the_model_function_that_fails():
    class Host(models.get("ob1").__class__):
        @staticmethod
        def log_likelihood(y, x, u, t, p):
            return list(x[:, 0])  # not an array of the namespace

    with pytest.raises(InputError, match=r"log_likelihood\(\) cannot run on numpy arrays"):
        cupy_backend.probe(np, Host(), Host().params())
    cupy_backend.probe(np, models.get("ob1"), models.get("ob1").params())


def test_trace_of_ob1_computes_what_the_model_computes():
    # mutation caught: reversed operands of a reflected operator, x ** 2 as pow with the wrong
    # exponent, a dropped column
    model = models.get("ob1")
    fns, p = model.kernel_functions(), model.params()
    rng = np.random.default_rng(0)
    x, z = rng.standard_normal((100, 1)) * 10, rng.standard_normal((100, 1))
    lines, out = trace.trace(fns["transition"], "transition", n_x=1, n_y=1, n_u=0, n_noise=1, p=p,
                             prefix="a", x_names=["x0"], z_names=["z0"])
    got = trace.evaluate(lines, out, {"x0": x[:, 0], "z0": z[:, 0], "t": 7.0})
    assert np.allclose(got[0], fns["transition"](x, None, 7, z, p)[:, 0], rtol=1e-14, atol=1e-12)
    lines, out = trace.trace(fns["log_likelihood"], "log_likelihood", n_x=1, n_y=1, n_u=0, n_noise=1,
                             p=p, prefix="b", x_names=["x0"], y_names=["yv[0]"])
    got = trace.evaluate(lines, out, {"x0": x[:, 0], "yv": np.array([3.0]), "t": 7.0})
    assert np.allclose(got[0], fns["log_likelihood"](np.array([3.0]), x, None, 7, p), rtol=1e-14)
    lg = _lg()
    with pytest.raises(trace.TraceError):
        trace.trace(lg.kernel_functions()["transition"], "transition", n_x=1, n_y=1, n_u=0, n_noise=1,
                    p=lg.params(), prefix="a", x_names=["x0"], z_names=["z0"])


def test_trace_follows_numpy_broadcasting_on_two_states():
    def f(x, u, t, noise, p):
        out = np.empty_like(x)
        out[:, 0] = np.cbrt(x[:, 0] * x[:, 0]) - 2.0 / (1.0 + x[:, 1])
        out[:, 1] = x[:, 1] ** 2 + noise[:, 0]
        return out

    lines, out = trace.trace(f, "transition", n_x=2, n_y=1, n_u=0, n_noise=1, p=(), prefix="a",
                             x_names=["x0", "x1"], z_names=["z0"])
    x, z = np.array([[1.5, 0.25], [-2.0, 3.0]]), np.array([[0.1], [0.2]])
    got = trace.evaluate(lines, out, {"x0": x[:, 0], "x1": x[:, 1], "z0": z[:, 0]})
    assert np.allclose(np.stack(got, axis=1), f(x, None, 0, z, ()))
    with pytest.raises(trace.TraceError, match="broadcast"):
        trace.trace(lambda x, u, t, z, p: x + x[:, 0], "transition", n_x=1, n_y=1, n_u=0, n_noise=1,
                    p=(), prefix="a", x_names=["x0"], z_names=["z0"])


def _has_cupy() -> bool:
    try:
        import cupy  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.skipif(_has_cupy(), reason="CuPy is installed here")
def test_cli_backend_cupy_without_cupy_is_one_line_exit_2():
    r = subprocess.run([sys.executable, "-m", "pfbench.cli", "run", "--model", "ob1", "--backend", "cupy",
                        "--particles", "100", "--steps", "5"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "CuPy" in r.stderr and "pfbench[gpu]" in r.stderr


# --------------------------------------------------------------------------- on a GPU
def _cupy_or_skip():
    cp = pytest.importorskip("cupy", reason="CuPy is not installed (pip install 'pfbench[gpu]')")
    try:
        if cp.cuda.runtime.getDeviceCount() < 1:
            pytest.skip("no CUDA device")
    except Exception as exc:  # noqa: BLE001
        pytest.skip(f"no CUDA device: {exc}")
    return cp


def test_gpu_fused_steps_are_active_for_ob1():
    cp = _cupy_or_skip()
    for dtype in ("float64", "float32"):
        steps = cupy_backend.fused_steps(cp, models.get("ob1"), dtype)
        assert set(steps.info["gpu_steps"]["fused"]) == {"normals", "model_step", "weigh", "resample"}, \
            steps.info["gpu_steps"]["why_not"]


@pytest.mark.parametrize("method", ["bootstrap", "sir", "sis", "multipdf"])
def test_gpu_agrees_with_the_same_code_on_numpy(method):
    # the same Philox words on both: estimates agree to the libraries' last bits for a few steps
    cp = _cupy_or_skip()  # noqa: F841
    model = models.get("ob1")
    traj = model.simulate(15, seed=1)
    kw = dict(method=method, n_particles=30_000, seed=3, **({"n_filters": 3} if method == "multipdf" else {}))
    g = pfbench.run_filter(model, traj.y, backend="cupy", **kw)
    c = pfbench.run_filter(model, traj.y, backend="xp-numpy", **kw)
    assert np.allclose(g.estimates, c.estimates, rtol=1e-6, atol=1e-6)
    assert g.loglik == pytest.approx(c.loglik, rel=1e-8)
    assert g.n_resampled == c.n_resampled


def test_gpu_namespace_path_runs_an_untraceable_model():
    cp = _cupy_or_skip()  # noqa: F841
    model = _lg()
    traj = model.simulate(20, seed=4)
    kf = pfbench.run_filter(model, traj.y, method="kalman", backend="numpy")
    pf = pfbench.run_filter(model, traj.y, n_particles=100_000, backend="cupy", seed=1)
    assert "model_step" not in pf.info["gpu_steps"]["fused"]
    se = np.sqrt(kf.variances[:, 0] / pf.ess)
    assert np.max(np.abs(pf.estimates[:, 0] - kf.estimates[:, 0]) / se) < 6


def test_gpu_resampling_kernel_on_concentrated_weights():
    cp = _cupy_or_skip()
    model = models.get("ob1")
    fz = cupy_backend.Fused(cp, model, "float64")
    rng = np.random.default_rng(1)
    n = 200_003
    for case in range(3):
        ll = np.full((2, n), -np.inf)
        if case == 0:
            ll[:, 5] = 0.0  # one particle carries everything
        elif case == 1:
            ll[:, rng.integers(0, n, 50)] = rng.standard_normal(50)
        else:
            ll[:] = -50 * rng.random((2, n)) ** 2
        x = rng.standard_normal((2, n, 1))
        c_h = ab.weigh(np, x, ll, None)[0]
        xd = cp.asarray(x)
        c_d = fz.weigh(cp, xd, cp.asarray(ll), None)[0]
        u = rng.random((2, 1))
        _, idx = fz.ancestors_and_gather(cp, xd, c_d, cp.asarray(u), None, True)
        want = np.stack([ab.ancestors(np, c_h, u, f) for f in range(2)])
        assert np.mean(cp.asnumpy(idx) != want) < 1e-4
