"""``pfbench compile``: the configurations it expands to, the kernels it compiles, and that a later
process loads them instead of compiling."""
import json
import os
import subprocess
import sys

import pytest

from pfbench import precompile
from pfbench.backends import numba_backend
from pfbench.precompile import Target


def test_targets_are_every_combination_with_all_threads_only_for_one_particle_filter():
    """Catches: a lost or repeated combination, an all-threads variant for the kernels that have
    none (MultiPDF's sub-filters run one thread each; mpf, guided and kalman are serial), none
    for the single particle filters."""
    got = precompile.targets(["ob1", "ob2", "ob1"], ["bootstrap", "multipdf", "mpf", "sir"],
                             ["systematic", "residual"], ["float64", "float32"], all_threads=True)
    assert len(got) == len(set(got))
    per = {(t.method, t.all_threads) for t in got}
    assert per == {("bootstrap", False), ("bootstrap", True), ("sir", False), ("sir", True),
                   ("multipdf", False), ("mpf", False)}
    assert len(got) == 2 * 2 * 2 * (2 + 2 + 1 + 1)
    assert all(not t.all_threads for t in precompile.targets(["ob1"], ["bootstrap"]))


class _Called(Exception):
    pass


@pytest.mark.parametrize("all_threads", [False, True])
def test_compile_target_runs_the_variant_asked_for(monkeypatch, all_threads):
    """The all-threads target runs the particle kernel with more than one stream block and not on
    one thread (what selects ``run_group_parallel``), the serial one with one block on one thread.
    Catches: both variants compiling the serial kernel (also on a busy machine, whose free cores
    are 1), or the serial target compiling the all-threads one."""
    from pfbench.filters import particle
    from pfbench.procs import numba_threads

    if all_threads and numba_threads() < 2:
        pytest.skip("numba has one thread here: no run uses the all-threads kernel")
    monkeypatch.setattr(particle, "free_cores", lambda: 1)  # a busy machine
    seen = {}

    def record(model, p, rng, y, u, x, *args, brngs=None, n_threads=1, block=None, **kw):
        seen.update(blocks=len(brngs or [rng]), n_threads=n_threads)
        raise _Called

    monkeypatch.setattr(numba_backend, "run_group", record)
    with pytest.raises(_Called):
        precompile.compile_target(Target("ob1", all_threads=all_threads))
    if all_threads:
        assert seen["blocks"] > 1 and seen["n_threads"] != 1
    else:
        assert seen == {"blocks": 1, "n_threads": 1}


def test_compiled_kernels_load_in_a_later_process(tmp_path):
    """``pfbench compile`` on an empty cache, then ``pfbench run``'s default configuration in a new
    process: its kernel loads from the cache (no compile). A method the model does not support is
    "not applicable", not a failure (exit 0). Catches: compiling another configuration than the
    default run (scheme, dtype, variant or parameter types), a cache that is not the one later
    processes read, an unsupported method reported as a failure."""
    env = dict(os.environ, PFBENCH_CACHE_DIR=str(tmp_path / "pf"), NUMBA_CACHE_DIR=str(tmp_path / "nb"))
    r = subprocess.run([sys.executable, "-m", "pfbench.cli", "compile", "--model", "ob1", "--method",
                        "bootstrap,mpf", "--jobs", "1", "--json"], capture_output=True, text=True, env=env,
                       timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    rows = {row["method"]: row for row in json.loads(r.stdout)}
    assert rows["bootstrap"]["status"] == "ready"
    assert rows["mpf"]["status"] == "not applicable" and "linear" in rows["mpf"]["detail"]
    script = ("import json, pfbench\n"
              "from pfbench.backends.kernels import build\n"
              "m = pfbench.models.get('ob1'); tr = m.simulate(20, seed=3)\n"
              "pfbench.run_filter(m, tr.y, tr.u, method='bootstrap', n_particles=1000, seed=3)\n"
              "st = build('particle', m, 'systematic').run_group.stats\n"
              "print(json.dumps({'hits': sum(st.cache_hits.values()), 'misses': sum(st.cache_misses.values())}))\n")
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600,
                       cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout.strip().splitlines()[-1]) == {"hits": 1, "misses": 0}



def test_a_mistake_in_the_models_code_fails_its_target(readme_model_file):
    """A model whose log_likelihood returns complex numbers is the model's failure, not "not
    applicable" (which exits 0 as if the method simply did not apply). Catches ModelError taken
    for a refused combination, and a missing function taken for a mistake."""
    from pfbench import models

    f = readme_model_file("compile_base")
    f.write_text(f.read_text() + (
        "\n@register('compile_complex_ll')\nclass ComplexLoglik(MyGrowth):\n    @staticmethod\n"
        "    def log_likelihood(y, x, u, t, p):\n        return MyGrowth.log_likelihood(y, x, u, t, p) + 0j\n"
        "\n@register('compile_no_ll')\nclass NoLoglik(MyGrowth):\n"
        "    log_likelihood = StateSpaceModel.log_likelihood\n"))
    models.load_files([f])
    row = precompile.compile_target(Target("compile_complex_ll"))
    assert row["status"] == "failed" and "log_likelihood() must return a float array" in row["detail"]
    assert "complex128" in row["detail"]
    # a model without the function a method needs is that method not applying, not a mistake
    row = precompile.compile_target(Target("compile_no_ll"))
    assert row["status"] == "not applicable" and "defines no log_likelihood()" in row["detail"]
