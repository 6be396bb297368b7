"""Worker pools: leaving one by an exception ends its workers now."""
import os
import signal
import time
from pathlib import Path

import pytest

from pfbench.procs import worker_pool


def _hold_sigterm():
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # as a worker does while numba compiles


def _started(path):
    open(path, "w").close()
    time.sleep(120)


def _square(v):
    return v * v


def _ended(p) -> bool:
    """Whether worker process ``p`` has ended. ``is_alive`` alone can stay True when the
    executor's own thread reaped the process first (then waitpid fails and multiprocessing cannot
    tell); the PID being gone, or a zombie, is the answer then."""
    p.join(timeout=30)
    if not p.is_alive():
        return True
    try:
        os.kill(p.pid, 0)
    except ProcessLookupError:
        return True
    try:
        return Path(f"/proc/{p.pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def test_an_exception_ends_a_worker_that_holds_sigterm_back(tmp_path):
    """A worker that holds SIGTERM back (numba compiling: pfbench.backends.interrupts) is ended at
    once when the block is left by an exception (Ctrl-C), its queued tasks dropped. Catches:
    SIGTERM (terminate) instead of SIGKILL, a shutdown that waits for the running task (which
    sleeps two minutes: the test would take that long)."""
    mark = tmp_path / "started"
    with pytest.raises(KeyboardInterrupt):
        with worker_pool(1, initializer=_hold_sigterm) as pool:
            pool.submit(_started, str(mark))
            pool.submit(_started, str(tmp_path / "never"))
            for _ in range(600):  # the worker starts (bounded wait)
                if mark.exists():
                    break
                time.sleep(0.05)
            assert mark.exists()
            workers = list(pool._processes.values())
            raise KeyboardInterrupt
    for p in workers:
        assert _ended(p)
    # the queued task never ran (its futures are failed by the executor's own thread, some time later)
    assert not (tmp_path / "never").exists()


def test_a_block_left_normally_waits_for_the_results():
    """Catches: killing the workers on a normal exit too."""
    with worker_pool(2) as pool:
        futures = [pool.submit(_square, v) for v in range(6)]
    assert [f.result() for f in futures] == [v * v for v in range(6)]


def _helper_allowed(_):
    import os

    from pfbench.backends import compile_helper

    return os.environ.get(compile_helper.ENV, "1") != "0"  # enabled() less its core count


def test_workers_of_a_shared_pool_start_no_compile_helpers(monkeypatch):
    """A pool of two or more already spreads over the cores: its workers start no compile helpers
    (pfbench.backends.compile_helper) on top; a one-worker pool may. Catches: helpers in every
    sweep worker (twice the processes on the cores while kernels compile)."""
    monkeypatch.delenv("PFBENCH_COMPILE_HELPER", raising=False)
    with worker_pool(2) as pool:
        assert list(pool.map(_helper_allowed, range(4))) == [False] * 4
    with worker_pool(1) as pool:
        assert list(pool.map(_helper_allowed, range(2))) == [True] * 2


def test_cgroup_quota_is_read_from_v2_and_v1_files(tmp_path):
    """A container's CPU quota caps the cores: catches a quota read as cores per period the wrong
    way round, and "max" (no quota) read as a number."""
    from pfbench.procs import cgroup_cpu_quota

    (tmp_path / "cpu.max").write_text("150000 100000\n")
    assert cgroup_cpu_quota(str(tmp_path)) == 1.5
    (tmp_path / "cpu.max").write_text("max 100000\n")
    assert cgroup_cpu_quota(str(tmp_path)) is None
    (tmp_path / "cpu.max").unlink()
    (tmp_path / "cpu").mkdir()
    (tmp_path / "cpu" / "cpu.cfs_quota_us").write_text("300000\n")
    (tmp_path / "cpu" / "cpu.cfs_period_us").write_text("100000\n")
    assert cgroup_cpu_quota(str(tmp_path)) == 3.0
    (tmp_path / "cpu" / "cpu.cfs_quota_us").write_text("-1\n")
    assert cgroup_cpu_quota(str(tmp_path)) is None


def test_free_cores_leaves_out_the_cores_other_processes_keep_busy():
    """With more spinning processes than cores, a parallel region gets one thread (the default
    thread count that kept a filter from collapsing on a busy machine); catches free_cores ignoring
    the load, and the kernel not asking it."""
    import subprocess
    import sys
    import time

    from pfbench.backends.numba_backend import free_cores as used_by_the_kernel
    from pfbench.bench.busy import SPIN
    from pfbench.procs import free_cores, usable_cores

    assert used_by_the_kernel is free_cores
    procs = [subprocess.Popen([sys.executable, "-c", SPIN]) for _ in range(usable_cores() + 2)]
    try:
        time.sleep(0.5)
        assert free_cores() == 1
    finally:
        for p in procs:
            p.kill()
            p.wait()


def test_a_thread_budget_caps_free_cores_and_reaches_a_pools_workers(monkeypatch):
    """A pool given ``threads`` (the sweep's) starts its workers with numba's pool, BLAS and the
    filters' default thread count held to it. Catches workers that each take every free core
    (W workers x cores threads) and a budget set too late for numba to see it."""
    from pfbench.procs import THREADS_ENV, free_cores, thread_env, worker_pool

    monkeypatch.setenv(THREADS_ENV, "1")
    assert free_cores() == 1
    monkeypatch.setenv(THREADS_ENV, "junk")     # not a count: no budget
    assert free_cores() >= 1
    monkeypatch.delenv(THREADS_ENV)
    import multiprocessing as mp

    with worker_pool(2, mp_context=mp.get_context("spawn"), threads=1) as pool:
        seen = pool.submit(_thread_view).result()
    assert seen == ({k: "1" for k in thread_env(1)}, 1, 1)
    assert THREADS_ENV not in __import__("os").environ      # the parent's environment is restored


def _thread_view():
    import os

    import numba

    from pfbench.procs import free_cores, thread_env

    return {k: os.environ.get(k) for k in thread_env(1)}, numba.config.NUMBA_NUM_THREADS, free_cores()
