"""Run a sweep on local processes or a Dask cluster, appending finished tasks to the store.

Executors
---------
``local`` (default): ``workers`` processes (``spawn``); ``workers=1`` runs in this process.
``dask``: ``scheduler="tcp://host:port"`` connects to a running cluster; without it a
``distributed.LocalCluster`` on 127.0.0.1 with ``workers`` single-threaded processes is started
(and closed afterwards). Every executor computes the same numbers (see :mod:`.core`).

Workers start once: a local worker imports pfbench and loads the spec's kernels in its
initializer, a Dask worker on its first unit, and then takes unit after unit. Each runs its
filters on one thread; a local pool's (and a LocalCluster's) workers are also held to
``free cores / workers`` threads in all (:func:`pfbench.procs.worker_threads`), so no filter
default, numba pool or BLAS library oversubscribes the machine. A remote cluster's workers, which
pfbench did not start, each take usable cores // the Dask threads of all workers on their host
(:func:`_share_host`).

Work units
----------
A task is one (run, configuration); a unit is a list of (run, configurations) groups, each group
one simulated trajectory filtered by its configurations (:func:`pfbench.sweep.core.run_chunk`).
:class:`Planner` cuts the units while the sweep runs, from the task times measured so far (and
those of a resumed store): a unit takes at most ``1 / (SHARE x workers)`` of the estimated work
still to hand out (guided self-scheduling: large units early, small ones at the end, so the
workers finish together), but no less than :data:`MIN_UNIT_S` (tiny tasks are batched: several
runs in a unit) and no more than :data:`MAX_UNIT_S`. A run much longer than the unit is split by
configuration, the largest tasks first. Until the first time is measured, a unit is at most one
run, and only one unit per worker is out.

A unit is written to the store in one append when it is done, so a killed worker loses at most
its current unit, and a resumed sweep never reruns a written task. At most ``2 x workers`` units
are in flight; Ctrl-C or SIGTERM stops the sweep after terminating the workers, keeping every
unit already written; re-running resumes. Local workers die with the sweep, also after
``kill -9`` (:func:`pfbench.procs.worker_pool`).

Before any work: ``workers`` must be >= 1 (``None``: all cores), the store must be ``.jsonl`` or
``.parquet``, the largest task must fit in memory once per worker (:func:`check_sweep_memory`),
and no other process may be writing the same store: a second sweep on the same ``out`` refuses
with the holder's PID (:func:`pfbench.procs.exclusive_lock`; a lock left by a killed sweep is
free again, the kernel releases it with its holder).
"""
from __future__ import annotations

import math
import numbers
import os
import re
import signal
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError, PfbenchError, UnknownNameError
from ..procs import exclusive_lock, thread_env, usable_cores, worker_pool, worker_threads
from ..resources import path_error
from .core import n_tasks, run_chunk, task_key, warm_up
from .store import Store, check_store_name, export_parquet, finished_export


@dataclass
class SweepReport:
    store: Path
    total: int
    done_before: int
    done_now: int
    wall_s: float
    #: finished tasks whose log-likelihood is -inf or NaN (every particle's likelihood was zero,
    #: NaN or infinite at some step): the model's trouble, said as ``pfbench run`` says it
    non_finite_loglik: int = 0
    #: finished tasks in which the model returned NaN or +inf log-likelihoods for some particles
    #: (weight zero; the record's ``invalid_loglik`` counts them)
    tasks_with_invalid_loglik: int = 0

    @property
    def tasks_per_s(self) -> float:
        return self.done_now / self.wall_s if self.wall_s > 0 else float("nan")


def pending_units(spec: dict, store: Store) -> list[tuple[int, list[int]]]:
    """The tasks not in ``store``, by run: ``[(run, [config indices])]`` in run order."""
    units = []
    for r in range(spec["runs"]):
        cis = [ci for ci in range(len(spec["configs"])) if task_key(ci, r) not in store.records]
        if cis:
            units.append((r, cis))
    return units


