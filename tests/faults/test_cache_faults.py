"""Damaged compiled-code caches heal themselves: one warning line, then the clean-cache numbers.

A cache is populated once per module (a template directory); every test copies it, damages one
file, and runs the same small filter again in a fresh process: exit 0, exactly one
``CacheRepairWarning`` line on stderr naming the damaged file, the file replaced, and the same
numbers, bit for bit, as the first run (same seed, same code: any difference is a wrong entry).

The processes run a snapshot copy of the package, so the cache stamp (a hash of the whole package)
cannot change under the tests while the package is being edited.
"""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import pfbench

PACKAGE = Path(pfbench.__file__).resolve().parent
WARNING = "CacheRepairWarning"

SCRIPT = """
import json, pfbench
from pfbench.backends.numba_backend import kernel_module
m = pfbench.models.get("ob1"); tr = m.simulate(6, seed=3)
r = pfbench.run_filter(m, tr.y, method="bootstrap", n_particles=32, backend="numba", seed=5)
st = kernel_module(m, "particle", "systematic").run_group.stats
print(json.dumps({"est": r.estimates.ravel().tolist(), "var": r.variances.ravel().tolist(),
                  "loglik": r.loglik, "hits": sum(st.cache_hits.values()), "file": kernel_module(m, "particle", "systematic").__file__}))
"""
CLI = ["-c", "import sys; from pfbench.cli import main; sys.exit(main())", "run", "--model", "ob1",
       "--particles", "32", "--steps", "6", "--seed", "5", "--json"]


def _run(args, cache: Path, snapshot: Path, **env_extra) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(snapshot), PFBENCH_CACHE_DIR=str(cache / "pf"),
               NUMBA_CACHE_DIR=str(cache / "nb"), **env_extra)
    env.pop("PYTHONWARNINGS", None)
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env, timeout=600,
                          cwd=str(cache))


@pytest.fixture(scope="module")
def template(tmp_path_factory):
    """(snapshot package dir, populated cache dir, clean-run numbers, clean CLI JSON)."""
    root = tmp_path_factory.mktemp("cachefaults")
    src = root / "src"
    shutil.copytree(PACKAGE, src / "pfbench", ignore=shutil.ignore_patterns("__pycache__"))
    cache = root / "cache"
    cache.mkdir()
    first = _run(["-c", SCRIPT], cache, src)
    assert first.returncode == 0 and first.stderr.strip() == "", first.stderr
    cli = _run(CLI, cache, src)
    assert cli.returncode == 0 and cli.stderr.strip() == "", cli.stderr
    shutil.copytree(cache, root / "pristine", symlinks=True)
    return src, cache, json.loads(first.stdout.splitlines()[-1]), json.loads(cli.stdout.splitlines()[-1])


@pytest.fixture()
def cache(template):
    """The populated cache, restored at its original path (numba keys entries on the source's
    directory, here the generated-kernel directory)."""
    cache = template[1]
    shutil.rmtree(cache)
    shutil.copytree(cache.parent / "pristine", cache, symlinks=True)
    return cache


def _kernel_entry(cache: Path, suffix: str) -> Path:
    """The particle kernel's numba index (``.nbi``) or data file (``.nbc``): the ones a cached run reads."""
    found = sorted((cache / "pf" / "numba").glob(f"kernels_*/k_particle_*run_group*{suffix}"))
    assert len(found) == 1, found
    return found[0]


def _kernel_file(cache: Path) -> Path:
    found = sorted((cache / "pf" / "kernels").glob("k_particle_systematic_*.py"))
    assert len(found) == 1, found
    return found[0]


def _one_warning(stderr: str, path: Path) -> None:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and WARNING in lines[0] and str(path) in lines[0], stderr


def _truncate(p: Path) -> None:
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])


def _empty(p: Path) -> None:
    p.write_bytes(b"")


def _garbage(p: Path) -> None:
    p.write_bytes(b"\x80\x05garbage, not a pickle" * 20)


def _directory(p: Path) -> None:
    p.unlink()
    (p / "sub").mkdir(parents=True)


# current numba: UnpicklingError (truncated .nbc), EOFError read by click as Ctrl-C (empty .nbi,
# "error: interrupted", exit 130), UnpicklingError (garbage .nbi), IsADirectoryError on save (.nbc dir)

def _healed_run(cache, src, target, clean) -> dict:
    """Run on the damaged cache: exit 0, one warning naming ``target``, the clean run's numbers."""
    r = _run(["-c", SCRIPT], cache, src)
    assert r.returncode == 0, r.stderr
    _one_warning(r.stderr, target)
    healed = json.loads(r.stdout.splitlines()[-1])
    assert {k: healed[k] for k in ("est", "var", "loglik")} == {k: clean[k] for k in ("est", "var", "loglik")}
    return healed

