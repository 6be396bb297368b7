"""Run a cross-compiled bootstrap filter in a Cortex-M4 emulator and count what it executes.

Two kinds of image, each "a Program + a way to write its inputs" (:func:`execute`):

* the hand-written Ob1 port ``pf_ob1.c`` (:func:`run`, :func:`emulate`; described below);
* the generic harness ``pf_model.c`` linked with ANY model's own compiled code
  (:func:`run_model`, :func:`emulate_model`): the host simulates the model and writes the
  initial particles, y, u and the true x into the image; the same counting, fit and breakdowns,
  plus the share of double-precision work (:func:`is_double`), RAM (painted stack/heap) and the
  cost model's prediction for the same run.

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

import re
import struct
from bisect import bisect_right
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ..errors import InputError, PfbenchError, UnsupportedError
from . import cores as _cores
from . import toolchain

FLASH, RAM = 0x08000000, 0x20000000
PAINT = 0xA5  # free RAM is painted with this byte before a run (stack/heap high-water mark)

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
    kind = None

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
        if ".f64" in ins.mnemonic and "fpu_divsqrt_f64" in c:   # M7: double on the FPU
            return "fpu_divsqrt", same(c["fpu_divsqrt_f64"]), None, False
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


@lru_cache(maxsize=8)
def timing_table(core: str = "m4") -> dict:
    """The instruction timing table of ``core`` (``data/cortex_<core>_timing.json``)."""
    return _cores.get(core).timing()


_DIS = re.compile(r"^\s*([0-9a-f]+):\t([0-9a-f ]+?)\s*\t(\S+)\s*(.*)$")


class Program:
    """A built image: decoded instructions, symbol table, user functions."""

    def __init__(self, build: toolchain.Build, core: str = "m4"):
        self.build = build
        self.core = core
        self.cpu = next((f.split("=", 1)[1] for f in build.cflags if f.startswith("-mcpu=")),
                        "cortex-m4")
        self.sizes: dict[str, int] = {}
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
            if len(parts) == 4:
                self.sizes[name] = int(parts[1], 16)
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
        self.timing = timing_table(core)
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
    by_owner_entry: dict = field(default_factory=dict)  # "owner > library entry" -> cycles
    ram: dict = field(default_factory=dict)     # see ram_usage()


def machine(image: bytes, cpu: str, stack_top: int):
    """A unicorn Cortex-M (the CPU model of ``cpu``, :mod:`pfbench.mcu.cores`) with the memory
    map of ``c/stm32f407.ld`` (1 MiB flash at FLASH, 128 KiB RAM at RAM) and the System Control
    Space (the CPACR write of Reset_Handler), ``image`` in flash and SP at ``stack_top``."""
    from unicorn import UC_ARCH_ARM, UC_MODE_MCLASS, UC_MODE_THUMB, Uc
    from unicorn import arm_const as A

    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.ctl_set_cpu_model(getattr(A, _cores.by_cpu(cpu).unicorn_cpu))
    uc.mem_map(FLASH, 1 << 20)
    uc.mem_map(RAM, 128 << 10)
    uc.mem_map(0xE000E000, 0x1000)
    uc.mem_write(FLASH, bytes(image))
    uc.reg_write(A.UC_ARM_REG_SP, stack_top)
    return uc


def image_with_inputs(prog: Program, inputs: dict) -> bytearray:
    """The flash image with ``inputs`` ({symbol: bytes}) written into the initialised-data
    image of those symbols (Reset_Handler copies it to RAM, as for any initialised global)."""
    sym = prog.symbols
    image = bytearray(prog.build.bin.read_bytes())
    for name, data in inputs.items():
        if name not in sym:
            raise PfbenchError(f"the image has no input symbol {name!r}")
        addr, size = sym[name], prog.sizes.get(name)
        if not sym["_sdata"] <= addr < sym["_edata"]:
            raise PfbenchError(f"input symbol {name!r} is not initialised data")
        if size is not None and len(data) > size:
            raise InputError(f"input {name!r} needs {len(data)} bytes, the image holds {size}")
        off = sym["_sidata"] - FLASH + (addr - sym["_sdata"])
        image[off:off + len(data)] = data
    return image


def execute(prog: Program, inputs: dict, precision: str, steps: int, particles: int,
            timeout_s: float = 300.0, stop: str = "pf_finish"):
    """Emulate ``prog`` from ``Reset_Handler`` to ``stop`` with ``inputs`` written first.

    An image is "a Program + a way to write its inputs": the caller packs its inputs
    ({symbol: bytes}) and reads its results from the returned ``uc`` (unicorn instance).
    Returns ``(RunResult, uc)``; the RunResult's ``ram`` holds the static RAM (.data, .bss)
    and the stack and heap actually used (the free RAM is painted before the run)."""
    from unicorn import UC_HOOK_BLOCK, UcError
    from unicorn import arm_const as A

    sym = prog.symbols
    ram_size = sym["_estack"] - RAM
    uc = machine(image_with_inputs(prog, inputs), prog.cpu, sym["_estack"])
    free_lo = sym.get("_end", sym["_ebss"])
    uc.mem_write(free_lo, bytes([PAINT]) * (sym["_estack"] - free_lo))

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
        uc.emu_start(sym["Reset_Handler"] | 1, sym[stop] & ~1, timeout=int(timeout_s * 1e6))
    except UcError as exc:
        pc = uc.reg_read(A.UC_ARM_REG_PC)
        ins = prog.insns.get(pc)
        what = f": {ins.mnemonic} {ins.ops}".rstrip() if ins else ""
        raise PfbenchError(f"emulation failed at 0x{pc:08x} ({prog.function_at(pc)}{what}) on "
                           f"unicorn's {prog.cpu}: {exc}")
    pc = uc.reg_read(A.UC_ARM_REG_PC)
    if pc != sym[stop] & ~1:
        raise PfbenchError(f"emulation stopped at 0x{pc:08x} before {stop} (timeout?)")

    P = np.array([prog.timing["scenarios"][s]["branch_refill_P"] for s in SCENARIOS], float)
    n_ins, classes, cycles = 0, np.zeros(len(CLASSES)), np.zeros(len(SCENARIOS))
    by_function: dict = {}
    by_phase: dict = {}
    by_entry: dict = {}
    by_owner: dict = {}
    by_owner_entry: dict = {}
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
        oe = f"{o} > {e}"
        by_owner_entry[oe] = by_owner_entry.get(oe, 0.0) + c[1]
    free = np.frombuffer(bytes(uc.mem_read(free_lo, sym["_estack"] - free_lo)), np.uint8)
    return RunResult(
        precision=precision, steps=steps, particles=particles, instructions=int(n_ins),
        classes={k: int(v) for k, v in zip(CLASSES, classes)},
        cycles={s: float(v) for s, v in zip(SCENARIOS, cycles)},
        by_function={k: {"instructions": int(v[0]), "cycles": float(v[1])}
                     for k, v in by_function.items()},
        by_phase=by_phase, by_entry=by_entry, by_owner=by_owner,
        by_owner_entry=by_owner_entry, ram=ram_usage(sym, free, ram_size)), uc


def ram_usage(sym: dict, free: np.ndarray, ram_size: int) -> dict:
    """Static and dynamic RAM of a run: .data, .bss, and from the painted free RAM ``free``
    (bytes from ``_end`` to the top of the stack) the stack (the used block touching the top)
    and the heap (the used block at the bottom, e.g. malloc for numba's arrays)."""
    used = np.flatnonzero(free != PAINT)
    stack = heap = 0
    if used.size:
        gaps = np.diff(used)
        cut = int(np.argmax(gaps)) if gaps.size else -1
        if gaps.size and gaps[cut] > 64:     # two blocks: heap below, stack above
            heap, stack = int(used[cut]) + 1, len(free) - int(used[cut + 1])
        elif used[0] < len(free) // 2 and used[-1] < len(free) - 64:
            heap = int(used[-1]) + 1         # heap only (stack never reached this far)
        else:
            stack = len(free) - int(used[0])
    data = sym["_edata"] - sym["_sdata"]
    bss = sym["_ebss"] - sym["_sbss"]
    return {"data_bytes": int(data), "bss_bytes": int(bss), "stack_bytes": int(stack),
            "heap_bytes": int(heap), "total_bytes": int(data + bss + stack + heap),
            "ram_bytes": int(ram_size), "fits": bool(data + bss + stack + heap <= ram_size)}


def run(precision: str, steps: int, particles: int, seed: int = 1,
        program: Program | None = None, timeout_s: float = 300.0) -> RunResult:
    """Emulate one run of the hand-written Ob1 port pf_ob1.c (M = ``steps``, N = ``particles``)."""
    if steps < 1 or particles < 1 or particles > 1000:
        raise InputError("emulated steps must be >= 1 and particles in 1..1000 (PF_NMAX)")
    prog = program or Program(toolchain.build(precision))
    res, uc = execute(prog, {"pf_config": struct.pack("<iiI", steps, particles, seed)},
                      precision, steps, particles, timeout_s)
    rbytes = uc.mem_read(prog.symbols["pf_result"], 32 if precision == "double" else 16)
    res.result = list(struct.unpack("<4d" if precision == "double" else "<4f", bytes(rbytes)))
    return res


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
    for attr in ("by_phase", "by_entry", "by_owner", "by_owner_entry"):
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


def analytic(precision: str, steps: int, particles: int, clock_mhz: float) -> dict:
    """The analytic cost model's prediction of the same Ob1 run (:func:`pfbench.mcu.costmodel.predict`),
    or ``{"error": why}`` where it refuses one (e.g. a filter the chip's RAM cannot hold)."""
    from .costmodel import predict  # noqa: PLC0415

    try:
        return predict(model="ob1", n_steps=steps, n_particles=particles, precision=precision,
                       method="bootstrap", n_filters=1, clock_mhz=clock_mhz)
    except PfbenchError as exc:
        return {"error": str(exc)}


def _top(d: dict, k: int = 12) -> dict:
    items = sorted(((name, c["per_particle_step"]) for name, c in d.items()), key=lambda t: -t[1])
    return {name: round(v, 2) for name, v in items[:k] if v > 0.5}


def summarise(runs: list[RunResult], prog: Program, clock: float, steps: int,
              particles: int) -> tuple[dict, dict]:
    """Fit ``runs`` and summarise per particle-step/step: ``(summary dict, fit)``; the summary
    holds the extrapolated time at (``steps``, ``particles``), counts, CPI, breakdowns, RAM."""
    f = fit(runs)
    per_ms = clock * 1e3
    req = {s: predict_cycles(f["cycles"][s], steps, particles) / per_ms for s in SCENARIOS}
    pps = f["cycles"]["nominal"]["per_particle_step"]
    return {
        "cflags": list(prog.build.cflags),
        "compiler": toolchain.compiler_version(),
        "core": prog.core,
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
            "by_function_self": _top(f["by_function"]),
            "by_library_call_inclusive": _top(f["by_entry"]),
            "by_c_function_inclusive": _top(f["by_owner"]),
            "by_phase": _top(f["by_phase"]),
            "by_c_function_and_library_call": _top(f["by_owner_entry"], 24),
        },
        "fit_residual_rel": f["residual_rel"],
        "ram": max((r.ram for r in runs), key=lambda d: d.get("total_bytes", 0), default={}),
        "unseen": UNSEEN,
    }, f