#: the least a unit should take (estimated seconds): below it the per-unit costs (a round trip to
#: the worker, one journal write with fsync, one trajectory simulated per run) start to weigh
MIN_UNIT_S = 0.2
#: the most a unit should take: a killed worker loses its current unit, and progress shows per unit
MAX_UNIT_S = 2.0
#: a unit takes at most 1 / (SHARE x workers) of the estimated work still to hand out
SHARE = 4


def task_seconds(record: dict) -> float | None:
    """A finished task's own time: a sweep record's ``elapsed_s`` (a compare record's ``wall_s``)."""
    v = record.get("elapsed_s", record.get("wall_s"))
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) and v >= 0 else None


def _prior(config) -> float:
    """Relative cost of a configuration before any is measured: 100 + N_p for a sweep's
    (method, N_p, N_f) (a task's fixed cost is about that of 100 particles), 1 otherwise."""
    if len(config) > 1 and isinstance(config[1], int) and not isinstance(config[1], bool):
        return 100.0 + config[1]
    return 1.0


class Planner:
    """Cuts the pending tasks into work units as the sweep goes (see the module docstring).

    ``pending``: ``[(run, [config indices])]`` (:func:`pending_units`); ``records``: finished tasks
    whose times seed the estimates (a resumed store's). :meth:`next_unit` hands out the next unit
    (``[(run, [config indices])]``, None when all are handed out); :meth:`learn` takes a finished
    unit's records and wall time. Only the cutting depends on the times: every task is handed out
    exactly once, whatever they are.
    """

    def __init__(self, spec: dict, pending, workers: int, records=()):
        n = len(spec["configs"])
        self.queue = deque([int(r), list(cis)] for r, cis in pending)
        self.workers = max(1, int(workers))
        self.prior = [_prior(c) for c in spec["configs"]]
        self.left = [0] * n  # tasks of each configuration not handed out yet
        for _, cis in self.queue:
            for ci in cis:
                self.left[ci] += 1
        self.sum_s, self.count = [0.0] * n, [0] * n
        self.extra_s, self.groups = 0.0, 0  # unit time beyond its tasks', and the groups it was spent on
        for rec in records:
            self._learn_task(rec)

    def _learn_task(self, rec: dict) -> None:
        s, ci = task_seconds(rec), rec.get("config")
        if s is not None and isinstance(ci, int) and 0 <= ci < len(self.count):
            self.sum_s[ci] += s
            self.count[ci] += 1

    def learn(self, groups, records, wall_s: float) -> None:
        """Take the records and wall time of a finished unit ``groups``."""
        for rec in records:
            self._learn_task(rec)
        own = sum(task_seconds(r) or 0.0 for r in records)
        self.extra_s += max(0.0, float(wall_s) - own)
        self.groups += len(groups)

    @property
    def known(self) -> bool:
        """Whether a task time has been measured (then costs are seconds, else relative)."""
        return any(self.count)

    def costs(self) -> tuple[list[float], float]:
        """(estimated cost of one task of each configuration, cost of a group beyond its tasks):
        seconds once a time is known (an unmeasured configuration scaled from the measured ones
        by :func:`_prior`), else relative (:func:`_prior`, no group cost)."""
        if not self.known:
            return list(self.prior), 0.0
        mean = [s / c if c else None for s, c in zip(self.sum_s, self.count)]
        seen = [i for i, m in enumerate(mean) if m is not None]
        scale = sum(mean[i] for i in seen) / sum(self.prior[i] for i in seen)
        extra = self.extra_s / self.groups if self.groups else 0.0
        return [m if m is not None else scale * p for m, p in zip(mean, self.prior)], extra

    def next_unit(self) -> list[tuple[int, list[int]]] | None:
        """The next unit: whole runs while it is below its target size, or, for a run longer than
        twice the target, a piece of it (the largest tasks first)."""
        if not self.queue:
            return None
        cost, extra = self.costs()
        remaining = sum(k * c for k, c in zip(self.left, cost)) + extra * len(self.queue)
        share = remaining / (SHARE * self.workers)
        if self.known:
            target = min(max(share, MIN_UNIT_S), MAX_UNIT_S)
        else:  # relative costs: at most one run until a time is measured
            target = min(share, extra + sum(cost[ci] for ci in self.queue[0][1]))
        unit, acc = [], 0.0
        while self.queue and acc < target:
            r, cis = self.queue[0]
            group = extra + sum(cost[ci] for ci in cis)
            if unit and acc + group > 2 * target:
                break  # a long run waits for a unit of its own
            if group <= 2 * target or len(cis) == 1:
                self.queue.popleft()
                unit.append((r, cis))
                acc += group
            else:  # split the run: this unit takes about group / pieces of it
                piece = group / math.floor(group / target) if target > 0 else group
                take, a = set(), extra
                for ci in sorted(cis, key=lambda c: -cost[c]):
                    if take and a >= piece:
                        break
                    take.add(ci)
                    a += cost[ci]
                unit.append((r, [ci for ci in cis if ci in take]))
                rest = [ci for ci in cis if ci not in take]
                if rest:
                    self.queue[0][1] = rest
                else:
                    self.queue.popleft()
                acc += a
                break
        for _, cis in unit:
            for ci in cis:
                self.left[ci] -= 1
        return unit


