"""Cortex-M time, energy and memory model ([Embedded] §5.1, Tables 1-3), for five cores.

Two layers, both always reported by :func:`predict`:

(a) **code** -- an instruction-level prediction of the code pfbench itself generates (the
    model's own numba-compiled functions in the C harness ``pfbench/mcu/c/pf_model.c``), i.e.
    what ``pfbench mcu emulate`` executes, zero wait states::

        code cycles = sum_op count(op) cycles(op)                      (instruction table)
                    + tmp (load + store) + mm_load load                (counted: compiled model code)
                    + alloc c_alloc + normal c_normal + M N c_ps       (fitted constants)

    ``tmp``/``alloc``/``mm_load`` are the compiled-code conventions of
    :mod:`pfbench.mcu.counting` (array temporaries materialised per element, per-tile
    allocations, matrix-product loads); the three constants (per allocation, per
    harness Box-Muller draw beyond the table's recipe, per particle-step of harness
    loop/call overhead) are fitted by :func:`derive_code_costs` on the emulation of TRAINING
    models only (Ob1, thesis example) and stored with their provenance in
    ``data/cortex_m4_code_costs.json``. ``c_ps`` is a residual: harness loop/call overhead
    (+) minus the work the NumPy reference engine counts but the C harness does not do
    (per-particle variances, N_eff, log-weights: -); in double, where those soft-float
    operations are expensive, it is negative. The constants are derived on the M4 and
    applied unchanged (in cycles) to the other cores -- an assumption;

(b) **board** -- the paper's hand-written C on the paper's STM32F407 board::

        board time = efficiency[precision] * sum_op count(op) * cycles(op, precision) / clock

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

``predicted_ms`` is (b) when ``calibrated`` (the default, unchanged) and the raw table time
otherwise; ``basis="code"`` makes it (a). ``code_ms`` and ``board_ms`` are always there.

Cores (:mod:`pfbench.mcu.cores`): Cortex-M0+, M3, M4F (default: the paper's STM32F407), M7,
M33, each with its own derived cycle table, typical chip clock and RAM. The efficiency factor
is fitted on the M4 only; on another core the SAME factor is applied (an assumption: it
stands for what an instruction table misses -- stalls, flash wait states, compiler
differences -- which we take to be alike in relative terms; the output says so).

Energy, two figures:

* board (the paper's path, M4 only): board power x time, 1.39 W from [Embedded] Table 3
  (0.0012 Wh / 3.110 s = 1.389 W and 0.0358 Wh / 91.75 s = 1.405 W) -- the whole board;
* MCU: the core's typical chip's active run current x supply voltage x time (datasheet
  figure, see ``data/cores.json``), i.e. what the chip alone draws while filtering.

``energy_wh`` is the board figure where a board power is known (the M4, or ``board_power_w``
given), else the MCU figure; both are reported beside it.
"""
from __future__ import annotations

import hashlib
import json
import math
from functools import lru_cache
from pathlib import Path

from ..errors import InputError
from . import cores as _cores
from . import counting
from .cycles import DATA_DIR, PRECISIONS, CycleTable, cycles_of, cycles_to_ms, load_table, primitive_cycles

#: fitted compiled-code constants (written by :func:`derive_code_costs`)
CODE_COSTS_PATH = DATA_DIR / "cortex_m4_code_costs.json"
#: models whose emulation the code constants are fitted on; every other model is held out
TRAINING_MODELS = ("ob1", "thesis_example")
#: (M, N) emulated per precision for the derivation (N a multiple of the 32-particle tile)
DERIVE_CONFIGS = {"float": ((4, 32), (8, 32), (4, 64), (8, 64)),
                  "double": ((2, 32), (4, 32), (2, 64), (4, 64))}
#: the (M, N) the training models are compared at (as in the embedded:mcu-models recipe)
DERIVE_AT = (100, 500)

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
                                    resampling=resampling, code=True).items())


