"""CLI: one-line errors with exit code 2, --version/--help, run --json."""
import json
import os
import subprocess
import sys

import pytest

PFBENCH = [sys.executable, "-m", "pfbench.cli"]


def _cli(*args, timeout=300):
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.run(PFBENCH + list(args), capture_output=True, text=True, timeout=timeout, env=env)


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
    (["reproduce", "no-such-recipe"], "unknown recipe"),
    (["no-such-command"], "no-such-command"),
])
def test_bad_input_is_one_line_exit_2(args, needle):
    r = _cli(*args)
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("error:") and needle in lines[0]
    assert "Traceback" not in r.stderr


def test_version_and_help():
    r = _cli("--version")
    assert r.returncode == 0 and "pfbench" in r.stdout
    for cmd in ("run", "list", "reproduce", "info", "report"):
        h = _cli(cmd, "--help")
        assert h.returncode == 0 and "Usage" in h.stdout, cmd


def test_run_json():
    r = _cli("run", "--model", "ob1", "--particles", "200", "--steps", "50", "--backend", "numpy",
             "--seed", "1", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for key in ("armse", "loglik", "elapsed_s", "ns_per_particle_step"):
        assert key in out
    assert 0 < out["armse"] < 20


def test_list_and_info():
    r = _cli("list", "--json")
    assert r.returncode == 0
    assert isinstance(json.loads(r.stdout), list)
    r = _cli("info", "--json")
    assert r.returncode == 0
    info = json.loads(r.stdout)
    assert info["host"]["cores"] >= 1 and "ob1" in info["models"]