class _Sigterm:
    """Turn SIGTERM into KeyboardInterrupt while a sweep runs (main thread only)."""

    def __enter__(self):
        self.old = None
        if threading.current_thread() is threading.main_thread():
            def handler(signum, frame):
                raise KeyboardInterrupt
            self.old = signal.signal(signal.SIGTERM, handler)
        return self

    def __exit__(self, *exc):
        if self.old is not None:
            signal.signal(signal.SIGTERM, self.old)
        return False


def run_sweep(spec: dict, out, *, workers: int | None = None, executor: str = "local",
              scheduler: str | None = None, progress: bool = True, overwrite: bool = False,
              max_units: int | None = None) -> SweepReport:
    """Run (or resume) ``spec`` into the store ``out``; ``max_units`` stops early (testing)."""
    if executor not in ("local", "dask"):
        raise InputError(f"unknown executor {executor!r}; choose local or dask")
    if scheduler:
        executor = "dask"
    if executor == "dask":
        require_dask()
    if scheduler:
        scheduler = check_scheduler(scheduler)
    if workers is None:
        workers = usable_cores()
    if isinstance(workers, bool) or not isinstance(workers, numbers.Integral) or workers < 1:
        raise InputError(f"--workers must be an integer >= 1 (omit it to use all cores), got {workers!r}")
    workers = int(workers)
    check_store_name(out)
    if spec.get("kind") is None:  # another kind of grid checks its own memory
        check_sweep_memory(spec, workers if executor == "local" else 1)
    with exclusive_lock(out, f"sweep store {out}"):
        return _run_locked(spec, out, workers, executor, scheduler, progress, overwrite, max_units)


#: seconds a Dask scheduler has to accept the connection and answer the handshake, together
HANDSHAKE_S = 8.0
_ADDRESS = re.compile(r"(?:(tcp|tls)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):([0-9]{1,5})")


