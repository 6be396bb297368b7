"""The simulated chamber (plant) of [Embedded] §3-§5.3."""
import numpy as np
import pytest

from pfbench.plants import chamber


@pytest.fixture(scope="module")
def hc():
    return chamber.heating_cooling(22.5, ambient=19.5, seed=3)


@pytest.fixture(scope="module")
def hn():
    return chamber.heating_normal(seed=3)


def _on_grid(v):
    q = np.asarray(v) / chamber.RESOLUTION
    return np.allclose(q, np.round(q), atol=1e-9)


def test_quantisation(hc, hn):
    for run in (hc, hn):
        assert _on_grid(run.y) and _on_grid(run.t_out)       # DS18B20: multiples of 0.0625 degC
        # quantisation error is at most half a step (+ a few sigma of the analogue noise)
        assert np.max(np.abs(run.y - run.truth)) <= chamber.RESOLUTION / 2 + 5 * chamber.ChamberParams().sensor_noise
    assert chamber.quantise(20.03) == 20.0 and chamber.quantise(20.04) == 20.0625


def test_fan_bound(hc, hn):
    assert chamber.clip_inputs(-5.0, 0.0) == (0.0, 30.0)
    assert chamber.clip_inputs(120.0, 150.0) == (100.0, 100.0)
    assert hc.u2.min() >= 30.0 and hn.u2.min() >= 30.0
    a, b = chamber.Chamber(seed=1), chamber.Chamber(seed=1)
    a.advance(50.0, 0.0, 20.0)
    b.advance(50.0, 30.0, 20.0)       # fan request 0 % runs the fan at 30 %
    np.testing.assert_array_equal(a.state, b.state)


def test_steady_state_gain():
    ch = chamber.Chamber(seed=0, drift_amp=0.0, drift_ou_sigma=0.0)
    g100 = ch.steady_gain(100.0, 30.0)
    assert 3.0 <= g100 <= 5.0                   # issue: heating ~3-5 degC above ambient at 100 %
    assert 0.0 < ch.steady_gain(10.0, 30.0) < ch.steady_gain(90.0, 30.0) < g100
    assert ch.steady_gain(100.0, 100.0) < g100  # ventilation cools
    # the equilibrium really is one of the integrated dynamics
    ch.state = ch.steady_state(100.0, 30.0, ch.p.ambient)
    s0 = ch.state.copy()
    ch.advance(100.0, 30.0, 60.0)
    np.testing.assert_allclose(ch.state, s0, atol=1e-8)


def test_heating_cooling_scenario(hc):
    k = hc.info["k_switch"]
    assert hc.y[k] >= 22.5 and np.all(hc.y[:k] < 22.5)
    assert np.all(hc.mode[:k] == 1) and np.all(hc.mode[k:] == 0)
    assert np.all(hc.u1[k:] == 0) and np.all(hc.u2[k:] == 100)
    assert hc.info["reached_base"] and hc.y[-1] <= chamber.BASE_TEMPERATURE
    np.testing.assert_array_equal(np.diff(hc.time_s), 1.0)


def test_heating_normal_two_position_control(hn):
    assert len(hn.y) == 1200
    np.testing.assert_array_equal(hn.mode, (hn.u1 == 90.0).astype(float))
    assert set(np.unique(hn.u1)) == {10.0, 90.0}
    assert hn.info["mode_switches"] >= 4
    first = np.argmax(hn.y >= 21.5 + 0.26)
    # after the first crossing the measurement stays in the band +- one resolution step of overshoot
    band = hn.y[first:]
    assert band.min() >= 21.5 - 0.26 - 3 * chamber.RESOLUTION and band.max() <= 21.5 + 0.26 + 3 * chamber.RESOLUTION


def test_reproducible():
    a = chamber.heating_normal(seed=5, duration_s=100)
    b = chamber.heating_normal(seed=5, duration_s=100)
    np.testing.assert_array_equal(a.y, b.y)


def test_mixing_bump_is_below_the_sensor_step(hc):
    # the docstring says the §5.2 mixing bump is NOT reproduced at the sensor: it exists in the bulk air,
    # is smaller at the lagged sensor element, and stays below the 0.0625 degC step (catches a retune of
    # the mixing that makes the docstring wrong, or a bump measured at the wrong sample)
    b = chamber.mixing_bump(hc)
    assert 0.0 < b["sensor"] < b["air"] < chamber.RESOLUTION
    k = hc.info["k_switch"]
    assert b["air"] == pytest.approx(np.max(hc.air[k:k + 60]) - hc.air[k])
    assert b["measured"] == pytest.approx(np.max(hc.y[k:k + 60]) - hc.y[k])
