"""Every multipdf recipe runs end to end on a tiny configuration and writes its outputs."""
import json

import pandas as pd
import pytest

from pfbench import recipes

TINY = {"runs": 2, "workers": 1, "steps": 300, "repeats": 1}
IDS = ["fig3", "fig4", "fig5", "fig6", "fig7", "fig8", "fig9", "fig10", "fig11", "table4",
       "table6", "table7", "fig12", "fig13"]


@pytest.fixture(scope="module")
def out_root(tmp_path_factory):
    return tmp_path_factory.mktemp("results")


@pytest.mark.parametrize("name", IDS)
def test_recipe_tiny(name, out_root):
    rec = recipes.resolve(f"multipdf:{name}")
    opts = {k: v for k, v in TINY.items() if k in rec.option_keys}  # unknown keys are refused
    ctx = recipes.run(rec, out_root=out_root, quiet=True, options=opts)
    prov = json.loads((out_root / "multipdf" / f"{name}.json").read_text())
    assert prov["recipe"] == f"multipdf:{name}"
    assert ctx.comparisons, "every recipe states the paper's claim next to ours"
    csv = out_root / "multipdf" / f"{name}.csv"
    assert csv.is_file()
    df = pd.read_csv(csv)
    assert len(df) > 0
    if name.startswith("fig") and name not in ("fig12", "fig13"):
        assert (out_root / "multipdf" / f"{name}.png").is_file()
        assert (df["runs"] == 2).all()
        assert df["armse_mean"].gt(0).all()
    if name == "table7":
        pct = df.set_index("event")["percent"]
        assert pct["d_MultiPDF < max(d_PF[1..3])"] >= pct["d_MultiPDF < min(d_PF[1..3])"]