@pytest.mark.parametrize("suffix, damage", [(".nbc", _truncate), (".nbi", _garbage), (".nbc", _directory)],
                         ids=["truncated-nbc", "garbage-nbi", "directory-nbc"])
def test_damaged_numba_entry_is_rebuilt(template, cache, suffix, damage):
    src, _, clean, _ = template
    target = _kernel_entry(cache, suffix)
    damage(target)
    _healed_run(cache, src, target, clean)
    assert target.is_file() and target.stat().st_size > 0
    if suffix == ".nbc":  # the rewritten entry loads again, silently (an .nbi repair leaves the .nbc in use)
        again = _run(["-c", SCRIPT], cache, src)
        assert again.returncode == 0 and again.stderr.strip() == "", again.stderr
        assert json.loads(again.stdout.splitlines()[-1])["hits"] >= 1


def test_cli_with_empty_index_exits_0_with_one_warning(template, cache):
    """Today an empty .nbi raises EOFError, which click turns into "error: interrupted", exit 130."""
    src, _, _, clean_cli = template
    target = _kernel_entry(cache, ".nbi")
    _empty(target)
    r = _run(CLI, cache, src)
    assert r.returncode == 0, r.stderr
    _one_warning(r.stderr, target)
    out = json.loads(r.stdout.splitlines()[-1])
    for key in ("loglik", "armse", "rmse", "n_resampled", "n_degenerate_steps"):
        assert out[key] == clean_cli[key], key
    assert target.stat().st_size > 0


def test_entry_holding_another_functions_code_is_recompiled(template, cache):
    """A data file that holds a different function's code (the index written by one process, the
    data by another, or a writer killed in between) must be recompiled, never run as this kernel:
    today numba loads it and calls the wrong machine code."""
    src, _, clean, _ = template
    target = _kernel_entry(cache, ".nbc")
    other = sorted((cache / "pf" / "numba").glob("kernels_*/k_particle_any_scheme_*._pass_a-*.nbc"))
    assert other, "the kernel's pass A was not cached"
    shutil.copyfile(other[0], target)
    r = _run(["-c", SCRIPT], cache, src)
    assert r.returncode == 0, r.stderr
    healed = json.loads(r.stdout.splitlines()[-1])
    assert {k: healed[k] for k in ("est", "var", "loglik")} == {k: clean[k] for k in ("est", "var", "loglik")}


def _syntax_error(p: Path) -> None:
    p.write_text(p.read_text() + "\ndef broken(:\n")


def _binary(p: Path) -> None:
    p.write_bytes(b"\xff\xfe\x00 not python")


# current code: rewrites a truncated or SyntaxError file silently; a non-UTF-8 file or a directory
# is a traceback (UnicodeDecodeError, IsADirectoryError)
@pytest.mark.parametrize("damage", [_truncate, _syntax_error, _binary, _directory],
                         ids=["truncated", "syntax-error", "not-utf8", "directory"])
def test_damaged_generated_kernel_file_is_rewritten(template, cache, damage):
    src, _, clean, _ = template
    target = _kernel_file(cache)
    good = target.read_bytes()
    damage(target)
    healed = _healed_run(cache, src, target, clean)
    assert target.read_bytes() == good
    assert healed["hits"] >= 1  # same text, same stamp: the compiled kernel still loads from disk


def test_damaged_bytecode_of_a_kernel_is_not_used(template, cache):
    """With byte-code writing on (the Python default), a damaged ``__pycache__`` copy of a kernel
    (valid header, truncated body) is an EOFError today ("error: interrupted"); the kernel must be
    executed from the generated text instead."""
    src, _, clean, _ = template
    r = _run(["-c", SCRIPT], cache, src, PYTHONDONTWRITEBYTECODE="")
    assert r.returncode == 0, r.stderr
    kernel = _kernel_file(cache)
    pyc = kernel.parent / "__pycache__" / f"{kernel.stem}.{sys.implementation.cache_tag}.pyc"
    if pyc.exists():
        pyc.write_bytes(pyc.read_bytes()[:40])
    else:  # never written any more: what a damaged one would be
        pyc.parent.mkdir(exist_ok=True)
        st = kernel.stat()
        import importlib.util
        header = importlib.util.MAGIC_NUMBER + b"\0\0\0\0" + int(st.st_mtime).to_bytes(4, "little") \
            + (st.st_size & 0xFFFFFFFF).to_bytes(4, "little")
        pyc.write_bytes(header + b"\xe3\x00\x00")
    env = {"PYTHONDONTWRITEBYTECODE": ""}
    r = _run(["-c", SCRIPT], cache, src, **env)
    assert r.returncode == 0, r.stderr
    healed = json.loads(r.stdout.splitlines()[-1])
    assert {k: healed[k] for k in ("est", "var", "loglik")} == {k: clean[k] for k in ("est", "var", "loglik")}
