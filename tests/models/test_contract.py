"""The model contract checked once before a run: a mistake in a user's model is one line naming
the model and the function, the same on both backends."""
import re

import numpy as np
import pytest
from click.testing import CliRunner

import pfbench
from pfbench.cli import main
from pfbench.errors import InputError
from pfbench.models.base import StateSpaceModel


class Good(StateSpaceModel):
    name = "good"
    n_x, n_y, n_noise = 1, 1, 1

    def params(self):
        return (1.0,)

    @staticmethod
    def initial(rng, n, p):
        return rng.standard_normal((n, 1))

    @staticmethod
    def transition(x, u, t, noise, p):
        return 0.9 * x + noise

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        return -0.5 * (y[0] - x[:, 0]) ** 2

    @staticmethod
    def observe(x, u, t, noise, p):
        return x + noise


class WideTransition(Good):
    name = "wide"

    @staticmethod
    def transition(x, u, t, noise, p):
        return x[:, :1] + noise[:, 0]          # broadcasts to (n, n): numba ran it silently


class ColumnLoglik(Good):
    name = "column"

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        return -0.5 * (y[0] - x[:, :1]) ** 2   # (n, 1): passed on NumPy, failed on numba


class Raises(Good):
    name = "raises"

    @staticmethod
    def transition(x, u, t, noise, p):
        raise ZeroDivisionError("boom in the user's code")


class NoStatic(Good):
    name = "nostatic"

    def transition(x, u, t, noise, p):          # forgot @staticmethod
        return x + noise


class NumbaCannot(Good):
    name = "numbacannot"

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        out = []                                  # a list of floats appended in a loop: fine in Python,
        for v in x[:, 0]:                         # but a reflected list of an object numba cannot type
            out.append(object())
        return -0.5 * (y[0] - x[:, 0]) ** 2


Y = np.zeros((5, 1))


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize("model, needle", [
    (WideTransition(), "transition() must return a float array of shape (3, 1), got shape (3, 3)"),
    (ColumnLoglik(), "log_likelihood() must return a float array of shape (3,), got shape (3, 1)"),
    (Raises(), "transition() raised ZeroDivisionError: boom in the user's code"),
    (NoStatic(), "transition must be a @staticmethod"),
])
def test_contract_mistakes_are_one_line_on_both_backends(model, needle, backend):
    """Catches the check skipped on one backend, or a message that does not name the function."""
    with pytest.raises(InputError) as err:
        pfbench.run_filter(model, Y, n_particles=10, backend=backend)
    assert needle in str(err.value) and f"model {model.name!r}" in str(err.value)
    assert "\n" not in str(err.value)


def test_a_good_model_passes_and_simulate_checks_too():
    res = pfbench.run_filter(Good(), Y, n_particles=10, backend="numpy")
    assert res.estimates.shape == (5, 1)
    with pytest.raises(InputError, match="transition must be a @staticmethod"):
        NoStatic().simulate(3)


def test_code_numba_cannot_compile_is_named():
    """The numba kernel fails to type the model; the error names log_likelihood (compiled alone to
    find it), not a pfbench internal error. NumPy runs the same model."""
    model = NumbaCannot()
    pfbench.run_filter(model, Y, n_particles=10, backend="numpy")
    with pytest.raises(InputError) as err:
        pfbench.run_filter(model, Y, n_particles=10, backend="numba")
    assert "model 'numbacannot': numba cannot compile log_likelihood()" in str(err.value)


