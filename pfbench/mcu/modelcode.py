"""A registered model's own code, compiled for a Cortex-M microcontroller.

The numba backend compiles a model's ``transition`` and ``log_likelihood`` staticmethods for the
host. This module compiles **the same Python source** for the target instead and wraps each in the
C ABI of ``pfbench/mcu/c/pf_model.h`` (``pfm_transition``, ``pfm_log_likelihood`` over a tile of
``n`` particles), so the generic C filter harness can call a model nobody ported to C by hand.

How (all with the tools the numba backend already depends on):

1. A worker process (``python -m pfbench.mcu.modelcode --worker JOB``) compiles, with numba, one
   small wrapper per function, e.g. for the transition::

       def wrapper(x_p, n, u_p, t, noise_p, out_p):     # void(real*, int32, real*, int32, real*, real*)
           x = carray(x_p, (n, N_X)); u = carray(u_p, (N_U,)); noise = carray(noise_p, (n, N_NOISE))
           r = model_transition(x, u, np.int64(t), noise, P)   # P: the params() tuple, frozen
           out = carray(out_p, (n, N_X)); out[i, j] = r[i, j] for every i, j

   with numba's LLVM optimisation switched off, so the IR is captured before any host-specific
   pass (x86 struct offsets, 64-bit atomics and vector widths would otherwise be baked in).
2. The IR is retargeted with llvmlite: triple ``thumbv7em-unknown-none-eabihf`` (the 3-part
   ``thumbv7em-none-eabihf`` silently gives the soft-float ABI), the ARM data layout, the host's
   ``target-cpu``/``target-features``/``tune-cpu`` attributes stripped, functions ``nounwind``;
   everything but the two C-ABI entry points is internalised, atomics are lowered to plain
   loads/stores (one thread, no interrupt touches a model's arrays: see ``c/nrt_shim.c``), and the
   module is optimised by LLVM's pass builder for the target machine as numba does for the host
   (O2, numba's reference-count pruning pass, O3), then emitted as an ELF object. Cores:
   :data:`CPUS` (the Cortex-M4F is the reference; M0+, M3, M33 and M7 also compile).
3. A model function that allocates arrays (every model here returns a new array) calls numba's
   runtime (NRT) allocator: ``c/nrt_shim.c`` implements those calls on newlib's ``malloc``; link
   it when :attr:`ModelObject.needs_nrt` (freed temporaries go on a free list and are reused,
   not returned to malloc). Matrix products (``@``, ``np.dot``) call numba's BLAS entry points:
   these are compiled INTO the model module (:data:`_BLAS`, numba-compiled loops) so LLVM
   inlines and specialises them per call site.

Precision. ``precision="double"`` compiles the source as it is. ``precision="float"`` compiles a
float32 rewrite of the source (and of the helpers it calls): float literals, ``np.pi``/``np.e``
and module-level float constants become float32 constants, integer literals in arithmetic become
float32 (not indices, shapes, ``range`` bounds or exponents), ``np.zeros/ones/empty/full/eye``
get ``dtype=np.float32``, every arithmetic result passes a float64 -> float32 narrowing ufunc
(:func:`_narrow`), ``np.cbrt`` becomes C's ``cbrtf``, and the parameters and inputs are
float32. Whatever still runs in double
(e.g. ``np.cos(1.2 * t)`` with the integer step ``t``: once per tile, not per particle) is counted
in :attr:`ModelObject.double_ops` / :attr:`ModelObject.double_loop_ops` (on a single-precision M4F
every double operation is a soft-float library call). The rules a model must follow are in
``docs/MCU_MODELS.md``.

Errors. What cannot be compiled (a construct numba rejects, a call into the Python C API, a numba
runtime helper that does not exist on the MCU, a model defined outside a ``.py`` file) is ONE
:class:`~pfbench.errors.UnsupportedError` line naming the model function and the construct. A
model that raises inside (numba's static exceptions, e.g. a shape mismatch) returns normally on the
target with the global ``int32_t pfm_status`` set to numba's non-zero status code (0 = success).

Results are cached under ``toolchain.cache_root() / "models" / <hash>``; the hash covers the whole
pfbench package source, the model's module source, its parameters, precision, cpu and the
llvmlite/numba versions, so a second call costs only the hash.
"""
from __future__ import annotations

import ast
import hashlib
import inspect
import json
import os
import pickle
import re
import subprocess
import sys
import textwrap
import types as _pytypes
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError, PfbenchError, UnsupportedError
from . import cores, toolchain

C_DIR = Path(__file__).resolve().parent / "c"
SHIM = C_DIR / "nrt_shim.c"
PRECISIONS = ("float", "double")

