"""thermal_inertial / thermal_rate / thermal_outdoor ([Embedded] eqs. 7-12)."""
import numpy as np
import pytest

import pfbench
from pfbench import models
from pfbench.models.thermal import K_H, T_H1, T_H2, T_C1, T_C2, cooling_gain

NAMES = ("thermal_inertial", "thermal_rate", "thermal_outdoor")


@pytest.mark.parametrize("name", NAMES)
def test_backends_agree_under_common_random_numbers(name):
    m = models.get(name)
    tr = m.simulate(120, seed=4)
    res = [pfbench.run_filter(m, tr.y, tr.u, method="bootstrap", n_particles=64, backend=b, seed=9,
                              common_random_numbers=True) for b in ("numpy", "numba")]
    # same random numbers, same operations: equal up to floating-point reassociation
    np.testing.assert_allclose(res[0].estimates, res[1].estimates, rtol=0, atol=1e-9)
    assert np.isfinite(res[0].loglik)


def _step(m, x, u):
    return m.transition(np.array([x], dtype=float), np.asarray(u, dtype=float), 0, np.zeros((1, 2)), m.params())[0]


def test_mode_switches_parameter_set():
    m = models.get("thermal_inertial", y0=19.5)
    # from rest at the operating point, one Euler step (eq. 10): x2 = T_s K u / (T1 T2)
    heat = _step(m, [19.5, 0.0], [100.0, 30.0, 1.0])
    cool = _step(m, [19.5, 0.0], [100.0, 30.0, 0.0])
    assert heat[1] == pytest.approx(K_H * 100.0 / (T_H1 * T_H2), rel=1e-12)   # heating: K_h, u1
    assert cool[1] == pytest.approx(cooling_gain(19.5) * 30.0 / (T_C1 * T_C2), rel=1e-12)  # cooling: K_c, u2
    assert heat[0] == cool[0] == 19.5


def test_cooling_gain_formula_and_units():
    assert cooling_gain(19.5) == pytest.approx(0.2069 - 0.195)
    m = models.get("thermal_inertial", y0=20.0)
    assert m.kc == pytest.approx(0.2069 - 0.2) and m.op == 20.0


@pytest.mark.parametrize("mode,u,gain", [(1.0, (100.0, 30.0), K_H * 100.0),
                                         (0.0, (0.0, 100.0), cooling_gain(19.5) * 100.0)])
def test_noise_free_steady_state_is_op_plus_k_u(mode, u, gain):
    # documented reading: u in %, output = op + K u at steady state (heating: 5.26 degC at 100 %)
    m = models.get("thermal_inertial", y0=19.5)
    x = np.array([19.5, 0.0])
    for _ in range(20000):
        x = _step(m, x, [u[0], u[1], mode])
    assert x[0] == pytest.approx(19.5 + gain, abs=1e-6)


def test_u_scale_reads_fractions():
    # fractional inputs with u_scale=100 give the same model as percent inputs
    frac = _step(models.get("thermal_inertial", y0=19.5, u_scale=100.0), [19.5, 0.0], [1.0, 0.3, 1.0])
    pct = _step(models.get("thermal_inertial", y0=19.5), [19.5, 0.0], [100.0, 30.0, 1.0])
    np.testing.assert_allclose(frac, pct, rtol=1e-12)
    # the alternative reading (K per unit fraction) would be 100x weaker
    alt = _step(models.get("thermal_inertial", y0=19.5, u_scale=0.01), [19.5, 0.0], [100.0, 30.0, 1.0])
    assert alt[1] == pytest.approx(K_H * 1.0 / (T_H1 * T_H2), rel=1e-12)


def test_rate_model_extrapolates_linearly():
    m = models.get("thermal_rate")
    x = m.transition(np.array([[20.1, 20.0]]), np.zeros(0), 0, np.zeros((1, 2)), m.params())
    np.testing.assert_allclose(x, [[20.2, 20.1]], atol=1e-12)      # eq. 11: 2 x1 - x2
    assert m.var_v1 == 1e-6 and m.var_v2 == 0.0 and m.var_n == 0.0225


def test_pf_initialised_from_first_measurement():
    m = models.get("thermal_inertial", y0=21.0, var_n=0.005)
    x0 = m.initial(np.random.default_rng(0), 20000, m.params())
    assert abs(x0[:, 0].mean() - 21.0) < 5 * np.sqrt(0.005 / 20000)
    assert np.all(x0[:, 1] == 0.0)


def test_bad_parameters_raise():
    with pytest.raises(ValueError):
        models.get("thermal_inertial", var_n=0.0)
