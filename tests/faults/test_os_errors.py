"""Unusable output paths are one line naming the path and what to do (exit 2), never a traceback.

Tests run as root in CI, where ``chmod 0555`` does not stop a write: the unusable paths here are
one whose parent is a regular file (ENOTDIR/EEXIST for anyone, root included), ``/proc`` (takes
no new files) and, for the errno that cannot be produced without mounting a file system
(EROFS, ENOSPC), an OSError injected where the file is opened, or a journal whose writes stop
after a budget of bytes with ENOSPC (as on a full file system: part of a buffer lands, the rest
fails, and closing the file fails again).
"""
import builtins
import errno
import io
import json
import os
from pathlib import Path

import pytest
from click.testing import CliRunner

from pfbench import cli
from pfbench.errors import DataError
from pfbench.sweep import make_spec
from pfbench.procs import lock_path
from pfbench.sweep import store as store_mod
from pfbench.sweep.store import Store

SWEEP = ["sweep", "--model", "ob1", "--particles", "10", "--runs", "1", "--steps", "3", "--workers", "1",
         "--backend", "numpy", "--quiet"]


def _one_line(r, *needles):
    err = r.stderr.strip()
    assert r.exit_code == 2, (r.exit_code, r.output)
    assert err.startswith("error:") and "\n" not in err and "Traceback" not in err, err
    assert all(n in err for n in needles), err
    return err


@pytest.fixture
def a_file(tmp_path):
    f = tmp_path / "plain-file"
    f.write_text("x")
    return f


@pytest.mark.parametrize("sub", ["s.jsonl", "d/s.parquet"])
def test_sweep_out_under_a_regular_file(a_file, sub):
    out = f"{a_file}/{sub}"
    _one_line(CliRunner().invoke(cli.main, [*SWEEP, "--out", out]), out, "choose another --out")


def test_sweep_out_in_proc():
    _one_line(CliRunner().invoke(cli.main, [*SWEEP, "--out", "/proc/pfbench-test.jsonl"]),
              "/proc/pfbench-test.jsonl", "--out")


def test_bench_out_is_checked_before_the_benchmark_runs(a_file, monkeypatch):
    from pfbench import bench

    def never(**kw):  # the check must come first: no minutes of timing for nothing
        raise AssertionError("the benchmark ran before --out was checked")

    monkeypatch.setattr(bench, "run_bench", never)
    out = f"{a_file}/bench.json"
    _one_line(CliRunner().invoke(cli.main, ["bench", "--quick", "--out", out]), out, "--out")
    _one_line(CliRunner().invoke(cli.main, ["bench", "--quick", "--out", "/proc/bench.json"]),
              "/proc/bench.json")


@pytest.mark.parametrize("code,word", [(errno.EROFS, "read-only"), (errno.ENOSPC, "disk is full"),
                                       (errno.EACCES, "permission")])
def test_store_creation_on_a_read_only_or_full_file_system(tmp_path, monkeypatch, code, word):
    def refuse(*a, **k):
        raise OSError(code, os.strerror(code), str(tmp_path / "s.jsonl.tmp"))

    monkeypatch.setattr(Store, "open", classmethod(lambda cls, *a, **k: refuse()))
    out = tmp_path / "s.jsonl"
    _one_line(CliRunner().invoke(cli.main, [*SWEEP, "--out", str(out)]), str(out), word)


def test_journal_append_on_a_full_disk_is_a_data_error(tmp_path, monkeypatch):
    spec = make_spec("ob1", particles=(10,), runs=1, steps=3, backend="numpy")
    st = Store.open(tmp_path / "s.jsonl", spec)

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(DataError, match=r"s\.jsonl: No space left on device; the disk is full"):
        st.append([])
    st.close()


def test_top_level_net_for_a_user_path_but_a_traceback_for_bugs(monkeypatch):
    from pfbench.sweep import cli as sweep_cli

    def raising(exc):
        def f(kw):
            raise exc
        return f

    # an OSError on a user path that no conversion caught: one line naming it
    monkeypatch.setattr(sweep_cli, "_do_run", raising(OSError(errno.EROFS, "Read-only file system", "/mnt/ro/x")))
    _one_line(CliRunner().invoke(cli.main, ["sweep"]), "/mnt/ro/x", "read-only")
    # no file name, or a file of the package itself: a bug, with its traceback and exit 1
    pkg_file = str(Path(cli.__file__).with_name("no-such-table.json"))
    for exc in (OSError(errno.EROFS, "Read-only file system"), OSError(errno.ENOENT, "missing", pkg_file),
                OSError(errno.EBADF, "Bad file descriptor", "/tmp/x")):
        monkeypatch.setattr(sweep_cli, "_do_run", raising(exc))
        r = CliRunner().invoke(cli.main, ["sweep"])
        assert r.exit_code == 1 and "Traceback" in r.stderr and "internal error" in r.stderr


@pytest.mark.parametrize("args", [["run", "--model", "ob1", "--steps", "3", "--particles", "5"],
                                  ["compile", "--model", "ob1", "--jobs", "1"]])
