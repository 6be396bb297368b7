"""Compiled code is cached on disk and never stale.

numba's own cache keys a function on its own file only: edit a jitted helper in another module and
a cached caller keeps the old machine code. pfbench keys every cache entry on the whole package
(:mod:`pfbench.backends.cache`); these tests edit a copy of the package between two fresh processes.
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

SCRIPT = """
import json, pfbench
from pfbench.backends.kernels import build
m = pfbench.models.get("ob1"); tr = m.simulate(5, seed=0)
pfbench.run_filter(m, tr.y, method="bootstrap", n_particles=8, backend="numba", seed=0)
st = build("particle", m, "systematic").run_group.stats
print(json.dumps({"hits": sum(st.cache_hits.values()), "misses": sum(st.cache_misses.values())}))
"""


def _run(code: str, env: dict) -> dict:
    # run outside the repository: `python -c` puts the working directory first on sys.path
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600,
                       cwd=env["PFBENCH_CACHE_DIR"].rsplit(os.sep, 1)[0])
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_second_process_loads_kernel_from_disk(tmp_path):
    env = dict(os.environ, PFBENCH_CACHE_DIR=str(tmp_path / "pf"), NUMBA_CACHE_DIR=str(tmp_path / "nb"))
    runs = [_run(SCRIPT, env) for _ in range(2)]
    assert runs[0]["misses"] >= 1
    assert runs[1]["misses"] == 0 and runs[1]["hits"] >= 1


@pytest.fixture()
def package_copy(tmp_path):
    """A copy of the installed package first on PYTHONPATH, with two probe modules: a jitted helper
    in one module and a disk-cached function calling it from another."""
    src = tmp_path / "src"
    shutil.copytree(PACKAGE, src / "pfbench", ignore=shutil.ignore_patterns("__pycache__"))
    (src / "pfbench" / "backends" / "probe_helper.py").write_text(
        "from numba.extending import register_jitable\n\n\n@register_jitable\n"
        "def helper(x):\n    return x + 1.0\n")
    (src / "pfbench" / "backends" / "probe_caller.py").write_text(
        "from pfbench.backends.cache import njit\nfrom pfbench.backends.probe_helper import helper\n\n\n"
        "@njit\ndef caller(x):\n    return 2.0 * helper(x)\n")
    env = dict(os.environ, PYTHONPATH=str(src), PFBENCH_CACHE_DIR=str(tmp_path / "pf"),
               NUMBA_CACHE_DIR=str(tmp_path / "nb"))
    return src / "pfbench", env


PROBE = """
import json, pfbench
from pfbench.backends.probe_caller import caller
assert pfbench.__file__.startswith({root!r}), pfbench.__file__
print(json.dumps({{"value": caller(1.0), "hits": sum(caller.stats.cache_hits.values())}}))
"""


def test_editing_a_helper_in_another_module_recompiles_its_caller(package_copy):
    """caller(1) = 2 (1 + 1) = 4; after the helper becomes x + 10 a fresh process must give 22.
    With numba's own stamp (caller's file unchanged) the second process would load 4 from disk."""
    pkg, env = package_copy
    code = PROBE.format(root=str(pkg))
    first = _run(code, env)
    again = _run(code, env)
    assert first["value"] == 4.0 and again["value"] == 4.0 and again["hits"] >= 1  # cache works
    helper = pkg / "backends" / "probe_helper.py"
    helper.write_text(helper.read_text().replace("x + 1.0", "x + 10.0"))
    assert _run(code, env)["value"] == 22.0


KERNEL = """
import json, numpy as np, pfbench
assert pfbench.__file__.startswith({root!r}), pfbench.__file__
m = pfbench.models.get("ob1"); tr = m.simulate(3, seed=0)
r = pfbench.run_filter(m, tr.y, method="bootstrap", n_particles=16, backend="numba", seed=0,
                       resampling="residual")
print(json.dumps({{"est": r.estimates[:, 0].tolist()}}))
"""


def test_editing_resampling_changes_the_generated_filter_kernel(package_copy):
    """The generated particle kernel inlines residual resampling from numba_resampling.py (systematic
    and stratified are the kernel's own merge); making
    every resampled particle a copy of the first ancestor must change the estimates of step 3."""
    pkg, env = package_copy
    code = KERNEL.format(root=str(pkg))
    before = _run(code, env)["est"]
    res = pkg / "backends" / "numba_resampling.py"
    text = res.read_text()
    line = "            idx[k] = i\n"  # _expand: the residual offspring counts become ancestors
    assert line in text
    res.write_text(text.replace(line, "            idx[k] = 0\n", 1))
    after = _run(code, env)["est"]
    assert before[:1] == after[:1] and before[2] != after[2]


def test_self_healing_cache_is_scoped_to_pfbench_functions(tmp_path):
    """pfbench's njit gives its dispatcher the self-healing cache; numba itself is not patched, so
    ``numba.njit(cache=True)`` code outside pfbench keeps numba's own cache class."""
    import numba
    from numba.core.caching import FunctionCache

    from pfbench.backends import cache

    def outside(x):  # defined in this test file: not pfbench code
        return x + 1.0

    ours = cache.njit(outside)
    theirs = numba.njit(cache=True)(outside)
    assert type(ours._cache).__name__ == "HealingFunctionCache"
    assert type(theirs._cache) is FunctionCache
    assert type(cache.njit(cache=False)(outside)._cache).__name__ == "NullCache"


def test_cache_root_is_the_variable_else_the_environments_else_the_users(monkeypatch, tmp_path):
    """$PFBENCH_CACHE_DIR wins; without it a writable virtual environment keeps its own cache (so
    `make all`, which precompiles, and the activated environment share one); outside one, or in
    one that cannot be written, the user's cache. Catches: the variable ignored, the environment
    not detected, a read-only environment chosen."""
    from pfbench.backends import cache
    from pfbench.mcu import toolchain

    venv = tmp_path / "venv"
    venv.mkdir()
    monkeypatch.setenv("PFBENCH_CACHE_DIR", str(tmp_path / "chosen"))
    monkeypatch.setattr(sys, "prefix", str(venv))
    monkeypatch.setattr(sys, "base_prefix", str(tmp_path / "base"))
    assert cache.cache_root() == tmp_path / "chosen"
    assert toolchain.cache_root() == tmp_path / "chosen" / "mcu"
    monkeypatch.delenv("PFBENCH_CACHE_DIR")
    assert cache.cache_root() == venv / "var" / "cache" / "pfbench"
    monkeypatch.setattr(os, "access", lambda path, mode: False)
    assert cache.cache_root() == Path.home() / ".cache" / "pfbench"
    monkeypatch.undo()
    monkeypatch.delenv("PFBENCH_CACHE_DIR", raising=False)
    monkeypatch.setattr(sys, "base_prefix", sys.prefix)
    assert cache.cache_root() == Path.home() / ".cache" / "pfbench"
