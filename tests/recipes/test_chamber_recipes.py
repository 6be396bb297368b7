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
from pfbench.verdicts import CONSTRUCTION, FINDING, VERDICTS

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


@pytest.mark.parametrize("name", ["fig9", "fig10", "tableA2", "figA1"])
def test_every_chamber_recipe_records_claims(tmp_path, name):
    _claims(_run(name, tmp_path))


def test_each_sentence_is_scored_in_one_recipe_only(tmp_path):
    # the Fig. 9 sentence was once scored six times across figs 6-9; now fig9 scores it once and figs 6-8 record
    # no finding on it (catches a per-figure claim coming back); the mixing bump is recorded by fig6 only
    found = {}
    for name in ("fig6", "fig7", "fig8", "fig9"):
        for c in _run(name, tmp_path).claims:
            if c["kind"] == FINDING:
                found.setdefault((c["claim"], c["where"]), []).append(name)
    assert all(len(v) == 1 for v in found.values()), found
    assert not any("reduced errors for the y_m2 chart" in k[0] for k in found)  # by construction (fig9)


def test_fig9_primary_reading_is_the_literal_one(tmp_path):
    # the literal reading is primary: the y_m2 chart (model (12)) has the reduced errors, (10) - (12) > 0, over the
    # three runs per PF seed; on our plant model (10) is lower, so it cannot agree (it was once scored on the
    # other reading, (12) keeping its error with fewer particles, with a margin of 68 % of that error). That
    # reading is a sensitivity row, its margin 10 % of (12)'s error at N_p = 1000; its mean pairs, per seed,
    # (12)'s RMS eps at N_p = 100 and 1000 on the B-1 log (catches a row fed one number or the wrong pair)
    ctx = recipes.run(recipes.resolve("fig9"), out_root=tmp_path, quiet=True, options={"pf_seeds": "2"}, seed=0)
    err = pd.read_csv(tmp_path / "embedded" / "fig9_errors.csv")
    (c,) = _claims(ctx)
    # by construction: (10) copies the measurement, (12)'s error has the quantisation floor (catches the
    # sentence counted as a finding again)
    assert c["kind"] == CONSTRUCTION and c["n"] == 2 and c["reading"].startswith("the literal reading")
    floor = 0.0625 / np.sqrt(12)
    assert err[err.model == "m1"].rms_eps.max() < floor < err[err.model == "m2"].rms_eps.min()
    g = err[err.test.isin(["B-1", "B2-1", "B3-1"])].groupby("model").rms_eps.mean()
    assert c["ours"] == pytest.approx(g["m1"] - g["m2"], abs=1e-12)
    assert c["ours"] < 0 and c["verdict"] in ("disagree", "undecided")
    fewer = [o for o in c["sensitivity"] if o["reading"].startswith("model (12) keeps its eq. 13 error")]
    assert len(fewer) == 1
    m2 = err[err.model == "m2"].set_index("test").rms_eps
    assert fewer[0]["ours"] == pytest.approx(m2["B-1 log at N_p = 100"] - m2["B-1"], abs=1e-12)
    assert fewer[0]["band"] == pytest.approx([-0.1 * m2["B-1"], 0.1 * m2["B-1"]])
    assert c["depends_on_reading"] == any(o["verdict"] != c["verdict"] for o in c["sensitivity"])


def test_fig6_outputs_and_claims(tmp_path):
    ctx = _run("fig6", tmp_path)
    df = pd.read_csv(tmp_path / "embedded" / "fig6.csv")
    assert {"y", "y_hat_m1", "y_hat_m2", "t_out", "u1", "u2", "mode", "truth"} <= set(df.columns)
    assert (tmp_path / "embedded" / "fig6.png").stat().st_size > 10_000
    m = ctx.extra["metrics"]
    # both estimators track: RMS error vs the true sensor temperature well below 0.1 degC
    assert m["m1"]["rms_true"] < 0.05 and m["m2"]["rms_true"] < 0.1
    # model (10) with sigma_v^2 = 0.010 on both states nearly copies the measurement (eps ~ 0.005 degC), while
    # model (12) with sigma_v1^2 = 1e-6 is smooth and lags at the heating->cooling switch (as the paper's text says)
    assert m["m1"]["rms_eps"] < m["m2"]["rms_eps"]
    claims = _claims(ctx)
    assert not [c for c in claims if "y_m2" in c["claim"] or "lower error" in c["claim"]]
    # the mixing bump is a property of the authors' chamber: not reproducible, with our measured bump
    bump = [c for c in claims if "sudden increase" in c["claim"]]
    assert bump[0]["verdict"] == "not reproducible" and "below the 0.0625" in bump[0]["rule"]
    assert ctx.extra["mixing_bump"]["sensor"] < 0.0625
    # the heating time is fixed by the plant (a colder start needs longer): shown, never scored
    heat = [c for c in claims if "warmed up" in c["claim"]][0]
    assert heat["kind"] == CONSTRUCTION and heat["note"]


