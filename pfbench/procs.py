"""Worker processes that die with their parent, and one writer per output (advisory file locks).

Every process pool of pfbench is made by :func:`process_pool`. Its workers

* ask the kernel for ``SIGKILL`` when the parent dies (Linux ``prctl(PR_SET_PDEATHSIG)``, set in
  the worker initializer through ``ctypes``), so a ``kill -9`` of ``pfbench sweep`` or
  ``pfbench reproduce`` leaves no idle workers behind;
* also run a daemon thread that ends the worker as soon as ``os.getppid()`` changes (the worker
  was re-parented), the fallback where ``prctl`` is unavailable (other Unixes) and for the one
  case ``PR_SET_PDEATHSIG`` misses: the parent died before the worker set it.

:func:`exclusive_lock` gives one writer per output: an ``fcntl.flock`` on ``<output>.lock``. The
kernel drops the lock when its holder dies (also on ``kill -9``), so a lock left by a killed run
is taken over without any stale-lock guesswork; a live holder makes the second command refuse
with the holder's PID (the PID written into the lock file). The lock file is opened without
following links and removed on release (:func:`exclusive_lock` says why that is race-free).

A pool given ``threads`` (the sweep's) starts its workers with that thread budget in their
environment (:func:`thread_env`): numba's thread pool, OpenMP and BLAS are sized to it before any
of them is loaded, and :func:`free_cores` (the default thread count of a filter) never exceeds it
in the worker, so W workers of ``cores / W`` threads never ask for more cores than there are.
"""
from __future__ import annotations

import contextlib
import errno
import os
import signal
import sys
import threading
from pathlib import Path
from typing import Callable, Iterator

from .errors import DataError, InputError

#: seconds between two parent checks of the fallback watcher thread
WATCH_INTERVAL_S = 0.5
_PR_SET_PDEATHSIG = 1


def _set_parent_death_signal() -> bool:
    """``prctl(PR_SET_PDEATHSIG, SIGKILL)`` on Linux; False where it is not available."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
    except (OSError, AttributeError):  # pragma: no cover - no libc/prctl
        return False


def _watch_parent(parent_pid: int) -> None:
    stop = threading.Event()
    while not stop.wait(WATCH_INTERVAL_S):
        if os.getppid() != parent_pid:
            os._exit(1)


def die_with_parent(parent_pid: int) -> None:
    """Make this (worker) process end when ``parent_pid`` ends (see the module docstring)."""
    _set_parent_death_signal()
    if os.getppid() != parent_pid:  # the parent died before prctl took effect
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent_pid,), name="pfbench-parent-watch",
                     daemon=True).start()


def usable_cores() -> int:
    """The cores this process may run on: its CPU affinity (``os.cpu_count()`` where that is not
    available), capped by a cgroup CPU quota (a container given 1.5 CPUs gets 1): the default number
    of sweep workers and compile jobs."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    quota = cgroup_cpu_quota()
    return max(1, min(cores, int(quota))) if quota is not None else cores


def cgroup_cpu_quota(root: str = "/sys/fs/cgroup") -> float | None:
    """CPUs the cgroup quota allows (cgroup v2 ``cpu.max``, else v1 ``cpu.cfs_quota_us`` /
    ``cpu.cfs_period_us``); None when there is no quota or it cannot be read."""
    try:
        quota, period = Path(root, "cpu.max").read_text().split()[:2]
        return None if quota == "max" else int(quota) / int(period)
    except (OSError, ValueError):
        pass
    try:
        quota = int(Path(root, "cpu", "cpu.cfs_quota_us").read_text())
        period = int(Path(root, "cpu", "cpu.cfs_period_us").read_text())
        return quota / period if quota > 0 and period > 0 else None
    except (OSError, ValueError):
        return None


def _runnable_elsewhere() -> int:
    """Threads of other processes that are running or waiting for a core right now: the kernel's
    runnable count (``/proc/loadavg``, 4th field) less this process's own running threads (numba's
    pool may still be spinning after its last parallel region). 0 where /proc is not there."""
    try:
        running = int(Path("/proc/loadavg").read_text().split()[3].split("/")[0])
    except (OSError, ValueError, IndexError):
        return 0
    own = 0
    try:
        for task in os.scandir("/proc/self/task"):
            try:
                stat = Path(task.path, "stat").read_text()
            except OSError:
                continue
            if stat[stat.rindex(")") + 2:].startswith("R"):
                own += 1
    except OSError:
        own = 1
    return max(0, running - own)


