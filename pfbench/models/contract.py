"""The model contract, checked once before a run, so that a mistake in a user's model reads as
one line naming the model, the function and the problem instead of a traceback from deep inside a
backend (or, worse, a run that goes on with wrongly broadcast arrays).

:func:`check_model` calls the model's functions on a tiny block of particles in NumPy, the
same check for both backends: each must be a ``@staticmethod`` and return float arrays of the
documented shapes (:mod:`pfbench.models.base`); the last three are the guided filter's, checked
where the model defines them:

=============================  =============================================  =============
function                       called as                                      returns
=============================  =============================================  =============
``initial``                    ``initial(rng, n, p)``                         (n, n_x)
``transition``                 ``transition(x, u_t, t, noise, p)``            (n, n_x)
``log_likelihood``             ``log_likelihood(y_t, x, u_t, t, p)``          (n,)
``observe``                    ``observe(x, u_t, t, noise, p)``               (n, n_y)
``proposal``                   ``proposal(x_prev, y_t, u_t, t, noise, p)``    (n, n_x)
``proposal_log_weight``        ``proposal_log_weight(x, x_prev, y_t, ...)``   (n,)
``predictive_log_likelihood``  ``predictive_log_likelihood(y_t, x_prev, ...)``  (n,)
=============================  =============================================  =============

A model that declares a linear-Gaussian structure has valid ``linear_states``
(:func:`linear_indices`), and its ``cl_transition``, ``cl_observation`` and ``cl_constrain`` are
each a ``@staticmethod`` too; :func:`pfbench.filters.marginalized.structure` checks what they return.
An exception raised by the model's own code is reported with its type and message (``pfbench
--debug`` shows the traceback; :func:`call`). :func:`numba_failure` does the same for code numba cannot compile:
it compiles the functions the model defines one by one on the probe's arguments to name the one
that fails.

During the run (:func:`named_model_errors`, :func:`compiled_model_code`): an exception raised in
the model's code is one line too, naming the function and the step on the NumPy backend (found in
the traceback), and the model on numba, whose compiled code keeps no traceback. An exception with no
frame of the model's functions is pfbench's and passes unchanged.
"""
from __future__ import annotations

import contextlib
import inspect

import numpy as np

from ..errors import InputError, ModelError, PfbenchError

FUNCTIONS = ("initial", "transition", "log_likelihood", "observe", "proposal", "proposal_log_weight",
             "predictive_log_likelihood", "cl_transition", "cl_observation", "cl_constrain")
PROBE = 3   # particles in the probe block


#: the position of the step ``t`` among each function's arguments (the table above)
_STEP_ARG = {"transition": 2, "log_likelihood": 3, "observe": 2, "proposal": 3, "proposal_log_weight": 4,
             "predictive_log_likelihood": 3, "cl_transition": 2, "cl_observation": 3}
#: how the compiled MPF reports a structure function whose array changed shape during the run
#: (:func:`pfbench.backends.numba_mpf_steps.copy_into`); :func:`compiled_model_code` names the model
RESHAPED = "() returned an array of another shape during the run than in the check before it"


def name_of(model) -> str:
    """The model's (or model class's) name for messages: its registered (or own) ``name``; a subclass
    that sets none is named by its class, so a user's variant of a built-in model is not taken for the
    built-in."""
    cls = model if isinstance(model, type) else type(model)
    own = (None if model is cls else vars(model).get("name")) or cls.__dict__.get("name")
    return str(own or cls.__name__)


def defined(model) -> set:
    """The contract functions the model's class defines (not the base class's abstract ones)."""
    from .base import StateSpaceModel

    def plain(f):
        return f.__func__ if isinstance(f, staticmethod) else f

    return {fn for fn in FUNCTIONS if plain(inspect.getattr_static(type(model), fn, None))
            is not plain(inspect.getattr_static(StateSpaceModel, fn))}


def _check_static(model, needs) -> set:
    have = defined(model)
    for fn in FUNCTIONS:
        if fn not in have:
            if fn in needs:   # the method does not apply to this model: not a mistake in its code
                raise InputError(f"model {name_of(model)!r} defines no {fn}(), which {needs[fn]} needs "
                                 "(see `pfbench.models.base`)")
            continue
        if not isinstance(inspect.getattr_static(type(model), fn), staticmethod):
            raise ModelError(f"model {name_of(model)!r}: {fn} must be a @staticmethod (it takes no self; "
                             "put @staticmethod above its def)")
    return have


