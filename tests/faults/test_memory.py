"""Check before you spend: runs and sweeps that cannot fit in memory are refused before allocating,
with both numbers and the largest N_p that fits; an out-of-memory that still happens is one line."""
import os
import re
import resource
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import pfbench
from pfbench.errors import InputError
from pfbench.models import get
from pfbench.resources import Limit, MemoryNeed, check_memory, filter_memory, memory_limits

ROOT = Path(__file__).resolve().parents[2]
#: a 2.5 GiB address space: the interpreter with numba loaded uses ~0.5-0.8 GiB of it, so a 1e9
#: particle run (~120 GiB) cannot fit, and any real attempt to allocate it would fail differently
AS_LIMIT = int(2.5 * 2**30)


def _pfbench(*args, as_limit=None, timeout=120):
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (as_limit, as_limit))

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "pfbench.cli", *args], capture_output=True, text=True,
                          timeout=timeout, env=env, cwd=ROOT, preexec_fn=limit if as_limit else None)


def _largest(err: str) -> int:
    m = re.search(r"largest N_p that fits is (\d+)", err)
    assert m, err
    return int(m.group(1))


def _one_line(err: str) -> str:
    err = err.strip()
    assert err.startswith("error:") and "\n" not in err and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("as_limit", [None, AS_LIMIT])
def test_run_with_a_billion_particles_is_refused_before_allocating(as_limit):
    # without a limit: the machine's available memory binds; with one: RLIMIT_AS binds. Before
    # the check, the limited run died with a numpy _ArrayMemoryError traceback (exit 1) and the
    # unlimited one started allocating gigabytes. The message can only come from the check: an
    # allocation under the limit would have raised MemoryError ("out of memory", no N_p).
    n = 10**9 if as_limit else 10**10  # 10^10 x ~100 B exceeds any test machine's memory
    r = _pfbench("run", "--model", "ob1", "--particles", str(n), as_limit=as_limit)
    assert r.returncode == 2, r.stderr
    err = _one_line(r.stderr)
    assert f"--particles {n}" in err and "needs about" in err and "is free" in err
    assert 1 <= _largest(err) < n
    if as_limit:
        assert "RLIMIT_AS" in err
        assert _largest(err) * 64 < AS_LIMIT  # >= 64 B per particle: the N_p fits the limit


def test_largest_n_p_is_exact_for_the_binding_limit():
    need = MemoryNeed(fixed=1000, per_particle=100)
    lim = [Limit(free=1_000_000, source="test", per_process=True)]
    usable = int(1_000_000 * 0.8)
    biggest = (usable - 1000) // 100
    check_memory(need, biggest, what="x", limits=lim)                    # fits exactly
    with pytest.raises(InputError, match=rf"largest N_p that fits is {biggest}\b"):
        check_memory(need, biggest + 1, what="x", limits=lim)
    # what does not grow with N_p (the per-step outputs) alone is too big: the message says so, not
    # only "--particles" (catches a message that sends the user to a flag that cannot help)
    with pytest.raises(InputError, match=r"not even N_p = 1 fits: what does not grow with N_p .* needs 976.6 KiB, "
                                         r"so fewer steps"):
        check_memory(MemoryNeed(fixed=1_000_000, per_particle=100), 10, what="x", limits=lim)


def test_shared_limits_count_every_worker_and_per_process_limits_one():
    need = MemoryNeed(fixed=0, per_particle=100)
    shared = [Limit(free=10_000, source="MemAvailable", per_process=False)]
    check_memory(need, 40, what="x", limits=shared, processes=2)         # 2 x 4000 <= 8000
    with pytest.raises(InputError, match=r"per worker x 2 workers.*largest N_p that fits is 40 .*fewer --workers"):
        check_memory(need, 41, what="x", limits=shared, processes=2)
    own = [Limit(free=10_000, source="RLIMIT_AS", per_process=True)]
    check_memory(need, 80, what="x", limits=own, processes=8)           # each worker has its own


def test_limits_include_the_address_space_limit_in_a_limited_process():
    code = ("import resource; resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30));"
            "from pfbench.resources import memory_limits as m;"
            "print([(L.source.split()[0], L.per_process, L.free < 3 << 30) for L in m()][0])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         env=dict(os.environ, PYTHONPATH=str(ROOT)), timeout=60).stdout
    assert out.strip() == "('address-space', True, True)"
    assert any(L.source.startswith("MemAvailable") for L in memory_limits())


def test_estimate_bounds_the_numpy_backend_peak():
    # tracemalloc sees every NumPy allocation: the estimate must be an upper bound of the real
    # peak (else a run that "fits" could still die) and within 4x of it (else the largest N_p
    # that we advertise would be needlessly small). Catches a dropped buffer/temporary term.
    m = get("ob1")
    tr = m.simulate(5, seed=0)
    n = 200_000
    need = filter_memory(m, "bootstrap", n_steps=5, backend="numpy")
    tracemalloc.start()
    pfbench.run_filter(m, tr.y, tr.u, method="bootstrap", n_particles=n, backend="numpy")
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak <= need.bytes(n) <= 4 * peak


def test_run_filter_api_refuses_too():
    m = get("ob1")
    tr = m.simulate(3, seed=0)
    with pytest.raises(InputError, match=r"n_particles 10000000000000: .*largest N_p"):
        pfbench.run_filter(m, tr.y, tr.u, n_particles=10**13, backend="numpy")
    # the marginalized PF with every state linear runs one copy: any N_p fits
    ob3 = get("ob3")
    t3 = ob3.simulate(3, seed=0)
    assert filter_memory(ob3, "mpf", n_steps=3).per_particle == 0
    assert np.isfinite(pfbench.run_filter(ob3, t3.y, t3.u, method="mpf", n_particles=10**13,
                                          backend="numpy").loglik)


def test_a_memory_error_that_still_happens_is_one_line(monkeypatch):
    from pfbench import cli
    from pfbench.filters import particle

    def boom(*a, **k):
        raise MemoryError("Unable to allocate 7.45 GiB")

    monkeypatch.setattr(particle, "run_groups", boom)
    r = CliRunner().invoke(cli.main, ["run", "--model", "ob1", "--particles", "100", "--steps", "5",
                                      "--backend", "numpy"])
    assert r.exit_code == 2
    assert "out of memory" in _one_line(r.stderr)


def test_sweep_with_too_many_particles_is_refused_before_any_worker(tmp_path):
    out = tmp_path / "s.jsonl"
    r = _pfbench("sweep", "--model", "ob1", "--particles", "100,10000000000", "--runs", "2",
                 "--steps", "5", "--workers", "2", "--quiet", "--out", str(out), as_limit=AS_LIMIT)
    assert r.returncode == 2, r.stderr
    err = _one_line(r.stderr)
    assert "--particles 10000000000" in err and "RLIMIT_AS" in err and _largest(err) > 100
    assert not out.exists()