#: environment variable: the most threads a filter of this process may use (set by a pool given
#: ``threads`` for its workers, :func:`thread_env`; a user may set it too)
THREADS_ENV = "PFBENCH_THREADS"


def thread_limit() -> int | None:
    """The thread budget of this process (``$PFBENCH_THREADS``, an integer >= 1), None if unset or
    not a positive integer."""
    try:
        n = int(os.environ.get(THREADS_ENV, ""))
    except ValueError:
        return None
    return n if n >= 1 else None


def thread_env(threads: int) -> dict:
    """The environment that holds a process to ``threads`` threads: numba's pool
    (``NUMBA_NUM_THREADS``, read when numba is imported), OpenMP and the BLAS libraries (read when
    NumPy loads them) and pfbench's own budget (:data:`THREADS_ENV`, read by :func:`free_cores`)."""
    n = str(max(1, int(threads)))
    return {THREADS_ENV: n, "NUMBA_NUM_THREADS": n, "OMP_NUM_THREADS": n, "OPENBLAS_NUM_THREADS": n,
            "MKL_NUM_THREADS": n}


def worker_threads(workers: int) -> int:
    """Threads each of ``workers`` processes may use so that together they use no more than the
    cores free now (:func:`free_cores`): ``free_cores() // workers``, at least 1."""
    return max(1, free_cores() // max(1, int(workers)))


@contextlib.contextmanager
def _environ(env: dict) -> Iterator[None]:
    """``os.environ`` updated with ``env`` while the block runs (a child started meanwhile inherits it)."""
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def numba_threads() -> int:
    """The threads numba may start in this process (``NUMBA_NUM_THREADS``, by default the cores)."""
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def free_cores() -> int:
    """How many cores a parallel region of this process can have to itself now: :func:`usable_cores`
    less the threads of other processes that are runnable, at least 1, and at most this process's
    thread budget (:func:`thread_limit`, set in the workers of a pool given ``threads``).

    Why: a parallel kernel waits at a barrier for its slowest thread a few times per step; on a
    core shared with another busy process that thread is descheduled for a whole time slice, and a
    run with all cores' threads became many times slower than with one thread. Asking for no more
    threads than there are free cores keeps the default from collapsing on a busy machine."""
    free = max(1, usable_cores() - _runnable_elsewhere())
    limit = thread_limit()
    return free if limit is None else min(free, limit)


def _init_worker(parent_pid: int, shared: bool, model_files: list, initializer: Callable | None,
                 initargs: tuple, threads: int | None = None) -> None:
    die_with_parent(parent_pid)
    if threads is not None:  # a worker forked later than the pool's start: the budget all the same
        os.environ.update(thread_env(threads))
    if shared:  # the pool's workers already use the cores: no compile helpers on top of them
        from .backends import compile_helper

        compile_helper.disable()
    if model_files:  # a model name must mean the same class in every process
        from .models import load_files

        load_files(model_files)
    if initializer is not None:
        initializer(*initargs)


def process_pool(max_workers: int, *, mp_context=None, initializer: Callable | None = None,
                 initargs: tuple = (), threads: int | None = None):
    """A ``concurrent.futures.ProcessPoolExecutor`` whose workers die with this process.

    Same arguments as the executor's; ``initializer(*initargs)`` runs after the worker has
    arranged to die with its parent. Create the pool from the main thread: the parent-death
    signal fires when the *thread* that started the worker ends. The workers of a pool of two or
    more start no compile helpers (:mod:`pfbench.backends.compile_helper`): the pool already
    spreads over the cores. Each worker loads the user model files this process has loaded
    (:func:`pfbench.models.loaded_files`), after the built-ins, as this process did.

    ``threads``: each worker's thread budget (:func:`thread_env`; e.g. :func:`worker_threads`). The
    workers are then started at once, inside that environment, so numba and the BLAS libraries
    size their pools to it when the worker imports them (with ``spawn`` or ``forkserver`` all
    workers start here; a ``fork`` worker started later gets :data:`THREADS_ENV` in its
    initializer, while numba keeps the parent's pool size).
    """
    from concurrent.futures import ProcessPoolExecutor

    from .models import loaded_files

    args = (os.getpid(), max_workers > 1, loaded_files(), initializer, initargs, threads)
    if threads is None:
        return ProcessPoolExecutor(max_workers=max_workers, mp_context=mp_context, initializer=_init_worker,
                                   initargs=args)
    with _environ(thread_env(threads)):
        pool = ProcessPoolExecutor(max_workers=max_workers, mp_context=mp_context, initializer=_init_worker,
                                   initargs=args)
        pool.submit(int)  # starts the workers now, in this environment (and while the caller prepares)
    return pool


@contextlib.contextmanager
def worker_pool(max_workers: int, **kwargs) -> Iterator:
    """A :func:`process_pool` for a ``with`` block: left normally, it waits for its tasks; left by an
    exception (Ctrl-C, SIGTERM turned into one, an error) it kills its live workers and drops the
    queued tasks at once instead of waiting for the running ones. SIGKILL, not SIGTERM: a worker
    holds SIGTERM back while numba compiles (:mod:`pfbench.backends.interrupts`), which protects a
    process that goes on, not one that ends; what a killed task was writing is abandoned whole
    (pfbench's outputs and compile caches are written to a temporary name and renamed)."""
    pool = process_pool(max_workers, **kwargs)
    try:
        yield pool
    except BaseException:
        for p in list((getattr(pool, "_processes", None) or {}).values()):
            if p.is_alive():
                p.kill()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def lock_path(output) -> Path:
    """The lock file of an output: ``<output>.lock`` beside it."""
    output = Path(output)
    return output.with_name(output.name + ".lock")


def writer_of(output) -> str | None:
    """Who holds the lock of ``output`` now (e.g. ``"PID 123"``), None if nobody does: a reader of an
    output being written (a sweep store) can say that what it read is partial."""
    import fcntl

    path = lock_path(output)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)  # released by the close below
    except BlockingIOError:
        return _holder(path)
    except OSError:
        return None
    finally:
        os.close(fd)
    return None


