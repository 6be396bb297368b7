"""The numba backend: a model's own functions compiled into cached filter kernels.

numba's on-disk cache cannot hold a kernel that receives the model functions as arguments or
closure variables. So each filter family has its kernel written as a real module of this package
(``numba_particle.py``, ``numba_mpf.py``, ``numba_guided.py``) that calls the model through module
globals, and for each (family, model class) we write a copy of that module into the cache
directory, with the model's njit-compiled functions bound to those globals at its end::

    <the family's kernel module source>
    <footer: bind the model's compiled functions to the kernel's globals>

and import it (a scheme's module also binds the family's scheme-free functions, :data:`SCHEME_FREE`,
to those of the model's any-scheme module, so they are compiled once per model). Its kernels are
ordinary module-level cached functions, so a second process loads
machine code from disk instead of recompiling. The file name carries a hash of the whole pfbench
package, the model's module source and the numba/NumPy versions, so editing anything gives a
new module and a fresh compile, never a stale kernel (see :mod:`pfbench.backends.cache`).

Cache location: ``kernels`` in :func:`pfbench.backends.cache.cache_root`.

A generated file that is damaged (truncated, garbage, not UTF-8, a directory in its place) no longer
matches the text pfbench generates: it is rewritten (atomically: temporary file + rename, so a
concurrent process never reads half a file) with one
:class:`~pfbench.backends.cache.CacheRepairWarning` line. The module is executed from the generated
text itself, never from the file or a ``__pycache__`` byte-code copy, so a file damaged after that
check cannot break the import either.
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import os
import sys
import threading
from pathlib import Path

import numpy as np

from ..io import write_text
from ..procs import free_cores
from ..filters.methods import Estimate, Method
from ..resampling import Scheme
from . import cache, compile_helper, native_call, pcg64

_HERE = Path(__file__).resolve().parent
#: family -> (kernel module file, the model functions it calls as ``_<name>``)
FAMILIES: dict[str, tuple[str, tuple[str, ...]]] = {
    "particle": ("numba_particle.py", ("transition", "log_likelihood")),
}
#: family -> its module's functions that depend on the model but not on the resampling scheme: the
#: module of a scheme takes them from the model's any-scheme module (``scheme=None``), so all the
#: schemes of a model share one compilation of them (the particle kernel's pass A, the draws and the
#: model inlined, is about 40 % of its cold compile)
SCHEME_FREE: dict[str, tuple[str, ...]] = {
    "particle": ("_pass_a",), "mpf": ("_transition_into", "_observation_into", "_constrain_into"),
    "guided": ("_propose_into", "_weight_into", "_predictive_into")}
_LOCK = threading.RLock()
_MODULES: dict[tuple[str, type, str, bool], object] = {}
_FUNCS: dict[tuple[type, str], object] = {}
_CLASSES: dict[tuple[str, str], type] = {}


def register_family(family: str, filename: str, functions: tuple[str, ...]) -> None:
    """Declare a kernel family: its module file in this folder and the model functions it binds."""
    FAMILIES[family] = (filename, tuple(functions))


def cache_dir() -> Path:
    return cache.check_cache_dir() / "kernels"


def model_class_by_name(module: str, qualname: str) -> type:
    """A model class from its module and qualified name (a kernel module's footer, a compile
    helper process)."""
    obj = _CLASSES.get((module, qualname))
    if obj is None:  # a process that imports the kernel module directly
        obj = importlib.import_module(module)
        for part in qualname.split("."):
            obj = getattr(obj, part)
    return obj


def model_function(module: str, qualname: str, name: str):
    """The njit-compiled staticmethod ``name`` of a model class (compiled once per process)."""
    cls = model_class_by_name(module, qualname)
    key = (cls, name)
    with _LOCK:
        if key not in _FUNCS:
            can_cache = disk_cacheable(cls)
            func = inspect.getattr_static(cls, name)
            func = getattr(func, "__func__", func)
            if can_cache:
                cache.track_file(inspect.getsourcefile(func))
            _FUNCS[key] = cache.njit(cache=can_cache, nogil=True)(func)
        return _FUNCS[key]


def scheme_free_function(family: str, module: str, qualname: str, f_tiles: bool, name: str):
    """Function ``name`` of the any-scheme kernel module of a model class (:data:`SCHEME_FREE`)."""
    return getattr(kernel_module(model_class_by_name(module, qualname), family, None, f_tiles=f_tiles), name)


def disk_cacheable(cls: type) -> bool:
    """Whether numba can reload this model's compiled code in a later process.

    numba's cache re-imports a function's module by name, so models defined in ``exec``'d code,
    notebooks or modules that cannot be found again are compiled in memory only.
    """
    try:
        src = inspect.getsourcefile(inspect.getattr_static(cls, "transition").__func__)
    except TypeError:
        return False
    if not src or not src.endswith(".py") or not os.path.exists(src):
        return False
    if cls.__module__ == "__main__":
        return True
    try:
        return importlib.util.find_spec(cls.__module__) is not None
    except (ImportError, ValueError):
        return False


def _source_fingerprint(cls: type, family: str) -> bytes:
    parts = [cache.package_fingerprint().encode(), family.encode(), str(disk_cacheable(cls)).encode()]
    mod = sys.modules.get(cls.__module__)
    try:
        parts.append(inspect.getsource(mod).encode())
    except (OSError, TypeError):
        for name in FAMILIES[family][1]:
            code = getattr(inspect.getattr_static(cls, name), "__func__", None)
            if code is not None:
                code = code.__code__
                parts.append(code.co_code + repr(code.co_consts).encode())
    return hashlib.sha256(b"\0".join(parts)).digest()


def kernel_module(model_or_cls, family: str = "particle", scheme=None, *, f_tiles: bool | None = None):
    """The generated kernel module of a model (class or instance) for a filter family.

    ``scheme`` (a :class:`~pfbench.resampling.Scheme`, its name or code) binds the kernel's
    ``_resample`` to that scheme's kernel only, so the module compiles no other scheme, and binds
    the family's :data:`SCHEME_FREE` functions to those of the model's module with ``scheme=None``,
    which binds :func:`~pfbench.backends.numba_resampling.any_scheme` (the scheme chosen at run
    time). ``f_tiles``: whether the particle kernel hands the model column-major tiles (default:
    :func:`column_major_tiles` of ``model_or_cls``).
    """
    from ..resampling import Scheme
    from .numba_resampling import kernel_name

    cls = model_or_cls if isinstance(model_or_cls, type) else type(model_or_cls)
    filename, functions = FAMILIES[family]
    resampler = kernel_name(scheme)
    if f_tiles is None:
        f_tiles = column_major_tiles(model_or_cls)
    f_tiles = family == "particle" and bool(f_tiles)
    key = (family, cls, resampler, f_tiles)
    with _LOCK:
        if key in _MODULES:
            return _MODULES[key]
        # models defined in scripts or notebooks are not importable by name: register the class
        _CLASSES[(cls.__module__, cls.__qualname__)] = cls
        digest = _source_fingerprint(cls, family).hex()[:16]
        safe = "".join(c if c.isalnum() else "_" for c in f"{cls.__module__}_{cls.__qualname__}")
        name = f"k_{family}_{resampler}{'_f' if f_tiles else ''}_{safe}_{digest}"
        path = cache_dir() / f"{name}.py"
        body = (_HERE / filename).read_text()
        footer = (f"\n\n# ---- generated by pfbench for {cls.__module__}.{cls.__qualname__}: bind the model\n"
                  "from pfbench.backends.numba_backend import model_function as _model_function\n")
        for fn in functions:
            footer += (f"_{fn} = _model_function({cls.__module__!r}, {cls.__qualname__!r}, {fn!r})\n")
        footer += f"from pfbench.backends.numba_resampling import {resampler} as _resample\n"
        footer += f"_SCHEME = {-1 if scheme is None else int(Scheme.parse(scheme) if isinstance(scheme, str) else scheme)}\n"
        footer += f"_F_TILES = {f_tiles}\n"
        shared = SCHEME_FREE.get(family, ()) if scheme is not None else ()
        if shared:
            footer += "from pfbench.backends.numba_backend import scheme_free_function as _scheme_free\n"
        for fn in shared:
            footer += f"{fn} = _scheme_free({family!r}, {cls.__module__!r}, {cls.__qualname__!r}, {f_tiles}, {fn!r})\n"
        text = body + footer
        if not disk_cacheable(cls):
            text = text.replace("_njit(nogil=True", "_njit(cache=False, nogil=True")
        _ensure_file(path, text)
        modname = f"pfbench_kernel_{name}"
        spec = importlib.util.spec_from_file_location(modname, path)
        mod = importlib.util.module_from_spec(spec)
        # numba's cache rebuilds a kernel's environment by importing its module by name
        sys.modules[modname] = mod
        try:  # the text we generated, not whatever the file (or a stale .pyc) holds by now
            exec(compile(text, str(path), "exec"), mod.__dict__)
        except BaseException:
            sys.modules.pop(modname, None)
            raise
        _MODULES[key] = mod
        return mod


def column_major_tiles(model_or_cls) -> bool:
    """Whether the particle kernel hands this model its tiles typed column-major ('F'): a model
    *instance* with one state and one noise component (its (tile, 1) arrays are both layouts; see
    ``numba_particle._column_major``). The dimensions are the instance's, which may differ from its
    class's defaults (``linear_gaussian`` sets them from its matrices), so a class alone gets
    False, the layout that is right for any shape."""
    if isinstance(model_or_cls, type):
        return False
    return int(getattr(model_or_cls, "n_x", 0)) == 1 and int(getattr(model_or_cls, "n_noise", 0)) == 1


def _ensure_file(path: Path, text: str) -> None:
    """Make ``path`` hold exactly ``text``; rewrite (and warn about) a damaged file."""
    data = text.encode("utf-8")
    try:
        if path.read_bytes() == data:
            return
        damage: BaseException | None = None
    except FileNotFoundError:
        write_text(path, text)
        return
    except OSError as exc:  # a directory in its place, unreadable
        damage = exc
    cache.remove_path(path)
    write_text(path, text)
    cache.warn_repaired(path, "generated kernel file", damage or "content differs from the generated text")


_WARM: set = set()
#: numba's default ``workqueue`` threading layer aborts when two Python threads launch parallel
#: regions at once: every ``run_group_parallel`` call holds this lock (tbb/omp would not need it)
_PARALLEL_LOCK = threading.Lock()


def warm_up(model, p, y, u, dtype, scheme=0, parallel: bool = False) -> None:
    """Compile (or load) the particle kernel for these argument types outside any timed region.

    numba compiles on the first call, so one call on a single step and particle with a
    throwaway generator; the caller's random streams are not touched. ``parallel`` warms the
    all-threads compilation instead of the serial one: a call compiles only the variant it runs.
    """
    key = (type(model), column_major_tiles(model), np.dtype(dtype).str, int(scheme),
           tuple(type(v).__name__ for v in p), parallel)
    if key in _WARM:
        return
    n_x = model.n_x
    for par in ((True,) if parallel else (False,)):
        x = np.empty((1, 2 if par else 1, n_x), dtype=dtype)
        G, n = 1, x.shape[1]
        rng = np.random.default_rng(0)
        run_group(model, p, rng, y[:1], u[:1], x, 0, int(scheme), 1.0, np.empty((G, 1, n_x)),
                  np.empty((G, 1, n_x)), np.empty((G, 1)), np.empty((G, 1)), np.zeros((G, 1), np.bool_),
                  np.zeros((G, 1), np.bool_), np.empty((G, 0, n, n_x), dtype), np.empty((G, 0, n)),
                  brngs=[rng, np.random.default_rng(1)] if par else None, n_threads=2 if par else 1,
                  block=1 if par else None)
    _WARM.add(key)


def run_group(model, p, rng, y, u, x, method, scheme, ess_threshold, est, var, ess, inc, resampled,
              degen, hist_x=None, hist_w=None, *, brngs=None, n_threads: int | None = 1,
              block: int | None = None, estimate: str = "pre") -> None:
    """Numba twin of :func:`pfbench.backends.numpy_backend.run_group` (releases the GIL).

    ``brngs``: the stream-block generators (:func:`pfbench.backends.numpy_backend.block_streams`;
    None: ``[rng]``, one block); ``block``: the largest stream block (default
    :data:`pfbench.backends.numpy_backend.BLOCK`; the layout is
    :func:`~pfbench.backends.numpy_backend.block_bounds`). With more than one block and
    ``n_threads`` != 1 the block loops run on ``n_threads`` numba threads (None: all); results do
    not depend on the thread count. ``estimate``: ``pre`` or ``post`` (the kernel's ``post`` flag).
    """
    import warnings

    from numba.core.errors import NumbaPendingDeprecationWarning

    from .numpy_backend import BLOCK, block_bounds, draw_initial

    y, u = np.ascontiguousarray(y), np.ascontiguousarray(u)  # the row types pass_a_types gives
    bounds = block_bounds(x.shape[1], int(block or BLOCK))
    if hist_x is None:
        G, n, n_x = x.shape
        hist_x, hist_w = np.empty((G, 0, n, n_x), x.dtype), np.empty((G, 0, n))
    brngs = [rng] if brngs is None else list(brngs)
    if len(brngs) != bounds.shape[0] - 1:
        raise ValueError(f"{len(brngs)} block streams for {x.shape[1]} particles in {bounds.shape[0] - 1} blocks")
    pcg64.check_generators([rng, *brngs])  # the kernel reads PCG64's state struct directly
    mod = kernel_module(model, "particle", scheme)
    work = work_arrays(x, bounds.shape[0] - 1, int(method))
    # in NumPy, as the NumPy backend, straight into the kernel's first particle buffer (block by
    # block on the run's threads above one block: the draw and its first touch of the buffer)
    draw_initial(model.kernel_functions()["initial"], p, rng, work[0][0], brngs, n_threads)
    args = [p, rng, brngs, y, u, x, int(model.n_noise), int(method),
            int(scheme), float(ess_threshold), bounds, est, var, ess, inc, resampled, degen, hist_x, hist_w,
            *work, Estimate.parse(estimate) == Estimate.POST, 0, 0, 0]
    parallel = len(brngs) > 1 and n_threads != 1
    driver = mod.run_group_parallel if parallel else mod.run_group
    with warnings.catch_warnings():  # the block generators travel as a (reflected) list
        warnings.simplefilter("ignore", NumbaPendingDeprecationWarning)
        import numba

        # the passes' argument types follow from these (every other argument the driver hands them
        # is a float64 or index row, or a C array in the particle dtype)
        key = (driver, numba.typeof(p), x.dtype, y.dtype, u.dtype)
        addresses = _PASS_ADDRESSES.get(key)
        if addresses is None:
            calls = [("_pass_a", pass_a_types(p, rng, y, u, work), numba.types.float64),
                     ("_pass_b", pass_b_types(work), numba.types.none)]
            if mod._SCHEME in (-1, Scheme.SYSTEMATIC, Scheme.STRATIFIED):  # the merge branch (-1: any)
                calls.append(("_merge_gather", merge_types(work), numba.types.none))
            addresses = native_addresses(model, "particle", mod, driver, args, calls,
                                         here=("_pass_b", "_merge_gather"), f_tiles=column_major_tiles(model))
            addresses = _PASS_ADDRESSES.setdefault(key, addresses + [0] * (3 - len(addresses)))
        args[-3:] = addresses  # an index scheme's kernel never calls the merge: its address is 0
        if parallel:
            k = min(int(n_threads or free_cores()), numba.config.NUMBA_NUM_THREADS)
            with _PARALLEL_LOCK:
                numba.set_num_threads(k)
                try:
                    driver(*args)
                except SystemError as exc:
                    raise _raised_in_parallel(exc) from None
        else:
            driver(*args)


#: (driver, parameter type, particle, y and u dtypes) -> the addresses of passes A, B and C for
#: that driver: found once per process (:func:`native_addresses` types every pass's arguments and
#: looks its entry point up; measured, Ob1, N_p = 1000: a run's time beyond its steps 0.35 ms when
#: done on every run, 0.19 ms with this table, 0.8 ns per particle-step less at M = 200); compiled
#: code stays at its address for the life of the process
_PASS_ADDRESSES: dict = {}


def native_addresses(model, family: str, mod, driver, args, calls, *, here=(), f_tiles: bool = False) -> list:
    """The native entry addresses of the functions ``driver`` calls by address
    (:mod:`pfbench.backends.native_call`), in the order of ``calls``: ``(name, argument types, return
    type)`` of functions of the kernel module ``mod`` that do not depend on the scheme: the ones that
    inline or call the model (:data:`SCHEME_FREE`, the model's own functions), or model-free ones
    it imports (step math). A return type of None means "known once compiled": such a function is
    only called by functions listed after it, which are compiled after it. When the driver (called
    with ``args``, the addresses' places holding ints) and any of the functions not named in
    ``here`` are cold, a helper process compiles those functions while this one compiles the driver
    and then the ones in ``here`` (:mod:`pfbench.backends.compile_helper`)."""
    funcs = [(name, getattr(mod, name), argtypes, restype) for name, argtypes, restype in calls]
    away = [(name, f, a) for name, f, a, _ in funcs if name not in here]
    with _LOCK:  # threads of one process start one helper, not one each
        for _, func, argtypes, restype in funcs:
            if restype is not None:
                native_call.declare(func, argtypes, restype)
        if compile_helper.enabled() and any(compile_helper.cold(f, a) for _, f, a in away):
            sig = tuple(driver.typeof_pyval(a) for a in args)
            if compile_helper.cold(driver, sig):
                helper = compile_helper.start(type(model), family, f_tiles, [(name, a) for name, _, a in away])
                if helper is not None:
                    try:
                        driver.compile(sig)
                        for name, f, a, _ in funcs:
                            if name in here:
                                native_call.entry_address(f, a)
                    except BaseException:  # Ctrl-C (delivered when the compile ends) or an error
                        helper.kill()
                        raise
                    helper.finish()
        return [native_call.entry_address(f, a) for _, f, a, _ in funcs]


def _raised_in_parallel(exc: SystemError) -> BaseException:
    """The exception compiled code raised inside a parallel region (the model's own ``raise``,
    e.g. an :class:`~pfbench.errors.UnsupportedError`): numba's parallel kernel returns with it
    set, which Python reports as a SystemError caused by it. The serial kernel raises it as it
    is, so the all-threads one does too; a SystemError without such a cause stays one."""
    cause = exc.__cause__
    return cause if isinstance(cause, Exception) and not isinstance(cause, SystemError) else exc


def pass_a_types(p, rng, y, u, work) -> tuple:
    """The numba types of the arguments the particle kernel's driver passes to pass A (its call in
    ``numba_particle._run_group``), from the driver's own arguments (C-contiguous ``y``, ``u`` and
    work arrays, so every row it passes is a C array): the parameters, a block generator, ``y[t]``,
    ``u[t]``, the step, one filter's particles ``xs[k, g]``, the block bounds and noise count, the
    log-weights ``lw[g]``, three flags with ``-log n``, and the rows ``lam``, ``lam_all``, ``la``
    of ``fwork``. The driver's compile refuses other types
    (:func:`pfbench.backends.native_call.caller`)."""
    import numba

    xs, lw, fwork = work[0], work[1], work[2]
    i, b = numba.types.int64, numba.types.boolean
    row = numba.typeof(fwork[0])
    return (numba.typeof(p), numba.typeof(rng), numba.typeof(y[0]), numba.typeof(u[0]), i,
            numba.typeof(xs[0, 0]), i, i, i, numba.typeof(lw[0]), b, numba.types.float64, b, row, b, row, row)


def pass_b_types(work) -> tuple:
    """The numba types of the arguments the particle kernel's driver passes to pass B
    (:func:`pfbench.backends.numba_weights.block_weights`)."""
    import numba

    xs, fwork, bwork, bmom = work[0], work[2], work[4], work[5]
    i, b, f = numba.types.int64, numba.types.boolean, numba.types.float64
    row, part = numba.typeof(fwork[0]), numba.typeof(xs[0, 0])
    brow, bm = numba.typeof(bwork[0]), numba.typeof(bmom[0])
    return (row, f, row, part, i, i, b, i, brow, brow, bm, bm)


def merge_types(work) -> tuple:
    """The numba types of the arguments the particle kernel's driver passes to pass C
    (:func:`pfbench.backends.numba_resampling.merge_gather`): the running sum, N_p, the uniform,
    a block's stratified uniforms, the flag, the block bounds, one filter's two particle buffers,
    the two lambda rows, the flag and the scratch rows."""
    import numba

    xs, fwork, iwork = work[0], work[2], work[3]
    i, b, f = numba.types.int64, numba.types.boolean, numba.types.float64
    row, irow, part = numba.typeof(fwork[0]), numba.typeof(iwork), numba.typeof(xs[0, 0])
    return (row, i, f, row, b, i, i, part, part, row, row, b, irow, row, irow)


def work_arrays(x, n_blocks: int, method: int) -> tuple:
    """The particle kernel's work arrays for particles ``x`` (G, N_p, n_x) in ``n_blocks`` stream
    blocks and a :class:`~pfbench.filters.methods.Method` code, in its argument order: the two
    particle buffers, the log-weights kept between steps (rows of N_p only for a method that may
    skip a resampling, else rows of 0), the float rows of N_p (stratified uniforms, running sum,
    log-weights that pass B turns into weights in place; ASIR adds its two lambda rows), the int
    row (N_p indices, then one estimate tile of merge marks per block), four per-block rows (max,
    weight sum, sum w^2, cdf offset), the per-block moments and the per-filter (current buffer,
    flat-weights) flags.

    Allocated here rather than in the kernel: each array constructor the kernel compiled cost
    about 0.1 s of a cold start. Only what the method touches: every page of a fresh array is
    zero-filled by the operating system on first touch. With the rows above, the initial particles
    drawn straight into the first buffer and no row initialised that the method never reads, the
    bootstrap at N_p = 10^6 touches 40 MB of work arrays instead of 72 MB, and a run's set-up (the
    time of a run beyond its steps) went from 19 to 13 ms on 1 thread (Ob1, 2-core Xeon)."""
    from .numba_resampling import ESTIMATE_TILE

    lw_rows = method != int(Method.BOOTSTRAP)
    asir = method == int(Method.ASIR)
    G, n, n_x = x.shape
    return (np.empty((2, G, n, n_x), x.dtype), np.empty((G, n) if lw_rows else (G, 0)),
            np.empty((5 if asir else 3, n)), np.empty(n + n_blocks * ESTIMATE_TILE, np.int64),
            np.empty((4, n_blocks)), np.empty((2, n_blocks, n_x)), np.empty((2, G), np.int64))
