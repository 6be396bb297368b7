"""Stream blocks and threads of the particle kernel: thread-count invariance, backend agreement on
multi-block runs, single-block runs pinned to the unblocked kernel's numbers, and a multi-block
filter that still tracks the Kalman mean. Multi-block runs are made small with the private
``_block`` keyword (N_p = 600 with blocks of at most 128: 16 blocks of 37 or 38 particles)."""
import numpy as np
import pytest

import pfbench
from pfbench import models

SCHEMES = list(pfbench.resampling.SCHEMES)


@pytest.fixture(scope="module")
def ob1():
    model = models.get("ob1")
    return model, model.simulate(30, seed=1)


def _run(model, traj, **kw):
    kw.setdefault("n_particles", 600)
    kw.setdefault("_block", 128)
    kw.setdefault("seed", 5)
    return pfbench.run_filter(model, traj.y, traj.u, **kw)


# every block loop of the kernel on 2 threads: both resampling paths (the merge that writes the
# particles: systematic, stratified with its per-block uniforms; the index schemes' gather:
# multinomial), ASIR's two stages, SIR's weights kept between resamplings, and float32 (draws,
# storage and gathers in the particle dtype); each (scheme, dtype) compiles its own all-threads
# kernel (15-25 s cold), so the backend agreement below runs on the serial compilation
@pytest.mark.parametrize("method,scheme,dtype", [("bootstrap", "systematic", "float64"),
                                                 ("bootstrap", "stratified", "float64"),
                                                 ("sir", "multinomial", "float64"),
                                                 ("asir", "systematic", "float64"),
                                                 ("sir", "systematic", "float32")])
