"""Emulated Cortex-M4 instruction counts of the C bootstrap filter.

Tests that need the cross toolchain skip with the reason when it is missing (`make mcu-tools`).
"""
from __future__ import annotations

import json

import pytest

from pfbench.mcu import emulate as E
from pfbench.mcu import toolchain

pytestmark = pytest.mark.mcu_tools

SOFT_DOUBLE = ("__aeabi_d", "__adddf3", "__subdf3", "__muldf3", "__divdf3", "__floatsidf",
               "__extendsfdf2", "__truncdfsf2", "__fixdfsi", "__aeabi_f2d", "__aeabi_i2d")


@pytest.fixture(scope="module")
def programs():
    why = toolchain.missing()
    if why:
        pytest.skip("Cortex-M4 toolchain/emulator missing: " + "; ".join(why))
    return {p: E.Program(toolchain.build(p)) for p in ("float", "double")}


# --- pure decoding (no toolchain needed) -------------------------------------------------
@pytest.mark.parametrize("mn,base,cond", [
    ("addseq.w", "add", True), ("bls.n", "b", True), ("bl", "bl", False), ("bleq", "bl", True),
    ("bics.w", "bic", False), ("lsls", "lsl", False), ("mls", "mls", False),
    ("vmovlt.f32", "vmov", True), ("rsbsgt", "rsb", True), ("ittte", "it", False),
    ("popgt", "pop", True), ("teq", "teq", False), ("ldrhne", "ldrh", True)])
def test_split_mnemonic(mn, base, cond):
    assert E.split_mnemonic(mn) == (base, cond)


def test_classify_cycles_from_table():
    t = E.timing_table()
    cls, cyc, kind, _ = E.classify(E.Insn(0, 2, "pop", "{r4, r5, r6, pc}"), t)
    assert (cls, kind, cyc["nominal"]) == ("branch", "jump", 1 + 4)   # 1+N, +P when taken
    cls, cyc, kind, _ = E.classify(E.Insn(0, 4, "vdiv.f32", "s0, s1, s2"), t)
    assert (cls, cyc["nominal"]) == ("fpu_divsqrt", 14)
    cls, cyc, kind, _ = E.classify(E.Insn(0, 4, "vpush", "{d8-d9}"), t)
    assert (cls, cyc["nominal"]) == ("fpu_load_store", 1 + 4)
    cls, cyc, kind, _ = E.classify(E.Insn(0, 4, "sdiv", "r0, r1, r2"), t)
    assert (cls, cyc["best"], cyc["worst"]) == ("div", 2, 12)
    assert E.classify(E.Insn(0, 2, "cbz", "r3, 8000"), t)[2] == "cjump"
    assert "source" in t and t["clock_mhz"] == 168.0


# --- emulated runs ----------------------------------------------------------------------
def test_build_is_cached(programs):
    b = programs["float"].build
    mtime = b.elf.stat().st_mtime_ns
    again = toolchain.build("float")
    assert again.elf == b.elf and again.elf.stat().st_mtime_ns == mtime


def test_float_build_executes_no_soft_double(programs):
    r = E.run("float", 4, 16, program=programs["float"])
    executed = set(r.by_function)
    assert not [f for f in executed if f.startswith(SOFT_DOUBLE)], executed
    assert {"cosf", "expf", "logf"} <= executed
    assert r.classes["fpu_addmul"] > 0 and r.classes["fpu_divsqrt"] > 0


def test_double_build_hot_functions_are_libgcc_soft_double(programs):
    r = E.run("double", 2, 16, program=programs["double"])
    # the FPU is never touched: every double operation is a libgcc call
    assert all(r.classes[k] == 0 for k in E.CLASSES if k.startswith("fpu"))
    hot = sorted(r.by_function, key=lambda f: -r.by_function[f]["cycles"])[:3]
    assert set(hot) <= {"__aeabi_dadd", "__aeabi_dsub", "__aeabi_dmul", "__aeabi_ddiv"}, hot
    soft = sum(v["cycles"] for f, v in r.by_function.items() if f.startswith(SOFT_DOUBLE))
    assert soft / r.cycles["nominal"] > 0.5
    assert {"cos", "exp", "log", "sqrt"} <= set(r.by_entry)


def test_float_and_double_builds_run_the_same_filter(programs):
    # same srand seed, same algorithm: the estimates agree to float precision on a short run
    f = E.run("float", 2, 8, program=programs["float"]).result
    d = E.run("double", 2, 8, program=programs["double"]).result
    assert f[3] == d[3] == 2.0
    assert f[1] == pytest.approx(d[1], rel=1e-4, abs=1e-5)   # last estimate
    assert f[2] == pytest.approx(d[2], rel=1e-4, abs=1e-5)   # last true state


@pytest.mark.parametrize("precision,m,n", [("float", 10, 50), ("double", 3, 20)])
def test_counts_scale_linearly_with_steps_and_particles(programs, precision, m, n):
    prog = programs[precision]
    runs = [E.run(precision, mm, nn, program=prog)
            for mm, nn in ((m, n), (2 * m, n), (m, 2 * n), (2 * m, 2 * n))]
    f = E.fit(runs)
    # Per-particle-step cost only varies through data-dependent libm paths (exp underflow,
    # argument reduction) and the resampling loop: a bounded per-step variation (cv < 0.3)
    # averaged over >= 60 particle-steps -> a few % at most; 5% leaves margin.
    assert f["residual_rel"] < 0.05
    held = E.run(precision, 3 * m, 3 * n, program=prog)
    c = f["cycles"]["nominal"]
    assert E.predict_cycles(c, 3 * m, 3 * n) == pytest.approx(held.cycles["nominal"], rel=0.05)
    ins = f["instructions"]
    assert E.predict_cycles(ins, 3 * m, 3 * n) == pytest.approx(held.instructions, rel=0.05)
    # the particle-step cost dominates: doubling N at fixed M nearly doubles the per-step work
    assert c["per_particle_step"] > 0 and c["per_particle_step"] * n > c["per_step"] * 0.5
    # the emulator is deterministic
    again = E.run(precision, m, n, program=prog)
    assert again.instructions == runs[0].instructions


def test_cli_emulate_json(programs):
    from click.testing import CliRunner

    from pfbench.mcu.cli import mcu

    res = CliRunner().invoke(mcu, ["emulate", "--precision", "float", "--steps", "500",
                                   "--particles", "500", "--configs", "4x16,8x16,4x32",
                                   "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    for key in ("predicted_ms", "instructions_per_particle_step", "cycles_per_particle_step",
                "breakdown", "table2", "unseen"):
        assert key in out
    lo, hi = out["predicted_ms_range"]
    assert lo <= out["predicted_ms"] <= hi
    # cycles per particle-step x M N / clock is the bulk of the predicted time
    assert out["predicted_ms"] >= out["cycles_per_particle_step"] * 500 * 500 / 168e3
