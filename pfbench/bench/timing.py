"""Timing helpers shared by the sections of ``pfbench bench``: the engine and the ``particles``
library, in ns per particle-step (medians; compilation excluded)."""
from __future__ import annotations

import json
import statistics
import subprocess
from pathlib import Path


def filter_ns(model, traj, n: int, backend: str, dtype: str, repeats: int, method: str = "bootstrap",
              n_filters: int = 1, n_threads: int | None = None, threads: list | None = None) -> float:
    """Median ``FilterResult.elapsed_s`` of ``repeats`` runs of :func:`pfbench.run_filter` on
    ``traj.y`` as ns per particle-step, after one untimed run on 3 steps (compilation). ``threads``:
    a list that gets each timed run's ``info["threads"]`` (how many it ran on)."""
    from ..filters import run_filter

    kw = dict(method=method, n_particles=n, n_filters=n_filters, backend=backend, dtype=dtype,
              n_threads=n_threads)
    run_filter(model, traj.y[:3], None, seed=0, **kw)  # compile / warm up
    runs = [run_filter(model, traj.y, None, seed=r, **kw) for r in range(max(int(repeats), 1))]
    if threads is not None:
        threads.extend(r.info.get("threads") for r in runs)
    return statistics.median(r.elapsed_s for r in runs) * 1e9 / (n * traj.n_steps)


def particles_ns(m: int, n: int, repeats: int) -> dict | None:
    """The ``particles`` library's bootstrap filter on Ob1, run by ``scripts/bench_particles.py``
    in ``.venv-particles`` (it pins an older NumPy) when that environment exists; None otherwise."""
    root = Path(__file__).resolve().parents[2]
    py = root / ".venv-particles" / "bin" / "python"
    script = root / "scripts" / "bench_particles.py"
    if not (py.exists() and script.exists()):
        return None
    try:
        r = subprocess.run([str(py), str(script), "--steps", str(m), "--particles", str(n),
                            "--repeats", str(repeats)], capture_output=True, text=True, timeout=1800)
    except (OSError, subprocess.SubprocessError) as exc:
        return {"error": str(exc)}
    if r.returncode != 0:
        return {"error": r.stderr.strip().splitlines()[-1] if r.stderr.strip() else "failed"}
    return json.loads(r.stdout.strip().splitlines()[-1])


def interleaved(measures: dict, rounds: int) -> dict:
    """Run the timers ``measures`` (name -> callable returning ns) in ``rounds`` interleaved rounds
    (round r runs every timer once, in order) and return name -> list of the ``rounds`` timings.

    On a shared machine the speed can change by a large factor within a minute (seen here: the
    same kernel at 22 and at 38 ns per particle-step in one run), so two medians taken minutes apart
    can compare a fast phase with a slow one; timings taken back to back in one round see the same
    machine, and :func:`paired_ratio` divides within rounds."""
    out = {k: [] for k in measures}
    for _ in range(max(int(rounds), 1)):
        for k, f in measures.items():
            out[k].append(float(f()))
    return out


def round_ratios(a: list, b: list) -> list:
    """a_r / b_r for every round r with both timings (b_r > 0)."""
    return [x / y for x, y in zip(a, b) if x is not None and y is not None and y > 0]


def paired_ratio(a: list, b: list) -> float | None:
    """Median over rounds of a_r / b_r (None without a complete pair)."""
    pairs = round_ratios(a, b)
    return statistics.median(pairs) if pairs else None


def ratio_range(a: list, b: list) -> list | None:
    """[smallest, largest] a_r / b_r over the rounds (None without a complete pair): how far a
    round's ratio strayed from the median that :func:`paired_ratio` reports."""
    pairs = round_ratios(a, b)
    return [min(pairs), max(pairs)] if pairs else None
