"""CLI: the error policy (user error -> one line, exit 2; bug -> traceback, exit 1; --debug),
--version/--help, run with every method and model variants, one KEY=VALUE typing for every flag,
declared recipe options."""
import ast
import inspect
import json
import os
import re
import subprocess
import sys
import textwrap
import types

import numpy as np
import pytest
from click.testing import CliRunner

from pfbench import recipes
from pfbench.cli import main
from pfbench.errors import InputError

PFBENCH = [sys.executable, "-m", "pfbench.cli"]


def _cli(*args, timeout=300):
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.run(PFBENCH + list(args), capture_output=True, text=True, timeout=timeout, env=env)


def _invoke(*args):
    return CliRunner().invoke(main, list(args))


def _one_error_line(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    assert lines[0].startswith("error:") and "Traceback" not in stderr
    return lines[0]


# --------------------------------------------------------------------------- error policy
@pytest.mark.parametrize("args,needle", [
    (["run", "--model", "ob1", "--particles", "0"], "--particles"),
    (["run", "--model", "ob1", "--method", "multipdf", "--filters", "0"], "--filters"),
    (["run", "--model", "ob1", "--method", "multipdf", "--particles", "5", "--filters", "6"], "--filters"),
    (["run", "--model", "nope"], "unknown model"),
    (["run", "--model", "ob1", "--method", "nope"], "--method"),
    (["run", "--model", "ob1", "--backend", "gpu"], "--backend"),
    (["run", "--model", "ob1", "--dtype", "float16"], "--dtype"),
    (["run", "--model", "ob1", "--particles", "abc"], "--particles"),
    (["run", "--model", "ob1", "--steps", "1.5"], "--steps"),
    (["run", "--model", "ob1", "--version", "4"], "--version"),       # no longer a run option
    (["run", "--model", "ob1", "--param", "q"], "KEY=VALUE"),
    (["run", "--model", "ob1", "--param", "q=-1"], "variances q and r must be positive"),  # model's InputError
    (["run", "--model", "ob1", "--method", "sir", "--ess-threshold", "12", "--steps", "3",
      "--backend", "numpy"], "fraction"),
    (["run", "--model", "ob1", "--method", "mpf", "--steps", "3"], "linear"),  # unsupported method
    (["reproduce", "no-such-recipe"], "unknown recipe"),
    (["no-such-command"], "no-such-command"),
])
def test_bad_input_is_one_line_exit_2(args, needle):
    # In process: exit code and stderr are what the console would show.
    r = _invoke(*args)
    assert r.exit_code == 2, r.output
    assert needle in _one_error_line(r.stderr)


def _tbb_loads() -> bool:
    try:
        import numba.np.ufunc.tbbpool  # noqa: F401
    except (ImportError, OSError):
        return False
    return True


@pytest.mark.parametrize("env, needle", [
    ({"NUMBA_NUM_THREADS": "0"}, "NUMBA_NUM_THREADS='0': numba needs a positive"),
    ({"NUMBA_NUM_THREADS": "abc"}, "NUMBA_NUM_THREADS='abc'"),
    ({"NUMBA_THREADING_LAYER": "foo"}, "NUMBA_THREADING_LAYER='foo': numba knows"),
    pytest.param({"NUMBA_THREADING_LAYER": "tbb"}, "numba's threads cannot start here (No threading layer",
                 marks=pytest.mark.skipif(_tbb_loads(), reason="TBB is installed here")),
    ({"NUMBA_DISABLE_JIT": "1"}, "NUMBA_DISABLE_JIT is set: the numba backend needs numba's compiler")])
def test_numba_settings_in_the_environment_are_checked_first(env, needle):
    """In a real process, where numba reads them at its import, each setting numba cannot work with
    is one line naming it: NUMBA_NUM_THREADS=0 (numba's import fails), an unknown layer or one
    that cannot load here (TBB not installed: threads fail to start, in a compile too), the JIT
    switched off (nothing compiles). Catches each check dropped or run after numba reads it."""
    r = subprocess.run([sys.executable, "-m", "pfbench.cli", "run", "--model", "ob1", "--particles", "20000",
                        "--steps", "3", "--threads", "2"], capture_output=True, text=True, timeout=300,
                       env=dict(os.environ, **env))
    assert r.returncode == 2 and needle in _one_error_line(r.stderr), r.stderr


def test_the_jit_switched_off_in_code_is_one_error_naming_it(monkeypatch):
    """numba.config.DISABLE_JIT set by a notebook, not the environment: the numba backend refuses in
    one line. Catches a check of the environment variable only (an AttributeError from the build)."""
    import numba

    import pfbench
    from pfbench import models

    monkeypatch.setattr(numba.config, "DISABLE_JIT", True)
    with pytest.raises(InputError, match="NUMBA_DISABLE_JIT is set"):
        pfbench.run_filter(models.get("ob1"), np.zeros((5, 1)), n_particles=50, backend="numba")


def test_user_error_one_line_in_a_real_process():
    r = _cli("run", "--model", "nope")
    assert r.returncode == 2 and "unknown model" in _one_error_line(r.stderr)


@pytest.mark.parametrize("exc", [ValueError("a bug"), RuntimeError("a bug"), KeyError("a bug"),
                                 EOFError("a bug")])  # click turns EOFError into Abort: not a Ctrl-C
def test_internal_error_shows_traceback_exit_1(monkeypatch, exc):
    # An exception that is not a PfbenchError is a bug: traceback + exit 1, never exit 2.
    from pfbench import models

    def broken(*a, **k):
        raise exc

    monkeypatch.setattr(models, "parse_spec", broken)
    r = _invoke("run", "--model", "ob1")
    assert r.exit_code == 1
    assert "Traceback" in r.stderr and "a bug" in r.stderr and "internal error" in r.stderr


def test_debug_shows_traceback_of_user_error():
    r = _invoke("--debug", "run", "--model", "nope")
    assert r.exit_code == 2
    assert "Traceback" in r.stderr and r.stderr.strip().splitlines()[-1].startswith("error: unknown model")
    r = _invoke("run", "--model", "nope")      # without --debug: one line (the flag does not leak)
    _one_error_line(r.stderr)


def test_ctrl_c_is_exit_130(monkeypatch):
    from pfbench import models

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(models, "parse_spec", interrupted)
    assert _invoke("run", "--model", "ob1").exit_code == 130


def test_version_and_help():
    r = _cli("--version")
    assert r.returncode == 0 and "pfbench" in r.stdout
    for cmd in ("run", "list", "reproduce", "info", "report", "options"):
        h = _invoke(cmd, "--help")
        assert h.exit_code == 0 and "Usage" in h.output, cmd


# --------------------------------------------------------------------------- run
def _run_json(*args):
    r = _invoke("run", *args, "--json")
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout)


