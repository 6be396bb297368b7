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
"""
from __future__ import annotations

import signal
import threading

#: the signals held back during a compile
SIGNALS = (signal.SIGINT, signal.SIGTERM)
_STATE = {"depth": 0, "saved": None, "pending": []}


def _record(signum, frame):
    _STATE["pending"].append(signum)


def _deliver(saved: dict, pending: list) -> None:
    for signum in pending:
        handler = saved.get(signum)
        if callable(handler):
            handler(signum, None)  # e.g. KeyboardInterrupt, or a sweep's SIGTERM handler
        elif handler == signal.SIG_DFL:
            signal.raise_signal(signum)  # the default action, now that the handler is restored


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
        if threading.current_thread() is threading.main_thread():
            if _STATE["depth"] == 0:  # (a handler not set from Python, None, is left alone)
                _STATE["saved"] = {s: signal.signal(s, _record) for s in SIGNALS
                                   if signal.getsignal(s) is not None}
            _STATE["depth"] += 1

    def deferring_release():
        deliver = None
        if threading.current_thread() is threading.main_thread() and _STATE["depth"] > 0:
            _STATE["depth"] -= 1
            if _STATE["depth"] == 0:
                saved, _STATE["saved"] = _STATE["saved"], None
                for s, handler in saved.items():
                    signal.signal(s, handler)
                pending, _STATE["pending"] = _STATE["pending"], []
                deliver = (saved, pending)
        release()
        if deliver and deliver[1]:
            _deliver(*deliver)

    lock.acquire, lock.release = deferring_acquire, deferring_release
    lock._pfbench_defers = True
    return True
