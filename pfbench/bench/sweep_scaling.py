"""``pfbench bench --sweep``: how a sweep's wall time falls with its number of workers.

One sweep, a MultiPDF grid on Ob1 ([MultiPDF] §5: N_p = 100, 300, 1000, 3000 x N_f = 1, 2, 5,
M = 1000 steps, numba; tasks of a few milliseconds), is sized to take about ``seconds`` on one
worker: the runs are ``seconds`` over the time of one run measured here first (which also fills
the kernel cache, so no timed sweep compiles). It then runs as ``pfbench sweep --workers W``,
a fresh command into a fresh store, for every W of ``workers``, in rounds (every W once per
round), and each time is what a user waits for: the command's wall time (interpreter, imports,
the workers' start-up and kernel loading, the sweep, the store). The sweep's own ``wall_s`` (its
``--json``) is kept beside it.

Per W: the medians over rounds, the speed-up T(1) / T(W) as the median of the per-round ratios
(:func:`pfbench.bench.timing.paired_ratio`: a shared machine that slows down between rounds
moves both times of a round) and its range, the efficiency speed-up / W against the target
(``sweep_efficiency``, at least 0.8 for every W > 1), and from the store the units the sweep cut
and how long after the command started the first unit began (the start-up the workers cost).
"""
from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: the grid: ``pfbench sweep`` arguments besides --runs, --workers and --out
GRID = {"model": "ob1", "method": "multipdf", "particles": (100, 300, 1000, 3000), "filters": (1, 2, 5),
        "steps": 1000}
SECONDS, QUICK_SECONDS = 60.0, 10.0


def default_workers() -> tuple[int, ...]:
    """1, 2 and every usable core (:func:`pfbench.procs.usable_cores`) when there are more."""
    from ..procs import usable_cores

    return tuple(sorted({1, 2, usable_cores()}))


def _spec(runs: int, grid=GRID) -> dict:
    from ..sweep import make_spec

    return make_spec(grid["model"], methods=[grid["method"]], particles=grid["particles"],
                     filters=grid["filters"], runs=runs, steps=grid["steps"], seed=0)


def run_seconds(grid=GRID, repeats: int = 3) -> float:
    """Seconds one run of ``grid`` (every configuration on one trajectory) takes in this process,
    median of ``repeats`` after one untimed run (which compiles or loads the kernels)."""
    from ..sweep.core import run_chunk, warm_up

    spec = _spec(repeats + 1, grid)
    warm_up(spec)
    every = range(len(spec["configs"]))
    run_chunk(spec, 0, every)
    times = []
    for r in range(1, repeats + 1):
        t0 = time.perf_counter()
        run_chunk(spec, r, every)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def sweep_command(runs: int, workers: int, out: Path, grid=GRID) -> list[str]:
    """The ``pfbench sweep`` command line of one timed sweep."""
    return [sys.executable, "-m", "pfbench.cli", "sweep", "--model", grid["model"], "--method", grid["method"],
            "--particles", ",".join(map(str, grid["particles"])), "--filters", ",".join(map(str, grid["filters"])),
            "--steps", str(grid["steps"]), "--runs", str(runs), "--seed", "0", "--workers", str(workers),
            "--quiet", "--json", "--overwrite", "--out", str(out)]


