"""Run the cross-compiled bootstrap filter in a Cortex-M4 emulator and count what it executes.

The C filter (``pfbench/mcu/c/pf_ob1.c``: [Embedded] Alg. 1 on Ob1 = [Embedded] eq. 6 with the
object simulated inside, systematic resampling) is built by :mod:`pfbench.mcu.toolchain` as
D(S) (``double``, soft double) or D(O) (``float``, FPv4-SP, -Ofast), loaded into the
``unicorn`` emulator (Cortex-M4 CPU model, Thumb + M-class) and run from ``Reset_Handler``
until execution reaches ``pf_finish``.

Counting works per *basic block* (a per-instruction Python hook would be ~10x slower):
the block hook records (block, call-context) hits; each block is decoded once from
``arm-none-eabi-objdump -d`` into instruction classes and cycles from the timing table
``data/cortex_m4_timing.json``.  A conditional branch ending a block counts as taken when the
next executed block does not start at its fall-through address.  A shadow call stack
(push on BL/BLX, pop on reaching the return address) attributes every block to

* ``function``: the function the code belongs to (self cost, ELF symbol table),
* ``phase``: the function called from ``main`` (sim_step, pf_predict, pf_weights, ...),
* ``entry``: the outermost library routine on the stack (``cos``, ``exp``, ``__aeabi_dmul`` ...)
  i.e. the inclusive cost of each C-library/libgcc call made by our code;
* ``owner``: the outermost function of our C file below the phase (``randn`` includes
  rand_uniform/rand, log/sqrt/cos and their soft-float calls: the cost of the normal draws).

Totals over several small (M, N) are fitted with ``cost = a + b M + c M N`` (least squares)
and extrapolated to Table 2's configurations: ``c`` is the per-particle-step cost, ``b`` the
per-step cost (object simulation, loop overheads, one resampling uniform), ``a`` start-up.
"""
from __future__ import annotations

import json
import re
import struct
from bisect import bisect_right
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import InputError, PfbenchError
from . import toolchain

TIMING_PATH = Path(__file__).resolve().parent / "data" / "cortex_m4_timing.json"

#: Table 2 of [Embedded] (published, ms): (M iterations, N particles) -> (D(S), D(O)).
TABLE2 = {(500, 500): (23247.0, 640.0), (500, 1000): (46374.0, 1376.0),
          (1000, 1000): (92950.0, 3112.0)}

CLASSES = ("int_alu", "mul", "div", "load_store", "branch", "fpu_addmul", "fpu_mac",
           "fpu_divsqrt", "fpu_load_store")
SCENARIOS = ("best", "nominal", "worst")

#: What the instruction-count model cannot see, and how large that is (used in CLI/recipe).
UNSEEN = (
    "The emulator counts executed instructions exactly but times them with a zero-wait-state "
    "table. It cannot see: (1) flash wait states (STM32F407 at 168 MHz: 5 WS) and the ART "
    "accelerator (prefetch, 64x128-bit instruction cache, 8 data lines) that hides most of them "
    "for small hot loops -- libm/libgcc code paths and literal-pool/constant-table loads from "
    "flash that miss the ART cost up to 6 cycles per 128-bit line; typical code on an F4 runs "
    "0-30% slower than zero-wait-state counts; (2) pipeline effects: branch refill P (1-3 "
    "cycles), load/store pipelining, IT folding, SDIV early termination (2-12) -- bracketed by "
    "the best/worst scenarios (typically +-10-15% around nominal); (3) bus contention and "
    "interrupts (SysTick etc.) on the board; (4) differences between our C and the authors' "
    "(unpublished) C, compiler version and flags -- likely the largest single factor.")

_COND = {"eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt",
         "gt", "le", "al"}

