"""One CLI vocabulary: the same option means the same thing with the same type and choices in
every command; every command that prints results has --json; progress bars only on a terminal;
model and recipe names complete in the shell."""
import io
import json
from pathlib import Path
from types import SimpleNamespace

import click
import pytest
from click.testing import CliRunner

from pfbench.cli import main
from pfbench.clitypes import ChoiceList

ROOT = Path(__file__).resolve().parent.parent


def _leaf_commands():
    """(path, command) of every command that runs something, subsystem groups included."""
    ctx = click.Context(main)
    out = []

    def walk(cmd, path):
        if isinstance(cmd, click.Group):
            for name in cmd.list_commands(ctx):
                walk(cmd.get_command(ctx, name), f"{path} {name}")
        if not isinstance(cmd, click.Group) or cmd.invoke_without_command:
            out.append((path, cmd))

    walk(main, "pfbench")
    return out


def _option(cmd, name):
    return next((p for p in cmd.params if name in getattr(p, "opts", ())), None)


def _choices(param):
    return tuple(param.type.choices) if isinstance(param.type, (click.Choice, ChoiceList)) else None


def test_same_option_same_choices_everywhere():
    """Before, `sweep --backend/--method` and `compile --method` were free text."""
    run = dict(_leaf_commands())["pfbench run"]
    for name in ("--backend", "--method", "--resampling", "--dtype", "--estimate"):
        want = set(_choices(_option(run, name)))
        for path, cmd in _leaf_commands():
            p = _option(cmd, name)
            if p is None:
                continue
            got = _choices(p)
            assert got is not None, f"{path} {name} is free text"
            assert set(got) <= want, f"{path} {name}: {got} not among {want}"  # mcu: the particle methods


def test_out_is_a_file_or_a_folder_with_the_same_metavar():
    """Before, --out was DIRECTORY, TEXT or FILE by command."""
    seen = {}
    for path, cmd in _leaf_commands():
        p = _option(cmd, "--out")
        if p is None:
            continue
        assert isinstance(p.type, click.Path), f"{path} --out is {p.type.name}"
        kind = "FILE" if not p.type.dir_okay else "DIR" if not p.type.file_okay else None
        assert kind is not None and p.metavar == kind, (path, p.metavar)
        seen[path] = kind
    assert seen["pfbench run"] == seen["pfbench sweep run"] == seen["pfbench bench"] == "FILE"
    assert seen["pfbench reproduce"] == seen["pfbench report"] == seen["pfbench compare"] == "DIR"


def test_every_command_that_prints_results_has_json():
    """Before, `options`, `reproduce` and `sweep run` had none."""
    missing = [path for path, cmd in _leaf_commands() if _option(cmd, "--json") is None]
    assert not missing


def _json(*args):
    r = CliRunner().invoke(main, list(args))
    assert r.exit_code == 0, r.output + r.stderr
    return json.loads(r.stdout)


def test_list_json_costs_in_seconds():
    rows = _json("list", "--json")
    assert all(isinstance(r["quick_cost_s"], float) and isinstance(r["full_cost_s"], float) for r in rows)
    fig5 = next(r for r in rows if r["id"] == "rtd:fig5")
    assert (fig5["quick_cost"], fig5["quick_cost_s"], fig5["full_cost_s"]) == ("~5 s", 5.0, 30.0)


def test_options_json():
    d = _json("options", "rtd:fig6", "--json")
    assert d["id"] == "rtd:fig6" and d["reads_data"] is True
    assert d["options"]["gain"]["type"] == "float"