def emulate(precision: str = "float", steps: int = 1000, particles: int = 1000,
            configs=None, clock_mhz: float | None = None, seed: int = 1,
            opt: str | None = None) -> dict:
    """Emulate small configurations of the hand-written Ob1 port (pf_ob1.c), fit, and predict
    (M=steps, N=particles) and Table 2.

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
    out, f = summarise(runs, prog, clock, steps, particles)
    col = 0 if precision == "double" else 1
    table2 = []
    for (m, n), paper in TABLE2.items():
        p = {s: predict_cycles(f["cycles"][s], m, n) / (clock * 1e3) for s in SCENARIOS}
        an = analytic(precision, m, n, clock)
        table2.append({"steps": m, "particles": n, "paper_ms": paper[col],
                       "emulated_ms": p["nominal"], "emulated_ms_best": p["best"],
                       "emulated_ms_worst": p["worst"],
                       "analytic_ms": an.get("predicted_ms")})
    an = analytic(precision, steps, particles, clock)
    return {
        "precision": precision,
        "build": toolchain.BUILDS[precision][0],
        **out,
        "emulated_configs": [{"steps": r.steps, "particles": r.particles,
                              "instructions": r.instructions,
                              "cycles": r.cycles["nominal"],
                              "sse": r.result[0]} for r in runs],
        "analytic": an,
        "analytic_ms": an.get("predicted_ms"),
        "table2": table2,
    }


# ------------------------------------------------------------------ any model: pf_model.c
#: Small (M, N) per precision for models.  N is a multiple of the tile (PF_TILE = 32): the
#: per-tile work (the model call, numba's array allocations) then grows with N as it does at
#: large N and lands in the per-particle-step coefficient c, not in the per-step b.
MODEL_CONFIGS = {"float": ((8, 32), (16, 32), (8, 64), (16, 64)),
                 "double": ((4, 32), (8, 32), (4, 64), (8, 64))}

_SOFT_DOUBLE = re.compile(r"^(__aeabi_(d|[ilf]2d|u[il]2d|cdcmp|cdrcmp)|__(add|sub|mul|div|neg)df3"
                          r"|__extendsfdf2|__truncdfsf2|__fix(uns)?df|__float(un)?(si|di)df"
                          r"|__(eq|ne|lt|le|gt|ge|un|cmp)df2)")
#: C library functions on double (their float twins end in ``f``: cosf, expf, ...).
DOUBLE_LIBM = frozenset("""sin cos tan asin acos atan atan2 sinh cosh tanh asinh acosh atanh exp
exp2 expm1 log log2 log10 log1p pow sqrt cbrt hypot fmod remainder erf erfc lgamma tgamma floor
ceil round trunc fabs copysign ldexp frexp modf""".split())


def is_double(name: str) -> bool:
    """Whether a library routine is double-precision work: libgcc soft-float double
    (``__aeabi_dmul``, ``__muldf3``, ``__aeabi_f2d`` ...) or a double libm call (``cos`` vs
    ``cosf``, and their ``__ieee754_*``/``__kernel_*`` internals)."""
    if _SOFT_DOUBLE.match(name) or name in DOUBLE_LIBM:
        return True
    m = re.match(r"^__(ieee754|kernel|math)_(\w+)$", name)
    return bool(m) and not m.group(2).endswith("f")


def double_share(by_entry: dict) -> float:
    """Share of cycles spent in double-precision library work (``by_entry``: inclusive cycles
    per outermost library routine, or per own function when none)."""
    tot = sum(by_entry.values())
    return float(sum(v for k, v in by_entry.items() if is_double(k)) / tot) if tot else 0.0


def model_object(spec: str, precision: str, params: dict | None = None, cpu: str = "cortex-m4"):
    """The model's own code compiled for ``cpu`` (:func:`pfbench.mcu.modelcode.compile_model`)."""
    try:
        from .modelcode import compile_model  # noqa: PLC0415 - sibling module, optional
    except ImportError as exc:
        raise UnsupportedError(f"compiling a model for the MCU needs pfbench.mcu.modelcode "
                               f"({exc})") from None
    return compile_model(spec, precision=precision, cpu=cpu, params=params)


