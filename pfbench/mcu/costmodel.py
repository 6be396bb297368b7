"""Cortex-M4 (STM32F407 @ 168 MHz) time, energy and memory model ([Embedded] §5.1, Tables 1-3).

time = efficiency[precision] * sum_op count(op) * cycles(op, precision) / clock

* ``count(op)``: derived automatically from the NumPy reference engine for any registered
  model and method (:mod:`pfbench.mcu.counting`);
* ``cycles(op, precision)``: a data table (:mod:`pfbench.mcu.cycles`) for ``float`` (FPU) and
  ``double`` (soft-float), replaceable by the user;
* ``efficiency``: ONE fitted factor per precision (2 parameters in all), fitted on the six
  cells of [Embedded] Table 2 by least squares in log space, i.e. the geometric mean of
  published / raw-predicted time. It absorbs what the instruction table does not see (pipeline
  stalls, flash wait states, loop overhead, register spills, what the compiler removed).
  :func:`calibrate` reports the fit, the leave-one-out error of every cell and the predicted
  vs published float/double ratios.

Energy = board power x time (board power 1.39 W: Table 3, 0.0012 Wh / 3.110 s = 1.389 W and
0.0358 Wh / 91.75 s = 1.405 W).
"""
from __future__ import annotations

import math
from functools import lru_cache

from ..errors import InputError
from . import counting
from .cycles import PRECISIONS, CycleTable, cycles_of, cycles_to_ms, load_table, primitive_cycles

#: [Embedded] Table 2: (M iterations, N_p particles) -> (D(S) ms, D(O) ms), STM32F407 @ 168 MHz
TABLE2 = {(500, 500): (23247.0, 640.0), (500, 1000): (46374.0, 1376.0), (1000, 1000): (92950.0, 3112.0)}
#: [Embedded] Table 3 (M = N_p = 1000): platform -> (processing time s, energy Wh)
TABLE3 = {"A": (0.249, 0.0068), "B": (0.260, 0.0030), "C": (1.767, 0.0155),
          "D(O)": (3.110, 0.0012), "D(S)": (91.750, 0.0358)}
#: [Embedded] §5.1 text: float/double ratios D(S)/D(O) per Table 2 cell (computed: 36.3, 33.7, 29.9)
PAPER_RATIOS = {k: v[0] / v[1] for k, v in TABLE2.items()}
BOARD_POWER_W = 1.39
CLOCK_MHZ = 168.0
RAM_BYTES = 192 * 1024          # STM32F407: 128 kB SRAM + 64 kB CCM (Table 1: 192 kB)
RAM_RESERVE_BYTES = 16 * 1024   # assumed: stack, libc/newlib state, globals, USART buffers
BYTES = {"float": 4, "double": 8}
_PREC_TO_COL = {"double": 0, "float": 1}   # D(S) = double standard build, D(O) = float -Ofast


def _table(cycles) -> CycleTable:
    if isinstance(cycles, CycleTable):
        return cycles
    return load_table(cycles)


def _check_precision(precision: str) -> None:
    if precision not in PRECISIONS:
        raise InputError(f"unknown precision {precision!r}; choose float or double")


def checked_number(value, what: str, unit: str = "", allow_zero: bool = False) -> float:
    """``value`` as a finite float > 0 (>= 0 with ``allow_zero``), else a one-line InputError."""
    unit_s = f" {unit}" if unit else ""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a number{' of ' + unit if unit else ''}, got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise InputError(f"{what} must be {'>=' if allow_zero else '>'} 0{unit_s}, got {value}")
    return v


def _check_clock(clock_mhz) -> float:
    return checked_number(clock_mhz, "clock", "MHz")


@lru_cache(maxsize=256)
def _counts_cached(model_name: str, params: tuple, n_steps: int, n_particles: int, method: str,
                   n_filters: int, resampling: str) -> tuple:
    from .. import models

    model = models.get(model_name, **dict(params))
    return tuple(counting.count_run(model, n_steps, n_particles, method=method, n_filters=n_filters,
                                    resampling=resampling).items())


def count_ops(model="ob1", n_steps: int = 1000, n_particles: int = 1000, method: str = "bootstrap",
              n_filters: int = 1, resampling: str = "systematic", model_params: dict | None = None) -> dict:
    """Operation counts of a run (cached per configuration); ``model`` is a name or an instance."""
    if isinstance(model, str):
        key = tuple(sorted((model_params or {}).items()))
        return dict(_counts_cached(model, key, int(n_steps), int(n_particles), method, int(n_filters),
                                   resampling))
    return counting.count_run(model, n_steps, n_particles, method=method, n_filters=n_filters,
                              resampling=resampling)


