"""SMC with the optimal proposal for the PMSM ([Thesis] eqs. 4.22-4.25)."""
import math

import numpy as np
import pytest

from pfbench.filters.optimal_proposal import (filter_params, optimal_proposal_moments,
                                              point_estimate, run_optimal_proposal,
                                              shift_inputs, smc_init, smc_step, step_time_us)
from pfbench.models.pmsm import Pmsm, pmsm_step


def test_optimal_proposal_matches_brute_force_importance_sampling():
    """Draw x_t from the transition prior, weight by p(y_t | x_t): the weighted mean/variance
    must match m_t, S (eqs. 4.23-4.24) and the mean weight p(y_t | x_{t-1}) (eq. 4.25)."""
    m = Pmsm()
    mp = m.param_array()
    x_prev = np.array([0.4, -0.3, 6.0, 0.8])
    u = np.array([3.0, 1.0])
    g = np.empty(4)
    pmsm_step(x_prev, u, mp, g)
    y = g[:2] + np.array([0.03, -0.02])
    mom, S, ll = optimal_proposal_moments(x_prev, u, y, mp, m.q, m.r)
    rng = np.random.default_rng(0)
    K = 400_000
    xs = g + rng.standard_normal((K, 4)) * np.sqrt(m.q)
    lik = np.exp(m.log_likelihood(y, xs, u, 0, m.params()))
    pred = lik.mean()
    se = lik.std() / math.sqrt(K)
    assert abs(pred - math.exp(ll)) < 5 * se
    w = lik / lik.sum()
    mean = w @ xs
    ess = 1 / np.sum(w * w)
    for k in range(4):
        sd = math.sqrt(S[k, k])
        assert abs(mean[k] - mom[k]) < 5 * sd / math.sqrt(ess)
    var_is = w @ (xs[:, 0] - mean[0]) ** 2
    assert var_is == pytest.approx(S[0, 0], rel=0.02)
    # (omega, theta) block of the proposal is the prior block (H has no columns there)
    assert mom[2:] == pytest.approx(g[2:]) and np.allclose(np.diag(S)[2:], m.q[2:])


def test_smc_step_weights_are_the_predictive_likelihood():
    m = Pmsm()
    mp = m.param_array()
    fp = filter_params(m, ess_threshold=0.0)       # never resample
    n = 8
    rng = np.random.default_rng(1)
    om = np.linspace(-5, 5, n)
    th = np.linspace(-3, 3, n)
    lw = np.full(n, -math.log(n))
    y_prev, u = np.array([0.2, -0.1]), np.array([1.0, 2.0])
    y = np.array([0.25, -0.02])
    om0, th0 = om.copy(), th.copy()
    inc, res, ess = smc_step(rng, om, th, lw, np.empty(n), y_prev, y, u, mp, fp)
    lls = np.array([optimal_proposal_moments([y_prev[0], y_prev[1], om0[i], th0[i]], u, y, mp,
                                             m.q, m.r)[2] for i in range(n)])
    ref = lls - np.log(np.sum(np.exp(lls)))
    assert np.allclose(lw, ref, atol=1e-12)
    assert inc == pytest.approx(np.log(np.mean(np.exp(lls))), abs=1e-12)
    assert not res and 1 <= ess <= n


def test_equidistant_initial_particles():
    m = Pmsm()
    n = 60
    om, th, lw = np.empty(n), np.empty(n), np.empty(n)
    smc_init(np.random.default_rng(0), om, th, lw, filter_params(m))
    assert np.allclose(np.diff(th), 2 * math.pi / n)
    assert th[0] == pytest.approx(-math.pi + math.pi / n)
    assert np.all(np.abs(om) <= 0.01) and np.allclose(np.exp(lw), 1 / n)


def test_point_estimates_on_a_wrapped_cluster():
    # four particles near +-pi (one cluster across the wrap) and one heavier particle at 0
    om = np.array([1.0, 1.1, 0.9, 1.05, -3.0])
    th = np.array([3.10, -3.10, 3.12, -3.12, 0.0])
    wn = np.array([0.18, 0.18, 0.18, 0.18, 0.28])
    out = np.empty(5)
    point_estimate(om, th, wn, 2, None, out)
    assert abs(abs(out[1]) - math.pi) < 0.05 and out[0] > 0.8      # maximum: the cluster
    point_estimate(om, th, wn, 0, None, out)
    assert abs(abs(out[1]) - math.pi) < 1e-9                          # circular mean at pi
    assert out[0] == pytest.approx(wn @ om)
    rng = np.random.default_rng(5)
    picks = []
    for _ in range(2000):
        point_estimate(om, th, wn, 1, rng, out)
        picks.append(out[1] == 0.0)
    assert abs(np.mean(picks) - 0.28) < 4 * math.sqrt(0.28 * 0.72 / 2000)


@pytest.mark.parametrize("point", ["mean", "sample", "max"])
def test_backends_identical(point):
    m = Pmsm(open_loop_amplitude=5.0)
    tr = m.simulate(300, seed=4)
    u = shift_inputs(tr.u)
    a = run_optimal_proposal(m, tr.y, u, backend="numpy", seed=7, point=point)
    b = run_optimal_proposal(m, tr.y, u, backend="numba", seed=7, point=point)
    assert a["resampled"].sum() > 0
    assert np.array_equal(a["estimates"], b["estimates"])
    assert np.array_equal(a["resampled"], b["resampled"])


def test_filter_tracks_open_loop_rotation():
    m = Pmsm(open_loop_amplitude=5.0)
    tr = m.simulate(1600, seed=1)
    r = run_optimal_proposal(m, tr.y, shift_inputs(tr.u), seed=3)
    err_th = np.angle(np.exp(1j * (r["estimates"][-200:, 1] - tr.x[-200:, 3])))
    assert np.abs(err_th).mean() < 0.3
    assert np.abs(r["estimates"][-200:, 0] - tr.x[-200:, 2]).mean() < 2.0


def test_step_fits_the_sampling_period():
    assert step_time_us(n_particles=60, n_steps=2000, point="max", repeats=2) < 125.0