#: cpu -> LLVM target (triple, cpu, features) and the matching arm-none-eabi-gcc flags of the
#: model object (its unicorn CPU model is the core's, :mod:`pfbench.mcu.cores`). The 4-part "-unknown-" triples matter: "thumbv7em-none-eabihf" silently
#: gives the soft-float ABI. No FPU on the M0+ and M3 (soft-float ABI, float and double both in
#: libgcc); single-precision FPU on the M4F (fpv4-sp-d16) and M33 (fpv5-sp-d16); double-precision
#: FPU on the M7 (fpv5-d16).
CPUS = {
    "cortex-m4": {
        "triple": "thumbv7em-unknown-none-eabihf", "cpu": "cortex-m4",
        "features": "+vfp4d16sp,+thumb-mode",
        "gcc": ("-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16"),
    },
    "cortex-m0plus": {
        "triple": "thumbv6m-unknown-none-eabi", "cpu": "cortex-m0plus", "features": "+thumb-mode",
        "gcc": ("-mcpu=cortex-m0plus", "-mthumb", "-mfloat-abi=soft"),
    },
    "cortex-m3": {
        "triple": "thumbv7m-unknown-none-eabi", "cpu": "cortex-m3", "features": "+thumb-mode",
        "gcc": ("-mcpu=cortex-m3", "-mthumb", "-mfloat-abi=soft"),
    },
    "cortex-m7": {
        "triple": "thumbv7em-unknown-none-eabihf", "cpu": "cortex-m7",
        "features": "+fp-armv8d16,+thumb-mode",
        "gcc": ("-mcpu=cortex-m7", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv5-d16"),
    },
    "cortex-m33": {
        "triple": "thumbv8m.main-unknown-none-eabihf", "cpu": "cortex-m33",
        "features": "+fp-armv8d16sp,+thumb-mode",
        "gcc": ("-mcpu=cortex-m33", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv5-sp-d16"),
    },
}

#: model function -> (C entry point, C argument kinds in order). "x"/"noise"/"out"/... are real
#: pointers, "n"/"t" int32.
FUNCTIONS = {
    "transition": ("pfm_transition", ("x", "n", "u", "t", "noise", "out")),
    "log_likelihood": ("pfm_log_likelihood", ("y", "x", "n", "u", "t", "out")),
}

#: external symbols an object may reference: newlib's libm/libc, libgcc, and c/nrt_shim.c
SHIM_SYMBOLS = frozenset({
    "NRT_MemInfo_alloc_aligned", "NRT_MemInfo_alloc_safe_aligned", "NRT_MemInfo_call_dtor",
    "NRT_Allocate", "NRT_Free", "NRT_MemInfo_alloc", "NRT_MemInfo_alloc_safe",
})
_LIBM = ("sin cos tan asin acos atan atan2 sinh cosh tanh asinh acosh atanh exp exp2 expm1 log "
         "log2 log10 log1p pow sqrt cbrt hypot fabs floor ceil trunc round rint nearbyint fmod "
         "copysign fmin fmax erf erfc lgamma tgamma ldexp frexp modf").split()
LIBC_SYMBOLS = frozenset(_LIBM + [f + "f" for f in _LIBM] + ["memcpy", "memmove", "memset",
                                                               "memcmp", "malloc", "free", "abort"])
_DOUBLE_LIBM = frozenset(_LIBM)

_WORKER_TIMEOUT_S = 600


@dataclass(frozen=True)
class ModelObject:
    """A model's ``transition``/``log_likelihood`` compiled for one MCU (see the module docstring).

    ``double_ops``: per C entry point, the static count of double-precision FP instructions and
    double libm calls in the final (optimised, target) IR including inlined/called helpers
    (fadd/fsub/fmul/fdiv/frem/fneg/fcmp on double, fpext/fptrunc and int<->double conversions,
    calls such as ``cos``/``llvm.cos.f64``); ``double_loop_ops``: the part of it inside loops (the
    per-particle work; the rest runs once per call, i.e. per tile).
    """

    model: str
    precision: str
    cpu: str
    obj: Path
    n_x: int
    n_y: int
    n_u: int
    n_noise: int
    defines: tuple
    needs_nrt: bool
    double_ops: dict
    double_loop_ops: dict = field(default_factory=dict)
    ir: Path | None = None            # the optimised target IR (for inspection)
    notes: tuple = ()                 # what the float rewrite could not do, etc.
    undefined: tuple = ()             # external symbols the object references

    @property
    def gcc_flags(self) -> tuple:
        """The arm-none-eabi-gcc CPU/ABI flags matching the object."""
        return CPUS[self.cpu]["gcc"]


# ---------------------------------------------------------------------------------------------
# the public entry point (parent process)
# ---------------------------------------------------------------------------------------------
def _resolve(spec, params):
    from ..models import StateSpaceModel, get_spec

    if isinstance(spec, StateSpaceModel):
        if params:
            raise InputError("params are only taken with a model spec string, not an instance")
        return spec, spec.name or type(spec).__name__
    if not isinstance(spec, str):
        raise InputError(f"model must be a registry spec string or a StateSpaceModel, got {spec!r}")
    return get_spec(spec, **dict(params or {})), spec.strip()


def _model_source(cls) -> tuple[str, str | None]:
    """(source text used for the cache key, the .py file the worker imports it from)."""
    mod = sys.modules.get(cls.__module__)
    path = getattr(mod, "__file__", None)
    if not path or not str(path).endswith(".py") or not os.path.exists(path):
        raise UnsupportedError(
            f"model class {cls.__qualname__!r} is not defined in a .py file (module "
            f"{cls.__module__!r}); put it in a module to compile it for the MCU")
    return Path(path).read_text(), str(path)


def _freeze(p) -> bytes:
    """Deterministic bytes of a params() tuple for the cache key."""
    out = []
    for v in p:
        if isinstance(v, np.ndarray):
            out.append(f"a{v.dtype.str}{v.shape}".encode() + np.ascontiguousarray(v).tobytes())
        elif isinstance(v, tuple):
            out.append(b"(" + _freeze(v) + b")")
        else:
            out.append(f"{type(v).__name__}:{v!r}".encode())
    return b"|".join(out)


def cache_dir() -> Path:
    return (toolchain.cache_root() / "models").resolve()


def compile_model(spec, precision: str = "float", cpu: str = "cortex-m4",
                  params: dict | None = None) -> ModelObject:
    """Compile a model's ``transition`` and ``log_likelihood`` for ``cpu`` (cached on disk).

    Parameters
    ----------
    spec : registry spec (``"ob1"``, ``"ob3:v4"``) or a :class:`~pfbench.models.StateSpaceModel`
        instance (its class must live in a ``.py`` file).
    precision : ``"float"`` (float32 rewrite, single-precision FPU) or ``"double"``.
    cpu : ``"cortex-m4"``.
    params : model parameters as :func:`pfbench.models.parse_spec` takes them.
    """
    import llvmlite
    import numba

    from ..backends.cache import package_fingerprint

    if precision not in PRECISIONS:
        raise InputError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    if cpu not in CPUS:
        raise InputError(f"cpu must be one of {', '.join(CPUS)}, got {cpu!r}")
    model, label = _resolve(spec, params)
    cls = type(model)
    source, path = _model_source(cls)
    p = tuple(model.params())
    dims = {k: int(getattr(model, k)) for k in ("n_x", "n_y", "n_u", "n_noise")}
    h = hashlib.sha256()
    for part in (package_fingerprint(), source, cls.__module__, cls.__qualname__, precision, cpu,
                 json.dumps(dims, sort_keys=True), llvmlite.__version__, numba.__version__,
                 Path(__file__).read_text()):
        h.update(part.encode() + b"\0")
    h.update(_freeze(p))
    out = cache_dir() / h.hexdigest()[:20]

    def make(tmp):
        job = {"module": cls.__module__, "qualname": cls.__qualname__, "file": path, "params": p,
               "dims": dims, "precision": precision, "cpu": cpu, "label": label, "out": str(tmp)}
        with open(tmp / "job.pkl", "wb") as f:
            pickle.dump(job, f)
        _run_worker(tmp / "job.pkl")
        res = json.loads((tmp / "result.json").read_text())
        if "error" in res:
            raise UnsupportedError(res["error"])
        (tmp / "job.pkl").unlink()
        (tmp / "result.json").replace(tmp / "meta.json")

    meta_path = toolchain.cached(out, ("meta.json", "model.o", "model.ll"), make)["meta.json"]
    meta = json.loads(meta_path.read_text())
    defines = tuple(toolchain.dims_flags(**dims)) + (("-DPF_FLOAT",) if precision == "float" else ())
    return ModelObject(model=label, precision=precision, cpu=cpu, obj=out / "model.o",
                       defines=defines, needs_nrt=bool(meta["needs_nrt"]),
                       double_ops=meta["double_ops"], double_loop_ops=meta["double_loop_ops"],
                       ir=out / "model.ll", notes=tuple(meta["notes"]),
                       undefined=tuple(meta["undefined"]), **dims)


def _run_worker(job: Path) -> None:
    env = dict(os.environ)
    scratch = job.parent / "scratch"
    # a private, empty numba/pfbench cache: no optimised host code may be loaded into the worker
    env["NUMBA_CACHE_DIR"] = str(scratch / "numba")
    env["PFBENCH_CACHE_DIR"] = str(scratch / "pfbench")
    env.pop("NUMBA_DISABLE_JIT", None)
    root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    try:
        res = subprocess.run([sys.executable, "-m", "pfbench.mcu.modelcode", "--worker", str(job)],
                             env=env, capture_output=True, text=True, timeout=_WORKER_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise PfbenchError(f"compiling the model for the MCU took over {_WORKER_TIMEOUT_S} s") from None
    if res.returncode != 0 or not (job.parent / "result.json").exists():
        tail = (res.stderr or res.stdout).strip().splitlines()[-1:] or ["(no output)"]
        raise PfbenchError(f"model compile worker failed: {tail[0]}")


# ---------------------------------------------------------------------------------------------
# float32 rewrite of a model function's source
# ---------------------------------------------------------------------------------------------
_ARRAY_CTORS = {"zeros": 1, "ones": 1, "empty": 1, "full": 2, "eye": 1, "identity": 1}
_SHAPE_FUNCS = {"range", "reshape", "zeros", "ones", "empty", "full", "eye", "identity", "arange",
                "zeros_like", "empty_like", "ones_like", "full_like", "int", "len", "int64",
                "int32", "intp", "ix_", "repeat", "tile", "transpose", "swapaxes", "sum", "mean",
                "prod", "argmax", "argmin", "take"}


def _cbrtf_ufunc():
    """``np.cbrt`` for float32 as C's ``cbrtf`` (numba implements ``np.cbrt`` as a double
    ``pow``): a ufunc over the C library function, so it fuses into array expressions and the
    target calls newlib's ``cbrtf``, as a C port of the model would."""
    import numba
    from numba import types

    cbrtf = types.ExternalFunction("cbrtf", types.float32(types.float32))

    @numba.vectorize([types.float32(types.float32)])
    def cbrt_f32(v):
        return cbrtf(v)

    return cbrt_f32


#: NumPy functions that numba computes in double even for float32 arguments: builders of their
#: float32 replacements in the float rewrite
_FLOAT_FUNCS = {"cbrt": _cbrtf_ufunc}
_FLOAT_JIT: dict = {}


def _njit_float_func(name):
    if name not in _FLOAT_JIT:
        _FLOAT_JIT[name] = _FLOAT_FUNCS[name]()
    return _FLOAT_JIT[name]


class _Float32Rewriter(ast.NodeTransformer):
    """Rewrite a function so its float arithmetic stays float32 (see the module docstring)."""

    def __init__(self, namespace: dict, local_names: set, convert_ints: bool, narrow: bool = True):
        self.ns = namespace
        self.locals = local_names
        self.convert_ints = convert_ints
        self.narrow = narrow
        self.protect = 0

    def _const(self, value) -> ast.Name:
        name = f"_pfm_f32_{len([k for k in self.ns if k.startswith('_pfm_f32_')])}"
        self.ns[name] = np.float32(value)
        return ast.Name(id=name, ctx=ast.Load())

    def _float_value(self, node):
        """The float a Name/Attribute chain resolves to in the function's globals, else None."""
        parts = []
        while isinstance(node, ast.Attribute):
            parts.append(node.attr)
            node = node.value
        if not isinstance(node, ast.Name) or node.id in self.locals or node.id not in self.ns:
            return None
        obj = self.ns[node.id]
        for a in reversed(parts):
            obj = getattr(obj, a, None)
        if type(obj) in (float, np.float64):
            return float(obj)
        return None

    def visit_Constant(self, node):
        if not self.protect and type(node.value) is float:
            return ast.copy_location(self._const(node.value), node)
        return node

    def _global_float(self, node):
        """A float global (``np.pi``, a module constant) read by ``node`` as a float32 constant,
        else None."""
        if isinstance(node.ctx, ast.Load) and not self.protect:
            v = self._float_value(node)
            if v is not None:
                return ast.copy_location(self._const(v), node)
        return None

    def visit_Name(self, node):
        return self._global_float(node) or node

    def visit_Attribute(self, node):
        const = self._global_float(node)
        if const is not None:
            return const
        self.generic_visit(node)
        return node

    def _protected(self, node):
        self.protect += 1
        try:
            return self.visit(node)
        finally:
            self.protect -= 1

    def visit_Subscript(self, node):
        node.value = self.visit(node.value)
        node.slice = self._protected(node.slice)
        return node

    def _narrow(self, node):
        """``_pfm_narrow(node)``: a float64 scalar result becomes float32 (see :func:`_narrow`)."""
        if self.protect or not self.narrow:
            return node
        return ast.copy_location(ast.Call(func=ast.Name("_pfm_narrow", ast.Load()), args=[node],
                                          keywords=[]), node)

    def visit_BinOp(self, node):
        if isinstance(node.op, ast.Pow):
            node.left = self.visit(node.left)
            node.right = self._protected(node.right)
            return self._narrow(node)
        arith = isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div))
        if self.convert_ints and arith and not self.protect:
            def is_int(n):
                return isinstance(n, ast.Constant) and type(n.value) is int
            if is_int(node.left) and not is_int(node.right):
                node.left = ast.copy_location(self._const(node.left.value), node.left)
            if is_int(node.right) and not is_int(node.left):
                node.right = ast.copy_location(self._const(node.right.value), node.right)
        self.generic_visit(node)
        return self._narrow(node) if arith else node

    def visit_Call(self, node):
        fname = node.func.attr if isinstance(node.func, ast.Attribute) else (
            node.func.id if isinstance(node.func, ast.Name) else None)
        if fname in _FLOAT_FUNCS and isinstance(node.func, ast.Attribute) and \
                getattr(self.ns.get(getattr(node.func.value, "id", "")), "__name__", "") == "numpy":
            self.ns[f"_pfm_{fname}"] = _njit_float_func(fname)
            node.func = ast.copy_location(ast.Name(f"_pfm_{fname}", ast.Load()), node.func)
        node.func = self.visit(node.func)
        if fname in _ARRAY_CTORS and isinstance(node.func, ast.Attribute) and \
                not any(k.arg == "dtype" for k in node.keywords) and \
                len(node.args) <= _ARRAY_CTORS[fname]:
            self.ns["_pfm_float32"] = np.float32
            node.keywords.append(ast.keyword(arg="dtype", value=ast.Name("_pfm_float32", ast.Load())))
        if fname in _SHAPE_FUNCS:
            if fname == "full" and len(node.args) >= 2:  # np.full(shape, FILL): fill is a value
                node.args = [self._protected(node.args[0]), self.visit(node.args[1])] + \
                    [self._protected(a) for a in node.args[2:]]
            else:
                node.args = [self._protected(a) for a in node.args]
        else:
            node.args = [self.visit(a) for a in node.args]
        for k in node.keywords:
            k.value = self._protected(k.value) if k.arg in ("axis", "shape", "dtype") else self.visit(k.value)
        base = node.func.value if isinstance(node.func, ast.Attribute) else None
        if isinstance(base, ast.Name) and base.id not in self.locals and \
                getattr(self.ns.get(base.id), "__name__", "") in ("numpy", "math") and \
                fname not in _SHAPE_FUNCS and fname not in _ARRAY_CTORS:
            return self._narrow(node)  # np.cos(...), math.exp(...): float64 scalar -> float32
        return node


def _narrow(v):
    """The float rewrite wraps every arithmetic result and NumPy/math call in this (compiled as
    the ufunc of :func:`_narrow_ufunc`): a float64 value becomes float32, integers and float32
    pass unchanged. A float64 scalar appears anyway in float code (``1.2 * t`` with the integer
    step ``t``: numba types int64 * float32 as float64) and would otherwise promote every array it
    meets to float64 (a float32 array plus a float64 scalar is a float64 array in numba). Being a
    ufunc, it fuses into numba's array expressions (no extra temporaries or loops)."""
    return v


_NARROW: list = []


def _narrow_ufunc():
    if not _NARROW:
        import numba

        _NARROW.append(numba.vectorize(["b1(b1)", "i4(i4)", "i8(i8)", "f4(f4)", "f4(f8)"],
                                       nopython=True)(_narrow))
    return _NARROW[0]


def _local_names(fdef: ast.FunctionDef) -> set:
    names = {a.arg for a in fdef.args.args + fdef.args.kwonlyargs}
    for node in ast.walk(fdef):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
    return names


def _helper_python_function(obj):
    """The Python function behind a model helper (register_jitable function, njit dispatcher)."""
    if isinstance(obj, _pytypes.FunctionType):
        return obj
    py = getattr(obj, "py_func", None)
    return py if isinstance(py, _pytypes.FunctionType) else None


def _is_helper(obj, model_file: str) -> bool:
    """Functions of pfbench or of the model's own file that the rewrite follows."""
    fn = _helper_python_function(obj)
    if fn is None:
        return False
    try:
        src = inspect.getsourcefile(fn) or ""
    except TypeError:
        return False
    pkg = str(Path(__file__).resolve().parents[1])
    return src == model_file or src.startswith(pkg + os.sep)


def float32_source(func, model_file: str, convert_ints: bool = True, narrow: bool = True,
                   _done=None):
    """The float32 rewrite of ``func`` as a new Python function (helpers njit'ed and rewritten too).

    Returns (function, notes).
    """
    import numba

    done = {} if _done is None else _done
    if func in done:
        return done[func], []
    src = textwrap.dedent(inspect.getsource(func))
    tree = ast.parse(src)
    fdef = tree.body[0]
    if not isinstance(fdef, ast.FunctionDef):
        raise UnsupportedError(f"cannot read the source of {func.__qualname__}")
    if func.__code__.co_freevars:
        raise UnsupportedError(f"{func.__qualname__} uses closure variables "
                               f"{', '.join(func.__code__.co_freevars)}: pass them in params()")
    fdef.decorator_list = []
    ns = dict(func.__globals__)
    ns["_pfm_narrow"] = _narrow_ufunc() if narrow else _narrow
    notes = []
    # helpers first: rewrite each referenced helper and bind its njit'ed rewrite under its name
    for node in ast.walk(fdef):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load) and node.id in ns \
                and node.id not in _local_names(fdef) and _is_helper(ns[node.id], model_file):
            hf = _helper_python_function(ns[node.id])
            sub, n2 = float32_source(hf, model_file, convert_ints, narrow, done)
            notes += n2
            ns[node.id] = numba.njit(sub)
    rw = _Float32Rewriter(ns, _local_names(fdef), convert_ints, narrow)
    fdef = rw.visit(fdef)
    ast.fix_missing_locations(tree)
    code = compile(tree, filename=f"<float32 rewrite of {func.__qualname__}>", mode="exec")
    exec(code, ns)
    new = ns[fdef.name]
    done[func] = new
    return new, notes


