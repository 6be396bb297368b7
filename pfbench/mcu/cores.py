"""Cortex-M cores as data (``pfbench/mcu/data/cores.json``): chip, clock, RAM, power, tables.

Five cores: Cortex-M0+ (no FPU), M3 (no FPU), M4F (single-precision FPU; the STM32F407 of
[Embedded] Table 1), M7 (double-precision FPU, dual issue) and M33 (single-precision FPU).
Each entry names a typical chip (clock, RAM), its active run current and supply voltage
(energy = current x voltage x time), the unicorn CPU model used to check the derivation
builds, the cycle table of the cost model (``cortex_<core>_cycles.json``, derived by
:mod:`pfbench.mcu.libcost` except the M4 one, which is the original [Recovered] table) and
the instruction-timing table (``cortex_<core>_timing.json``). Every number carries a source
string; values not read from a primary document say ``assumed`` and why.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from ..errors import DataError, InputError

DATA_DIR = Path(__file__).with_name("data")
CORES_PATH = DATA_DIR / "cores.json"


@dataclass(frozen=True)
class Core:
    """One Cortex-M core with its typical chip."""

    key: str
    name: str
    architecture: str
    fpu: str                    # "none" | "sp" | "dp"
    unicorn_cpu: str
    chip: str
    clock_mhz: float
    ram_bytes: int
    reserve_bytes: int
    voltage_v: float
    current_ma_per_mhz: float   # active run current scales ~linearly with the clock
    board_power_w: float | None
    coremark_per_mhz: float
    cycles_path: Path
    timing_path: Path
    gcc: dict
    sources: dict = field(default_factory=dict)

    def current_ma(self, clock_mhz: float | None = None) -> float:
        """Active run current at ``clock_mhz`` (default: the chip's typical clock), mA.

        Datasheet run currents are close to linear in f_HCLK; the one published point is scaled
        through the origin, leaving out the static part: below that clock the current is
        underestimated, above it overestimated, and the energy per step comes out the same at
        every clock."""
        return self.current_ma_per_mhz * float(clock_mhz or self.clock_mhz)

    def power_w(self, clock_mhz: float | None = None) -> float:
        """MCU power in run mode: active current x supply voltage."""
        return self.current_ma(clock_mhz) * 1e-3 * self.voltage_v

    def cycle_table(self):
        from .cycles import load_table

        return load_table(self.cycles_path)

    def timing(self) -> dict:
        return json.loads(self.timing_path.read_text())

    @property
    def cpu(self) -> str:
        """The gcc/LLVM CPU name (``cortex-m4``), from the core's ``-mcpu`` flag."""
        return next(f.split("=", 1)[1] for f in self.gcc["float"] if f.startswith("-mcpu="))

    def has_hw(self, precision: str) -> bool:
        """Whether ``precision`` arithmetic runs on an FPU (else libgcc soft-float)."""
        return self.fpu == "dp" or (self.fpu == "sp" and precision == "float")

    def as_dict(self) -> dict:
        return {"core": self.key, "name": self.name, "architecture": self.architecture,
                "fpu": self.fpu, "chip": self.chip, "clock_mhz": self.clock_mhz,
                "ram_kb": self.ram_bytes / 1024, "reserve_kb": self.reserve_bytes / 1024,
                "voltage_v": self.voltage_v, "current_ma": self.current_ma(),
                "power_w": self.power_w(), "board_power_w": self.board_power_w,
                "coremark_per_mhz": self.coremark_per_mhz, "unicorn_cpu": self.unicorn_cpu,
                "cycles_table": self.cycles_path.name, "timing_table": self.timing_path.name,
                "sources": self.sources}


def _num(entry: dict, key: str, where: str) -> float:
    v = entry.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
        raise DataError(f"{CORES_PATH.name}: {where}: {key!r} must be a number > 0, got {v!r}")
    return float(v)


@lru_cache(maxsize=1)
def _load() -> tuple[dict, tuple, str, dict]:
    raw = json.loads(CORES_PATH.read_text())
    cores = {}
    for key in raw["order"]:
        e = raw["cores"][key]
        chip, power = e["chip"], e["power"]
        if "current_ua_per_mhz" in power:
            per_mhz = _num(power, "current_ua_per_mhz", key) * 1e-3
        else:
            per_mhz = _num(power, "current_ma", key) / _num(power, "at_clock_mhz", key)
        sources = {"chip": chip["source"], "power": power["source"],
                   "power_condition": power["condition"], "ram_reserve": e["ram_reserve_source"],
                   "coremark": e["coremark_per_mhz"]["source"]}
        if "board_power_source" in e:
            sources["board_power"] = e["board_power_source"]
        for what in ("source",):
            for table in (e["cycles"], e["timing"]):
                p = DATA_DIR / table
                if p.exists():
                    sources[table] = json.loads(p.read_text()).get(what, "")
        cores[key] = Core(
            key=key, name=e["name"], architecture=e["architecture"], fpu=e["fpu"],
            unicorn_cpu=e["unicorn_cpu"], chip=chip["name"], clock_mhz=_num(chip, "clock_mhz", key),
            ram_bytes=int(_num(chip, "ram_kb", key) * 1024),
            reserve_bytes=int(e["ram_reserve_kb"] * 1024), voltage_v=_num(power, "voltage_v", key),
            current_ma_per_mhz=per_mhz, board_power_w=e.get("board_power_w"),
            coremark_per_mhz=float(e["coremark_per_mhz"]["value"]),
            cycles_path=DATA_DIR / e["cycles"], timing_path=DATA_DIR / e["timing"],
            gcc=e["gcc"], sources=sources)
    aliases = {}
    for key in raw["order"]:
        for a in (key, *raw["cores"][key].get("aliases", ())):
            aliases[a.lower()] = key
    return cores, tuple(raw["order"]), raw.get("default", "m4"), aliases


def names() -> tuple[str, ...]:
    """Core keys in order of capability (m0plus, m3, m4, m7, m33)."""
    return _load()[1]


DEFAULT = "m4"


def get(name: str | Core | None = None) -> Core:
    """The core called ``name`` (key or alias, case-insensitive; None = the default M4)."""
    if isinstance(name, Core):
        return name
    cores, order, default, aliases = _load()
    key = aliases.get(str(name if name is not None else default).strip().lower())
    if key is None:
        raise InputError(f"unknown core {name!r}; choose one of {', '.join(order)}")
    return cores[key]


def by_cpu(cpu: str) -> Core:
    """The core whose ``-mcpu`` name is ``cpu`` (``cortex-m0plus`` -> the M0+)."""
    for c in all_cores():
        if c.cpu == cpu:
            return c
    raise InputError(f"unknown cpu {cpu!r}; known: {', '.join(c.cpu for c in all_cores())}")


def all_cores() -> list[Core]:
    cores, order, _, _ = _load()
    return [cores[k] for k in order]