def count_ops(model="ob1", n_steps: int = 1000, n_particles: int = 1000, method: str = "bootstrap",
              n_filters: int = 1, resampling: str = "systematic", model_params: dict | None = None,
              code: bool = False) -> dict:
    """Operation counts of a run (cached per configuration); ``model`` is a name or an instance.
    ``code``: include the compiled-code classes :data:`pfbench.mcu.counting.CODE_OPS`."""
    if isinstance(model, str):
        key = tuple(sorted((model_params or {}).items()))
        out = dict(_counts_cached(model, key, int(n_steps), int(n_particles), method, int(n_filters),
                                  resampling))
    else:
        out = counting.count_run(model, n_steps, n_particles, method=method, n_filters=n_filters,
                                 resampling=resampling, code=True)
    return out if code else {k: v for k, v in out.items() if k not in counting.CODE_OPS}


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
def memory_bytes(model, n_particles: int, n_steps: int, precision: str, history: bool = True,
                 core=None) -> dict:
    """RAM of a C port at ``precision``: particles + resampling buffer (2 n_x) and one weight
    per particle, plus (``history``) the per-step arrays of the simulated experiment (true
    state, measurement, estimate: 2 n_x + n_y per step), as the paper's board run kept them.
    ``core``: whose typical chip's RAM and reserve (default the M4's STM32F407, 192 kB)."""
    c = _cores.get(core)
    ram, reserve = c.ram_bytes, c.reserve_bytes
    s = BYTES[precision]
    per_particle = (2 * model.n_x + 1) * s
    hist = (2 * model.n_x + model.n_y) * s * int(n_steps) if history else 0
    total = per_particle * int(n_particles) + hist
    usable = ram - reserve
    max_np = max((usable - hist) // per_particle, 0)
    return {"bytes": int(total), "particle_bytes": int(per_particle * n_particles), "history_bytes": int(hist),
            "bytes_per_particle": int(per_particle), "ram_bytes": ram, "reserve_bytes": reserve,
            "usable_bytes": usable, "fits": total <= usable, "max_particles": int(max_np),
            "chip": c.chip, "core": c.key}


def check_memory(model, n_particles: int, n_steps: int, precision: str, history: bool = True,
                 core=None, history_flag: str | None = "--no-history") -> dict:
    """:func:`memory_bytes`, or an InputError if it does not fit, with the largest N_p that does;
    ``history_flag``: the caller's option that leaves the history out (None: it has none)."""
    mem = memory_bytes(model, n_particles, n_steps, precision, history, core)
    if not mem["fits"]:
        extra = (f" + {mem['history_bytes'] / 1024:.1f} kB history for {n_steps} steps" if history else "")
        hint = (f"the largest N_p that fits is {mem['max_particles']}" if mem["max_particles"] > 0 else
                "the per-step history alone does not fit: reduce --steps"
                + (f" or use {history_flag}" if history_flag else ""))
        raise InputError(
            f"{n_particles} particles at {precision} need {mem['bytes'] / 1024:.1f} kB "
            f"({mem['particle_bytes'] / 1024:.1f} kB particle arrays{extra}) but the {mem['chip']} has "
            f"{mem['ram_bytes'] / 1024:.0f} kB ({mem['usable_bytes'] / 1024:.0f} kB usable after a "
            f"{mem['reserve_bytes'] // 1024} kB reserve); {hint}")
    return mem


# ------------------------------------------------------------------------- (a) code layer
#: the fitted constants of the code layer, and what each stands for
CODE_CONSTANTS = {
    "alloc": "cycles per array allocation + free of the compiled model code (numba's NRT "
             "allocation calls), per counted ``alloc`` (one per array result per 32-particle tile)",
    "normal": "cycles per standard-normal draw of the harness beyond the cycle table's Box-Muller "
              "recipe (the out-of-line randn/rand_uniform calls, the division in rand_uniform, "
              "the large-argument cos reduction)",
    "particle_step": "cycles per particle-step of harness loop, call and index overhead not in the "
                     "counts (the rest of the training residual)",
}


def _zero_costs() -> dict:
    return {"constants": {k: {p: 0.0 for p in PRECISIONS} for k in CODE_CONSTANTS},
            "source": "none (no derivation found: code layer = counted structure only)"}


def load_code_costs(path=None) -> dict:
    """The fitted code-layer constants (:func:`derive_code_costs`); zeros if none were derived."""
    p = Path(path) if path is not None else CODE_COSTS_PATH
    if not p.exists():
        if path is not None:
            from ..errors import DataError
            raise DataError(f"code-costs file {str(p)!r} not found")
        return _zero_costs()
    return json.loads(p.read_text())


def code_terms(counts: dict, precision: str, table: CycleTable, n_steps: int, n_particles: int,
               costs: dict | None = None) -> dict:
    """Cycles of the code layer (a), per term: ``table`` (engine counts x cycle table),
    ``temporaries`` (tmp x (load + store)), ``matmul_loads`` (mm_load x load) and the fitted
    ``alloc``, ``normal`` and ``particle_step`` terms. ``counts`` must include the compiled-code
    classes (``count_ops(..., code=True)``)."""
    k = (costs or load_code_costs())["constants"]
    engine = {op: n for op, n in counts.items() if op not in counting.CODE_OPS}
    ld, st = table.cost(precision, "load"), table.cost(precision, "store")
    return {
        "table": raw_cycles(engine, precision, table),
        "temporaries": counts.get("tmp", 0) * (ld + st),
        "matmul_loads": counts.get("mm_load", 0) * ld,
        "alloc": counts.get("alloc", 0) * k["alloc"][precision],
        "normal": counts.get("normal", 0) * k["normal"][precision],
        "particle_step": int(n_steps) * int(n_particles) * k["particle_step"][precision],
    }


def code_version() -> dict:
    """Hashes of the sources whose compiled code the derivation emulates."""
    here = Path(__file__).resolve().parent
    files = ["c/pf_model.c", "c/pf_model.h", "c/pf_common.h", "c/nrt_shim.c", "modelcode.py", "emulate.py", "toolchain.py",
             "counting.py", "data/cortex_m4_timing.json", "data/cortex_m4_cycles.json"]
    h = hashlib.sha256()
    for f in files:
        fp = here / f
        if fp.exists():
            h.update(f.encode() + fp.read_bytes())
    return {"sha256": h.hexdigest()[:16], "files": files}


def _emulate_training(name: str, precision: str, seed: int = 1) -> dict:
    """Emulate one training model's compiled code in the harness (M4) and fit a + b M + c M N;
    returns the fit's per-particle-step cycles of the harness's randn, of numba's NRT calls and
    the total cycles at :data:`DERIVE_AT`."""
    import numpy as np

    from .. import models
    from . import emulate as E
    from . import toolchain

    model = models.get(name)
    configs = DERIVE_CONFIGS[precision]
    m_max, n_max = max(m for m, _ in configs), max(n for _, n in configs)
    mo = E.model_object(name, precision, None, "cortex-m4")
    build = toolchain.build_model(mo, precision, nmax=max(64, n_max), mmax=max(16, m_max), tile=counting.TILE)
    prog = E.Program(build, core="m4")
    traj = model.simulate(m_max, seed=seed)
    x0 = np.asarray(model.initial(np.random.default_rng([seed, 1]), n_max, model.params()),
                    dtype=np.float64).reshape(n_max, model.n_x)
    f = E.fit([E.run_model(prog, model, traj, x0, m, n, seed=seed) for m, n in configs])
    m, n = DERIVE_AT
    c = f["cycles"]["nominal"]
    return {"model": name, "precision": precision, "configs": [list(x) for x in configs],
            "cycles_per_particle_step_at": E.predict_cycles(c, m, n) / (m * n),
            "randn_per_particle_step": f["by_owner"].get("randn", {}).get("per_particle_step", 0.0),
            "nrt_per_particle_step": sum(v["per_particle_step"] for k, v in f["by_entry"].items()
                                         if k.startswith("NRT_")),
            "fit_residual_rel": f["residual_rel"]}


def derive_code_costs(training=TRAINING_MODELS, write: bool = False, seed: int = 1) -> dict:
    """Fit the code-layer constants on the emulation of the ``training`` models (M4, nominal
    timing), by attribution then residual:

    * ``normal`` = emulated harness ``randn`` cycles per draw - the table's ``normal`` cost;
    * ``alloc``  = emulated NRT allocation/free cycles per counted ``alloc``;
    * ``particle_step`` = emulated cycles at M, N = :data:`DERIVE_AT` per particle-step minus
      the code layer with the two constants above (mean over the training models).

    Each constant is the mean over the training models. ``write`` stores the result with its
    provenance (what was emulated, source hashes, compiler) in :data:`CODE_COSTS_PATH`
    (needs ``make mcu-tools``). Re-run after the harness or the model compiler changes:
    ``python -m pfbench.mcu.costmodel --derive``."""
    from . import toolchain

    table = load_table()
    m, n = DERIVE_AT
    emus, consts = [], {k: {} for k in CODE_CONSTANTS}
    for prec in PRECISIONS:
        parts = {k: [] for k in CODE_CONSTANTS}
        rows = []
        for name in training:
            e = _emulate_training(name, prec, seed)
            small = count_ops(name, 8, 64, code=True)     # exact tiles, as the emulated N
            ps_small = 8 * 64
            normals = small.get("normal", 0) / ps_small
            allocs = small.get("alloc", 0) / ps_small
            parts["normal"].append(e["randn_per_particle_step"] / normals - table.cost(prec, "normal")
                                   if normals else 0.0)
            parts["alloc"].append(e["nrt_per_particle_step"] / allocs if allocs else 0.0)
            rows.append((name, e))
            emus.append(e)
        consts["normal"][prec] = sum(parts["normal"]) / len(parts["normal"])
        consts["alloc"][prec] = sum(parts["alloc"]) / len(parts["alloc"])
        partial = {"constants": {"normal": consts["normal"], "alloc": consts["alloc"],
                                 "particle_step": {p: 0.0 for p in PRECISIONS}}}
        resid = []
        for name, e in rows:
            counts = count_ops(name, m, n, code=True)
            pred = sum(code_terms(counts, prec, table, m, n, partial).values()) / (m * n)
            resid.append(e["cycles_per_particle_step_at"] - pred)
        consts["particle_step"][prec] = sum(resid) / len(resid)
    out = {"name": "cortex-m4 code-layer constants",
           "source": "fitted by pfbench.mcu.costmodel.derive_code_costs on the unicorn emulation "
                     "(Cortex-M4 nominal timing table) of the training models' own compiled code in "
                     "pfbench/mcu/c/pf_model.c; every other model is held out",
           "training_models": list(training), "compared_at": {"steps": m, "particles": n},
           "emulated": emus, "code_version": code_version(),
           "compiler": toolchain.compiler_version(), "cycles_table": str(table.path),
           "notes": CODE_CONSTANTS,
           "constants": {k: {p: round(v, 3) for p, v in d.items()} for k, d in consts.items()}}
    if write:
        CODE_COSTS_PATH.write_text(json.dumps(out, indent=1) + "\n")
    return out


# ------------------------------------------------------------------------- prediction
EFFICIENCY_NOTE = ("efficiency fitted on the Cortex-M4 ([Embedded] Table 2) and applied unchanged to this core "
                   "(assumption: the share of cycles an instruction table misses is alike across cores)")


def _efficiency(core, table: CycleTable, precision: str, calibrated: bool) -> tuple[float, str]:
    if not calibrated:
        return 1.0, "uncalibrated (instruction-table cycles)"
    if core.key == "m4":
        return calibrate(table)["efficiency"][precision], "fitted on [Embedded] Table 2 (this core)"
    return calibrate()["efficiency"][precision], EFFICIENCY_NOTE


def predict(model="ob1", n_steps: int = 1000, n_particles: int = 1000, precision: str = "float",
            method: str = "bootstrap", n_filters: int = 1, clock_mhz: float | None = None, *,
            core="m4", cycles=None, board_power_w: float | None = None, calibrated: bool = True,
            resampling: str = "systematic", memory: bool = True, history: bool = True,
            model_params: dict | None = None, basis: str | None = None, code_costs=None) -> dict:
    """Predicted run time, energy and RAM of a filter run on a Cortex-M core.

    Parameters
    ----------
    model : registered model name (or a model instance).
    precision : ``float`` (the paper's optimised build D(O); FPU where the core has one) or
        ``double`` (D(S); soft-float except on the M7's double-precision FPU).
    core : ``m0plus``, ``m3``, ``m4`` (default, the STM32F407 of [Embedded] Table 1), ``m7``,
        ``m33`` (:mod:`pfbench.mcu.cores`).
    clock_mhz : core clock (default: the core's typical chip, 168 MHz for the M4).
    cycles : path of a cycle table JSON (default: the core's) or a :class:`CycleTable`.
    board_power_w : board power for the board energy figure (default: 1.39 W, [Embedded]
        Table 3, on the M4; none on the other cores).
    calibrated : apply the Table-2 efficiency factor of ``precision`` (see :func:`calibrate`;
        fitted on the M4 and applied unchanged to the other cores).
    memory : refuse (InputError) configurations whose arrays exceed the chip's RAM.
    basis : what ``predicted_ms`` (and energy, cycles) is: ``"board"`` (layer (b), the default
        when ``calibrated``), ``"table"`` (raw instruction-table time, the default when not) or
        ``"code"`` (layer (a): pfbench's own compiled code, what ``pfbench mcu emulate`` checks).
        ``code_ms``/``code_terms`` and ``board_ms`` are reported whatever the basis.
    code_costs : path of a code-constants JSON (default ``data/cortex_m4_code_costs.json``).

    Returns
    -------
    dict with ``predicted_ms``, ``energy_wh`` (board where known, else MCU),
    ``energy_board_wh``, ``energy_mcu_wh``, ``energy_per_step_uj`` (MCU), ``precision``,
    ``clock_mhz``, ``core``, ``ops`` (counts), ``cycles_by_op`` (primitive ops), ``share``,
    ``raw_ms``, ``efficiency`` (+ ``efficiency_basis``), ``memory`` and more.
    """
    from .. import models

    _check_precision(precision)
    c = _cores.get(core)
    clock = _check_clock(c.clock_mhz if clock_mhz is None else clock_mhz)
    if board_power_w is None:
        board_power_w = c.board_power_w
    power = None if board_power_w is None else checked_number(board_power_w, "board power", "W",
                                                             allow_zero=True)
    table = _table(c.cycles_path if cycles is None else cycles)
    table.check_precision(precision)
    mdl = models.get(model, **(model_params or {})) if isinstance(model, str) else model
    counting._validate(mdl, n_steps, n_particles, method, n_filters, resampling)
    requested, n_particles = int(n_particles), particles_used(n_particles, method, n_filters)
    mem = (check_memory if memory else memory_bytes)(mdl, n_particles, int(n_steps), precision, history, c)
    if basis is None:
        basis = "board" if calibrated else "table"
    if basis not in ("board", "code", "table"):
        raise InputError(f"unknown basis {basis!r}; choose board, code or table")
    calibrated = basis == "board"
    all_counts = count_ops(model if isinstance(model, str) else mdl, int(n_steps), int(n_particles),
                           method, int(n_filters), resampling, model_params, code=True)
    counts = {k: v for k, v in all_counts.items() if k not in counting.CODE_OPS}
    costs = load_code_costs(code_costs)
    terms = code_terms(all_counts, precision, table, n_steps, n_particles, costs)
    code_total = float(sum(terms.values()))
    by_op = primitive_cycles(counts, table, precision)
    prim_counts: dict[str, float] = {}
    for op, n in counts.items():
        for prim, m in table.expand(precision, op).items():
            prim_counts[prim] = prim_counts.get(prim, 0.0) + n * m
    total = float(sum(by_op.values()))
    raw_ms = cycles_to_ms(total, clock)
    board_eff, eff_basis = _efficiency(c, table, precision, True)
    code_ms = cycles_to_ms(code_total, clock)
    eff, ebasis = {"board": (board_eff, eff_basis),
                   "table": (1.0, "uncalibrated (instruction-table cycles)"),
                   "code": (code_total / total if total else 1.0, CODE_BASIS + " (code_ms / raw_ms)")}[basis]
    ms = eff * raw_ms
    ps = int(n_steps) * int(n_particles)
    mcu_w = c.power_w(clock)
    e_mcu = mcu_w * ms / 1e3 / 3600.0
    e_board = None if power is None else power * ms / 1e3 / 3600.0
    return {
        "model": getattr(mdl, "name", str(model)), "method": method, "n_filters": int(n_filters),
        "n_steps": int(n_steps), "n_particles": int(n_particles), "n_particles_requested": requested,
        "resampling": resampling,
        "precision": precision, "core": c.key, "core_name": c.name, "chip": c.chip, "fpu": c.fpu,
        "clock_mhz": clock, "predicted_ms": ms, "raw_ms": raw_ms, "step_us": 1e3 * ms / int(n_steps),
        "efficiency": eff, "efficiency_basis": ebasis, "calibrated": bool(calibrated), "basis": basis,
        "code_ms": code_ms, "code_cycles": code_total, "code_cycles_per_particle_step": code_total / ps,
        "code_terms": {k: v / ps for k, v in terms.items()},
        "code_costs_source": costs.get("source", ""),
        "board_ms": board_eff * raw_ms, "board_efficiency": board_eff, "board_basis": eff_basis,
        "board_cycles_per_particle_step": board_eff * total / ps,
        "board_over_code": board_eff * total / code_total if code_total else None,
        "cycles": eff * total, "raw_cycles": total, "cycles_per_particle_step": eff * total / ps,
        "board_power_w": power, "mcu_power_w": mcu_w,
        "mcu_current_ma": c.current_ma(clock), "mcu_voltage_v": c.voltage_v,
        "mcu_current_assumed": c.sources.get("power", "").startswith("assumed"),
        "energy_wh": e_board if e_board is not None else e_mcu,
        "energy_basis": ("board power x time ([Embedded] Table 3)" if e_board is not None
                         else "MCU active current x voltage x time (datasheet, see cores.json)"),
        "energy_board_wh": e_board, "energy_mcu_wh": e_mcu,
        "energy_per_step_uj": e_mcu * 3.6e9 / int(n_steps),
        "energy_board_per_step_uj": None if e_board is None else e_board * 3.6e9 / int(n_steps),
        "ops": counts, "ops_per_particle_step": {k: v / ps for k, v in counts.items()},
        "primitive_ops": prim_counts,
        "primitive_ops_per_particle_step": {k: v / ps for k, v in prim_counts.items()},
        "cycles_each": {k: table.cost(precision, k) for k in prim_counts},
        "cycles_by_op": by_op, "share": {k: v / total for k, v in by_op.items()} if total else {},
        "memory": mem, "cycles_table": table.path,
    }


# ------------------------------------------------------------------------- fit
#: particle counts at which the per-step cost is counted; counts are affine in N_p for the
#: particle methods (checked at a third point, ``linearity_error`` in the output)
_FIT_NP = (100, 200, 400)
_FIT_MAX_STEPS = 100


CODE_BASIS = "code layer: pfbench's compiled code, zero wait states"


def _step_model(model, n_steps, precision, method, n_filters, resampling, model_params, table, clock, eff,
                basis="board"):
    """Per-step time (us) as a + b N_p from counts at two N_p; the third checks linearity.
    ``basis`` "code": the code layer (a) (``eff`` unused); else ``eff`` x table cycles."""
    m = min(int(n_steps), _FIT_MAX_STEPS)
    points = fit_points(n_filters)
    us = []
    for n in points:
        nf = int(n_filters)
        counts = count_ops(model, m, n, method, nf, resampling, model_params, code=basis == "code")
        cyc = (float(sum(code_terms(counts, precision, table, m, n).values())) if basis == "code"
               else eff * raw_cycles(counts, precision, table))
        us.append(cycles_to_ms(cyc, clock) * 1e3 / m)
    b = (us[1] - us[0]) / (points[1] - points[0])
    a = us[0] - b * points[0]
    lin = abs(a + b * points[2] - us[2]) / us[2]
    return a, b, lin


def _assumed_currents(rows: list) -> str:
    """How many of the rows' cores have a run current marked assumed in cores.json, as "k of n"."""
    keys = dict.fromkeys(r["core"] for r in rows)
    k = sum(_cores.get(key).sources.get("power", "").startswith("assumed") for key in keys)
    return f"{k} of {len(keys)}"


def particles_used(n_particles: int, method: str, n_filters: int) -> int:
    """The particles a run of ``n_particles`` has: MultiPDF gives each of its N_f sub-filters
    round(N_p / N_f) (:func:`pfbench.filters.particle.split_particles`), so it runs a multiple of N_f;
    the cost, the RAM and :func:`fit`'s answer are of that many."""
    from ..filters.particle import split_particles

    return split_particles(int(n_particles), int(n_filters)) * int(n_filters) if method == "multipdf" else int(
        n_particles)


def fit_points(n_filters: int) -> tuple:
    """The N_p of :func:`_step_model`'s counts: 100, 200 and 400, times the smallest factor that
    gives each of the N_f sub-filters at least one particle."""
    k = -(-max(int(n_filters), 1) // _FIT_NP[0])
    return tuple(k * n for n in _FIT_NP)


def fit(model="ob1", n_steps: int = 1000, period_us: float = 1000.0, method: str = "bootstrap",
        n_filters: int = 1, resampling: str = "systematic", *, cores=None, precisions=PRECISIONS,
        clock_mhz: dict | None = None, history: bool = False, calibrated: bool = True,
        model_params: dict | None = None, basis: str | None = None) -> dict:
    """For each core and precision, the largest N_p whose per-step time meets ``period_us``
    AND whose arrays fit the core's RAM; which limit binds; energy per step at that N_p.

    ``basis`` is the time layer as in :func:`predict`: "board" (default; the [Embedded] Table-2
    efficiency: hand-written C on the paper's board), "code" (the code pfbench compiles for the
    MCU, zero wait states; its constants were derived on the M4) or "table".

    The per-step time is affine in N_p, ``a + b N_p`` (fixed per-step work + per-particle
    work), fitted from operation counts at N_p = 100 and 200 over ``min(M, 100)`` steps
    (checked at 400: ``linearity_error``). ``history`` includes the per-step history arrays
    of an M-step experiment in the RAM check (off: a deployed filter keeps no history).
    ``clock_mhz`` maps core -> clock (default: each core's typical chip)."""
    from .. import models

    period = checked_number(period_us, "sampling period", "us")
    if isinstance(n_steps, bool) or not isinstance(n_steps, int) or n_steps < 1:
        raise InputError(f"steps must be an integer >= 1, got {n_steps!r}")
    for p in precisions:
        _check_precision(p)
    mdl = models.get(model, **(model_params or {})) if isinstance(model, str) else model
    counting._validate(mdl, n_steps, max(fit_points(n_filters)), method, n_filters, resampling)
    key = model if isinstance(model, str) else mdl
    if basis is None:
        basis = "board" if calibrated else "table"
    if basis not in ("board", "code", "table"):
        raise InputError(f"unknown basis {basis!r}; choose board, code or table")
    rows = []
    for c in [_cores.get(k) for k in (cores or _cores.names())]:
        clock = _check_clock((clock_mhz or {}).get(c.key, c.clock_mhz))
        table = c.cycle_table()
        for prec in precisions:
            eff, ebasis = _efficiency(c, table, prec, basis == "board")
            if basis == "code":
                eff, ebasis = None, CODE_BASIS + ("" if c.key == "m4" else
                                                  "; constants derived on the Cortex-M4, applied unchanged")
            a, b, lin = _step_model(key, n_steps, prec, method, n_filters, resampling, model_params, table,
                                    clock, eff, basis)
            n_time = int(math.floor((period - a) / b)) if period > a else 0
            mem = memory_bytes(mdl, 1, n_steps, prec, history, c)
            n_ram = mem["max_particles"]
            n_p = max(min(n_time, n_ram), 0)
            if method == "multipdf":  # sub-filters of equal size: a multiple of N_f (particles_used)
                n_p -= n_p % int(n_filters)
            if n_p < max(int(n_filters), 1):
                binding = "time" if n_time <= n_ram else "ram"
                n_p = 0
            else:
                binding = "time" if n_time <= n_ram else "ram"
            step_us = a + b * n_p if n_p else None
            e_uj = None if step_us is None else c.power_w(clock) * step_us
            rows.append({"core": c.key, "core_name": c.name, "chip": c.chip, "fpu": c.fpu,
                         "clock_mhz": clock, "ram_kb": c.ram_bytes / 1024, "precision": prec,
                         "max_particles": n_p, "binding": binding, "n_time": max(n_time, 0),
                         "n_ram": n_ram, "step_us": step_us, "fixed_us": a, "per_particle_us": b,
                         "utilisation": None if step_us is None else step_us / period,
                         "mcu_power_w": c.power_w(clock), "energy_per_step_uj": e_uj,
                         "bytes_per_particle": mem["bytes_per_particle"],
                         "efficiency": eff, "efficiency_basis": ebasis, "linearity_error": lin})
    return {"model": getattr(mdl, "name", str(model)), "method": method, "n_filters": int(n_filters),
            "basis": basis,
            "resampling": resampling, "n_steps": int(n_steps), "period_us": period,
            "rate_hz": 1e6 / period, "history": bool(history), "rows": rows,
            "notes": ["max_particles: largest N_p with per-step time <= period AND arrays <= usable RAM; "
                      "binding names the limit reached first ('time' or 'ram'); 0 = not even the "
                      "minimum fits",
                      "energy_per_step_uj: MCU active current x voltage x per-step time at that N_p "
                      f"(run currents from cores.json; {_assumed_currents(rows)} of the rows' cores marked "
                      "assumed there, not read from a datasheet in this project)",
                      *([] if history else ["RAM: the filter's arrays only (a deployed filter keeps no "
                                            "history); `mcu estimate` counts the M-step history too unless "
                                            "--no-history, and --history counts it here"]),
                      *([f"the board layer's leave-one-out error on [Embedded] Table 2 reaches "
                         f"{calibrate()['max_abs_loo_error']:.0%} (`pfbench mcu calibrate`): an N_p that fills the "
                         "period to the last percent may miss it on a board; leave that margin"]
                        if basis == "board" else []),
                      EFFICIENCY_NOTE + " for every core but the M4" if basis == "board" else
                      f"time basis: {basis} ({CODE_BASIS if basis == 'code' else 'instruction-table cycles'})"
                      + ("; its constants were derived on the Cortex-M4 and are applied unchanged to the other "
                         "cores" if basis == "code" else "")]}


if __name__ == "__main__":  # python -m pfbench.mcu.costmodel --derive [--write]
    import sys

    if "--derive" in sys.argv:
        res = derive_code_costs(write="--write" in sys.argv)
        print(json.dumps(res["constants"], indent=1))
