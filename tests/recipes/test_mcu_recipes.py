"""The MCU recipes: `embedded:mcu-fit` (largest N_p per core) and `embedded:mcu-models` (cost model
vs emulation per model). Neither reproduces a published number: they record no paper claim, and
their comparisons carry no "paper" value."""
import json

import pandas as pd
import pytest

from pfbench import recipes


def _run(name, tmp_path, **options):
    return recipes.run(recipes.resolve(name), out_root=tmp_path, quiet=True, options=options, seed=0)


def test_mcu_fit_tabulates_every_core_and_precision(tmp_path):
    ctx = _run("embedded:mcu-fit", tmp_path)
    df = pd.read_csv(tmp_path / "embedded" / "mcu_fit.csv")
    cores = df.groupby("model")["core"].nunique()
    assert (cores == 5).all() and set(df.precision) == {"float", "double"}
    assert (tmp_path / "embedded" / "mcu_fit.png").stat().st_size > 0
    assert not ctx.claims and all(c.paper is None for c in ctx.comparisons)


def test_mcu_models_checks_the_cost_model_against_the_emulation(tmp_path):
    if not recipes.needs_met(("mcu-tools",)):
        pytest.skip("needs `make mcu-tools`")
    ctx = _run("embedded:mcu-models", tmp_path, models="ob1,ob4")
    out = json.loads((tmp_path / "embedded" / "mcu_models.data.json").read_text())
    check = out["check"]
    assert check["n_pairs"] == 4 and check["n_held_out"] == 2     # ob1 trains, ob4 is held out
    # the check is computed from the rows, not typed: it agrees with the table
    df = pd.read_csv(tmp_path / "embedded" / "mcu_models.csv")
    assert check["n_within"] == int(df.within_target.sum())
    assert check["met"] == bool(df.within_target.all())
    assert set(out["hand_port"]) == {"float", "double"}
    assert not ctx.claims and all(c.paper is None for c in ctx.comparisons)