# ---------------------------------------------------------------------------------------------
# the worker (a fresh process: numba's optimiser switched off before anything compiles)
# ---------------------------------------------------------------------------------------------
def _summarise(exc: BaseException) -> str:
    text = re.sub(r"\x1b\[[0-9;]*m", "", str(exc))
    for line in text.splitlines():
        s = line.strip()
        if s and not s.startswith(("Failed in", "During:", "File ", "^", "- ", "Resolution failure")):
            return s.rstrip(".:")
    return type(exc).__name__


def _wrapper_source(fn_name: str, dims: dict) -> str:
    nx, ny, nu, nz = dims["n_x"], dims["n_y"], dims["n_u"], dims["n_noise"]
    if fn_name == "transition":
        return textwrap.dedent(f"""
            def _pfm_wrapper(x_p, n, u_p, t, noise_p, out_p):
                x = carray(x_p, (n, {nx}))
                u = carray(u_p, ({nu},))
                noise = carray(noise_p, (n, {nz}))
                r = _pfm_model(x, u, np.int64(t), noise, _pfm_p)
                out = carray(out_p, (n, {nx}))
                for i in range(n):
                    for j in range({nx}):
                        out[i, j] = r[i, j]
            """)
    return textwrap.dedent(f"""
        def _pfm_wrapper(y_p, x_p, n, u_p, t, out_p):
            y = carray(y_p, ({ny},))
            x = carray(x_p, (n, {nx}))
            u = carray(u_p, ({nu},))
            r = _pfm_model(y, x, u, np.int64(t), _pfm_p)
            out = carray(out_p, (n,))
            for i in range(n):
                out[i] = r[i]
        """)


