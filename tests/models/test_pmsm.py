"""PMSM model ([Thesis] eqs. 4.11-4.21, Jacobian eq. 4.26)."""
import math

import numpy as np
import pytest

import pfbench
from pfbench.models import get
from pfbench.models.pmsm import Pmsm, jacobian, pmsm_step, wrap_angle, wrap_angles


def _noise_free(model):
    return Pmsm(q=(0, 0, 0, 0), r=model.r)


def test_registered_and_parameters():
    m = get("pmsm")
    assert isinstance(m, Pmsm)
    mp = m.param_array()
    assert mp[:6].tolist() == [0.9898, 0.0072, 0.0361, 1.0, 0.0149, 125e-6]
    assert m.u_max == 10.0
    assert m.inductance == pytest.approx(125e-6 / 0.0361)
    assert m.flux == pytest.approx(0.0072 / 0.0361)


def test_zero_input_zero_noise_keeps_currents_at_zero():
    m = _noise_free(Pmsm())
    p = m.params()
    x = np.array([[0.0, 0.0, 0.0, 0.7]])
    u = np.zeros(2)
    for t in range(200):
        x = m.transition(x, u, t, np.zeros((1, 4)), p)
    assert np.all(x[0, :3] == 0.0) and x[0, 3] == 0.7


def test_theta_advances_by_omega_dt():
    m = _noise_free(Pmsm())
    p = m.params()
    x = np.array([[0.0, 0.0, 5.0, 3.1]])
    x1 = m.transition(x, np.zeros(2), 0, np.zeros((1, 4)), p)
    assert x1[0, 3] == pytest.approx(3.1 + 5.0 * 125e-6, abs=1e-15)
    # crossing pi wraps to (-pi, pi]
    x = np.array([[0.0, 0.0, 100.0, math.pi - 1e-3]])
    x1 = m.transition(x, np.zeros(2), 0, np.zeros((1, 4)), p)
    assert x1[0, 3] == pytest.approx(-math.pi - 1e-3 + 100 * 125e-6, abs=1e-12)


def test_wrap():
    th = np.array([math.pi, -math.pi, 3 * math.pi, 0.0, -3.5, 7.0])
    w = wrap_angles(th)
    assert np.all(w > -math.pi) and np.all(w <= math.pi)
    assert np.allclose(np.exp(1j * w), np.exp(1j * th))
    assert wrap_angle(-math.pi) == pytest.approx(math.pi)


def test_transition_matches_scalar_step_and_equations():
    m = Pmsm()
    mp = m.param_array()
    x = np.array([0.3, -0.2, 4.0, 1.1])
    u = np.array([2.0, -1.0])
    out = np.empty(4)
    pmsm_step(x, u, mp, out)
    a, b, c, d, e, dt = mp[:6]
    s, co = math.sin(1.1), math.cos(1.1)
    assert out[0] == pytest.approx(a * 0.3 + b * 4 * s + c * 2)
    assert out[1] == pytest.approx(a * -0.2 - b * 4 * co + c * -1)
    assert out[2] == pytest.approx(d * 4 + e * (-0.2 * co - 0.3 * s))
    vec = m.transition(x[None], u, 0, np.zeros((1, 4)), m.params())[0]
    assert np.allclose(vec, out)


def test_jacobian_matches_finite_differences():
    mp = Pmsm().param_array()
    rng = np.random.default_rng(3)
    for _ in range(5):
        x = rng.normal(size=4) * np.array([2, 2, 10, 1])
        J = jacobian(x, mp)
        h = 1e-6
        num = np.empty((4, 4))
        for k in range(4):
            xp, xm = x.copy(), x.copy()
            xp[k] += h
            xm[k] -= h
            fp, fm = np.empty(4), np.empty(4)
            pmsm_step(xp, np.zeros(2), mp, fp)
            pmsm_step(xm, np.zeros(2), mp, fm)
            num[:, k] = (fp - fm) / (2 * h)
        assert np.allclose(J, num, rtol=1e-7, atol=1e-9)


def test_log_likelihood_is_gaussian_density():
    m = Pmsm()
    x = np.array([[0.1, 0.2, 0, 0], [0.0, 0.0, 0, 0]])
    y = np.array([0.12, 0.15])
    ll = m.log_likelihood(y, x, np.zeros(2), 0, m.params())
    r = m.r
    ref = [np.sum(-0.5 * (y - xi[:2]) ** 2 / r - 0.5 * np.log(2 * np.pi * r)) for xi in x]
    assert np.allclose(ll, ref)


def test_prior_and_simulate():
    m = Pmsm()
    x = m.initial(np.random.default_rng(0), 5000, m.params())
    assert np.all(np.abs(x[:, :3]) <= 0.01) and np.all(np.abs(x[:, 3]) <= math.pi)
    assert abs(x[:, 3].mean()) < 4 * math.pi / math.sqrt(3 * 5000)
    tr = m.simulate(50, seed=1)
    assert tr.x.shape == (50, 4) and tr.y.shape == (50, 2) and tr.u.shape == (50, 2)


def test_generic_engine_both_backends_agree():
    m = Pmsm()
    tr = m.simulate(40, seed=2)
    a = pfbench.run_filter(m, tr.y, tr.u, method="sir", n_particles=64, backend="numpy", seed=1,
                           common_random_numbers=True)
    b = pfbench.run_filter(m, tr.y, tr.u, method="sir", n_particles=64, backend="numba", seed=1,
                           common_random_numbers=True)
    assert np.allclose(a.estimates, b.estimates, rtol=1e-9, atol=1e-9)