def test_run_json():
    out = _run_json("--model", "ob1", "--particles", "200", "--steps", "50", "--backend", "numpy",
                    "--seed", "1")
    for key in ("armse", "loglik", "elapsed_s", "ns_per_particle_step"):
        assert key in out
    assert 0 < out["armse"] < 20


def test_model_variant_spec_equals_version_param():
    a = _run_json("--model", "ob3:v4", "--particles", "50", "--steps", "10", "--backend", "numpy")
    b = _run_json("--model", "ob3", "--param", "version=4", "--particles", "50", "--steps", "10",
                  "--backend", "numpy")
    c = _run_json("--model", "ob3:4", "--particles", "50", "--steps", "10", "--backend", "numpy")
    assert a["params"] == b["params"] == c["params"] == {"version": 4}
    assert a["armse"] == b["armse"] == c["armse"]
    d = _run_json("--model", "ob3", "--particles", "50", "--steps", "10", "--backend", "numpy")
    assert d["armse"] != a["armse"]          # the variant really reaches the model (v1 != v4)


@pytest.mark.parametrize("spec,needle", [
    ("ob1:v2", "no variants"), ("ob3:vx", "vN or N"), ("ob3:v9", "version must be 1..5"),
    ("nope:v1", "unknown model"),
])
def test_bad_model_specs(spec, needle):
    r = _invoke("run", "--model", spec, "--steps", "3")
    assert r.exit_code == 2 and needle in _one_error_line(r.stderr)


def test_model_variant_given_twice_must_agree():
    from pfbench import models

    assert models.parse_spec("ob3:v2", {"version": 2}) == ("ob3", {"version": 2})
    with pytest.raises(InputError, match="give the variant once"):
        models.parse_spec("ob3:v2", {"version": 4})
    assert models.get_spec("ob3:v5").version == 5


