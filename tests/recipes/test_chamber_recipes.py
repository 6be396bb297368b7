"""Recipes embedded:fig6-fig10, tableA1/A2, figA1 on the simulated chamber (fixed seeds) and on a log.

Each qualitative claim of [Embedded] is checked as the property *we measure*, with the paper's
expectation written beside it; where our simulation disagrees the test pins the disagreement
(so a change in behaviour is noticed) and the recipe says so in its ledger.
"""
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pfbench import recipes
from pfbench.plants import chamber
from pfbench.verdicts import VERDICTS

EXAMPLE = Path(__file__).resolve().parents[2] / "reproductions" / "embedded" / "example_log.csv"
OPTS = {"pf_seeds": "1"}


def _run(name, tmp_path, **kw):
    return recipes.run(recipes.resolve(name), out_root=tmp_path, quiet=True, options=OPTS, seed=0, **kw)


def _ledger(ctx):
    return {c.quantity: c for c in ctx.comparisons}


def _claims(ctx):
    """The recorded claims, each with a computed verdict of pfbench.verdicts and its rule."""
    for c in ctx.claims:
        assert c["verdict"] in VERDICTS and c["rule"] and c["where"].startswith("[Embedded]"), c
    assert ctx.claims, "recipe records no claims"
    return ctx.claims


@pytest.mark.parametrize("name", ["fig7", "fig8", "fig9", "fig10", "tableA2", "figA1"])
def test_every_chamber_recipe_records_claims(tmp_path, name):
    _claims(_run(name, tmp_path))


def test_m2_vs_m1_claim_uses_per_seed_differences(tmp_path):
    # two PF seeds: the direction rule gets two paired differences m1 - m2 (one per seed), whose mean
    # is the difference of the recorded seed-averaged RMS errors (catches a claim fed with one number)
    ctx = recipes.run(recipes.resolve("fig9"), out_root=tmp_path, quiet=True, options={"pf_seeds": "2"}, seed=0)
    err = pd.read_csv(tmp_path / "embedded" / "fig9_errors.csv")
    for c in _claims(ctx):
        assert c["n"] == 2
        test = c["claim"].split(" ")[0]
        g = err[err.test == test].set_index("model").rms_eps
        assert c["ours"] == pytest.approx(g["m1"] - g["m2"], abs=1e-12)
        # our plant: model (10) has the lower eq. 13 error, so the paper's direction (m2 lower) fails
        assert c["ours"] < 0 and c["verdict"] in ("disagree", "undecided")


def test_fig6_outputs_and_claims(tmp_path):
    ctx = _run("fig6", tmp_path)
    df = pd.read_csv(tmp_path / "embedded" / "fig6.csv")
    assert {"y", "y_hat_m1", "y_hat_m2", "t_out", "u1", "u2", "mode", "truth"} <= set(df.columns)
    assert (tmp_path / "embedded" / "fig6.png").stat().st_size > 10_000
    m = ctx.extra["metrics"]
    # both estimators track: RMS error vs the true sensor temperature well below 0.1 degC
    assert m["m1"]["rms_true"] < 0.05 and m["m2"]["rms_true"] < 0.1
    # paper (§5.2, Fig. 9): model (12) has the lower eps. We measure the opposite: model (10) with
    # sigma_v^2 = 0.010 on both states nearly copies the measurement (eps ~ 0.005 degC), while model (12)
    # with sigma_v1^2 = 1e-6 is smooth and lags at the heating->cooling switch.
    assert m["m1"]["rms_eps"] < m["m2"]["rms_eps"]
    claims = _claims(ctx)
    # the Fig. 9 ranking is decided per PF seed (direction rule); with one seed it cannot be decided
    ranking = [c for c in claims if "lower error than model (10)" in c["claim"]]
    assert len(ranking) == 1 and ranking[0]["verdict"] == "undecided" and ranking[0]["n"] == 1
    # the mixing bump is a property of the authors' chamber: not reproducible, with our measured bump
    bump = [c for c in claims if "sudden increase" in c["claim"]]
    assert bump[0]["verdict"] == "not reproducible" and "below the 0.0625" in bump[0]["rule"]
    assert ctx.extra["mixing_bump"]["sensor"] < 0.0625
    heat = [c for c in claims if "warmed up" in c["claim"]][0]
    assert heat["verdict"] == "agree"