def _check_dimensions(model) -> None:
    """n_x, n_y (at least 1), n_noise, n_u and n_obs_noise (unless None) are integers >= 0."""
    for attr, least in (("n_x", 1), ("n_y", 1), ("n_noise", 0), ("n_u", 0), ("n_obs_noise", 0)):
        v = getattr(model, attr, None)
        if v is None and attr == "n_obs_noise":
            continue
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < least:
            raise ModelError(f"model {name_of(model)!r}: {attr} must be an integer >= {least}, got {v!r}")


def _probe_args(model, y, u) -> dict:
    """Arguments of each function on the probe block (zero noise, the first measurement)."""
    p = call(model, "params", {"params": "the run"})
    _check_params(model, p)
    n = PROBE
    n_prop = getattr(model, "n_proposal_noise", None)
    return {"p": p, "n": n, "y0": np.asarray(y[0]), "u0": np.asarray(u[0]),
            "noise": np.zeros((n, int(model.n_noise))), "obs_noise": np.zeros((n, int(model.obs_noise_dim))),
            "prop_noise": np.zeros((n, int(model.n_noise if n_prop is None else n_prop))),
            "linear": None if getattr(model, "linear_states", None) is None else linear_indices(model)}


def _check_params(model, p, path: str = "") -> None:
    """``params()`` must be a tuple of numbers, numeric arrays and such tuples: what numba can type. A
    dict, a list or an object ran on NumPy and failed deep in numba ("Cannot determine Numba type")."""
    ok = "a number, a numeric array or a tuple of them"
    if not isinstance(p, tuple):
        raise ModelError(f"model {name_of(model)!r}: params() must return a tuple, each entry {ok}; got a "
                         f"{type(p).__name__}")
    for i, v in enumerate(p):
        where = f"model {name_of(model)!r}: params(){path}[{i}]"
        if isinstance(v, tuple):
            _check_params(model, v, f"{path}[{i}]")
        elif not (isinstance(v, (int, float, np.number)) or (isinstance(v, np.ndarray) and v.dtype.kind in "biuf")):
            raise ModelError(f"{where} is a {type(v).__name__}; it must be {ok}")
        elif getattr(v, "dtype", None) == np.float16:  # np.sqrt(True), for one, is a float16
            raise ModelError(f"{where} is float16, which numba cannot compile: make it a float (float32 or float64)")
        elif isinstance(v, int) and not -2 ** 63 <= v < 2 ** 64:
            raise ModelError(f"{where} is the integer {v}, beyond 64 bits: numba cannot hold it (make it a float)")


def invalid_log_likelihoods(ll) -> int:
    """How many of the model's log-likelihoods ``ll`` are NaN or +inf (each a particle given weight
    zero: the model's trouble). Counted with NumPy here, outside :mod:`pfbench.mcu.counting`'s count of
    the NumPy backend's operations: the firmware it costs does no such count."""
    return int(np.count_nonzero(~(np.asarray(ll) < np.inf)))


def linear_indices(model) -> np.ndarray:
    """The model's ``linear_states`` as distinct int64 indices of x^l in 0..n_x-1, at least one;
    else a ModelError."""
    raw = np.asarray(model.linear_states)
    n_x = int(model.n_x)
    if (raw.ndim != 1 or raw.size == 0 or raw.dtype.kind not in "iu" or len(set(raw.tolist())) != raw.size
            or raw.min() < 0 or raw.max() >= n_x):
        raise ModelError(f"model {name_of(model)!r}: linear_states must be a sequence of distinct state "
                         f"indices in 0..{n_x - 1} (integers), at least one, got {model.linear_states!r}")
    return raw.astype(np.int64)


def _calls(a: dict, x, want_x: tuple, want_y: tuple) -> tuple:
    """(function, shape it returns, its arguments on the probe block ``x``) after ``initial``; the
    structure functions' shapes are checked by :func:`pfbench.filters.marginalized.structure`."""
    p, y0, u0 = a["p"], a["y0"], a["u0"]
    structure = ()
    if a["linear"] is not None:
        xn = np.zeros((a["n"], x.shape[1] - a["linear"].size))
        structure = (("cl_transition", None, (xn, u0, 0, p)), ("cl_constrain", None, (xn, p)),
                     ("cl_observation", None, (xn, np.zeros((a["n"], a["linear"].size)), u0, 0, p)))
    return structure + (("transition", want_x, (x, u0, 0, a["noise"], p)),
            ("log_likelihood", (a["n"],), (y0, x, u0, 0, p)),
            ("observe", want_y, (x, u0, 0, a["obs_noise"], p)),
            ("proposal", want_x, (x, y0, u0, 0, a["prop_noise"], p)),
            ("proposal_log_weight", (a["n"],), (x, x, y0, u0, 0, p)),
            ("predictive_log_likelihood", (a["n"],), (y0, x, u0, 0, p)))