def _cast_params(p, real):
    out = []
    for v in p:
        if isinstance(v, tuple):
            out.append(_cast_params(v, real))
        elif isinstance(v, np.ndarray) and v.dtype.kind == "f":
            out.append(np.ascontiguousarray(v, dtype=real))
        elif isinstance(v, (float, np.floating)):
            out.append(real(v))
        else:
            out.append(v)
    return tuple(out)


def _load_class(job):
    import importlib
    import importlib.util

    mod = None
    if job["module"] != "__main__":
        try:
            mod = importlib.import_module(job["module"])
        except ImportError:
            mod = None
    if mod is None:
        spec = importlib.util.spec_from_file_location("_pfm_user_model", job["file"])
        mod = importlib.util.module_from_spec(spec)
        sys.modules["_pfm_user_model"] = mod
        spec.loader.exec_module(mod)
    obj = mod
    for part in job["qualname"].split("."):
        obj = getattr(obj, part)
    return obj


def _numba_ir(cls, fn_name, job, notes):
    """Unoptimised LLVM IR (text) of the C-ABI wrapper of one model function, and its name."""
    import numba
    from numba import carray, types

    precision = job["precision"]
    real = np.float32 if precision == "float" else np.float64
    func = inspect.getattr_static(cls, fn_name)
    func = getattr(func, "__func__", func)
    label = f"model {job['label']!r} function {fn_name}"
    model_fn = None
    if precision == "float":
        errors = []
        ladder = ((True, True, None),
                  (False, True, "integer literals left as integers"),
                  (False, False, "integer literals left as integers and float64 scalars not "
                                 "narrowed to float32"))
        for convert_ints, narrow, what in ladder:
            try:
                py, n2 = float32_source(func, job["file"], convert_ints, narrow)
                model_fn = numba.njit(py)
                sig_args = _sample_args(fn_name, job["dims"], real)
                model_fn.compile(tuple(numba.typeof(a) for a in sig_args) + (numba.typeof(
                    _cast_params(job["params"], real)),))
                if what:
                    notes.append(f"{fn_name}: {what} (the full float rewrite failed: {errors[0]})")
                notes += n2
                break
            except UnsupportedError as exc:
                raise UnsupportedError(f"{label}: {exc}") from None
            except Exception as exc:  # noqa: BLE001 - numba typing/lowering errors, summarised
                errors.append(_summarise(exc))
                model_fn = None
        if model_fn is None:
            raise UnsupportedError(f"{label} cannot be compiled for the MCU: {errors[-1]}")
    else:
        model_fn = numba.njit(func)
    ns = {"np": np, "carray": carray, "_pfm_model": model_fn,
          "_pfm_p": _cast_params(job["params"], real)}
    exec(_wrapper_source(fn_name, job["dims"]), ns)
    R = types.CPointer(types.float32 if precision == "float" else types.float64)
    kinds = FUNCTIONS[fn_name][1]
    sig = types.void(*[types.int32 if k in ("n", "t") else R for k in kinds])
    try:
        disp = numba.njit(sig, no_cpython_wrapper=True)(ns["_pfm_wrapper"])
    except Exception as exc:  # noqa: BLE001
        raise UnsupportedError(f"{label} cannot be compiled for the MCU: {_summarise(exc)}") from None
    cres = disp.overloads[sig.args]
    return cres.library.get_llvm_str(), cres.fndesc.mangled_name


