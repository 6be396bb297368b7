"""Cores as data (pfbench.mcu.cores), per-core cycle tables, multi-core predict, ``fit``, ``mcu fit``."""
import json

import pytest
from click.testing import CliRunner

from pfbench.cli import main
from pfbench.errors import PfbenchError
from pfbench.mcu import cores
from pfbench.mcu import costmodel as cm
from pfbench.mcu.counting import OPS
from pfbench.mcu.cycles import load_table

ALL = ("m0plus", "m3", "m4", "m7", "m33")


def test_every_core_has_data_with_sources():
    # catches: a core dropped from cores.json, a missing source string, a table missing an op
    assert cores.names() == ALL
    raw = json.loads(cores.CORES_PATH.read_text())
    for c in cores.all_cores():
        e = raw["cores"][c.key]
        for what in (e["chip"], e["power"]):
            assert len(what["source"]) > 20
        assert c.clock_mhz > 0 and c.ram_bytes > c.reserve_bytes > 0 and c.power_w() > 0
        table = load_table(c.cycles_path)
        assert table.source and json.loads(c.timing_path.read_text())["source"]
        for prec in ("float", "double"):
            for op in OPS:
                assert table.cost(prec, op) > 0
    assert cores.get("M0+").key == "m0plus" and cores.get(None).key == "m4"
    with pytest.raises(PfbenchError, match="unknown core 'm9'; choose one of m0plus"):
        cores.get("m9")


def test_fpu_shapes_the_tables():
    # catches: M7 double left soft-float, M0+ float given an FPU, tables swapped between cores
    t = {k: load_table(cores.get(k).cycles_path) for k in ALL}
    for op in ("add", "mul", "div", "exp"):
        assert t["m7"].cost("double", op) * 10 < t["m4"].cost("double", op)
        assert t["m0plus"].cost("float", op) > 5 * t["m4"].cost("float", op)
        assert t["m3"].cost("float", op) > 5 * t["m33"].cost("float", op)
    # the original M4 table is kept (the paper's calibration rests on it)
    assert t["m4"].cost("float", "cos") == 132 and t["m4"].cost("double", "exp") == 2440


def test_predict_per_core_defaults_and_energy():
    m4 = cm.predict("ob1", 50, 100, "double")
    assert m4["core"] == "m4" and m4["clock_mhz"] == 168.0
    assert m4["energy_wh"] == pytest.approx(1.39 * m4["predicted_ms"] / 3.6e6, rel=1e-12)
    c = cores.get("m4")
    assert m4["energy_mcu_wh"] == pytest.approx(c.power_w() * m4["predicted_ms"] / 3.6e6, rel=1e-12)
    m7 = cm.predict("ob1", 50, 100, "double", core="m7")
    assert m7["clock_mhz"] == 480.0 and m7["energy_board_wh"] is None
    assert m7["energy_wh"] == m7["energy_mcu_wh"]
    assert m7["predicted_ms"] * 20 < m4["predicted_ms"]          # hardware double + 480 MHz
    # same factor applied to other cores, and said so
    assert m7["efficiency"] == pytest.approx(cm.calibrate()["efficiency"]["double"], rel=1e-12)
    assert "applied unchanged" in m7["efficiency_basis"]
    # explicit clock halves -> time doubles, MCU power halves (linear current) -> energy equal
    slow = cm.predict("ob1", 50, 100, "double", core="m7", clock_mhz=240.0)
    assert slow["predicted_ms"] == pytest.approx(2 * m7["predicted_ms"], rel=1e-12)
    assert slow["energy_mcu_wh"] == pytest.approx(m7["energy_mcu_wh"], rel=1e-12)


def test_ram_check_uses_the_cores_chip():
    # catches: RAM still the STM32F407's 192 kB on another core
    mem = cm.memory_bytes(cm_model(), 100, 10, "float", history=False, core="m3")
    assert mem["ram_bytes"] == 20 * 1024 and mem["chip"] == "STM32F103C8"
    with pytest.raises(PfbenchError, match="STM32F103C8 has 20 kB"):
        cm.predict("ob1", 10, 5000, "float", core="m3", history=False)


def cm_model():
    from pfbench.models.ob1 import Ob1

    return Ob1()


@pytest.fixture(scope="module")
def fit_1khz():
    return cm.fit("ob1", 1000, 1000.0)


def test_fit_meets_period_and_ram(fit_1khz):
    rows = fit_1khz["rows"]
    assert len(rows) == 10
    for r in rows:
        assert r["linearity_error"] < 1e-6        # bootstrap counts are affine in N_p
        if r["max_particles"]:
            assert r["step_us"] <= 1000.0 + 1e-9
            # one more particle breaks the binding limit (maximality)
            if r["binding"] == "time":
                assert r["fixed_us"] + r["per_particle_us"] * (r["max_particles"] + 1) > 1000.0
            assert r["max_particles"] <= r["n_ram"]
    by = {(r["core"], r["precision"]): r["max_particles"] for r in rows}
    assert by[("m7", "double")] > 10 * by[("m4", "double")]
    assert by[("m4", "float")] > 10 * by[("m0plus", "float")]


