"""Run a sweep on local processes or a Dask cluster, appending finished tasks to the store.

Executors
---------
``local`` (default): ``workers`` processes (``spawn``); ``workers=1`` runs in this process.
``dask``: ``scheduler="tcp://host:port"`` connects to a running cluster; without it a
``distributed.LocalCluster`` on 127.0.0.1 with ``workers`` single-threaded processes is started
(and closed afterwards). Every executor computes the same numbers (see :mod:`.core`).

At most ``2 x workers`` work units are in flight; Ctrl-C or SIGTERM stops the sweep after
terminating the workers, keeping every unit already written; re-running resumes. Local workers die
with the sweep, also after ``kill -9`` (:func:`pfbench.procs.worker_pool`).

Before any work: ``workers`` must be >= 1 (``None``: all cores), the store must be ``.jsonl`` or
``.parquet``, the largest task must fit in memory once per worker (:func:`check_sweep_memory`),
and no other process may be writing the same store: a second sweep on the same ``out`` refuses
with the holder's PID (:func:`pfbench.procs.exclusive_lock`; a lock left by a killed sweep is
free again, the kernel releases it with its holder).
"""
from __future__ import annotations

import os
import re
import signal
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError, PfbenchError
from ..procs import exclusive_lock, usable_cores, worker_pool
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

    @property
    def tasks_per_s(self) -> float:
        return self.done_now / self.wall_s if self.wall_s > 0 else float("nan")


def pending_units(spec: dict, store: Store) -> list[tuple[int, list[int]]]:
    units = []
    for r in range(spec["runs"]):
        cis = [ci for ci in range(len(spec["configs"])) if task_key(ci, r) not in store.records]
        if cis:
            units.append((r, cis))
    return units


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
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(f"--workers must be an integer >= 1 (omit it to use all cores), got {workers!r}")
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
    units = pending_units(spec, store)
    if max_units is not None:
        units = units[:max_units]
    from ..progress import progress_bar

    bar = progress_bar(show=progress, total=total, initial=before, unit="task",
                       desc=f"{spec.get('kind', 'sweep')} {spec.get('model', '')}", dynamic_ncols=True, smoothing=0.1)
    t0 = time.perf_counter()

    def done(recs, wall, worker):
        store.append(recs, {"run": recs[0]["run"] if recs else -1, "n": len(recs),
                            "wall_s": round(wall, 6), "worker": worker})
        bar.update(len(recs))

    try:
        with _Sigterm():
            if not units:
                pass
            elif executor == "local" and workers == 1:
                work(spec)[1](spec)
                for r, cis in units:
                    t1 = time.perf_counter()
                    recs = work(spec)[0](spec, r, cis)
                    done(recs, time.perf_counter() - t1, "local-0")
            elif executor == "local":
                _run_local(spec, units, workers, done)
            else:
                _run_dask(spec, units, workers, scheduler, done)
    finally:
        bar.close()
        store.close()
    wall = time.perf_counter() - t0
    if store.complete and Path(out).suffix == ".parquet":
        try:
            export_parquet(store, out)
        except OSError as exc:
            raise path_error(exc, out, "--out") from None
    return SweepReport(Path(out), total, before, len(store.records) - before, wall)


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


def _timed_chunk(spec, r, cis):
    from .core import spec_hash

    h = spec_hash(spec)
    if h not in _WARM:  # load the kernels outside the timed region (Dask workers)
        work(spec)[1](spec)
        _WARM.add(h)
    t1 = time.perf_counter()
    recs = work(spec)[0](spec, r, cis)
    return recs, time.perf_counter() - t1, f"pid-{os.getpid()}"


def _run_local(spec, units, workers, done):
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, wait
    from concurrent.futures.process import BrokenProcessPool

    todo = list(reversed(units))
    inflight = set()
    with worker_pool(workers, mp_context=mp.get_context("spawn"), initializer=work(spec)[1], initargs=(spec,)) as pool:
        while todo or inflight:
            while todo and len(inflight) < 2 * workers:
                r, cis = todo.pop()
                inflight.add(pool.submit(_timed_chunk, spec, r, cis))
            finished, inflight = wait(inflight, return_when=FIRST_COMPLETED)
            for fut in finished:
                try:
                    recs, wall, who = fut.result()
                except BrokenProcessPool:
                    raise PfbenchError("a sweep worker process died (killed, e.g. by the out-of-memory "
                                       "killer); finished tasks are saved, re-run the same command to "
                                       "resume") from None
                except MemoryError:
                    raise PfbenchError("a sweep worker ran out of memory; finished tasks are saved; use "
                                       "fewer --workers or smaller --particles, then re-run to resume") from None
                done(recs, wall, who)


DASK_MISSING = "--executor dask needs Dask, which is not installed: pip install 'pfbench[cluster]'"


def require_dask() -> None:
    """Dask is the optional extra ``cluster``: without it, ``--executor dask`` is one line before any work."""
    import importlib.util

    if importlib.util.find_spec("distributed") is None:
        raise InputError(DASK_MISSING)


def _run_dask(spec, units, workers, scheduler, done):
    try:
        from distributed import Client, LocalCluster, as_completed
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
                                   host="127.0.0.1", dashboard_address=None)
            client = Client(cluster)
        try:
            n_workers = max(1, len(client.scheduler_info().get("workers", {})) or workers)
            todo = list(reversed(units))
            ac = as_completed()
            for _ in range(min(len(todo), 2 * n_workers)):
                r, cis = todo.pop()
                ac.add(client.submit(_timed_chunk, spec, r, cis, pure=False))
            for fut in ac:
                recs, wall, who = fut.result()
                done(recs, wall, who)
                fut.release()
                if todo:
                    r, cis = todo.pop()
                    ac.add(client.submit(_timed_chunk, spec, r, cis, pure=False))
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()
