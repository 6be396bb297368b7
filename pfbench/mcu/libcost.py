"""Derive per-core cycle tables: cross-compile a micro-benchmark, emulate it, count, time.

For every core of :mod:`pfbench.mcu.cores` and each precision, a tiny C program (below) is
built with the core's gcc flags against Debian's newlib/libgcc, run in unicorn with the
core's CPU model, and its executed basic blocks are classified and timed with
:func:`pfbench.mcu.emulate.classify` (through :class:`pfbench.mcu.emulate.Program`) and the
core's instruction-timing table ``data/cortex_<core>_timing.json`` -- the way the Cortex-M4
table was derived ("instruction counts x the instruction-timing table", see its source).

The cost of one operation is a difference of two runs: a loop of ``K`` evaluations of the
operation on representative arguments (written into the image by the host) minus the same
loop that stores ``-a`` instead (same loads, same register file, same store), divided by
``K``, plus the one-cycle negation (VNEG or an EOR of the sign bit) the baseline spent. It therefore
includes the call, the argument marshalling and the return of a library routine
(``__aeabi_dadd``, ``expf`` ...) or the FPU instruction(s) gcc emits inline.

Representative arguments (``_ARGS``): add/mul/div/cmp mixed signs and magnitudes 1e-2..1e2;
sqrt (0.01, 100); exp (-20, 0) (likelihood weights); log (1e-6, 1) (Box-Muller); cos in
(-2 pi, 2 pi) (Box-Muller angles, electrical angles), and separately ``cos_big`` in (0, 1200)
(Ob1's cos(1.2 k) for k <= 1000: the large-argument reduction path, reported in the notes);
pow base (0.1, 10), exponent (0.5, 3); cbrt (``np.cbrt``, e.g. Ob4's transition) both signs,
magnitudes 1e-3..1e3; int->real conversion of integers in (-1000, 1000).

On a core whose FPU handles the precision, add/mul/cmp/cvt/div are one inline FPU
instruction and cost that instruction's timing-table entry (VADD/VMUL/VCMP/VCVT ``fpu_simple``,
VDIV ``fpu_divsqrt``), as in the M4 table; the loop difference is kept in the notes.
Ops the micro-benchmark does not measure come from the timing table: ``int`` (one ALU op),
``load``/``store`` (a word load/store, or a double-word LDRD/VLDR.64), and ``div_scalar``
(the float build is -Ofast, i.e. a multiplication by a hoisted reciprocal = ``mul``; the
double build divides = ``div``), exactly as the M4 table defines them.

Run ``python -m pfbench.mcu.libcost [--write]`` to re-derive (about a minute); ``--write``
rewrites ``data/cortex_{m0plus,m3,m7,m33}_cycles.json`` (the M4 table is the original
[Recovered] one and is only compared, never overwritten; its ``cbrt`` entry, an op the original
table did not cost, was taken from this derivation for the M4).
"""
from __future__ import annotations

import json
import struct

import numpy as np

from ..errors import PfbenchError
from . import cores as _cores
from . import toolchain

#: loops K evaluations of one op; K arguments per op
K = 64

#: op name -> (C expression on a, b / ia, result kind), in selector order (0 = the baseline)
_OPS = {
    "base": ("-a", "r"),
    "add": ("a + b", "r"),
    "mul": ("a * b", "r"),
    "div": ("a / b", "r"),
    "cmp": ("a < b", "i"),
    "sqrt": ("SQRT(a)", "r"),
    "exp": ("EXP(a)", "r"),
    "log": ("LOG(a)", "r"),
    "cos": ("COS(a)", "r"),
    "cos_big": ("COS(a)", "r"),
    "pow": ("POW(a, b)", "r"),
    "cvt": ("(real)ia", "r"),
    "rand": ("rand()", "i"),
    "cbrt": ("CBRT(a)", "r"),
}