_ALU = set("""mov movw movt mvn add addw adc sub subw sbc rsb rsc and orr orn eor bic lsl lsr asr
ror rrx cmp cmn tst teq clz rbit rev rev16 revsh sxtb sxth uxtb uxth sxtab sxtah uxtab uxtah ubfx
sbfx bfi bfc nop adr ssat usat sel uadd8 usub8 sadd8 ssub8 uadd16 usub16 sadd16 ssub16 qadd qsub
qdadd qdsub neg dsb isb dmb cpsid cpsie mrs msr yield wfi wfe sev bkpt udf svc""".split())
_MUL = {"mul": "mul", "mla": "mul_accumulate", "mls": "mul_accumulate", "umull": "mul_long",
        "smull": "mul_long", "umlal": "mul_long", "smlal": "mul_long", "smulbb": "mul",
        "smulbt": "mul", "smultb": "mul", "smultt": "mul", "smlabb": "mul", "smmul": "mul",
        "smmla": "mul_accumulate", "usad8": "mul"}
_DIV = {"sdiv", "udiv"}
_LS_SINGLE = {"ldr", "ldrb", "ldrh", "ldrsb", "ldrsh", "ldrex", "ldrexb", "ldrexh", "str", "strb",
              "strh", "strex", "strexb", "strexh", "ldrt", "strt", "pld"}
_LS_DOUBLE = {"ldrd", "strd"}
_LS_MULTI = {"ldm", "ldmia", "ldmfd", "ldmdb", "stm", "stmia", "stmea", "stmdb", "stmfd", "push",
             "pop"}
_BRANCH = {"b", "bl", "blx", "bx", "cbz", "cbnz", "tbb", "tbh"}
_FPU_SIMPLE = {"vadd", "vsub", "vmul", "vnmul", "vabs", "vneg", "vcmp", "vcmpe", "vcvt", "vcvtr",
               "vcvtb", "vcvtt", "vmov", "vmrs", "vmsr"}
_FPU_MAC = {"vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma", "vfnms"}
_FPU_DIVSQRT = {"vdiv", "vsqrt"}
_FPU_LS = {"vldr", "vstr"}
_FPU_LS_MULTI = {"vldm", "vldmia", "vldmdb", "vstm", "vstmia", "vstmdb", "vpush", "vpop"}
_KNOWN = (_ALU | set(_MUL) | _DIV | _LS_SINGLE | _LS_DOUBLE | _LS_MULTI | _BRANCH | _FPU_SIMPLE
          | _FPU_MAC | _FPU_DIVSQRT | _FPU_LS | _FPU_LS_MULTI)
_IT = re.compile(r"^it[te]{0,3}$")


def split_mnemonic(mn: str) -> tuple[str, bool]:
    """``'addseq.w' -> ('add', True)``: base mnemonic and whether it carries a condition."""
    head = mn.split(".")[0].lower()
    if _IT.match(head):
        return "it", False
    if head in _KNOWN:
        return head, False
    if head[-2:] in _COND and head[:-2] in _KNOWN:
        return head[:-2], True
    if head.endswith("s") and head[:-1] in _KNOWN:
        return head[:-1], False
    if head[-2:] in _COND and head[-3:-2] == "s" and head[:-3] in _KNOWN:
        return head[:-3], True
    return head, False


def _reglist_words(ops: str) -> tuple[int, bool]:
    """Words moved by a register list ``{r4-r7, lr}`` / ``{d8-d9}``; and whether PC is in it."""
    m = re.search(r"\{([^}]*)\}", ops)
    if not m:
        return 1, False
    words, has_pc = 0, False
    for part in m.group(1).split(","):
        part = part.strip()
        if not part:
            continue
        width = 2 if part.startswith("d") else 1
        if "-" in part:
            lo, hi = part.split("-")
            words += width * (int(re.sub(r"\D", "", hi)) - int(re.sub(r"\D", "", lo)) + 1)
        else:
            words += width
            has_pc |= part == "pc"
    return words, has_pc


@dataclass
class Insn:
    addr: int
    size: int
    mnemonic: str
    ops: str


