"""Files that are safe to share: lock files, a report beside a running recipe, a rerun without its
journal, a full disk when a lock takes its PID (a full disk during a sweep and a lock that is a link,
on the command line: test_os_errors.py). Each test names the mutation it catches."""
import errno
import hashlib
import json
import os
from pathlib import Path

import pytest
from click.testing import CliRunner

from pfbench import cli
from pfbench.errors import DataError, InputError
from pfbench.procs import exclusive_lock, lock_path
from pfbench.report import check_results
from pfbench.sweep import make_spec
from pfbench.sweep.runner import run_sweep
from pfbench.sweep.store import journal_path

SPEC_ARGS = dict(particles=(10,), runs=6, steps=3, backend="numpy")


# --------------------------------------------------------------------------- lock files
@pytest.mark.parametrize("link,why", [(Path.symlink_to, "symbolic link"),
                                      (Path.hardlink_to, "not a plain file of its own")])
def test_a_lock_file_that_is_a_link_is_refused_and_its_target_kept(tmp_path, link, why):
    # Before: os.open(O_RDWR | O_CREAT) followed the link and truncated the target to a PID.
    # Catches: dropping O_NOFOLLOW (a symlink's target is overwritten), the hard-link check, or the
    # one-line refusal (an OSError).
    target = tmp_path / "precious.txt"
    target.write_text("keep me\n")
    out = tmp_path / "s.jsonl"
    link(lock_path(out), target)
    with pytest.raises(DataError, match=why):
        with exclusive_lock(out, "test"):
            pass
    assert target.read_text() == "keep me\n"


def test_the_lock_file_is_removed_on_release_and_the_holder_still_refuses_others(tmp_path):
    # Before: every run left its lock file behind. Catches: not unlinking on release, or unlinking
    # while a second holder could take the same path (the second writer must still be refused).
    out = tmp_path / "s.jsonl"
    with exclusive_lock(out, "store"):
        assert lock_path(out).read_text().strip() == str(os.getpid())
        with pytest.raises(InputError, match=rf"PID {os.getpid()}\b"):
            with exclusive_lock(out, "store"):
                pass
        assert lock_path(out).exists()  # the refused second writer did not remove it
    assert not lock_path(out).exists()
    run_sweep(make_spec("ob1", **SPEC_ARGS), out, workers=1, progress=False)
    assert not lock_path(out).exists()


def test_an_acquirer_that_locked_a_removed_lock_file_locks_the_current_one(tmp_path, monkeypatch):
    # The race of removing lock files: B opens the lock file, A releases (unlinks and closes), B gets
    # the flock of a file that no longer has a name, while C creates and locks a new one. B must not
    # believe it holds the lock. Catches: dropping the "path still names the inode I locked" check
    # (B would then hold the lock beside C).
    import pfbench.procs as procs

    out = tmp_path / "s.jsonl"
    real_open = procs._open_lock
    calls = []

    def open_then_release_by_a(path, output, flag):
        fd = real_open(path, output, flag)
        calls.append(fd)
        if len(calls) == 1:  # A's release happens between B's open and B's flock
            os.unlink(path)
            path.write_text("")  # C's fresh lock file at the same name (not locked: B may take it)
        return fd

    monkeypatch.setattr(procs, "_open_lock", open_then_release_by_a)
    with exclusive_lock(out, "store"):
        assert len(calls) == 2  # B went round again and locked the file that bears the name
        assert lock_path(out).read_text().strip() == str(os.getpid())


# --------------------------------------------------------------------------- report beside a commit
def _result_set(root: Path) -> Path:
    """A verified result set of thesis:fig2.2 under root (a record with the checksum of its artefact)."""
    d = root / "thesis"
    d.mkdir(parents=True)
    (d / "fig2.2.csv").write_text("a,b\n1,2\n")
    digest = hashlib.sha256((d / "fig2.2.csv").read_bytes()).hexdigest()
    (d / "fig2.2.json").write_text(json.dumps({"recipe": "thesis:fig2.2", "artefacts": {"fig2.2.csv": digest}}))
    return d


def _damaged(root):
    return [p for p in check_results(root)[1] if p.recipe == "thesis:fig2.2" and p.damaged]


def test_report_skips_a_recipe_that_is_committing_and_strict_does_not_fail(tmp_path):
    # Before: report ran while a recipe committed (artefact renamed, record not yet) and flagged the
    # healthy run as damaged; report --strict exited 2. Catches: checking the recipe's lock no more.
    d = _result_set(tmp_path)
    assert not _damaged(tmp_path)
    (d / "fig2.2.csv").write_text("a,b\n1,3\n")  # the new artefact is in place, its record not yet
    assert _damaged(tmp_path)  # with nobody writing, that is damage
    with exclusive_lock(d / ".fig2.2", "recipe thesis:fig2.2"):  # what `pfbench reproduce` holds
        assert not _damaged(tmp_path)
        notes = [p for p in check_results(tmp_path)[1] if p.recipe == "thesis:fig2.2"]
        assert len(notes) == 1 and "being written" in notes[0].what
        r = CliRunner().invoke(cli.main, ["report", "--strict", "--json", "--out", str(tmp_path)])
        assert r.exit_code == 0, r.output


# --------------------------------------------------------------------------- rerun without the journal
def test_a_rerun_without_its_journal_keeps_the_finished_parquet(tmp_path, monkeypatch):
    # Before: the rerun deleted the finished Parquet before any work, so a kill during the
    # recompute lost the result. Catches: unlinking the export when the journal is created, or
    # recomputing a sweep whose complete export is there.
    spec = make_spec("ob1", **SPEC_ARGS)
    out = tmp_path / "s.parquet"
    run_sweep(spec, out, workers=1, progress=False)
    finished = out.read_bytes()
    journal_path(out).unlink()
    rep = run_sweep(spec, out, workers=1, progress=False)  # complete export: nothing to do
    assert rep.done_now == 0 and rep.done_before == rep.total and out.read_bytes() == finished

    # --overwrite recomputes; killed in the middle (Ctrl-C after one unit), the old result stays
    import pfbench.sweep.runner as runner

    real = runner.run_chunk
    calls = []

    def killed_after_one(*a):
        calls.append(1)
        if len(calls) > 1:
            raise KeyboardInterrupt
        return real(*a)

    monkeypatch.setattr(runner, "run_chunk", killed_after_one)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(spec, out, workers=1, progress=False, overwrite=True)
    assert out.read_bytes() == finished


def test_a_parquet_of_another_sweep_without_journal_is_refused_not_replaced(tmp_path):
    # Catches: a different sweep silently recomputed over a finished result (as the journal of
    # another sweep is refused, so is its export).
    out = tmp_path / "s.parquet"
    run_sweep(make_spec("ob1", **SPEC_ARGS), out, workers=1, progress=False)
    journal_path(out).unlink()
    finished = out.read_bytes()
    with pytest.raises(InputError, match="different sweep.*--overwrite"):
        run_sweep(make_spec("ob1", **dict(SPEC_ARGS, runs=7)), out, workers=1, progress=False)
    assert out.read_bytes() == finished and not journal_path(out).exists()


# --------------------------------------------------------------------------- a full disk
def test_a_full_disk_when_the_lock_takes_its_pid_is_no_error(tmp_path, monkeypatch):
    # Catches: a failed PID write (the disk is full) stopping the run with an OSError traceback.
    import pfbench.procs as procs

    def full(fd, data, offset):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(procs.os, "pwrite", full)
    with exclusive_lock(tmp_path / "s.jsonl", "store") as path:
        assert path.exists()