def test_run_mpf_reports_particles_used_and_note():
    out = _run_json("--model", "ob2", "--method", "mpf", "--particles", "50", "--steps", "20",
                    "--backend", "numpy")
    assert out["method"] == "mpf" and 0 < out["armse"] < 20
    # Ob2 is linear in every state: one Kalman/EKF copy runs, whatever N_p says.
    assert out["n_particles"] == 1 and out["n_particles_requested"] == 50 and out["note"]
    r = _invoke("run", "--model", "ob2", "--method", "mpf", "--particles", "50", "--steps", "20",
                "--backend", "numpy")
    assert r.exit_code == 0 and "note: " in r.stdout


def test_run_multipdf_uneven_split_prints_note():
    r = _invoke("run", "--model", "ob1", "--method", "multipdf", "--particles", "100", "--filters", "3",
                "--steps", "10", "--backend", "numpy")
    assert r.exit_code == 0, r.output
    assert "n_particles: 99" in r.stdout and "note: N_p = 100" in r.stdout


def test_run_warns_of_the_models_nan_log_likelihoods_and_strict_refuses(log_of_state_file):
    """A model whose log_likelihood is NaN for some particles (log of a negative state): the run
    says how many, at how many steps and the first, and goes on (weight zero); --strict makes it an
    error. Catches the count kept in info but never said."""
    f = log_of_state_file("cli_log_of_state")
    args = ["--models", str(f), "run", "--model", "cli_log_of_state", "--backend", "numpy", "--particles", "500",
            "--steps", "15"]
    with np.errstate(all="ignore"):
        r = _invoke(*args, "--json")
        assert r.exit_code == 0, r.output
        assert json.loads(r.stdout)["invalid_log_likelihoods"] > 0
        assert re.search(r"^warning: log_likelihood returned NaN or \+inf \d+ time\(s\) at \d+ step\(s\), "
                         r"first at step \d+: those particles got weight zero", r.stderr, re.M), r.stderr
        r = _invoke(*args, "--strict")
    assert r.exit_code == 2 and "log_likelihood returned NaN or +inf" in _one_error_line(r.stderr)


def test_run_kalman_on_linear_gaussian():
    out = _run_json("--model", "linear_gaussian", "--method", "kalman", "--steps", "40", "--backend", "numpy")
    assert out["method"] == "kalman" and 0 < out["armse"] < 5 and out["ns_per_step"] > 0
    # no particles: no particle counts, no resampling scheme, no cost per particle
    assert not {"n_particles", "resampling", "estimate", "n_resampled", "ns_per_particle_step"} & set(out)


def test_run_guided_on_pmsm():
    try:
        import pfbench.filters.guided  # noqa: F401
    except ImportError:
        pytest.skip("the guided filter (pfbench.filters.guided) is not in this tree yet")
    out = _run_json("--model", "pmsm", "--method", "guided", "--particles", "30", "--steps", "30",
                    "--backend", "numpy")
    assert out["method"] == "guided" and out["n_particles"] == 30 and out["armse"] > 0


def test_run_every_method_is_a_choice():
    from pfbench.filters import METHODS

    h = _invoke("run", "--help").output
    for m in METHODS:
        assert m in h


# --------------------------------------------------------------------------- one KEY=VALUE typing
TEXTS = ["q=2", "r=0.5", "shared_noise=true"]
TYPED = {"q": 2, "r": 0.5, "shared_noise": True}   # int, float, bool: what parse_value gives


@pytest.fixture
def probe_recipe(monkeypatch):
    """A throw-away recipe (removed after the test) with untyped options q, r, shared_noise."""
    recipes.discover()
    monkeypatch.setattr(recipes, "_REGISTRY", dict(recipes._REGISTRY))
    seen = {}

    @recipes.recipe("thesis:zz-probe", title="probe", options={k: "probe" for k in TYPED})
    def probe(ctx):
        seen.update(ctx.options)
        if "q" in ctx.options:
            seen["q_as_float"] = ctx.option("q", 0.0, float)

    return seen


