"""A model's vectorised ``transition`` / ``log_likelihood`` traced into per-particle C statements.

The fused CuPy model step (:mod:`pfbench.backends.cupy_backend`) runs the model's own functions
as one GPU kernel: :func:`trace` calls a function once on symbolic arguments (:class:`Sym`)
that record every arithmetic operator and NumPy ufunc as a line of C (``double v3 = (v1 * v2);``),
following NumPy's broadcasting over the particle axis. What a model may use: arithmetic,
the ufuncs of :data:`UFUNCS`, columns ``x[:, k]`` and column ranges, ``np.stack(..., axis=1)``,
``np.column_stack``, ``np.concatenate(..., axis=1)``, ``np.empty_like``/``np.zeros_like`` with
column assignments, ``np.ascontiguousarray``, ``np.sum(..., axis=1)``, and scalars (the
parameters ``p``, ``t``, ``y[k]``, ``u[k]``). Anything else (``@``, loops over particles, arrays
made with ``np.zeros(n)``) raises :class:`TraceError`, and the caller runs the function through
the array namespace instead (unfused, still on the GPU). Tracing runs on the CPU, so the CPU
tests check the generated statements (:func:`evaluate` runs them with NumPy).
"""
from __future__ import annotations

import math
import numbers

import numpy as np


class TraceError(Exception):
    """The function uses something the tracer does not turn into C."""


#: NumPy ufunc name -> (C function, number of arguments)
UFUNCS = {"exp": ("exp", 1), "log": ("log", 1), "log1p": ("log1p", 1), "expm1": ("expm1", 1),
          "sqrt": ("sqrt", 1), "cbrt": ("cbrt", 1), "cos": ("cos", 1), "sin": ("sin", 1),
          "tan": ("tan", 1), "arctan": ("atan", 1), "arcsin": ("asin", 1), "arccos": ("acos", 1),
          "tanh": ("tanh", 1), "sinh": ("sinh", 1), "cosh": ("cosh", 1), "absolute": ("fabs", 1),
          "fabs": ("fabs", 1), "floor": ("floor", 1), "ceil": ("ceil", 1),
          "arctan2": ("atan2", 2), "power": ("pow", 2), "maximum": ("fmax", 2),
          "minimum": ("fmin", 2), "fmax": ("fmax", 2), "fmin": ("fmin", 2), "hypot": ("hypot", 2)}
_BINARY = {"add": "+", "subtract": "-", "multiply": "*", "divide": "/", "true_divide": "/"}


class Tape:
    """The C statements of one traced function (names ``<prefix><k>``)."""

    def __init__(self, prefix: str):
        self.prefix, self.lines = prefix, []

    def emit(self, expr: str) -> str:
        name = f"{self.prefix}{len(self.lines)}"
        self.lines.append(f"double {name} = {expr};")
        return name


def const(v) -> str:
    """A number as a C double literal (round-trip exact)."""
    if isinstance(v, (bool, np.bool_)):
        raise TraceError("booleans are not traced")
    v = float(v)
    if math.isnan(v):
        return "(0.0 / 0.0)"
    if math.isinf(v):
        return "(1.0 / 0.0)" if v > 0 else "(-1.0 / 0.0)"
    return f"({v!r})"