def test_lower_room_temperature_heats_longer(tmp_path):
    # paper (§5.2): Fig. 6 (room ~19.3 degC) heats to 22.5 degC longer than Figs. 7-8 (~19.6 degC)
    t6 = _run("fig6", tmp_path).extra["heating_time_s"]
    t7 = _run("fig7", tmp_path).extra["heating_time_s"]
    assert t6 > t7


def test_fig10_switches_modes_and_tracks(tmp_path):
    ctx = _run("fig10", tmp_path)
    # paper (§5.3): the PF switches parameter set at every mode change and still tracks
    assert ctx.extra["mode_switches"] >= 4
    assert ctx.extra["metrics"]["m1"]["rms_true"] < 0.05


def test_appendix_grid_claims(tmp_path):
    ctx = _run("tableA1", tmp_path)
    df = pd.read_csv(tmp_path / "embedded" / "tableA1.csv")
    assert len(df) == 14 and set(df.test) >= {"A-1", "C-4", "A-5", "A-6"}
    good = df[~df.test.str.endswith(("-5", "-6"))]
    bad = df[df.test.str.endswith(("-5", "-6"))]
    # paper (§6, Fig. A1): large variances are worse -- we measure the same, vs the truth
    # and vs the measurement (eq. 13)
    assert bad.rms_true.min() > good.rms_true.max()
    assert bad.rms_eps.min() > good.rms_eps.max()
    # paper (§6): sigma_n^2 comparable to the sensor resolution is best. Measured: the best mean RMS
    # error is at sigma_n in [0.03, 0.1] degC, i.e. within a factor 2 of the 0.0625 degC resolution.
    best = df.groupby("var_n").rms_true.mean().idxmin()
    assert 0.03 <= np.sqrt(best) <= 0.1
    assert any("lowest mean RMS error" in c.quantity for c in ctx.comparisons)
    claims = {c["claim"]: c for c in _claims(ctx)}
    # worse than tests 1-4: per-seed direction; with one PF seed undecided (n = 1)
    assert [c["verdict"] for k, c in claims.items() if "too high" in k] == ["undecided", "undecided"]
    # the two readings of "sigma_n^2 comparable to the resolution" are claimed separately and decided by
    # the best sigma_n^2 of the grid: agree exactly for the reading whose nearest grid value is the best
    readings = [c for k, c in claims.items() if "comparable to the resolution" in k]
    assert sorted(c["paper"] for c in readings) == [0.005, 0.1]
    for c in readings:
        assert (c["verdict"] == "agree") == (c["paper"] == best)


def test_tableA2_and_figA1(tmp_path):
    _run("tableA2", tmp_path)
    a2 = pd.read_csv(tmp_path / "embedded" / "tableA2.csv")
    assert sorted(a2.n_particles.unique()) == [100, 500, 1000] and len(a2) == 9
    # paper: model (10) needs enough particles. Measured: N_p = 100 is worse than N_p = 1000 on average
    by = a2.groupby("n_particles").rms_true.mean()
    assert by[100] > by[1000]
    _run("figA1", tmp_path)
    assert (tmp_path / "embedded" / "figA1.png").exists()


def test_fig6_and_fig9_on_a_real_log(tmp_path):
    ctx = _run("fig6", tmp_path, data=EXAMPLE)
    df = pd.read_csv(tmp_path / "embedded" / "fig6.csv")
    assert len(df) == len(pd.read_csv(EXAMPLE)) and df.truth.isna().all()
    assert np.isfinite(ctx.extra["metrics"]["m1"]["rms_eps"])
    _run("fig9", tmp_path, data=EXAMPLE)
    assert (tmp_path / "embedded" / "fig9.png").exists()


def test_bad_log_is_a_one_line_error(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,y,u1\n0,19.5,100\n")
    with pytest.raises(recipes.PfbenchError, match="bad.csv:1: missing column"):
        _run("fig10", tmp_path, data=bad)