def test_run_warns_of_a_non_finite_log_likelihood_with_its_first_step(tmp_path):
    """A NaN likelihood used to end in loglik -inf, exit 0, without a word."""
    f = tmp_path / "nanll.py"
    f.write_text(
        "import numpy as np\n"
        "from pfbench.models import register\n"
        "from pfbench.models.base import StateSpaceModel\n"
        "@register('nanll')\n"
        "class NanLL(StateSpaceModel):\n"
        "    n_x, n_y, n_noise = 1, 1, 1\n"
        "    def params(self):\n        return (1.0,)\n"
        "    @staticmethod\n    def initial(rng, n, p):\n        return rng.standard_normal((n, 1))\n"
        "    @staticmethod\n    def transition(x, u, t, noise, p):\n        return x + noise\n"
        "    @staticmethod\n    def log_likelihood(y, x, u, t, p):\n"
        "        return np.where(t >= 3, np.nan, -0.5 * (y[0] - x[:, 0]) ** 2)\n"
        "    @staticmethod\n    def observe(x, u, t, noise, p):\n        return x + noise\n")
    r = CliRunner().invoke(main, ["--models", str(f), "run", "--model", "nanll", "--particles", "20",
                                  "--steps", "6", "--backend", "numpy"])
    assert r.exit_code == 0, r.output
    non_finite, invalid = [ln for ln in r.stderr.splitlines() if ln.startswith("warning:")]
    assert "from step 3 on" in non_finite
    assert "NaN or +inf 60 time(s) at 3 step(s), first at step 3" in invalid  # 20 particles, steps 3-5
    strict = CliRunner().invoke(main, ["--models", str(f), "run", "--model", "nanll", "--particles", "20",
                                       "--steps", "6", "--backend", "numpy", "--strict"])
    assert strict.exit_code == 2 and "error: the log-likelihood is -inf from step 3 on" in strict.stderr


def _user_helper(t):
    raise ValueError(f"late in the user's code, t = {t}")


class LateHelper(Good):
    name = "latehelper"

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        if t >= 3:
            _user_helper(t)                       # the error is the function pfbench called
        return -0.5 * (y[0] - x[:, 0]) ** 2


class LateRaise(Good):
    name = "lateraise"

    @staticmethod
    def transition(x, u, t, noise, p):
        if t >= 3:
            raise ValueError("late in the user's code")
        return 0.9 * x + noise


@pytest.mark.parametrize("method", ["bootstrap", "multipdf"])
def test_an_exception_after_the_check_names_the_function_and_the_step(method):
    """The check before the run sees step 0 only; a function that raises later is still one line,
    on NumPy with the function and the step (from its traceback), on numba with the model (compiled
    code keeps no traceback). Catches: the traceback walk dropped or reading the wrong argument as
    the step, the numba kernel call not wrapped (a raw ValueError, which the CLI calls a pfbench bug)."""
    kw = dict(method=method, n_particles=8, n_filters=2 if method == "multipdf" else 1)
    for model, needle in ((LateHelper(), "log_likelihood() raised ValueError at step 3: late in the user's "
                           "code, t = 3"), (LateRaise(), "transition() raised ValueError at step 3")):
        with pytest.raises(InputError) as err:
            pfbench.run_filter(model, np.zeros((6, 1)), backend="numpy", **kw)
        assert str(err.value).startswith(f"model {model.name!r}: {needle}"), err.value
    with pytest.raises(InputError) as err:
        pfbench.run_filter(LateRaise(), np.zeros((6, 1)), backend="numba", **kw)
    assert str(err.value).startswith("model 'lateraise': its compiled code raised ValueError: late in the "
                                     "user's code (compiled code keeps no traceback"), err.value
    assert "\n" not in str(err.value)


def test_simulate_names_a_function_that_raises_at_a_later_step():
    """simulate() checks step 0 like a run and names a later exception too. Catches its loop not
    wrapped (a raw ValueError)."""
    with pytest.raises(InputError, match=r"^model 'lateraise': transition\(\) raised ValueError at step 3"):
        LateRaise().simulate(6)


class NaNFromStep2(Good):
    name = "nanstate"

    @staticmethod
    def transition(x, u, t, noise, p):
        return x + noise + (np.nan if t >= 2 else 0.0)


class InfMeasurement(Good):
    name = "infmeas"

    @staticmethod
    def observe(x, u, t, noise, p):
        return x + noise + (np.inf if t >= 4 else 0.0)


@pytest.mark.parametrize("model, says", [
    (NaNFromStep2(), "simulate(): transition() gave a non-finite state at step 2 ([nan])"),
    (InfMeasurement(), "simulate(): observe() gave a non-finite measurement at step 4 ([inf])"),
])
def test_a_simulation_that_goes_non_finite_names_the_model(model, says):
    """The run then refused the measurements as if they were the user's bad data. Catches the
    check dropped, or the state and measurement steps confused."""
    with pytest.raises(InputError, match=rf"^model {model.name!r}: {re.escape(says)}"):
        model.simulate(6)