# numba's BLAS entry points (``@``, ``np.dot``: numba.np.linalg) compiled INTO the model module,
# so that LLVM inlines them at each call site and specialises them on what is constant there
# (kind, transposes, leading dimensions, usually k): a matrix product on a tile becomes a plain
# loop with no call, no per-element transpose test or stride multiply.  Column-major BLAS
# semantics, unit strides, the same summation order as c/nrt_shim.c (which keeps the linkable
# C versions).  Characters arrive as their codes ('n' = 110, 'N' = 78).
#: the zero of the sums below: :func:`_blas_ir` rebinds it to float32 or float64 zero per compiled body
_ZERO = 0.0


def _pfm_gemm(transa, transb, m, n, k, alpha, a, lda, b, ldb, beta, c, ldc):
    """C = alpha op(A) op(B) + beta C (column-major ?gemm)."""
    ta = transa != 110 and transa != 78
    tb = transb != 110 and transb != 78
    a_i, a_l = (lda, 1) if ta else (1, lda)   # element (i, l) of op(A) is a[i a_i + l a_l]
    b_l, b_j = (ldb, 1) if tb else (1, ldb)   # element (l, j) of op(B) is b[l b_l + j b_j]
    al = alpha[0]
    be = beta[0]
    for j in range(n):
        for i in range(m):
            s = _ZERO
            for l in range(k):
                s += a[i * a_i + l * a_l] * b[l * b_l + j * b_j]
            if be == 0:
                c[i + j * ldc] = al * s
            else:
                c[i + j * ldc] = al * s + be * c[i + j * ldc]


def _pfm_gemv(trans, m, n, alpha, a, lda, x, beta, y):
    """y = alpha op(A) x + beta y (column-major ?gemv, A is m x n)."""
    tr = trans != 110 and trans != 78
    rows, cols = (n, m) if tr else (m, n)
    a_i, a_l = (lda, 1) if tr else (1, lda)
    al = alpha[0]
    be = beta[0]
    for i in range(rows):
        s = _ZERO
        for l in range(cols):
            s += a[i * a_i + l * a_l] * x[l]
        if be == 0:
            y[i] = al * s
        else:
            y[i] = al * s + be * y[i]


def _pfm_dot(n, dx, dy, result):
    """result = dx . dy (?dot)."""
    s = _ZERO
    for i in range(n):
        s += dx[i] * dy[i]
    result[0] = s


#: entry point -> (Python body, argument kinds: c = char code (i8), i = intp, p = pointer; the
#: kind character is the first argument of the entry point and selects the real type)
_BLAS = {
    "numba_xxgemm": (_pfm_gemm, "cciiipp" "ip" "ippi"),
    "numba_xxgemv": (_pfm_gemv, "ciipp" "ippp"),
    "numba_xxdot": (_pfm_dot, "c" "ippp"),   # (kind,) conjugate, n, dx, dy, result
}


