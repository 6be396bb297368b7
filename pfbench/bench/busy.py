"""``pfbench bench --busy``: the default thread count against one thread on a busy machine.

With 2 x :func:`pfbench.procs.usable_cores` other processes spinning on every core, one filter
(Ob1 bootstrap, M = 200) at N_p = 2·10^4 and 10^5 runs with the default thread count and with one
thread, back to back in each round (:func:`pfbench.bench.timing.interleaved`). The target: the
default is never more than 1.5x the one-thread time, in any round. The same pair is timed on the
quiet machine first, where the default should be faster than one thread.
"""
from __future__ import annotations

import subprocess
import sys
import time

SIZES = (20_000, 100_000)
TARGET = 1.5
SPIN = "import os, time\nparent = os.getppid()\nwhile os.getppid() == parent:\n    time.time()\n"


def _spinners(count: int) -> list:
    """``count`` processes that spin until killed (or until this process dies: they poll their
    parent)."""
    return [subprocess.Popen([sys.executable, "-c", SPIN]) for _ in range(count)]


def run_busy(rounds: int = 5, steps: int = 200, sizes=SIZES) -> dict:
    """Per size: the per-round ratios default / one thread, quiet and busy (see the module docstring)."""
    from ..models import get
    from ..procs import usable_cores
    from ..provenance import provenance
    from .timing import filter_ns, interleaved, round_ratios

    model = get("ob1")
    traj = model.simulate(steps, seed=1)
    out = {}
    for n in sizes:
        def timers(used: list, n=n) -> dict:  # used: the threads of every timed default run
            return {"default": lambda: filter_ns(model, traj, n, "numba", "float64", 3, threads=used),
                    "one": lambda: filter_ns(model, traj, n, "numba", "float64", 3, n_threads=1)}

        used = {"quiet": [], "busy": []}
        quiet = interleaved(timers(used["quiet"]), rounds)
        procs = _spinners(2 * usable_cores())
        try:
            time.sleep(0.3)
            busy = interleaved(timers(used["busy"]), rounds)
        finally:
            for p in procs:
                p.kill()
            for p in procs:
                p.wait()
        out[str(n)] = {"quiet": round_ratios(quiet["default"], quiet["one"]),
                       "busy": round_ratios(busy["default"], busy["one"]),
                       "busy_ns": busy, "quiet_ns": quiet,
                       "default_threads": used}
    return provenance(kind="bench_busy", section="busy", busy_processes=2 * usable_cores(), steps=steps, target=TARGET,
                      sizes=out)


def text(res: dict) -> list[str]:
    lines = []
    for n, r in res["sizes"].items():
        worst = max(r["busy"]) if r["busy"] else float("nan")
        verdict = "meets" if worst <= res["target"] else "misses"
        lines.append(f"N_p = {int(n):,}: default / 1 thread, quiet rounds "
                     + " ".join(f"{x:.2f}" for x in r["quiet"]) + f"; with {res['busy_processes']} busy "
                     "processes " + " ".join(f"{x:.2f}" for x in r["busy"])
                     + f" (target <= {res['target']}x in every round: {verdict})")
    return lines
