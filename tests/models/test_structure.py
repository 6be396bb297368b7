"""A declared linear-Gaussian structure ([Schon2005] eq. 3) must be the model that ``transition``
and ``observe`` describe: methods mpf and kalman filter with the ``cl_*`` functions, simulate() and
the particle methods with the two full-state ones, so a mistake in either made the MPF filter
another model than the one that made the data (and read as an MPF bug in a comparison)."""
import numpy as np
import pytest

import pfbench
from pfbench.errors import ModelError
from pfbench.models import StateSpaceModel, get, names
from pfbench.models.base import gaussian_loglik_diag
from pfbench.models.catalog import supported
from pfbench.filters.marginalized import check_agreement
from pfbench.models.contract import linear_indices, name_of
from pfbench.models.linear_gaussian import LinearGaussian


class UserMixed(StateSpaceModel):
    """A user's model with x^l = state 0 before x^n = state 1, f^l and C that depend on x^n::

        x0' = 0.5 sin(x1) + 0.9 x0 + w0,   x1' = atan(x1) + x0 + w1,   y = (x1^2 / 5, cos(x1) x0) + e
    """

    name = "user_mixed"
    n_x, n_y, n_noise = 2, 2, 2
    linear_states = (0,)

    def params(self):
        return (np.full(2, 0.2),)

    @staticmethod
    def initial(rng, n, p):
        return rng.standard_normal((n, 2))

    @staticmethod
    def transition(x, u, t, noise, p):
        return np.stack((0.5 * np.sin(x[:, 1]) + 0.9 * x[:, 0], np.arctan(x[:, 1]) + x[:, 0]), axis=1) \
            + np.sqrt(0.5) * noise

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        return gaussian_loglik_diag(y - np.stack((x[:, 1] ** 2 / 5, np.cos(x[:, 1]) * x[:, 0]), axis=1), p[0])

    @staticmethod
    def observe(x, u, t, noise, p):
        return np.stack((x[:, 1] ** 2 / 5, np.cos(x[:, 1]) * x[:, 0]), axis=1) + np.sqrt(p[0]) * noise

    @staticmethod
    def cl_transition(xn, u, t, p):
        n = xn.shape[0]
        return np.arctan(xn), np.ones((n, 1, 1)), 0.5 * np.sin(xn), np.full((n, 1, 1), 0.9)

    @staticmethod
    def cl_observation(xn, xl, u, t, p):
        C = np.zeros((xn.shape[0], 2, 1))
        C[:, 1, 0] = np.cos(xn[:, 0])
        return np.stack((xn[:, 0] ** 2 / 5, np.cos(xn[:, 0]) * xl[:, 0]), axis=1), C

    def cl_noise(self):
        return 0.5 * np.eye(2), 0.2 * np.eye(2)

    def cl_prior(self):
        return np.zeros(1), np.eye(1)


class WrongSignFl(UserMixed):
    name = "wrong_sign_fl"

    @staticmethod
    def cl_transition(xn, u, t, p):
        fn, An, fl, Al = UserMixed.cl_transition(xn, u, t, p)
        return fn, An, -fl, Al


class ForgotCos(UserMixed):
    name = "forgot_cos"

    @staticmethod
    def cl_observation(xn, xl, u, t, p):
        h, C = UserMixed.cl_observation(xn, xl, u, t, p)
        h[:, 1] = xl[:, 0]
        return h, C


class ZeroStartWrongAl(UserMixed):
    """Starts at exactly 0, where f^l = 0.5 sin(0) and A^l x^l vanish whatever A^l is."""
    name = "zero_start_wrong_al"

    @staticmethod
    def initial(rng, n, p):
        return np.zeros((n, 2))

    @staticmethod
    def cl_transition(xn, u, t, p):
        fn, An, fl, Al = UserMixed.cl_transition(xn, u, t, p)
        return fn, An, fl, -Al


class WritesItsInput(UserMixed):
    """UserMixed whose transition and observe overwrite their input after use (allowed: the
    particle methods hand them copies)."""
    name = "writes_its_input"

    @staticmethod
    def transition(x, u, t, noise, p):
        out = UserMixed.transition(x, u, t, noise, p)
        x[:] = 0.0
        return out

    @staticmethod
    def observe(x, u, t, noise, p):
        out = UserMixed.observe(x, u, t, noise, p)
        x[:] = 0.0
        return out


class NoInitial(UserMixed):
    name = "no_initial"

    @staticmethod
    def initial(rng, n, p):
        return None


class FlippedAl(LinearGaussian):
    name = "flipped_al"

    @staticmethod
    def cl_transition(xn, u, t, p):
        fn, An, fl, Al = LinearGaussian.cl_transition(xn, u, t, p)
        return fn, An, fl, -Al


_LINEAR = dict(A=[[0.8, 0.5, 0.0], [0.2, 0.9, 0.1], [0.0, -0.2, 0.7]], C=[[1.0, 0.0, 0.0], [0.5, 1.0, 1.0]],
               Q=np.eye(3), R=np.eye(2), B=[[1.0], [0.5], [0.0]], D=[[0.2], [0.0]])


def _structured():
    """Every registered model that declares a structure, at its defaults, and variants of its own."""
    models = [get(nm) for nm in names()]
    models = [m for m in models if supported(m)["mpf"]]
    models += [get("ob3", version=v) for v in range(2, 6)] + [get("ob3", version=3, pairs="all")]
    models += [get("linear_gaussian", **_LINEAR, linear_states=ls) for ls in (None, (1, 2), (2, 0))]
    return models


