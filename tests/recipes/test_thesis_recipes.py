"""Thesis recipes run end-to-end on tiny configurations."""
import json

import pytest

from pfbench.recipes import resolve, run


@pytest.mark.parametrize("rid,opts", [
    ("thesis:fig2.2", {"steps": "10"}), ("thesis:fig2.3", {"steps": "10"}),
    ("thesis:fig2.4", {"runs": "5"}), ("thesis:fig4.7", {"runs": "2", "particles": "15"}),
])
def test_recipe_tiny(tmp_path, rid, opts):
    ctx = run(resolve(rid), out_root=tmp_path, quiet=True, options=opts)
    rec = json.loads((tmp_path / "thesis" / f"{rid.split(':')[1]}.json").read_text())
    assert rec["comparisons"] and all((tmp_path / "thesis").glob("*.png"))
    assert ctx.comparisons[0].ours is not None
