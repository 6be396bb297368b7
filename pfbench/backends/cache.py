"""Compiled code that is never stale: every numba disk cache entry of pfbench is keyed on the whole
package source.

numba keys a compiled function on its own source file only, so an edit of a helper it inlined would
leave old machine code in use. :func:`install` puts first a cache locator for pfbench's functions and
the model files a kernel compiles (:func:`track_file`) whose source stamp is
:func:`package_fingerprint` plus the function's file hash, one directory per module (a template runs
as one module per model, :func:`pfbench.backends.kernels.build`), under ``cache_root() / "numba"``.

Damaged entries heal themselves (:class:`HealingFunctionCache`, for :func:`njit` functions): an index
or data file that cannot be read, unpickled or rebuilt is removed, reported by one
:class:`CacheRepairWarning` line and recompiled. The data file is written before its index entry and
holds its key, so a writer killed or racing between the two leaves a miss, never wrong code.

:func:`install` runs when ``pfbench`` is imported, before any pfbench module defines a cached function.
"""
from __future__ import annotations

import functools
import hashlib
import itertools
import os
import shutil
import sys
import warnings
from pathlib import Path

from ..sources import digest, file_hash

PACKAGE_DIR = Path(__file__).resolve().parent.parent
_TRACKED: set[str] = set()


def cache_root() -> Path:
    """Where pfbench keeps compiled code: ``$PFBENCH_CACHE_DIR``; else ``<environment>/var/cache/pfbench``
    from a writable virtual environment; else ``~/.cache/pfbench``. One cache per installation, shared
    by ``make all`` (:mod:`pfbench.precompile`), the tests and later commands, removed with the environment.
    """
    root = os.environ.get("PFBENCH_CACHE_DIR")
    if root:
        return Path(root)
    if sys.prefix != sys.base_prefix and os.access(sys.prefix, os.W_OK):
        return Path(sys.prefix) / "var" / "cache" / "pfbench"
    return Path(os.path.expanduser("~")) / ".cache" / "pfbench"


_USABLE: set[Path] = set()


def check_cache_dir() -> Path:
    """:func:`cache_root`, created and probed once per process: an unwritable one is a one-line
    :class:`~pfbench.errors.DataError` naming it and ``PFBENCH_CACHE_DIR``, not a numba traceback."""
    root = cache_root()
    if root not in _USABLE:
        from ..resources import check_writable

        check_writable(root, "PFBENCH_CACHE_DIR (the compile cache)", directory=True)
        _USABLE.add(root)
    return root


@functools.cache
def package_fingerprint() -> str:
    """Hash of every ``.py`` file of the package plus the Python, numba and NumPy versions; the recipes
    (``pfbench/reproductions``) are left out (:func:`pfbench.recipes.code_fingerprint` adds one's own)."""
    import numba
    import numpy

    h = hashlib.sha256()
    h.update(f"{sys.version_info[:3]}|{numba.__version__}|{numpy.__version__}".encode())
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        if "__pycache__" in path.parts or path.relative_to(PACKAGE_DIR).parts[0] == "reproductions":
            continue
        h.update(str(path.relative_to(PACKAGE_DIR)).encode() + b"\0")
        h.update(path.read_bytes() + b"\0")
    return h.hexdigest()


def track_file(path) -> None:
    """Key the numba cache of functions defined in ``path`` (a model's file) on the package too."""
    _TRACKED.add(os.path.realpath(str(path)))


def _covered(py_file: str) -> bool:
    real = os.path.realpath(py_file)
    return real in _TRACKED or Path(real).is_relative_to(os.path.realpath(PACKAGE_DIR))


