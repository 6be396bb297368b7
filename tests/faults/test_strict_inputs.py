"""Strict inputs: unknown --param/--option keys list the valid ones with a "did you mean";
badly typed or NaN values name the option; selectors that match nothing are errors."""
import pytest
from click.testing import CliRunner

from pfbench import models
from pfbench.cli import main
from pfbench.errors import InputError
from pfbench.options import typed


def _error(*args):
    r = CliRunner().invoke(main, list(args))
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in r.stderr, r.stderr
    return lines[0]


RUN = ["run", "--model", "ob1", "--steps", "3", "--particles", "10", "--backend", "numpy"]


@pytest.mark.parametrize("param,needles", [
    ("qq=2", ["--param qq", "valid keys: q, r, x0", "did you mean q?"]),
    ("q=abc", ["--param q=abc", "expected a number"]),           # before: "'<=' not supported ..."
    ("q=nan", ["--param q=nan", "expected a number"]),
    ("x0=true", ["--param x0=true", "expected a number"]),
])
def test_param_keys_and_values(param, needles):
    line = _error(*RUN, "--param", param)
    for n in needles:
        assert n in line, line


def test_param_version_must_be_an_integer():
    assert "expected an integer" in _error("run", "--model", "ob3", "--param", "version=2.5",
                                           "--steps", "3", "--backend", "numpy")


def test_unknown_param_is_refused_before_construction(monkeypatch):
    cls = models.model_class("ob1")
    built = []
    monkeypatch.setattr(cls, "__init__", lambda self, q=10.0, r=1.0, x0=0.1: built.append(1))
    with pytest.raises(InputError, match="did you mean r"):
        models.get("ob1", rr=1.0)
    assert not built
    models.get("ob1", q=2)            # a valid key still constructs
    assert built == [1]


@pytest.mark.parametrize("args,needles", [
    (["reproduce", "thesis:fig2.3", "--option", "stpes=10"], ["stpes", "did you mean steps?"]),
    (["reproduce", "--all", "--paper", "nosuch"], ["--paper", "embedded, multipdf, thesis, rtd"]),
    (["reproduce", "--all", "--paper", "thesys"], ["did you mean thesis?"]),
    (["reproduce", "fig2.2", "--paper", "thesis"], ["--paper", "not both"]),
    (["reproduce", "thesis:fig2.22"], ["unknown recipe", "did you mean"]),
])
def test_recipe_selectors_and_options(tmp_path, args, needles):
    line = _error(*args, "--out", str(tmp_path))
    for n in needles:
        assert n in line, line
    assert not (tmp_path / "thesis").exists()          # refused before any work


def test_option_without_value_names_option():
    # (this one already worked; kept with the new "did you mean" of a misspelt key)
    assert "--option 'foo': expected KEY=VALUE" in _error("reproduce", "fig2.3", "--option", "foo")
    assert "did you mean particles?" in _error("reproduce", "fig2.3", "--option", "partciles=3")


def test_typed_rejects_non_finite_numbers():
    with pytest.raises(InputError, match="--option x=nan: expected a finite number"):
        typed(float("nan"), float, "--option x=nan")
    assert typed("1e3", float, "x") == 1000.0


def test_comma_lists_are_split_one_way_for_every_flag():
    """`pfbench compile` and `pfbench sweep` split comma-separated values with one parser: items
    stripped, a list from a grid file taken as it is, an empty item, an empty value or an item
    outside the choices is one InputError naming the flag (with "did you mean"). Catches: empty
    items dropped silently (as the sweep's method list did), an unchecked choice."""
    from pfbench.options import comma_list

    assert comma_list(" bootstrap, sir ", "--method") == ["bootstrap", "sir"]
    assert comma_list(["mpf", "sir"], "--method", ("mpf", "sir")) == ["mpf", "sir"]
    for bad, words in (("a,,b", "empty item"), ("a,", "empty item"), ("", "is empty"), ([], "is empty")):
        with pytest.raises(InputError, match=words):
            comma_list(bad, "--method")
    with pytest.raises(InputError, match="--method 'bootstrp' is not one of.*did you mean bootstrap"):
        comma_list("bootstrp", "--method", ("bootstrap", "sir"))