def classify(ins: Insn, t: dict) -> tuple[str, dict, str | None, bool]:
    """Class, cycles per scenario (without branch refill), branch kind, single load/store.

    Branch kind: None, ``'jump'`` (always taken), ``'cjump'`` (conditional), ``'call'``,
    ``'ccall'`` (conditional call)."""
    c, sc = t["cycles"], t["scenarios"]
    base, cond = split_mnemonic(ins.mnemonic)
    ops = ins.ops.split("@")[0].split(";")[0]
    kind, single = None, False

    def same(v):
        return {s: v for s in SCENARIOS}

    if base == "it":
        return "int_alu", {s: (0 if sc[s]["it_folded"] else c["it"]) for s in SCENARIOS}, None, False
    if base in _BRANCH:
        if base in ("bl", "blx"):
            kind = "ccall" if cond else "call"
        elif base in ("cbz", "cbnz") or cond:
            kind = "cjump"
        else:
            kind = "jump"
        cyc = c["table_branch_base"] if base in ("tbb", "tbh") else c["branch_base"]
        return "branch", same(cyc), kind, False
    if base in _LS_MULTI:
        words, has_pc = _reglist_words(ops)
        if base in ("push", "pop") or "{" in ops:
            cyc = c["load_store_multiple_base"] + words
        else:
            cyc = 2
        if has_pc:
            return "branch", same(cyc), ("cjump" if cond else "jump"), False
        return "load_store", same(cyc), None, False
    if base in _LS_SINGLE:
        dest = ops.split(",")[0].strip()
        if base == "ldr" and dest == "pc":
            return "branch", same(c["load"]), ("cjump" if cond else "jump"), False
        return "load_store", same(c["load"] if base.startswith("ld") else c["store"]), None, True
    if base in _LS_DOUBLE:
        return "load_store", same(c["load_store_double"]), None, False
    if base in _MUL:
        return "mul", same(c[_MUL[base]]), None, False
    if base in _DIV:
        return "div", {s: sc[s]["div"] for s in SCENARIOS}, None, False
    if base in _FPU_LS_MULTI:
        words, _ = _reglist_words(ops)
        return "fpu_load_store", same(c["fpu_load_store_multiple_base"] + words), None, False
    if base in _FPU_LS:
        return "fpu_load_store", same(c["fpu_load_store"]), None, False
    if base in _FPU_DIVSQRT:
        return "fpu_divsqrt", same(c["fpu_divsqrt"]), None, False
    if base in _FPU_MAC:
        return "fpu_mac", same(c["fpu_mac"]), None, False
    if base in _FPU_SIMPLE:
        regs = [r.strip() for r in ops.split(",")]
        core = sum(1 for r in regs if re.fullmatch(r"r\d+|ip|lr|sp|fp|sl", r))
        if base == "vmov" and core == 2:
            return "fpu_addmul", same(c["fpu_vmov_two_core"]), None, False
        return "fpu_addmul", same(c["fpu_simple"]), None, False
    if base == "mov" and ops.split(",")[0].strip() == "pc":
        return "branch", same(c["branch_base"]), "jump", False
    return "int_alu", same(c["int_alu"]), None, False


@lru_cache(maxsize=1)
def timing_table() -> dict:
    return json.loads(TIMING_PATH.read_text())


_DIS = re.compile(r"^\s*([0-9a-f]+):\t([0-9a-f ]+?)\s*\t(\S+)\s*(.*)$")


