"""Ctrl-C and SIGTERM during a numba compile take effect when the compile ends
(:mod:`pfbench.backends.interrupts`): an interrupt raised inside numba's compiler left it half
built (a RuntimeError from its cache writer, or a segmentation fault, instead of exit 130)."""
import signal

import pytest

from pfbench.backends import cache, interrupts


class Stop(Exception):
    pass


@pytest.fixture
def handlers():
    """SIGINT -> KeyboardInterrupt and SIGTERM -> Stop (as a sweep sets it), restored afterwards."""
    cache.install()
    old = {s: signal.getsignal(s) for s in interrupts.SIGNALS}
    calls = []

    def on_term(signum, frame):
        calls.append(signum)
        raise Stop

    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, on_term)
    yield calls
    for s, h in old.items():
        signal.signal(s, h)


def _lock():
    from numba.core.compiler_lock import global_compiler_lock

    return global_compiler_lock


@pytest.mark.parametrize("signum,exc", [(signal.SIGINT, KeyboardInterrupt), (signal.SIGTERM, Stop)])
def test_a_signal_during_a_compile_arrives_when_the_compile_ends(handlers, signum, exc):
    """Nested holds (numba compiles callees inside a compile): the signal waits for the outermost
    release, arrives once, and the handler in place before the compile is back. Catches no
    deferral (the exception inside the lock), a lost signal, delivery at an inner release, and a
    handler left replaced."""
    lock = _lock()
    reached = []
    with pytest.raises(exc):
        with lock:
            with lock:
                signal.raise_signal(signum)
                reached.append("inner")
            reached.append("outer")
    assert reached == ["inner", "outer"]
    assert handlers == ([signal.SIGTERM] if signum == signal.SIGTERM else [])
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.getsignal(signal.SIGTERM) is not interrupts._record


def test_no_signal_no_delivery(handlers):
    """A compile without a signal leaves the handlers as they were and raises nothing."""
    with _lock():
        pass
    assert handlers == []
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
