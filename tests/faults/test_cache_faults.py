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
from pfbench.backends.kernels import build
m = pfbench.models.get("ob1"); tr = m.simulate(6, seed=3)
r = pfbench.run_filter(m, tr.y, method="bootstrap", n_particles=32, backend="numba", seed=5)
st = build("particle", m, "systematic").run_group.stats
print(json.dumps({"est": r.estimates.ravel().tolist(), "var": r.variances.ravel().tolist(),
                  "loglik": r.loglik, "hits": sum(st.cache_hits.values())}))
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
    """The populated cache, restored at its original path."""
    cache = template[1]
    shutil.rmtree(cache)
    shutil.copytree(cache.parent / "pristine", cache, symlinks=True)
    return cache


def _kernel_entry(cache: Path, suffix: str) -> Path:
    """The particle kernel's numba index (``.nbi``) or data file (``.nbc``): the ones a cached run reads."""
    found = sorted((cache / "pf" / "numba").glob(f"backends_*/pfbench_kernel_particle_0_*/*run_group-*{suffix}"))
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
    other = sorted((cache / "pf" / "numba").glob("backends_*/pfbench_kernel_particle_any_*/*._pass_a-*.nbc"))
    assert other, "the kernel's pass A was not cached"
    shutil.copyfile(other[0], target)
    r = _run(["-c", SCRIPT], cache, src)
    assert r.returncode == 0, r.stderr
    healed = json.loads(r.stdout.splitlines()[-1])
    assert {k: healed[k] for k in ("est", "var", "loglik")} == {k: clean[k] for k in ("est", "var", "loglik")}