def test_a_guided_proposal_that_raises_after_the_check_is_named():
    """As above for the guided family (its own kernel call). Catches that call not wrapped."""
    class LateProposal(Guided):
        name = "lateproposal"

        @staticmethod
        def proposal(x_prev, y, u, t, noise, p):
            if t >= 3:
                raise ValueError("late in the user's code")
            return 0.9 * x_prev + noise

    for backend, needle in (("numpy", "proposal() raised ValueError at step 3"),
                            ("numba", "its compiled code raised ValueError")):
        with pytest.raises(InputError) as err:
            pfbench.run_filter(LateProposal(), np.zeros((6, 1)), method="guided", n_particles=8, backend=backend)
        assert str(err.value).startswith(f"model 'lateproposal': {needle}"), err.value


class LateRows(Good):
    name = "laterows"

    @staticmethod
    def transition(x, u, t, noise, p):
        if t >= 3:
            return np.zeros((x.shape[0] + 1, 1))  # a row more: stored by index, out of bounds
        return 0.9 * x + noise


class LateShortLoglik(Good):
    name = "lateshort"

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        out = -0.5 * (y[0] - x[:, 0]) ** 2
        return out[:-1] if t >= 3 else out        # a row fewer: read out of bounds


@pytest.mark.parametrize("model, numpy_says, numba_says", [
    (LateRows(), "transition() must return a float array of shape (8, 1), got shape (9, 1) of float64 (at step 3)",
     "transition() returned an array of another shape during the run"),
    (LateShortLoglik(), "log_likelihood() must return a float array of shape (8,), got shape (7,) of float64 "
     "(at step 3)", "log_likelihood() returned an array of another shape during the run"),
])
def test_a_shape_that_changes_after_the_check_is_named(model, numpy_says, numba_says):
    """The particle kernels read and store the model's rows by index: a changed shape was a
    broadcast error (NumPy, reported as a pfbench bug) or memory read or written out of bounds, with
    results that looked normal (numba). Catches either per-step check dropped."""
    for backend, says in (("numpy", numpy_says), ("numba", numba_says)):
        with pytest.raises(InputError) as err:
            pfbench.run_filter(model, np.zeros((6, 1)), n_particles=8, backend=backend)
        assert str(err.value).startswith(f"model {model.name!r}: {says}"), (backend, err.value)


class HalfState(Good):
    name = "halfstate"
    n_x = 1.5


class SqrtParams(Good):
    name = "sqrtparams"

    def __init__(self, q=None):
        self.q = q

    def params(self):
        return (np.sqrt(self.q),)


class DictParams(Good):
    name = "dictparams"

    def params(self):
        return {"q": 1.0}


class NestedText(Good):
    name = "nestedtext"

    def params(self):
        return (1.0, (np.ones(2), "x"))


class HalfParams(Good):
    name = "halfparams"

    def params(self):
        return (np.sqrt(True), np.ones(2, np.float16))  # np.sqrt of a bool is a float16


class HugeParams(Good):
    name = "hugeparams"

    def params(self):
        return (1.0, (2 ** 70,))


@pytest.mark.parametrize("model, says", [
    (DictParams(), "params() must return a tuple, each entry a number, a numeric array or a tuple of them; got a dict"),
    (NestedText(), "params()[1][1] is a str"),
    (HalfParams(), "params()[0] is float16, which numba cannot compile"),
    (HugeParams(), "params()[1][0] is the integer 1180591620717411303424, beyond 64 bits"),
])
def test_params_numba_cannot_type_are_refused_before_the_run(model, says):
    """A dict or a string in params() ran on NumPy and failed deep in numba ("Cannot determine
    Numba type of <class 'dict'>", reported as a pfbench bug), as did a float16 (NotImplementedError)
    or an integer beyond 64 bits. Catches the type check dropped."""
    with pytest.raises(InputError) as err:
        pfbench.run_filter(model, Y, n_particles=10, backend="numpy")
    assert str(err.value).startswith(f"model {model.name!r}: {says}"), err.value


class FailingInit(Good):
    name = "failinginit_test"

    def __init__(self):
        raise RuntimeError("no licence file")