class Sym:
    """A traced value: ``ndim`` 0 (a scalar: t, y[k], u[k] and what comes of them), 1 (one value
    per particle, shape (n,)) or 2 (``len(cols)`` values per particle, shape (n, k)); ``cols``
    holds the C expression (a name or literal) of each column."""

    __array_priority__ = 1000

    def __init__(self, tape: Tape, cols, ndim: int):
        self.tape, self.cols, self.ndim = tape, list(cols), ndim

    # ----- shape
    @property
    def shape(self):
        return {0: (), 1: (0,), 2: (0, len(self.cols))}[self.ndim]  # n reads 0: nothing is sized by it

    def __array__(self, *a, **k):
        raise TraceError("a traced value was converted to a NumPy array")

    def __len__(self):
        raise TraceError("len() of a traced value")

    def __bool__(self):
        raise TraceError("a traced value decides a branch")

    # ----- indexing
    def __getitem__(self, key):
        if self.ndim == 2 and isinstance(key, tuple) and len(key) == 2 and key[0] == slice(None):
            k = key[1]
            if isinstance(k, numbers.Integral):
                return Sym(self.tape, [self.cols[int(k)]], 1)
            if isinstance(k, slice):
                return Sym(self.tape, self.cols[k], 2)
        raise TraceError(f"indexing {key!r}")

    def __setitem__(self, key, value):
        if self.ndim == 2 and isinstance(key, tuple) and len(key) == 2 and key[0] == slice(None) \
                and isinstance(key[1], numbers.Integral):
            v = _lift(self.tape, value)
            if v.ndim == 2:
                if len(v.cols) != 1:
                    raise TraceError("assigning several columns to one")
            self.cols[int(key[1])] = v.cols[0]
            return
        raise TraceError(f"assignment to {key!r}")

    # ----- arithmetic
    def _bin(self, other, op, reverse=False):
        a, b = (_lift(self.tape, other), self) if reverse else (self, _lift(self.tape, other))
        return _binary(self.tape, a, b, lambda x, y: f"({x} {op} {y})")

    def __add__(self, o): return self._bin(o, "+")
    def __radd__(self, o): return self._bin(o, "+", True)
    def __sub__(self, o): return self._bin(o, "-")
    def __rsub__(self, o): return self._bin(o, "-", True)
    def __mul__(self, o): return self._bin(o, "*")
    def __rmul__(self, o): return self._bin(o, "*", True)
    def __truediv__(self, o): return self._bin(o, "/")
    def __rtruediv__(self, o): return self._bin(o, "/", True)

    def __pow__(self, o):
        return _power(self.tape, self, _lift(self.tape, o))

    def __rpow__(self, o):
        return _power(self.tape, _lift(self.tape, o), self)

    def __neg__(self):
        return _unary(self.tape, self, lambda x: f"(-{x})")

    def __pos__(self):
        return self

    def __abs__(self):
        return _unary(self.tape, self, lambda x: f"fabs({x})")

    def __matmul__(self, o):
        raise TraceError("matrix product")

    __rmatmul__ = __matmul__

    # ----- NumPy protocols
    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        if method != "__call__" or kwargs:
            raise TraceError(f"np.{ufunc.__name__}.{method} with {sorted(kwargs)}")
        args = [_lift(self.tape, v) for v in inputs]
        name = ufunc.__name__
        if name in _BINARY:
            op = _BINARY[name]
            return _binary(self.tape, args[0], args[1], lambda x, y: f"({x} {op} {y})")
        if name == "negative":
            return -args[0]
        if name == "square":
            return _unary(self.tape, args[0], lambda x: f"({x} * {x})")
        if name == "reciprocal":
            return _unary(self.tape, args[0], lambda x: f"(1.0 / {x})")
        if name == "power":
            return _power(self.tape, args[0], args[1])
        if name not in UFUNCS:
            raise TraceError(f"np.{name}")
        fn, nargs = UFUNCS[name]
        if nargs == 1:
            return _unary(self.tape, args[0], lambda x: f"{fn}({x})")
        return _binary(self.tape, args[0], args[1], lambda x, y: f"{fn}({x}, {y})")

    def __array_function__(self, func, types, args, kwargs):
        name = func.__name__
        if name == "ascontiguousarray" and not kwargs.get("dtype"):
            return args[0]
        if name in ("empty_like", "zeros_like") and set(kwargs) <= {"dtype"} and len(args) == 1:
            src = args[0]
            return Sym(self.tape, [const(0.0)] * len(src.cols), src.ndim)
        if name in ("stack", "column_stack", "concatenate"):
            axis = kwargs.get("axis", args[1] if len(args) > 1 else (1 if name == "column_stack" else 0))
            parts = [_lift(self.tape, v) for v in args[0]]
            if name == "stack" and axis in (1, -1) and all(v.ndim == 1 for v in parts):
                return Sym(self.tape, [v.cols[0] for v in parts], 2)
            if name == "column_stack" and all(v.ndim in (1, 2) for v in parts):
                return Sym(self.tape, [c for v in parts for c in v.cols], 2)
            if name == "concatenate" and axis in (1, -1) and all(v.ndim == 2 for v in parts):
                return Sym(self.tape, [c for v in parts for c in v.cols], 2)
        if name == "sum" and len(args) == 1 and kwargs.get("axis") in (1, -1) and args[0].ndim == 2:
            cols = args[0].cols
            return Sym(self.tape, [self.tape.emit("(" + " + ".join(cols) + ")")], 1)
        raise TraceError(f"np.{name}")


class Vector:
    """A measurement or input row (y_t, u_t): ``shape`` and scalar items ``v[k]`` only."""

    def __init__(self, tape: Tape, names):
        self.tape, self.names = tape, list(names)

    @property
    def shape(self):
        return (len(self.names),)

    def __getitem__(self, k):
        if isinstance(k, numbers.Integral):
            return Sym(self.tape, [self.names[int(k)]], 0)
        raise TraceError(f"indexing a row with {k!r}")

    def __array__(self, *a, **k):
        raise TraceError("a measurement/input row used as an array")


def _lift(tape, v) -> Sym:
    if isinstance(v, Sym):
        return v
    if isinstance(v, (numbers.Real, np.floating, np.integer)) or (isinstance(v, np.ndarray) and v.ndim == 0):
        return Sym(tape, [const(v)], 0)
    raise TraceError(f"an operand of type {type(v).__name__}")


