"""How a compiled filter kernel is built: the kernel families as data and one :func:`build`.

A family (particle, MPF, guided) is a template module of this package whose compiled functions call
the model through module globals, as numba's disk cache cannot hold a function that receives the
model's functions as arguments or closures. :func:`build` runs the template once per (model class,
scheme, tile layout) as a module of its own, named for the model and a hash of the package and the
model's source, with the model's functions bound while it runs; the template reads them at its top::

    _b = binding()                       # the build in progress (stubs on a plain import)
    _transition = _b.model("transition")
    _resample = _b.resample               # the scheme's kernel, or the run-time choice

No source is generated; the cache keeps a directory per module name (:mod:`pfbench.backends.cache`),
so a later process loads machine code, and an edit of the package or model gives a new name, never a
stale kernel. A scheme's module takes the family's scheme-free functions (:attr:`Family.shared`) from
the model's any-scheme module (:meth:`Binding.shared`), so a model's schemes share one compilation.
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import os
import sys
import threading
import types
from dataclasses import dataclass

from ..errors import InputError
from ..sources import model_digest
from . import cache


@dataclass(frozen=True)
class Family:
    """A kernel family: its template module (in this package), the model functions it binds (as
    ``_<name>``) and its functions shared by every scheme of a model."""

    template: str
    model_functions: tuple[str, ...]
    shared: tuple[str, ...] = ()


#: every kernel family of the numba backend
FAMILIES: dict[str, Family] = {
    "particle": Family("numba_particle", ("transition", "log_likelihood"), ("_pass_a",)),
    "mpf": Family("numba_mpf", ("cl_transition", "cl_observation", "cl_constrain"),
                  ("_transition_into", "_observation_into", "_constrain_into")),
    "guided": Family("numba_guided", ("initial", "proposal", "proposal_log_weight", "predictive_log_likelihood"),
                     ("_propose_into", "_weight_into", "_predictive_into")),
}

_LOCK = threading.RLock()
_LOCAL = threading.local()
_MODULES: dict[tuple, types.ModuleType] = {}
_FUNCS: dict[tuple[type, str], object] = {}


class Binding:
    """What a template module binds while :func:`build` runs it: ``cls`` the model class (None: a plain
    import, stubs), ``scheme`` a :class:`~pfbench.resampling.Scheme` code (-1: chosen at run time),
    ``f_tiles`` whether the particle kernel hands the model column-major tiles."""

    def __init__(self, family: str, cls: type | None, scheme: int, f_tiles: bool):
        self.family, self.cls, self.scheme, self.f_tiles = family, cls, scheme, f_tiles
        self.cacheable = cls is None or disk_cacheable(cls)

    def model(self, name: str):
        """The model's compiled function ``name`` (a stub that raises on a plain import)."""
        if self.cls is None:
            def stub(*args):  # pragma: no cover - a template is only run through build()
                raise NotImplementedError(f"{name}: bound per model by pfbench.backends.kernels.build")
            return stub
        return model_function(self.cls, name)

    @property
    def resample(self):
        """The scheme's resampling kernel, or ``any_scheme`` (the code chosen at run time)."""
        from . import numba_resampling

        return getattr(numba_resampling, numba_resampling.kernel_name(None if self.scheme < 0 else self.scheme))

    def shared(self, name: str, own):
        """``own`` in the any-scheme module, else the any-scheme module's ``name`` (one compilation per model)."""
        if self.cls is None or self.scheme < 0:
            return own
        return getattr(build(self.family, self.cls, None, f_tiles=self.f_tiles), name)

    def jit(self, **options):
        """:func:`pfbench.backends.cache.njit`, disk-cached when :func:`disk_cacheable`."""
        return cache.njit(cache=self.cacheable, **options)


def binding() -> Binding:
    """The binding of the template module being run by :func:`build`; stubs on a plain import."""
    return getattr(_LOCAL, "binding", None) or Binding("", None, -1, False)


def build(family: str, model, scheme=None, *, f_tiles: bool | None = None) -> types.ModuleType:
    """The compiled kernel module of ``family`` for a model (class or instance) and a scheme.

    ``scheme``: a :class:`~pfbench.resampling.Scheme`, its name or code; None: chosen at run time (the
    module of per-step callers and the shared functions). ``f_tiles``: default
    :func:`column_major_tiles` of ``model``. Its drivers compile on first call per argument types.
    """
    from ..resampling import Scheme

    cls = model if isinstance(model, type) else type(model)
    fam = FAMILIES[family]
    code = -1 if scheme is None else int(Scheme.parse(scheme) if isinstance(scheme, str) else scheme)
    tiles = family == "particle" and bool(column_major_tiles(model) if f_tiles is None else f_tiles)
    key = (family, cls, code, tiles)
    with _LOCK:
        if key in _MODULES:
            return _MODULES[key]
        if importlib.import_module("numba").config.DISABLE_JIT:  # numba would compile nothing
            raise InputError("NUMBA_DISABLE_JIT is set: the numba backend needs numba's compiler; unset it, or "
                             "step through the model's plain Python on --backend numpy")
        if disk_cacheable(cls):  # an unusable cache directory is one line naming it, before any compile
            cache.check_cache_dir()
        parts = (cache.package_fingerprint(), fam.template, str(disk_cacheable(cls)), model_digest(cls))
        digest = hashlib.sha256("\0".join(parts).encode()).hexdigest()[:16]
        safe = "".join(c if c.isalnum() else "_" for c in f"{cls.__module__}_{cls.__qualname__}")
        name = f"pfbench_kernel_{family}_{'any' if code < 0 else code}{'_f' if tiles else ''}_{safe}_{digest}"
        spec = importlib.util.find_spec(f"{__package__}.{fam.template}")
        spec = importlib.util.spec_from_file_location(name, spec.origin)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod  # numba's cache rebuilds a function's environment from its module's name
        outer = getattr(_LOCAL, "binding", None)
        _LOCAL.binding = Binding(family, cls, code, tiles)
        try:
            spec.loader.exec_module(mod)
        except BaseException:
            sys.modules.pop(name, None)
            raise
        finally:
            _LOCAL.binding = outer
        _MODULES[key] = mod
        return mod


def column_major_tiles(model) -> bool:
    """Whether the particle kernel hands this model its tiles typed column-major ('F'): a model
    *instance* with one state and one noise component (``numba_particle._column_major``); a class,
    whose instances may have other dimensions, gets False, right for any shape."""
    if isinstance(model, type):
        return False
    return int(getattr(model, "n_x", 0)) == 1 and int(getattr(model, "n_noise", 0)) == 1


def model_class_by_name(module: str, qualname: str) -> type:
    """A model class from its module and qualified name (a compile helper process)."""
    obj = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def model_function(cls: type, name: str):
    """The njit-compiled staticmethod ``name`` of a model class (one dispatcher per process)."""
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


def disk_cacheable(cls: type) -> bool:
    """Whether numba can reload this model's code in a later process: its cache re-imports a function's
    module by name, so models from ``exec``'d code or notebooks are compiled in memory only."""
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


def twin(func, name: str):
    """A copy of ``func`` named ``name``, with its own dispatcher and cache entry (serial and parallel twins)."""
    f = types.FunctionType(func.__code__, func.__globals__, name, func.__defaults__, func.__closure__)
    f.__qualname__ = name
    f.__doc__ = func.__doc__
    return f
