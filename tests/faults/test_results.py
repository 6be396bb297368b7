"""Fault injection on recipe result sets: ``kill -9`` of ``pfbench reproduce thesis:fig2.2
--seed 2`` at every rename of its commit and at a few wall-clock moments, garbage/truncated
records, missing/changed artefacts, unwritable output directories, two concurrent writers,
file permissions. The invariant: a result set that ``report`` accepts belongs to one run (its
files are byte-identical to a clean run with the record's seed); anything else is listed as
damaged and ``report --strict`` exits 2."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from pfbench import recipes, report
from pfbench.cli import main

HERE = Path(__file__).parent
RECIPE = ["reproduce", "thesis:fig2.2", "--backend", "numpy", "--quiet", "--option", "runs=10"]  # files, not statistics
FILES = ("fig2.2.csv", "fig2.2.png")


def _env():
    return dict(os.environ, MPLBACKEND="Agg")


def _cli(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "pfbench.cli", *args], capture_output=True,
                          text=True, timeout=timeout, env=_env())


def _killer(n, mode, *args, **kw):
    return subprocess.Popen([sys.executable, str(HERE / "_killer.py"), str(n), mode, "--", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(_env(), **kw))


def _invoke(*args):
    return CliRunner().invoke(main, list(args))


@pytest.fixture(scope="module")
def refs(tmp_path_factory):
    """Clean result sets of seed 1 and seed 2: {seed: {file: bytes}}."""
    out = {}
    for seed in (1, 2):
        root = tmp_path_factory.mktemp(f"ref{seed}")
        r = _cli(*RECIPE, "--seed", str(seed), "--out", str(root))
        assert r.returncode == 0, r.stderr
        out[seed] = {f: (root / "thesis" / f).read_bytes() for f in FILES}
        out[seed]["root"] = root
    assert out[1]["fig2.2.csv"] != out[2]["fig2.2.csv"]
    return out


def _seed1_set(tmp_path, refs):
    """A complete seed-1 result set under tmp_path (copied from the reference run)."""
    import shutil

    shutil.copytree(refs[1]["root"] / "thesis", tmp_path / "thesis")
    return tmp_path


def _damaged(root):
    return [p for p in report.check_results(root)[1] if p.damaged and p.recipe == "thesis:fig2.2"]


def _assert_consistent_or_flagged(root, refs):
    """Either the record verifies and every file is the clean run of the record's seed, or
    report lists the recipe as damaged (and --strict exits 2)."""
    d = root / "thesis"
    rec, problems = report.verify(d / "fig2.2.json", "thesis:fig2.2")
    if not problems:
        for f in FILES:
            assert (d / f).read_bytes() == refs[rec["seed"]][f], (f, rec["seed"])
        return "consistent", rec["seed"]
    assert _damaged(root), problems
    r = _invoke("report", "--out", str(root), "--strict")
    assert r.exit_code == 2 and "thesis:fig2.2" in r.stderr and "pfbench reproduce thesis:fig2.2" in r.stderr
    assert "Not reproduced / damaged" in (root / "REPORT.md").read_text()
    return "flagged", None


def _no_leftovers(root):
    left = [p.name for p in (root / "thesis").iterdir()
            if p.name.endswith(".tmp") or ".staging@" in p.name]
    assert not left, left


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5])
def test_kill_9_at_each_rename_leaves_old_set_or_a_flagged_one(tmp_path, refs, n):
    # Renames of one run: 1-2 artefacts into the staging dir, 3-4 staged artefacts into
    # results/thesis/, 5 the provenance record. A kill before 3 must leave seed 1 intact, a kill
    # at 4 or 5 leaves seed-2 files beside the seed-1 record: that must be flagged.
    # Mutations caught: writing artefacts straight into results/ (a kill at 2 leaves a seed-2
    # PNG beside the seed-1 record, unflagged); report not verifying checksums.
    root = _seed1_set(tmp_path, refs)
    p = _killer(n, "kill", *RECIPE, "--seed", "2", "--out", str(root))
    p.communicate(timeout=120)
    assert p.returncode == -signal.SIGKILL
    state, seed = _assert_consistent_or_flagged(root, refs)
    assert (state, seed) == (("consistent", 1) if n <= 3 else ("flagged", None))
    # the next run cleans the leftovers of the killed one and leaves a verified seed-2 set
    r = _cli(*RECIPE, "--seed", "2", "--out", str(root))
    assert r.returncode == 0, r.stderr
    _no_leftovers(root)
    assert _assert_consistent_or_flagged(root, refs) == ("consistent", 2)


@pytest.mark.parametrize("ms", [300, 700, 1100])
def test_kill_9_after_n_ms_is_consistent_or_flagged(tmp_path, refs, ms):
    root = _seed1_set(tmp_path, refs)
    p = subprocess.Popen([sys.executable, "-m", "pfbench.cli", *RECIPE, "--seed", "2", "--out",
                          str(root)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=_env())
    time.sleep(ms / 1000)
    p.send_signal(signal.SIGKILL)
    p.wait(timeout=60)
    _assert_consistent_or_flagged(root, refs)
    r = _cli(*RECIPE, "--seed", "2", "--out", str(root))     # cleans up after the killed run
    assert r.returncode == 0, r.stderr
    _no_leftovers(root)


@pytest.mark.parametrize("damage,needle", [
    (lambda d: (d / "fig2.2.json").write_text((d / "fig2.2.json").read_text()[:200]), "damaged"),
    (lambda d: (d / "fig2.2.json").write_bytes(b"\x00\xffgarbage{"), "damaged"),
    (lambda d: (d / "fig2.2.json").write_text('{"recipe": "thesis:fig2.2", "x": NaN}'), "damaged"),
    (lambda d: (d / "fig2.2.json").write_text("[1, 2]"), "not a provenance record"),
    (lambda d: (d / "fig2.2.png").unlink(), "missing"),
    (lambda d: (d / "fig2.2.csv").write_text("t,x\n1,2\n"), "not match"),
])
def test_damaged_records_are_reported_not_dropped(tmp_path, refs, damage, needle):
    # Before: a truncated/garbage record made the recipe vanish from REPORT.md, exit 0, no warning.
    root = _seed1_set(tmp_path, refs)
    assert _invoke("report", "--out", str(root), "--strict").exit_code == 0   # clean set passes
    damage(root / "thesis")
    r = _invoke("report", "--out", str(root))
    assert r.exit_code == 0
    warn = [ln for ln in r.stderr.splitlines() if ln.startswith("warning:")]
    assert len(warn) == 1 and "thesis:fig2.2" in warn[0] and needle in warn[0], r.stderr
    # the command redoes it where and as it was (a bare one wrote to results/ with the defaults)
    assert "Traceback" not in r.stderr
    readable = needle in ("missing", "not match")   # the record itself is intact: its seed is known
    redo = f"pfbench reproduce thesis:fig2.2 --out {root}" + (" --backend numpy --seed 1 --option runs=10`" if readable else "`")
    assert redo in warn[0], warn[0]
    section = (root / "REPORT.md").read_text().split("## Not reproduced / damaged", 1)[1]
    assert "thesis:fig2.2" in [ln for ln in section.splitlines() if needle in ln][0]
    r = _invoke("report", "--out", str(root), "--strict")
    assert r.exit_code == 2 and r.stderr.strip().splitlines()[-1].startswith("error: report --strict")


def test_recipe_needing_tools_is_listed_as_not_run(tmp_path, refs, monkeypatch):
    root = _seed1_set(tmp_path, refs)
    monkeypatch.setattr(recipes, "needs_met", lambda needs: False)
    r = _invoke("report", "--out", str(root), "--strict")
    assert r.exit_code == 0, r.output        # not run is listed, but is not damage
    text = (root / "REPORT.md").read_text()
    assert "- `embedded:mcu`: not run: needs `make mcu-tools`" in text
    assert f"- `thesis:fig2.3`: not run (no result); run `pfbench reproduce thesis:fig2.3 --out {root}`" in text


def test_files_get_normal_permissions(tmp_path):
    # Before: results and REPORT.md were 0600 (the temp-file default).
    old = os.umask(0o022)
    try:
        assert _invoke(*RECIPE, "--out", str(tmp_path)).exit_code == 0
        assert _invoke("report", "--out", str(tmp_path)).exit_code == 0
    finally:
        os.umask(old)
    for f in ("thesis/fig2.2.csv", "thesis/fig2.2.png", "thesis/fig2.2.json", "REPORT.md"):
        assert (tmp_path / f).stat().st_mode & 0o777 == 0o644, f


def _unusable_dirs(tmp_path):
    """Output directories that cannot be written. chmod 0555 does not stop root (CI runs tests as
    root), so as root only the other way is used: a path whose parent is a regular file."""
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    dirs = [blocker / "results"]
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        (ro / "thesis").mkdir(parents=True)
        (ro / "thesis").chmod(0o555)
        ro.chmod(0o555)
        dirs.append(ro)
    return dirs


@pytest.mark.parametrize("cmd", [RECIPE, ["report"]])
def test_unwritable_output_is_one_line_exit_2(tmp_path, cmd):
    # Before: OSError traceback, exit 1.
    for d in _unusable_dirs(tmp_path):
        r = _invoke(*cmd, "--out", str(d))
        assert r.exit_code == 2, (d, r.output)
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("error: cannot") and str(d) in lines[0], r.stderr


def test_second_writer_refused_with_pid_and_stale_lock_taken_over(tmp_path, refs):
    # Before: both ran and wrote the same files.
    ready = tmp_path / "ready"
    a = _killer(3, "hold", *RECIPE, "--seed", "2", "--out", str(tmp_path), KILLER_READY=str(ready))
    try:
        t0 = time.monotonic()
        while not ready.exists():
            assert a.poll() is None and time.monotonic() - t0 < 60, a.communicate()
            time.sleep(0.05)
        r = _cli(*RECIPE, "--seed", "2", "--out", str(tmp_path))
        assert r.returncode == 2, r.stdout + r.stderr
        assert f"PID {a.pid}" in r.stderr and "fig2.2" in r.stderr
    finally:
        a.kill()
        a.wait(timeout=30)
    # A is gone (kill -9): its lock is stale and its staging dir is left; the next run proceeds.
    assert list((tmp_path / "thesis").glob(".fig2.2.staging@*"))
    r = _cli(*RECIPE, "--seed", "2", "--out", str(tmp_path))
    assert r.returncode == 0, r.stderr
    _no_leftovers(tmp_path)
    assert _assert_consistent_or_flagged(tmp_path, refs) == ("consistent", 2)
    assert not (tmp_path / "thesis" / ".fig2.2.lock").exists()  # removed on release