def _check_at(model, states, u):
    """The agreement check of method mpf at the states ``states`` (3, n_x)."""
    idx_l = linear_indices(model)
    idx_n = np.setdiff1d(np.arange(model.n_x), idx_l)
    check_agreement(model, states.astype(np.float64), u[0], model.params(), idx_n, idx_l, "mpf")


@pytest.mark.parametrize("model", _structured(), ids=lambda m: name_of(m))
def test_every_built_in_structure_agrees_with_its_model(model):
    """mpf runs every built-in structured model, and the check passes at states of a simulated run
    too.
    Catches: a false refusal from a tolerance below rounding, or x^n/x^l split unlike the MPF."""
    assert supported(model)["mpf"]
    tr = model.simulate(10, seed=1)
    u = model.input_array(tr.u, 10)
    pfbench.run_filter(model, tr.y, tr.u, method="mpf", n_particles=10, backend="numpy")
    for t in range(1, 10, 3):
        _check_at(model, tr.x[t - 1:t + 2], u[t:t + 1])


def test_ob5_at_its_constraints_passes():
    """Ob5's transition clips x1, x3, x4 after the Euler step, as the MPF applies cl_constrain to
    its draw of x^n, so with zero noise the structure's x^n is cl_constrain(f^n + A^n x^l): here the
    ball sits at the upper magnet moving up (f^n + A^n x^l gives x1 = -1e-6) and a coil at I_MAX.
    Catches: cl_constrain left out of the comparison (ob5 at its bounds refused)."""
    states = np.array([[0.0, -0.01, 0.9, 0.5], [0.009, 0.0, 2.38, 0.5], [0.02, 0.001, 0.5, 0.03884]])
    _check_at(get("ob5"), states, np.array([[1.0, 0.2]]))


@pytest.mark.parametrize("model, method, state", [
    (WrongSignFl(), "mpf", r"state 0 \(x\^l\[0\]\)"),
    (ZeroStartWrongAl(), "mpf", r"state 0 \(x\^l\[0\]\)"),
    (FlippedAl(**_LINEAR, linear_states=(2, 0)), "mpf", r"state 0 \(x\^l\[1\]\)"),
    (FlippedAl(**_LINEAR), "kalman", r"state 0 \(x\^l\[0\]\)"),
], ids=["user-f^l", "user-A^l-zero-start", "linear-A^l-mpf", "linear-A^l-kalman"])
def test_a_transition_structure_of_another_model_is_refused(model, method, state):
    """A wrong sign in f^l (a user's model), in A^l of a model that starts at 0, or in A^l
    (linear_gaussian's, for both structured methods) is a one-line ModelError naming cl_transition,
    the state and both values. Catches: the check dropped, not run for kalman, run on the initial
    states only (where the zero start hides A^l), or a state named by its x^l column, not its index."""
    tr = model.simulate(5, seed=0)
    kw = {} if method == "kalman" else {"n_particles": 10}
    with pytest.raises(ModelError, match=rf"^model {model.name!r}: transition\(\) and cl_transition\(\) disagree: "
                       rf"with zero noise {state} is \S+ by transition, \S+ by cl_transition \(f\^l \+ A\^l x\^l\); "
                       rf"method {method!r} would filter another model$"):
        pfbench.run_filter(model, tr.y, tr.u, method=method, backend="numpy", **kw)


def test_an_observation_structure_of_another_model_is_refused():
    """cl_observation's h without observe's cos(x1) factor is refused naming cl_observation and the
    output; UserMixed itself runs (h taken at the particles' own x^l equals observe's).
    Catches: the observation half of the check dropped, or h compared at another x^l."""
    tr = UserMixed().simulate(5, seed=0)
    pfbench.run_filter(UserMixed(), tr.y, method="mpf", n_particles=10, backend="numpy")
    with pytest.raises(ModelError, match=r"^model 'forgot_cos': observe\(\) and cl_observation\(\) disagree: with "
                       r"zero noise output 1 is \S+ by observe, \S+ by cl_observation \(h at the particle's own "
                       r"x\^l\); method 'mpf' would filter another model$"):
        pfbench.run_filter(ForgotCos(), tr.y, method="mpf", n_particles=10, backend="numpy")


@pytest.mark.parametrize("model", [WrongSignFl(), ForgotCos()], ids=name_of)
def test_the_particle_methods_and_simulate_ignore_the_structure(model):
    """The bootstrap filter and simulate() use transition and observe only, so an inconsistent
    structure does not stop them.
    Catches: the check run for every method (or in simulate()) instead of for mpf and kalman only."""
    tr = model.simulate(5, seed=0)
    res = pfbench.run_filter(model, tr.y, method="bootstrap", n_particles=20, backend="numpy")
    assert res.estimates.shape == (5, 2)


def test_a_model_that_writes_its_input_agrees_and_a_missing_initial_is_named():
    """A transition and observe that overwrite their input still agree with the structure (the
    check hands each its own copy); an initial() returning None is the one-line shape error.
    Catches the probe shared between calls, or a None indexed into (a TypeError traceback)."""
    tr = UserMixed().simulate(5, seed=0)
    pfbench.run_filter(WritesItsInput(), tr.y, method="mpf", n_particles=10, backend="numpy")
    with pytest.raises(ModelError, match=r"^model 'no_initial': initial\(\) must return"):
        pfbench.run_filter(NoInitial(), tr.y, method="mpf", n_particles=10, backend="numpy")
