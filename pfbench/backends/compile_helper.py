"""A cold kernel compiled on two cores: the model's part in a helper process, the driver here.

A filter kernel in no cache is two compiles that do not need each other: the functions that
inline the model (the particle kernel's pass A; the MPF kernel's calls of the model's ``cl_*``
functions) and the driver with the model-free passes, which calls the model's part through its
native entry point (:mod:`pfbench.backends.native_call`) and so needs its signature, not its code.
numba compiles one function at a time per process (one global compiler lock).

With two or more usable cores, when the driver and any of those functions are missing from the
disk cache, :func:`pfbench.backends.numba_backend.native_addresses` calls :func:`start`: a new
Python (``python -c`` with this process's import path; the model's module by name, or a user's
model file by its path) is handed the model class, the kernel family, the tile layout and the
functions' names and argument types, and compiles them into the same disk cache
(:mod:`pfbench.backends.cache`) while this process compiles the driver, then waits for it and loads
the functions from disk. The caller chooses what stays here (``here`` of ``native_addresses``),
to balance the two cores.

The helper only ever saves time. Whatever goes wrong there (an import error, a compile error, a
crash, a kill) leaves no cache entry, and this process compiles the functions itself, raising any
error as it would without a helper. The helper dies with this process
(:func:`pfbench.procs.die_with_parent`) and is killed if the driver's compile ends by an interrupt
or an error.

Not used: with one usable core, in pfbench's pool workers (the pool already uses every core), for
a model that numba cannot cache on disk or that lives in ``__main__``, and when
``PFBENCH_COMPILE_HELPER=0``.
"""
from __future__ import annotations

import os
import pickle
import subprocess
import sys

from ..procs import usable_cores

#: set to "0" to compile everything in the calling process
ENV = "PFBENCH_COMPILE_HELPER"


def enabled() -> bool:
    """Whether a helper may be started from this process (two cores, not switched off)."""
    return os.environ.get(ENV, "1") != "0" and usable_cores() >= 2


def disable() -> None:
    """Start no helpers from this process (and its children), e.g. in a pool worker."""
    os.environ[ENV] = "0"


def cold(dispatcher, argtypes: tuple) -> bool:
    """Whether ``dispatcher`` has ``argtypes`` neither compiled in this process nor in its disk
    cache (False for a dispatcher without pfbench's disk cache: a helper could not hand it over)."""
    if tuple(argtypes) in dispatcher.overloads:
        return False
    has_entry = getattr(dispatcher._cache, "has_entry", None)  # pfbench's HealingFunctionCache
    return has_entry is not None and not has_entry(tuple(argtypes), dispatcher.targetctx)


def stop(proc: subprocess.Popen) -> None:
    """Kill a helper still running (its work is no longer wanted: an interrupt or an error here);
    SIGKILL, as it holds SIGTERM back while numba compiles (:mod:`pfbench.backends.interrupts`)."""
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def start(model_cls: type, family: str, f_tiles: bool, functions) -> subprocess.Popen | None:
    """Compile ``functions``, a list of ``(name, argument types)``, of the any-scheme kernel module
    of ``model_cls`` for the kernel ``family`` (:func:`pfbench.backends.kernels.build`
    with ``scheme=None``) in a helper process, into the disk cache; None when no helper is used
    (see the module docstring) or it cannot be started."""
    if not enabled() or model_cls.__module__ == "__main__":
        return None
    functions = [(name, tuple(argtypes)) for name, argtypes in functions]
    spec = {"module": model_cls.__module__, "qualname": model_cls.__qualname__, "family": family,
            "file": getattr(sys.modules.get(model_cls.__module__), "__file__", None), "f_tiles": bool(f_tiles),
            "functions": functions, "parent": os.getpid()}
    try:
        proc = subprocess.Popen([sys.executable, "-c", _BOOT], stdin=subprocess.PIPE,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return None
    try:  # this process's import path first, so the helper imports the pfbench and model it uses
        proc.stdin.write(pickle.dumps((list(sys.path), pickle.dumps(spec))))
        proc.stdin.close()
    except OSError:  # it died at once: compile here
        stop(proc)
        return None
    return proc


#: the helper's program: this process's import path, then :func:`_main` with the spec (numba types,
#: unpickled once the path is set); ``os._exit`` at the end: the cache files are closed by then, and
#: the waiting process need not sit through the teardown of numba's and LLVM's objects
_BOOT = ("import os, pickle, sys\n"
         "path, spec = pickle.loads(sys.stdin.buffer.read())\n"
         "sys.path[:] = path\n"
         "from pfbench.backends.compile_helper import _main\n"
         "os._exit(_main(pickle.loads(spec)))\n")


def _main(spec: dict) -> int:
    """Compile the functions of ``spec`` (:func:`start`) of the model's any-scheme kernel module into
    the disk cache; runs in the helper."""
    from pfbench.procs import die_with_parent

    die_with_parent(spec["parent"])
    from pfbench.backends import native_call
    from pfbench.backends.kernels import build, model_class_by_name
    from pfbench.models import import_path

    try:
        model_cls = model_class_by_name(spec["module"], spec["qualname"])
    except ImportError:  # a user's model file (pfbench.models.load_files): imported under the same name
        import_path(spec["module"], spec["file"])
        model_cls = model_class_by_name(spec["module"], spec["qualname"])
    mod = build(spec["family"], model_cls, None, f_tiles=spec["f_tiles"])
    for name, argtypes in spec["functions"]:
        native_call.entry_address(getattr(mod, name), argtypes)
    return 0
