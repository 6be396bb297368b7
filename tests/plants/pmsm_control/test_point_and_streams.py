"""The heaviest-particle "maximum" and the Fig. 4.5 filter streams of the closed loop ([Thesis] §4.4)."""
import numpy as np
import pytest

from pfbench.plants.pmsm_control.closed_loop import LoopConfig, Scenario, run_once
from pfbench.plants.pmsm_control.smc import point_estimate

SHORT = Scenario(ramp_s=0.02, hold_s=0.01, omega_final=2.0)


def test_max_weight_is_the_heaviest_particle_not_the_density_mode():
    # a dense light cluster near theta = 1 and one heavy isolated particle at theta = -2:
    # the kernel-density mode is in the cluster, the heaviest particle is the isolated one
    om = np.array([1.0, 1.02, 0.98, 1.01, 5.0])
    th = np.array([1.0, 1.01, 0.99, 1.02, -2.0])
    wn = np.array([0.17, 0.17, 0.17, 0.17, 0.32])
    out = np.empty(5)
    point_estimate(om, th, wn, 3, None, out)
    assert out[0] == 5.0 and out[1] == -2.0
    point_estimate(om, th, wn, 2, None, out)
    assert abs(out[1] - 1.0) < 0.05


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_filter_stream_keeps_the_plant_noise_and_changes_the_filter(backend):
    a = run_once(LoopConfig(scenario=SHORT, backend=backend, filter_stream=1), 0, 2)
    b = run_once(LoopConfig(scenario=SHORT, backend=backend, filter_stream=2), 0, 2)
    c = run_once(LoopConfig(scenario=SHORT, backend=backend), 0, 2)
    assert np.array_equal(a["x0"], b["x0"]) and np.array_equal(a["x0"], c["x0"])
    assert np.array_equal(a["y"][0], b["y"][0])                 # same plant noise before control acts
    assert not np.array_equal(a["est"][1:], b["est"][1:])       # other random numbers in the filter
    d = run_once(LoopConfig(scenario=SHORT, backend=backend, filter_stream=1), 0, 2)
    assert np.array_equal(a["est"], d["est"])                   # reproducible


def test_max_weight_backends_agree():
    a = run_once(LoopConfig(scenario=SHORT, point="max_weight", backend="numpy"), 3, 1)
    b = run_once(LoopConfig(scenario=SHORT, point="max_weight", backend="numba"), 3, 1)
    assert np.allclose(a["est"], b["est"], rtol=1e-9, atol=1e-9)
