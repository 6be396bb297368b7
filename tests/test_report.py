"""`pfbench report`: the scorecard counts computed verdicts per paper, figures are inline, the same
data comes as JSON; `reproduce --all` skips results that are up to date (how `make full` resumes)."""
import dataclasses
import json

import pytest
from click.testing import CliRunner

from pfbench import recipes, report, verdicts
from pfbench.cli import main

TINY = {"steps": 8}


def _with_claims(rec):
    def func(ctx):
        rec.func(ctx)
        ctx.claim("A beats B", "[Thesis] §0", "paired difference", verdicts.direction([1.0, 1.1, 0.9, 1.2]))
        ctx.claim("a rate", "[Thesis] §0", "failures", verdicts.proportion(1, 10, 0.08, 0.02))
        ctx.claim("measured data", "[Thesis] §0", "-", verdicts.not_reproducible("the data are lost"))
    return dataclasses.replace(rec, func=func)


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("results")
    rec = _with_claims(recipes.resolve("thesis:fig2.2"))
    recipes.run(rec, out_root=root, quiet=True, options=TINY)
    return root


def test_scorecard_counts_the_computed_verdicts(results):
    card = report.scorecard(report.check_results(results)[0])
    assert card["thesis"]["agree"] >= 1 and card["thesis"]["undecided"] >= 1
    assert card["thesis"]["not reproducible"] >= 1
    assert card["thesis"]["claims"] == sum(card["thesis"][k] for k in verdicts.VERDICTS)
    assert card["rtd"]["claims"] == 0
    assert card["thesis"]["modes"] == ["quick"] and card["thesis"]["recipes"] == 1


def test_report_opens_with_the_scorecard_and_shows_figures_inline(results):
    path, _ = report.write_report(results)
    text = path.read_text()
    assert text.index("## Contents") < text.index("## Scorecard") < text.index("## What the words mean")
    assert "[thesis](thesis/REPORT.md)" in text
    for word in (*verdicts.VERDICTS, *verdicts.KINDS):
        assert f"- **{word}**: " in text
    paper = (results / "thesis" / "REPORT.md").read_text()
    assert "![thesis:fig2.2: fig2.2.png](fig2.2.png)" in paper and "(../REPORT.md)" in paper
    assert "**agree**" in paper and "95 % t-interval" in paper


def test_each_result_says_how_busy_the_machine_was(results):
    """Timing claims depend on the load: every record keeps the load averages when it was written
    and the report prints them beside the recipe. Catches the load not recorded or not shown."""
    rec = report.check_results(results)[0][0]
    load = rec["host"]["load_average"]
    assert len(load) == 3 and all(v >= 0 for v in load)
    report.write_report(results)
    text = (results / "thesis" / "REPORT.md").read_text()
    assert f"load average {load[0]:g}/{load[1]:g}/{load[2]:g} (1/5/15 min)" in text


def test_report_json_is_the_same_data_and_writes_nothing(results):
    """Catches `report --json` rewriting REPORT.md (it prints the data only)."""
    before = {p: p.stat().st_mtime_ns for p in results.rglob("REPORT.md")}
    (results / "REPORT.md").unlink(missing_ok=True)
    r = CliRunner().invoke(main, ["report", "--out", str(results), "--json"])
    assert not (results / "REPORT.md").exists()
    assert all(p.stat().st_mtime_ns == t for p, t in before.items() if p.exists())
    data = json.loads(r.stdout.splitlines()[0], parse_constant=lambda c: pytest.fail(c))
    assert data["scorecard"] == report.scorecard(report.check_results(results)[0])
    claims = data["recipes"]["thesis:fig2.2"]["claims"]
    assert {c["verdict"] for c in claims} >= {verdicts.AGREE, verdicts.NOT_REPRODUCIBLE}


def test_claims_need_computed_outcomes(results, tmp_path):
    rec = recipes.resolve("thesis:fig2.2")

    def typed_verdict(ctx):
        ctx.claim("x", "y", "z", "agree")          # a hand-typed verdict string is a bug

    with pytest.raises(TypeError):
        recipes.run(dataclasses.replace(rec, func=typed_verdict), out_root=tmp_path, quiet=True)