class Program:
    """A built image: decoded instructions, symbol table, user functions."""

    def __init__(self, build: toolchain.Build):
        self.build = build
        self.insns: dict[int, Insn] = {}
        for line in build.disasm.read_text().splitlines():
            m = _DIS.match(line)
            if m and not m.group(3).startswith("."):
                addr = int(m.group(1), 16)
                size = len(m.group(2).replace(" ", "")) // 2
                self.insns[addr] = Insn(addr, size, m.group(3), m.group(4))
        self.symbols: dict[str, int] = {}
        funcs: dict[int, str] = {}
        for line in build.symbols.read_text().splitlines():
            parts = line.split()
            if len(parts) < 3:
                continue
            addr, typ, name = int(parts[0], 16), parts[-2], parts[-1]
            self.symbols[name] = addr
            if typ in "TtWw" and not name.startswith("$"):
                a = addr & ~1
                old = funcs.get(a)
                # prefer the ABI name (__aeabi_dmul over __muldf3), then the shorter/public one
                if old is None or _alias_rank(name) < _alias_rank(old):
                    funcs[a] = name
        self.func_starts = sorted(funcs)
        self.func_names = [funcs[a] for a in self.func_starts]
        self.user_functions = set()
        for line in build.user_symbols.read_text().splitlines():
            parts = line.split()
            if len(parts) >= 3 and parts[1] in "Tt":
                self.user_functions.add(parts[2])
        self.user_functions.add("Reset_Handler")
        self.timing = timing_table()
        self._blocks: dict[tuple[int, int], tuple] = {}

    def function_at(self, addr: int) -> str:
        i = bisect_right(self.func_starts, addr) - 1
        return self.func_names[i] if i >= 0 else "?"

    def block(self, addr: int, size: int) -> tuple:
        """Decode a basic block once: (n, class counts, cycles per scenario, kind, function)."""
        key = (addr, size)
        info = self._blocks.get(key)
        if info is not None:
            return info
        counts = np.zeros(len(CLASSES))
        cyc = np.zeros(len(SCENARIOS))
        pipelining = np.array([self.timing["scenarios"][s]["load_store_pipelining"]
                               for s in SCENARIOS])
        a, end, n, kind, prev_single = addr, addr + size, 0, None, False
        while a < end:
            ins = self.insns.get(a)
            if ins is None:
                raise PfbenchError(f"emulated code at 0x{a:08x} is not in the disassembly")
            klass, cy, kind, single = classify(ins, self.timing)
            counts[CLASSES.index(klass)] += 1
            cyv = np.array([cy[s] for s in SCENARIOS], dtype=float)
            if single and prev_single:
                cyv = np.where(pipelining, cyv - 1, cyv)
            cyc += cyv
            prev_single = single
            n += 1
            a += ins.size
        info = (n, counts, cyc, kind, self.function_at(addr))
        self._blocks[key] = info
        return info


def _alias_rank(name: str) -> tuple:
    return (0 if name.startswith("__aeabi_") else 1, name.startswith("_"), len(name))


@dataclass
class RunResult:
    """Counts of one emulated run of (steps, particles)."""

    precision: str
    steps: int
    particles: int
    instructions: int
    classes: dict
    cycles: dict                    # scenario -> cycles
    by_function: dict               # self function -> {"instructions", "cycles"} (nominal)
    by_phase: dict                  # phase -> cycles (nominal)
    by_entry: dict                  # library entry (inclusive) -> cycles (nominal)
    by_owner: dict                  # our C function (inclusive of its library calls) -> cycles
    result: list = field(default_factory=list)  # pf_result: sse, last est, last x, M