def test_same_text_types_the_same_through_every_flag(tmp_path, monkeypatch, probe_recipe):
    flags = {}
    flags["run --param"] = _run_json("--model", "ob4", *sum((["--param", t] for t in TEXTS), []),
                                     "--particles", "20", "--steps", "5", "--backend", "numpy")["params"]
    r = _invoke("reproduce", "thesis:zz-probe", "--out", str(tmp_path), "--quiet",
                *sum((["--option", t] for t in TEXTS), []))
    assert r.exit_code == 0, r.output
    flags["reproduce --option"] = {k: probe_recipe[k] for k in TYPED}
    assert probe_recipe["q_as_float"] == 2.0   # an int is a valid float
    from pfbench.mcu import costmodel

    got = {}
    monkeypatch.setattr(costmodel, "predict", lambda *a, **k: got.update(k["model_params"]) or {})
    monkeypatch.setattr("pfbench.mcu.cli._format", lambda *a, **k: "")
    r = _invoke("mcu", "estimate", "--model", "ob4", *sum((["--param", t] for t in TEXTS), []))
    assert r.exit_code == 0, r.output
    flags["mcu estimate --param"] = got
    out = tmp_path / "s.jsonl"
    r = _invoke("sweep", "--model", "ob4", *sum((["--param", t] for t in TEXTS), []), "--method",
                "bootstrap", "--runs", "1", "--steps", "2", "--workers", "1", "--quiet",
                "--backend", "numpy", "--out", str(out))
    assert r.exit_code == 0, r.output
    flags["sweep --param"] = json.loads(out.read_text().splitlines()[0])["spec"]["params"]
    for flag, typed in flags.items():
        assert typed == TYPED and all(type(typed[k]) is type(v) for k, v in TYPED.items()), flag


# --------------------------------------------------------------------------- recipe options
def test_unknown_option_lists_valid_keys(tmp_path):
    r = _invoke("reproduce", "thesis:fig2.3", "--out", str(tmp_path), "--option", "stpes=10")
    assert r.exit_code == 2
    line = _one_error_line(r.stderr)
    assert "stpes" in line and "particles, runs, steps, threshold" in line
    assert not (tmp_path / "thesis").exists()          # refused before any work


@pytest.mark.parametrize("text,needle", [("steps=2.7", "expected an integer"),
                                         ("steps=2.0", "expected an integer"),
                                         ("steps=true", "expected an integer"),
                                         ("threshold=abc", "expected a number")])
def test_option_values_are_typed_not_rounded(tmp_path, text, needle):
    r = _invoke("reproduce", "thesis:fig2.3", "--out", str(tmp_path), "--option", text)
    assert r.exit_code == 2 and needle in _one_error_line(r.stderr)


def test_data_on_a_recipe_that_reads_none(tmp_path):
    log = tmp_path / "log.csv"
    log.write_text("time_s,y\n0,1\n")
    r = _invoke("reproduce", "thesis:fig2.3", "--out", str(tmp_path), "--data", str(log))
    assert r.exit_code == 2 and "reads no data" in _one_error_line(r.stderr)


def test_reading_an_undeclared_option_is_a_bug(tmp_path, monkeypatch):
    recipes.discover()
    monkeypatch.setattr(recipes, "_REGISTRY", dict(recipes._REGISTRY))

    @recipes.recipe("thesis:zz-rot", title="rotten declaration", options={"a": (int, "declared")})
    def rot(ctx):
        ctx.option("b", 1, int)

    r = _invoke("reproduce", "thesis:zz-rot", "--out", str(tmp_path))
    assert r.exit_code == 1 and "Traceback" in r.stderr and "does not declare" in r.stderr
    ctx = recipes.RecipeContext(recipe=recipes.resolve("thesis:zz-rot"), options={})
    with pytest.raises(RuntimeError):
        "b" in ctx.options                              # direct lookups are guarded too
    assert ctx.option("a", 7) == 7 and "a" not in ctx.options


def test_list_and_options_show_declarations():
    r = _invoke("list", "--json")
    assert r.exit_code == 0
    recs = {d["id"]: d for d in json.loads(r.stdout)}
    assert recs["thesis:fig2.3"]["options"]["threshold"]["type"] == "float"
    assert recs["embedded:fig6"]["reads_data"] and not recs["thesis:fig2.3"]["reads_data"]
    r = _invoke("list")
    assert "takes --option particles, steps, threshold" in r.stdout
    r = _invoke("options", "fig2.3")
    assert r.exit_code == 0 and "threshold" in r.stdout and "float" in r.stdout


def test_info_json():
    r = _invoke("info", "--json")
    assert r.exit_code == 0
    info = json.loads(r.stdout)
    assert info["host"]["cores"] >= 1 and "ob1" in info["models"]


# ---- declarations vs code: a static reading of every recipe and the helpers it calls ----------
def _is_options(node):
    return isinstance(node, ast.Attribute) and node.attr == "options"


