"""run_filter(estimate="pre"|"post"): where a step's point estimate is taken. ``post`` is the
unweighted mean/variance of the resampled particles ([MultiPDF] Alg. 1 step 6, Alg. 2 step 2e);
``pre`` the weighted one before resampling. Backends agree, thread counts do not matter, steps
that do not resample keep ``pre``, and ``post`` is ``pre`` plus zero-mean resampling noise."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

import pfbench
from pfbench import models
from pfbench.errors import InputError


def _run(model, traj, backend, method, estimate, **kw):
    kw.setdefault("n_particles", 120)
    if method == "multipdf":
        kw.setdefault("n_filters", 3)
    return pfbench.run_filter(model, traj.y, traj.u, method=method, backend=backend, seed=7,
                              common_random_numbers=True, estimate=estimate, **kw)


# ob4: two states (every component's sums, the 4-way partial sums of the second); ob1 SIR at
# ess_threshold 0.5 resamples at 28 of 40 steps (both kinds of step); ob1 float32 (moments of the
# stored float32 states in float64, as pre); MultiPDF under common random numbers: a group of 3
# sub-filters in one kernel call (pass D per filter of the group)
@pytest.mark.parametrize("name,method,dtype,kw", [
    ("ob4", "bootstrap", "float64", {}),
    ("ob4", "multipdf", "float64", {}),
    ("ob1", "sir", "float64", {"ess_threshold": 0.5}),
    ("ob1", "bootstrap", "float32", {}),
])
def test_backends_agree_for_post(name, method, dtype, kw):
    """NumPy and numba give the same post estimates and variances (<= 1e-9, the tolerance of every
    backend-agreement test: the moments are summed in another order) and the same run as pre
    (loglik, ess, resampling decisions bit for bit on each backend: the estimate feeds nothing
    back). Post differs from pre exactly at the steps that resampled and equals it bit for bit at
    the others. Catches a numba pass D that is missing (numba's post is pre), reads the
    pre-resampling buffer, divides by the wrong count, uses a wrong shift for the variance or skips
    a filter of the group; a post applied at steps that did not resample (SIR); and an estimate
    that changes the filter itself."""
    model = models.get(name)
    traj = model.simulate(40, seed=3)
    runs = {(be, at): _run(model, traj, be, method, at, dtype=dtype, **kw)
            for be in ("numpy", "numba") for at in ("pre", "post")}
    a, b = runs["numpy", "post"], runs["numba", "post"]
    np.testing.assert_allclose(b.estimates, a.estimates, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.variances, a.variances, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.sub_estimates, a.sub_estimates, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.sub_variances, a.sub_variances, rtol=1e-9, atol=1e-9)
    assert b.loglik == pytest.approx(a.loglik, rel=1e-10, abs=1e-9)
    assert a.info["estimate"] == b.info["estimate"] == "post"
    for be in ("numpy", "numba"):
        pre, post = runs[be, "pre"], runs[be, "post"]
        assert pre.info["estimate"] == "pre"
        assert post.loglik == pre.loglik and np.array_equal(post.ess, pre.ess)
        did = post.extras["resampled"]  # (N_f, M)
        assert np.array_equal(did, pre.extras["resampled"])
        assert did.any()
        same = np.all(post.sub_estimates == pre.sub_estimates, axis=2)
        assert np.array_equal(same, ~did), be  # differs exactly where it resampled
        assert np.array_equal(post.sub_variances[~did], pre.sub_variances[~did])
    if method == "sir":
        assert not did.all()  # the test needs steps that kept their weights


@pytest.mark.parametrize("method", ["sis", "asir"])
@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_post_is_pre_where_nothing_resamples_after_the_estimate(backend, method):
    """SIS never resamples, and ASIR resamples before it propagates (its step ends with the
    weighted particles): post is pre, bit for bit. Catches a post estimate taken at every step
    (the unweighted mean of weighted particles) or after ASIR's first-stage resampling."""
    model = models.get("ob1")
    traj = model.simulate(30, seed=2)
    pre = _run(model, traj, backend, method, "pre")
    post = _run(model, traj, backend, method, "post")
    np.testing.assert_array_equal(post.estimates, pre.estimates)
    np.testing.assert_array_equal(post.variances, pre.variances)


@pytest.mark.parametrize("method,n_particles", [("bootstrap", 9000), ("multipdf", 18000)])
def test_post_does_not_depend_on_the_thread_count(method, n_particles):
    """N_p > 8192: 16 stream blocks per filter (MultiPDF: 2 sub-filters of 9000, one group under
    common random numbers), so pass D's block loop is a prange. 1 and 2 threads give bit-identical
    post estimates and variances, and NumPy the same to 1e-9. Catches a thread-order reduction of
    the block sums, a block left out of pass D (NumPy would differ) or sums of one filter of the
    group written over another's."""
    model = models.get("ob1")
    traj = model.simulate(12, seed=4)
    kw = dict(method=method, n_particles=n_particles, seed=5, common_random_numbers=True, estimate="post")
    if method == "multipdf":
        kw["n_filters"] = 2
    a = pfbench.run_filter(model, traj.y, n_threads=1, **kw)
    b = pfbench.run_filter(model, traj.y, n_threads=2, **kw)
    c = pfbench.run_filter(model, traj.y, backend="numpy", **kw)
    for name in ("estimates", "variances", "sub_estimates", "sub_variances"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        np.testing.assert_allclose(getattr(a, name), getattr(c, name), rtol=1e-9, atol=1e-9, err_msg=name)
    pre = pfbench.run_filter(model, traj.y, n_threads=2, **{**kw, "estimate": "pre"})
    assert np.all(pre.sub_estimates != b.sub_estimates)  # bootstrap resamples at every step


def test_post_is_pre_plus_zero_mean_resampling_noise():
    """Systematic resampling gives particle i N w_i offspring in expectation, so given everything up
    to the weighting of step t, E[post_t] = pre_t: D_t = post_t - pre_t has conditional mean 0, and
    so has D_t e_t for any e_t known by then, here e_t = y_t - post_{t-1} (the innovation the
    filter's prediction leaves, with A = C = 1). Per seed s (independent trajectory and filter),
    d_s = mean_t D_t and g_s = mean_t D_t e_t are then zero-mean, and across S = 200 seeds each
    mean must lie within 4 standard errors sd/sqrt(S) of 0 (a false alarm once in ~16000 per
    statistic; the seeds are fixed, so the test is deterministic). The state sits near 10, so
    d catches a post mean that is scaled (a divisor N - 1) or taken with stale weights; g catches
    a post taken from the propagated particles before resampling, unweighted: D_t is then about
    -K (y_t - prediction), and g about -K E[e^2] < 0. Same backend, same seed: the run itself is
    the same (loglik bit for bit), post really differs (at every step), and NumPy needs no compile."""
    model = models.get("linear_gaussian", A=[[1.0]], C=[[1.0]], Q=[[0.1]], R=[[1.0]], x0=[10.0], P0=[[1.0]])
    S, M = 200, 30
    d, g = [], []
    for s in range(S):
        traj = model.simulate(M, seed=1000 + s)
        kw = dict(method="bootstrap", n_particles=100, backend="numpy", seed=s)
        pre = pfbench.run_filter(model, traj.y, estimate="pre", **kw)
        post = pfbench.run_filter(model, traj.y, estimate="post", **kw)
        assert post.loglik == pre.loglik
        D = post.estimates[:, 0] - pre.estimates[:, 0]
        assert np.all(D != 0)
        d.append(D.mean())
        g.append(np.mean(D[1:] * (traj.y[1:, 0] - post.estimates[:-1, 0])))
    for name, v in (("d", np.array(d)), ("g", np.array(g))):
        se = v.std(ddof=1) / np.sqrt(S)
        assert abs(v.mean()) < 4 * se, (name, v.mean(), se)


@pytest.mark.parametrize("method", ["mpf", "guided", "kalman"])
def test_post_is_refused_where_it_does_not_apply(method):
    """mpf, guided and kalman take their estimate their own way: post is one InputError naming the
    method (pre, the default, runs). Catches a post silently ignored (pre numbers labelled post)."""
    model = models.get("pmsm" if method == "guided" else "linear_gaussian")  # pmsm has a proposal
    traj = model.simulate(5, seed=1)
    kw = dict(method=method, n_particles=10, backend="numpy")
    with pytest.raises(InputError, match=f"estimate='post'.*not '{method}'"):
        pfbench.run_filter(model, traj.y, traj.u, estimate="post", **kw)
    pfbench.run_filter(model, traj.y, traj.u, estimate="pre", **kw)


@pytest.mark.parametrize("method", ["bootstrap", "multipdf"])
def test_post_is_refused_on_the_array_backends(method):
    """The array-namespace kernel (cupy, xp-numpy) takes pre only: post is one InputError naming
    the backend, in run_filter and in make_spec (before any sweep work); pre runs. Catches post
    silently running as pre there."""
    model = models.get("ob1")
    traj = model.simulate(5, seed=1)
    kw = dict(method=method, n_particles=40, n_filters=2 if method == "multipdf" else 1, backend="xp-numpy")
    with pytest.raises(InputError, match="estimate='post' is not available on backend 'xp-numpy'") as e:
        pfbench.run_filter(model, traj.y, traj.u, estimate="post", **kw)
    assert "\n" not in str(e.value)
    r = pfbench.run_filter(model, traj.y, traj.u, estimate="pre", **kw)
    assert r.info["estimate"] == "pre" and np.isfinite(r.estimates).all()
    with pytest.raises(InputError, match="--estimate post is not available on backend 'xp-numpy'"):
        pfbench.sweep.make_spec("ob1", methods=[method], particles=(40,), filters=(kw["n_filters"],), runs=1,
                                steps=5, backend="xp-numpy", estimate="post")
    spec = pfbench.sweep.make_spec("ob1", methods=[method], particles=(40,), filters=(kw["n_filters"],), runs=1,
                                   steps=5, backend="xp-numpy", estimate="pre")
    assert spec["estimate"] == "pre"


@pytest.mark.parametrize("bad", ["mid", "", None, 2])
def test_bad_estimate_is_an_input_error(bad):
    """Catches a value that is not checked (a typo running as pre)."""
    model = models.get("ob1")
    traj = model.simulate(5, seed=1)
    with pytest.raises(InputError, match="unknown estimate"):
        pfbench.run_filter(model, traj.y, method="bootstrap", n_particles=10, backend="numpy", estimate=bad)
    with pytest.raises(InputError, match="unknown estimate"):
        pfbench.sweep.make_spec("ob1", particles=(10,), runs=1, steps=5, estimate=bad)


def test_cli_run_estimate():
    """``pfbench run --estimate post`` runs post (its aRMSE is run_filter's with estimate="post") and
    says so; a bad value is click's one-line usage error. Catches the option not handed on."""
    from pfbench.cli import main

    args = ["run", "--model", "ob1", "--particles", "50", "--steps", "20", "--truth-seed", "0", "--json"]
    args_np = [*args, "--backend", "numpy"]
    out = {}
    for at in ("pre", "post"):
        r = CliRunner().invoke(main, [*args_np, "--estimate", at])
        assert r.exit_code == 0, r.output
        out[at] = json.loads(r.output)
        assert out[at]["estimate"] == at
    model = models.get("ob1")
    traj = model.simulate(20, seed=0)
    ref = pfbench.run_filter(model, traj.y, method="bootstrap", n_particles=50, backend="numpy", seed=0,
                             estimate="post")
    assert out["post"]["armse"] == pfbench.metrics.armse(ref.estimates, traj.x) != out["pre"]["armse"]
    r = CliRunner().invoke(main, [*args_np, "--estimate", "mid"])
    assert r.exit_code == 2 and "--estimate" in r.output
    r = CliRunner().invoke(main, [*args, "--backend", "cupy", "--estimate", "post"])  # GPU or not
    assert r.exit_code == 2 and "estimate='post' is not available on backend 'cupy'" in r.output


def test_sweep_estimate_cli_store_and_older_stores(tmp_path):
    """``pfbench sweep --estimate post`` on a MultiPDF-vs-MPF grid: the MultiPDF tasks are
    run_filter's post aRMSEs (the task's own filter seed; pre gives others on the same seeds), the
    MPF tasks keep the MPF's own estimate (pre: post is refused by run_filter but not by a sweep
    that compares against the MPF), and the frame and summary say which per configuration. A store
    whose spec has no ``estimate`` (written before the option) reads as pre. Catches a spec option
    the tasks ignore, a post sweep refused for its MPF configurations, and an older store that no
    longer loads."""
    from pfbench.cli import main
    from pfbench.sweep import load_frame, summarize_frame
    from pfbench.sweep.core import filter_seed, trajectory_seed
    from pfbench.sweep.store import Store

    out = tmp_path / "post.jsonl"
    r = CliRunner().invoke(main, ["sweep", "--model", "ob2", "--method", "multipdf,mpf", "--particles", "20",
                                  "--filters", "1,2", "--runs", "2", "--steps", "10", "--backend", "numpy",
                                  "--estimate", "post", "--workers", "1", "--quiet", "--out", str(out)])
    assert r.exit_code == 0, r.output
    frame, spec, _ = load_frame(out)
    assert spec["estimate"] == "post" and len(frame) == 6
    expect = {"multipdf": "post", "mpf": "pre"}
    assert list(frame["estimate"]) == [expect[m] for m in frame["method"]]
    summ = summarize_frame(frame, spec)
    assert list(summ["estimate"]) == [expect[m] for m in summ["method"]]
    model = models.get("ob2")
    for row in frame.itertuples():
        traj = model.simulate(10, seed=np.random.default_rng(trajectory_seed(spec, row.run)))
        cfg = spec["configs"][row.config]
        run = lambda at: pfbench.metrics.armse(pfbench.run_filter(  # noqa: E731
            model, traj.y, traj.u, method=cfg[0], n_particles=cfg[1], n_filters=cfg[2], backend="numpy",
            seed=filter_seed(spec, cfg, row.run), estimate=at).estimates, traj.x)
        assert row.armse == pytest.approx(run(row.estimate), rel=1e-12)
        if row.method == "multipdf":
            assert row.armse != pytest.approx(run("pre"), rel=1e-12)
    old_spec = {k: v for k, v in spec.items() if k != "estimate"}
    old = Store.open(tmp_path / "old.jsonl", old_spec)
    old.append([dict(rec) for rec in Store.read(out).records.values()])
    old.close()
    frame, spec, _ = load_frame(tmp_path / "old.jsonl")
    assert "estimate" not in spec and set(frame["estimate"]) == {"pre"}
    assert set(summarize_frame(frame, spec)["estimate"]) == {"pre"}
