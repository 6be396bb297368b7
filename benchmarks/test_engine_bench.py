"""pytest-benchmark suite (`make bench`): engine and resampling speed. Not run by `make test`.

Results are in seconds per call; divide by M * N_p for ns per particle-step. `pfbench bench`
reports the same engine numbers as ratios to the irreducible-work floor measured in the run.
"""
import numpy as np
import pytest

import pfbench
from pfbench import resampling
from pfbench.backends import numba_resampling

M, N = 1000, 1000


@pytest.fixture(scope="module")
def ob1_data():
    model = pfbench.models.get("ob1")
    return model, model.simulate(M, seed=1)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_ob1_bootstrap(benchmark, ob1_data, backend, dtype):
    """M = N_p = 1000; numba on 1 thread (the engine targets are per thread)."""
    model, traj = ob1_data
    kw = dict(method="bootstrap", n_particles=N, backend=backend, dtype=dtype,
              n_threads=1 if backend == "numba" else None)
    pfbench.run_filter(model, traj.y[:5], **kw)
    benchmark.extra_info["particle_steps"] = M * N
    benchmark.pedantic(pfbench.run_filter, args=(model, traj.y), kwargs=dict(kw, seed=0),
                       rounds=5 if backend == "numba" else 2, iterations=1)


@pytest.mark.parametrize("threads", [1, None], ids=["1thread", "allthreads"])
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_ob1_bootstrap_large(benchmark, ob1_data, threads, dtype):
    """N_p = 10^5, M = 50, numba: 1 thread vs all cores, float64 vs float32."""
    model, traj = ob1_data
    y = traj.y[:50]
    kw = dict(method="bootstrap", n_particles=100_000, backend="numba", dtype=dtype, n_threads=threads)
    pfbench.run_filter(model, y[:3], **kw)
    benchmark.extra_info["particle_steps"] = 50 * 100_000
    benchmark.pedantic(pfbench.run_filter, args=(model, y), kwargs=dict(kw, seed=0), rounds=3, iterations=1)


def test_floor(benchmark):
    """The irreducible work (1 normal + 1 exp per particle-step), M = N_p = 1000."""
    from pfbench.bench.floor import _floor

    rng = np.random.default_rng(0)
    _floor(rng, 8, 2)
    benchmark.extra_info["particle_steps"] = M * N
    benchmark(_floor, rng, N, M)


@pytest.mark.parametrize("scheme", resampling.SCHEMES)
@pytest.mark.parametrize("impl", ["numpy", "numba"])
def test_resampling(benchmark, scheme, impl):
    w = np.random.default_rng(0).random(100_000)
    fn = resampling.resample if impl == "numpy" else numba_resampling.resample
    fn(scheme, w, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    benchmark(fn, scheme, w, rng)
