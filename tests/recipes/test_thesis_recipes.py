"""Thesis recipes run end-to-end on tiny configurations and record claims with computed verdicts."""
import json
import re
import math

import numpy as np
import pytest

from pfbench.recipes import resolve, run
from pfbench.verdicts import AGREE, VERDICTS

TINY = [
    ("thesis:fig2.2", {"steps": "10"}), ("thesis:fig2.3", {"steps": "10"}),
    ("thesis:fig2.4", {"runs": "5", "particles": "20"}),
    ("thesis:fig4.7", {"runs": "2", "particles": "15,10"}),
    ("thesis:fig4.9", {"runs": "3", "particles": "15"}),
    ("thesis:fig4.6", {"runs": "2", "points": "2"}),
    ("thesis:fig4.5", {}), ("thesis:fig4.1", {}), ("thesis:fig4.2", {}), ("thesis:fig4.3", {}),
    ("thesis:fig4.4", {}),
]


@pytest.mark.parametrize("rid,opts", TINY)
def test_recipe_records_claims_with_verdicts(tmp_path, rid, opts):
    ctx = run(resolve(rid), out_root=tmp_path, quiet=True, options=opts)
    rec = json.loads((tmp_path / "thesis" / f"{rid.split(':')[1]}.json").read_text())
    assert rec["claims"], "every thesis recipe records the paper's claims it tests"
    for c in rec["claims"]:
        assert c["verdict"] in VERDICTS and c["rule"] and c["where"].startswith("[Thesis]")
    assert ctx.claims == rec["claims"] or len(ctx.claims) == len(rec["claims"])


def test_fig4_9_runs_both_readings_and_both_maxima(tmp_path):
    ctx = run(resolve("thesis:fig4.9"), out_root=tmp_path, quiet=True,
              options={"runs": "3", "particles": "15"})
    q = [c["quantity"] for c in ctx.claims]
    for prior in ("uniform", "equidistant"):
        for m in ("mean", "sample", "max", "max_weight"):
            assert f"failure rate, {prior} initial particles, PI on {m}" in q
        assert sum(prior in x and "loss(" in x for x in q) == 4      # 2 others x 2 maxima
    assert (tmp_path / "thesis" / "fig4.9.png").exists()
    assert (tmp_path / "thesis" / "fig4.9_equidistant.png").exists()


def test_fig2_4_sweeps_observation_and_particles(tmp_path):
    ctx = run(resolve("thesis:fig2.4"), out_root=tmp_path, quiet=True,
              options={"runs": "4", "particles": "10,20", "steps": "8"})
    q = [c["quantity"] for c in ctx.claims]
    assert len(q) == 2 * 2 * 2
    assert any("x^2/20" in x and "N = 20" in x for x in q)


def test_mse_reduction_and_its_standard_error():
    from reproductions.thesis.ch2 import mse_reduction

    b = np.array([1.0, 2.0, 3.0, 4.0])
    red, se = mse_reduction(b, 0.5 * b)                       # a = R b exactly: no spread
    assert red == pytest.approx(0.5) and se == pytest.approx(0.0, abs=1e-15)
    a = np.array([0.4, 1.1, 1.4, 2.1])
    red, se = mse_reduction(b, a)
    R = a.mean() / b.mean()
    assert red == pytest.approx(1 - R)
    assert se == pytest.approx(np.std(a - R * b, ddof=1) / 2 / b.mean())


def test_quadratic_reading_observes_x_squared_over_20():
    from reproductions.thesis.ch2 import ThesisExampleQuadratic

    m = ThesisExampleQuadratic()
    p = m.params()
    x = np.array([[0.0], [2.0], [-2.0]])
    ll = m.log_likelihood(np.array([0.2]), x, None, 1, p)     # y = 0.2 = 2^2 / 20
    assert ll[1] == pytest.approx(ll[2]) and ll[1] > ll[0]
    assert ll[1] == pytest.approx(-math.log(0.05) - 0.5 * math.log(2 * math.pi))
    assert type(m.without_outlier()) is ThesisExampleQuadratic


def test_tables_match_the_document(tmp_path):
    for rid in ("thesis:table4.1", "thesis:table4.2"):
        ctx = run(resolve(rid), out_root=tmp_path, quiet=True)
        assert not ctx.claims   # parameter rows are comparisons, not scorecard claims
        verdicts = [re.search(r"\): (agree|disagree|undecided|not reproducible), ", c.note).group(1)
                    for c in ctx.comparisons if c.note]
        assert verdicts and set(verdicts) <= {AGREE, "not reproducible"}, verdicts