def test_fit_monotone_in_period_and_ram_binds_on_tiny_chip(fit_1khz):
    # catches: a longer period lowering N_p; RAM ignored
    slow = cm.fit("ob1", 1000, 1e6, cores=["m0plus", "m3", "m4"], precisions=("float",))
    fast = {(r["core"], r["precision"]): r for r in fit_1khz["rows"]}
    for r in slow["rows"]:
        assert r["max_particles"] >= fast[(r["core"], r["precision"])]["max_particles"]
    m3 = next(r for r in slow["rows"] if r["core"] == "m3")
    assert m3["binding"] == "ram" and m3["max_particles"] == m3["n_ram"] == (20 - 4) * 1024 // 12


def _run(args):
    return CliRunner().invoke(main, ["mcu", *args])


def test_fit_cli_json_and_text():
    r = _run(["fit", "--model", "ob1", "--steps", "200", "--period-us", "1000", "--core", "m4", "--core", "m7",
              "--json"])
    assert r.exit_code == 0, r.output
    obj = json.loads(r.stdout)
    assert [x["core"] for x in obj["rows"]] == ["m4", "m4", "m7", "m7"]
    ref = cm.fit("ob1", 200, 1000.0, cores=["m4", "m7"])
    assert [x["max_particles"] for x in obj["rows"]] == [x["max_particles"] for x in ref["rows"]]
    t = _run(["fit", "--model", "ob1", "--period-us", "1000", "--precision", "float"])
    assert t.exit_code == 0 and "Cortex-M7" in t.stdout and "limit" in t.stdout


def test_estimate_core_option():
    r = _run(["estimate", "--core", "m7", "--clock-mhz", "480", "--steps", "50", "--particles", "100", "--json"])
    assert r.exit_code == 0, r.output
    obj = json.loads(r.stdout)
    assert obj["core"] == "m7" and obj["clock_mhz"] == 480.0 and obj["chip"] == "STM32H743"


@pytest.mark.parametrize("args,needle", [
    (["fit", "--period-us", "0"], "--period-us"),
    (["fit", "--period-us", "1000", "--core", "m9"], "unknown core"),
    (["fit"], "--period-us"),
    (["fit", "--period-us", "1000", "--model", "nope"], "unknown model"),
    (["fit", "--period-us", "1000", "--steps", "0"], "--steps"),
    (["estimate", "--core", "m9"], "unknown core"),
    (["estimate", "--core", "m3", "--particles", "5000", "--no-history"], "STM32F103C8"),
])
def test_cli_errors_one_line(args, needle):
    r = _run(args)
    assert r.exit_code == 2, r.output
    err = r.stderr.strip()
    assert "\n" not in err and needle in err and "Traceback" not in r.output


def test_libcost_rederives_a_table_entry():
    # catches: a cycle table edited by hand away from its derivation (or a broken derivation)
    from pfbench.mcu import libcost, toolchain

    if toolchain.missing():
        pytest.skip("; ".join(toolchain.missing()))
    core = cores.get("m0plus")
    prog = libcost._program(core, "float")
    base = libcost.run_op(prog, core, "base")["cycles"]["nominal"]
    add = libcost.run_op(prog, core, "add")["cycles"]["nominal"]
    per_call = (add - base) / libcost.K + core.timing()["cycles"]["int_alu"]
    assert per_call == pytest.approx(load_table(core.cycles_path).cost("float", "add"), abs=0.06)


def test_fit_basis_selects_the_time_layer():
    # the code layer (what `mcu emulate --model` runs) gives other per-step times than the board
    # layer, and its step times agree with predict(basis="code") at the N_p it returns.
    # Catches --basis ignored by fit, or fit and predict using different layers.
    kw = dict(cores=["m4"], precisions=("float",))
    board = cm.fit("ob1", 200, 1000.0, **kw)
    code = cm.fit("ob1", 200, 1000.0, basis="code", **kw)
    assert board["basis"] == "board" and code["basis"] == "code"
    rb, rc = board["rows"][0], code["rows"][0]
    assert rb["max_particles"] != rc["max_particles"]
    p = cm.predict("ob1", 100, rc["max_particles"], "float", core="m4", basis="code", memory=False)
    assert p["predicted_ms"] * 1e3 / 100 == pytest.approx(rc["step_us"], rel=0.02)
    with pytest.raises(PfbenchError, match="unknown basis"):
        cm.fit("ob1", 200, 1000.0, basis="nope", **kw)
