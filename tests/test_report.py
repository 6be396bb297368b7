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


def test_report_opens_with_the_scorecard_and_shows_figures_inline(results):
    path, _ = report.write_report(results)
    text = path.read_text()
    assert text.index("## Scorecard") < text.index("## thesis")
    assert "![thesis:fig2.2: fig2.2.png](thesis/fig2.2.png)" in text
    assert "**agree**" in text and "95 % t-interval" in text


def test_each_result_says_how_busy_the_machine_was(results):
    """Timing claims depend on the load: every record keeps the load averages when it was written
    and the report prints them beside the recipe. Catches the load not recorded or not shown."""
    rec = report.check_results(results)[0][0]
    load = rec["host"]["load_average"]
    assert len(load) == 3 and all(v >= 0 for v in load)
    path, _ = report.write_report(results)
    assert f"load average {load[0]:g}/{load[1]:g}/{load[2]:g} (1/5/15 min)" in path.read_text()


def test_report_json_is_the_same_data(results):
    r = CliRunner().invoke(main, ["report", "--out", str(results), "--json"])
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
    assert row.replace("\\|", "").count("|") == 9


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