def run_model(prog: Program, model, traj, x0: np.ndarray, steps: int, particles: int,
              seed: int = 1, timeout_s: float = 300.0) -> RunResult:
    """Emulate the harness ``prog`` (:func:`toolchain.build_model`) on the first ``steps``
    steps of the host trajectory ``traj`` with initial particles ``x0`` (>= particles, n_x).

    ``result`` = [SSE per state (n_x), last estimate (n_x), steps, degenerate steps]."""
    b = prog.build
    if not 1 <= steps <= b.mmax or not 1 <= particles <= b.nmax:
        raise InputError(f"emulated steps must be in 1..{b.mmax} and particles in 1..{b.nmax} "
                         "(PF_MMAX, PF_NMAX of the build)")
    dt = "<f4" if b.precision == "float" else "<f8"
    u = model.input_array(traj.u, traj.n_steps)[:steps]

    def pack(a):
        return np.ascontiguousarray(a, dtype=np.float64).astype(dt).tobytes()

    inputs = {"pf_config": struct.pack("<iiIi", steps, particles, seed, 0),
              "pf_x": pack(x0[:particles]), "pf_y": pack(traj.y[:steps]),
              "pf_xtrue": pack(traj.x[:steps])}
    if b.n_u:
        inputs["pf_u"] = pack(u)
    res, uc = execute(prog, inputs, b.precision, steps, particles, timeout_s)
    size = np.dtype(dt).itemsize
    raw = bytes(uc.mem_read(prog.symbols["pf_result"], 2 * b.n_x * size + 8))
    vals = np.frombuffer(raw[:2 * b.n_x * size], dt)
    res.result = [float(v) for v in vals] + list(struct.unpack("<ii", raw[2 * b.n_x * size:]))
    return res