def test_a_models_dimensions_parameters_and_constructor_are_its_own_errors(monkeypatch):
    """Each was a TypeError or RuntimeError the CLI reported as a pfbench bug. Catches the
    dimension check, params() outside the contract's call, get() passing a constructor's
    exception on."""
    from pfbench import models

    with pytest.raises(InputError, match=r"^model 'halfstate': n_x must be an integer >= 1, got 1.5$"):
        pfbench.run_filter(HalfState(), Y, n_particles=10, backend="numpy")
    with pytest.raises(InputError, match=r"^model 'sqrtparams': params\(\) raised TypeError"):
        pfbench.run_filter(SqrtParams(q="abc"), Y, n_particles=10, backend="numpy")
    monkeypatch.setitem(models._REGISTRY, "failinginit_test", FailingInit)   # registered for this test only
    with pytest.raises(InputError, match=r"^model 'failinginit_test': __init__ raised RuntimeError: no licence file$"):
        models.get("failinginit_test")


def test_only_an_exception_of_compiled_code_is_blamed_on_the_model():
    """An exception numba's own Python code raises around a kernel call (here: a thread count it
    refuses; in the field an unknown NUMBA_THREADING_LAYER) is numba's, not the model's. Catches
    every builtin exception inside the kernel call blamed on the model's compiled code."""
    import numba

    from pfbench.models.contract import compiled_model_code

    @numba.njit(cache=False)
    def kernel():
        raise ValueError("from compiled code")

    with pytest.raises(InputError, match=r"^model 'good': its compiled code raised ValueError: from compiled code"):
        with compiled_model_code(Good()):
            kernel()
    with pytest.raises(ValueError, match="number of threads"):
        with compiled_model_code(Good()):
            numba.set_num_threads(0)


def test_a_pfbench_error_during_the_run_is_not_blamed_on_the_model(monkeypatch):
    """An exception with no frame of the model's functions passes unchanged (the CLI then reports
    a pfbench bug). Catches every exception during a run turned into the model's InputError."""
    from pfbench.backends import numpy_backend

    def broken(*args, **kwargs):
        raise RuntimeError("a bug in pfbench")

    monkeypatch.setattr(numpy_backend, "run_group", broken)
    with pytest.raises(RuntimeError, match="a bug in pfbench"):
        pfbench.run_filter(LateRaise(), np.zeros((2, 1)), n_particles=8, backend="numpy")


def test_a_subclass_that_sets_no_name_is_named_by_its_class():
    """Catches the inherited name used: a user's variant of a built-in model read as the built-in."""
    from pfbench.models import get
    from pfbench.models.contract import name_of

    ob1 = get("ob1")

    class MyOb1(type(ob1)):
        pass

    named = type(ob1)()
    named.name = "mine"
    assert (name_of(ob1), name_of(MyOb1()), name_of(LateRaise()), name_of(named)) == ("ob1", "MyOb1", "lateraise",
                                                                                     "mine")


class Guided(Good):
    """Good with its own proposal (the prior: the weight is the log-likelihood)."""
    name = "guided"
    proposal_kind = "proposal"

    @staticmethod
    def proposal(x_prev, y, u, t, noise, p):
        return 0.9 * x_prev + noise

    @staticmethod
    def proposal_log_weight(x, x_prev, y, u, t, p):
        return -0.5 * (y[0] - x[:, 0]) ** 2


class ProposalNoStatic(Guided):
    name = "proposalnostatic"

    def proposal(x_prev, y, u, t, noise, p):     # forgot @staticmethod
        return 0.9 * x_prev + noise


class WideWeight(Guided):
    name = "wideweight"

    @staticmethod
    def proposal_log_weight(x, x_prev, y, u, t, p):
        return -0.5 * (y[0] - x) ** 2               # (n, 1)


