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
    model, traj = ob1_data
    pfbench.run_filter(model, traj.y[:5], method="bootstrap", n_particles=N, backend=backend, dtype=dtype)
    benchmark.extra_info["particle_steps"] = M * N
    benchmark.pedantic(pfbench.run_filter, args=(model, traj.y),
                       kwargs=dict(method="bootstrap", n_particles=N, backend=backend, dtype=dtype, seed=0),
                       rounds=5 if backend == "numba" else 2, iterations=1)


@pytest.mark.parametrize("scheme", resampling.SCHEMES)
@pytest.mark.parametrize("impl", ["numpy", "numba"])
def test_resampling(benchmark, scheme, impl):
    w = np.random.default_rng(0).random(100_000)
    fn = resampling.resample if impl == "numpy" else numba_resampling.resample
    fn(scheme, w, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    benchmark(fn, scheme, w, rng)