def _host_rmse(model, traj, steps: int, particles: int, seed: int) -> list[float]:
    """RMSE per state of the host's NumPy bootstrap filter on the same measurements."""
    from ..filters.run import run_filter  # noqa: PLC0415

    u = model.input_array(traj.u, traj.n_steps)[:steps] if model.n_u else None
    r = run_filter(model, np.ascontiguousarray(traj.y[:steps]), u, method="bootstrap",
                   n_particles=particles, resampling="systematic", backend="numpy", seed=seed)
    err = np.asarray(r.estimates)[:steps] - traj.x[:steps]
    return [float(v) for v in np.sqrt(np.mean(err ** 2, axis=0))]


def emulate_model(spec: str, precision: str = "float", steps: int = 100, particles: int = 500,
                  configs=None, seed: int = 1, core: str = "m4", params: dict | None = None,
                  clock_mhz: float | None = None, opt: str | None = None, model_code=None,
                  tile: int = 32, costmodel: bool = True) -> dict:
    """Emulate the generic harness ``pf_model.c`` running ANY model's own compiled code.

    Compiles the model (``model_code`` overrides, e.g. a hand-written C model from
    :func:`toolchain.compile_c_model`), links it with the harness, simulates the model on the
    host (``model.simulate(seed)``; initial particles from ``model.initial``), runs the small
    ``configs`` (M, N), fits ``cost = a + b M + c M N`` and extrapolates to (``steps``,
    ``particles``).  Beside the counts and breakdowns of :func:`emulate` it reports

    * ``double_share``: the share of per-particle-step cycles spent in double-precision work
      (soft-float libgcc ``__aeabi_d*`` and double libm calls: what an M4F does without an FPU);
    * ``costmodel``: :func:`pfbench.mcu.costmodel.predict` for the same model, precision, M, N
      and clock, and its error ``predicted / emulated - 1``;
    * ``ram``: .data + .bss + stack + heap of the largest run and whether it fits the image's
      RAM (bytes; static buffers are sized for PF_NMAX = max(64, largest N) particles and
      include the buffers holding the host's y, u and true x: ``input_bytes``);
    * ``tracking``: RMSE per state of the emulated filter and of the host NumPy bootstrap
      filter on the same measurements (largest configuration), and ``crn_rel_diff``: the
      relative difference of the emulated SSE from :func:`harness_reference` (the harness in
      float64 NumPy with the target's random numbers).
    """
    from .. import models

    if precision not in MODEL_CONFIGS:
        raise InputError(f"precision must be 'float' or 'double', got {precision!r}")
    if steps < 1 or particles < 1:
        raise InputError("--steps and --particles must be positive")
    name, params = models.parse_spec(spec, params)
    model = models.get(name, **params)
    timing = timing_table(core)
    clock = float(clock_mhz or timing["clock_mhz"])
    configs = tuple(configs or (MODEL_CONFIGS[precision] if tile == 32 else tuple(
        (m, tile * k) for m, k in ((4, 1), (8, 1), (4, 2), (8, 2)))))
    if any(n % tile for _, n in configs):
        raise InputError(f"emulated particle counts must be multiples of the tile ({tile}) so "
                         "that per-tile costs scale with N as they do at large N; got "
                         + ",".join(f"{m}x{n}" for m, n in configs))
    cpu = _cores.get(core).cpu
    mo = model_code if model_code is not None else model_object(spec, precision, params, cpu)
    m_max, n_max = max(m for m, _ in configs), max(n for _, n in configs)
    build = toolchain.build_model(mo, precision, opt=opt, nmax=max(64, n_max),
                                  mmax=max(16, m_max), tile=tile)
    prog = Program(build, core=core)
    traj = model.simulate(m_max, seed=seed)
    x0 = np.asarray(model.initial(np.random.default_rng([seed, 1]), n_max, model.params()),
                    dtype=np.float64).reshape(n_max, model.n_x)
    runs = [run_model(prog, model, traj, x0, m, n, seed=seed) for m, n in configs]
    out, f = summarise(runs, prog, clock, steps, particles)
    pps = out["cycles_per_particle_step"]
    dbl = sum(c["per_particle_step"] for k, c in f["by_entry"].items() if is_double(k))
    out["ram"]["input_bytes"] = sum(prog.sizes.get(k, 0) for k in ("pf_y", "pf_u", "pf_xtrue"))
    out["ram"].update(_core_ram(core, out["ram"]))
    big = max(range(len(runs)), key=lambda i: runs[i].steps * runs[i].particles)
    rb = runs[big]
    emu_rmse = [float(np.sqrt(v / rb.steps)) for v in rb.result[:model.n_x]]
    ref = harness_reference(model, traj, x0, rb.steps, rb.particles, seed)
    emu_sse = np.array(rb.result[:model.n_x])
    res = {
        "model": spec, "params": params, "precision": precision,
        "build": build.label, "double_ops": dict(getattr(mo, "double_ops", {}) or {}),
        "needs_nrt": bool(getattr(mo, "needs_nrt", False)), "tile": tile,
        "nmax": build.nmax, "mmax": build.mmax,
        **out,
        "double_share": min(max(float(dbl / pps), 0.0), 1.0) if pps else 0.0,  # fit rounding
        "double_share_total": double_share(rb.by_entry),
        "model_cycles_per_particle_step": sum(
            f["by_owner"].get(k, {}).get("per_particle_step", 0.0)
            for k in ("pfm_transition", "pfm_log_likelihood")),
        "emulated_configs": [{"steps": r.steps, "particles": r.particles,
                              "instructions": r.instructions, "cycles": r.cycles["nominal"],
                              "degenerate_steps": r.result[-1]} for r in runs],
        "tracking": {"steps": rb.steps, "particles": rb.particles, "emulated_rmse": emu_rmse,
                     "host_rmse": _host_rmse(model, traj, rb.steps, rb.particles, seed),
                     "degenerate_steps": rb.result[-1],
                     # the same filter in float64 NumPy with the same random numbers: equal to
                     # ~1e-12 for a double build (libm ulps), ~1e-5 or a flipped resampling
                     # index for float
                     "crn_reference_sse": [float(v) for v in ref["sse"]],
                     "crn_rel_diff": float(np.max(np.abs(emu_sse - ref["sse"])
                                                  / np.maximum(ref["sse"], 1e-300))),
                     "state_names": list(model.state_names or
                                         [f"x{i}" for i in range(model.n_x)])},
    }
    res["costmodel"] = _costmodel(name, params, precision, steps, particles, clock,
                                  out["predicted_ms"], core) if costmodel else None
    return res


