"""Compiled code that is never stale: every numba disk cache entry of pfbench is keyed on the whole
package source.

numba's own cache keys a compiled function on *its* source file only, so editing a jitted helper
in another module (which the cached function inlined) leaves the old machine code in use. pfbench
therefore installs a numba cache locator for

* every function defined in the installed ``pfbench`` package,
* the generated kernel modules under ``$PFBENCH_CACHE_DIR/kernels``, and
* model source files that a kernel compiles (registered by :func:`track_file`),

whose source stamp is :func:`package_fingerprint` (a hash of every ``.py`` file of the package,
the Python, numba and NumPy versions) combined with the hash of the function's own file. Any edit
anywhere in the package, or in the model's file, changes the stamp, and numba recompiles instead of
loading old code. The entries live under ``$PFBENCH_CACHE_DIR/numba`` (default
``~/.cache/pfbench/numba``), apart from numba's own cache.

:func:`install` runs when ``pfbench`` is imported, before any pfbench module defines a cached
function.
"""
from __future__ import annotations

import hashlib
import os
import sys
import threading
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent.parent
_LOCK = threading.Lock()
_FINGERPRINT: str | None = None
_TRACKED: set[str] = set()


def cache_root() -> Path:
    """``$PFBENCH_CACHE_DIR`` (default ``~/.cache/pfbench``)."""
    root = os.environ.get("PFBENCH_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "pfbench")
    return Path(root)


def package_fingerprint() -> str:
    """Hash of every ``.py`` file of the installed package plus the Python, numba and NumPy versions."""
    global _FINGERPRINT
    with _LOCK:
        if _FINGERPRINT is None:
            import numba
            import numpy

            h = hashlib.sha256()
            h.update(f"{sys.version_info[:3]}|{numba.__version__}|{numpy.__version__}".encode())
            for path in sorted(PACKAGE_DIR.rglob("*.py")):
                if "__pycache__" in path.parts:
                    continue
                h.update(str(path.relative_to(PACKAGE_DIR)).encode() + b"\0")
                h.update(path.read_bytes() + b"\0")
            _FINGERPRINT = h.hexdigest()
        return _FINGERPRINT


def track_file(path) -> None:
    """Key the numba cache of functions defined in ``path`` (a model's file) on the package too."""
    _TRACKED.add(os.path.realpath(str(path)))


def _file_hash(path: str) -> str:
    st = os.stat(path)
    return _hash_cached(path, st.st_mtime_ns, st.st_size)


_HASHES: dict = {}


def _hash_cached(path: str, mtime_ns: int, size: int) -> str:
    key = (path, mtime_ns, size)
    if key not in _HASHES:
        with open(path, "rb") as fh:
            _HASHES[key] = hashlib.sha256(fh.read()).hexdigest()
    return _HASHES[key]


def _covered(py_file: str) -> bool:
    real = os.path.realpath(py_file)
    if real in _TRACKED:
        return True
    for root in (PACKAGE_DIR, cache_root() / "kernels"):
        try:
            Path(real).relative_to(os.path.realpath(root))
            return True
        except ValueError:
            continue
    return False


def _locator_class():
    from numba.core import caching

    class PackageKeyedLocator(caching._CacheLocator):
        """numba cache locator whose freshness stamp covers the whole pfbench package."""

        def __init__(self, py_func, py_file):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = str(cache_root() / "numba" / self.get_suitable_cache_subpath(py_file))

        def get_cache_path(self):
            return self._cache_path

        def get_source_stamp(self):
            return (package_fingerprint(), _file_hash(self._py_file))

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


_INSTALLED = False


def install() -> None:
    """Put the package-keyed locator first in numba's list (idempotent)."""
    global _INSTALLED
    if _INSTALLED:
        return
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl")  # renamed in numba 0.6x
    classes = impl._locator_classes
    if not any(getattr(c, "__name__", "") == "PackageKeyedLocator" for c in classes):
        classes.insert(0, _locator_class())
    _INSTALLED = True


def njit(*args, **options):
    """``numba.njit(cache=True, ...)`` with the package-keyed cache: the one way pfbench compiles a
    disk-cached function. Use as ``@njit`` or ``@njit(nogil=True)``; ``cache=False`` is allowed
    for code that cannot be reloaded (models defined in notebooks)."""
    import numba

    install()
    options.setdefault("cache", True)
    if args and callable(args[0]) and len(args) == 1 and not options.keys() - {"cache"}:
        return numba.njit(**options)(args[0])
    return numba.njit(*args, **options)
