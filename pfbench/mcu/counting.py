"""Automatic operation counting for any registered model and filter method.

The counts are *derived*, never typed in per model: we run the NumPy reference engine
(:func:`pfbench.backends.numpy_backend.run_group`, the same code ``run_filter(backend="numpy")``
runs) on :class:`CountingArray` s - an ``ndarray`` subclass whose ``__array_ufunc__`` /
``__array_function__`` hooks record every elementwise operation, reduction, scan, gather and
store - with a :class:`CountingGenerator` that records uniform and normal draws. While
counting, the module-level ``np`` of the engine and of :mod:`pfbench.resampling` is replaced
by a proxy whose array constructors return :class:`CountingArray` s, so the engine's own
normalisation / resampling work ([Embedded] Alg. 1 steps 3-6) is counted as well as the
model's transition and likelihood.

Counting conventions (what a C port on a Cortex-M4 would execute):

* one operation per output element of an elementwise ufunc (``x * y`` on N particles = N mul);
  a scalar expression (``8 cos(1.2 t)``) costs once per step, i.e. it is loop-invariant and
  hoisted out of the particle loop (what ``-O2``/``-Ofast`` does with a pure function);
* ``x ** 2`` -> 1 mul, ``x ** 0.5`` -> sqrt, ``x ** k`` (small integer k) -> k-1 mul, other
  powers -> ``pow``; ``np.cbrt`` -> ``cbrt`` (libm ``cbrt``/``cbrtf``, about half a ``pow``);
  ``sin``/``tan``/``arctan`` are counted as ``cos`` (same libm cost class);
* reductions and scans of n elements cost n-1 operations (``max`` -> cmp, ``cumsum`` -> add);
  ``a @ b`` of inner length k costs k mul + k-1 add per output element;
* ``searchsorted`` of sorted positions costs a linear merge, len(cdf) + len(positions) cmp
  (the loop the numba backend and the paper's C code use); sorts cost n ceil(log2 n) cmp;
* a division of a particle array by a scalar (``x / 20``, ``w / total``) is ``div_scalar``: a
  build with ``-freciprocal-math`` (part of ``-Ofast``) turns it into a multiplication by a
  hoisted reciprocal, a standard build divides every time - the cycle table decides;
* integer-typed arithmetic goes to ``int``; float<->int conversions and floor to ``cvt``;
* ``load``/``store`` count element traffic of *stored* arrays (particles, weights, CDF, inputs,
  measurements): gathers ``x[idx]``, assignments ``x[:] = ...``, operands of ufuncs that live
  in memory and scans. Results of elementwise expressions are temporaries kept in registers
  by a fused C loop and are not counted as traffic;
* ``uniform`` / ``normal`` count generator draws; their cost (e.g. Box-Muller) is expanded by
  the cycle table (:mod:`pfbench.mcu.cycles`).

Compiled-code conventions (``count_run(..., code=True)``): what the model's OWN code does
when numba compiles it for the target and the C harness ``pfbench/mcu/c/pf_model.c`` calls it
on tiles of :data:`TILE` particles. They apply only inside the model's ``transition`` and
``log_likelihood`` and add the operation classes of :data:`CODE_OPS` (costed by
:mod:`pfbench.mcu.costmodel`, not by the cycle tables):

* ``tmp``: every array-valued result (ufunc, reduction along an axis, gather, copy) is
  materialised in memory by the compiled code: one store + one load per element;
* ``alloc``: each such array is allocated (and freed) per call, i.e. once per tile of
  :data:`TILE` particles: ``ceil(N / TILE)`` allocations per array per step;
* ``mm_load``: a matrix product ``a @ b`` of inner length k runs an element loop that loads
  both operands: 2 k loads per output element (besides its k mul + k - 1 add).

A run's counts are affine in the number of steps for the methods whose work does not depend on
the data (bootstrap, MultiPDF, SIS, ASIR with systematic resampling), so :func:`count_run`
counts a few steps exactly and extrapolates (``exact=True`` counts every step).
"""
from __future__ import annotations