BENCH_C = r"""
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#ifdef PF_FLOAT
typedef float real;
#define SQRT sqrtf
#define EXP expf
#define LOG logf
#define COS cosf
#define POW powf
#define CBRT cbrtf
#else
typedef double real;
#define SQRT sqrt
#define EXP exp
#define LOG log
#define COS cos
#define POW pow
#define CBRT cbrt
#endif
#define K %(K)d
volatile struct { int32_t op; int32_t pad; } bench_cfg = {-1, 1}; /* non-zero: .data, patched by the host */
volatile real arg_a[K] = {1}, arg_b[K] = {1};
volatile int32_t arg_i[K] = {1};
volatile real out_r;
volatile int32_t out_i;
__attribute__((noinline)) void bench_finish(void) { __asm__ volatile("nop"); }
%(loops)s
int main(void)
{
    switch (bench_cfg.op) {
%(cases)s
    default: break;
    }
    bench_finish();
    return 0;
}
"""


def _source() -> str:
    loops, cases = [], []
    for i, (op, (expr, kind)) in enumerate(_OPS.items()):
        sink = "out_r" if kind == "r" else "out_i"
        loops.append(
            f"__attribute__((noinline)) static void loop_{op}(void)\n{{\n"
            f"    for (int k = 0; k < K; k++) {{\n"
            f"        real a = arg_a[k], b = arg_b[k]; int32_t ia = arg_i[k];\n"
            f"        (void)a; (void)b; (void)ia;\n"
            f"        {sink} = {expr};\n    }}\n}}")
        cases.append(f"    case {i}: loop_{op}(); break;")
    return BENCH_C % {"K": K, "loops": "\n".join(loops), "cases": "\n".join(cases)}