def test_up_to_date_only_for_the_same_code_settings_and_intact_files(results):
    rec = recipes.resolve("thesis:fig2.2")
    kw = dict(out_root=results, full=False, seed=0, backend="numba", options=TINY)
    assert recipes.up_to_date(rec, **kw)
    assert not recipes.up_to_date(rec, **dict(kw, seed=1))
    assert not recipes.up_to_date(rec, **dict(kw, full=True))
    assert not recipes.up_to_date(rec, **dict(kw, options={"steps": 9}))
    csv = results / "thesis" / "fig2.2.csv"
    csv.write_text(csv.read_text() + "\n")
    assert not recipes.up_to_date(rec, **kw)          # a changed artefact is redone


def test_table_cells_escape_pipes():
    """A rule such as "|ours - paper| <= 10 %" must not split its Markdown table row."""
    row = report._claims_table([{"claim": "max |e| small", "where": "w", "quantity": "q", "ours": 1.0,
                                 "verdict": "agree", "rule": "|ours - paper| <= 10 %"}])[2]
    assert row.replace("\\|", "").count("|") == 10


def test_compare_lists_the_verdicts_that_changed(results, tmp_path):
    """`report --compare OTHER`: the claims whose verdict differs between two result sets (how the
    closing note of a paper-scale run lists what changed against quick mode). Catches claims matched
    by position instead of by (recipe, claim, where, quantity), and unchanged claims listed."""
    rec = recipes.resolve("thesis:fig2.2")

    def func(ctx):
        rec.func(ctx)
        ctx.claim("A beats B", "[Thesis] §0", "paired difference", verdicts.direction([1.0, -1.1, 0.9, -1.2]))
        ctx.claim("measured data", "[Thesis] §0", "-", verdicts.not_reproducible("the data are lost"))

    recipes.run(dataclasses.replace(rec, func=func), out_root=tmp_path, quiet=True, options=TINY)
    cmp = report.compare_verdicts(report.check_results(results)[0], tmp_path)
    assert cmp["transitions"] == {"undecided -> agree": 1}
    [c] = cmp["changed"]
    assert (c["claim"], c["before"], c["after"]) == ("A beats B", "undecided", "agree")
    assert cmp["only_here"] == 1 and cmp["only_there"] == 0  # "a rate" is in one set only
    r = CliRunner().invoke(main, ["report", "--out", str(results), "--compare", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert "1 changed verdict; undecided -> agree: 1" in r.output
    assert "## Verdicts against" in (results / "REPORT.md").read_text()


def _run_claims(tmp_path, claims):
    """Run a tiny recipe that records ``claims(ctx)`` and return the scorecard of its result."""
    rec = recipes.resolve("thesis:fig2.2")

    recipes.run(dataclasses.replace(rec, func=claims), out_root=tmp_path, quiet=True)
    return report.scorecard(report.check_results(tmp_path)[0])["thesis"]


def test_only_findings_are_scored(tmp_path):
    """Setup checks and claims true by construction are shown, never counted as agreement. Catches
    a scorecard that counts every claim, and a by-construction claim without its reason."""
    def claims(ctx):
        ctx.claim("A beats B", "[Thesis] §0", "d", verdicts.direction([1.0, 1.1, 0.9, 1.2]))
        ctx.claim("the model is second order", "[Thesis] eq. 1", "degree", verdicts.holds(True, "degree 2"),
                  kind=verdicts.SETUP)
        ctx.claim("one is always farther", "[Thesis] §0", "share", verdicts.holds(True, "always"),
                  kind=verdicts.CONSTRUCTION, note="the triangle inequality makes it true")

    card = _run_claims(tmp_path, claims)
    assert card["claims"] == 1 and card["agree"] == 1
    assert card["setup checks"] == 1 and card["setup checks holding"] == 1 and card["by construction"] == 1
    paper = report.write_report(tmp_path)[0].parent / "thesis" / "REPORT.md"
    text = paper.read_text()
    assert text.index("Findings (scored)") < text.index("Setup checks") < text.index("True by construction")
    rec = recipes.resolve("thesis:fig2.2")
    no_reason = dataclasses.replace(rec, func=lambda ctx: ctx.claim(
        "x", "y", "z", verdicts.holds(True, "t"), kind=verdicts.CONSTRUCTION))
    with pytest.raises(ValueError, match="reason"):
        recipes.run(no_reason, out_root=tmp_path / "b", quiet=True)


def test_one_sentence_is_one_finding_with_other_readings_beneath(tmp_path):
    """A sentence scored twice is a bug; other readings are sensitivity rows, and the claim says
    "depends on reading" only when their verdicts differ. Catches counting readings as findings."""
    agree = verdicts.direction([1.0, 1.1, 0.9, 1.2])
    against = verdicts.direction([-1.0, -1.1, -0.9, -1.2])

    def claims(ctx):
        ctx.claim("max beats mean", "[Thesis] Fig. 4.9", "loss", agree, reading="the max-weight particle",
                  others=[verdicts.Reading("the kernel-density maximum", "loss (kde)", agree)])
        ctx.claim("fewer particles lose more", "[Thesis] Fig. 4.7", "loss", agree, reading="panel 1 first",
                  others=[verdicts.Reading("panels swapped", "loss (swapped)", against)])

    card = _run_claims(tmp_path, claims)
    assert card["claims"] == 2 and card["depends on reading"] == 1
    claims_ = report.check_results(tmp_path)[0][0]["claims"]
    assert [c["depends_on_reading"] for c in claims_[-2:]] == [False, True]
    report.write_report(tmp_path)
    text = (tmp_path / "thesis" / "REPORT.md").read_text()
    assert "↳ other reading: panels swapped" in text and "(depends on reading)" in text
    rec = recipes.resolve("thesis:fig2.2")

    def twice(ctx):
        ctx.claim("s", "w", "q1", agree)
        ctx.claim("s", "w", "q2", agree)

    with pytest.raises(RuntimeError, match="twice"):
        recipes.run(dataclasses.replace(rec, func=twice), out_root=tmp_path / "b", quiet=True)
    with pytest.raises(ValueError, match="primary"):
        recipes.run(dataclasses.replace(rec, func=lambda ctx: ctx.claim(
            "s", "w", "q", agree, others=[verdicts.Reading("r", "q", agree)])), out_root=tmp_path / "c", quiet=True)


def test_a_sentence_scored_by_two_recipes_counts_once(tmp_path):
    rec2, rec3 = recipes.resolve("thesis:fig2.2"), recipes.resolve("thesis:fig2.3")
    claim = lambda ctx: ctx.claim("model 12 reduces errors", "[Thesis] §0", "q", verdicts.holds(True, "t"))
    for rec in (rec2, rec3):
        recipes.run(dataclasses.replace(rec, func=claim), out_root=tmp_path, quiet=True)
    records = report.check_results(tmp_path)[0]
    assert report.scorecard(records)["thesis"]["claims"] == 1
    [p] = report.scored_findings(records)[1]
    assert "scores the sentence" in p.what and not p.damaged


def test_scorecard_states_the_multiplicity(tmp_path):
    def claims(ctx):
        ctx.claim("A beats B", "[Thesis] §0", "d", verdicts.direction([1.0, 1.1, 0.9, 1.2]))

    assert _run_claims(tmp_path, claims)["interval decisions"] == 1
    text = report.write_report(tmp_path)[0].read_text()
    assert "1 of the agree/disagree verdicts are decisions from a 95 % interval" in text
    assert "at most about 0.1 of them are expected to be wrong by chance" in text


def test_no_claim_agrees_with_an_interval_that_leaves_its_band(tmp_path):
    """The rules cannot produce it; an Outcome built by hand that does (the old overlap rule's
    'agree' on 9/100 against 2 % ± 3 %) is refused when recorded."""
    rec = recipes.resolve("thesis:fig2.2")
    overlap = verdicts.Outcome(verdicts.AGREE, "overlap", 0.09, (0.048, 0.162), 100, (0.0, 0.05))
    with pytest.raises(RuntimeError, match="leaves its band"):
        recipes.run(dataclasses.replace(rec, func=lambda ctx: ctx.claim("rate", "w", "q", overlap)),
                    out_root=tmp_path, quiet=True)


def test_report_on_a_missing_folder_is_refused_and_creates_nothing(tmp_path):
    """A mistyped --out made a folder with a report of every recipe "not run", exit 0. Catches the
    check dropped."""
    r = CliRunner().invoke(main, ["report", "--out", str(tmp_path / "nosuch")])
    assert r.exit_code == 2 and "no such results folder" in r.stderr
    assert not (tmp_path / "nosuch").exists()
