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


def test_load_files_registers_the_readme_model(readme_model_file):
    path = readme_model_file("user_growth_a")
    assert models.load_files([path]) == ["user_growth_a"]
    assert models.load_files([path]) == []  # imported once per process
    m = models.get_spec("user_growth_a")
    assert m.simulate(5, seed=0).y.shape == (5, 1)


@pytest.mark.parametrize("content,why", [(None, "not an existing .py file"),
                                         ("import no_such_module_xyz\n", "failed to import: ModuleNotFoundError")])
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
    args = ("run", "--model", "user_growth_b", "--steps", "20", "--particles", "50", "--json")
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
             "--runs", "2", "--steps", "10", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "4/4 tasks" in r.stdout
