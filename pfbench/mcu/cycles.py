"""Cortex-M cycle tables (data, with their source) and cycle arithmetic.

One table per core (``data/cortex_<core>_cycles.json``, chosen through
:mod:`pfbench.mcu.cores`; the M0+/M3/M7/M33 ones derived by :mod:`pfbench.mcu.libcost`).
The default table is ``pfbench/mcu/data/cortex_m4_cycles.json`` (values from
[Recovered]: FPv4-SP instruction timings for ``float`` with the FPU, and
libgcc/newlib soft-float call costs for ``double``). A user table has the same layout::

    {"source": "...", "clock_mhz": 168,
     "precisions": {"float": {"cycles": {"add": 1, ...}}, "double": {"cycles": {...}}},
     "generators": {"uniform": {"rand": 1, "cvt": 1, "mul": 1},
                    "normal": {"uniform": 2, "log": 1, "sqrt": 1, "cos": 1, "mul": 3}}}

(``{"float": {...}, "double": {...}}`` with the cycle dicts at the top level is accepted too;
``generators`` defaults to the built-in ones). Every operation the counter produces
(:data:`pfbench.mcu.counting.OPS`, with ``uniform``/``normal`` expanded through the
generators) must have a cycle count, else :class:`~pfbench.errors.DataError` names it.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import DataError, InputError
from .counting import OPS

DATA_DIR = Path(__file__).with_name("data")
DEFAULT_TABLE = DATA_DIR / "cortex_m4_cycles.json"
PRECISIONS = ("float", "double")
GENERATED = ("uniform", "normal")


@dataclass(frozen=True)
class CycleTable:
    """Cycles per operation for each precision, plus the random-number generator recipes."""

    cycles: dict            # precision -> {op: cycles}
    generators: dict        # "uniform"/"normal" -> {op: count}
    source: str = ""
    name: str = ""
    path: str = ""
    clock_mhz: float = 168.0
    notes: dict = field(default_factory=dict)

    def check_precision(self, precision: str) -> None:
        if precision not in PRECISIONS:
            raise InputError(f"unknown precision {precision!r}; choose float or double")
        if precision not in self.cycles:
            raise DataError(f"cycles table {self.path or self.name}: no {precision!r} section")

    def cost(self, precision: str, op: str, _depth: int = 0) -> float:
        """Cycles of one ``op`` at ``precision``; generated draws expand through their recipe."""
        self.check_precision(precision)
        tab = self.cycles[precision]
        if op in tab:
            return float(tab[op])
        if op in self.generators and _depth < 5:
            return sum(n * self.cost(precision, sub, _depth + 1) for sub, n in self.generators[op].items())
        raise DataError(f"cycles table {self.path or self.name}: precision {precision!r} has no "
                        f"cycle count for operation {op!r}")

    def expand(self, precision: str, op: str) -> dict[str, float]:
        """Primitive operations (and multiplicities) one ``op`` stands for, e.g. a Box-Muller normal."""
        tab = self.cycles[precision]
        if op in tab or op not in self.generators:
            return {op: 1.0}
        out: dict[str, float] = {}
        for sub, n in self.generators[op].items():
            for prim, m in self.expand(precision, sub).items():
                out[prim] = out.get(prim, 0.0) + n * m
        return out

    def validate(self, precision: str, ops=OPS) -> None:
        for op in ops:
            self.cost(precision, op)


def load_table(path: str | Path | None = None) -> CycleTable:
    """Load a cycle table (the built-in one if ``path`` is None) and check it is complete."""
    p = Path(path) if path is not None else DEFAULT_TABLE
    try:
        raw = json.loads(p.read_text())
    except FileNotFoundError:
        raise DataError(f"cycles file {str(p)!r} not found") from None
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:   # a binary file: not UTF-8 text
        raise DataError(f"cycles file {str(p)!r} is not valid JSON: {exc}") from None
    if not isinstance(raw, dict):
        raise DataError(f"cycles file {str(p)!r}: expected a JSON object")
    if "precisions" in raw:
        precs = raw["precisions"]
        if not isinstance(precs, dict):
            raise DataError(f"cycles file {str(p)!r}: 'precisions' must be an object")
        cycles = {k: (v.get("cycles", v) if isinstance(v, dict) else v) for k, v in precs.items()}
    else:
        cycles = {k: raw[k] for k in PRECISIONS if k in raw}
    if not cycles:
        raise DataError(f"cycles file {str(p)!r}: no 'float' or 'double' cycle counts")
    for prec, tab in cycles.items():
        if prec not in PRECISIONS:
            raise DataError(f"cycles file {str(p)!r}: unknown precision {prec!r} (use float, double)")
        if not isinstance(tab, dict):
            raise DataError(f"cycles file {str(p)!r}: {prec!r} cycles must be an object")
        for op, v in tab.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < math.inf:
                raise DataError(f"cycles file {str(p)!r}: {prec} cycles of {op!r} must be a finite "
                                f"non-negative number, got {v!r}")
    generators = raw.get("generators")
    if generators is None:
        generators = (json.loads(DEFAULT_TABLE.read_text())["generators"] if p != DEFAULT_TABLE else {})
    clock = raw.get("clock_mhz", 168.0)
    if isinstance(clock, bool) or not isinstance(clock, (int, float)) or not 0 < clock < math.inf:
        raise DataError(f"cycles file {str(p)!r}: clock_mhz must be a finite number > 0, got {clock!r}")
    table = CycleTable(cycles=cycles, generators=generators, source=str(raw.get("source", "")),
                       name=str(raw.get("name", p.stem)), path=str(p),
                       clock_mhz=float(clock), notes=raw.get("notes", {}))
    for prec in cycles:
        table.validate(prec)
    return table


def cycles_of(counts: dict[str, int], table: CycleTable, precision: str) -> dict[str, float]:
    """Cycles spent per operation class: ``counts[op] * table.cost(precision, op)``."""
    table.check_precision(precision)
    return {op: n * table.cost(precision, op) for op, n in counts.items() if n}


def primitive_cycles(counts: dict[str, int], table: CycleTable, precision: str) -> dict[str, float]:
    """Like :func:`cycles_of` but with generated draws split into their primitive operations
    (so a Box-Muller normal's ``log`` shows up under ``log``)."""
    out: dict[str, float] = {}
    for op, n in counts.items():
        for prim, m in table.expand(precision, op).items():
            out[prim] = out.get(prim, 0.0) + n * m * table.cost(precision, prim)
    return out


def cycles_to_ms(cycles: float, clock_mhz: float) -> float:
    """Milliseconds for ``cycles`` at ``clock_mhz`` (cycles / (MHz * 1e3))."""
    if not clock_mhz > 0:
        raise InputError(f"clock must be > 0 MHz, got {clock_mhz}")
    return float(cycles) / (float(clock_mhz) * 1e3)