def timed_sweep(runs: int, workers: int, out: Path, grid=GRID) -> dict:
    """Run one sweep as a command; its wall time, the sweep's own, and its units from the store."""
    from ..errors import PfbenchError
    from ..sweep.store import Store

    root = str(Path(__file__).resolve().parents[2])  # the pfbench of this process, installed or not
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p))
    launched, t0 = time.time(), time.perf_counter()
    r = subprocess.run(sweep_command(runs, workers, out, grid), env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        lines = r.stderr.strip().splitlines()
        raise PfbenchError(f"the timed sweep on {workers} workers failed (exit {r.returncode}): "
                           f"{lines[-1] if lines else 'no message'}")
    own = json.loads(r.stdout.strip().splitlines()[-1])
    chunks = Store.read(out).chunks
    starts = [c["start"] for c in chunks if "start" in c]
    return {"command_s": wall, "sweep_s": float(own["wall_s"]), "units": len(chunks),
            "first_unit_s": (min(starts) - launched) if starts else None,
            "threads": max((c.get("threads", 0) for c in chunks), default=None)}


def run_sweep_scaling(seconds: float = SECONDS, workers=None, rounds: int = 3, grid=GRID,
                      progress: bool = True, runs: int | None = None) -> dict:
    """Time the sweep on every worker count of ``workers`` (default :func:`default_workers`; 1 is
    always added: the speed-ups are against it) in ``rounds`` rounds; the provenance record.
    ``runs`` fixes the sweep's size instead of ``seconds`` (the same sweep on two versions of the
    code, whatever the machine's speed at calibration)."""
    from ..procs import usable_cores
    from ..progress import progress_bar
    from ..provenance import provenance
    from .report import check
    from .timing import paired_ratio, ratio_range

    workers = sorted({1, *(int(w) for w in (workers or default_workers()))})
    per_run = run_seconds(grid)
    runs = max(2, round(float(seconds) / per_run)) if runs is None else int(runs)
    spec = _spec(runs, grid)
    bar = progress_bar(show=progress, total=rounds * len(workers), desc="bench --sweep", leave=False)
    times = {w: [] for w in workers}
    tmp = Path(tempfile.mkdtemp(prefix="pfbench-bench-sweep-"))
    try:
        for _ in range(int(rounds)):
            for w in workers:
                bar.set_postfix_str(f"{w} workers")
                times[w].append(timed_sweep(runs, w, tmp / f"w{w}.jsonl", grid))
                bar.update()
    finally:
        bar.close()
        shutil.rmtree(tmp, ignore_errors=True)
    one = [t["command_s"] for t in times[1]]
    one_own = [t["sweep_s"] for t in times[1]]
    rows, targets = [], []
    for w in workers:
        cmd = [t["command_s"] for t in times[w]]
        own = [t["sweep_s"] for t in times[w]]
        speedup = paired_ratio(one, cmd)
        row = {"workers": w, "command_s": cmd, "sweep_s": own, "command_median_s": statistics.median(cmd),
               "sweep_median_s": statistics.median(own), "speedup": speedup, "speedup_rounds": ratio_range(one, cmd),
               "sweep_speedup": paired_ratio(one_own, own),
               "efficiency": None if speedup is None else speedup / w,
               "units": [t["units"] for t in times[w]], "first_unit_s": [t["first_unit_s"] for t in times[w]],
               "threads_per_worker": max((t["threads"] or 0) for t in times[w]) or None}
        rows.append(row)
        if w > 1:
            targets.append(check("sweep_efficiency", row["efficiency"],
                                 f"sweep on {w} workers: speed-up / {w} ({speedup or float('nan'):.2f}x, "
                                 f"command wall time, about {seconds:g} s on 1 worker, median of "
                                 f"{rounds} round(s))"))
    return provenance(kind="bench_sweep", grid={k: list(v) if isinstance(v, tuple) else v for k, v in grid.items()},
                      seconds_asked=float(seconds), run_s=per_run, runs=runs, tasks=runs * len(spec["configs"]),
                      rounds=int(rounds), cores=usable_cores(), rows=rows, targets=targets)


def text(res: dict) -> list[str]:
    """The table and the targets as printed lines."""
    from .report import fmt

    g = res["grid"]
    out = [f"sweep: {g['model']} {g['method']}, N_p {g['particles']} x N_f {g['filters']}, M = {g['steps']}, "
           f"{res['runs']} runs = {res['tasks']} tasks (one run {res['run_s'] * 1e3:.0f} ms here), "
           f"{res['cores']} usable cores",
           f"{'workers':>7} {'command s':>10} {'sweep s':>8} {'speed-up':>9} {'rounds':>12} {'/ W':>5} "
           f"{'units':>6} {'1st unit s':>10}"]
    for r in res["rows"]:
        rng = r["speedup_rounds"]
        first = [v for v in r["first_unit_s"] if v is not None]
        out.append(f"{r['workers']:>7} {r['command_median_s']:>10.2f} {r['sweep_median_s']:>8.2f} "
                   f"{r['speedup'] or float('nan'):>8.2f}x "
                   f"{(f'{rng[0]:.2f}-{rng[1]:.2f}x' if rng else 'n/a'):>12} {r['efficiency'] or float('nan'):>5.2f} "
                   f"{statistics.median(r['units']):>6.0f} "
                   f"{(statistics.median(first) if first else float('nan')):>10.2f}")
    out.append("(medians over rounds; speed-up = median of the per-round ratios of the command wall times)")
    out.extend(fmt(t) for t in res["targets"])
    return out