def run(precision: str, steps: int, particles: int, seed: int = 1,
        program: Program | None = None, timeout_s: float = 300.0) -> RunResult:
    """Emulate one run of the C filter with ``steps`` = M and ``particles`` = N."""
    from unicorn import UC_ARCH_ARM, UC_HOOK_BLOCK, UC_MODE_MCLASS, UC_MODE_THUMB, Uc, UcError
    from unicorn import arm_const as A

    if steps < 1 or particles < 1 or particles > 1000:
        raise InputError("emulated steps must be >= 1 and particles in 1..1000 (PF_NMAX)")
    prog = program or Program(toolchain.build(precision))
    sym = prog.symbols
    image = bytearray(prog.build.bin.read_bytes())
    flash, ram = 0x08000000, 0x20000000
    cfg = sym["pf_config"]
    off = sym["_sidata"] - flash + (cfg - sym["_sdata"])
    image[off:off + 12] = struct.pack("<iiI", steps, particles, seed)

    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.ctl_set_cpu_model(A.UC_CPU_ARM_CORTEX_M4)
    uc.mem_map(flash, 1 << 20)
    uc.mem_map(ram, 128 << 10)
    uc.mem_map(0xE000E000, 0x1000)  # System Control Space (CPACR write in Reset_Handler)
    uc.mem_write(flash, bytes(image))
    uc.reg_write(A.UC_ARM_REG_SP, sym["_estack"])

    hits: dict = {}
    taken: dict = {}
    stack: list = []            # (return address, function name)
    rets: dict = {}             # return address -> frames on the stack waiting for it
    contexts: dict = {}
    ctx_names: list = []
    user = prog.user_functions
    state = {"prev": None, "end": 0, "kind": None, "ctx": 0}

    def context_id():
        phase = stack[1][1] if len(stack) > 1 else (stack[0][1] if stack else "startup")
        entry = next((f for _, f in stack if f not in user), "")
        owner = next((f for _, f in stack[2:] if f in user), phase)
        key = (phase, entry, owner)
        cid = contexts.get(key)
        if cid is None:
            cid = contexts[key] = len(ctx_names)
            ctx_names.append(key)
        return cid

    state["ctx"] = context_id()
    blocks = prog._blocks

    def hook(_uc, addr, size, _data):
        kind = state["kind"]
        if kind is not None:
            if kind == "call" or (kind == "ccall" and addr != state["end"]):
                info = blocks.get((addr, size)) or prog.block(addr, size)
                stack.append((state["end"], info[4]))
                rets[state["end"]] = rets.get(state["end"], 0) + 1
                state["ctx"] = context_id()
            if kind[0] == "c" and addr != state["end"]:  # taken conditional jump/call
                taken[state["prev"]] = taken.get(state["prev"], 0) + 1
        if addr in rets:
            # returning; libgcc special-case handlers reached by BL return straight to the
            # outer caller (pop {.., pc}), so unwind every frame above the matching one
            while stack:
                ret, _ = stack.pop()
                rets[ret] -= 1
                if not rets[ret]:
                    del rets[ret]
                if ret == addr:
                    break
            state["ctx"] = context_id()
        key = (addr, size, state["ctx"])
        hits[key] = hits.get(key, 0) + 1
        info = blocks.get((addr, size)) or prog.block(addr, size)
        state["prev"], state["end"], state["kind"] = key, addr + size, info[3]

    uc.hook_add(UC_HOOK_BLOCK, hook)
    try:
        uc.emu_start(sym["Reset_Handler"] | 1, sym["pf_finish"] & ~1,
                     timeout=int(timeout_s * 1e6))
    except UcError as exc:
        pc = uc.reg_read(A.UC_ARM_REG_PC)
        raise PfbenchError(f"emulation failed at 0x{pc:08x} ({prog.function_at(pc)}): {exc}")
    pc = uc.reg_read(A.UC_ARM_REG_PC)
    if pc != sym["pf_finish"] & ~1:
        raise PfbenchError(f"emulation stopped at 0x{pc:08x} before pf_finish (timeout?)")

    P = np.array([prog.timing["scenarios"][s]["branch_refill_P"] for s in SCENARIOS], float)
    n_ins, classes, cycles = 0, np.zeros(len(CLASSES)), np.zeros(len(SCENARIOS))
    by_function: dict = {}
    by_phase: dict = {}
    by_entry: dict = {}
    by_owner: dict = {}
    for key, h in hits.items():
        n, cnt, cyc, kind, func = prog.block(key[0], key[1])
        n_taken = h if kind in ("jump", "call") else taken.get(key, 0)
        c = h * cyc + n_taken * P
        n_ins += h * n
        classes += h * cnt
        cycles += c
        d = by_function.setdefault(func, [0, 0.0])
        d[0] += h * n
        d[1] += c[1]
        phase, entry, owner = ctx_names[key[2]]
        o = owner or func
        by_owner[o] = by_owner.get(o, 0.0) + c[1]
        by_phase[phase] = by_phase.get(phase, 0.0) + c[1]
        e = entry or func  # outermost library routine on the stack, else the code itself
        by_entry[e] = by_entry.get(e, 0.0) + c[1]
    rbytes = uc.mem_read(sym["pf_result"], 32 if precision == "double" else 16)
    res = list(struct.unpack("<4d" if precision == "double" else "<4f", bytes(rbytes)))
    return RunResult(
        precision=precision, steps=steps, particles=particles, instructions=int(n_ins),
        classes={k: int(v) for k, v in zip(CLASSES, classes)},
        cycles={s: float(v) for s, v in zip(SCENARIOS, cycles)},
        by_function={k: {"instructions": int(v[0]), "cycles": float(v[1])}
                     for k, v in by_function.items()},
        by_phase=by_phase, by_entry=by_entry, by_owner=by_owner, result=res)