def _core_ram(core: str, ram: dict) -> dict:
    """RAM of the core's typical chip (:mod:`pfbench.mcu.cores`) and whether the filter fits
    (the emulated image has the STM32F407's 128 kB; the host-written logs are not counted)."""
    chip = _cores.get(core)
    need = ram["total_bytes"] - ram.get("input_bytes", 0)
    return {"chip": chip.chip, "chip_ram_bytes": int(chip.ram_bytes),
            "fits_chip": bool(need <= chip.ram_bytes)}


def _costmodel(name, params, precision, steps, particles, clock, emulated_ms,
               core: str = "m4") -> dict:
    """The cost model for the same configuration and its error vs the emulation.

    ``error`` compares like with like: the code layer (the code pfbench generates, zero wait
    states; what the emulation runs) with the emulated time. The board layer ([Embedded] Table-2
    efficiency: the paper's code on the paper's board) is reported beside it as ``board_ms``."""
    from .costmodel import predict  # noqa: PLC0415

    try:
        p = predict(model=name, n_steps=steps, n_particles=particles, precision=precision,
                    clock_mhz=clock, model_params=params or None, memory=False, core=core,
                    basis="code")
    except PfbenchError as exc:
        return {"error": str(exc)}
    return {"predicted_ms": p["predicted_ms"], "basis": "code",
            "cycles_per_particle_step": p["cycles_per_particle_step"],
            "error": p["predicted_ms"] / emulated_ms - 1.0, "board_ms": p["board_ms"]}


