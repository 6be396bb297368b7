"""Worker pools: stopping one ends its workers now."""
import signal
import time

from pfbench.procs import process_pool, stop_pool


def _hold_sigterm():
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # as a worker does while numba compiles


def _started(path):
    open(path, "w").close()
    time.sleep(120)


def test_stop_pool_ends_a_worker_that_holds_sigterm_back(tmp_path):
    """A worker that holds SIGTERM back (numba compiling: pfbench.backends.interrupts) is ended by
    stop_pool at once, its queued tasks dropped. Catches: SIGTERM (terminate) instead of SIGKILL,
    a shutdown that waits for the running task (which sleeps two minutes)."""
    pool = process_pool(1, initializer=_hold_sigterm)
    mark = tmp_path / "started"
    running = pool.submit(_started, str(mark))
    queued = pool.submit(_started, str(tmp_path / "never"))
    for _ in range(600):  # the worker starts (bounded wait)
        if mark.exists():
            break
        time.sleep(0.05)
    assert mark.exists()
    workers = list(pool._processes.values())
    stop_pool(pool)
    for p in workers:
        p.join(timeout=30)
        assert not p.is_alive()
    assert queued.done() and not (tmp_path / "never").exists()  # cancelled, or failed as broken
    assert running.done()
