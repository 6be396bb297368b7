"""Strict RFC 8259 JSON everywhere: non-finite numbers become null with a "<key>_nonfinite"
note (pfbench.io), parsed here with a parser that rejects NaN/Infinity."""
import json
import math

import pytest
from click.testing import CliRunner

from pfbench import io, recipes
from pfbench.cli import main
from pfbench.errors import DataError


def _strict_loads(text):
    def refuse(name):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(text, parse_constant=refuse)


def _invoke(*args):
    return CliRunner().invoke(main, list(args))


def test_run_json_with_minus_inf_loglik_is_strict_json():
    # q=1e300: every particle weight underflows, loglik = -inf. Before: "loglik": -Infinity.
    r = _invoke("run", "--model", "ob1", "--param", "q=1e300", "--steps", "30", "--particles", "50",
                "--backend", "numpy", "--json")
    assert r.exit_code == 0, r.output
    out = _strict_loads(r.stdout)
    assert out["loglik"] is None
    assert out["loglik_nonfinite"].startswith("-inf") and "degenerate" in out["loglik_nonfinite"]
    assert out["n_degenerate_steps"] > 0
    for args in (["list", "--json"], ["info", "--json"]):     # the other --json outputs
        r = _invoke(*args)
        assert r.exit_code == 0
        _strict_loads(r.stdout)


def test_strict_conversion_convention():
    import numpy as np

    obj = {"a": float("nan"), "b": [1.0, float("inf"), np.float64("-inf")],
           "c": {"d": np.array([0.5, np.nan])}, "e": float("-inf"), "e_nonfinite": "-inf: a reason",
           "f": 2.5, "g": np.int64(3)}
    out = _strict_loads(io.to_json(obj))
    assert out == {"a": None, "a_nonfinite": "nan", "b": [1.0, None, None],
                   "b_nonfinite": "inf at [1]; -inf at [2]", "c": {"d": [0.5, None],
                                                                  "d_nonfinite": "nan at [1]"},
                   "e": None, "e_nonfinite": "-inf: a reason", "f": 2.5, "g": 3}
    assert _strict_loads(io.to_json([float("nan")])) == [None]
    with pytest.raises(DataError):
        io.loads('{"x": NaN}', "f.json")


def test_results_files_are_strict_json(tmp_path, monkeypatch):
    # A recipe whose numbers are non-finite: its provenance record and .data.json stay valid.
    recipes.discover()
    monkeypatch.setattr(recipes, "_REGISTRY", dict(recipes._REGISTRY))

    @recipes.recipe("thesis:zz-nan", title="non-finite numbers")
    def zz(ctx):
        ctx.compare("loglik", ours=-math.inf, paper=-10.0)
        ctx.write_json("zz-nan", {"loglik": float("nan"), "x": [1.0, math.inf]})

    r = _invoke("reproduce", "thesis:zz-nan", "--out", str(tmp_path), "--quiet")
    assert r.exit_code == 0, r.output
    rec = _strict_loads((tmp_path / "thesis" / "zz-nan.json").read_text())
    assert rec["comparisons"][0]["ours"] is None and rec["comparisons"][0]["ours_nonfinite"] == "-inf"
    data = _strict_loads((tmp_path / "thesis" / "zz-nan.data.json").read_text())
    assert data == {"loglik": None, "loglik_nonfinite": "nan", "x": [1.0, None],
                    "x_nonfinite": "inf at [1]"}
    assert _invoke("report", "--out", str(tmp_path)).exit_code == 0
    assert "| loglik | -inf | -10 |" in (tmp_path / "thesis" / "REPORT.md").read_text()
