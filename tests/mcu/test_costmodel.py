"""Cycle arithmetic, cycle tables, calibration and memory check (pfbench.mcu.cycles/costmodel)."""
import json
import math

import pytest

from pfbench.errors import PfbenchError
from pfbench.mcu import costmodel as cm
from pfbench.mcu.counting import OPS
from pfbench.mcu.cycles import DEFAULT_TABLE, cycles_of, cycles_to_ms, load_table
from pfbench.models.ob1 import Ob1


@pytest.fixture(scope="module")
def table():
    return load_table()


def test_builtin_table_complete_and_sourced(table):
    raw = json.loads(DEFAULT_TABLE.read_text())
    assert "[Recovered]" in raw["source"]
    for prec in ("float", "double"):
        table.validate(prec)
        for op in OPS:
            assert table.cost(prec, op) >= 0


def test_cycle_arithmetic(table):
    assert cycles_to_ms(168_000, 168.0) == pytest.approx(1.0, rel=1e-15)
    # Box-Muller: 2 uniforms (rand + int->real + mul) + log + sqrt + cos + 3 mul
    c = table.cycles["float"]
    uni = c["rand"] + c["cvt"] + c["mul"]
    assert table.cost("float", "uniform") == uni
    assert table.cost("float", "normal") == 2 * uni + c["log"] + c["sqrt"] + c["cos"] + 3 * c["mul"]
    d = table.cycles["double"]
    assert table.cost("double", "normal") == (2 * (d["rand"] + d["cvt"] + d["mul"]) + d["log"] + d["sqrt"]
                                              + d["cos"] + 3 * d["mul"])
    counts = {"add": 10, "exp": 2, "normal": 3}
    got = cycles_of(counts, table, "double")
    assert got == {"add": 10 * d["add"], "exp": 2 * d["exp"], "normal": 3 * table.cost("double", "normal")}
    assert cm.raw_cycles(counts, "double", table) == sum(got.values())


def test_prediction_scales_with_clock_and_power():
    a = cm.predict("ob1", 200, 100, "float", clock_mhz=168.0)
    b = cm.predict("ob1", 200, 100, "float", clock_mhz=84.0, board_power_w=2.78)
    assert b["predicted_ms"] == pytest.approx(2 * a["predicted_ms"], rel=1e-12)
    assert a["energy_wh"] == pytest.approx(1.39 * a["predicted_ms"] / 3.6e6, rel=1e-12)
    assert b["energy_wh"] == pytest.approx(4 * a["energy_wh"], rel=1e-12)
    for key in ("predicted_ms", "energy_wh", "ops", "precision", "clock_mhz"):
        assert key in a


def test_one_extra_cos_costs_one_cos_of_cycles():
    import numpy as np

    class ExtraCos(Ob1):
        @staticmethod
        def transition(x, u, t, noise, p):
            out = Ob1.transition(x, u, t, noise, p)
            np.cos(out)
            return out

    for prec in ("float", "double"):
        a = cm.predict(Ob1(), 20, 50, prec, calibrated=False)
        b = cm.predict(ExtraCos(), 20, 50, prec, calibrated=False)
        per = load_table().cost(prec, "cos")
        assert b["raw_cycles"] - a["raw_cycles"] == pytest.approx(20 * 50 * per, rel=1e-12)


def test_user_table_scaling(tmp_path, table):
    raw = json.loads(DEFAULT_TABLE.read_text())
    for prec in raw["precisions"].values():
        prec["cycles"] = {k: 2 * v for k, v in prec["cycles"].items()}
    f = tmp_path / "double_cost.json"
    f.write_text(json.dumps(raw))
    a = cm.predict("ob1", 50, 100, "double", calibrated=False)
    b = cm.predict("ob1", 50, 100, "double", calibrated=False, cycles=str(f))
    # every primitive doubles and generators are linear in primitives -> time doubles
    assert b["predicted_ms"] == pytest.approx(2 * a["predicted_ms"], rel=1e-12)


def test_cycles_file_missing_operation_named(tmp_path):
    raw = json.loads(DEFAULT_TABLE.read_text())
    del raw["precisions"]["float"]["cycles"]["exp"]
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(raw))
    with pytest.raises(PfbenchError, match="'exp'"):
        load_table(f)


@pytest.mark.parametrize("content,match", [("{not json", "not valid JSON"),
                                           ('{"float": {"add": -1}}', "non-negative"),
                                           ('{"quad": {"add": 1}}', "no 'float' or 'double'"),
                                           # each of these three was an internal-error traceback
                                           ('{"float": {"add": 1e400}}', "must be a finite non-negative"),
                                           ('{"float": {"add": 1}, "clock_mhz": "fast"}', "clock_mhz must be a finite"),
                                           (b"\xff\xfe\x00binary", "not valid JSON")])
def test_bad_cycles_files(tmp_path, content, match):
    f = tmp_path / "t.json"
    f.write_bytes(content) if isinstance(content, bytes) else f.write_text(content)
    with pytest.raises(PfbenchError, match=match):
        load_table(f)