def raw_cycles(counts: dict, precision: str, cycles=None) -> float:
    """Uncalibrated cycles of a run: sum of count x cycles."""
    return float(sum(cycles_of(counts, _table(cycles), precision).values()))


# ------------------------------------------------------------------------- calibration
def _fit(pairs) -> float:
    """Efficiency minimising sum (log(published) - log(eff * raw))^2: the geometric mean ratio."""
    logs = [math.log(pub / raw) for raw, pub in pairs]
    return math.exp(sum(logs) / len(logs))


@lru_cache(maxsize=16)
def _calibrate_cached(table_key: str) -> dict:
    table = load_table(None if table_key == "" else table_key)
    cells = []
    for (m, n), pub in TABLE2.items():
        counts = count_ops("ob1", m, n)
        for prec in PRECISIONS:
            raw_ms = cycles_to_ms(raw_cycles(counts, prec, table), CLOCK_MHZ)
            cells.append({"M": m, "N_p": n, "precision": prec, "build": "D(S)" if prec == "double" else "D(O)",
                          "published_ms": pub[_PREC_TO_COL[prec]], "raw_ms": raw_ms})
    eff = {}
    for prec in PRECISIONS:
        mine = [c for c in cells if c["precision"] == prec]
        eff[prec] = _fit([(c["raw_ms"], c["published_ms"]) for c in mine])
        for c in mine:
            c["fitted_ms"] = eff[prec] * c["raw_ms"]
            c["fit_error"] = c["fitted_ms"] / c["published_ms"] - 1.0
            others = [(o["raw_ms"], o["published_ms"]) for o in mine if o is not c]
            c["loo_efficiency"] = _fit(others)
            c["loo_ms"] = c["loo_efficiency"] * c["raw_ms"]
            c["loo_error"] = c["loo_ms"] / c["published_ms"] - 1.0
    ratios = []
    for (m, n), pub in TABLE2.items():
        d = next(c for c in cells if (c["M"], c["N_p"], c["precision"]) == (m, n, "double"))
        f = next(c for c in cells if (c["M"], c["N_p"], c["precision"]) == (m, n, "float"))
        ratios.append({"M": m, "N_p": n, "published_ratio": pub[0] / pub[1],
                       "raw_ratio": d["raw_ms"] / f["raw_ms"], "fitted_ratio": d["fitted_ms"] / f["fitted_ms"],
                       "loo_ratio": d["loo_ms"] / f["loo_ms"]})
        r = ratios[-1]
        r["fitted_ratio_error"] = r["fitted_ratio"] / r["published_ratio"] - 1.0
        r["loo_ratio_error"] = r["loo_ratio"] / r["published_ratio"] - 1.0
    return {"efficiency": eff, "n_parameters": len(eff), "cells": cells, "ratios": ratios,
            "max_abs_loo_error": max(abs(c["loo_error"]) for c in cells),
            "method": "one efficiency factor per precision, least squares in log space on [Embedded] "
                      "Table 2 (Ob1, bootstrap, systematic resampling, 168 MHz)",
            "cycles_table": table.path}


def calibrate(cycles=None) -> dict:
    """Fit the per-precision efficiency on Table 2; report fit, leave-one-out errors and ratios."""
    if isinstance(cycles, CycleTable):
        key = cycles.path
    else:
        key = "" if cycles is None else str(cycles)
    import copy

    return copy.deepcopy(_calibrate_cached(key))