def _holder(path: Path) -> str:
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        try:
            pid = os.read(fd, 32).decode("ascii", "replace").strip()
        finally:
            os.close(fd)
    except OSError:
        pid = ""
    return f"PID {pid}" if pid.isdigit() else "another process"


def _open_lock(path: Path, output, flag: str) -> int:
    """Open (create) the lock file ``path`` without following a link: a symbolic link there (or a
    file that is not a plain file of its own) is refused, so a link planted at ``<output>.lock``
    cannot make pfbench truncate and write the file it points to."""
    import stat

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o666)
    except OSError as exc:
        if exc.errno == errno.ELOOP and path.is_symlink():
            raise DataError(f"lock file {path} is a symbolic link; pfbench does not write through links: "
                            "remove it and re-run") from None
        from .resources import path_error

        raise path_error(exc, output, flag) from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode) or st.st_nlink > 1:  # 0: just removed by its holder (retried)
        os.close(fd)
        raise DataError(f"lock file {path} is not a plain file of its own (a hard link, device or pipe); "
                        "remove it and re-run")
    return fd


def _same_file(fd: int, path: Path) -> bool:
    """Whether ``path`` still names the file open as ``fd`` (a releasing holder unlinks it)."""
    try:
        a, b = os.fstat(fd), os.lstat(path)
    except OSError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


@contextlib.contextmanager
def exclusive_lock(output, what: str, flag: str = "--out") -> Iterator[Path]:
    """Hold the advisory lock of ``output`` (a path) while the block runs, or refuse.

    Raises :class:`~pfbench.errors.InputError` naming the holder's PID if another live process
    holds it, a :class:`~pfbench.errors.DataError` naming ``output`` and ``flag`` if its directory
    cannot be used or the lock file is a symbolic link. ``what`` names the output in the message
    (e.g. ``"sweep store x.jsonl"``).

    The lock file is removed on release, without racing another process: the holder unlinks it
    while it still holds the ``flock``, and an acquirer, once it has the ``flock``, checks that the
    path still names the file it locked (a process that opened the file just before it was
    unlinked gets the lock of a file nobody can find again); if not, it opens the path afresh.
    A lock file left by a killed holder (the kernel dropped its flock) is simply taken over.
    """
    import fcntl

    path = lock_path(output)
    while True:
        fd = _open_lock(path, output, flag)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise InputError(f"{what} is being written by {_holder(path)} (lock {path}); wait for "
                             "it to finish or stop it, then re-run") from None
        if _same_file(fd, path):
            break
        os.close(fd)  # the previous holder removed it as we locked it: lock the current file
    try:
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        except OSError:  # e.g. a full disk: the PID is only for the message of a second writer
            pass
        yield path
    finally:
        try:
            if _same_file(fd, path):
                os.unlink(path)
        except OSError:  # a directory that became read-only: the stale file is taken over later
            pass
        os.close(fd)  # releases the flock


__all__ = ["process_pool", "die_with_parent", "exclusive_lock", "lock_path", "thread_env", "thread_limit",
           "worker_threads"]