def _key_nodes(tree):
    """Expressions used as option keys: ctx.option(K), ctx.options.get(K), ctx.options[K], K in ctx.options."""
    for n in ast.walk(tree):
        if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute) and n.args:
            if n.func.attr == "option" or (n.func.attr == "get" and _is_options(n.func.value)):
                yield n.args[0]
        elif isinstance(n, ast.Subscript) and _is_options(n.value):
            yield n.slice
        elif isinstance(n, ast.Compare) and isinstance(n.ops[0], (ast.In, ast.NotIn)) \
                and _is_options(n.comparators[0]):
            yield n.left


def _resolve(func, node):
    """The reproductions function a call node calls, if any."""
    scope = dict(func.__globals__)
    if func.__closure__:
        scope.update(zip(func.__code__.co_freevars, (c.cell_contents for c in func.__closure__)))
    obj = None
    if isinstance(node.func, ast.Name):
        obj = scope.get(node.func.id)
    elif isinstance(node.func, ast.Attribute) and isinstance(node.func.value, ast.Name):
        mod = scope.get(node.func.value.id)
        obj = getattr(mod, node.func.attr, None) if isinstance(mod, types.ModuleType) else None
    if inspect.isfunction(obj) and obj.__module__.startswith("pfbench.reproductions"):
        return inspect.unwrap(obj)
    return None


def _reads(func, memo):
    """(option keys read, parameter names used as keys, reads ctx.data) of func and its helpers."""
    if func in memo:
        return memo[func]
    memo[func] = (set(), set(), False)        # recursion guard
    tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    params = set(inspect.signature(func).parameters)
    keys, key_params = set(), set()
    for k in _key_nodes(tree):
        if isinstance(k, ast.Constant) and isinstance(k.value, str):
            keys.add(k.value)
        elif isinstance(k, ast.Name) and k.id in params:
            key_params.add(k.id)
        else:
            raise AssertionError(f"{func.__qualname__}: option key {ast.unparse(k)} is not a literal")
    data = any(isinstance(n, ast.Attribute) and n.attr == "data" and isinstance(n.value, ast.Name)
               and n.value.id == "ctx" for n in ast.walk(tree))
    for call in (n for n in ast.walk(tree) if isinstance(n, ast.Call)):
        helper = _resolve(func, call)
        if helper is None or helper is func:
            continue
        h_keys, h_params, h_data = _reads(helper, memo)
        keys |= h_keys
        data |= h_data
        if h_params:
            bound = inspect.signature(helper).bind_partial(*call.args, **{kw.arg: kw.value for kw in call.keywords})
            for p in h_params:
                arg = bound.arguments.get(p)
                if isinstance(arg, ast.Constant):
                    keys.add(arg.value)
                elif isinstance(arg, ast.Name) and arg.id in params:
                    key_params.add(arg.id)
    memo[func] = (keys, key_params, data)
    return memo[func]


def test_every_recipe_declares_what_its_code_reads():
    memo = {}
    reg = recipes.discover()
    assert len(reg) > 30
    for rec in reg.values():
        keys, _, data = _reads(inspect.unwrap(rec.func), memo)
        assert keys == set(rec.option_keys), (rec.id, sorted(keys), rec.option_keys)
        assert data == rec.reads_data, rec.id


def test_static_reader_sees_helpers():
    # the reader must follow helpers and key parameters, or the test above proves nothing
    t3 = recipes.resolve("embedded:table3")
    keys, _, _ = _reads(inspect.unwrap(t3.func), {})
    assert {"repeats", "host_power_w", "board_power_w"} <= keys       # via _opt_float / _repeats
    keys, _, data = _reads(inspect.unwrap(recipes.resolve("embedded:tableA1").func), {})
    assert keys == {"pf_seeds"} and data                              # via _grid -> _experiment