import math
import threading
from collections import Counter

import numpy as np

from ..errors import InputError, UnsupportedError

#: every operation class the counter produces (the cycle tables must cost each one)
OPS = ("add", "mul", "div", "div_scalar", "cmp", "sqrt", "exp", "log", "cos", "pow", "cbrt", "cvt",
       "int", "load", "store", "uniform", "normal")
#: operation classes of the compiled-code conventions (``count_run(code=True)``, see above)
CODE_OPS = ("tmp", "alloc", "mm_load")
#: particles per model call in the C harness (PF_TILE of pfbench/mcu/c/pf_model.c)
TILE = 32

_UFUNC_OPS = {
    "add": "add", "subtract": "add", "negative": "add",
    "multiply": "mul", "square": "mul",
    "true_divide": "div", "divide": "div", "reciprocal": "div", "floor_divide": "div",
    "remainder": "div", "fmod": "div",
    "sqrt": "sqrt", "cbrt": "cbrt",
    "exp": "exp", "exp2": "exp", "expm1": "exp",
    "log": "log", "log2": "log", "log10": "log", "log1p": "log",
    "cos": "cos", "sin": "cos", "tan": "cos", "arctan": "cos", "arctan2": "cos", "arcsin": "cos",
    "arccos": "cos", "cosh": "exp", "sinh": "exp", "tanh": "exp", "hypot": "sqrt",
    "power": "pow", "float_power": "pow",
    "greater": "cmp", "greater_equal": "cmp", "less": "cmp", "less_equal": "cmp", "equal": "cmp",
    "not_equal": "cmp", "maximum": "cmp", "minimum": "cmp", "fmax": "cmp", "fmin": "cmp",
    "isnan": "cmp", "isinf": "cmp", "isfinite": "cmp", "logical_and": "cmp", "logical_or": "cmp",
    "logical_not": "cmp", "logical_xor": "cmp", "sign": "cmp", "clip": "cmp",
    "absolute": "int", "fabs": "int", "invert": "int", "bitwise_and": "int", "bitwise_or": "int",
    "bitwise_xor": "int", "left_shift": "int", "right_shift": "int", "positive": None,
    "floor": "cvt", "ceil": "cvt", "trunc": "cvt", "rint": "cvt",
}


class OpCounter:
    """A bag of operation counts (a thin wrapper over :class:`collections.Counter`)."""

    def __init__(self):
        self.c = Counter()

    def add(self, op: str, n) -> None:
        n = int(n)
        if n > 0 and op:
            self.c[op] += n

    def as_dict(self) -> dict[str, int]:
        return {op: int(self.c.get(op, 0)) for op in OPS if self.c.get(op, 0)} | {
            k: int(v) for k, v in self.c.items() if k not in OPS and v}


_STATE = threading.local()
_LOCK = threading.RLock()


def _counter() -> OpCounter | None:
    return getattr(_STATE, "counter", None)


def _model_tiles() -> int:
    """Tiles of the current model call when compiled-code counting is on, else 0."""
    return getattr(_STATE, "model_tiles", 0)


def _count_materialised(cnt, result, sources=()) -> None:
    """Compiled-code convention: an array result inside a model function is stored and loaded
    once per element (``tmp``) and allocated once per tile (``alloc``); views cost nothing."""
    tiles = _model_tiles()
    if not tiles or cnt is None:
        return
    res = result[0] if isinstance(result, tuple) else result
    if not isinstance(res, np.ndarray) or res.ndim == 0 or res.size <= 1:
        return
    for s_ in sources:
        if isinstance(s_, np.ndarray) and np.shares_memory(res, s_):
            return
    cnt.add("tmp", res.size)
    cnt.add("alloc", tiles)


def _is_int(dt) -> bool:
    return np.issubdtype(dt, np.integer) or np.issubdtype(dt, np.bool_)


