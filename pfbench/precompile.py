"""``pfbench compile``: fill the compile cache before the first run (a precompile workload).

The numba backend compiles a filter's kernel on its first call and keeps the machine code on disk
(:mod:`pfbench.backends.cache`), keyed on the whole package source. On an empty cache a first
``pfbench run`` therefore spends most of its wall time compiling (``pfbench bench --startup`` times
cold and warm starts per method; the particle kernel's compile is numba's type inference and
lowering as much as LLVM, so it cannot be made to vanish). This module compiles chosen kernels
ahead of time by running each configuration once on a tiny problem (two steps, a few particles),
so that every later run of the same installation with that configuration loads its kernel from
the cache: the "precompile workload" way of JIT systems that ship with a compile step.

What a configuration compiles. A kernel is specific to the model (its functions and the types of
its parameters), the method's kernel family (bootstrap, sir, sis, asir and multipdf share the
particle kernel), the resampling scheme, the particle dtype and the variant: the serial kernel,
or the all-threads one that a filter with more than
:data:`pfbench.backends.numpy_backend.BLOCK` particles runs unless ``n_threads=1``. The numbers a
kernel computes do not depend on the problem size it was compiled on.

``make all`` runs ``pfbench compile`` for the default ``pfbench run`` of every registered model
(bootstrap, systematic, float64, serial); the cache is the installation's
(:func:`pfbench.backends.cache.cache_root`), so a later ``pfbench run`` in the activated
environment finds it.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass

#: time steps and particles of the tiny problem each configuration is compiled on
STEPS, PARTICLES = 2, 4


@dataclass(frozen=True)
class Target:
    """One kernel configuration to compile: ``model`` is a model spec (``ob3:v4``)."""

    model: str
    method: str = "bootstrap"
    resampling: str = "systematic"
    dtype: str = "float64"
    all_threads: bool = False


def targets(models, methods=("bootstrap",), schemes=("systematic",), dtypes=("float64",),
            all_threads: bool = False) -> list[Target]:
    """Every combination of the given models, methods, schemes and dtypes; the serial kernel, and
    with ``all_threads`` the all-threads kernel too for the methods that have one (one particle
    filter: MultiPDF runs its sub-filters side by side on one thread each, and the mpf, guided and
    kalman kernels are serial)."""
    from .methods import Method

    def variants(method):
        m = Method.parse(method)
        return (False, True) if all_threads and m.family == "particle" and m != Method.MULTIPDF else (False,)

    return [Target(m, me, s, d, v) for m in dict.fromkeys(models) for me in dict.fromkeys(methods)
            for s in dict.fromkeys(schemes) for d in dict.fromkeys(dtypes) for v in variants(me)]


def compile_target(target: Target) -> dict:
    """Compile (or load) the kernel of ``target`` by running it once on a tiny problem.

    Returns ``asdict(target)`` plus ``status`` (``"ready"``; ``"not applicable"`` when the model
    does not support the method or the dtype: the run's :class:`~pfbench.errors.UnsupportedError`,
    or its :class:`~pfbench.errors.InputError` refusing the combination; ``"failed"`` on any other
    :class:`~pfbench.errors.PfbenchError`, such as a :class:`~pfbench.errors.ModelError` (a mistake in
    the model's code) or a :class:`~pfbench.errors.DataError` for a cache directory that cannot be
    written), ``detail`` (the error's one line) and ``seconds``.
    """
    from . import models
    from .errors import DataError, InputError, ModelError, PfbenchError, UnsupportedError
    from .filters import run_filter

    row = asdict(target)
    t0 = time.perf_counter()
    try:
        name, kw = models.parse_spec(target.model)
        model = models.get(name, **kw)
        traj = model.simulate(STEPS, seed=0)
        # all threads: the kernel runs with more than one stream block, which a block of 2
        # particles gives without allocating BLOCK of them, on 2 threads (not the free cores,
        # which are 1 on a busy machine: the all-threads kernel serves any count above 1)
        run_filter(model, traj.y, traj.u, method=target.method, n_particles=PARTICLES,
                   n_filters=2 if target.method == "multipdf" else 1, resampling=target.resampling,
                   backend="numba", dtype=target.dtype, seed=0, n_threads=2 if target.all_threads else 1,
                   _block=2 if target.all_threads else None)
        row.update(status="ready", detail=None)
    except PfbenchError as exc:
        refused = isinstance(exc, (UnsupportedError, InputError)) and not isinstance(exc, (DataError, ModelError))
        row.update(status="not applicable" if refused else "failed", detail=" ".join(str(exc).split()))
    row["seconds"] = time.perf_counter() - t0
    return row


def _compile_group(group: list[Target]) -> list[dict]:
    return [compile_target(t) for t in group]


def compile_all(todo: list[Target], jobs: int | None = None, progress: bool = True) -> list[dict]:
    """Compile every target, the targets of one model in one process (they share the model's
    compiled functions), ``jobs`` processes at a time (default: all cores; 1: this process).
    Rows in the order of ``todo``."""

    from .progress import progress_bar

    from .procs import usable_cores

    groups: dict[str, list[Target]] = {}
    for t in todo:
        groups.setdefault(t.model, []).append(t)
    jobs = max(1, min(int(jobs or usable_cores()), len(groups)))
    done: dict[Target, dict] = {}
    with progress_bar(show=progress, total=len(todo), desc="compile", leave=False) as bar:
        if jobs == 1:
            for group in groups.values():
                for t in group:
                    bar.set_postfix_str(f"{t.model} {t.method}")
                    done[t] = compile_target(t)
                    bar.update()
        else:
            from concurrent.futures import as_completed
            from concurrent.futures.process import BrokenProcessPool

            from .errors import PfbenchError
            from .procs import worker_pool

            with worker_pool(jobs) as pool:  # Ctrl-C or an error ends the compiles under way at once
                futures = {pool.submit(_compile_group, g): g for g in groups.values()}
                for fut in as_completed(futures):
                    try:
                        rows = fut.result()
                    except BrokenProcessPool:
                        raise PfbenchError("a compile worker process died (killed, e.g. by the out-of-memory "
                                           "killer); use --jobs 1, or fewer --model at a time") from None
                    for t, row in zip(futures[fut], rows):
                        done[t] = row
                    bar.update(len(futures[fut]))
    return [done[t] for t in todo]


def text(rows: list[dict], cache: str) -> list[str]:
    """The table ``pfbench compile`` prints."""
    out = [f"{'model':<18} {'method':<10} {'resampling':<22} {'dtype':<8} {'threads':<8} {'s':>6}  result"]
    for r in rows:
        line = (f"{r['model']:<18} {r['method']:<10} {r['resampling']:<22} {r['dtype']:<8} "
                f"{'all' if r['all_threads'] else '1':<8} {r['seconds']:>6.1f}  {r['status']}")
        if r["detail"]:
            line += f": {r['detail']}"
        out.append(line)
    n = sum(r["status"] == "ready" for r in rows)
    out.append(f"{n} of {len(rows)} configurations ready in {cache}; later runs of this installation "
               "with them load the compiled kernels instead of compiling")
    return out