#: Small configurations (M, N) emulated for the fit; enough spread to separate a, b and c.
DEFAULT_CONFIGS = {"float": ((10, 50), (20, 50), (10, 100), (20, 100)),
                   "double": ((4, 25), (8, 25), (4, 50), (8, 50))}


def fit(runs: list[RunResult]) -> dict:
    """Least-squares ``cost = a + b M + c M N`` for every counted quantity.

    Returns per-quantity dicts ``{"fixed": a, "per_step": b, "per_particle_step": c}`` plus
    ``residual_rel``: the largest relative residual of the nominal-cycle fit."""
    X = np.array([[1.0, r.steps, r.steps * r.particles] for r in runs])
    if np.linalg.matrix_rank(X) < 3:
        raise InputError("need at least three (M, N) configurations with different M and N")

    def lsq(y):
        coef, *_ = np.linalg.lstsq(X, np.asarray(y, float), rcond=None)
        return {"fixed": float(coef[0]), "per_step": float(coef[1]),
                "per_particle_step": float(coef[2])}

    out = {"instructions": lsq([r.instructions for r in runs]),
           "cycles": {s: lsq([r.cycles[s] for r in runs]) for s in SCENARIOS},
           "classes": {k: lsq([r.classes[k] for r in runs]) for k in CLASSES}}
    for attr in ("by_phase", "by_entry", "by_owner"):
        names = sorted({k for r in runs for k in getattr(r, attr)})
        out[attr] = {k: lsq([getattr(r, attr).get(k, 0.0) for r in runs]) for k in names}
    names = sorted({k for r in runs for k in r.by_function})
    out["by_function"] = {k: lsq([r.by_function.get(k, {}).get("cycles", 0.0) for r in runs])
                          for k in names}
    y = np.array([r.cycles["nominal"] for r in runs])
    c = out["cycles"]["nominal"]
    pred = X @ np.array([c["fixed"], c["per_step"], c["per_particle_step"]])
    out["residual_rel"] = float(np.max(np.abs(pred - y) / y))
    return out


def predict_cycles(coef: dict, steps: int, particles: int) -> float:
    return coef["fixed"] + coef["per_step"] * steps + coef["per_particle_step"] * steps * particles


def analytic(precision: str, steps: int, particles: int, clock_mhz: float) -> dict | None:
    """The analytic cost model (``pfbench.mcu.costmodel.predict``) if it is importable."""
    try:
        from .costmodel import predict  # noqa: PLC0415 - optional sibling module
    except ImportError:
        return None
    try:
        out = predict(model="ob1", n_steps=steps, n_particles=particles, precision=precision,
                      method="bootstrap", n_filters=1, clock_mhz=clock_mhz)
    except Exception as exc:  # noqa: BLE001 - another helper's module: report, don't crash
        return {"error": f"{type(exc).__name__}: {exc}"}
    return out if isinstance(out, dict) else {"predicted_ms": float(out)}


