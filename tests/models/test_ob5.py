"""Ob5 (MLS2EM) model: constraints, equilibrium, Euler stability, backends."""
import numpy as np
import pytest

from pfbench.models import get
from pfbench.models.ob5 import (FEMP1, FEMP2, FIP1, FIP2, G, I_MAX, I_MIN, M_BALL, TS, U_MIN,
                                equilibrium_current, ob5_coil_factor, ob5_fem)


def test_equilibrium_by_hand():
    # F_em1 = m g at x1 = 9 mm: i^2 = m g FemP2 / FemP1 * exp(x1 / FemP2)
    # = 0.0571 * 9.81 * 5.8231e-3 / 1.7521e-2 * exp(0.009 / 5.8231e-3) = 0.8733 -> i = 0.9345 A
    i = equilibrium_current(0.009)
    assert i == pytest.approx(0.9345, abs=5e-4)
    assert float(ob5_fem(np.array([i]), np.array([0.009]))[0]) == pytest.approx(M_BALL * G, rel=1e-12)
    # the model's equilibrium also balances the small lower-magnet pull (u2 bias): a bit higher
    m = get("ob5")
    fem2 = float(ob5_fem(np.array([m.x_eq[3]]), np.array([m.xd - 0.009]))[0])
    assert fem2 / (M_BALL * G) < 0.02                  # ~1.2 %: current up by ~0.6 %
    assert m.x_eq[2] == pytest.approx(i * np.sqrt(1 + fem2 / (M_BALL * G)), rel=1e-12)
    # zero noise, zero velocity, currents at their targets -> acceleration ~ 0 at x_eq
    x = m.x_eq.reshape(1, 4)
    u = np.array([(m.x_eq[2] - 0.0243) / 2.5165, m.u2])
    nxt = m.transition(x, u, 0, np.zeros((1, 4)), m.params())
    assert abs(nxt[0, 1]) < 1e-9          # velocity change = Ts * (g - Fem1/m + Fem2/m)
    assert abs(nxt[0, 2] - x[0, 2]) < 1e-12


def test_simulation_respects_constraints():
    m = get("ob5")
    tr = m.simulate(3000, seed=11)
    assert np.isfinite(tr.x).all() and np.isfinite(tr.y).all()
    assert (tr.x[:, 0] >= 0).all() and (tr.x[:, 0] <= m.xd).all()
    assert (tr.x[:, 2:] >= I_MIN).all() and (tr.x[:, 2:] <= I_MAX).all()
    assert (tr.u >= U_MIN).all() and (tr.u <= 1.0).all()
    # the stabilising controller keeps the ball near the 9 mm reference (open loop diverges)
    assert np.abs(tr.x[:, 0] - 0.009).max() < 2e-3


def test_euler_factor_is_stable_everywhere():
    z = np.linspace(0.0, 0.037, 1001)
    a = ob5_coil_factor(z, TS)
    assert (a > 0).all() and (a <= 1.0).all()          # |1 - a| < 1: stable, monotone
    fi = FIP1 / FIP2 * np.exp(-z / FIP2)
    raw = TS / fi
    np.testing.assert_array_equal(a[raw < 1], raw[raw < 1])  # plain Euler where monotone
    assert raw.max() > 2                                # plain Euler alone would be unstable
    assert (TS / (FIP1 / FIP2 * np.exp(-0.016 / FIP2))) < 0.12  # upper coil, x1 <= 16 mm


def test_ob5_backends_agree():
    import pfbench

    m = get("ob5")
    tr = m.simulate(40, seed=2)
    a = pfbench.run_filter(m, tr.y, tr.u, method="multipdf", n_particles=60, n_filters=3,
                           backend="numpy", seed=5)
    b = pfbench.run_filter(m, tr.y, tr.u, method="multipdf", n_particles=60, n_filters=3,
                           backend="numba", seed=5)
    np.testing.assert_allclose(a.estimates, b.estimates, rtol=1e-12, atol=1e-14)
    assert FEMP1 > 0 and FEMP2 > 0
