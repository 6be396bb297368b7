"""pfbench sweep: determinism across workers/executors, resume, corruption, CLI."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

import pfbench
from pfbench import models
from pfbench.errors import PfbenchError
from pfbench.models import get
from pfbench.sweep import load_frame, make_spec, run_chunk, run_multipdf, run_sweep, summarize_frame
from pfbench.sweep.core import SEED_KEY, filter_seed, trajectory_seed
from pfbench.sweep.store import Store, journal_path

COLS = ["config", "run", "method", "n_particles", "n_filters", "armse", "rmse_1"]


def _spec(runs=6, model="ob1", **kw):
    return make_spec(model, particles=(20, 40), filters=(1, 2), runs=runs, steps=20, seed=3, **kw)


def _frame(path):
    return load_frame(path)[0][COLS]


def test_run_multipdf_equals_run_filter():
    m = get("ob4")
    tr = m.simulate(30, seed=1)
    ss = lambda: np.random.SeedSequence(5, spawn_key=(1, 2))  # noqa: E731 (spawn() mutates)
    est, sub = run_multipdf(m, tr.y, m.input_array(tr.u, 30), 60, 3, ss())
    ref = pfbench.run_filter(m, tr.y, tr.u, method="multipdf", n_particles=60, n_filters=3,
                             seed=ss())
    np.testing.assert_array_equal(est, ref.estimates)
    np.testing.assert_array_equal(sub, ref.sub_estimates)


def test_one_vs_two_workers_identical(tmp_path):
    """Catches: numbers that depend on the worker count or on how tasks are batched into units, a
    task written twice, tiny tasks not batched, and workers whose numba pool is not held to their
    share of the cores."""
    from pfbench.procs import usable_cores

    spec = _spec()
    run_sweep(spec, tmp_path / "a.jsonl", workers=1, progress=False)
    run_sweep(spec, tmp_path / "b.parquet", workers=2, progress=False)
    a, b = _frame(tmp_path / "a.jsonl"), _frame(tmp_path / "b.parquet")
    assert len(a) == len(spec["configs"]) * spec["runs"] == 24
    pd.testing.assert_frame_equal(a, b)
    chunks = Store.read(journal_path(tmp_path / "b.parquet")).chunks
    assert sum(c["n"] for c in chunks) == 24                      # every task once
    assert max(len(c["runs"]) for c in chunks) > 1                # ~1 ms tasks: several runs per unit
    assert 1 <= min(c["threads"] for c in chunks) <= max(c["threads"] for c in chunks) <= max(1, usable_cores() // 2)


def test_resume_after_interruption_gives_same_store(tmp_path, monkeypatch):
    import pfbench.sweep.runner as runner

    monkeypatch.setattr(runner, "MIN_UNIT_S", 0.0)  # units of a run or two: the sweep is tiny
    spec = _spec()
    run_sweep(spec, tmp_path / "full.jsonl", workers=1, progress=False)
    part = tmp_path / "part.jsonl"
    run_sweep(spec, part, workers=1, progress=False, max_units=2)  # "interrupted" after 2 units
    n = len(Store.read(part).records)
    assert 0 < n < 24 and n % 4 == 0                                # whole runs: 4 configurations
    with open(part, "a") as fh:                                     # torn write of a crash
        fh.write('{"crc": 1, "d": {"key": "0:5", "arm')
    rep = run_sweep(spec, part, workers=1, progress=False)
    assert rep.done_before == n and rep.done_now == 24 - n
    pd.testing.assert_frame_equal(_frame(part), _frame(tmp_path / "full.jsonl"))
    # re-running a complete sweep does nothing
    assert run_sweep(spec, part, workers=1, progress=False).done_now == 0


def test_batched_resume_reruns_nothing_written(tmp_path):
    """A sweep stopped after two batched units (two workers) resumes with the rest only: every
    task in the journal once, the store equal to an uninterrupted one. Catches a resume that
    reruns written tasks or loses more than the units in flight."""
    spec = _spec(runs=12)
    part = tmp_path / "part.jsonl"
    run_sweep(spec, part, workers=2, progress=False, max_units=2)
    first = Store.read(part)
    assert 0 < len(first.records) < 48 and sum(c["n"] for c in first.chunks) == len(first.records)
    rep = run_sweep(spec, part, workers=1, progress=False)
    assert rep.done_before == len(first.records) and rep.done_now == 48 - len(first.records)
    keys = [json.loads(ln)["d"]["key"] for ln in part.read_text().splitlines()[1:] if '"d":' in ln]
    assert len(keys) == len(set(keys)) == 48
    run_sweep(spec, tmp_path / "full.jsonl", workers=1, progress=False)
    pd.testing.assert_frame_equal(_frame(part), _frame(tmp_path / "full.jsonl"))


def _planner(configs, runs, workers, seconds=None):
    from pfbench.sweep.runner import Planner

    spec = {"configs": configs, "runs": runs}
    recs = [] if seconds is None else [{"config": ci, "elapsed_s": s} for ci, s in enumerate(seconds)]
    return Planner(spec, [(r, list(range(len(configs)))) for r in range(runs)], workers, recs)


def _drain(planner):
    units = []
    while (u := planner.next_unit()) is not None:
        units.append(u)
    return units


def test_planner_batches_tiny_tasks_splits_long_runs_and_hands_out_each_task_once():
    """Catches: one unit per run whatever its size (tiny tasks: the per-unit costs dominate; long
    runs: a ragged tail), units that grow towards the end, and a task handed out twice or never."""
    cfgs = [["bootstrap", 100, 1], ["bootstrap", 1000, 1], ["multipdf", 1000, 2]]
    tiny = _drain(_planner(cfgs, 400, 2, seconds=[0.001, 0.002, 0.002]))   # 5 ms a run
    big = _drain(_planner(cfgs, 4, 8, seconds=[0.5, 3.0, 3.0]))            # 6.5 s a run
    for units, runs in ((tiny, 400), (big, 4)):
        tasks = [(r, ci) for u in units for r, cis in u for ci in cis]
        assert sorted(tasks) == [(r, ci) for r in range(runs) for ci in range(3)]
    assert all(len(u) >= 0.2 / 0.005 for u in tiny[:-1])          # >= MIN_UNIT_S of whole runs
    assert len(tiny) < 400 / 20
    assert all(len(u) == 1 and len(u[0][1]) < 3 for u in big)     # the runs are split ...
    assert big[0][0][1] in ([1], [2])                             # ... the largest tasks first
    sizes = [sum(len(cis) for _, cis in u) for u in tiny]
    assert sizes[0] >= sizes[-1]
    # before a time is known a unit is at most one run
    first = _planner(cfgs, 10, 2).next_unit()
    assert len(first) == 1 and first[0][1] == [0, 1, 2]


def test_planner_hands_out_every_pending_task_once_whatever_the_times(monkeypatch):
    """Random grids, partly finished runs, worker counts and measured times (zero included, and no
    least unit size): every pending task exactly once, no empty group. Catches a split run that
    leaves an empty group behind or drops its last configuration."""
    import random

    import pfbench.sweep.runner as runner

    rng = random.Random(1)
    for _ in range(200):
        monkeypatch.setattr(runner, "MIN_UNIT_S", rng.choice([0.0, 0.2]))
        nc, runs = rng.randint(1, 6), rng.randint(1, 30)
        cfgs = [["bootstrap", rng.choice([10, 100, 1000, 10000]), 1] for _ in range(nc)]
        pending = [(r, sorted(rng.sample(range(nc), rng.randint(1, nc)))) for r in range(runs)]
        planner = runner.Planner({"configs": cfgs, "runs": runs}, pending, rng.randint(1, 20))
        got = []
        while (unit := planner.next_unit()) is not None:
            assert unit and all(cis for _, cis in unit)
            got += [(r, ci) for r, cis in unit for ci in cis]
            planner.learn(unit, [{"config": ci, "elapsed_s": rng.choice([0.0, 1e-4, 0.01, 1.0, 5.0])}
                                 for _, cis in unit for ci in cis], rng.random())
        assert sorted(got) == [(r, ci) for r, cis in pending for ci in cis]


def test_sigterm_then_resume(tmp_path):
    out = tmp_path / "s.jsonl"
    cmd = [sys.executable, "-m", "pfbench.cli", "sweep", "--model", "ob1", "--particles", "1000",
           "--filters", "1,2", "--runs", "300", "--steps", "100", "--seed", "1", "--workers", "1",
           "--quiet", "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.time() + 30
    while time.time() < deadline:
        if out.exists() and out.read_text().count("\n") > 20:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err.decode()[-4000:]  # a crash: the stacks faulthandler printed
    st = Store.read(out)
    assert 0 < len(st.records) < 600
    spec = st.spec
    run_sweep(spec, out, workers=1, progress=False)
    ref = tmp_path / "ref.jsonl"
    small = dict(spec)
    run_sweep(small, ref, workers=1, progress=False)
    pd.testing.assert_frame_equal(_frame(out), _frame(ref))


def test_corrupt_and_foreign_stores(tmp_path):
    spec = _spec(runs=2)
    p = tmp_path / "c.jsonl"
    run_sweep(spec, p, workers=1, progress=False)
    lines = p.read_text().splitlines(keepends=True)
    lines[2] = lines[2].replace('"run":', '"run": 0, "x":', 1)
    p.write_text("".join(lines))
    with pytest.raises(PfbenchError, match="corrupt store at line 3"):
        Store.read(p)
    f = tmp_path / "foreign.jsonl"
    f.write_text('{"hello": 1}\n')
    with pytest.raises(PfbenchError, match="not a pfbench sweep store"):
        run_sweep(spec, f, workers=1, progress=False)
    g = tmp_path / "g.jsonl"
    run_sweep(spec, g, workers=1, progress=False)
    with pytest.raises(PfbenchError, match="different sweep"):
        run_sweep(_spec(runs=3), g, workers=1, progress=False)
    bad = tmp_path / "x.parquet"
    bad.write_bytes(b"PAR1 not really")
    with pytest.raises(PfbenchError):
        load_frame(bad)


def test_dask_localcluster_matches_local(tmp_path):
    pytest.importorskip("distributed")
    spec = _spec(runs=4)
    run_sweep(spec, tmp_path / "l.jsonl", workers=1, progress=False)
    run_sweep(spec, tmp_path / "d.jsonl", workers=2, executor="dask", progress=False)
    pd.testing.assert_frame_equal(_frame(tmp_path / "l.jsonl"), _frame(tmp_path / "d.jsonl"))
    from pfbench.procs import usable_cores

    chunks = Store.read(tmp_path / "d.jsonl").chunks   # the same batching, workers held to their share
    assert sum(c["n"] for c in chunks) == 16 and max(len(c["runs"]) for c in chunks) > 1
    assert 1 <= min(c["threads"] for c in chunks) <= max(c["threads"] for c in chunks) <= max(1, usable_cores() // 2)


def test_summarize_cli(tmp_path):
    from pfbench.cli import main

    out = tmp_path / "s.parquet"
    r = CliRunner().invoke(main, ["sweep", "--model", "ob3:v2", "--particles", "20,40",
                                  "--filters", "1,2", "--method", "multipdf,mpf", "--runs", "3",
                                  "--steps", "10", "--workers", "1", "--quiet", "--backend", "numpy",
                                  "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert out.is_file() and journal_path(out).is_file()
    r = CliRunner().invoke(main, ["sweep", "summarize", str(out), "--json"])
    assert r.exit_code == 0, r.output
    data = json.loads(r.output[: r.output.rindex("]") + 1])
    assert {d["method"] for d in data} == {"multipdf", "mpf"}
    assert load_frame(out)[1]["params"] == {"version": 2}   # the variant is stored as a parameter
    # rows and summary name the full model spec (they said "ob3" for every version)
    assert {d["model"] for d in data} == {"ob3:v2"} and set(load_frame(out)[0]["model"]) == {"ob3:v2"}
    assert all(d["runs"] == 3 and d["armse_lo"] <= d["armse_mean"] <= d["armse_hi"] for d in data)
    assert Path(str(out) + ".summary.png").is_file()
    assert "being written" not in r.output
    from pfbench.procs import exclusive_lock

    with exclusive_lock(out, "test"):   # a sweep writing the store: what it has so far, said so
        r = CliRunner().invoke(main, ["sweep", "summarize", str(out), "--no-plot"])
    assert r.exit_code == 0 and f"is being written by PID {os.getpid()}" in r.output, r.output
    r = CliRunner().invoke(main, ["sweep", "summarize", str(tmp_path / "nope.jsonl")])
    assert r.exit_code == 2 and "does not exist" in r.output
    r = CliRunner().invoke(main, ["sweep", "summarize", str(tmp_path)])   # a folder: not "does not exist"
    assert r.exit_code == 2 and "is a folder" in r.output


def test_summary_interval():
    frame = pd.DataFrame({"method": "multipdf", "n_particles": 10, "n_filters": 1,
                          "armse": [1.0, 2.0, 3.0, 4.0], "elapsed_s": 0.5})
    s = summarize_frame(frame).iloc[0]
    half = 2 * np.std([1, 2, 3, 4], ddof=1) / 2
    assert s["armse_mean"] == 2.5 and s["armse_hi"] - 2.5 == pytest.approx(half)
    assert s["runs_per_s"] == pytest.approx(2.0)


def test_summary_says_how_many_runs_were_not_finite(monkeypatch):
    """A diverged run (NaN or infinite aRMSE) used to vanish from the mean without a word. Catches
    a summary (and `sweep summarize`) that drops runs silently."""
    from click.testing import CliRunner

    from pfbench.cli import main
    from pfbench.metrics import mean_interval

    assert mean_interval([1.0, np.nan, 3.0, np.inf]) == (2.0, pytest.approx(0.0), pytest.approx(4.0), 2)
    frame = pd.DataFrame({"method": "bootstrap", "n_particles": 10, "n_filters": 1,
                          "armse": [1.0, np.nan, 3.0, np.inf], "elapsed_s": 0.5})
    s = summarize_frame(frame, {"model": "ob3", "params": {"version": 4}}).iloc[0]
    assert s["runs"] == 4 and s["dropped"] == 2 and s["armse_mean"] == 2.0 and s["model"] == "ob3:v4"
    assert models.format_spec("ob4", {"shared_noise": True}) == "ob4 shared_noise=true"
    assert models.parse_spec(models.format_spec("ob3", {"version": 4})) == ("ob3", {"version": 4})
    monkeypatch.setattr("pfbench.sweep.store.load_frame",
                        lambda path: (frame, {"model": "ob3", "params": {"version": 4}}, []))
    r = CliRunner().invoke(main, ["sweep", "summarize", "any.jsonl", "--no-plot"])
    assert r.exit_code == 0, r.output
    assert "ob3:v4" in r.stdout and "2 run(s) with a NaN or infinite aRMSE" in r.stderr


def test_grid_file(tmp_path):
    from pfbench.cli import main

    grid = tmp_path / "g.yaml"
    grid.write_text("model: ob4\nparticles: [20, 40]\nfilters: [1, 2]\nruns: 2\nsteps: 10\n"
                    "workers: 1\nquiet: true\n")
    out = tmp_path / "g.jsonl"
    r = CliRunner().invoke(main, ["sweep", "run", "--grid", str(grid), "--runs", "3",
                                  "--out", str(out)])
    assert r.exit_code == 0, r.output
    st = Store.read(out)
    assert st.spec["runs"] == 3 and st.spec["model"] == "ob4" and len(st.records) == 12
    toml = tmp_path / "g.toml"
    toml.write_text('model = "nope"\n')
    r = CliRunner().invoke(main, ["sweep", "--grid", str(toml), "--out", str(out)])
    assert r.exit_code == 2 and "unknown model" in r.output


def test_sweep_takes_a_resampling_scheme(tmp_path):
    """`--resampling` (or a grid's ``resampling``) reaches every configuration: the store's spec
    holds it and the runs differ from the default's, paired on the same seeds. Catches the option
    accepted but not passed on (the default, systematic, run silently)."""
    from pfbench.cli import main

    armse = {}
    for scheme in ("systematic", "multinomial"):
        out = tmp_path / f"{scheme}.jsonl"
        r = CliRunner().invoke(main, ["sweep", "--model", "ob1", "--method", "bootstrap", "--particles", "50",
                                      "--runs", "2", "--steps", "10", "--workers", "1", "--quiet", "--backend",
                                      "numpy", "--resampling", scheme, "--out", str(out)])
        assert r.exit_code == 0, r.output
        st = Store.read(out)
        assert st.spec["resampling"] == scheme
        armse[scheme] = st.frame()["armse"].tolist()
    assert armse["systematic"] != armse["multinomial"]


def test_a_sweep_says_where_the_model_returned_nan_log_likelihoods(tmp_path, log_of_state_file):
    """The tasks whose model returned NaN log-likelihoods for some particles (log of a negative
    state) are counted in the store (invalid_loglik) and said after the sweep; a model without
    them stores 0. Catches the count lost between the kernel and the sweep's record."""
    from pfbench.cli import main

    f = log_of_state_file("sweep_log_of_state")
    out = tmp_path / "s.jsonl"
    with np.errstate(all="ignore"):
        r = CliRunner().invoke(main, ["--models", str(f), "sweep", "--model", "sweep_log_of_state", "--method",
                                      "bootstrap,multipdf", "--filters", "2", "--particles", "100", "--runs", "2",
                                      "--steps", "15", "--workers", "1", "--quiet", "--backend", "numpy",
                                      "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["tasks_with_invalid_loglik"] == 4
    assert "warning: in 4 of 4 tasks the model's log_likelihood returned NaN or +inf" in r.stderr
    assert (Store.read(out).frame()["invalid_loglik"] > 0).all()
    out = tmp_path / "ob1.jsonl"
    r = CliRunner().invoke(main, ["sweep", "--model", "ob1", "--method", "bootstrap", "--particles", "50",
                                  "--runs", "2", "--steps", "10", "--workers", "1", "--quiet", "--backend", "numpy",
                                  "--out", str(out)])
    assert r.exit_code == 0 and "warning" not in r.output and (Store.read(out).frame()["invalid_loglik"] == 0).all()


def test_seed_keys_of_existing_methods_never_change():
    # Stored sweeps of multipdf / bootstrap / mpf keep their numbers only if these stay put.
    assert {m: SEED_KEY[m] for m in ("multipdf", "bootstrap", "mpf")} == {"multipdf": 0, "bootstrap": 1,
                                                                          "mpf": 2}
    assert set(SEED_KEY) == set(pfbench.filters.METHODS) and len(set(SEED_KEY.values())) == len(SEED_KEY)
    spec = {"seed": 3}
    assert filter_seed(spec, ["bootstrap", 20, 1], 4).spawn_key == (1, 1, 20, 1, 4)


@pytest.mark.parametrize("model,params,method,n_f", [
    ("ob1", {}, "sir", 1), ("ob1", {}, "sis", 1), ("ob1", {}, "asir", 1), ("ob1", {}, "bootstrap", 1),
    ("ob4", {}, "multipdf", 2), ("ob2", {}, "mpf", 1), ("linear_gaussian", {}, "kalman", 1),
])
def test_every_method_in_a_sweep_equals_run_filter(model, params, method, n_f):
    # A sweep task is exactly run_filter(method, seed=filter_seed) on the run's trajectory.
    spec = make_spec(model, params=params, methods=[method], particles=(20,), filters=(n_f,), runs=2,
                     steps=12, seed=5, backend="numpy")
    rec = run_chunk(spec, 1, [0])[0]
    m = get(model, **params)
    tr = m.simulate(12, seed=np.random.default_rng(trajectory_seed(spec, 1)))
    ref = pfbench.run_filter(m, tr.y, tr.u, method=method, n_particles=20, n_filters=n_f, backend="numpy",
                             seed=filter_seed(spec, spec["configs"][0], 1))
    r = pfbench.metrics.rmse(ref.estimates, tr.x)
    assert rec["method"] == method and rec["armse"] == pytest.approx(float(np.mean(r)), rel=1e-12)


def test_guided_sweep_on_pmsm():
    try:
        import pfbench.filters.guided  # noqa: F401
    except ImportError:
        pytest.skip("the guided filter (pfbench.filters.guided) is not in this tree yet")
    spec = make_spec("pmsm", methods=["guided"], particles=(20,), runs=1, steps=10, backend="numpy")
    assert run_chunk(spec, 0, [0])[0]["armse"] > 0


def test_sweep_cli_method_sir(tmp_path):
    from pfbench.cli import main

    out = tmp_path / "sir.jsonl"
    r = CliRunner().invoke(main, ["sweep", "--model", "ob1", "--method", "sir,bootstrap", "--particles", "20,40",
                                  "--runs", "2", "--steps", "10", "--workers", "1", "--quiet",
                                  "--out", str(out)])
    assert r.exit_code == 0, r.output
    frame = load_frame(out)[0]
    assert set(frame["method"]) == {"sir", "bootstrap"} and len(frame) == 8
    s = summarize_frame(frame, {"model": "ob1"})
    assert list(s["method"]) == ["bootstrap", "bootstrap", "sir", "sir"]      # Method table order


@pytest.mark.parametrize("args,needle", [
    (["--model", "ob1", "--method", "mpf"], "linear"),                 # the model cannot run it
    (["--model", "ob1", "--method", "nope"], "--method 'nope' is not one of"),  # checked by click, as run's
    (["--model", "ob3:v9"], "version must be 1..5"),
    (["--model", "ob1", "--particles", "10,2.5"], "--particles"),
])
def test_sweep_refuses_before_any_work(tmp_path, args, needle):
    from pfbench.cli import main

    out = tmp_path / "x.jsonl"
    r = CliRunner().invoke(main, ["sweep", *args, "--runs", "2", "--steps", "5", "--workers", "1", "--quiet",
                                  "--out", str(out)])
    assert r.exit_code == 2
    err = r.stderr.strip()
    assert err.startswith("error:") and "\n" not in err and needle in err
    assert not out.exists()


def test_grid_file_model_spec_param_texts_and_unknown_keys(tmp_path):
    from pfbench.cli import main

    grid = tmp_path / "g.yaml"
    grid.write_text("model: ob3:v2\nparam: [q=2]\nmethod: [sir]\nparticles: [20]\nruns: 1\nsteps: 5\n"
                    "workers: 1\nquiet: true\n")
    out = tmp_path / "g.jsonl"
    r = CliRunner().invoke(main, ["sweep", "--grid", str(grid), "--out", str(out)])
    assert r.exit_code == 0, r.output
    spec = Store.read(out).spec
    assert spec["params"] == {"version": 2, "q": 2} and spec["configs"] == [["sir", 20, 1]]
    for text, needle in (("model: ob1\nrunz: 3\n", "runz"), ("model: ob1\nruns: 2.5\n", "--runs")):
        grid.write_text(text)
        r = CliRunner().invoke(main, ["sweep", "--grid", str(grid), "--out", str(tmp_path / "h.jsonl")])
        assert r.exit_code == 2 and needle in r.stderr and "\n" not in r.stderr.strip()


def test_a_remote_dask_worker_takes_its_share_of_the_host(tmp_path):
    """Workers that pfbench did not start (no thread budget), two processes of two Dask threads on
    this host: each task's filter may use usable cores // 4 threads (at least 1), as the journal
    records. Catches: remote workers left without a budget, whose filters would each ask for all
    the host's cores (numba's pool: every core), and the host's threads not summed over workers."""
    pytest.importorskip("distributed")
    from distributed import LocalCluster

    from pfbench.procs import THREADS_ENV, usable_cores

    if usable_cores() < 2:
        pytest.skip("one usable core: every share is one thread")
    env = {k: v for k, v in os.environ.items() if k not in (THREADS_ENV, "NUMBA_NUM_THREADS")}
    with LocalCluster(n_workers=2, threads_per_worker=2, processes=True, host="127.0.0.1",
                      dashboard_address=None, env=env) as cluster:
        run_sweep(_spec(runs=2), tmp_path / "r.jsonl", workers=2, executor="dask",
                  scheduler=cluster.scheduler_address, progress=False)
    chunks = Store.read(tmp_path / "r.jsonl").chunks
    assert chunks and {c["threads"] for c in chunks} == {max(1, usable_cores() // 4)}



_LATE = """

@register("sweep_late_raise")
class LateRaise(MyGrowth):
    @staticmethod
    def log_likelihood(y, x, u, t, p):
        if t >= 3:
            raise RuntimeError("ll boom")
        return MyGrowth.log_likelihood(y, x, u, t, p)

@register("sweep_nan_ll")
class NaNLoglik(MyGrowth):
    @staticmethod
    def log_likelihood(y, x, u, t, p):
        return np.where(t >= 3, np.nan, MyGrowth.log_likelihood(y, x, u, t, p))
"""


def test_a_sweep_names_the_models_errors_and_warns_of_its_non_finite_likelihoods(readme_model_file):
    """As `pfbench run` does: a model's exception at a later step was a traceback the CLI called a
    pfbench bug, and -inf log-likelihoods passed without a word. Catches the sweep's particle runs
    not wrapped, and the warning dropped."""
    from pfbench.cli import main

    f = readme_model_file("sweep_base")
    f.write_text(f.read_text() + _LATE)
    args = ["--models", str(f), "sweep", "--particles", "20", "--runs", "2", "--steps", "6", "--method",
            "bootstrap", "--backend", "numpy", "--workers", "1", "--quiet"]
    r = CliRunner().invoke(main, args + ["--model", "sweep_late_raise", "--out", str(f.with_name("a.parquet"))])
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert "model 'sweep_late_raise': log_likelihood() raised RuntimeError at step 3: ll boom" in r.stderr
    r = CliRunner().invoke(main, args + ["--model", "sweep_nan_ll", "--out", str(f.with_name("b.parquet"))])
    assert r.exit_code == 0, r.output
    assert "warning: 2 of 2 tasks have a log-likelihood of -inf or NaN" in r.stderr


def test_make_spec_takes_one_value_where_a_list_is_meant():
    """From Python, particles=1000 was a TypeError, methods="bootstrap" was split into letters
    ("unknown method 'b'") and a model object "unknown model '<model ...'". Catches either back."""
    from pfbench import models
    from pfbench.errors import InputError

    spec = make_spec("ob1", particles=100, filters=1, methods="bootstrap", runs=2, steps=5)
    assert spec["configs"] == [["bootstrap", 100, 1]]
    # sub-filters asked of methods that have none ran N_f = 1 without a word; beside multipdf they
    # apply to it alone
    with pytest.raises(InputError, match="only multipdf has sub-filters"):
        make_spec("ob1", particles=100, filters=3, methods="bootstrap", runs=2, steps=5)
    spec = make_spec("ob1", particles=100, filters=(1, 3), methods=["bootstrap", "multipdf"], runs=2, steps=5)
    assert spec["configs"] == [["bootstrap", 100, 1], ["multipdf", 100, 1], ["multipdf", 100, 3]]
    with pytest.raises(InputError, match="model must be a registered model spec"):
        make_spec(models.get("ob1"))