def test_lower_room_temperature_heats_longer(tmp_path):
    # paper (§5.2): Fig. 6 (room ~19.3 degC) heats to 22.5 degC longer than Figs. 7-8 (~19.6 degC)
    t6 = _run("fig6", tmp_path).extra["heating_time_s"]
    t7 = _run("fig7", tmp_path).extra["heating_time_s"]
    assert t6 > t7


def test_fig10_switches_modes_and_tracks(tmp_path):
    # two PF seeds: the tracking rule needs at least two runs for an interval
    ctx = recipes.run(recipes.resolve("fig10"), out_root=tmp_path, quiet=True, options={"pf_seeds": "2"}, seed=0)
    # paper (§5.3): the PF switches parameter set at every mode change and still tracks
    assert ctx.extra["mode_switches"] >= 4
    assert ctx.extra["metrics"]["m1"]["rms_true"] < 0.05
    claims = _claims(ctx)
    assert [c["kind"] for c in claims if "Switching" in c["claim"]] == [CONSTRUCTION]
    # one sentence, one finding: the worse of the two models decides, each model alone is a sensitivity row
    (track,) = [c for c in claims if "tracks" in c["claim"]]
    worse = max(ctx.extra["metrics"]["m1"]["rms_eps"], ctx.extra["metrics"]["m2"]["rms_eps"])
    assert track["ours"] == pytest.approx(worse) and track["band"] == [0.0, chamber.RESOLUTION]
    assert track["n"] == 2 and len(track["sensitivity"]) == 2


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
    claims = {c["claim"]: c for c in _claims(ctx)}
    # worse than tests 1-4: per-seed direction on eq. 13; with one PF seed undecided (n = 1)
    high = [c for k, c in claims.items() if "too high" in k or "overly high" in k]
    assert [c["verdict"] for c in high] == ["undecided", "undecided"] and all(c["sensitivity"] for c in high)
    # "cannot match the measurements" is worse by more than half a sensor step (an excess of 3 % of a step
    # agreed); "limits the confidence in the measurement" is a direction
    assert high[0]["quantity"].endswith("minus half a sensor step (0.03125 °C), per PF seed [°C]")
    assert "half a sensor step" not in high[1]["quantity"]
    # decided by our plant's mismatch and noise (guessed): not reproducible, never a reading built to fail
    sn = [c for k, c in claims.items() if "comparable to the resolution" in k]
    sv = [c for k, c in claims.items() if "lower process-noise variance" in k]
    assert len(sn) == 1 and len(sv) == 1
    assert sn[0]["verdict"] == sv[0]["verdict"] == "not reproducible"
    # both readings of "comparable to the resolution" are still computed and shown, over tests 1-4 only
    near = [c for c in ctx.comparisons if c.quantity.startswith("grid σn² of tests 1-4 nearest")]
    assert sorted(c.ours for c in near) == [0.005, 0.01]
    assert any("lowest mean RMS error" in c.quantity for c in ctx.comparisons)


def test_tableA2(tmp_path):
    _run("tableA2", tmp_path)
    a2 = pd.read_csv(tmp_path / "embedded" / "tableA2.csv")
    assert sorted(a2.n_particles.unique()) == [100, 500, 1000] and len(a2) == 9
    # paper: model (10) needs enough particles. Measured: N_p = 100 is worse than N_p = 1000 on average
    by = a2.groupby("n_particles").rms_true.mean()
    assert by[100] > by[1000]


def test_np_sentence_is_one_finding(tmp_path):
    (c,) = [c for c in _claims(_run("tableA2", tmp_path)) if "number of particles" in c["claim"]]
    assert c["reading"] and {o["reading"] for o in c["sensitivity"]} >= {"N_p = 500 worse than N_p = 1000"}


def test_figA1_every_panel_is_labelled(tmp_path, monkeypatch):
    # the 20 panels of Fig. A1 each carry axis labels with units and a title naming the test (catches a panel
    # drawn without pfbench.plotting.label)
    figs = {}
    orig = recipes.RecipeContext.write_figure

    def keep(self, name, fig):
        figs[name] = fig
        return orig(self, name, fig)

    monkeypatch.setattr(recipes.RecipeContext, "write_figure", keep)
    _run("figA1", tmp_path)
    axes = [ax for ax in figs["figA1"].axes if ax.axison]
    assert len(axes) == 20
    for ax in axes:
        assert "[s]" in ax.get_xlabel() and "[°C]" in ax.get_ylabel()
        assert "σv²=" in ax.get_title() and "°C" in ax.get_title()


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