class WeightCallsTheClass(Guided):
    name = "weightcallstheclass"

    @staticmethod
    def proposal_log_weight(x, x_prev, y, u, t, p):
        return WeightCallsTheClass.log_likelihood(y, x, u, t, p)   # a class attribute: not numba code


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize("model, needle", [
    (ProposalNoStatic(), "proposal must be a @staticmethod"),
    (WideWeight(), "proposal_log_weight() must return a float array of shape (3,), got shape (3, 1)"),
])
def test_guided_function_mistakes_are_one_line_on_both_backends(model, needle, backend):
    """The guided filter's own functions are held to the contract as the four are. Catches them
    left out of the check: NumPy then failed with "'NoneType' object is not callable" (an internal
    error) where numba ran, and a (n, 1) weight broadcast against the log-weights."""
    pfbench.run_filter(Guided(), Y, method="guided", n_particles=10, backend=backend)
    with pytest.raises(InputError) as err:
        pfbench.run_filter(model, Y, method="guided", n_particles=10, backend=backend)
    assert needle in str(err.value) and f"model {model.name!r}" in str(err.value)


def test_guided_code_numba_cannot_compile_is_named():
    """A proposal weight that calls the class's own method runs in Python and fails numba's typing;
    the error names proposal_log_weight. Catches the guided functions left out of the functions
    compiled one by one (the failure was then "internal error in pfbench")."""
    model = WeightCallsTheClass()
    pfbench.run_filter(model, Y, method="guided", n_particles=10, backend="numpy")
    with pytest.raises(InputError) as err:
        pfbench.run_filter(model, Y, method="guided", n_particles=10, backend="numba")
    assert "model 'weightcallstheclass': numba cannot compile proposal_log_weight()" in str(err.value)


class LateNarrowProposal(Guided):
    name = "latenarrowproposal"

    @staticmethod
    def proposal(x_prev, y, u, t, noise, p):
        out = 0.9 * x_prev + noise
        return out[:1] if t >= 3 else out       # one row: broadcast into every particle


class LateShortWeight(Guided):
    name = "lateshortweight"

    @staticmethod
    def proposal_log_weight(x, x_prev, y, u, t, p):
        out = -0.5 * (y[0] - x[:, 0]) ** 2
        return out[:1] if t >= 3 else out


@pytest.mark.parametrize("model, fn, shape", [(LateNarrowProposal(), "proposal", "(8, 1), got shape (1, 1)"),
                                              (LateShortWeight(), "proposal_log_weight", "(8,), got shape (1,)")])
def test_a_guided_shape_that_changes_after_the_check_is_named(model, fn, shape):
    """The guided filter assigned the model's arrays into its own, so a one-row result broadcast
    to every particle and the run printed normal results on both backends. Catches either
    backend's per-step check dropped."""
    for backend, says in (("numpy", f"{fn}() must return a float array of shape {shape} of float64 (at step 3)"),
                          ("numba", f"{fn}() returned an array of another shape during the run")):
        with pytest.raises(InputError) as err:
            pfbench.run_filter(model, np.zeros((6, 1)), method="guided", n_particles=8, backend=backend)
        assert str(err.value).startswith(f"model {model.name!r}: {says}"), (backend, err.value)


class NoLoglik(Good):
    name = "nologlik"
    log_likelihood = StateSpaceModel.log_likelihood     # as a marginalized-PF-only model has it


def test_a_function_the_method_needs_must_be_defined_the_others_only_if_present():
    """An MPF-only model (no log_likelihood) still simulates; a bootstrap run of it names what is
    missing. Catches every function demanded of every model, and a missing one found only as a
    NotImplementedError deep in a kernel."""
    traj = NoLoglik().simulate(4)
    with pytest.raises(InputError, match="defines no log_likelihood\\(\\), which method 'bootstrap' needs"):
        pfbench.run_filter(NoLoglik(), traj.y, n_particles=10, backend="numpy")


def test_a_malformed_linear_states_is_the_models_error_everywhere():
    """linear_states = 1 (not a sequence) was a TypeError in the memory check of an mpf run and broke
    `pfbench models` for every model. Catches len() of it again."""
    from pfbench.errors import ModelError
    from pfbench.models import get
    from pfbench.models.catalog import supported
    from pfbench.resources import check_filter_memory

    model = get("linear_gaussian")
    model.linear_states = 1
    with pytest.raises(ModelError, match="linear_states must be a sequence"):
        check_filter_memory(model, "mpf", 100, n_steps=10)
    assert supported(model) == {"mpf": False, "guided": False, "kalman": False}
