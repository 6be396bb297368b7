"""Timing helpers shared by the sections of ``pfbench bench``: the engine and the ``particles``
library, in ns per particle-step (medians; compilation excluded)."""
from __future__ import annotations

import json
import statistics
import subprocess
from pathlib import Path


def filter_ns(model, traj, n: int, backend: str, dtype: str, repeats: int, method: str = "bootstrap",
              n_filters: int = 1, n_threads: int | None = None) -> float:
    """Median ``FilterResult.elapsed_s`` of ``repeats`` runs of :func:`pfbench.run_filter` on
    ``traj.y`` as ns per particle-step, after one untimed run on 3 steps (compilation)."""
    from ..filters import run_filter

    kw = dict(method=method, n_particles=n, n_filters=n_filters, backend=backend, dtype=dtype,
              n_threads=n_threads)
    run_filter(model, traj.y[:3], None, seed=0, **kw)  # compile / warm up
    times = [run_filter(model, traj.y, None, seed=r, **kw).elapsed_s for r in range(max(int(repeats), 1))]
    return statistics.median(times) * 1e9 / (n * traj.n_steps)


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