def _locator_class():
    from numba.core import caching

    class PackageKeyedLocator(caching._CacheLocator):
        """numba cache locator whose freshness stamp covers the whole pfbench package."""

        def __init__(self, py_func, py_file):
            self._py_file, self._py_func = py_file, py_func
            self._lineno = py_func.__code__.co_firstlineno
            # one directory per module: a kernel template runs as one module per model
            # (:func:`pfbench.backends.kernels.build`), whose functions share file and line
            self._cache_path = str(cache_root() / "numba" / self.get_suitable_cache_subpath(py_file)
                                   / py_func.__module__)

        def get_cache_path(self):
            return self._cache_path

        def get_source_stamp(self):  # a model's file: also the user's code its function reaches
            user = os.path.realpath(self._py_file) in _TRACKED
            return (package_fingerprint(), file_hash(self._py_file), digest([self._py_func]) if user else "")

        def get_disambiguator(self):
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func, py_file):
            if not os.path.exists(py_file) or not _covered(py_file):
                return None
            self = cls(py_func, py_file)
            try:
                self.ensure_cache_path()
            except OSError:
                return None
            return self

    return PackageKeyedLocator


class CacheRepairWarning(UserWarning):
    """A damaged compiled-code cache file was removed and rebuilt."""


_REPAIRED: set[str] = set()


def warn_repaired(path, what: str, exc: BaseException | str | None = None) -> None:
    """Report a repaired cache file once per process, as one line attributed to ``path`` at line 0
    (``<path>:0: CacheRepairWarning: damaged <what> (<reason>): removed and rebuilt``, no source line);
    ``-W ignore::pfbench.backends.cache.CacheRepairWarning`` silences it."""
    reason = f" ({exc})" if isinstance(exc, str) else ""
    if isinstance(exc, BaseException):
        detail = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        detail = " ".join(detail.split())[:120]
        reason = f" ({type(exc).__name__}{': ' + detail if detail else ''})"
    _warn_once(path, f"damaged {what}{reason}: removed and rebuilt")


def _warn_once(path, message: str) -> None:
    path = str(path)
    if path in _REPAIRED:
        return
    _REPAIRED.add(path)
    warnings.warn_explicit(message, CacheRepairWarning, path, 0, module=__name__)


def remove_path(path) -> None:
    """Remove a file, symlink or directory; a missing path is fine, other failures are ignored
    (the caller rebuilds anyway, and a later write reports what is wrong with the directory)."""
    try:
        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path, ignore_errors=True)
        else:
            os.unlink(path)
    except OSError:
        pass