def check_scheduler(address: str) -> str:
    """The Dask scheduler ``address`` (``tcp://HOST:PORT``, ``tls://...`` or ``HOST:PORT``), checked
    before the sweep touches any file: a malformed address, one where nothing answers, or a service
    that is not a Dask scheduler is an InputError, within :data:`HANDSHAKE_S` seconds in all.

    Why a handshake of our own: ``distributed.Client``'s timeout covers opening the connection but
    not the answer, so an HTTP server on the port kept it waiting for minutes, and a service whose
    reply was read as a frame length made it allocate exabytes ("out of memory")."""
    m = _ADDRESS.fullmatch(str(address).strip())
    if not m or not 0 < int(m.group(3)) < 65536:
        raise InputError(f"--scheduler {address!r} is not a Dask scheduler address; give tcp://HOST:PORT "
                         "(e.g. tcp://127.0.0.1:8786)")
    address = f"{m.group(1) or 'tcp'}://{m.group(2)}:{int(m.group(3))}"
    import asyncio

    require_dask()
    from distributed.comm import connect

    async def identity():
        comm = await connect(address, timeout=HANDSHAKE_S / 2)  # a refused port: its own message
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(identity(), HANDSHAKE_S))
    except asyncio.TimeoutError:
        raise InputError(f"--scheduler {address}: no Dask scheduler answered within {HANDSHAKE_S:g} s "
                         "(another service on that port?)") from None
    except OSError as exc:
        raise InputError(f"--scheduler {address}: cannot reach a Dask scheduler there "
                         f"({' '.join(str(exc).split()) or type(exc).__name__})") from None
    except Exception:  # noqa: BLE001 - whatever a foreign protocol's bytes make of the decoder
        reply = None
    if not (isinstance(reply, dict) and reply.get("type") == "Scheduler"):
        raise InputError(f"--scheduler {address}: the service there is not a Dask scheduler (its answer "
                         "is not a Dask handshake)")
    return address


def check_sweep_memory(spec: dict, workers: int) -> None:
    """Refuse a sweep whose largest task does not fit in memory, per worker (before any work).

    The memory of a task is :func:`pfbench.resources.filter_memory` of its configuration;
    ``workers`` processes hold one task each at a time.
    """
    from .. import models
    from ..resources import check_memory, filter_memory

    model = models.get(spec["model"], **spec["params"])
    procs = max(1, min(int(workers), int(spec["runs"])))
    needs = [(filter_memory(model, m, n_filters=n_f, n_steps=spec["steps"], backend=spec["backend"]), m, n_p, n_f)
             for m, n_p, n_f in spec["configs"]]
    need, m, n_p, n_f = max(needs, key=lambda t: t[0].bytes(t[2]))  # if it fits, every task does
    check_memory(need, n_p, what=f"a sweep task ({m}, N_f={n_f}, {spec['steps']} steps on {spec['model']})",
                 processes=procs)


def _run_locked(spec, out, workers, executor, scheduler, progress, overwrite, max_units):
    total = n_tasks(spec)
    try:
        if finished_export(out, spec, overwrite=overwrite):  # its journal was removed: nothing to redo
            return SweepReport(Path(out), total, total, 0, 0.0)
        store = Store.open(out, spec, overwrite=overwrite)
    except OSError as exc:
        raise path_error(exc, out, "--out") from None
    before = len(store.records)
    pending = pending_units(spec, store)

    def planner(n_workers):
        return Planner(spec, pending, n_workers, store.records.values())

    from ..progress import progress_bar

    bar = progress_bar(show=progress, total=total, initial=before, unit="task",
                       desc=f"{spec.get('kind', 'sweep')} {spec.get('model', '')}", dynamic_ncols=True, smoothing=0.1)
    t0 = time.perf_counter()

    def done(groups, recs, wall, info):
        store.append(recs, {"run": groups[0][0], "runs": [r for r, _ in groups], "n": len(recs),
                            "wall_s": round(wall, 6), **info})
        bar.update(len(recs))

    try:
        with _Sigterm():
            if not pending:
                pass
            elif executor == "local" and workers == 1:
                _run_here(spec, planner(1), done, max_units)
            elif executor == "local":
                _run_local(spec, planner, workers, done, max_units)
            else:
                _run_dask(spec, planner, workers, scheduler, done, max_units)
    finally:
        bar.close()
        store.close()
    wall = time.perf_counter() - t0
    if store.complete and Path(out).suffix == ".parquet":
        try:
            export_parquet(store, out)
        except OSError as exc:
            raise path_error(exc, out, "--out") from None
    bad = sum(1 for r in store.records.values()   # read back from a journal, -inf is null and a note
              if "loglik_nonfinite" in r or not math.isfinite(r.get("loglik") or 0.0))
    invalid = sum(1 for r in store.records.values() if (r.get("invalid_loglik") or 0) > 0)
    return SweepReport(Path(out), total, before, len(store.records) - before, wall, bad, invalid)