def hand_port_reference(hand: dict) -> dict:
    """What the hand-written Ob1 port (:func:`emulate` of pf_ob1.c) costs per particle-step for
    the work the harness + compiled Ob1 does: pf_ob1.c evaluates ``cos(1.2 k)`` inside the
    transition, i.e. per particle unless the compiler hoists it (-Ofast does, -O0 does not),
    whereas the compiled model computes it once per tile; that call is taken out.

    Returns ``{"cycles_per_particle_step", "transition_cos", "reference"}``."""
    pairs = hand["breakdown"]["by_c_function_and_library_call"]
    cos = sum(v for k, v in pairs.items()
              if k.split(" > ")[-1] in ("cos", "cosf") and k.split(" > ")[0] != "randn")
    return {"cycles_per_particle_step": hand["cycles_per_particle_step"], "transition_cos": cos,
            "reference": hand["cycles_per_particle_step"] - cos}


class NewlibRand:
    """newlib's ``srand``/``rand`` (64-bit LCG with Knuth's MMIX constants; returns bits 62..32),
    i.e. the random numbers the C harness draws on the target."""

    A, C, RAND_MAX = 6364136223846793005, 1, 0x7FFFFFFF

    def __init__(self, seed: int):
        self.state = int(seed) & (2 ** 64 - 1)

    def rand(self, n: int) -> np.ndarray:
        out = np.empty(n, dtype=np.int64)
        s = self.state
        for i in range(n):  # a scalar recurrence (n = a few hundred per step in tests)
            s = (s * self.A + self.C) & (2 ** 64 - 1)
            out[i] = (s >> 32) & self.RAND_MAX
        self.state = s
        return out

    def uniform(self, n: int) -> np.ndarray:
        """``rand_uniform()`` of pf_model.c: (rand() + 1) / (RAND_MAX + 2)."""
        return (self.rand(n).astype(np.float64) + 1.0) / (self.RAND_MAX + 2.0)


