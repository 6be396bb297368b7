"""The thesis SMC ([Thesis] §4.2.1) = the reduced PMSM model + the generic guided filter: point
estimates, backends, tracking, and the numbers recorded before it was built on the generic filter."""
import math

import numpy as np
import pytest

from pfbench.backends.guided_work import Moments, Particles, Settings
from pfbench.models.pmsm import Pmsm, PmsmReduced
from pfbench.plants.pmsm_control.smc import (N_NOISE, guided_init, guided_step, point_estimate,
                                             run_smc, shift_inputs, weights_from_log)


def _data(n_steps=600, seed=4):
    m = Pmsm(open_loop_amplitude=5.0)
    tr = m.simulate(n_steps, seed=seed)
    return m, tr, shift_inputs(tr.u)


def test_step_weights_are_the_predictive_likelihood():
    """One step of the per-step functions (never resampling): the new log-weights are the
    normalised p(y_t | x_{t-1}) of eq. 4.25, the increment is log mean p(y_t | x_{t-1})."""
    p = PmsmReduced().params()
    n = 8
    x = np.column_stack([np.linspace(-5, 5, n), np.linspace(-3, 3, n)])
    lw = np.full(n, -math.log(n))
    ured = np.array([1.0, 2.0, 0.2, -0.1])                     # (u_{t-1}, y_{t-1})
    y = np.array([0.25, -0.02])
    lls = PmsmReduced.predictive_log_likelihood(y, x, ured, 1, p)
    inc, ess, res, deg = guided_step(p, np.random.default_rng(1), Particles(x, lw), y, ured, 1,
                                     Settings(N_NOISE, 4, 0.0), Moments(np.empty(2), np.empty(2)))
    assert np.allclose(lw, lls - np.log(np.sum(np.exp(lls))), atol=1e-12)
    assert inc == pytest.approx(np.log(np.mean(np.exp(lls))), abs=1e-12)
    assert not res and not deg and 1 <= ess <= n


def test_init_is_the_equidistant_prior():
    p = PmsmReduced().params()
    x, lw = np.empty((60, 2)), np.empty(60)
    guided_init(p, np.random.default_rng(0), x, lw)
    assert np.allclose(np.diff(x[:, 1]), 2 * math.pi / 60) and np.allclose(np.exp(lw), 1 / 60)
    wn = np.empty(60)
    weights_from_log(lw, wn)
    assert np.allclose(wn, 1 / 60)


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
def test_backends_agree(point):
    m, tr, u = _data(300)
    a = run_smc(m, tr.y, u, backend="numpy", seed=7, point=point)
    b = run_smc(m, tr.y, u, backend="numba", seed=7, point=point)
    assert a["resampled"].sum() > 0
    assert np.array_equal(a["resampled"], b["resampled"])
    assert np.max(np.abs(a["estimates"] - b["estimates"])) <= 1e-9
    assert np.max(np.abs(a["loglik_increments"] - b["loglik_increments"])) <= 1e-9


@pytest.mark.parametrize("point,prior,last,n_res", [
    ("max", "equidistant", [-0.414251183734599, -2.1970946322615115], 6),
    ("mean", "gaussian", [27.441478349224408, 0.7958023768981037], 7),
    ("sample", "uniform", [5.339201391543787, -2.085262470881619], 4),
])
def test_recorded_numbers(point, prior, last, n_res):
    """Final point estimates and resampling counts of the thesis SMC recorded with the former
    PMSM-only implementation (same seeds, 600 open-loop steps). The generic guided filter changes
    the floating-point order of the weighting (log w + log p in one sum, log(w) - log(sum)), so
    agreement is to round-off, not bit-for-bit; the resampling decisions are identical."""
    m, tr, u = _data(600)
    r = run_smc(m, tr.y, u, backend="numba", seed=7, point=point, theta_prior=prior, theta_mu=0.5,
                theta_sd=0.7)
    assert r["estimates"][-1] == pytest.approx(last, rel=1e-9, abs=1e-9)
    assert int(r["resampled"].sum()) == n_res


def test_filter_tracks_open_loop_rotation():
    m = Pmsm(open_loop_amplitude=5.0)
    tr = m.simulate(1600, seed=1)
    r = run_smc(m, tr.y, shift_inputs(tr.u), seed=3)
    err_th = np.angle(np.exp(1j * (r["estimates"][-200:, 1] - tr.x[-200:, 3])))
    assert np.abs(err_th).mean() < 0.3
    assert np.abs(r["estimates"][-200:, 0] - tr.x[-200:, 2]).mean() < 2.0