def call(model, fn: str, needs: dict, *args):
    """``model.fn(*args)``; None when the model refuses on purpose (a PfbenchError, e.g. "use
    method='guided'") and the run does not need ``fn``; that refusal as it is when it does."""
    try:
        return getattr(model, fn)(*args)
    except PfbenchError:
        if fn in needs:
            raise
        return None
    except Exception as exc:   # the user's code: report it as theirs, not as a pfbench bug
        raise _raised(model, f"{fn}()", exc) from exc


def _raised(model, what: str, exc: BaseException, step=None, how: str = "pfbench --debug shows the traceback"):
    """The one-line ModelError for an exception ``exc`` of ``what`` (the model's function, at ``step``)."""
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    at = f" at step {step}" if step is not None else ""
    return ModelError(f"model {name_of(model)!r}: {what} raised {type(exc).__name__}{at}"
                      + (f": {first}" if first else "") + f" ({how})")


def call_returning(model, fn: str, names: tuple | None, *args):
    """``model.fn(*args)`` for a function the run needs (:func:`call`), checked by :func:`returned`."""
    return returned(model, fn, call(model, fn, {fn: "the run"}, *args), names)


def returned(model, fn: str, out, names: tuple | None):
    """``out``, what the model's ``fn`` returned, as a tuple of one result per name of ``names``
    (None: ``out``, any one value); a ModelError when it is not a tuple or list of that length."""
    if names is None:
        return out
    if not isinstance(out, (tuple, list)) or len(out) != len(names):
        got = f"{len(out)} values" if isinstance(out, (tuple, list)) else type(out).__name__
        raise ModelError(f"model {name_of(model)!r}: {fn}() must return ({', '.join(names)}), got {got}")
    return tuple(out)


def shaped(model, fn: str, value, want: tuple, where: str | None = None) -> np.ndarray:
    """``value``, what the model's ``fn`` returned on the probe block (``where`` None) or ``where``
    else (e.g. "at step 3"), as a float64 array of shape ``want``; a ModelError naming it otherwise."""
    arr = np.asanyarray(value)   # any: the operation counter's arrays stay counting (pfbench.mcu.counting)
    if arr.shape != want or arr.dtype.kind not in "fiu":
        got = f"shape {arr.shape} of {arr.dtype}" if arr.ndim or np.issubdtype(arr.dtype, np.number) \
            else type(value).__name__
        raise ModelError(f"model {name_of(model)!r}: {fn}() must return a float array of shape {want}, "
                         f"got {got} ({where or f'on a block of {PROBE} particles'})")
    return arr.astype(np.float64, copy=False)


def check_model(model, y, u, needs: dict | None = None) -> None:
    """Check the model's contract on a probe block (module docstring); a ModelError naming the
    model, the function and the problem otherwise. ``y``, ``u``: the run's checked inputs
    (:func:`pfbench.filters.inputs.check_inputs`). ``needs``: function -> what needs it (e.g.
    ``{"log_likelihood": "method 'bootstrap'"}``): those must be defined; the others are checked
    where the model defines them (a model for the marginalized PF may have no log_likelihood)."""
    needs = needs or {}
    _check_dimensions(model)
    have = _check_static(model, needs)
    a = _probe_args(model, y, u)
    n, n_x, n_y = a["n"], int(model.n_x), int(model.n_y)
    if "initial" not in have:
        return
    x = call(model, "initial", needs, np.random.default_rng(0), n, a["p"])
    if x is None:
        return
    x = shaped(model, "initial", x, (n, n_x))
    for fn, want, args in _calls(a, x, (n, n_x), (n, n_y)):
        if fn in have and want is not None:
            out = call(model, fn, needs, *args)
            if out is not None:
                shaped(model, fn, out, want)


def needs_of(family: str, label: str) -> dict:
    """The contract functions a method family calls: the particle and guided families propagate
    and weigh with the model's own functions; the marginalized PF and the Kalman family use the
    declared linear-Gaussian structure instead."""
    if family == "particle":
        return {fn: f"method {label!r}" for fn in ("initial", "transition", "log_likelihood")}
    if family == "guided":   # the proposal and its weight may stand in for transition and log_likelihood
        return {"initial": f"method {label!r}"}
    return {}