def _blas_ir(name: str, tm_layout: str, triple: str) -> str:
    """Target IR modules (texts) defining the BLAS entry point ``name`` (see :data:`_BLAS`): the
    body compiled by numba for float32 and float64, and a dispatcher on the kind ('s' = 115, 'd' = 100; any
    other kind returns -1, which numba's caller turns into abort())."""
    import numba
    from numba import types

    body, kinds = _BLAS[name]
    ll = {"c": "i8", "i": "i64", "p": "ptr"}
    params = [f"{ll[k]} %a{i}" for i, k in enumerate("c" + kinds)]
    skip = 2 if name == "numba_xxdot" else 1  # xxdot's `conjugate` flag (real kinds: unused)
    parts, calls, decls = [], [], []
    for code, real in ((115, types.float32), (100, types.float64)):
        fn = _pytypes.FunctionType(body.__code__, {"_ZERO": np.dtype(str(real)).type(0)},
                                   f"{body.__name__}_{real}")
        sig = types.void(*[{"c": types.int8, "i": types.intp, "p": types.CPointer(real)}[k]
                           for k in kinds[skip - 1:]])
        disp = numba.njit(sig, no_cpython_wrapper=True)(fn)
        cres = disp.overloads[sig.args]
        parts.append(_retarget(cres.library.get_llvm_str(), tm_layout, triple))
        args = ", ".join(params[skip:])
        decls.append(f"declare i32 @\"{cres.fndesc.mangled_name}\"(ptr, ptr, "
                     + ", ".join(q.split()[0] for q in params[skip:]) + ")")
        calls.append(f"k{code}:\n  call i32 @\"{cres.fndesc.mangled_name}\"(ptr %ret, ptr %exc, "
                     f"{args})\n  ret i32 0")
    disp_ir = textwrap.dedent(f"""\
        target datalayout = "{tm_layout}"
        target triple = "{triple}"
        define i32 @{name}({", ".join(params)}) nounwind alwaysinline {{
        entry:
          %ret = alloca [16 x i8], align 8
          %exc = alloca ptr, align 4
          switch i8 %a0, label %other [i8 115, label %k115
                                       i8 100, label %k100]
        other:
          ret i32 -1
        """) + "\n".join(calls) + "\n}\n" + "\n".join(decls) + "\n"
    return parts + [disp_ir]


def _sample_args(fn_name, dims, real):
    n = 2
    x = np.zeros((n, dims["n_x"]), real)
    u = np.zeros(dims["n_u"], real)
    if fn_name == "transition":
        return (x, u, np.int64(0), np.zeros((n, dims["n_noise"]), real))
    return (np.zeros(dims["n_y"], real), x, u, np.int64(0))


def _c_entry_ir(fn_name: str, target: str, target_args: list) -> str:
    """LLVM IR of the C entry point calling numba's function ``target`` (numba's calling
    convention: status = f(ret*, excinfo**, args...)); stores the status in ``pfm_status``."""
    cname, kinds = FUNCTIONS[fn_name]
    args = ", ".join(("i32" if k in ("n", "t") else "ptr") + f" %{k}" for k in kinds)
    return textwrap.dedent(f"""
        @pfm_status = weak global i32 0, align 4

        declare i32 @"{target}"({', '.join(target_args)})

        define void @{cname}({args}) nounwind {{
        entry:
          %ret = alloca [16 x i8], align 8
          %exc = alloca ptr, align 4
          store ptr null, ptr %exc
          %rc = call i32 @"{target}"(ptr %ret, ptr %exc, {args})
          store i32 %rc, ptr @pfm_status
          ret void
        }}
        """)


_ATTR_STRIP = re.compile(r'\s*"(target-cpu|target-features|tune-cpu)"="[^"]*"')


_FATAL = re.compile(r"call void @numba_gil_ensure\(ptr %[\w.]+\)\n(\s*)call void @Py_FatalError\(ptr [^)]*\)")
_UNWRAP = re.compile(r'^(define [^\n]*@"?__excinfo_unwrap_args[^\n]*\{)\n.*?^\}$', re.M | re.S)


def _retarget(ir: str, tm_layout: str, triple: str) -> str:
    """The host IR made a target IR: data layout and triple, no host cpu/feature attributes, and
    the bodies of numba's ``__excinfo_unwrap_args*`` emptied (they build the Python arguments of
    a dynamic exception, e.g. a shape-mismatch message, with the Python C API, and only the host
    calls them: on the target the status code alone reports the error)."""
    ir = _UNWRAP.sub(lambda m: m.group(1) + "\n  ret ptr null\n}", ir)
    # numba's fatal paths (a BLAS wrapper returning an error): take the GIL, Py_FatalError ->
    # abort() (newlib: stop), the only thing a fatal error can do on the MCU
    ir, k = _FATAL.subn(r"\1call void @abort()", ir)
    if k and not re.search(r"^declare void @abort\(\)", ir, flags=re.M):
        ir += "\ndeclare void @abort()\n"
    ir = re.sub(r'^target datalayout = ".*"$', f'target datalayout = "{tm_layout}"', ir, flags=re.M)
    ir = re.sub(r'^target triple = ".*"$', f'target triple = "{triple}"', ir, flags=re.M)
    return _ATTR_STRIP.sub("", ir)


_DOUBLE_RE = [
    re.compile(r"=\s*(fadd|fsub|fmul|fdiv|frem|fneg)\s+(?:[a-z]+\s+)*(?:<\d+ x )?double\b"),
    re.compile(r"=\s*fcmp\s+(?:[a-z]+\s+)+(?:<\d+ x )?double\b"),
    re.compile(r"=\s*(fpext|fptrunc|sitofp|uitofp|fptosi|fptoui)\b[^=]*\bdouble\b"),
]
_CALL_RE = re.compile(r'\bcall\b.*?@("[^"]+"|[\w.$]+)\(')


def double_op_counts(ir: str) -> dict:
    """Per defined function of an LLVM IR module: (own double ops, own double ops in loops,
    [(callee, call site in a loop)]). See :class:`ModelObject`."""
    funcs = {}
    lines = ir.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("define "):
            m = re.search(r'@("[^"]+"|[\w.$]+)\(', line)
            name = m.group(1).strip('"')
            blocks, order, cur = {}, [], "%entry"
            blocks[cur] = []
            order.append(cur)
            i += 1
            while i < len(lines) and lines[i] != "}":
                s = lines[i]
                lm = re.match(r'^("[^"]+"|[\w.$-]+):', s)
                if lm:
                    cur = "%" + lm.group(1).strip('"')
                    blocks[cur] = []
                    order.append(cur)
                elif s.strip() and not s.strip().startswith(";"):
                    blocks[cur].append(s)
                i += 1
            funcs[name] = (blocks, order)
        i += 1
    declared = set(re.findall(r'^declare .*?@("[^"]+"|[\w.$]+)\(', ir, flags=re.M))
    declared = {d.strip('"') for d in declared}
    out = {}
    for name, (blocks, order) in funcs.items():
        succ = {b: [("%" + t.strip('"')) for t in re.findall(r'label %("[^"]+"|[\w.$-]+)', " ".join(
            s for s in body if not s.strip().startswith(("%", "store", "call")) or "br " in s
            or "switch" in s))] for b, body in blocks.items()}
        in_loop = _loop_blocks(succ)
        own = loop = 0
        calls = []
        for b, body in blocks.items():
            for s in body:
                n = 0
                if any(r.search(s) for r in _DOUBLE_RE):
                    n = 1
                cm = _CALL_RE.search(s)
                if cm:
                    callee = cm.group(1).strip('"')
                    if callee in declared:
                        base = callee
                        if (base.startswith("llvm.") and base.endswith(".f64")) or base in _DOUBLE_LIBM:
                            n = 1
                    elif callee in funcs:
                        calls.append((callee, b in in_loop))
                own += n
                loop += n if b in in_loop else 0
        out[name] = (own, loop, calls)
    return out