def harness_reference(model, traj, x0: np.ndarray, steps: int, particles: int,
                      seed: int = 1) -> dict:
    """pf_model.c re-done on the host in float64 NumPy with the SAME random numbers (newlib's
    rand, Box-Muller one normal per call, draw order of the harness) and the model's NumPy
    functions: the common-random-numbers reference of a double-precision emulated run.

    Returns ``{"sse": (n_x,), "est": (n_x,), "estimates": (steps, n_x)}``."""
    p = model.params()
    u = model.input_array(traj.u, traj.n_steps)
    rng = NewlibRand(seed)
    x = np.array(x0[:particles], dtype=np.float64).reshape(particles, model.n_x)
    nn = model.n_noise
    ests = np.empty((steps, model.n_x))
    for t in range(steps):
        uu = rng.uniform(2 * particles * nn)       # per normal: u1 then u2, particle-major
        noise = (np.sqrt(-2.0 * np.log(uu[0::2])) * np.cos(6.283185307179586 * uu[1::2]))
        xp = np.asarray(model.transition(x, u[t], t, noise.reshape(particles, nn), p),
                        dtype=np.float64).reshape(particles, model.n_x)
        lw = np.asarray(model.log_likelihood(traj.y[t], xp, u[t], t, p), dtype=np.float64)
        w = np.exp(lw - lw.max())
        s = w.sum()
        w = w * (1.0 / s) if s > 0 else np.full(particles, 1.0 / particles)
        ests[t] = w @ xp
        step = 1.0 / particles
        ptr = np.cumsum(np.r_[rng.uniform(1)[0] * step, np.full(particles - 1, step)])
        idx = np.minimum(np.searchsorted(np.cumsum(w), ptr, side="left"), particles - 1)
        x = xp[idx]
    err = ests - traj.x[:steps]
    return {"sse": (err ** 2).sum(axis=0), "est": ests[-1], "estimates": ests}