def numba_failure(model, y, u, exc: BaseException) -> ModelError | None:
    """After numba failed to compile a kernel for ``model`` (``exc``): compile each model function
    alone on the probe's arguments and return a ModelError naming the first that numba cannot
    compile, with numba's first line; None when each compiles alone (then the failure is not the
    model's, and the caller re-raises it)."""
    import numba

    a = _probe_args(model, y, u)
    have = defined(model)
    # initial is drawn in NumPy by every kernel and observe only simulates: neither is compiled
    for fn, _, args in _calls(a, np.zeros((a["n"], int(model.n_x))), (), ()):
        if fn == "observe" or fn not in have:
            continue
        try:
            numba.njit(getattr(type(model), fn))(*args)
        except Exception as err:   # numba's typing / bytecode errors, or the model's own raise
            lines = [ln.strip() for ln in str(err).splitlines() if ln.strip()]
            why = next((ln for ln in lines if not ln.startswith(("During:", "File", "^"))), type(err).__name__)
            return ModelError(f"model {name_of(model)!r}: numba cannot compile {fn}(): {why} "
                              "(--backend numpy runs plain Python; pfbench --debug shows numba's report)")
    return None


def _raised_in_model(model, exc: BaseException) -> ModelError | None:
    """:func:`_raised` for an exception raised inside one of the model's functions during the run
    (found in its traceback, with the step from that function's ``t`` argument); None when no
    frame of the traceback is the model's, or the exception is in compiled code (no frames)."""
    codes = {}
    for fn in defined(model):
        f = inspect.getattr_static(type(model), fn)
        f = getattr(f.__func__ if isinstance(f, staticmethod) else f, "__code__", None)
        if f is not None:
            codes[f] = fn
    tb = exc.__traceback__
    while tb is not None:   # outermost first: the function pfbench called, not a helper of it
        fn = codes.get(tb.tb_frame.f_code)
        if fn is not None:
            step = None
            if fn in _STEP_ARG and _STEP_ARG[fn] < tb.tb_frame.f_code.co_argcount:
                step = tb.tb_frame.f_locals.get(tb.tb_frame.f_code.co_varnames[_STEP_ARG[fn]])
            return _raised(model, f"{fn}()", exc, step if isinstance(step, (int, np.integer)) else None)
        tb = tb.tb_next
    return None


@contextlib.contextmanager
def named_model_errors(model, y, u, backend: str):
    """Around a run: an exception raised in the model's own code becomes a one-line ModelError
    naming the function and the step (:func:`_raised_in_model`); a numba compile failure caused by
    the model's code becomes :func:`numba_failure`'s. Other exceptions pass unchanged."""
    try:
        yield
    except (PfbenchError, MemoryError):   # MemoryError: the CLI's own message says what fits
        raise
    except Exception as exc:
        if backend == "numba" and type(exc).__module__.startswith("numba"):
            named = numba_failure(model, y, u, exc)
        else:
            named = _raised_in_model(model, exc)
        if named is None:
            raise
        raise named from exc


@contextlib.contextmanager
def compiled_model_code(model):
    """Around a call of a compiled kernel that runs the model's functions: an exception the kernel
    raises (a ``raise`` in the model's code, a division by zero in it, or
    :data:`RESHAPED`) becomes a one-line ModelError naming the model. Compiled code keeps no
    traceback, so the function and the step are named by the same run on ``--backend numpy``.
    numba's own errors pass unchanged: a compile failure (:func:`named_model_errors` names it), and
    an exception raised in numba's Python code (e.g. an unknown ``NUMBA_THREADING_LAYER`` when the
    threads start), as does MemoryError."""
    try:
        yield
    except (PfbenchError, MemoryError):   # as in named_model_errors
        raise
    except Exception as exc:
        tb = exc.__traceback__
        while tb is not None and tb.tb_next is not None:
            tb = tb.tb_next
        if type(exc).__module__ != "builtins" or (
                tb is not None and tb.tb_frame.f_globals.get("__name__", "").startswith("numba")):
            raise
        if RESHAPED in str(exc):
            raise ModelError(f"model {name_of(model)!r}: {exc}") from exc
        raise _raised(model, "its compiled code", exc, how="compiled code keeps no traceback: the same "
                      "run with --backend numpy names the function and the step") from exc