def test_thread_count_does_not_change_a_multi_block_run(ob1, method, scheme, dtype):
    """n_threads=1 (serial compilation) and 2 (parallel compilation, block loops on 2 threads) give
    bit-identical results. Catches a prange reduction (thread-dependent summation order), block
    streams keyed on the thread, or a parallel variant that drifts from the serial one."""
    model, traj = ob1
    a = _run(model, traj, method=method, resampling=scheme, dtype=dtype, n_threads=1)
    b = _run(model, traj, method=method, resampling=scheme, dtype=dtype, n_threads=2)
    for name in ("estimates", "variances", "ess", "loglik_increments"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.loglik == b.loglik


# float64 with every scheme; float32 with one scheme of each resampling path (the merge that writes
# the particles, the index schemes' gather): what float32 changes (draws, storage, gathers in the
# particle dtype) does not depend on the scheme. On one thread: the block layout, not the thread
# count, fixes the numbers (the test above), so the serial compilation stands for both
@pytest.mark.parametrize("dtype,scheme", [*(("float64", s) for s in SCHEMES), ("float32", "systematic"),
                                          ("float32", "multinomial")])
@pytest.mark.parametrize("method", ["bootstrap", "sir", "sis", "asir", "multipdf"])
def test_numpy_and_numba_agree_on_multi_block_runs(ob1, scheme, method, dtype):
    """The NumPy reference reproduces the block layout (streams, blockwise cdf, resampling
    uniforms) under common random numbers. float64: <= 1e-9 (the backends differ only in the
    summation order of the moments). float32: both backends store float32 particles from the same
    float64 model evaluation, so the trajectories are the same; only the moment sums differ
    (float32 inputs, float64 sums): the same 1e-9 holds, well above 30 steps x n_x x eps64 x N_p.
    Catches a NumPy/numba mismatch in any stream (noise of block b, stratified uniforms), in the
    cdf offsets or in the float32 draw."""
    model, traj = ob1
    kw = dict(method=method, resampling=scheme, dtype=dtype, common_random_numbers=True, n_threads=1)
    if method == "multipdf":
        kw.update(n_filters=2, n_particles=600)  # 2 sub-filters of 300: 3 blocks each
    a = _run(model, traj, backend="numpy", **kw)
    b = _run(model, traj, backend="numba", **kw)
    np.testing.assert_allclose(b.estimates, a.estimates, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.variances, a.variances, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.loglik_increments, a.loglik_increments, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.ess, a.ess, rtol=1e-9)


# Numbers of the unblocked kernel (before stream blocks and fused passes), Ob1 bootstrap,
# N_p = 1000 (one block), M = 50 (simulate seed 1), seed 3, float64: (loglik, last estimate).
PINNED = {
    "systematic": (-125.5559786786084, 2.379461199007912),
    "stratified": (-126.10494774740626, 2.506818278187377),
    "multinomial": (-125.91516516805098, 2.5101344579388396),
    "residual": (-126.1361738102991, 2.2809817944265687),
    "residual_deterministic": (-125.01556481877101, 2.350883037653931),
}


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_single_block_runs_keep_the_single_stream_numbers(scheme, backend):
    """With one block the filter draws from its own stream in the documented order: the numbers
    are those of the unblocked kernel, bit for bit. Catches a changed draw order (e.g. resampling
    uniforms before the noise, tile-wise draws that are not the one big draw, a block stream used
    with one block) or a changed weight/cdf arithmetic."""
    assert scheme in PINNED, "a new scheme: pin the numbers of this run in PINNED (its first kernel's)"
    model = models.get("ob1")
    traj = model.simulate(50, seed=1)
    r = pfbench.run_filter(model, traj.y, method="bootstrap", n_particles=1000, resampling=scheme,
                           backend=backend, seed=3)
    assert r.loglik == PINNED[scheme][0]
    # the mean feeds nothing back, and each backend sums it in its own order (numba: beside the
    # running sum in pass B; NumPy: a BLAS dot product), so it is the same to rounding
    assert r.estimates[-1, 0] == pytest.approx(PINNED[scheme][1], rel=1e-12)


def test_multi_block_filter_tracks_the_kalman_mean():
    """On a scalar linear-Gaussian model the multi-block bootstrap mean tracks the exact Kalman mean.
    Tolerance: the MC error of a weighted mean is about sqrt(P / N_eff) with P the Kalman variance
    and N_eff >= N_p / 4 here; 5 sigma per step. The mean absolute error must also be below
    1.5 sqrt(P / N_p) (expected about 0.8 sqrt(P/N_eff) <= 1.6 sqrt(P/N_p) ... averaged over 60
    steps). Catches blocks that reuse one stream (correlated noise), a wrong cdf offset (particles
    drawn from the wrong block) or a lost block in the reductions."""
    model = models.get("linear_gaussian")
    traj = model.simulate(60, seed=4)
    kf = pfbench.run_filter(model, traj.y, traj.u, method="kalman")
    r = pfbench.run_filter(model, traj.y, traj.u, method="bootstrap", n_particles=2000, _block=256, seed=7,
                           n_threads=1)  # the numbers do not depend on the thread count (tested above)
    sd = np.sqrt(kf.variances[:, 0])
    err = np.abs(r.estimates[:, 0] - kf.estimates[:, 0])
    assert np.all(err < 5 * sd / np.sqrt(r.ess / 1.0))
    assert err.mean() < 2.0 * np.mean(sd) / np.sqrt(r.ess.mean())


@pytest.mark.parametrize("method", ["bootstrap", "sir"])
def test_final_particles_are_the_same_on_both_backends_and_thread_counts(ob1, method):
    """The backends' ``run_group`` hands back the final particles in ``x`` (the numba kernel copies
    them out of its current buffer block by block, on every thread). Two filters in one group,
    16 blocks: NumPy, numba on 1 thread and numba on 2 threads give the same particles, bit for bit
    (the trajectories are the same under common random numbers; the particles are copies, no
    arithmetic). Catches a copy-out that skips blocks or filters, reads the other buffer, or lands
    the initial particles anywhere but where the first step reads them."""
    from pfbench.backends import numba_backend, numpy_backend
    from pfbench.backends.particle_work import outputs
    from pfbench.filters.particle import streams

    model, traj = ob1
    n, block, G, M = 600, 128, 2, traj.y.shape[0]
    code = int(pfbench.methods.Method.parse(method))
    finals = []
    for be, threads in ((numpy_backend, 1), (numba_backend, 1), (numba_backend, 2)):
        rng = streams(11, 1, True)[0]
        brngs = numpy_backend.block_streams(rng, rng.bit_generator.seed_seq, n, block)
        out = outputs(G, M, n, 1)
        out.x[:] = np.nan
        be.run_group(model, model.params(), rng, traj.y, np.zeros((M, 0)), out, code, 0, 300.0,
                     brngs=brngs, n_threads=threads, block=block)
        finals.append(out.x)
    assert not np.isnan(finals[0]).any()
    assert not np.array_equal(finals[0][0], finals[0][1])  # two filters, two sets of particles
    np.testing.assert_array_equal(finals[1], finals[0])
    np.testing.assert_array_equal(finals[2], finals[0])


# ---------------------------------------------------------------- the initial draw
# Ob1 starts every particle at one point, so the tests above never see a random initial draw; the
# stochastic-volatility model draws its initial particles from its stationary law.
@pytest.fixture(scope="module")
def sv():
    model = models.get("stochastic_volatility")
    return model, model.simulate(30, seed=1)


def _old_draw(model, rng, G, n):
    """The initial draw of the code before per-block draws: filter after filter from the group's stream."""
    init, p = model.kernel_functions()["initial"], model.params()
    return np.stack([np.asarray(init(rng, n, p)) for _ in range(G)])


@pytest.mark.parametrize("n,block", [(600, 128), (1000, 8192)])
def test_initial_draw_is_per_block(sv, n, block):
    """Several blocks: block b of filter g is ``initial(brngs[b], size of block b)``, filters in turn
    within a block. One block: the group's stream, filter after filter, as before per-block draws
    (the single-stream numbers). Catches a block drawn from the wrong stream or into the wrong
    slice, a block skipped, or a changed single-block draw."""
    from pfbench.backends import numpy_backend as nb
    from pfbench.filters.particle import streams

    model, _ = sv
    init, p, G = model.kernel_functions()["initial"], model.params(), 2

    def fresh():
        rng = streams(9, 1, True)[0]
        return rng, nb.block_streams(rng, rng.bit_generator.seed_seq, n, block)

    rng, brngs = fresh()
    if len(brngs) == 1:
        want = _old_draw(model, rng, G, n)
    else:
        bounds = nb.block_bounds(n, block)
        want = np.empty((G, n, 1))
        for b, r in enumerate(brngs):
            for g in range(G):
                want[g, bounds[b]:bounds[b + 1]] = init(r, int(bounds[b + 1] - bounds[b]), p)
    rng, brngs = fresh()
    x = np.full((G, n, 1), np.nan)
    nb.draw_initial(init, p, rng, x, brngs)
    np.testing.assert_array_equal(x, want)
    assert not np.array_equal(x[0], x[1])  # the two filters drew their own particles


# (loglik, last estimate) of the code before per-block draws (NumPy backend), SV model, M = 40
# (simulate seed 1), N_p = 1000 (one block), seed 3
SV_PINNED = {"systematic": (-31.65523086253603, -1.6685340625195144),
             "multinomial": (-31.366166706505357, -1.6650360570349663)}


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize("scheme", list(SV_PINNED))
def test_single_block_runs_keep_their_random_initial_draw(backend, scheme):
    """With one block the initial particles still come from the filter's own stream before any
    other draw: a model with a random initial draw keeps the numbers it had. Catches the per-block
    draw reaching single-block runs (a block stream with one block, or the draw moved after the
    first noise)."""
    model = models.get("stochastic_volatility")
    traj = model.simulate(40, seed=1)
    r = pfbench.run_filter(model, traj.y, traj.u, method="bootstrap", n_particles=1000, resampling=scheme,
                           backend=backend, seed=3)
    assert r.loglik == pytest.approx(SV_PINNED[scheme][0], rel=1e-12)
    assert r.estimates[-1, 0] == pytest.approx(SV_PINNED[scheme][1], rel=1e-12)


def test_random_initial_draw_multi_block_threads_and_backends_agree(sv):
    """A model with a random initial draw, 16 blocks: numba on 1 and 2 threads bit-identical, and
    the NumPy reference within the agreement test's 1e-9 (MultiPDF with common random numbers:
    two filters in one group share the block streams). Catches a backend that draws the initial
    particles in another order or from another stream, or a thread-dependent draw."""
    model, traj = sv
    for kw in (dict(method="bootstrap"), dict(method="multipdf", n_filters=2, common_random_numbers=True)):
        if kw["method"] == "multipdf":
            kw["n_particles"] = 1200  # 2 filters of 600 in one group
        a = _run(model, traj, backend="numba", n_threads=1, **kw)
        b = _run(model, traj, backend="numba", n_threads=2, **kw)
        c = _run(model, traj, backend="numpy", **kw)
        for name in ("estimates", "variances", "ess", "loglik_increments"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
            np.testing.assert_allclose(getattr(c, name), getattr(a, name), rtol=1e-9, atol=1e-9, err_msg=name)


def test_the_result_says_how_many_threads_the_run_used(ob1, monkeypatch):
    """``info["threads"]``: the threads asked for (at most numba's), the free cores by default, 1 for
    one stream block or on NumPy, the pool's workers for MultiPDF's groups. Catches a result that
    reports the request instead of what ran, or no count at all (a slow run on a busy machine then
    looks like pfbench's fault)."""
    from pfbench.filters import particle
    from pfbench.procs import numba_threads

    model, traj = ob1
    top = numba_threads()
    assert _run(model, traj, n_threads=1).info["threads"] == 1
    assert _run(model, traj, n_threads=2).info["threads"] == min(2, top)
    monkeypatch.setattr(particle, "free_cores", lambda: 1)  # a busy machine: one free core
    assert _run(model, traj).info["threads"] == 1
    monkeypatch.setattr(particle, "free_cores", lambda: 64)
    assert _run(model, traj).info["threads"] == top
    assert _run(model, traj, n_threads=2, _block=None).info["threads"] == 1  # 600 particles: one block
    assert _run(model, traj, n_threads=2, backend="numpy").info["threads"] == 1
    mpdf = _run(model, traj, method="multipdf", n_filters=4, n_threads=3, _block=None)
    assert mpdf.info["threads"] == min(3, top)
