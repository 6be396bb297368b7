"""Registry and the [MultiPDF] objects Ob1-Ob4 + the linear-Gaussian reference."""
import re

import numpy as np
import pytest

from pfbench import models
from pfbench.errors import PfbenchError


def test_registry_has_core_models():
    for name in ("ob1", "ob2", "ob3", "ob4", "linear_gaussian"):
        assert name in models.names()
    with pytest.raises(PfbenchError, match="unknown model"):
        models.get("nope")
    with pytest.raises(PfbenchError, match="not a parameter of model"):
        models.get("ob1", nonsense=1)


@pytest.mark.parametrize("name,kw,shape", [
    ("ob1", {}, (1, 1, None)), ("ob2", {}, (5, 15, None)), ("ob3", {"version": 2}, (4, 14, None)),
    ("ob3", {"version": 2, "pairs": "all"}, (4, 16, None)), ("ob4", {}, (2, 2, 1)),
])
def test_simulate_shapes(name, kw, shape):
    m = models.get(name, **kw)
    tr = m.simulate(25, seed=0)
    n_x, n_y, n_u = shape
    assert tr.x.shape == (25, n_x) and tr.y.shape == (25, n_y)
    assert (tr.u is None) if n_u is None else tr.u.shape == (25, n_u)
    assert np.all(np.isfinite(tr.y))
    # reproducible
    assert np.array_equal(tr.y, m.simulate(25, seed=0).y)


def test_ob1_noise_free_step_matches_equation():
    m = models.get("ob1")
    p = m.params()
    x = np.array([[0.1], [2.0]])
    out = m.transition(x, np.zeros(0), 3, np.zeros((2, 1)), p)
    expect = 0.5 * x + 25 * x / (1 + x ** 2) + 8 * np.cos(1.2 * 3)
    assert np.allclose(out, expect)


def test_ob1_process_noise_variance_is_10():
    m = models.get("ob1")
    x = np.zeros((200_000, 1))
    out = m.transition(x, np.zeros(0), 0, np.random.default_rng(0).standard_normal((200_000, 1)), m.params())
    assert np.var(out - 8.0) == pytest.approx(10.0, rel=0.02)


def test_ob3_v1_outputs():
    m = models.get("ob3", version=1)
    x = np.array([[1.0, 2.0, 3.0, 4.0]])
    y = m.observe(x, np.zeros(0), 0, np.zeros((1, m.n_y)), m.params())[0]
    assert np.allclose(y[:4], [1, 2, 3, 4])
    pairs = list(zip(m.pi, m.pj))
    assert (0, 3) not in pairs and (3, 0) not in pairs and len(pairs) == 10
    assert np.allclose(y[4:], [x[0, i] - x[0, j] for i, j in pairs])


def test_ob4_uses_its_input():
    m = models.get("ob4")
    x = np.array([[0.1, 0.1]])
    a = m.transition(x, np.array([1.0]), 0, np.zeros((1, 2)), m.params())
    b = m.transition(x, np.array([-1.0]), 0, np.zeros((1, 2)), m.params())
    assert np.allclose(a - b, 0.4)


def test_linear_gaussian_loglik_matches_scipy():
    from scipy.stats import multivariate_normal

    m = models.get("linear_gaussian", A=np.eye(2), C=[[1.0, 2.0], [0.0, 1.0]], Q=np.eye(2),
                   R=[[2.0, 0.3], [0.3, 1.0]])
    x = np.random.default_rng(0).normal(size=(5, 2))
    y = np.array([0.5, -1.0])
    ll = m.log_likelihood(y, x, np.zeros(0), 0, m.params())
    ref = [multivariate_normal(mean=m.C @ xi, cov=m.R).logpdf(y) for xi in x]
    assert np.allclose(ll, ref)


@pytest.mark.parametrize("args, says", [((2.7,), "n_steps must be an integer >= 1, got 2.7"),   # ran 2 steps
                                        ((True,), "n_steps must be an integer >= 1, got True"),
                                        ((5, -1), "seed must be a non-negative integer")])      # NumPy's raw error
def test_simulate_refuses_what_it_would_misread(args, says):
    from pfbench.errors import InputError

    with pytest.raises(InputError, match=re.escape(says)):
        models.get("ob1").simulate(*args)
