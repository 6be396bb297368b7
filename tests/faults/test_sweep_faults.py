"""Sweep faults: bad grid/CLI values, kill -9 (no orphans, consistent resume), two writers."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from pfbench.cli import main
from pfbench.errors import InputError
from pfbench.procs import exclusive_lock, lock_path
from pfbench.sweep import load_frame, make_spec, run_sweep

ROOT = Path(__file__).resolve().parents[2]


def _err(r) -> str:
    err = r.stderr.strip()
    assert r.exit_code == 2, r.output
    assert err.startswith("error:") and "\n" not in err and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("grid,needles", [
    ("model: ob1\npartciles: [10]\n", ["partciles (did you mean particles?)", "valid keys:", "runs"]),
    ("model: ob1\nrnus: 3\n", ["rnus (did you mean runs?)"]),
    ("model: ob1\nruns: 2.7\n", ["--runs", "2.7"]),
])
def test_bad_grid_files(tmp_path, grid, needles):
    g = tmp_path / "g.yaml"
    g.write_text(grid)
    out = tmp_path / "x.jsonl"
    err = _err(CliRunner().invoke(main, ["sweep", "--grid", str(g), "--out", str(out), "--quiet"]))
    assert all(n in err for n in needles), err
    assert not out.exists()


@pytest.mark.parametrize("args,needles", [
    (["--particles", "10,,20"], ["--particles", "empty item"]),
    (["--particles", "10,20,"], ["--particles", "empty item"]),
    (["--workers", "0"], ["--workers", ">= 1", "got 0"]),      # 0 is an error, like -2 ...
    (["--workers", "-2"], ["--workers", ">= 1", "got -2"]),
    (["--seed", "-1"], ["--seed", ">= 0"]),                    # not a worker traceback
    (["--out", "{tmp}/a.txt"], ["--out", ".jsonl", ".parquet"]),   # not JSON lines under any name
])
def test_bad_sweep_values(tmp_path, args, needles):
    args = [a.format(tmp=tmp_path) for a in args]
    workers = [] if "--workers" in args else ["--workers", "1"]    # the last --out given wins
    cmd = ["sweep", "--model", "ob1", "--runs", "2", "--steps", "5", "--quiet", *workers,
           "--out", str(tmp_path / "x.jsonl"), *args]
    err = _err(CliRunner().invoke(main, cmd))
    assert all(n in err for n in needles), err
    assert "resume" not in err
    assert not list(tmp_path.iterdir())  # nothing written


def test_workers_none_means_all_cores_in_the_api(tmp_path):
    spec = make_spec("ob1", particles=(10,), runs=1, steps=3, backend="numpy")
    with pytest.raises(InputError, match="--workers"):
        run_sweep(spec, tmp_path / "a.jsonl", workers=0, progress=False)
    with pytest.raises(InputError, match="--seed"):
        make_spec("ob1", seed=-1)


def test_help_names_existing_commands():
    """Every `pfbench X` a command's help names is a command (the help once pointed to a missing one)."""
    import re

    for cmd in ("sweep", "run"):
        text = " ".join(CliRunner().invoke(main, [cmd, "--help"]).output.split())
        named = set(re.findall(r"`?pfbench ([a-z][a-z-]*)", text))
        assert named and named <= set(main.list_commands(None)), (cmd, named)


def test_second_writer_refuses_naming_the_holder_and_a_stale_lock_is_taken_over(tmp_path):
    spec = make_spec("ob1", particles=(10,), runs=2, steps=3, backend="numpy")
    out = tmp_path / "s.jsonl"
    with exclusive_lock(out, "test"):
        with pytest.raises(InputError, match=rf"PID {os.getpid()}\b"):
            run_sweep(spec, out, workers=1, progress=False)
    assert not out.exists()  # refused before creating the store
    lock_path(out).write_text("999999999\n")  # left by a killed run: the file, but no flock
    rep = run_sweep(spec, out, workers=1, progress=False)
    assert rep.done_now == 2


# --------------------------------------------------------------------------- kill -9
ARGS = ["--model", "ob1", "--particles", "2000,4000", "--filters", "1,2", "--runs", "12", "--steps", "400",
        "--seed", "7", "--backend", "numba", "--quiet"]



def SPEC():  # noqa: N802 - the spec of ARGS
    return make_spec("ob1", particles=(2000, 4000), filters=(1, 2), runs=12, steps=400, seed=7)


def _children(pid: int) -> set[int]:
    """PIDs whose parent is ``pid`` (a /proc scan)."""
    out = set()
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.add(int(d.name))
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _records(journal: Path) -> list[str]:
    keys = []
    for ln in journal.read_text().splitlines()[1:]:
        obj = json.loads(ln)
        if "d" in obj:
            keys.append(obj["d"]["key"])
    return keys


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_kill9_leaves_no_workers_a_second_sweep_refuses_and_resume_is_consistent(tmp_path):
    out = tmp_path / "k.jsonl"
    cmd = [sys.executable, "-m", "pfbench.cli", "sweep", *ARGS, "--workers", "2", "--out", str(out)]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    a = subprocess.Popen(cmd, env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline and a.poll() is None:
            if out.exists() and len(_records(out)) >= 2:  # workers are running and writing
                break
            time.sleep(0.05)
        assert a.poll() is None, a.communicate()
        workers = _children(a.pid)  # the pool's workers (and multiprocessing's resource tracker)
        # a second identical sweep refuses at once, naming the holder (no double work)
        with pytest.raises(InputError, match=rf"being written by PID {a.pid}\b"):
            run_sweep(SPEC(), out, workers=1, progress=False)
        os.kill(a.pid, signal.SIGKILL)
        a.wait(timeout=10)
    finally:
        if a.poll() is None:
            a.kill()
            a.wait()
    assert len(workers) >= 2
    deadline = time.monotonic() + 10  # the kernel's parent-death signal is immediate; watcher <= 0.5 s
    while time.monotonic() < deadline and any(_alive(w) for w in workers):
        time.sleep(0.05)
    survivors = [w for w in workers if _alive(w)]
    for w in survivors:
        os.kill(w, signal.SIGKILL)
    assert not survivors, "worker processes outlived the killed sweep"
    # the lock of the killed sweep is free again: resume to the end
    n_before = len(_records(out))
    assert 0 < n_before < 48
    r = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stderr
    keys = _records(out)
    assert len(keys) == len(set(keys)) == 4 * 12  # no task twice
    ref = tmp_path / "ref.jsonl"
    run_sweep(SPEC(), ref, workers=1, progress=False)
    cols = ["config", "run", "method", "n_particles", "n_filters", "armse", "rmse_1"]
    pd.testing.assert_frame_equal(load_frame(out)[0][cols], load_frame(ref)[0][cols])


def test_no_bare_process_pools_in_pfbench():
    # every worker pool must come from pfbench.procs.process_pool (workers that die with the parent)
    bad = [str(p.relative_to(ROOT)) for p in (ROOT / "pfbench").rglob("*.py")
           if p.name != "procs.py" and "ProcessPoolExecutor(" in p.read_text()]
    assert not bad, bad