def _loop_blocks(succ: dict) -> set:
    """Blocks on a cycle of the control-flow graph (Tarjan's strongly connected components)."""
    index, low, stack, on, res = {}, {}, [], set(), set()
    counter = [0]
    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in succ.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in succ.get(v, ()):
                res.update(comp)

    for v in succ:
        if v not in index:
            strong(v)
    return res


def _aggregate(counts: dict, root: str) -> tuple[int, int]:
    """(total, in loops) of ``root`` including everything it calls."""
    memo = {}

    def walk(f, seen):
        if f in memo:
            return memo[f]
        if f in seen or f not in counts:
            return (0, 0)
        own, loop, calls = counts[f]
        tot, lp = own, loop
        for callee, site_in_loop in calls:
            ct, cl = walk(callee, seen | {f})
            tot += ct
            lp += ct if site_in_loop else cl
        memo[f] = (tot, lp)
        return memo[f]

    return walk(root, frozenset())


def _classify_symbol(sym: str) -> str:
    if sym.startswith(("Py", "_Py", "numba_gil", "numba_unpickle", "numba_do_raise")):
        return f"the Python C API ({sym}): Python objects or object-mode code cannot run on the MCU"
    if sym.startswith("numba_"):
        return (f"numba's runtime helper {sym} (e.g. np.random, np.linalg or string code inside "
                "the model function), which does not exist on the MCU")
    return f"the external symbol {sym}, which neither newlib nor the NRT shim provides"


def _worker(job_path: str) -> int:
    from numba.core import codegen

    # capture the IR before ANY host optimisation (installed before anything is compiled)
    codegen.CPUCodeLibrary._optimize_functions = lambda self, mod: None
    codegen.CPUCodeLibrary._optimize_final_module = lambda self: None

    import llvmlite.binding as llvm

    with open(job_path, "rb") as f:
        job = pickle.load(f)
    out = Path(job["out"])

    def fail(msg):
        (out / "result.json").write_text(json.dumps({"error": msg}))
        return 0

    try:
        cls = _load_class(job)
    except Exception as exc:  # noqa: BLE001
        return fail(f"model {job['label']!r}: cannot import {job['module']}.{job['qualname']} "
                    f"for compilation: {_summarise(exc)}")
    cpu = CPUS[job["cpu"]]
    llvm.initialize_all_targets()
    llvm.initialize_all_asmprinters()
    target = llvm.Target.from_triple(cpu["triple"])
    tm = target.create_target_machine(cpu=cpu["cpu"], features=cpu["features"], reloc="static",
                                      codemodel="default", opt=3)
    layout = str(tm.target_data)
    notes: list = []
    modules = []
    double_ops, double_loop, undefined, needs_nrt = {}, {}, set(), False
    for fn_name, (cname, _) in FUNCTIONS.items():
        try:
            ir, mangled = _numba_ir(cls, fn_name, job, notes)
        except UnsupportedError as exc:
            return fail(str(exc))
        ir = _retarget(ir, layout, cpu["triple"])
        mod = llvm.parse_assembly(ir)
        decl = next(f for f in mod.functions if f.name == mangled)
        for f in [f for f in mod.functions if f.is_declaration and f.name in _BLAS]:
            for part in _blas_ir(f.name, layout, cpu["triple"]):
                mod.link_in(llvm.parse_assembly(part))
        mod.link_in(llvm.parse_assembly(
            f'target datalayout = "{layout}"\ntarget triple = "{cpu["triple"]}"\n'
            + _c_entry_ir(fn_name, mangled, [str(a.type) for a in decl.arguments])))
        for f in mod.functions:
            if not f.is_declaration:
                f.add_function_attribute("nounwind")
                if f.name != cname:
                    f.linkage = "internal"
        for g in mod.global_variables:
            if g.name != "pfm_status" and not g.is_declaration:
                g.linkage = "internal"
        mod = _optimise(llvm, tm, mod)
        label = f"model {job['label']!r} function {fn_name}"
        for f in mod.functions:
            if f.is_declaration and not f.name.startswith("llvm.") and f.name not in LIBC_SYMBOLS:
                if f.name in SHIM_SYMBOLS:
                    needs_nrt = True
                    undefined.add(f.name)
                    continue
                return fail(f"{label} cannot be compiled for the MCU: it calls "
                            + _classify_symbol(f.name))
            elif f.is_declaration and not f.name.startswith("llvm."):
                undefined.add(f.name)
        counts = double_op_counts(str(mod))
        double_ops[cname], double_loop[cname] = _aggregate(counts, cname)
        modules.append(mod)
    final = modules[0]
    for m in modules[1:]:
        final.link_in(m)
    final.verify()
    (out / "model.ll").write_text(str(final))
    (out / "model.o").write_bytes(tm.emit_object(final))
    (out / "result.json").write_text(json.dumps({
        "needs_nrt": needs_nrt, "double_ops": double_ops, "double_loop_ops": double_loop,
        "notes": notes, "undefined": sorted(undefined)}))
    return 0


def _optimise(llvm, tm, mod):
    """Optimise for the target machine, as numba does for the host: atomics lowered (one
    thread), an O2 pass with numba's NRT_incref/NRT_decref kept out of line, numba's reference-
    count pruning pass (removes the incref/decref pairs of a function's temporaries), then the
    refcount helpers made inlinable and LLVM's O3 pipeline. Returns the optimised module."""
    def run(m, level, extra=None):
        pto = llvm.create_pipeline_tuning_options(speed_level=level)
        pb = llvm.create_pass_builder(tm, pto)
        try:
            if extra is not None:
                pm = llvm.create_new_module_pass_manager()
                extra(pm)
                pm.run(m, pb)
            if level:
                pb.getModulePassManager().run(m, pb)
        finally:
            pb.close()

    def pre(pm):
        pm.add_lower_atomic_pass()
        pm.add_global_dead_code_eliminate_pass()

    run(mod, 2, pre)
    run(mod, 0, lambda pm: pm.add_refprune_pass())
    text = re.sub(r"^(attributes #\d+ = \{.*?)\bnoinline\b", r"\1", str(mod), flags=re.M)
    mod = llvm.parse_assembly(text)
    run(mod, 3)
    return mod


