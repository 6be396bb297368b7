"""A cold particle kernel compiles pass A in a helper process while the driver compiles here; a
helper that fails costs only the parallelism, and no helper runs where it cannot win."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from pfbench.backends import compile_helper


SCRIPT = r"""
import json, re, sys
import numpy as np
from pfbench.backends import compile_helper, numba_backend
from pfbench.filters.run import run_filter
from pfbench.models import get
from pfbench.backends.kernels import build

started = []
kinds = []
real_start = compile_helper.start


def counting_start(cls, *args):
    started.append(cls.__qualname__)
    if cls.__qualname__ == "Ob1":  # a helper that cannot build its model's kernel: it fails
        cls = type("Nope", (), {"__module__": "pfbench_no_such_module"})
    helper = real_start(cls, *args)
    kinds.append(type(helper).__name__ if helper else None)
    return helper


compile_helper.start = counting_start
out = {}
for name, scheme in (("ob1", "systematic"), ("ob2", "systematic"), ("ob2", "stratified")):
    m = get(name)
    y = m.simulate(15, seed=1).y
    r = run_filter(m, y, n_particles=64, seed=3, resampling=scheme, n_threads=1)
    mod = build("particle", m, scheme)
    a, d = mod._pass_a.stats, mod.run_group.stats
    out[f"{name}/{scheme}"] = {"pass_a": [sum(a.cache_hits.values()), sum(a.cache_misses.values())],
                               "driver_misses": sum(d.cache_misses.values()),
                               "started": list(started), "est": r.estimates.tolist()}
m = get("linear_gaussian")
tr = m.simulate(15, seed=1)
r = run_filter(m, tr.y, tr.u, method="kalman")
mod = build("mpf", m, None)
out["kalman"] = {"step_calls": [[sum(f.stats.cache_hits.values()), sum(f.stats.cache_misses.values())]
                                for f in (mod._time_update, mod._kalman_update, mod._mixture_moments)],
                 "driver_misses": sum(mod.run_linear.stats.cache_misses.values()),
                 "driver_defines": re.findall(r"define [^@]*@(\S+)\(",
                                              mod.run_linear.inspect_llvm(mod.run_linear.signatures[0])),
                 "started": list(started), "est": r.estimates.tolist()}
m = get("ob5")
tr = m.simulate(15, seed=1)
r = run_filter(m, tr.y, tr.u, method="mpf", n_particles=64, seed=3)
mod = build("mpf", m, "systematic")
out["mpf"] = {"model_calls": [[sum(f.stats.cache_hits.values()), sum(f.stats.cache_misses.values())]
                              for f in (mod._cl_transition, mod._cl_observation, mod._cl_constrain,
                                        mod._transition_into, mod._observation_into, mod._constrain_into)],
              "driver_misses": sum(mod.run.stats.cache_misses.values()),
              "driver_defines": re.findall(r"define [^@]*@(\S+)\(", mod.run.inspect_llvm(mod.run.signatures[0])),
              "started": list(started), "est": r.estimates.tolist()}
m = get("pmsm_reduced")
tr = m.simulate(15, seed=1)
r = run_filter(m, tr.y, tr.u, method="guided", n_particles=64, seed=3)
mod = build("guided", m, None)
out["guided"] = {"model_calls": [[sum(f.stats.cache_hits.values()), sum(f.stats.cache_misses.values())]
                                 for f in (mod._propose_into, mod._predictive_into)],
                 "started": list(started), "est": r.estimates.tolist()}
from pfbench.models import load_files
(user,) = load_files([sys.argv[1]])  # a user's model file: its module cannot be imported by name
m = get(user)
r = run_filter(m, m.simulate(15, seed=1).y, n_particles=64, seed=3, n_threads=1)
a = build("particle", m, "systematic")._pass_a.stats
out["user"] = {"pass_a": [sum(a.cache_hits.values()), sum(a.cache_misses.values())],
               "started": list(started), "est": r.estimates.tolist()}