def emulate(precision: str = "float", steps: int = 1000, particles: int = 1000,
            configs=None, clock_mhz: float | None = None, seed: int = 1,
            opt: str | None = None) -> dict:
    """Emulate small configurations, fit, and predict (M=steps, N=particles) and Table 2.

    Returns a JSON-ready dict: ``predicted_ms`` (nominal) with ``predicted_ms_range`` (best,
    worst), ``instructions``/``cycles`` per particle-step and per step, class counts and the
    breakdowns per particle-step, the analytic model and Table 2 beside it."""
    if precision not in toolchain.BUILDS:
        raise InputError(f"precision must be 'float' or 'double', got {precision!r}")
    if steps < 1 or particles < 1:
        raise InputError("--steps and --particles must be positive")
    clock = float(clock_mhz or timing_table()["clock_mhz"])
    prog = Program(toolchain.build(precision, opt=opt))
    configs = tuple(configs or DEFAULT_CONFIGS[precision])
    runs = [run(precision, m, n, seed=seed, program=prog) for m, n in configs]
    f = fit(runs)
    per_ms = clock * 1e3

    def ms(m, n):
        return {s: predict_cycles(f["cycles"][s], m, n) / per_ms for s in SCENARIOS}

    pps = f["cycles"]["nominal"]["per_particle_step"]

    def top(d, k=12):
        items = sorted(((name, c["per_particle_step"]) for name, c in d.items()),
                       key=lambda t: -t[1])
        return {name: round(v, 2) for name, v in items[:k] if v > 0.5}

    col = 0 if precision == "double" else 1
    table2 = []
    for (m, n), paper in TABLE2.items():
        p = ms(m, n)
        an = analytic(precision, m, n, clock)
        table2.append({"steps": m, "particles": n, "paper_ms": paper[col],
                       "emulated_ms": p["nominal"], "emulated_ms_best": p["best"],
                       "emulated_ms_worst": p["worst"],
                       "analytic_ms": (an or {}).get("predicted_ms")})
    req = ms(steps, particles)
    an = analytic(precision, steps, particles, clock)
    return {
        "precision": precision,
        "build": toolchain.BUILDS[precision][0],
        "cflags": list(prog.build.cflags),
        "compiler": toolchain.compiler_version(),
        "clock_mhz": clock,
        "steps": steps,
        "particles": particles,
        "predicted_ms": req["nominal"],
        "predicted_ms_range": [req["best"], req["worst"]],
        "instructions_per_particle_step": f["instructions"]["per_particle_step"],
        "cycles_per_particle_step": pps,
        "cycles_per_particle_step_range": [f["cycles"]["best"]["per_particle_step"],
                                           f["cycles"]["worst"]["per_particle_step"]],
        "instructions_per_step": f["instructions"]["per_step"],
        "cycles_per_step": f["cycles"]["nominal"]["per_step"],
        "cycles_fixed": f["cycles"]["nominal"]["fixed"],
        "cpi": pps / f["instructions"]["per_particle_step"],
        "classes_per_particle_step": {k: round(v["per_particle_step"], 2)
                                      for k, v in f["classes"].items()},
        "breakdown": {
            "by_function_self": top(f["by_function"]),
            "by_library_call_inclusive": top(f["by_entry"]),
            "by_c_function_inclusive": top(f["by_owner"]),
            "by_phase": top(f["by_phase"]),
        },
        "fit_residual_rel": f["residual_rel"],
        "emulated_configs": [{"steps": r.steps, "particles": r.particles,
                              "instructions": r.instructions,
                              "cycles": r.cycles["nominal"],
                              "sse": r.result[0]} for r in runs],
        "analytic": an if an is not None else "pfbench.mcu.costmodel not available",
        "analytic_ms": (an or {}).get("predicted_ms"),
        "table2": table2,
        "unseen": UNSEEN,
    }
