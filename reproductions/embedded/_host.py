"""Host timing and energy helpers for the platform comparison ([Embedded] §5.1, Fig. 5, Table 3).

* :func:`time_filter`: median wall time of repeated single-threaded ``run_filter`` calls
  (numba compilation / cache loading happens in an untimed warm-up run);
* :func:`rapl_energy_j`: package energy counters of Linux RAPL (``/sys/class/powercap``) when
  readable, else None - then callers must use an explicit, labelled power model;
* :func:`cpu_name`: the host CPU model string for tables.
"""
from __future__ import annotations

import statistics
from pathlib import Path

RAPL_ROOT = Path("/sys/class/powercap")


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or platform.machine()


def rapl_domains() -> list[Path]:
    """Package-level RAPL energy counters that this process can read (may be empty)."""
    out = []
    if not RAPL_ROOT.is_dir():
        return out
    for d in sorted(RAPL_ROOT.glob("intel-rapl:*")):
        if d.name.count(":") != 1:  # sub-domains (core, uncore, dram) are inside the package
            continue
        f = d / "energy_uj"
        try:
            int(f.read_text())
        except (OSError, ValueError):
            continue
        out.append(d)
    return out


def rapl_energy_j() -> float | None:
    """Sum of the readable package energy counters in joules, or None if none is readable."""
    doms = rapl_domains()
    if not doms:
        return None
    return sum(int((d / "energy_uj").read_text()) for d in doms) / 1e6


def _rapl_delta(e0: float, e1: float) -> float:
    if e1 >= e0:
        return e1 - e0
    # counter wrapped: add the range of the (first) domain
    try:
        rng = int((rapl_domains()[0] / "max_energy_range_uj").read_text()) / 1e6
    except (OSError, IndexError, ValueError):
        return float("nan")
    return e1 + rng - e0


def time_filter(model, y, u=None, *, backend: str, dtype: str, n_particles: int, repeats: int,
                seed: int = 0, method: str = "bootstrap", n_filters: int = 1, warmup: bool = True) -> dict:
    """Median wall time (s) of ``repeats`` runs of ``run_filter`` (single thread: one filter group).

    Also measures package energy with RAPL around the timed runs when available
    (``energy_j`` per run, else None).
    """
    from pfbench.filters import run_filter

    kw = dict(method=method, n_particles=n_particles, n_filters=n_filters, backend=backend, dtype=dtype,
              common_random_numbers=True, n_threads=1)
    if warmup:
        run_filter(model, y, u, seed=seed, **kw)
    times = []
    e0 = rapl_energy_j()
    for r in range(int(repeats)):
        res = run_filter(model, y, u, seed=seed + r, **kw)
        times.append(res.elapsed_s)
    e1 = rapl_energy_j()
    energy = None if e0 is None or e1 is None else _rapl_delta(e0, e1) / max(int(repeats), 1)
    return {"median_s": statistics.median(times), "min_s": min(times), "max_s": max(times),
            "times_s": times, "repeats": int(repeats), "energy_j": energy}