def _args(op: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    def mixed(n):
        return rng.choice([-1.0, 1.0], n) * 10.0 ** rng.uniform(-2, 2, n)

    a, b = mixed(K), mixed(K)
    if op == "sqrt":
        a = rng.uniform(0.01, 100.0, K)
    elif op == "exp":
        a = rng.uniform(-20.0, 0.0, K)
    elif op == "log":
        a = rng.uniform(1e-6, 1.0, K)
    elif op == "cos":
        a = rng.uniform(-2 * np.pi, 2 * np.pi, K)
    elif op == "cos_big":
        a = rng.uniform(0, 1200.0, K)
    elif op == "pow":
        a, b = rng.uniform(0.1, 10.0, K), rng.uniform(0.5, 3.0, K)
    elif op == "cbrt":
        a = rng.choice([-1.0, 1.0], K) * 10.0 ** rng.uniform(-3, 3, K)
    ia = rng.integers(-1000, 1000, K)
    return a, b, ia


def build(core: _cores.Core, precision: str, force: bool = False) -> toolchain.Build:
    """Build (cached under toolchain.cache_root()/libcost) the micro-benchmark for a core."""
    toolchain.check_tools()
    flags = [*core.gcc[precision], *toolchain.BARE_METAL]
    flags += ["-DPF_FLOAT", "-Ofast"] if precision == "float" else ["-O2"]
    src = _source()

    def make(tmp):
        (tmp / "bench.c").write_text(src)
        toolchain.run_tool([toolchain.GCC, *flags, "-c", "bench.c", "-o", "bench.o"], tmp)
        toolchain.link(tmp, "bench", flags, ["bench.c"], ["bench.o"])

    return toolchain.image(f"libcost/{core.key}-{precision}", [("bench.c", src)], "bench", precision,
                           f"libcost-{core.key}", tuple(flags), make, force)


def run_op(prog, core: _cores.Core, op: str, seed: int = 0) -> dict:
    """Emulate the loop of ``op``; return total cycles per scenario and instruction count."""
    from .emulate import execute

    a, b, ia = _args(op, np.random.default_rng(seed))
    fmt = "f" if prog.build.precision == "float" else "d"
    inputs = {"bench_cfg": struct.pack("<ii", list(_OPS).index(op), 0),
              "arg_a": struct.pack(f"<{K}{fmt}", *a), "arg_b": struct.pack(f"<{K}{fmt}", *b),
              "arg_i": struct.pack(f"<{K}i", *ia)}
    try:
        r, _uc = execute(prog, inputs, prog.build.precision, 1, 1, timeout_s=120.0, stop="bench_finish")
    except PfbenchError as exc:
        raise PfbenchError(f"libcost {core.key}/{op}: {exc}") from None
    return {"cycles": r.cycles, "instructions": r.instructions}


def _program(core: _cores.Core, precision: str):
    from .emulate import Program

    return Program(build(core, precision), core=core.key)


def measure(core: _cores.Core | str, precision: str, seed: int = 0) -> dict:
    """Per-call cycles (nominal, best, worst) and instructions of every micro-benchmarked op."""
    core = _cores.get(core)
    prog = _program(core, precision)
    base = run_op(prog, core, "base", seed)
    c = prog.timing["cycles"]
    neg = c["fpu_simple"] if core.has_hw(precision) else c["int_alu"]
    out = {}
    for op in _OPS:
        if op == "base":
            continue
        r = run_op(prog, core, op, seed)
        out[op] = {s: (r["cycles"][s] - base["cycles"][s]) / K + neg for s in r["cycles"]}
        out[op]["instructions"] = (r["instructions"] - base["instructions"]) / K + 1
    return out


#: libm routines whose double cost on a double-precision FPU is scaled from the float one
_LIBM = ("exp", "log", "cos", "cos_big", "pow", "cbrt")


def _dp_double(core: _cores.Core, float_meas: dict, seed: int = 0) -> dict:
    """Double precision on a double-precision FPU (the Cortex-M7), which unicorn 2.1 cannot
    execute (its M-profile CPU models all decode FPv5 double-precision instructions as
    invalid). Arithmetic is one FPU instruction timed by the core's table (VADD/VMUL/VCMP/
    VCVT.F64: ``fpu_simple``; VDIV/VSQRT.F64: ``fpu_divsqrt_f64``), like the M4 table times
    its float arithmetic; a libm routine costs its float version on this core times the
    double/float instruction-count ratio of the same routine built soft-float for the
    Cortex-M3 (both precisions in software there: the ratio measures the algorithm's extra
    work, e.g. more polynomial terms). ``rand`` is integer code: the float build's value."""
    c = core.timing()["cycles"]
    m3 = _cores.get("m3")
    ratio = {}
    for_m3 = {p: measure(m3, p, seed) for p in ("float", "double")}
    for op in _LIBM:
        ratio[op] = for_m3["double"][op]["instructions"] / for_m3["float"][op]["instructions"]
    out = {}
    for op, cyc in (("add", c["fpu_simple"]), ("mul", c["fpu_simple"]), ("cmp", c["fpu_simple"]),
                    ("cvt", c["fpu_simple"]), ("div", c["fpu_divsqrt_f64"]),
                    ("sqrt", c["fpu_divsqrt_f64"])):
        out[op] = {"best": cyc, "nominal": cyc, "worst": cyc, "instructions": 1.0}
    for op in _LIBM:
        out[op] = {k: v * ratio[op] for k, v in float_meas[op].items()}
    out["rand"] = dict(float_meas["rand"])
    out["_ratio"] = ratio
    return out


def _memory_ops(core: _cores.Core, precision: str) -> dict:
    c = core.timing()["cycles"]
    if precision == "float":
        hw = core.has_hw("float")
        return {"load": c["fpu_load_store"] if hw else c["load"],
                "store": c["fpu_load_store"] if hw else c["store"]}
    key = "fpu_load_store" if core.has_hw("double") else "load_store_double"
    return {"load": c[key], "store": c[key]}


def derive(core: _cores.Core | str, seed: int = 0) -> dict:
    """The cycle table of ``core`` (same schema as data/cortex_m4_cycles.json)."""
    core = _cores.get(core)
    precs, notes, meas = {}, {}, {}
    timing = core.timing()
    for prec in ("float", "double"):
        if core.fpu == "dp" and prec == "double":
            m = _dp_double(core, meas["float"], seed)
        else:
            m = measure(core, prec, seed)
        meas[prec] = m
        cyc = {op: round(m[op]["nominal"], 1) for op in
               ("add", "mul", "div", "cmp", "sqrt", "exp", "log", "cos", "pow", "cbrt", "cvt", "rand")}
        if core.has_hw(prec):
            # one inline FPU instruction: its timing-table cost (the loop difference is off by
            # the load class of the unused operand, +-1 cycle; the measurement stays in the notes)
            c = timing["cycles"]
            cyc.update(add=c["fpu_simple"], mul=c["fpu_simple"], cmp=c["fpu_simple"],
                       cvt=c["fpu_simple"],
                       div=c["fpu_divsqrt_f64" if prec == "double" and "fpu_divsqrt_f64" in c
                             else "fpu_divsqrt"])
        cyc["div_scalar"] = cyc["mul"] if prec == "float" else cyc["div"]
        cyc["int"] = timing["cycles"]["int_alu"]
        cyc.update(_memory_ops(core, prec))
        hw = "hardware FPU" if core.has_hw(prec) else "libgcc soft-float"
        flags = " ".join(core.gcc[prec]) + (" -Ofast" if prec == "float" else " -O2")
        precs[prec] = {"description": f"{prec} with {hw} ({flags}), newlib libm",
                       "cycles": {k: cyc[k] for k in ("add", "mul", "div", "div_scalar", "cmp", "sqrt",
                                                      "exp", "log", "cos", "pow", "cbrt", "cvt", "int",
                                                      "load", "store", "rand")}}
    for op in ("add", "mul", "div", "cmp", "sqrt", "exp", "log", "cos", "cos_big", "pow", "cbrt", "cvt",
               "rand"):
        notes[op] = "; ".join(
            f"{p}: {meas[p][op]['nominal']:.1f} (best {meas[p][op]['best']:.1f}, worst "
            f"{meas[p][op]['worst']:.1f}; {meas[p][op]['instructions']:.1f} instructions)"
            for p in ("float", "double"))
    if "_ratio" in meas["double"]:
        notes["double_on_dp_fpu"] = (
            "unicorn 2.1 cannot execute FPv5 double-precision instructions, so the double column is "
            "not emulated: arithmetic = one FPU instruction from the timing table, libm = float cost x "
            "the double/float instruction ratio of the soft-float Cortex-M3 build ("
            + ", ".join(f"{k} {v:.2f}" for k, v in meas["double"]["_ratio"].items()) + "); assumed")
    notes["div_scalar"] = "float build -Ofast: multiplication by a hoisted reciprocal (= mul); double: = div"
    notes["int"] = "one integer ALU instruction (timing table int_alu)"
    notes["load"] = notes["store"] = ("timing table: word LDR/STR or VLDR/VSTR for float; LDRD/STRD (soft) "
                                      "or VLDR.64/VSTR.64 (double-precision FPU) for double")
    return {
        "name": f"{core.name.lower()}-{core.chip.lower()}",
        "clock_mhz": core.clock_mhz,
        "source": (f"derived by pfbench.mcu.libcost: micro-benchmark built with Debian's arm-none-eabi "
                   f"gcc/newlib/libgcc ({toolchain.compiler_version()}), run in unicorn "
                   f"{core.unicorn_cpu}, executed instructions x {core.timing_path.name} "
                   f"({timing['source'][:120]}...). Per call, difference of a {K}-evaluation loop and "
                   f"its argument-only baseline, nominal scenario."),
        "notes": notes,
        "precisions": precs,
        "generators": json.loads((_cores.DATA_DIR / "cortex_m4_cycles.json").read_text())["generators"],
    }


def compare_m4(seed: int = 0) -> dict:
    """Re-derive the M4 costs and set them beside the original M4 table (op -> (orig, derived))."""
    orig = json.loads((_cores.DATA_DIR / "cortex_m4_cycles.json").read_text())["precisions"]
    new = derive("m4", seed)["precisions"]
    return {p: {op: (orig[p]["cycles"][op], new[p]["cycles"][op]) for op in orig[p]["cycles"]}
            for p in ("float", "double")}


def main(argv=None) -> None:  # pragma: no cover - derivation tool
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="rewrite data/cortex_<core>_cycles.json")
    ap.add_argument("--core", action="append", help="core(s) to derive (default: all but m4)")
    args = ap.parse_args(argv)
    keys = args.core or [c for c in _cores.names() if c != "m4"]
    for key in keys:
        core = _cores.get(key)
        table = derive(core)
        print(core.key, json.dumps({p: v["cycles"] for p, v in table["precisions"].items()}))
        if args.write and core.key != "m4":
            core.cycles_path.write_text(json.dumps(table, indent=2) + "\n")
    cmp = compare_m4()
    print("m4 original vs re-derived:")
    for p, ops in cmp.items():
        print(" ", p, ", ".join(f"{op} {a:g}/{b:g}" for op, (a, b) in ops.items()))


if __name__ == "__main__":  # pragma: no cover
    main()
