"""User model files: `pfbench --models FILE.py` / PFBENCH_MODELS make a user's @register classes
nameable everywhere (`run`, `sweep`, `mcu ...`), with one-line errors for bad files."""
import json
import os
import subprocess
import sys

import pytest

from pfbench import models
from pfbench.errors import InputError

PFBENCH = [sys.executable, "-m", "pfbench.cli"]


def _cli(*args, env=None):
    env = dict(os.environ, MPLBACKEND="Agg", **(env or {}))
    return subprocess.run(PFBENCH + list(args), capture_output=True, text=True, timeout=600, env=env)


def test_a_files_module_name_does_not_depend_on_the_other_files(readme_model_file):
    """Kernels are cached under the model's module name: `compile --models a.py --models b.py` did
    not serve a later `run --models b.py` (b was the second file there, the first here). Catches a
    name taken from the file's place in the list. One process loads each file once, so two
    processes load the same file second and first."""
    a, b = readme_model_file("user_order_a"), readme_model_file("user_order_b")
    script = ("import sys; from pfbench import models; models.load_files(sys.argv[1:]); "
              "print(models.model_class('user_order_b').__module__)")
    names = [subprocess.run([sys.executable, "-c", script, *files], capture_output=True, text=True, timeout=120,
                            check=True).stdout.strip() for files in ([str(a), str(b)], [str(b)])]
    assert names[0] == names[1] and names[0].endswith("_user_order_b")


def test_load_files_registers_the_readme_model(readme_model_file):
    path = readme_model_file("user_growth_a")
    assert models.load_files([path]) == ["user_growth_a"]
    assert models.load_files([path]) == []  # imported once per process
    m = models.get_spec("user_growth_a")
    assert m.simulate(5, seed=0).y.shape == (5, 1)


@pytest.mark.parametrize("content,why", [(None, "not an existing .py file"),
                                         ("import no_such_module_xyz\n", "failed to import: ModuleNotFoundError"),
                                         # exit code 0 and nothing run, before
                                         ("import sys\nsys.exit(0)\n", "failed to import: SystemExit: 0"),
                                         # both registered nothing, without a word
                                         ("x = 1\n", "registers no model"),
                                         ("from pfbench.models import register\n"
                                          "from pfbench.models.base import StateSpaceModel\n"
                                          "@register\nclass Mine(StateSpaceModel):\n    pass\n",
                                          "@register needs the model's name as text"),
                                         # registered, but `--model my:growth` named the model 'my'
                                         ("from pfbench.models import register\n"
                                          "from pfbench.models.base import StateSpaceModel\n"
                                          "@register('my:growth')\nclass Mine(StateSpaceModel):\n    pass\n",
                                          "a model's name cannot hold ':'")])
def test_bad_model_file_is_one_line_input_error(tmp_path, content, why):
    path = tmp_path / "bad_model.py"
    if content is not None:
        path.write_text(content)
    with pytest.raises(InputError, match=why):
        models.load_files([path])
    r = _cli("--models", str(path), "run", "--model", "ob1", "--steps", "3", "--particles", "10")
    assert r.returncode == 2 and why in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_cli_runs_a_user_model_by_flag_and_by_environment(readme_model_file):
    path = readme_model_file("user_growth_b")
    args = ("run", "--model", "user_growth_b", "--steps", "20", "--particles", "50", "--backend", "numpy", "--json")
    by_flag = _cli("--models", str(path), *args)
    assert by_flag.returncode == 0, by_flag.stderr
    by_env = _cli(*args, env={models.MODELS_ENV: str(path)})
    assert by_env.returncode == 0, by_env.stderr
    # same model, same seed: the same numbers whichever way the file was named
    assert json.loads(by_flag.stdout)["loglik"] == json.loads(by_env.stdout)["loglik"]
    unknown = _cli(*args)
    assert unknown.returncode == 2 and "unknown model 'user_growth_b'" in unknown.stderr


def test_sweep_workers_find_a_user_model(readme_model_file, tmp_path):
    # sweep tasks run in worker processes: they must import the user's file too (through the
    # environment the CLI sets). Catches a worker that only knows the built-in models.
    path = readme_model_file("user_growth_c")
    out = tmp_path / "sweep.parquet"
    r = _cli("--models", str(path), "sweep", "--model", "user_growth_c", "--particles", "20,40",
             "--runs", "2", "--steps", "10", "--backend", "numpy", "--workers", "2", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "4/4 tasks" in r.stdout


def _file_registering(path, name):
    """A copy of the README model's file at ``path`` that registers ``name``."""
    from pathlib import Path

    readme = Path(__file__).resolve().parents[2] / "README.md"
    code = readme.read_text().split("## Your own model", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    path.write_text(code.split("\nm = ", 1)[0].replace('"my_growth"', f'"{name}"'))
    return path


def test_a_user_file_taking_a_builtin_name_is_an_error_naming_both_files(tmp_path):
    """Before, the built-in won in the main process and the user's class in spawned sweep workers:
    --workers 1 and 2 gave different numbers under one label, silently. Catches a user class that
    replaces a built-in (or the reverse, in either order of loading)."""
    builtin = models.model_class("ob1")
    path = _file_registering(tmp_path / "shadow.py", "ob1")
    with pytest.raises(InputError, match=r"shadow\.py.*'ob1'.*ob1\.py") as ei:
        models.load_files([path])
    assert "\n" not in str(ei.value)
    assert models.model_class("ob1") is builtin and str(path.resolve()) not in models.loaded_files()
    r = _cli("--models", str(path), "run", "--model", "ob1", "--steps", "3", "--particles", "10")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "shadow.py" in r.stderr and "ob1.py" in r.stderr


def test_two_user_files_registering_one_name_is_an_error_naming_both(tmp_path):
    first = _file_registering(tmp_path / "first.py", "user_twice")
    second = _file_registering(tmp_path / "second.py", "user_twice")
    assert models.load_files([first]) == ["user_twice"]
    kept = models.model_class("user_twice")
    with pytest.raises(InputError, match=r"second\.py.*'user_twice'.*first\.py"):
        models.load_files([second])
    assert models.model_class("user_twice") is kept      # the registry is as before the refused file


def test_pool_workers_load_the_files_the_parent_loaded(tmp_path):
    """A file loaded through the Python API (no --models, no PFBENCH_MODELS) is loaded by the
    workers of a process pool too. Catches workers that only see the environment."""
    from pfbench.procs import process_pool
    import multiprocessing as mp

    path = _file_registering(tmp_path / "pooled.py", "user_pooled")
    models.load_files([path])
    with process_pool(1, mp_context=mp.get_context("spawn")) as pool:
        assert pool.submit(models.names).result(timeout=300).count("user_pooled") == 1
