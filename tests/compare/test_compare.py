"""pfbench compare: py:, cmd: and broken contenders on two tasks, the agreement of a pure-NumPy
bootstrap with pfbench:bootstrap, the log-likelihood bias on the linear-Gaussian task, one-line
errors, the journal, the leaderboard files. Built-in contenders run with backend=numpy (nothing
to compile), small N_p and few runs, so the file takes seconds."""
import json
import math
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from click.testing import CliRunner

from pfbench.cli import main
from pfbench.compare import contenders as C
from pfbench.compare.run import make_spec, run_chunk
from pfbench.compare.stats import summarize
from pfbench.errors import InputError
from pfbench.verdicts import t_interval

README = Path(__file__).resolve().parents[2] / "README.md"


def _readme_blocks():
    section = README.read_text().split("## Benchmark your own filter", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, re.S)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """The README's two contenders, plus a broken one, written as a user would."""
    d = tmp_path_factory.mktemp("contenders")
    py, cmd = _readme_blocks()
    (d / "my_filter.py").write_text(py)
    (d / "my_filter_cmd.py").write_text(cmd)
    (d / "broken.py").write_text(textwrap.dedent('''
        import numpy as np
        def crash(model, y, u, *, n_particles, seed):
            if model.n_x == 1:
                raise RuntimeError("boom\\nsecond line")
            return {"estimates": np.zeros((3, 3))}          # malformed: wrong shape
        def exits(model, y, u, *, n_particles, seed):
            import sys
            sys.exit(3)
        def hard_exits(model, y, u, *, n_particles, seed):
            import os
            os._exit(0)
    '''))
    (d / "garbage.py").write_text("import sys; sys.stdin.read(); print('not json')\n")
    (d / "vandal.py").write_text(textwrap.dedent('''
        import numpy as np
        from my_filter import bootstrap        # a neighbour module, as a script imports it
        def vandal(model, y, u, *, n_particles, seed):
            print("chatter on standard output")
            out = bootstrap(model, y, u, n_particles=n_particles, seed=seed)
            y[:] = 0.0                         # in place: the next contender's data, and its model
            model.R = model.R * 100.0
            return out
    '''))
    (d / "slow.py").write_text("import sys, time; sys.stdin.read(); time.sleep(30)\n")
    return d


def _invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_a_contender_that_calls_sys_exit_is_a_failed_run(files, tmp_path):
    """sys.exit in a py: contender ended the whole comparison with its exit code and no output.
    Catches SystemExit not taken as the contender's failure."""
    out = tmp_path / "cmp"
    res = _invoke("compare", "--task", "ob1", "--runs", 2, "--particles", 50, "--quiet", "--out", out,
                  "--contender", "pfbench:bootstrap:backend=numpy",
                  "--contender", f"quits=py:{files / 'broken.py'}:exits")
    assert res.exit_code == 0, res.output
    cs = json.loads((out / "compare.json").read_text())["tasks"]["ob1"]["contenders"]
    assert cs["quits"]["failed"] == 2 and list(cs["quits"]["failures"]) == ["SystemExit: 3"]
    assert cs["bootstrap-numpy"]["complete"]