def test_reproduce_json_is_one_object_and_progress_goes_to_stderr(tmp_path):
    r = CliRunner().invoke(main, ["reproduce", "multipdf:table3", "--json", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output + r.stderr
    d = json.loads(r.stdout)  # the whole of stdout
    (rec,) = d["recipes"]
    assert rec["id"] == "multipdf:table3" and rec["status"] == "ran" and rec["files"]
    assert d["mode"] == "quick" and "== multipdf:table3" in r.stderr


def test_bare_recipe_name_says_which_others_exist():
    """`reproduce fig5` runs embedded:fig5 (as designed) and says that two more fig5 exist."""
    r = CliRunner().invoke(main, ["reproduce", "fig5", "--option", "nosuch=1"])  # stops before running
    assert "note: fig5 is embedded:fig5; multipdf:fig5 and rtd:fig5 also exist" in r.stderr
    r = CliRunner().invoke(main, ["reproduce", "rtd:fig5", "--option", "nosuch=1"])
    assert "note:" not in r.stderr


def test_models_lists_description_dimensions_and_methods():
    rows = {r["name"]: r for r in _json("models", "--json")}
    assert rows["ob3"]["supports"] == {"mpf": True, "guided": False, "kalman": True}
    assert rows["ob5"]["supports"] == {"mpf": True, "guided": False, "kalman": False}
    assert rows["pmsm"]["supports"]["guided"] and not rows["ob1"]["supports"]["mpf"]
    assert (rows["ob4"]["n_x"], rows["ob4"]["n_y"], rows["ob4"]["n_u"]) == (2, 2, 1)
    assert rows["ob2"]["description"].startswith("Ob2: five states")  # from the module: no class docstring
    assert rows["ob1"]["description"] == "Ob1 ([MultiPDF] §4; [Embedded] eq. 6)"
    text = CliRunner().invoke(main, ["models"]).stdout
    assert "mpf, kalman" in text.split("\nob3 ")[1].splitlines()[0]


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_progress_bars_only_on_a_terminal(capsys):
    """tqdm wrote carriage-return redraws into redirected logs."""
    from pfbench.progress import progress_bar
    from pfbench.recipes import RecipeContext

    ctx = SimpleNamespace(quiet=False, recipe=SimpleNamespace(id="x"))
    assert list(RecipeContext.progress(ctx, range(3))) == [0, 1, 2]
    assert "\r" not in capsys.readouterr().err  # pytest's stderr is not a terminal
    tty = _Terminal()
    list(progress_bar(range(3), file=tty))
    assert "\r" in tty.getvalue()
    quiet = _Terminal()
    list(progress_bar(range(3), show=False, file=quiet))
    assert quiet.getvalue() == ""


def test_sweep_writes_no_bar_into_a_redirected_log(tmp_path):
    r = CliRunner().invoke(main, ["sweep", "--model", "ob1", "--method", "bootstrap", "--particles", "10",
                                  "--runs", "2", "--steps", "5", "--backend", "numpy", "--workers", "1",
                                  "--out", str(tmp_path / "s.jsonl")])
    assert r.exit_code == 0, r.output + r.stderr
    assert "\r" not in r.stderr and "2/2 tasks" in r.stdout


def _complete(words: str) -> list[str]:
    r = CliRunner().invoke(main, [], prog_name="pfbench",
                           env={"_PFBENCH_COMPLETE": "bash_complete", "COMP_WORDS": words,
                                "COMP_CWORD": str(len(words.split()) - (0 if words.endswith(" ") else 1))})
    return [ln.split(",", 1)[1] for ln in r.stdout.splitlines()]


@pytest.mark.parametrize("words,want", [
    ("pfbench run --model ob", {"ob1", "ob2", "ob3", "ob4", "ob5"}),
    ("pfbench sweep --model thermal_", {"thermal_inertial", "thermal_outdoor", "thermal_rate"}),
    ("pfbench compile --model ob1,thermal_r", {"ob1,thermal_rate"}),
    ("pfbench reproduce rtd:fig", {"rtd:fig2", "rtd:fig3", "rtd:fig4", "rtd:fig5", "rtd:fig6", "rtd:fig7"}),
    ("pfbench options multipdf:table", {"multipdf:table3", "multipdf:table4", "multipdf:table6"}),
    ("pfbench sweep --method bootstrap,s", {"bootstrap,sir", "bootstrap,sis"}),
])
def test_shell_completion_of_names(words, want):
    got = set(_complete(words))
    assert want <= got, got


def test_readme_documents_completion():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "_PFBENCH_COMPLETE=bash_source pfbench" in text and "_PFBENCH_COMPLETE=zsh_source" in text