def _width(a: Sym, b: Sym) -> tuple[int, int]:
    """The result's ndim and column count under NumPy broadcasting on the particle axis."""
    if a.ndim == 2 and b.ndim == 2:
        ka, kb = len(a.cols), len(b.cols)
        if ka != kb and 1 not in (ka, kb):
            raise TraceError(f"broadcast of (n, {ka}) with (n, {kb})")
        return 2, max(ka, kb)
    if 2 in (a.ndim, b.ndim) and 1 in (a.ndim, b.ndim):
        raise TraceError("broadcast of (n, k) with (n,): (n, n) in NumPy, surely not meant")
    nd = max(a.ndim, b.ndim)
    return nd, len(a.cols) if a.ndim == nd else len(b.cols)


def _col(s: Sym, j: int) -> str:
    return s.cols[0] if len(s.cols) == 1 else s.cols[j]


def _binary(tape, a: Sym, b: Sym, fmt) -> Sym:
    nd, k = _width(a, b)
    return Sym(tape, [tape.emit(fmt(_col(a, j), _col(b, j))) for j in range(k)], nd)


def _unary(tape, a: Sym, fmt) -> Sym:
    return Sym(tape, [tape.emit(fmt(c)) for c in a.cols], a.ndim)


def _power(tape, a: Sym, b: Sym) -> Sym:
    if b.ndim == 0 and b.cols[0] in ("(2.0)", "(2)"):  # x ** 2 is NumPy's exact square
        return _unary(tape, a, lambda x: f"({x} * {x})")
    return _binary(tape, a, b, lambda x, y: f"pow({x}, {y})")


def trace(fn, kind: str, *, n_x: int, n_y: int, n_u: int, n_noise: int, p, prefix: str,
          x_names, z_names=None, t_name="t", y_names=None, u_names=None) -> tuple[list[str], list[str]]:
    """Trace ``fn`` (``kind`` ``"transition"`` or ``"log_likelihood"``) on symbolic particles.

    ``x_names`` (n_x) / ``z_names`` (n_noise) name the C variables of one particle's state and
    noise, ``t_name`` the step and ``y_names``/``u_names`` the rows' items. Returns (statements,
    output expressions): n_x outputs for a transition, 1 for a log-likelihood. Raises
    :class:`TraceError` if the function leaves what the tracer can follow.
    """
    tape = Tape(prefix)
    x = Sym(tape, x_names, 2)
    u = Vector(tape, u_names if u_names is not None else [f"u_{k}" for k in range(n_u)])
    t = Sym(tape, [t_name], 0)
    try:
        with np.errstate(all="ignore"):
            if kind == "transition":
                out = fn(x, u, t, Sym(tape, z_names, 2), p)
            else:
                out = fn(Vector(tape, y_names), x, u, t, p)
    except TraceError:
        raise
    except Exception as exc:  # noqa: BLE001 - anything the model did that symbols cannot do
        raise TraceError(f"{type(exc).__name__}: {exc}") from None
    if not isinstance(out, Sym):
        raise TraceError(f"returned {type(out).__name__}, not a traced array")
    if kind == "transition":
        if not ((out.ndim == 2 and len(out.cols) == n_x) or (n_x == 1 and out.ndim in (1, 2) and len(out.cols) == 1)):
            raise TraceError(f"returned shape {out.shape}, not (n, {n_x})")
    elif out.ndim == 2 or len(out.cols) != 1:
        raise TraceError(f"returned shape {out.shape}, not (n,)")
    return tape.lines, out.cols


def evaluate(lines, outputs, env: dict) -> list:
    """Run traced statements with NumPy (the CPU check of :func:`trace`): ``env`` maps the input
    names to arrays or numbers; returns the output expressions' values."""
    import re

    ns = {"exp": np.exp, "log": np.log, "log1p": np.log1p, "expm1": np.expm1, "sqrt": np.sqrt,
          "cbrt": np.cbrt, "cos": np.cos, "sin": np.sin, "tan": np.tan, "atan": np.arctan,
          "asin": np.arcsin, "acos": np.arccos, "tanh": np.tanh, "sinh": np.sinh, "cosh": np.cosh,
          "fabs": np.abs, "floor": np.floor, "ceil": np.ceil, "atan2": np.arctan2, "pow": np.power,
          "fmax": np.fmax, "fmin": np.fmin, "hypot": np.hypot, **env}
    with np.errstate(all="ignore"):
        for line in lines:
            m = re.fullmatch(r"double (\w+) = (.*);", line)
            ns[m.group(1)] = eval(m.group(2), {"__builtins__": {}}, ns)  # noqa: S307 - our own lines
        return [eval(o, {"__builtins__": {}}, ns) for o in outputs]  # noqa: S307