_WARM: set = set()

#: other kinds of grid that run on this machinery (``spec["kind"]``): the module with their
#: ``run_chunk(spec, run, config_indices)`` and ``warm_up(spec)``; a sweep spec has no kind
KINDS = {"compare": "pfbench.compare.run"}


def work(spec: dict):
    """(run_chunk, warm_up) of ``spec``: a sweep's, or those of its ``kind`` (:data:`KINDS`)."""
    kind = spec.get("kind")
    if kind is None:
        return run_chunk, warm_up
    import importlib

    mod = importlib.import_module(KINDS[kind])
    return mod.run_chunk, mod.warm_up


def _warm(spec: dict) -> None:
    """Load the spec's kernels once per process (a local worker's initializer; a Dask worker's first
    unit), outside every unit's timing."""
    from .core import spec_hash

    h = spec_hash(spec)
    if h not in _WARM:
        work(spec)[1](spec)
        _WARM.add(h)


def _warm_quietly(spec: dict) -> None:
    """A local worker's initializer: :func:`_warm`, whose failure is left to the worker's first unit
    to raise (it runs :func:`_warm` again). A failing initializer breaks the whole pool, and its
    exception reached the parent only as "a worker process died"."""
    try:
        _warm(spec)
    except Exception:  # noqa: BLE001 - raised again, and reported, by the unit
        pass


#: what a worker that cannot find a name lacks (it is a fresh interpreter, ``spawn``)
SPAWN_HINT = ("; the worker processes start afresh, so tasks, models and contenders defined in a script's "
              "__main__ or a notebook do not exist there: define them in a module or a --models file")


def _threads() -> int:
    """The most threads a filter of this process can run: numba's pool size, within the process's
    thread budget (:func:`pfbench.procs.thread_limit`)."""
    import numba

    from ..procs import thread_limit

    return int(min(numba.config.NUMBA_NUM_THREADS, thread_limit() or numba.config.NUMBA_NUM_THREADS))


def _timed_unit(spec: dict, groups, host_threads: dict | None = None) -> tuple[list, float, dict]:
    """Run the unit ``groups`` (``[(run, [config indices])]``): its records, its wall time and the
    journal's note of who ran it (``worker``), when (``start``, Unix time) and with how many
    threads at most (``threads``). ``host_threads``: on a Dask cluster, :func:`_host_threads`."""
    if host_threads is not None:
        _share_host(host_threads)
    _warm(spec)
    run = work(spec)[0]
    start, t1 = time.time(), time.perf_counter()
    recs = []
    for r, cis in groups:
        recs += run(spec, r, cis)
    return recs, time.perf_counter() - t1, {"worker": f"pid-{os.getpid()}", "start": round(start, 3),
                                           "threads": _threads()}


def _host_threads(info: dict) -> dict:
    """Dask worker address -> the Dask threads of every worker on its host, from the scheduler's
    ``scheduler_info()``."""
    workers = info.get("workers", {})
    per_host: dict = {}
    for w in workers.values():
        per_host[w.get("host")] = per_host.get(w.get("host"), 0) + int(w.get("nthreads") or 1)
    return {address: per_host[w.get("host")] for address, w in workers.items()}


