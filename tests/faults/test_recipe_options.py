"""Every recipe option declares its type and range (:mod:`pfbench.ranges`), and a value outside it
is one ``error:`` line, exit 2, before any work: walked over every registered recipe."""
import json

import pytest
from click.testing import CliRunner

from pfbench import recipes
from pfbench.cli import main
from pfbench.errors import InputError
from pfbench.ranges import ListOf, ModelSpec, OneOf, Range, above, at_least


def _refused(tmp_path, rec_id, text):
    """``reproduce rec_id --option text`` is one error line, exit 2, and nothing was written."""
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["reproduce", rec_id, "--option", text, "--out", str(out), "--quiet"])
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error:"), (rec_id, text, r.output)
    assert not out.exists(), (rec_id, text)             # refused before any work
    return lines[0]


def _number(value, kind):
    return json.dumps(int(value) if kind is int else float(value))


def _outside(rule, kind) -> list[str]:
    """Option texts just outside ``rule`` (values of the right type, so the rule must refuse them)."""
    if rule is None:                    # the items of a list of any text
        return []
    if isinstance(rule, Range):
        bad = []
        if rule.low is not None:
            bad.append(_number(rule.low if rule.low_open else rule.low - 1, kind))
        if rule.high is not None:
            bad.append(_number(rule.high if rule.high_open else rule.high + 1, kind))
        return bad
    if isinstance(rule, OneOf):
        return ["zz-no-such-choice"]
    if isinstance(rule, ModelSpec):
        return ["zz-no-such-model"]
    if isinstance(rule, ListOf):
        ok = {int: "1", float: "1.0", str: "x"}[rule.item]
        bad = ["", f"{ok},{ok}"]                                   # no items; an item twice
        bad += [f"[{json.dumps(b) if rule.item is str else b}]" for b in _outside(rule.rule, rule.item)]
        if rule.max_items is not None:
            bad.append(",".join(str(i) for i in range(rule.max_items + 1)))
        return bad
    raise AssertionError(f"unknown rule {rule!r}")


CASES = [(rec.id, o.key, text) for rec in recipes.discover().values() for o in rec.options
         for text in (_outside(o.rule, o.type) if o.rule is not None else [])]


def test_every_recipe_option_declares_type_and_range():
    """Catches a recipe option declared without a type or rule (e.g. ``"steps": (int, "help")``)."""
    missing = [(rec.id, o.key) for rec in recipes.discover().values() for o in rec.options
               if o.type is None or o.rule is None]
    assert not missing
    assert len(CASES) > 100


@pytest.mark.parametrize("rec_id,key,text", CASES, ids=[f"{r}-{k}={t}" for r, k, t in CASES])
def test_out_of_range_option_is_refused_before_work(tmp_path, rec_id, key, text):
    """Catches a rule that is declared but not applied before the recipe runs."""
    assert f"--option {key}=" in _refused(tmp_path, rec_id, f"{key}={text}")


@pytest.mark.parametrize("rec_id,text,needle", [
    ("rtd:fig5", "Q=-1", ">= 0"),             # before: ValueError: array must not contain infs or NaNs
    ("rtd:fig6", "gain=0", "> 0"),            # before: TypeError in a format string
    ("thesis:fig4.1", "run=-1", ">= 0"),      # before: ValueError: expected non-negative integer
    ("thesis:fig4.3", "t_end=0", ">="),       # before: IndexError on an empty window
    ("embedded:fig6", "pf_seeds=0", ">= 1"),  # before: IndexError: list index out of range
    ("rtd:fig5", "model=eq53", "eq52, eq54"),
    ("thesis:fig2.4", "particles=50,0", "item 0"),
    ("thesis:fig2.4", "observations=linear,cubic", "linear, quadratic"),
    ("thesis:fig4.5", "streams=1", "2 items"),
    ("multipdf:fig11", "r_scale=1,,10", "empty item"),
])
def test_issue_cases_are_one_line(tmp_path, rec_id, text, needle):
    """The values the issue found ending in a traceback; catches a range declared too wide."""
    assert needle in _refused(tmp_path, rec_id, text)


def test_options_command_shows_the_range():
    r = CliRunner().invoke(main, ["options", "rtd:fig5"])
    assert r.exit_code == 0 and "Q" in r.stdout and ">= 0" in r.stdout and "one of eq52, eq54" in r.stdout
    r = CliRunner().invoke(main, ["list", "--json"])
    opts = {d["id"]: d["options"] for d in json.loads(r.stdout)}
    assert opts["rtd:fig6"]["gain"]["range"] == "> 0"


def test_rules():
    """Bounds, open and closed; lists typed item by item; catches an off-by-one at a bound."""
    assert at_least(1).contains(1) and not at_least(1).contains(0)
    assert not above(0).contains(0) and above(0).contains(1e-300)
    assert Range(0, 1, high_open=True).contains(0) and not Range(0, 1, high_open=True).contains(1)
    assert str(Range(0, 1, low_open=True)) == "in (0, 1]" and str(Range()) == "any finite"
    rule = ListOf(int, at_least(1), max_items=2)
    assert rule.check("10, 20", "x") == [10, 20] and rule.check(5, "x") == [5] and rule.check([3], "x") == [3]
    for bad in ("10,2.5", "a", "1,2,3", "0", "[]", ","):
        with pytest.raises(InputError):
            rule.check(bad if bad != "[]" else [], "x")


def test_declaration_without_a_matching_rule_is_a_bug():
    with pytest.raises(ValueError):
        recipes._declare({"n": (int, "count", OneOf("a"))})
    with pytest.raises(ValueError):
        recipes._declare({"xs": (list, "counts", at_least(1))})


def test_a_bound_set_by_another_option_is_one_line(tmp_path):
    """thesis:fig2.3 threshold is a particle count, at most particles (was: a ValueError deep in
    the filter for 0, and for more than particles)."""
    r = CliRunner().invoke(main, ["reproduce", "thesis:fig2.3", "--option", "particles=10", "--option",
                                  "threshold=11", "--out", str(tmp_path), "--quiet"])
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.exit_code == 2 and lines == ["error: --option threshold=11: must be at most particles (10)"]