# ---------------------------------------------------------------------------------------------
# calling a compiled function on the emulated target
# ---------------------------------------------------------------------------------------------
_MAIN = "int main(void) { return 0; }\n"


def link_test_image(mo: ModelObject):
    """An image (:class:`pfbench.mcu.toolchain.Build`) of the model object, the NRT shim,
    newlib's libm, startup.c and a trivial main, for :func:`call_on_target` (cached)."""
    toolchain.check_tools()
    flags = (*mo.gcc_flags, "-O2", *toolchain.BARE_METAL, *mo.defines)

    def make(tmp):
        (tmp / "main.c").write_text(_MAIN)
        toolchain.run_tool([toolchain.GCC, *flags, "-c", "main.c", "-o", "main.o"], tmp)
        toolchain.link(tmp, "t", flags, ["main.o", SHIM, Path(mo.obj).resolve()], [Path(mo.obj).resolve()])

    return toolchain.image(f"models/test-{mo.cpu}-{mo.precision}",
                           [("model.o", Path(mo.obj).read_bytes()), ("shim", SHIM.read_bytes())],
                           "t", mo.precision, f"{mo.model} test image", flags, make)


def call_on_target(mo: ModelObject, function: str, inputs: dict, *, count: bool = False):
    """Call ``pfm_transition``/``pfm_log_likelihood`` of ``mo`` in the unicorn emulator (the CPU
    model of ``mo.cpu``; unicorn's Cortex-M7 lacks the double-precision FPU instructions).

    ``inputs``: for ``"transition"`` x (n, n_x), u (n_u,), t (int), noise (n, n_noise); for
    ``"log_likelihood"`` y (n_y,), x (n, n_x), u (n_u,), t. The arrays are written into RAM as
    the object's real type, the function is called per the AAPCS (r0-r3, then the stack; LR = a
    halt address) and the output is read back. Returns the output array (float64), or
    (output, instructions executed) with ``count=True``. A non-zero ``pfm_status`` (the model
    raised) is a :class:`~pfbench.errors.PfbenchError`.
    """
    import struct

    from unicorn import UC_HOOK_CODE, UcError
    from unicorn import arm_const as A

    from .emulate import Program, machine

    if function not in FUNCTIONS:
        raise InputError(f"function must be one of {', '.join(FUNCTIONS)}, got {function!r}")
    build = link_test_image(mo)
    sym = Program(build, core=cores.by_cpu(mo.cpu).key).symbols
    real = np.float32 if mo.precision == "float" else np.float64
    x = np.ascontiguousarray(inputs["x"], dtype=real).reshape(-1, mo.n_x)
    n = x.shape[0]
    u = np.ascontiguousarray(inputs.get("u", np.zeros(mo.n_u)), dtype=real).reshape(mo.n_u)
    t = int(inputs.get("t", 0))
    scratch = 0x30000000  # the call's arrays, outside the image's RAM
    uc = machine(build.bin.read_bytes(), mo.cpu, sym["_estack"])
    main = sym["main"] & ~1
    try:  # .data/.bss init and FPU enable, up to main
        uc.emu_start(sym["Reset_Handler"] | 1, main, timeout=10_000_000)
        bufs, addr = {}, scratch
        arrays = {"x": x, "u": u}
        if function == "transition":
            arrays["noise"] = np.ascontiguousarray(inputs["noise"], dtype=real).reshape(n, mo.n_noise)
            arrays["out"] = np.zeros((n, mo.n_x), real)
        else:
            arrays["y"] = np.ascontiguousarray(inputs["y"], dtype=real).reshape(mo.n_y)
            arrays["out"] = np.zeros(n, real)
        size = sum(a.nbytes + 8 for a in arrays.values())
        uc.mem_map(scratch, max(4096, (size + 4095) // 4096 * 4096))
        for k, a in arrays.items():
            bufs[k] = addr if a.size else 0
            uc.mem_write(addr, a.tobytes())
            addr += (a.nbytes + 7) // 8 * 8
        if mo.n_u == 0:
            bufs["u"] = 0
        vals = [{"n": n, "t": t}.get(k, bufs.get(k)) for k in FUNCTIONS[function][1]]
        sp = (sym["_estack"] - 64) & ~7
        for i, v in enumerate(vals):
            if i < 4:
                uc.reg_write(getattr(A, f"UC_ARM_REG_R{i}"), v & 0xFFFFFFFF)
            else:
                uc.mem_write(sp + 4 * (i - 4), struct.pack("<I", v & 0xFFFFFFFF))
        uc.reg_write(A.UC_ARM_REG_SP, sp)
        uc.reg_write(A.UC_ARM_REG_LR, main | 1)
        uc.mem_write(sym["pfm_status"], b"\0\0\0\0")
        counter = [0]
        if count:
            uc.hook_add(UC_HOOK_CODE, lambda _u, _a, _s, _d: counter.__setitem__(0, counter[0] + 1))
        uc.emu_start(sym[FUNCTIONS[function][0]] | 1, main, timeout=60_000_000)
    except UcError as exc:
        pc = uc.reg_read(A.UC_ARM_REG_PC)
        raise PfbenchError(f"emulating {FUNCTIONS[function][0]} failed at 0x{pc:08x}: {exc}") from None
    if uc.reg_read(A.UC_ARM_REG_PC) != main:
        raise PfbenchError(f"{FUNCTIONS[function][0]} did not return (timeout?)")
    status = struct.unpack("<i", bytes(uc.mem_read(sym["pfm_status"], 4)))[0]
    if status != 0:
        raise PfbenchError(f"model {mo.model!r} raised on the target ({FUNCTIONS[function][0]}: "
                           f"pfm_status = {status})")
    outb = bytes(uc.mem_read(bufs["out"], arrays["out"].nbytes))
    res = np.frombuffer(outb, dtype=real).reshape(arrays["out"].shape).astype(np.float64)
    return (res, counter[0]) if count else res


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) == 2 and argv[0] == "--worker":
        return _worker(argv[1])
    print("usage: python -m pfbench.mcu.modelcode --worker JOB", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