def test_run_truth_and_filter_streams_are_apart_and_out_writes_tidy_steps(tmp_path):
    """The truth used to be simulated from the filter's own seed (ob1 at N_p = 1 gave aRMSE exactly
    0 for most seeds); now it comes from a derived stream or --truth-seed, said in --json. --out
    writes one row per step and the provenance beside it. Catches the shared stream and a missing
    per-step column."""
    import pandas as pd

    out = tmp_path / "est.csv"
    r = CliRunner().invoke(main, ["run", "--model", "ob1", "--particles", "1", "--steps", "20", "--backend",
                                  "numpy", "--json", "--out", str(out)])
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)
    assert data["armse"] > 0 and "derived from --seed 0" in data["truth_seed"]
    frame = pd.read_csv(out)
    assert len(frame) == 20 and {"step", "x", "x_var", "ess", "loglik_increment", "degenerate"} <= set(frame)
    assert frame["loglik_increment"].sum() == pytest.approx(data["loglik"])
    prov = json.loads((tmp_path / "est.csv.json").read_text())
    assert prov["command"] == "pfbench run" and prov["n_particles"] == 1 and "packages" in prov
    r2 = CliRunner().invoke(main, ["run", "--model", "ob1", "--particles", "1", "--steps", "20", "--backend",
                                   "numpy", "--json", "--truth-seed", "7"])
    assert json.loads(r2.stdout)["truth_seed"] == 7 and json.loads(r2.stdout)["armse"] != data["armse"]


@pytest.mark.parametrize("args, needle", [
    (["run", "--model", "ob1", "--seed", "-1"], "--seed"),
    (["run", "--model", "ob1", "--filters", "2"], "--filters 2 needs --method multipdf"),
    (["run", "--model", "ob1", "--out", "x.txt"], ".csv or .parquet"),
    (["reproduce", "fig5", "--seed", "-1"], "--seed"),
    (["run", "--model", "ob1", "--out", ""], "'--out': an empty path"),           # wrote nothing, exit 0
    (["reproduce", "fig5", "--out", ""], "'--out': an empty path"),
    # options the method cannot use were printed beside results they did not shape
    (["run", "--model", "linear_gaussian", "--method", "kalman", "--particles", "5", "--dtype", "float32"],
     "--particles, --dtype cannot apply to --method kalman"),
    (["run", "--model", "ob1", "--method", "sis", "--resampling", "stratified"],
     "--resampling cannot apply to --method sis"),
    (["run", "--model", "ob1", "--param", "q=[1,2]"], "--param q=[1, 2]: expected a number"),  # was "'<=' not supported"
    (["run", "--model", "ob2", "--param", "q=-1"], "bad parameters for model 'ob2': ob2 needs a variance q > 0"),
    (["run", "--model", "ob4", "--param", "r=-1"], "bad parameters for model 'ob4'"),  # both blamed transition()
    (["run", "--model", "ob1", "--models", "m.py"], "--models is an option of pfbench itself"),
    (["compile", "--model", "ob1", "--method", "nosuch"], "--method 'nosuch' is not one of"),  # said --methods
])
def test_run_and_reproduce_refuse_bad_values_in_one_line(args, needle):
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2 and needle in r.output and "Traceback" not in r.output


def test_a_crash_in_compiled_code_names_the_call():
    """A segmentation fault (here a read at address 0, as a model indexing out of its arrays in
    compiled code would do) prints the Python stack of the command that crashed instead of ending
    in silence; catches the CLI not enabling faulthandler."""
    import os
    import subprocess
    import sys

    code = ("import ctypes\n"
            "from pfbench import cli\n"
            "@cli.main.command('crash_here')\n"
            "def crash_here():\n"
            "    ctypes.string_at(0)\n"
            "cli.main(['crash_here'])\n")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONFAULTHANDLER"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode != 0
    assert "Segmentation fault" in r.stderr and "crash_here" in r.stderr, r.stderr[-500:]


def test_a_runs_provenance_names_its_inputs(tmp_path, readme_model_file):
    """The provenance of `pfbench run --out` held neither the command line, nor the user's model file,
    nor the data file: a result could not be traced to what made it. Catches any of the three gone."""
    from pfbench.models import load_files
    from pfbench.plants import chamber
    from pfbench.plants.datalog import write_log
    from pfbench.sources import file_hash

    model = readme_model_file("prov_growth")
    load_files([model])
    log = write_log(tmp_path / "log.csv", chamber.heating_normal(seed=1, duration_s=30))
    out = tmp_path / "r.csv"
    res = CliRunner().invoke(main, ["run", "--model", "thermal_inertial", "--data", str(log), "--particles", "50",
                                    "--backend", "numpy", "--out", str(out)])
    assert res.exit_code == 0, res.output
    prov = json.loads((tmp_path / "r.csv.json").read_text())
    assert prov["data"] == str(log) and prov["data_sha256"] == file_hash(str(log))
    assert prov["model_files"][str(model.resolve())] == file_hash(str(model.resolve()))
    assert isinstance(prov["argv"], list)