@functools.cache
def _healing_cache_class():
    """Build (once) the numba cache classes used by every :func:`njit` function of pfbench."""
    from numba.core import caching

    class HealingIndexDataCacheFile(caching.IndexDataCacheFile):
        """numba's index + data files: damaged files removed, data written first, holding its key."""

        def _discard(self, path, exc) -> None:
            remove_path(path)
            warn_repaired(path, "numba cache entry", exc)

        def _load_index(self):
            try:
                overloads = super()._load_index()
                if not isinstance(overloads, dict):
                    raise TypeError(f"the index holds a {type(overloads).__name__}, not a dict")
                return overloads
            except FileNotFoundError:
                return {}
            except Exception as exc:  # noqa: BLE001 - any unreadable index is a damaged one
                self._discard(self._index_path, exc)
                return {}

        def load_entry(self, key):
            """``(data file path, payload)`` of the entry for ``key``, or None (then recompile)."""
            name = self._load_index().get(key)
            if not isinstance(name, str):
                return None
            path = self._data_path(name)
            try:
                stored = self._load_data(name)
            except FileNotFoundError:  # removed, or its writer was killed before writing it
                return None
            except Exception as exc:  # noqa: BLE001 - truncated, garbage, a directory, unreadable
                self._discard(path, exc)
                return None
            if not (isinstance(stored, tuple) and len(stored) == 2):
                self._discard(path, TypeError("not a pfbench cache entry"))
                return None
            if stored[0] != key:  # two writers raced for one file name: a miss, not damage
                return None
            return path, stored[1]

        def load(self, key):
            found = self.load_entry(key)
            return None if found is None else found[1]

        def save(self, key, data):
            overloads = self._load_index()
            name = overloads.get(key)
            if not isinstance(name, str):
                used = set(overloads.values())
                name = next(n for n in map(self._data_name, itertools.count(1)) if n not in used)
            path = self._data_path(name)
            if os.path.isdir(path) and not os.path.islink(path):
                remove_path(path)  # os.replace cannot put a file over a directory
            self._save_data(name, (key, data))  # data first: an index entry never precedes its data
            if overloads.get(key) != name:
                overloads[key] = name
                self._save_index(overloads)

        def _save_index(self, overloads):
            if os.path.isdir(self._index_path) and not os.path.islink(self._index_path):
                remove_path(self._index_path)
            super()._save_index(overloads)

    class HealingFunctionCache(caching.FunctionCache):
        """numba's per-function disk cache with :class:`HealingIndexDataCacheFile`, a failed rebuild
        treated as damage, and an unwritable directory reported once (the function runs from memory)."""

        def __init__(self, py_func):
            super().__init__(py_func)
            # own file names (".pf.nbi", ".pf.<n>.nbc"): the data files hold (key, data), which
            # numba's own FunctionCache must never try to load
            self._cache_file = HealingIndexDataCacheFile(
                cache_path=self._cache_path, filename_base=self._impl.filename_base + ".pf",
                source_stamp=self._impl.locator.get_source_stamp())

        def _load_overload(self, sig, target_context):
            if not self._enabled:
                return None
            found = self._cache_file.load_entry(self._index_key(sig, target_context.codegen()))
            if found is None:
                return None
            path, payload = found
            try:
                return self._impl.rebuild(target_context, payload)
            except Exception as exc:  # noqa: BLE001 - unpickled, but not code numba can rebuild
                self._cache_file._discard(path, exc)
                return None

        def has_entry(self, sig, target_context) -> bool:
            """Whether the index holds an entry for ``sig`` (its data is checked when loaded)."""
            return bool(self._enabled) and \
                self._index_key(sig, target_context.codegen()) in self._cache_file._load_index()

        def save_overload(self, sig, data):
            try:
                super().save_overload(sig, data)
            except OSError as exc:
                _warn_once(self._cache_path, f"cannot write the compiled-code cache here "
                           f"({type(exc).__name__}: {exc.strerror or exc}); continuing without it")
                self.disable()

    return HealingFunctionCache


@functools.cache
def install() -> None:
    """Put the package-keyed locator first in numba's list, apply the compile settings of
    :mod:`pfbench.backends.codegen` and defer interrupts during compiles
    (:mod:`pfbench.backends.interrupts`) (idempotent)."""
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl")  # renamed in numba 0.6x
    classes = impl._locator_classes
    if not any(getattr(c, "__name__", "") == "PackageKeyedLocator" for c in classes):
        classes.insert(0, _locator_class())
    from .codegen import constant_shape_errors, keep_selects
    from .interrupts import defer_during_compiles

    keep_selects()
    constant_shape_errors()
    defer_during_compiles()


def njit(*args, **options):
    """``numba.njit(cache=True, ...)`` with the package-keyed cache and no C-callable wrapper, the one
    way pfbench compiles; ``cache=False`` for code that cannot be reloaded (models in notebooks)."""
    import numba

    install()
    cache = options.pop("cache", True)
    options.setdefault("no_cfunc_wrapper", True)
    if args and callable(args[0]) and len(args) == 1:
        return _healing(numba.njit(**options)(args[0]), cache)
    decorator = numba.njit(*args, **options)
    return lambda func: _healing(decorator(func), cache)


def _healing(dispatcher, cache: bool):
    """Enable a dispatcher's disk cache with :func:`_healing_cache_class` (numba's ``enable_caching``)."""
    if cache and hasattr(dispatcher, "_cache") and hasattr(dispatcher, "py_func"):
        dispatcher._cache = _healing_cache_class()(dispatcher.py_func)
    return dispatcher