def _share_host(host_threads: dict) -> None:
    """Give a Dask worker process that has no thread budget (:func:`pfbench.procs.thread_limit`;
    one that pfbench started has one) its share of its host: usable cores // the Dask threads of
    every worker on the host (``host_threads``; a worker that joined later: its own threads), as
    each of those threads may run a filter at once. Without it every task's filter would ask for
    all the host's free cores and the tasks of one host would oversubscribe it."""
    from ..procs import THREADS_ENV, thread_limit, usable_cores

    if thread_limit() is not None:
        return
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):  # not on a Dask worker
        return
    sharing = host_threads.get(worker.address) or getattr(worker, "nthreads", 1)
    os.environ[THREADS_ENV] = str(max(1, usable_cores() // max(1, int(sharing))))


def _run_here(spec, planner, done, max_units):
    """``workers=1``: the units one after the other in this process."""
    n = 0
    while max_units is None or n < max_units:
        groups = planner.next_unit()
        if groups is None:
            break
        recs, wall, info = _timed_unit(spec, groups)
        done(groups, recs, wall, dict(info, worker="local-0"))
        planner.learn(groups, recs, wall)
        n += 1


def _drive(planner, workers, submit, finished, result, done, max_units):
    """Hand ``planner``'s units to ``workers`` workers (``submit(groups)`` -> a future), one per
    worker until a task time is known, then two (one queued behind the running one); record each
    unit as it finishes (``finished(futures)``: the done ones, waiting for one; ``result(fut)``)."""
    inflight, handed = {}, 0
    while True:
        limit = (2 if planner.known else 1) * workers
        while len(inflight) < limit and (max_units is None or handed < max_units):
            groups = planner.next_unit()
            if groups is None:
                break
            inflight[submit(groups)] = groups
            handed += 1
        if not inflight:
            return
        for fut in finished(list(inflight)):
            groups = inflight.pop(fut)
            recs, wall, info = result(fut)
            done(groups, recs, wall, info)
            planner.learn(groups, recs, wall)


def _run_local(spec, planner, workers, done, max_units):
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, wait
    from concurrent.futures.process import BrokenProcessPool

    def result(fut):
        try:
            return fut.result()
        except BrokenProcessPool:
            raise PfbenchError("a sweep worker process died (killed, e.g. by the out-of-memory "
                               "killer); finished tasks are saved, re-run the same command to "
                               "resume") from None
        except MemoryError:
            raise PfbenchError("a sweep worker ran out of memory; finished tasks are saved; use "
                               "fewer --workers or smaller --particles, then re-run to resume") from None
        except UnknownNameError as exc:
            raise UnknownNameError(f"{exc}{SPAWN_HINT}") from None

    with worker_pool(workers, mp_context=mp.get_context("spawn"), initializer=_warm_quietly, initargs=(spec,),
                     threads=worker_threads(workers)) as pool:
        _drive(planner(workers), workers, lambda groups: pool.submit(_timed_unit, spec, groups),
               lambda futs: wait(futs, return_when=FIRST_COMPLETED)[0], result, done, max_units)


DASK_MISSING = "--executor dask needs Dask, which is not installed: pip install 'pfbench[cluster]'"


def require_dask() -> None:
    """Dask is the optional extra ``cluster``: without it, ``--executor dask`` is one line before any work."""
    import importlib.util

    if importlib.util.find_spec("distributed") is None:
        raise InputError(DASK_MISSING)


def _run_dask(spec, planner, workers, scheduler, done, max_units):
    try:
        from distributed import Client, LocalCluster, wait
    except ImportError:
        raise InputError(DASK_MISSING) from None
    cluster = None
    try:
        if scheduler:
            try:
                client = Client(scheduler, timeout=f"{HANDSHAKE_S:g}s")
            except (OSError, MemoryError) as exc:  # it answered check_scheduler but went away since
                raise InputError(f"cannot reach Dask scheduler {scheduler}: {exc}") from None
        else:
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   host="127.0.0.1", dashboard_address=None,
                                   env=thread_env(worker_threads(workers)))
            client = Client(cluster)
        try:
            try:
                info = client.scheduler_info(n_workers=-1)  # every worker (newer Dask returns 5 by default)
            except TypeError:  # an older Dask: every worker anyway
                info = client.scheduler_info()
            n_workers = max(1, len(info.get("workers", {})) or workers)
            shares = _host_threads(info)

            def result(fut):
                out = fut.result()
                fut.release()
                return out

            _drive(planner(n_workers), n_workers,
                   lambda groups: client.submit(_timed_unit, spec, groups, shares, pure=False),
                   lambda futs: wait(futs, return_when="FIRST_COMPLETED").done, result, done, max_units)
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()