class CountingArray(np.ndarray):
    """``ndarray`` that records the operations done on it into the active :class:`OpCounter`.

    ``_mem`` marks arrays that live in memory (loads/stores are counted for them); results of
    elementwise expressions are register temporaries (``_mem=False``).
    """

    _mem = True

    def __array_finalize__(self, obj):
        self._mem = getattr(obj, "_mem", True)

    # ---------------------------------------------------------------- ufuncs
    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        cnt = _counter()
        raw_in = [np.asarray(a).view(np.ndarray) if isinstance(a, CountingArray) else a for a in inputs]
        out = kwargs.get("out")
        if out is not None:
            kwargs["out"] = tuple(o.view(np.ndarray) if isinstance(o, CountingArray) else o for o in out)
        result = getattr(ufunc, method)(*raw_in, **kwargs)
        if cnt is not None:
            self._count_ufunc(cnt, ufunc, method, inputs, raw_in, result, out, kwargs.get("axis", 0))
            if out is None:
                _count_materialised(cnt, result)
        if out is not None:
            if isinstance(result, tuple):
                return out
            return out[0]
        if isinstance(result, tuple):
            return tuple(_wrap(r, mem=False) for r in result)
        return _wrap(result, mem=False)

    @staticmethod
    def _count_ufunc(cnt, ufunc, method, inputs, raw_in, result, out, axis=0):
        res0 = result[0] if isinstance(result, tuple) else result
        res_size = int(np.size(res0))
        for a in inputs:  # memory traffic of stored operands
            if isinstance(a, CountingArray) and a._mem and a.size > 0:
                cnt.add("load", a.size if method != "__call__" or a.size > 1 else 1)
        if out is not None:
            for o in out:
                if isinstance(o, np.ndarray) and getattr(o, "_mem", True):
                    cnt.add("store", o.size)
        name = ufunc.__name__
        if method == "__call__":
            if name == "matmul":
                a = np.asarray(raw_in[0])
                k = a.shape[-1] if a.ndim else 1
                cnt.add("mul", res_size * k)
                cnt.add("add", res_size * max(k - 1, 0))
                if _model_tiles():
                    cnt.add("mm_load", 2 * res_size * k)
                return
            op = _UFUNC_OPS.get(name, "add")
            if name == "power":
                e = raw_in[1]
                if np.ndim(e) == 0:
                    e = float(e)
                    if e == 0.5:
                        op = "sqrt"
                    elif e == int(e) and 1 <= e <= 8:
                        cnt.add("mul", res_size * (int(e) - 1))
                        return
            if op is None:
                return
            if op == "div" and name in ("true_divide", "divide") and res_size > 1 \
                    and np.size(raw_in[1]) == 1:
                op = "div_scalar"  # divisor invariant over the particle loop
            if op != "cvt" and any(isinstance(r, np.ndarray) and _is_int(r.dtype) for r in [res0]) \
                    and all(_is_int(np.asarray(a).dtype) for a in raw_in):
                op = "int"
            cnt.add(op, res_size)
        elif method in ("reduce", "accumulate"):
            a = np.asarray(raw_in[0])
            if method == "reduce":
                n_ops = a.size - res_size
            else:  # a scan along `axis`: one op per element except the first of each line
                n_ops = a.size - (a.size // max(a.shape[axis or 0], 1) if a.ndim else 1)
            op = _UFUNC_OPS.get(name, "add") or "add"
            if _is_int(a.dtype) and op not in ("cmp",):
                op = "int"
            cnt.add(op, max(n_ops, 0))
        else:  # at, outer, reduceat: count per output element
            cnt.add(_UFUNC_OPS.get(name, "add") or "add", res_size)

    # ---------------------------------------------------------------- functions
    def __array_function__(self, func, types, args, kwargs):
        cnt = _counter()
        name = func.__name__
        raw_args = _unwrap(args)
        raw_kwargs = _unwrap(kwargs)
        result = func(*raw_args, **raw_kwargs)
        if cnt is not None:
            _count_function(cnt, name, args, raw_args, raw_kwargs, result)
            _count_materialised(cnt, result, [a for a in raw_args if isinstance(a, np.ndarray)])
        mem = name not in _TEMP_FUNCS
        if isinstance(result, tuple):
            return tuple(_wrap(r, mem=mem) for r in result)
        return _wrap(result, mem=mem)

    # ---------------------------------------------------------------- indexing
    def __getitem__(self, key):
        cnt = _counter()
        raw = self.view(np.ndarray)[_unwrap(key)]
        if cnt is not None and _is_fancy(key):
            n = int(np.size(raw))
            if self._mem:
                cnt.add("load", n)
            cnt.add("store", n)  # a gather materialises a new array
            _count_materialised(cnt, raw)
            return _wrap(raw, mem=True)
        if np.ndim(raw) == 0:  # one element
            if cnt is not None and self._mem:
                cnt.add("load", 1)
            return _wrap(np.asarray(raw), mem=False) if isinstance(raw, np.generic) else raw
        out = raw.view(type(self))
        out._mem = self._mem
        return out

    def __setitem__(self, key, value):
        cnt = _counter()
        target = self.view(np.ndarray)
        before = target[_unwrap(key)]
        n = int(np.size(before))
        if cnt is not None and self._mem:
            cnt.add("store", n)
        target[_unwrap(key)] = _unwrap(value)

    # ndarray methods that bypass __array_function__
    def cumsum(self, axis=None, dtype=None, out=None):
        return np.cumsum(self, axis=axis, dtype=dtype, out=out)

    def sum(self, *a, **k):
        return np.add.reduce(self, *a, **k) if not a and not k else np.sum(self, *a, **k)

    def copy(self, order="C"):
        cnt = _counter()
        if cnt is not None:
            if self._mem:
                cnt.add("load", self.size)
            cnt.add("store", self.size)
        out = self.view(np.ndarray).copy(order).view(CountingArray)
        out._mem = True
        return out


_TEMP_FUNCS = {"where", "clip", "round", "around"}


def _is_fancy(key) -> bool:
    keys = key if isinstance(key, tuple) else (key,)
    return any(isinstance(k, (np.ndarray, list)) and np.asarray(k).ndim > 0 for k in keys)


def _unwrap(obj):
    if isinstance(obj, CountingArray):
        return obj.view(np.ndarray)
    if isinstance(obj, tuple):
        return tuple(_unwrap(o) for o in obj)
    if isinstance(obj, list):
        return [_unwrap(o) for o in obj]
    if isinstance(obj, dict):
        return {k: _unwrap(v) for k, v in obj.items()}
    return obj


def _wrap(x, mem: bool):
    if isinstance(x, np.ndarray):
        if isinstance(x, CountingArray):
            return x
        out = x.view(CountingArray)
        out._mem = mem
        return out
    if isinstance(x, np.generic):
        out = np.asarray(x).view(CountingArray)
        out._mem = mem
        return out
    return x


def _count_function(cnt: OpCounter, name: str, args, raw_args, raw_kwargs, result) -> None:
    a0 = args[0] if args else None
    size0 = int(np.size(raw_args[0])) if args else 0
    mem0 = isinstance(a0, CountingArray) and a0._mem
    if name in ("cumsum", "cumprod", "nancumsum"):
        cnt.add("add" if "sum" in name else "mul", max(size0 - 1, 0))
        if mem0:
            cnt.add("load", size0)
        cnt.add("store", size0)
    elif name in ("sum", "prod", "mean", "nansum"):
        cnt.add("add" if name != "prod" else "mul", max(size0 - int(np.size(result)), 0))
        if name == "mean":
            cnt.add("div", int(np.size(result)))
        if mem0:
            cnt.add("load", size0)
    elif name in ("amax", "amin", "max", "min", "argmax", "argmin", "any", "all"):
        cnt.add("cmp", max(size0 - int(np.size(result)), 0))
        if mem0:
            cnt.add("load", size0)
    elif name == "searchsorted":
        nv = int(np.size(raw_args[1] if len(raw_args) > 1 else raw_kwargs.get("v")))
        cnt.add("cmp", size0 + nv)
        cnt.add("load", size0 + nv)
        cnt.add("int", nv)
        cnt.add("store", nv)
    elif name in ("sort", "argsort"):
        n = max(size0, 1)
        cnt.add("cmp", n * math.ceil(math.log2(n)) if n > 1 else 0)
        cnt.add("load", n)
        cnt.add("store", n)
    elif name in ("repeat", "bincount", "nonzero", "flatnonzero"):
        out_n = int(np.size(result[0] if isinstance(result, tuple) else result))
        cnt.add("int", size0 + out_n)
        cnt.add("store", out_n)
    elif name in ("copy", "concatenate", "stack", "hstack", "vstack", "take"):
        n = int(np.size(result))
        cnt.add("load", n)
        cnt.add("store", n)
    elif name in ("dot", "inner", "vdot"):
        a = np.asarray(raw_args[0])
        k = a.shape[-1] if a.ndim else 1
        n = max(int(np.size(result)), 1)
        cnt.add("mul", n * k)
        cnt.add("add", n * max(k - 1, 0))
        if _model_tiles():
            cnt.add("mm_load", 2 * n * k)
    elif name == "where" and len(raw_args) == 3:
        cnt.add("cmp", int(np.size(result)))
    # shape manipulation (reshape, ravel, transpose, ...) and constructors cost nothing here


# ---------------------------------------------------------------------- numpy proxy
_MATERIALISE = {"array", "asarray", "ascontiguousarray", "copy", "asanyarray"}


class _NumpyProxy:
    """Stands in for the ``np`` global of the engine while counting: constructors return
    :class:`CountingArray` s; everything else is NumPy itself."""

    def __getattr__(self, name):
        f = getattr(np, name)
        if isinstance(f, type) or not callable(f) or isinstance(f, np.ufunc):
            return f

        def wrapper(*args, **kwargs):
            cnt = _counter()
            src = args[0] if args else None
            result = f(*args, **kwargs)
            if isinstance(result, np.ndarray) and not isinstance(result, CountingArray):
                out = result.view(CountingArray)
                out._mem = True
                if cnt is not None and name in _MATERIALISE and isinstance(src, CountingArray):
                    copied = not np.shares_memory(result, src.view(np.ndarray))
                    if copied:
                        if src._mem:
                            cnt.add("load", src.size)
                        cnt.add("store", src.size)
                    elif not src._mem:  # a temporary that now gets a name: stored once
                        cnt.add("store", src.size)
                return out
            if isinstance(result, CountingArray) and name in _MATERIALISE and not result._mem:
                if cnt is not None:
                    cnt.add("store", result.size)
                result._mem = True
            return result

        wrapper.__name__ = name
        return wrapper


class CountingGenerator:
    """Wraps a ``numpy.random.Generator`` and counts its draws (uniform, normal)."""

    def __init__(self, rng: np.random.Generator, counter: OpCounter):
        self._rng, self._cnt = rng, counter

    def random(self, size=None, *a, **k):
        r = self._rng.random(size, *a, **k)
        self._cnt.add("uniform", np.size(r))
        return _wrap(r, mem=False) if size is not None else r

    def standard_normal(self, size=None, *a, **k):
        r = self._rng.standard_normal(size, *a, **k)
        self._cnt.add("normal", np.size(r))
        return _wrap(r, mem=False) if size is not None else r

    def normal(self, loc=0.0, scale=1.0, size=None):
        r = self._rng.normal(loc, scale, size)
        self._cnt.add("normal", np.size(r))
        self._cnt.add("mul", np.size(r))
        self._cnt.add("add", np.size(r))
        return _wrap(r, mem=False) if size is not None else r

    def uniform(self, low=0.0, high=1.0, size=None):
        r = self._rng.uniform(low, high, size)
        self._cnt.add("uniform", np.size(r))
        self._cnt.add("mul", np.size(r))
        self._cnt.add("add", np.size(r))
        return _wrap(r, mem=False) if size is not None else r

    def __getattr__(self, name):  # other distributions: not costed
        attr = getattr(self._rng, name)
        if callable(attr):
            def wrapper(*a, **k):
                self._cnt.add(f"draw_{name}", 1)
                return attr(*a, **k)
            return wrapper
        return attr


class counting:
    """Context manager: ``with counting() as c: ...`` records into ``c`` (an :class:`OpCounter`).

    Patches the ``np`` global of :mod:`pfbench.backends.numpy_backend` and
    :mod:`pfbench.resampling` with the constructor proxy for the duration (under a lock).
    """

    def __init__(self, counter: OpCounter | None = None):
        self.counter = counter or OpCounter()

    def __enter__(self) -> OpCounter:
        from .. import resampling
        from ..backends import numpy_backend

        _LOCK.acquire()
        self._mods = [numpy_backend, resampling]
        self._saved = [m.np for m in self._mods]
        for m in self._mods:
            m.np = _NumpyProxy()
        # the engine's branch-free exp (pfbench.backends.fastexp) stands for the target's libm exp:
        # counted as one exp per element, not as the arithmetic that spells it out on the host
        self._exp = numpy_backend.exp_weights
        numpy_backend.exp_weights = np.exp
        _STATE.counter = self.counter
        return self.counter

    def __exit__(self, *exc):
        try:
            for m, s in zip(self._mods, self._saved):
                m.np = s
            self._mods[0].exp_weights = self._exp
            _STATE.counter = None
        finally:
            _LOCK.release()
        return False


# ---------------------------------------------------------------------- public API


def _run_counted(model, n_steps: int, n_particles: int, method: str, n_filters: int,
                 resampling: str, ess_threshold, seed: int, compiled: bool = False) -> dict[str, int]:
    from ..backends import numpy_backend
    from ..backends.particle_work import outputs
    from ..filters.inputs import ess_count
    from ..methods import Method
    from ..filters.particle import split_particles
    from ..resampling import Scheme

    traj = model.simulate(n_steps, seed=seed)
    y = np.ascontiguousarray(traj.y, dtype=np.float64)
    u = model.input_array(traj.u, n_steps)
    m = Method.parse(method)
    n_per = split_particles(n_particles, n_filters) if m == Method.MULTIPDF else n_particles
    thr = ess_count(ess_threshold, n_per)
    code = Method.BOOTSTRAP if m == Method.MULTIPDF else m
    p = model.params()
    with counting() as cnt:
        rng = CountingGenerator(np.random.default_rng(seed), cnt)
        G = n_filters if m == Method.MULTIPDF else 1
        out = outputs(G, n_steps, n_per, model.n_x)
        out = out._replace(x=_wrap(out.x, mem=True))
        yc, uc = _wrap(y, mem=True), _wrap(u, mem=True)
        numpy_backend.run_group(_CountingModel(model, compiled), p, rng, yc, uc, out, int(code),
                                int(Scheme.parse(resampling)), thr)
    return cnt.as_dict()


class _CountingModel:
    """Delegates to a model but hands ``t`` to its functions as a counted 0-d array, so that
    per-step scalar work (e.g. ``8 cos(1.2 t)``) is counted once per step."""

    def __init__(self, model, code: bool = False):
        self._m = model
        self.n_noise = model.n_noise
        self._code = bool(code)

    def _in_model(self, fn, x, *args):
        """Call a model function; with compiled-code counting on, inside a model scope."""
        if not self._code:
            return fn(*args)
        _STATE.model_tiles = -(-int(np.shape(x)[0]) // TILE)
        try:
            return fn(*args)
        finally:
            _STATE.model_tiles = 0

    def kernel_functions(self):
        fns = self._m.kernel_functions()

        def initial(rng, n, p):
            return fns["initial"](rng, n, p)

        def transition(x, u, t, noise, p):
            return self._in_model(fns["transition"], x, x, u, _scalar_t(t), noise, p)

        def log_likelihood(y, x, u, t, p):
            return self._in_model(fns["log_likelihood"], x, y, x, u, _scalar_t(t), p)

        return {"initial": initial, "transition": transition, "log_likelihood": log_likelihood,
                "observe": fns["observe"]}


def _scalar_t(t):
    out = np.asarray(float(t)).view(CountingArray)
    out._mem = False
    return out


def _validate(model, n_steps, n_particles, method, n_filters, resampling):
    from ..methods import PARTICLE_METHODS, Method
    from ..resampling import Scheme

    if Method.parse(method).family != "particle":
        raise UnsupportedError(f"operation counts cover the particle methods {', '.join(PARTICLE_METHODS)}; "
                               f"got {method!r}")
    Scheme.parse(resampling)
    if int(n_steps) < 1:
        raise InputError(f"n_steps must be >= 1, got {n_steps}")
    if int(n_particles) < 1:
        raise InputError(f"n_particles must be >= 1, got {n_particles}")
    if int(n_filters) < 1:
        raise InputError(f"n_filters must be >= 1, got {n_filters}")
    if method != "multipdf" and int(n_filters) != 1:
        raise InputError(f"n_filters={n_filters} needs method='multipdf'")
    if int(n_filters) > int(n_particles):
        raise InputError(f"n_filters ({n_filters}) cannot exceed n_particles ({n_particles})")


def count_run(model, n_steps: int, n_particles: int, *, method: str = "bootstrap",
              n_filters: int = 1, resampling: str = "systematic", ess_threshold=None,
              seed: int = 0, exact: bool = False, probe_steps: int = 4,
              code: bool = False) -> dict[str, int]:
    """Operation counts of a whole filter run (``n_steps`` steps, ``n_particles`` particles).

    ``model`` is a :class:`~pfbench.models.base.StateSpaceModel` instance or a registered name.
    Counts are obtained by running the NumPy reference engine on counting arrays. Unless
    ``exact``, only ``probe_steps`` and ``2 * probe_steps`` steps are run and the counts are
    extrapolated affinely in the number of steps (exact for data-independent methods; for
    ``sir`` the resampling rate of the first steps is assumed). ``code``: add the
    compiled-code operation classes :data:`CODE_OPS` of the model's own functions (see the
    module docstring); the other counts are the same either way.
    """
    from .. import models as _models

    if isinstance(model, str):
        model = _models.get(model)
    _validate(model, n_steps, n_particles, method, n_filters, resampling)
    n_steps, n_particles, n_filters = int(n_steps), int(n_particles), int(n_filters)
    k = int(probe_steps)
    if exact or n_steps <= 2 * k:
        return _run_counted(model, n_steps, n_particles, method, n_filters, resampling, ess_threshold, seed,
                            code)
    a = _run_counted(model, k, n_particles, method, n_filters, resampling, ess_threshold, seed, code)
    b = _run_counted(model, 2 * k, n_particles, method, n_filters, resampling, ess_threshold, seed, code)
    out = {}
    for op in set(a) | set(b):
        ca, cb = a.get(op, 0), b.get(op, 0)
        per_step = (cb - ca) / k
        const = ca - k * per_step
        v = int(round(const + per_step * n_steps))
        if v > 0:
            out[op] = v
    order = OPS + CODE_OPS
    return {op: out[op] for op in sorted(out, key=lambda o: (order.index(o) if o in order else 99, o))}
