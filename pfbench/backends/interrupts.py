"""Ctrl-C and SIGTERM during a numba compile take effect when the compile ends.

Python delivers a signal to the main thread between two bytecodes, wherever they are. A
``KeyboardInterrupt`` raised inside numba's compiler (its type inference, code generation and
cache writer are Python code) leaves numba's and LLVM's state half built: the process then fails
with an unrelated error ("no compiled object yet for <Library 'run_group'>") or a segmentation
fault instead of exiting with 130 and its finished work saved.

:func:`defer_during_compiles` makes numba's global compiler lock, held through every compile and
every load from the disk cache, hold SIGINT and SIGTERM back: while the main thread holds it, such
a signal is only recorded; when the lock is released (the compile complete and consistent) the
previous handlers are restored and called, so the interrupt arrives, seconds late at most, in
ordinary Python code. Other threads need nothing: signals are handled in the main thread only.

:func:`held` does the same around a call of compiled code that takes NumPy Generators: numba
unboxes a Generator by calling ``ctypes.cast`` (Python code, where a pending signal's handler runs)
and does not check that call for an exception, so an interrupt raised there ended the process with
a segmentation fault. Compiled code never runs a handler anyway, so holding the signals back until
the call returns delays nothing.
"""
from __future__ import annotations

import contextlib
import signal
import threading

#: the signals held back during a compile
SIGNALS = (signal.SIGINT, signal.SIGTERM)
_STATE = {"depth": 0, "saved": None, "pending": []}


def _record(signum, frame):
    _STATE["pending"].append(signum)


def _hold() -> None:
    """Start holding SIGINT and SIGTERM back (main thread only; nests)."""
    if threading.current_thread() is threading.main_thread():
        if _STATE["depth"] == 0:  # (a handler not set from Python, None, is left alone)
            _STATE["saved"] = {s: signal.signal(s, _record) for s in SIGNALS
                               if signal.getsignal(s) is not None}
        _STATE["depth"] += 1


def _let_go(then=None) -> None:
    """End one :func:`_hold`, call ``then`` (the compiler lock's release), and at the outermost
    restore the handlers and deliver the signals that arrived meanwhile."""
    saved, pending = {}, []
    if threading.current_thread() is threading.main_thread() and _STATE["depth"] > 0:
        _STATE["depth"] -= 1
        if _STATE["depth"] == 0:
            saved, _STATE["saved"] = _STATE["saved"], None
            for s, handler in saved.items():
                signal.signal(s, handler)
            pending, _STATE["pending"] = _STATE["pending"], []
    if then is not None:
        then()
    for signum in pending:
        handler = saved.get(signum)
        if callable(handler):
            handler(signum, None)  # e.g. KeyboardInterrupt, or a sweep's SIGTERM handler
        elif handler == signal.SIG_DFL:
            signal.raise_signal(signum)  # the default action, now that the handler is restored


@contextlib.contextmanager
def held():
    """SIGINT and SIGTERM held back while the block runs in the main thread, and delivered when
    it ends (see the module docstring)."""
    _hold()
    try:
        yield
    finally:
        _let_go()


def defer_during_compiles() -> bool:
    """Wrap numba's global compiler lock so the main thread defers SIGINT/SIGTERM while it holds
    the lock (idempotent). Returns whether the lock now defers them (False: a numba whose lock
    has another layout, left as it is)."""
    try:
        from numba.core.compiler_lock import global_compiler_lock as lock
    except ImportError:  # pragma: no cover - another numba layout
        return False
    if getattr(lock, "_pfbench_defers", False):
        return True
    acquire, release = getattr(lock, "acquire", None), getattr(lock, "release", None)
    if acquire is None or release is None:  # pragma: no cover - another numba layout
        return False

    def deferring_acquire():
        acquire()
        _hold()

    lock.acquire, lock.release = deferring_acquire, lambda: _let_go(release)
    lock._pfbench_defers = True
    return True