def test_compile_cache_that_cannot_be_written(a_file, args):
    """A compile cache under a regular file: one line naming the directory and PFBENCH_CACHE_DIR,
    before any kernel is compiled, for a run and for `pfbench compile` (where it is a failure,
    exit 2, not a configuration that does not apply). Catches: the first kernel file's write
    error advising "--out", a compile that reports it as "not applicable" and exits 0."""
    import subprocess
    import sys

    # a fresh process: one that has the kernel loaded already writes nothing to the cache
    env = dict(os.environ, PFBENCH_CACHE_DIR=str(a_file / "cache"))
    r = subprocess.run([sys.executable, "-m", "pfbench.cli", *args], capture_output=True, text=True, env=env,
                       timeout=300)
    err = r.stderr.strip()
    assert r.returncode == 2 and err.startswith("error:") and "\n" not in err, (r.returncode, err)
    assert str(a_file / "cache") in err and "PFBENCH_CACHE_DIR" in err and "--out" not in err, err


def test_compile_sorts_errors_into_not_applicable_and_failed(monkeypatch):
    """The run's refusal of a combination (UnsupportedError, InputError) is "not applicable"; a
    DataError (an unusable file or directory) or another PfbenchError is "failed". Catches: a
    DataError (an InputError subclass) counted as not applicable, a failure hidden."""
    import pfbench.filters
    from pfbench import precompile
    from pfbench.errors import InputError, NumericalError, UnsupportedError

    for exc, status in ((UnsupportedError("no structure"), "not applicable"),
                        (InputError("float64 only"), "not applicable"),
                        (DataError("cannot use the cache"), "failed"),
                        (NumericalError("diverged"), "failed")):
        def boom(*a, exc=exc, **k):
            raise exc
        monkeypatch.setattr(pfbench.filters, "run_filter", boom)
        row = precompile.compile_target(precompile.Target("ob1"))
        assert (row["status"], row["detail"]) == (status, str(exc))


class _FullDisk(io.RawIOBase):
    """A file that takes ``budget`` more bytes, then fails every write with ENOSPC."""

    def __init__(self, path, budget):
        self._f = builtins.open(path, "ab", buffering=0)
        self.left = budget

    def writable(self):
        return True

    def write(self, b):
        if self.left <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        n = min(len(b), self.left)
        self._f.write(bytes(b[:n]))
        self.left -= n
        return n

    def fileno(self):
        return self._f.fileno()

    def close(self):
        if not self.closed:
            self._f.close()
        super().close()


def _keys(journal: Path) -> dict:
    """key -> (aRMSE, log-likelihood) of a journal's records (a torn last line, cut by the full disk, left out)."""
    text = journal.read_text()
    out = {}
    for ln in text[: text.rfind("\n") + 1].splitlines()[1:]:
        obj = json.loads(ln)
        if "d" in obj:
            out[obj["d"]["key"]] = (obj["d"]["armse"], obj["d"]["loglik"])
    return out


def test_a_full_disk_during_a_sweep_is_one_line_and_resume_is_exact(tmp_path, monkeypatch):
    # Before: the append's error was replaced by a second ENOSPC when the journal was closed:
    # a traceback and exit 1. Catches: closing the journal without turning its OSError into one line.
    ref = tmp_path / "ref.jsonl"
    assert CliRunner().invoke(cli.main, [*SWEEP, "--runs", "6", "--out", str(ref)]).exit_code == 0
    out = tmp_path / "s.jsonl"
    header = None

    def full_after_two_records(path, mode="r", **kw):
        if mode != "a":  # the header: written before the disk fills
            return builtins.open(path, mode, **kw)
        nonlocal header
        header = header or Path(path).stat().st_size
        raw = _FullDisk(path, budget=(ref.stat().st_size - header) // 3)
        return io.TextIOWrapper(io.BufferedWriter(raw), encoding=kw.get("encoding", "utf-8"))

    monkeypatch.setattr(store_mod, "open", full_after_two_records, raising=False)
    r = CliRunner().invoke(cli.main, [*SWEEP, "--runs", "6", "--out", str(out)])
    _one_line(r, str(out), "disk is full")
    monkeypatch.undo()
    kept = _keys(out)
    assert 0 < len(kept) < 6  # the data written before the disk filled survive
    r = CliRunner().invoke(cli.main, [*SWEEP, "--runs", "6", "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert _keys(out) == _keys(ref)


def test_a_lock_file_that_is_a_symlink_is_one_line(tmp_path):
    # Before: the link's target was truncated to a PID. Catches: an OSError (ELOOP) left unconverted.
    target = tmp_path / "precious.txt"
    target.write_text("keep me\n")
    out = tmp_path / "s.jsonl"
    lock_path(out).symlink_to(target)
    _one_line(CliRunner().invoke(cli.main, [*SWEEP, "--out", str(out)]), str(lock_path(out)), "symbolic link")
    assert target.read_text() == "keep me\n" and not out.exists()