out["kinds"] = kinds
print(json.dumps(out))
"""


def _run_cold(script: str, tmp_path, *args) -> dict:
    """Run ``script`` with ``args`` in a fresh process on empty caches (helpers allowed); its last
    output line."""
    env = dict(os.environ, PFBENCH_CACHE_DIR=str(tmp_path / "pf"), NUMBA_CACHE_DIR=str(tmp_path / "nb"))
    env.pop(compile_helper.ENV, None)
    r = subprocess.run([sys.executable, "-c", script, *map(str, args)], capture_output=True, text=True, env=env,
                       timeout=900, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(compile_helper.usable_cores() < 2, reason="a compile helper needs a second core")
def test_a_cold_kernel_compiles_pass_a_in_a_helper_and_falls_back_when_it_fails(tmp_path, readme_model_file):
    """In one fresh process with an empty cache:

    * Ob1, whose helper fails (it cannot import the model): this process compiles pass A itself (a
      miss) and the results are right. Catches: trusting a helper that failed.
    * Ob2, cold: the helper compiles pass A, this process loads it from disk (a hit, no miss) and
      compiles the driver. Catches: no helper, or a helper that compiles other argument types.
    * Ob2 with another scheme: pass A is compiled already, so no helper starts. Catches: a helper
      for every cold driver.
    * The Kalman filter on the linear-Gaussian model: the helper compiles the step math its
      driver calls, this process loads it (hits) and compiles the driver with the model inlined;
      the driver's code defines none of the steps. Catches: steps called directly.
    * The MPF on Ob5 (three nonlinear states): the helper compiles the model's three functions
      and the kernel's three wrappers that call them, this process loads them (hits, no miss) and
      compiles the driver, whose code defines none of them and none of the step math (called by
      address). Catches: a driver calling the model, a wrapper or a step directly.
    * The guided filter on the reduced PMSM model (the optimal proposal): the helper compiles the
      wrappers of its proposal and predictive likelihood, this process loads them (hits, no
      miss). Catches: a guided run that compiles the model itself.
    * A model from a user's file (the README's, loaded as ``--models`` loads it): the helper
      imports the file by its path and compiles pass A, this process loads it (a hit). Catches: a
      helper that imports the model's module by name only, which a user's file has not.

    Every run gives the estimates of the same run in this (test) process, bit for bit."""
    from pfbench.filters.run import run_filter
    from pfbench.models import get

    path = readme_model_file("helper_growth")
    got = _run_cold(SCRIPT, tmp_path, path)
    assert got.pop("kinds") == ["Popen"] * 6
    ob1, ob2, ob2s = got["ob1/systematic"], got["ob2/systematic"], got["ob2/stratified"]
    assert ob1["pass_a"] == [0, 1] and ob1["driver_misses"] == 1
    assert ob2["pass_a"] == [1, 0] and ob2["driver_misses"] == 1
    assert ob2["started"] == ["Ob1", "Ob2"]
    assert ob2s["started"] == ["Ob1", "Ob2"] and ob2s["driver_misses"] == 1
    kal = got.pop("kalman")
    assert kal["step_calls"] == [[1, 0]] * 3 and kal["driver_misses"] == 1
    assert any("run_linear" in d for d in kal["driver_defines"])
    assert not any(k in d for d in kal["driver_defines"] for k in ("time_update", "kalman_update", "mixture"))
    assert kal["started"] == ["Ob1", "Ob2", "LinearGaussian"]
    m = get("linear_gaussian")
    tr = m.simulate(15, seed=1)
    np.testing.assert_array_equal(np.asarray(kal["est"]), run_filter(m, tr.y, tr.u, method="kalman").estimates)
    mpf = got.pop("mpf")
    assert mpf["model_calls"] == [[1, 0]] * 6 and mpf["driver_misses"] == 1
    assert any("run" in d for d in mpf["driver_defines"])
    steps = ("cl_", "_into", "sandwich", "condition", "time_update", "kalman_update", "weigh", "moments", "normals")
    assert not any(k in d for d in mpf["driver_defines"] for k in steps)  # the model and the steps are not in it
    assert mpf["started"] == ["Ob1", "Ob2", "LinearGaussian", "Ob5"]
    m = get("ob5")
    tr = m.simulate(15, seed=1)
    want = run_filter(m, tr.y, tr.u, method="mpf", n_particles=64, seed=3).estimates
    np.testing.assert_array_equal(np.asarray(mpf["est"]), want)
    guided = got.pop("guided")
    assert guided["model_calls"] == [[1, 0]] * 2
    m = get("pmsm_reduced")
    assert guided["started"][-1] == type(m).__qualname__
    tr = m.simulate(15, seed=1)
    want = run_filter(m, tr.y, tr.u, method="guided", n_particles=64, seed=3).estimates
    np.testing.assert_array_equal(np.asarray(guided["est"]), want)
    user = got.pop("user")
    assert user["pass_a"] == [1, 0] and user["started"][-1] == "MyGrowth"
    from pfbench.models import load_files

    (name,) = load_files([path])
    m = get(name)
    want = run_filter(m, m.simulate(15, seed=1).y, n_particles=64, seed=3, n_threads=1).estimates
    np.testing.assert_array_equal(np.asarray(user["est"]), want)
    for key, res in got.items():
        name, scheme = key.split("/")
        m = get(name)
        want = run_filter(m, m.simulate(15, seed=1).y, n_particles=64, seed=3, resampling=scheme,
                          n_threads=1).estimates
        np.testing.assert_array_equal(np.asarray(res["est"]), want)


def test_no_helper_on_one_core_or_when_switched_off(monkeypatch):
    """Catches: a helper that competes with this process for its only core, or one that ignores
    ``PFBENCH_COMPILE_HELPER=0``."""
    monkeypatch.delenv(compile_helper.ENV, raising=False)
    monkeypatch.setattr(compile_helper, "usable_cores", lambda: 1)
    assert not compile_helper.enabled()
    assert compile_helper.start(type(None), "particle", False, [("_pass_a", ())]) is None
    monkeypatch.setattr(compile_helper, "usable_cores", lambda: 2)
    assert compile_helper.enabled()
    monkeypatch.setenv(compile_helper.ENV, "0")
    assert not compile_helper.enabled()


def test_a_helper_that_cannot_run_reports_failure(monkeypatch):
    """A helper whose model module does not exist exits non-zero, in a child process. Catches: a
    start() that imports the model here (or forks and returns in the child), or a helper that
    exits 0 without compiling."""
    nope = type("Nope", (), {"__module__": "pfbench_no_such_module"})
    monkeypatch.delenv(compile_helper.ENV, raising=False)
    if compile_helper.enabled():
        me = os.getpid()
        helper = compile_helper.start(nope, "particle", False, [("_pass_a", ())])
        assert os.getpid() == me  # this is the caller, not a child that came back
        assert helper.wait() != 0


def test_kill_ends_a_helper_at_once():
    """A helper whose work is no longer wanted (Ctrl-C or an error while the driver compiles) is
    ended with SIGKILL: it holds SIGTERM back while numba compiles
    (:mod:`pfbench.backends.interrupts`). Catches: terminate() (this one ignores SIGTERM and would
    sleep a minute)."""
    import signal

    code = "import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); time.sleep(60)"
    helper = subprocess.Popen([sys.executable, "-c", code])
    compile_helper.stop(helper)
    assert helper.returncode == -signal.SIGKILL