def test_fit_is_geometric_mean_and_exact_on_consistent_data():
    assert cm._fit([(1.0, 2.0), (2.0, 4.0)]) == pytest.approx(2.0, rel=1e-15)
    assert cm._fit([(1.0, 1.0), (1.0, 4.0)]) == pytest.approx(2.0, rel=1e-15)


def test_calibration_on_table2():
    c = cm.calibrate()
    assert c["n_parameters"] == 2
    assert len(c["cells"]) == 6
    for cell in c["cells"]:
        # the LOO prediction uses the other two cells only
        others = [o for o in c["cells"] if o["precision"] == cell["precision"] and o is not cell]
        eff = math.exp(sum(math.log(o["published_ms"] / o["raw_ms"]) for o in others) / 2)
        assert cell["loo_ms"] == pytest.approx(eff * cell["raw_ms"], rel=1e-12)
        # target of the issue: every Table 2 cell within 15 % when left out
        assert abs(cell["loo_error"]) < 0.15
    # soft-float double is an order of magnitude more expensive than FPU float
    for r in c["ratios"]:
        assert 10 < r["raw_ratio"] < 60


def test_memory_limit_and_largest_np():
    m = Ob1()
    mem = cm.memory_bytes(m, 1000, 1000, "double")
    usable = 192 * 1024 - cm.RAM_RESERVE_BYTES
    hist = (2 * 1 + 1) * 8 * 1000
    assert mem["max_particles"] == (usable - hist) // 24
    cm.check_memory(m, mem["max_particles"], 1000, "double")
    with pytest.raises(PfbenchError, match=f"largest N_p that fits is {mem['max_particles']}"):
        cm.predict("ob1", 1000, mem["max_particles"] + 1, "double")
    # float needs half the bytes per particle
    assert cm.memory_bytes(m, 1000, 1000, "float")["bytes"] * 2 == mem["bytes"]


@pytest.mark.parametrize("kw,match", [(dict(precision="half"), "unknown precision"),
                                      (dict(clock_mhz=-5), "clock must be > 0"),
                                      (dict(clock_mhz=0), "clock must be > 0"),
                                      (dict(board_power_w=-1), "board power"),
                                      (dict(method="multipdf", n_filters=0), "n_filters"),
                                      (dict(model="nope"), "unknown model")])
def test_bad_inputs(kw, match):
    args = dict(model="ob1", n_steps=10, n_particles=10, precision="float") | kw
    with pytest.raises(PfbenchError, match=match):
        cm.predict(**args)


# ---------------------------------------------------------------- two layers: code and board
def test_code_terms_structure(table):
    # each term is its count x its cost: catches a term costed with the wrong count or left out
    counts = {"add": 10, "normal": 4, "tmp": 6, "mm_load": 8, "alloc": 2}
    k = {"constants": {"alloc": {"float": 5.0, "double": 7.0}, "normal": {"float": 3.0, "double": 11.0},
                       "particle_step": {"float": -2.0, "double": 13.0}}}
    t = cm.code_terms(counts, "double", table, 3, 7, k)
    ld, st = table.cost("double", "load"), table.cost("double", "store")
    assert t["table"] == pytest.approx(10 * table.cost("double", "add") + 4 * table.cost("double", "normal"))
    assert t["temporaries"] == 6 * (ld + st)
    assert t["matmul_loads"] == 8 * ld
    assert (t["alloc"], t["normal"], t["particle_step"]) == (14.0, 44.0, 3 * 7 * 13.0)


def test_predict_layers():
    # board (b) = Table-2 efficiency x table cycles, unchanged default; code (a) = sum of its
    # terms with no Table-2 factor; basis picks which one predicted_ms is
    b = cm.predict("ob1", 50, 200, "float")
    c = cm.predict("ob1", 50, 200, "float", basis="code")
    eff = cm.calibrate()["efficiency"]["float"]
    assert b["predicted_ms"] == pytest.approx(eff * b["raw_ms"]) == pytest.approx(b["board_ms"])
    assert c["predicted_ms"] == pytest.approx(c["code_ms"]) == pytest.approx(b["code_ms"])
    assert c["code_cycles_per_particle_step"] == pytest.approx(sum(c["code_terms"].values()))
    assert c["code_terms"]["table"] == pytest.approx(b["raw_cycles"] / (50 * 200))
    assert cm.predict("ob1", 50, 200, "float", calibrated=False)["predicted_ms"] == \
        pytest.approx(b["raw_ms"])
    with pytest.raises(PfbenchError, match="basis"):
        cm.predict("ob1", 50, 200, "float", basis="paper")


def test_code_constants_fitted_on_training_models_only():
    # provenance of the fitted constants: what was emulated (training models only) and on what code
    k = cm.load_code_costs()
    assert set(k["training_models"]) == set(cm.TRAINING_MODELS)
    assert {e["model"] for e in k["emulated"]} == set(cm.TRAINING_MODELS)
    assert set(k["constants"]) == set(cm.CODE_CONSTANTS)
    # derived on the code that is emulated today: a change to the harness, the model compiler,
    # the emulator or the tables must be followed by `python -m pfbench.mcu.costmodel --derive
    # --write` (catches constants left stale by such a change)
    assert k["code_version"]["sha256"] == cm.code_version()["sha256"], \
        "code-layer constants are stale: run python -m pfbench.mcu.costmodel --derive --write"