# ------------------------------------------------------------------------- memory
def memory_bytes(model, n_particles: int, n_steps: int, precision: str, history: bool = True) -> dict:
    """RAM of a C port at ``precision``: particles + resampling buffer (2 n_x) and one weight
    per particle, plus (``history``) the per-step arrays of the simulated experiment (true
    state, measurement, estimate: 2 n_x + n_y per step), as the paper's board run kept them."""
    s = BYTES[precision]
    per_particle = (2 * model.n_x + 1) * s
    hist = (2 * model.n_x + model.n_y) * s * int(n_steps) if history else 0
    total = per_particle * int(n_particles) + hist
    usable = RAM_BYTES - RAM_RESERVE_BYTES
    max_np = max((usable - hist) // per_particle, 0)
    return {"bytes": int(total), "particle_bytes": int(per_particle * n_particles), "history_bytes": int(hist),
            "bytes_per_particle": int(per_particle), "ram_bytes": RAM_BYTES, "reserve_bytes": RAM_RESERVE_BYTES,
            "usable_bytes": usable, "fits": total <= usable, "max_particles": int(max_np)}


def check_memory(model, n_particles: int, n_steps: int, precision: str, history: bool = True) -> dict:
    mem = memory_bytes(model, n_particles, n_steps, precision, history)
    if not mem["fits"]:
        extra = (f" + {mem['history_bytes'] / 1024:.1f} kB history for {n_steps} steps" if history else "")
        hint = (f"the largest N_p that fits is {mem['max_particles']}" if mem["max_particles"] > 0 else
                "the per-step history alone does not fit: reduce --steps or use --no-history")
        raise InputError(
            f"{n_particles} particles at {precision} need {mem['bytes'] / 1024:.1f} kB "
            f"({mem['particle_bytes'] / 1024:.1f} kB particle arrays{extra}) but the STM32F407 has 192 kB "
            f"({mem['usable_bytes'] / 1024:.0f} kB usable after a {RAM_RESERVE_BYTES // 1024} kB reserve); {hint}")
    return mem


# ------------------------------------------------------------------------- prediction
def predict(model="ob1", n_steps: int = 1000, n_particles: int = 1000, precision: str = "float",
            method: str = "bootstrap", n_filters: int = 1, clock_mhz: float = CLOCK_MHZ, *,
            cycles=None, board_power_w: float = BOARD_POWER_W, calibrated: bool = True,
            resampling: str = "systematic", memory: bool = True, history: bool = True,
            model_params: dict | None = None) -> dict:
    """Predicted STM32F4 time and energy of a filter run.

    Parameters
    ----------
    model : registered model name (or a model instance).
    precision : ``float`` (FPU, the paper's optimised build D(O)) or ``double`` (soft-float, D(S)).
    clock_mhz : core clock (default 168, the STM32F407 of [Embedded] Table 1).
    cycles : path of a cycle table JSON (default: the built-in one) or a :class:`CycleTable`.
    calibrated : apply the Table-2 efficiency factor of ``precision`` (see :func:`calibrate`).
    memory : refuse (InputError) configurations whose arrays exceed the 192 kB RAM.

    Returns
    -------
    dict with ``predicted_ms``, ``energy_wh``, ``precision``, ``clock_mhz``, ``ops`` (counts),
    ``cycles_by_op`` (primitive ops, e.g. a Box-Muller normal split into its log/sqrt/cos),
    ``share`` (fraction of cycles per op), ``raw_ms``, ``efficiency``, ``memory`` and more.
    """
    from .. import models

    _check_precision(precision)
    clock = _check_clock(clock_mhz)
    power = checked_number(board_power_w, "board power", "W", allow_zero=True)
    table = _table(cycles)
    table.check_precision(precision)
    mdl = models.get(model, **(model_params or {})) if isinstance(model, str) else model
    counting._validate(mdl, n_steps, n_particles, method, n_filters, resampling)
    mem = (check_memory if memory else memory_bytes)(mdl, int(n_particles), int(n_steps), precision, history)
    counts = count_ops(model if isinstance(model, str) else mdl, int(n_steps), int(n_particles), method,
                       int(n_filters), resampling, model_params)
    by_op = primitive_cycles(counts, table, precision)
    prim_counts: dict[str, float] = {}
    for op, n in counts.items():
        for prim, m in table.expand(precision, op).items():
            prim_counts[prim] = prim_counts.get(prim, 0.0) + n * m
    total = float(sum(by_op.values()))
    raw_ms = cycles_to_ms(total, clock)
    eff = calibrate(table)["efficiency"][precision] if calibrated else 1.0
    ms = eff * raw_ms
    ps = int(n_steps) * int(n_particles)
    return {
        "model": getattr(mdl, "name", str(model)), "method": method, "n_filters": int(n_filters),
        "n_steps": int(n_steps), "n_particles": int(n_particles), "resampling": resampling,
        "precision": precision, "clock_mhz": clock, "predicted_ms": ms, "raw_ms": raw_ms,
        "efficiency": eff, "calibrated": bool(calibrated),
        "cycles": eff * total, "raw_cycles": total, "cycles_per_particle_step": eff * total / ps,
        "board_power_w": power, "energy_wh": power * ms / 1e3 / 3600.0,
        "ops": counts, "ops_per_particle_step": {k: v / ps for k, v in counts.items()},
        "primitive_ops": prim_counts,
        "primitive_ops_per_particle_step": {k: v / ps for k, v in prim_counts.items()},
        "cycles_each": {k: table.cost(precision, k) for k in prim_counts},
        "cycles_by_op": by_op, "share": {k: v / total for k, v in by_op.items()} if total else {},
        "memory": mem, "cycles_table": table.path,
    }