def test_a_contender_that_calls_os_exit_is_a_failed_run(files, tmp_path):
    """os._exit(0) in a py: contender ended pfbench with status 0 and no output, as if it had
    finished. Catches the call not intercepted around the contender (in a process of its own, since
    without the fix the call would end this one)."""
    out = tmp_path / "cmp"
    res = subprocess.run([sys.executable, "-m", "pfbench", "compare", "--task", "ob1", "--runs", "2",
                          "--particles", "50", "--quiet", "--out", str(out),
                          "--contender", "pfbench:bootstrap:backend=numpy",
                          "--contender", f"quits=py:{files / 'broken.py'}:hard_exits"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    cs = json.loads((out / "compare.json").read_text())["tasks"]["ob1"]["contenders"]
    assert cs["quits"]["failed"] == 2
    assert any("os._exit(0)" in reason for reason in cs["quits"]["failures"])
    assert cs["bootstrap-numpy"]["complete"]


def test_readme_contenders_are_short():
    py, cmd = _readme_blocks()
    code = lambda s: [ln for ln in s.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]  # noqa: E731
    assert len(code(py)) <= 20 and len(code(cmd)) <= 10


def test_py_cmd_and_broken_contenders_on_two_tasks(files, tmp_path):
    """The README contenders through py: and cmd:, a crashing/malformed py: one and a cmd: that
    prints garbage, on ob1 and lg-d2: the broken ones are failed runs with
    one-line reasons, the others complete, exit code 0, the leaderboard says so."""
    out = tmp_path / "cmp"
    res = _invoke("compare", "--task", "ob1,lg-d2", "--runs", 3, "--particles", 200, "--quiet",
                  "--out", out, "--timeout", 5,
                  "--contender", "pfbench:bootstrap:backend=numpy",
                  "--contender", f"mine=py:{files / 'my_filter.py'}:bootstrap",
                  "--contender", f"mine-cmd=cmd:{sys.executable} {files / 'my_filter_cmd.py'}",
                  "--contender", f"bad=py:{files / 'broken.py'}:crash",
                  "--contender", f"garbage=cmd:{sys.executable} {files / 'garbage.py'}")
    assert res.exit_code == 0, res.output
    data = json.loads((out / "compare.json").read_text())
    for task in ("ob1", "lg-d2"):
        cs = data["tasks"][task]["contenders"]
        for name in ("bootstrap-numpy", "mine", "mine-cmd"):
            assert cs[name]["complete"] and cs[name]["failed"] == 0, (task, name, cs[name])
        for name in ("bad", "garbage"):
            assert cs[name]["runs"] == 0 and cs[name]["failed"] == 3
            assert all("\n" not in r and "Traceback" not in r for r in cs[name]["failures"])
        # the same filter through py: and cmd: gives the same numbers (JSON round trip)
        assert cs["mine"]["armse"] == pytest.approx(cs["mine-cmd"]["armse"], rel=1e-12)
        assert cs["mine-cmd"]["startup_s"] > 0
    fails = data["tasks"]["ob1"]["contenders"]
    assert list(fails["bad"]["failures"]) == ["RuntimeError: boom"]
    assert "shape (3, 3)" in next(iter(data["tasks"]["lg-d2"]["contenders"]["bad"]["failures"]))
    assert "malformed output" in next(iter(fails["garbage"]["failures"]))
    md = (out / "leaderboard.md").read_text()
    assert "`bad` failed 3 of 3 runs: RuntimeError: boom (3x)" in md
    assert (out / "ob1.png").stat().st_size > 0 and (out / "lg-d2.png").stat().st_size > 0
    assert set(data["complete_contenders"]) == {"bootstrap-numpy", "mine", "mine-cmd"}
    # resumable: the same command again finds every run in the journal and does no work
    again = _invoke("compare", "--task", "ob1,lg-d2", "--runs", 3, "--particles", 200, "--quiet",
                    "--out", out, "--timeout", 5, "--json",
                    "--contender", "pfbench:bootstrap:backend=numpy",
                    "--contender", f"mine=py:{files / 'my_filter.py'}:bootstrap",
                    "--contender", f"mine-cmd=cmd:{sys.executable} {files / 'my_filter_cmd.py'}",
                    "--contender", f"bad=py:{files / 'broken.py'}:crash",
                    "--contender", f"garbage=cmd:{sys.executable} {files / 'garbage.py'}")
    assert again.exit_code == 0
    assert json.loads(again.stdout)["tasks"]["ob1"]["contenders"]["mine"]["armse"] == \
        data["tasks"]["ob1"]["contenders"]["mine"]["armse"]


def test_a_contender_cannot_change_what_the_others_see(files):
    """Each contender gets its own copies of y, u and the model: `vandal` zeroed y and scaled R in
    place, and the exact Kalman filter after it scored a log-likelihood bias of -259 against the
    reference made before. Its file imports a neighbour module, and what it prints goes to
    standard error, so `--json` stays one JSON object. Catches the shared arrays and model, the
    folder missing from sys.path and the prints on stdout."""
    args = ["compare", "--task", "lg-d2", "--runs", 2, "--particles", 50, "--quiet", "--json",
            "--contender", "pfbench:kalman"]
    alone = _invoke(*args)
    res = _invoke(*args, "--contender", f"v=py:{files / 'vandal.py'}:vandal", "--contender", "k2=pfbench:kalman")
    assert res.exit_code == 0 and "chatter" not in res.stdout, res.output
    cs = json.loads(res.stdout)["tasks"]["lg-d2"]["contenders"]
    assert cs["v"]["complete"], cs["v"]
    ref = json.loads(alone.stdout)["tasks"]["lg-d2"]["contenders"]["kalman"]["loglik"]
    assert cs["kalman"]["loglik"] == cs["k2"]["loglik"] == ref
    assert cs["k2"]["vs_baseline"]["loglik"]["verdict"] == "identical within rounding"


def test_a_timeout_ends_what_the_program_started(tmp_path):
    """A program that started a child and hung: the timeout killed the program and left the child
    running, orphaned, to slow every later run. Catches the program not in a session of its own."""
    import os
    import time

    pid_file = tmp_path / "child.pid"
    script = tmp_path / "spawns.sh"
    script.write_text(f"#!/bin/sh\ncat > /dev/null\nsleep 60 &\necho $! > {pid_file}\nwait\n")
    script.chmod(0o755)
    c = C.parse(f"cmd:{script}")
    with pytest.raises(C.RunFailed, match="timed out after 2 s"):
        c._call({"x": 1}, 2.0)
    pid = int(pid_file.read_text())
    for _ in range(50):  # the kernel reaps a killed orphan soon after
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.1)
    else:
        os.kill(pid, 9)
        pytest.fail("the program's child outlived the timeout")


def test_bytes_that_are_not_utf8_on_stderr_do_not_fail_a_run(tmp_path):
    """A correct program that wrote a Latin-1 byte to stderr failed every run with a
    UnicodeDecodeError. Catches the strict decoding."""
    script = tmp_path / "latin1.py"
    script.write_text("import sys, json; sys.stdin.read(); sys.stderr.buffer.write(b'\\xb5s'); "
                      "json.dump({'estimates': [0.0]}, sys.stdout)\n")
    raw, _ = C.parse(f"cmd:{sys.executable} {script}")._call({"x": 1}, 30.0)
    assert raw == {"estimates": [0.0]}


def test_timeout_is_a_failed_run(files, tmp_path):
    res = _invoke("compare", "--task", "ob1", "--runs", 2, "--particles", 10, "--quiet", "--timeout", 1,
                  "--contender", f"mine=py:{files / 'my_filter.py'}:bootstrap",
                  "--contender", f"slow=cmd:{sys.executable} {files / 'slow.py'}", "--json")
    assert res.exit_code == 0, res.output
    s = json.loads(res.stdout)["tasks"]["ob1"]["contenders"]["slow"]
    assert s["failed"] == 2 and next(iter(s["failures"])).startswith("timed out after 1 s")


def _records(spec):
    return [r for run in range(spec["runs"]) for r in run_chunk(spec, run, range(len(spec["configs"])))]


@pytest.mark.parametrize("task", ["ob1", "ob4"])
def test_numpy_bootstrap_agrees_with_pfbench_bootstrap(files, task):
    """Target: the pure-NumPy bootstrap gives pfbench:bootstrap's aRMSE within Monte Carlo error.
    Tolerance derived from the data: the 95 % t-interval of the paired per-run aRMSE differences
    must contain 0 (a wrong filter, e.g. no resampling or unnormalised weights, moves the mean
    difference by many standard errors). Against an independent run of pfbench:bootstrap (its
    sir twin with threshold 1 has other streams), the same rule applies to two filters whose
    difference is pure Monte Carlo noise."""
    spec = make_spec(task, ["pfbench:bootstrap:backend=numpy",
                            f"mine=py:{files / 'my_filter.py'}:bootstrap"], runs=8, n_particles=300)
    s = summarize(spec, _records(spec))["tasks"][task]["contenders"]
    d = s["mine"]["vs_baseline"]["armse"]
    assert d is not None and d["ci"][0] <= 0.0 <= d["ci"][1], d
    # with the shared seeds the two draw the same numbers: equal up to rounding, or noise where
    # the model's arithmetic differs in order
    assert d["verdict"] in ("no difference at 95 %", "identical within rounding")


def test_linear_gaussian_loglik_bias(files):
    """Target: PF log-likelihood bias consistent with zero against the exact (Kalman) value, the
    Kalman contender's |bias| <= 1e-9. The PF's likelihood L_hat is unbiased, so the 95 % interval
    of the mean of L_hat / L over R = 10 runs must contain 1; its log has Jensen's bias -var/2.
    Measured on lg-d2: var(log L_hat) ~ 0.44 at N_p = 2000 (a bias of -0.22, which 10 runs do
    detect), so var ~ 0.09 at N_p = 10^4 (var ~ 1/N_p): a bias of -0.045 against an interval
    half-width t sd/sqrt(R) ~ 2.26 x 0.3 / 3.2 ~ 0.2, consistent with zero as the target asks. A
    dropped constant or a wrong weight shifts log L_hat by whole units and fails both checks."""
    spec = make_spec("lg-d2", ["pfbench:bootstrap:backend=numpy", "kf=pfbench:kalman:backend=numpy",
                               f"mine=py:{files / 'my_filter.py'}:bootstrap", "filterpy:ekf"],
                     runs=10, n_particles=10000)
    recs = _records(spec)
    s = summarize(spec, recs)["tasks"]["lg-d2"]["contenders"]
    for name in ("bootstrap-numpy", "mine"):
        lo, hi = s[name]["lik_ratio_ci"]
        assert lo <= 1.0 <= hi, (name, s[name]["lik_ratio_ci"])
        blo, bhi = s[name]["loglik_bias_ci"]
        assert blo <= 0.0 <= bhi, (name, s[name]["loglik_bias_ci"])
        assert s[name]["loglik_variance"] < 0.2
    for name in ("kf", "filterpy:ekf"):
        errs = [abs(r["loglik_error"]) for r in recs if r["contender"] == name]
        assert len(errs) == 10 and max(errs) <= 1e-9, (name, max(errs))
        assert s[name]["armse_vs_exact"] < 1e-9
    assert s["kf"]["coverage90"] == pytest.approx(0.9, abs=0.05)


@pytest.mark.parametrize("args,needle", [
    (["--task", "nope", "--contender", "pfbench:bootstrap"], "unknown task 'nope'"),
    (["--task", "ob1", "--contender", "what:ever"], "SPEC must be"),
    (["--task", "ob1", "--contender", "pfbench:nomethod"], "unknown method"),
    (["--task", "ob1", "--contender", "pfbench:bootstrap:colour=red"], "colour"),
    (["--task", "ob1", "--contender", "py:/no/such/file.py:f"], "does not exist"),
    (["--task", "ob1", "--contender", "py:json:no_such_function"], "no function"),
    (["--task", "ob1", "--contender", "cmd:/no/such/program --x"], "not found"),
    (["--task", "ob1", "--contender", "pfbench:bootstrap", "--contender", "pfbench:bootstrap"],
     "two contenders are called"),
    (["--task", "ob1", "--contender", "pfbench:bootstrap", "--runs", "101"], "has 100 datasets"),
    (["--task", "ob1", "--contender", "pfbench:bootstrap", "--baseline", "x"], "--baseline"),
])
def test_bad_input_is_one_line_and_exit_2(args, needle):
    res = CliRunner().invoke(main, ["compare", *args])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and needle in lines[0], res.stderr


def test_exit_2_when_no_contender_completes(files, tmp_path):
    res = _invoke("compare", "--task", "ob1", "--runs", 2, "--particles", 10, "--quiet",
                  "--contender", f"bad=py:{files / 'broken.py'}:crash")
    assert res.exit_code == 2 and "no contender completed every run" in res.stderr
    assert "RuntimeError: boom" in res.stdout


def test_spec_parsing():
    assert C.split_name("pfbench:sir:ess_threshold=0.3") == (None, "pfbench:sir:ess_threshold=0.3")
    assert C.split_name("fast=pfbench:sir") == ("fast", "pfbench:sir")
    c = C.parse("pfbench:multipdf:filters=4,resampling=stratified")
    assert c.name == "multipdf-4-stratified" and c.options == {"filters": 4, "resampling": "stratified"}
    assert C.parse("py:json:dumps").func is json.dumps
    with pytest.raises(InputError, match="filters"):
        C.parse("pfbench:multipdf:filters=2.5")


def test_make_spec_from_python_values():
    """From Python: one contender as a string was split into letters ("--contender 'p'"), runs=2.5
    and n_particles=300.7 were cut to 2 and 300. Catches either back."""
    import numpy as np

    spec = make_spec("ob1", "pfbench:bootstrap", runs=np.int64(2), n_particles=300)
    assert [c["spec"] for c in spec["contenders"]] == ["pfbench:bootstrap"] and spec["runs"] == 2
    for kw, says in ((dict(runs=2.5), "--runs must be an integer >= 1, got 2.5"),
                     (dict(n_particles=300.7), "--particles must be an integer >= 1, got 300.7"),
                     (dict(runs=True), "--runs must be an integer")):
        with pytest.raises(InputError, match=re.escape(says)):
            make_spec("ob1", "pfbench:bootstrap", **kw)



@pytest.mark.parametrize("spec, says", [("pfbench:bootstrap:resampling=sys", "unknown resampling scheme 'sys'"),
                                        ("pfbench:bootstrap:threads=0", "threads must be >= 1"),
                                        ("pfbench:multipdf:filters=0", "filters must be >= 1"),
                                        ("pfbench:sir:ess_threshold=1.5", "ess_threshold must be a fraction"),
                                        ("pfbench:bootstrap:dtype=float16", "unknown dtype 'float16'"),
                                        # accepted, then every run failed
                                        ("pfbench:bootstrap:filters=2", "filters applies to pfbench:multipdf only"),
                                        ("pfbench:bootstrap:ess_threshold=0.5",
                                         "ess_threshold applies to pfbench:sir only")])
def test_a_pfbench_contenders_values_are_refused_up_front(spec, says):
    """They were accepted, and every run then failed with the same error (threads=0 even ran, as a
    contender named bootstrap-0). Catches any of the checks dropped."""
    with pytest.raises(InputError, match=rf"^--contender {re.escape(spec)}: {re.escape(says)}"):
        C.parse(spec)


def test_normalise_rejects_malformed():
    with pytest.raises(C.RunFailed, match="no 'estimates'"):
        C.normalise({"loglik": 1.0}, 3, 1, 0.0)
    with pytest.raises(C.RunFailed, match="non-finite"):
        C.normalise({"estimates": [1.0, math.nan, 2.0]}, 3, 1, 0.0)
    with pytest.raises(C.RunFailed, match="loglik"):
        C.normalise({"estimates": [1.0, 2.0, 3.0], "loglik": "x"}, 3, 1, 0.0)
    out = C.normalise({"estimates": [1.0, 2.0, 3.0], "loglik": -2, "elapsed_s": 0.5}, 3, 1, 1.0)
    assert out.estimates.shape == (3, 1) and out.loglik == -2.0 and out.own_s == 0.5
    # outputs that were accepted: each left a metric out, or skewed it, unseen
    est = {"estimates": [1.0, 2.0, 3.0]}
    for raw, says in (({**est, "log_lik": -2.0}, "unknown key 'log_lik' (did you mean 'loglik'?)"),
                      ({**est, "loglik": math.nan}, "log-likelihood nan"),
                      ({**est, "loglik": -math.inf}, "log-likelihood -inf (every particle weight zero"),
                      ({**est, "variances": [1.0, -1.0, 1.0]}, "1 variances are negative or not finite"),
                      ({**est, "elapsed_s": 1e6}, "'elapsed_s' 1e+06 s is not within the call's 1 s"),
                      ({**est, "elapsed_s": "0.5"}, "'elapsed_s' must be a number"),
                      ({**est, "n_particles": 2.5}, "'n_particles' must be an integer >= 0")):
        with pytest.raises(C.RunFailed) as err:
            C.normalise(raw, 3, 1, 1.0)
        assert says in str(err.value), (raw, err.value)
    assert C.normalise({**est, "ess": [1, 2, 3]}, 3, 1, 1.0).loglik is None  # a key of its own: ignored


def test_pareto_front():
    from pfbench.compare.leaderboard import pareto

    pts = [(1.0, 5.0), (2.0, 4.0), (3.0, 4.5), (0.5, 9.0), (4.0, 1.0)]
    assert pareto(pts) == [3, 0, 1, 4]


def test_paired_interval_matches_scorecard_rule():
    from pfbench.compare.stats import paired

    a = {r: {"armse": 1.0 + 0.1 * r} for r in range(5)}
    b = {r: {"armse": 1.2 + 0.1 * r + 0.01 * (-1) ** r} for r in range(5)}
    p = paired(a, b, "armse")
    ti = t_interval([a[r]["armse"] - b[r]["armse"] for r in range(5)])
    assert p["ci"] == [ti[1], ti[2]] and p["verdict"] == "lower"
    # the last bits of one filter on two backends: a zero-width interval read as "lower"
    c = {r: {"armse": v["armse"] * (1.0 + 2e-16 * (-1) ** r)} for r, v in a.items()}
    assert paired(c, a, "armse") == {"mean": 0.0, "ci": [0.0, 0.0], "n": 5, "verdict": "identical within rounding"}


def test_real_data_ranks_by_the_mean_log_likelihood():
    """On real data the spread of the log-likelihood ranked alone, so a filter returning one wrong
    value every run (spread 0) came first, and one with no log-likelihood had a rank. Catches the
    ranking by the spread, and a rank without the metric."""
    from pfbench.compare.leaderboard import _rank, markdown, ranked

    def stats(ll, sd):
        return {"complete": True, "runs": 3, "failed": 0, "missing": 0, "failures": {}, "loglik": ll,
                "loglik_sd": sd, "ns_per_particle_step": 1.0, "loglik_ci": None}

    task = {"data": "real", "model": "sv", "steps": 10, "reference": None, "runs": 3, "baseline": "pf",
            "n_particles": 10, "contenders": {"pf": stats(-492.0, 0.8), "const": stats(-1000.0, 0.0),
                                              "none": stats(None, None), "better": stats(-491.5, 0.3)}}
    assert _rank(task)[:3] == ["better", "pf", "const"] and not ranked(task, "none")
    md = markdown({"runs": 3, "n_particles": 10, "baseline": "pf", "tasks": {"sv": task},
                   "complete_contenders": list(task["contenders"])})
    assert "| – | `none` |" in md and "Δ log-lik vs baseline" in md and "mean log-likelihood (higher first)" in md


def test_particles_adapter_runs_when_available():
    """The particles adapter's Feynman-Kac bootstrap against pfbench's on sv-gbpusd (real data):
    the two log-likelihood estimates agree within Monte Carlo error (paired-free: each mean's
    95 % interval, widened by the other's)."""
    if C.particles_python() is None:
        try:
            import particles  # noqa: F401
        except ImportError:
            pytest.skip("`particles` is not importable here (it pins NumPy < 2) and no "
                        ".venv-particles / PFBENCH_PARTICLES_PYTHON was found")
    spec = make_spec("sv-gbpusd", ["pfbench:bootstrap:backend=numpy", "particles:bootstrap"],
                     runs=3, n_particles=300)
    s = summarize(spec, _records(spec))["tasks"]["sv-gbpusd"]["contenders"]
    assert s["particles:bootstrap"]["complete"], s["particles:bootstrap"]["failures"]
    a, b = s["bootstrap-numpy"], s["particles:bootstrap"]
    se = math.hypot(a["loglik_sd"], b["loglik_sd"]) / 2.0
    assert abs(a["loglik"] - b["loglik"]) < 4.0 * se + 0.5


def test_dask_cluster_gives_the_local_numbers(files, tmp_path):
    """The same comparison on a Dask cluster (a LocalCluster of 2 workers, as `--executor dask`
    without --scheduler starts) gives the local run's numbers: the grid runs on the sweep machinery
    unchanged. Catches a contender spec or dataset seed lost on the way to a worker."""
    pytest.importorskip("distributed")
    args = ["--task", "ob1", "--runs", 2, "--particles", 100, "--quiet", "--json",
            "--contender", "pfbench:bootstrap:backend=numpy",
            "--contender", f"mine=py:{files / 'my_filter.py'}:bootstrap"]
    local = _invoke("compare", *args, "--out", tmp_path / "local")
    dask = _invoke("compare", *args, "--out", tmp_path / "dask", "--executor", "dask", "--workers", 2)
    assert local.exit_code == 0 and dask.exit_code == 0, dask.output
    a, b = (json.loads(r.stdout)["tasks"]["ob1"]["contenders"] for r in (local, dask))
    for name in ("bootstrap-numpy", "mine"):
        assert b[name]["runs"] == 2 and b[name]["armse"] == pytest.approx(a[name]["armse"], rel=1e-12)


def test_resume_follows_the_cmd_script_and_not_the_baseline(files, tmp_path):
    """An edited cmd: script resumed with the old runs (a py: file was refused); another
    --baseline, which only pairs the results, was refused. Catches the cmd: files left out of the
    code fingerprint, and the baseline kept in the journal's spec."""
    script = tmp_path / "f.py"
    script.write_text((files / "my_filter_cmd.py").read_text())
    (tmp_path / "my_filter.py").write_text((files / "my_filter.py").read_text())
    args = ["compare", "--task", "ob1", "--runs", 2, "--particles", 20, "--quiet", "--out", tmp_path / "o",
            "--contender", "pfbench:bootstrap:backend=numpy", "--contender", f"c=cmd:{sys.executable} {script}"]
    assert _invoke(*args).exit_code == 0
    again = _invoke(*args, "--baseline", "c", "--json")
    assert again.exit_code == 0, again.output
    assert json.loads(again.stdout)["baseline"] == "c"
    script.write_text(script.read_text() + "# edited\n")
    edited = _invoke(*args)
    assert edited.exit_code == 2 and "differs in: code" in edited.output, edited.output


def test_a_name_the_workers_cannot_find_is_said_so(tmp_path, monkeypatch):
    """A task defined in the caller only (a notebook, a script's __main__) is unknown to the spawned
    workers: their initializer failed, the pool broke, and the user read "a sweep worker process
    died (killed, e.g. by the out-of-memory killer)". Catches the initializer's failure breaking the
    pool."""
    from pfbench import tasks
    from pfbench.compare.run import run_compare
    from pfbench.errors import UnknownNameError

    monkeypatch.setitem(tasks.TASKS, "here-only", tasks.Task("here-only", "ob1", 5, datasets=2))
    spec = make_spec(["here-only"], ["pfbench:bootstrap:backend=numpy"], runs=2, n_particles=10)
    with pytest.raises(UnknownNameError, match="unknown task .here-only..*start afresh.*define them in a module"):
        run_compare(spec, tmp_path / "j.jsonl", workers=2, progress=False)


def test_intervals_of_nonnegative_quantities_stop_at_zero_and_a_silent_baseline_is_said():
    """At R = 2 the t-interval of an aRMSE or of L̂/L went below zero ([-13.4, 18.8]); a baseline
    that completed no run left every Δ as "—" without a word. Catches either back."""
    from pfbench.compare.leaderboard import markdown
    from pfbench.compare.stats import contender_stats

    recs = [{"ok": True, "armse": v, "loglik": -v, "loglik_error": e} for v, e in ((0.1, -3.0), (3.0, 2.0))]
    s = contender_stats(recs, 2)
    assert s["armse_ci"][0] == 0.0 < s["armse_ci"][1] and s["lik_ratio_ci"][0] == 0.0
    assert contender_stats(recs, 2)["loglik_ci"][0] < 0.0          # a log-likelihood may be negative
    task = {"data": "simulated", "model": "m", "steps": 3, "reference": None, "runs": 2, "baseline": "b",
            "n_particles": 5, "contenders": {"b": {**contender_stats([], 2), "complete": False}, "a": s}}
    md = markdown({"runs": 2, "n_particles": 5, "baseline": "b", "tasks": {"t": task}, "complete_contenders": ["a"]})
    assert "The baseline `b` completed no run: no paired differences." in md


def test_a_method_that_cannot_run_a_task_does_not_apply_rather_than_fail(tmp_path):
    """pfbench:kalman in a comparison over ob1 and lg-d2 failed every ob1 run and so never counted
    as complete; it does not apply to ob1 (a nonlinear model), and completes lg-d2. Catches the
    UnsupportedError taken for a failure."""
    res = _invoke("compare", "--task", "ob1,lg-d2", "--runs", 2, "--particles", 20, "--quiet", "--json",
                  "--contender", "pfbench:bootstrap:backend=numpy", "--contender", "pfbench:kalman")
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    k_ob1 = data["tasks"]["ob1"]["contenders"]["kalman"]
    assert k_ob1["failed"] == 0 and "linear-Gaussian substructure" in k_ob1["not_applicable"]
    assert data["tasks"]["lg-d2"]["contenders"]["kalman"]["complete"]
    assert set(data["complete_contenders"]) == {"bootstrap-numpy", "kalman"}
    md = _invoke("compare", "--task", "ob1", "--runs", 2, "--particles", 20, "--quiet",
                 "--contender", "pfbench:bootstrap:backend=numpy", "--contender", "pfbench:kalman").stdout
    assert "- `kalman` does not apply to this task:" in md and "| does not apply |" in md


def test_overwrite_with_other_tasks_leaves_no_old_plot(tmp_path):
    """--overwrite with fewer tasks left the old <task>.png beside the new leaderboard. Catches the
    old plots kept."""
    args = ["compare", "--runs", 2, "--particles", 20, "--quiet", "--out", tmp_path,
            "--contender", "pfbench:bootstrap:backend=numpy"]
    assert _invoke(*args, "--task", "ob1,lg-d2").exit_code == 0 and (tmp_path / "ob1.png").is_file()
    assert _invoke(*args, "--task", "lg-d2", "--overwrite").exit_code == 0
    assert not (tmp_path / "ob1.png").exists() and (tmp_path / "lg-d2.png").is_file()
