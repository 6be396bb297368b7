"""The engine's targets and how a measured value compares with them.

Each :class:`Target` is data (a bound and a direction); :func:`check` computes "meets" or
"misses" from the number measured in the run, so no verdict is ever typed by hand.
"""
from __future__ import annotations

import math
import operator
from dataclasses import dataclass

_OPS = {"<=": operator.le, ">=": operator.ge, "<": operator.lt, ">": operator.gt}


@dataclass(frozen=True)
class Target:
    """``value op bound`` is the goal; ``unit`` is printed after numbers ("x" for ratios)."""

    label: str
    op: str
    bound: float
    unit: str = "x"

    def verdict(self, value) -> str:
        if value is None or not math.isfinite(float(value)):
            return "not measured"
        return "meets" if _OPS[self.op](float(value), self.bound) else "misses"


#: the engine's performance targets (medians; ratios from one run)
TARGETS = {
    "numba_over_c": Target("numba float64 1 thread / C (faster RNG), Ob1 bootstrap", "<=", 0.55),
    "numba_over_floor": Target("numba float64 1 thread / floor (1 normal + 1 exp)", "<=", 2.0),
    "threads_speedup_1e6": Target("numba all threads vs 1 thread, N_p = 10^6 (speed-up)", ">=", 1.8),
    "threads_speedup_1e5": Target("numba all threads vs 1 thread, N_p = 10^5 (speed-up)", ">=", 1.7),
    "float32_speedup_1e5": Target("numba float32 vs float64, N_p = 10^5 (speed-up)", ">=", 1.3),
    "ns_1e6_over_1e3": Target("numba 1 thread ns/p-step at N_p = 10^6 / at N_p = 10^3", "<=", 1.3),
    "end_to_end_speedup": Target("whole run_filter calls, N_p = 10^6, M = 12: 2 threads vs 1 (speed-up)", ">=", 1.8),
    "sweep_efficiency": Target("sweep on W workers vs 1 worker: speed-up / W", ">=", 0.8),
    "cold_start_s": Target("cold first `pfbench run` (empty caches), wall time", "<", 5.0, " s"),
}


def check(key: str, value, label: str | None = None) -> dict:
    """The record of one measured value against ``TARGETS[key]``."""
    t = TARGETS[key]
    v = None if value is None else float(value)
    return {"target": key, "label": label or t.label, "value": v, "op": t.op, "bound": t.bound,
            "unit": t.unit, "verdict": t.verdict(v)}


def fmt(rec: dict) -> str:
    """``label 0.83x (target <= 0.55x: misses)``."""
    unit = rec.get("unit", "x")
    v = rec["value"]
    shown = "n/a" if v is None or not math.isfinite(v) else f"{v:.3g}{unit}"
    return f"{rec['label']}: {shown} (target {rec['op']} {rec['bound']:g}{unit}: {rec['verdict']})"
