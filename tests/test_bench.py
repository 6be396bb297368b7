"""`pfbench bench`: every figure it reports is there and is computed from the timings of the same
run; the C reference builds, filters and draws proper normals; the scaling and startup sections
measure what they say. No wall-clock value is asserted (timings belong in the benchmark itself)."""
import math
import os
import sys

import numpy as np
import pytest

from pfbench.bench import c_reference, main_text, run_bench, scaling, startup, summarize
from pfbench.bench.report import TARGETS, check
from pfbench.bench.timing import interleaved, paired_ratio, ratio_range

HAVE_CC = c_reference.compiler() is not None


@pytest.fixture(scope="module")
def res():
    return run_bench(repeats=1, quick=True, with_particles=False, progress=False)


def test_rows_cover_backends_and_dtypes(res):
    assert {(r["backend"], r["dtype"]) for r in res["rows"]} == {
        (b, d) for b in ("numba", "numpy") for d in ("float64", "float32")}
    for r in res["rows"]:
        assert math.isfinite(r["ns_per_particle_step"]) and r["ns_per_particle_step"] > 0
        assert r["threads"] == (1 if r["backend"] == "numba" else None)  # targets are per 1 thread
    for f in res["floors"]:
        assert set(f["breakdown_ns"]) == {"normal", "normal_engine", "exp", "exp_engine", "memory_pass"}
        assert all(v > 0 for v in f["breakdown_ns"].values())


def test_kernel_parts_are_timed_and_reported(res):
    """Each part of the particle kernel is timed (positive, finite) and the unaccounted rest is the
    whole filter minus the three passes. Catches a part left out of the sum or of the printed line."""
    d = res["kernel_parts"]
    for k in ("normals", "model", "transition_c", "transition_f", "pass_a", "exp", "pass_b", "resample",
              "filter"):
        assert math.isfinite(d[k]) and d[k] > 0, k
    assert d["rest"] == pytest.approx(d["filter"] - d["pass_a"] - d["pass_b"] - d["resample"])
    assert any(line.startswith("kernel parts") and "resampling + gather" in line for line in main_text(res))


def test_float32_parts_are_measured_in_both_dtypes(res):
    """The float32 account: every compared part timed in each dtype at the large N_p, and the printed
    speed-ups are float64 / float32 of those parts. Catches parts timed in one dtype only (the
    float32 harness silently running float64), a speed-up inverted, or medians not of the rounds."""
    from pfbench.bench.passes import _COMPARED

    dp = res["dtype_parts"]
    big = res["summary"]["big_config"]["particles"]
    assert [dp[dt]["dtype"] for dt in ("float64", "float32")] == ["float64", "float32"]
    for dt in ("float64", "float32"):
        assert dp[dt]["particles"] == big
        for k, _ in _COMPARED:
            assert math.isfinite(dp[dt][k]) and dp[dt][k] > 0, k
    line = next(x for x in main_text(res) if x.startswith("float32 vs float64 kernel parts"))
    a, b, r = dp["float64"], dp["float32"], dp["speedup"]
    assert f"pass A {a['pass_a']:.1f} vs {b['pass_a']:.1f} ({r['pass_a']:.2f}x)" in line
    for k, _ in _COMPARED:  # float64 / float32 within each round, not the other way round
        assert r[k] == pytest.approx(paired_ratio(dp["rounds"]["float64"][k], dp["rounds"]["float32"][k]))
        assert a[k] == pytest.approx(np.median(dp["rounds"]["float64"][k]))


def test_ratios_are_computed_from_the_same_run(res):
    """Catches a ratio computed from the wrong pair of timings (or typed in)."""
    for r in res["rows"]:
        assert r["ratio_to_floor"] == pytest.approx(r["ns_per_particle_step"] / r["floor_numba_ns"])
    mp = res["multipdf"]
    assert mp["speedup"] == pytest.approx(mp["ns_1_thread"] / mp["ns_2_threads"])
    for t in res["threads"]:
        assert t["speedup"] == pytest.approx(t["ns_1_thread"] / t["ns_all_threads"])
    s = res["summary"]
    key = (s["config"]["steps"], s["config"]["particles"])
    big = (s["big_config"]["steps"], s["big_config"]["particles"])
    by = {(r["steps"], r["particles"], r["backend"], r["dtype"]): r["ns_per_particle_step"] for r in res["rows"]}
    nb = by[key + ("numba", "float64")]
    assert s["numba_over_floor"] == pytest.approx(nb / res["floors"][0]["numba_ns"])
    assert s["numpy_over_numba_big"] == pytest.approx(by[big + ("numpy", "float64")] / by[big + ("numba", "float64")])
    assert s["float32_over_float64_numba"] == pytest.approx(by[key + ("numba", "float32")] / nb)
    assert s["float32_speedup_big"] == pytest.approx(by[big + ("numba", "float64")] / by[big + ("numba", "float32")])
    if res["c_rows"]:
        c = {r["variant"]: r["ns_per_particle_step"] for r in res["c_rows"] if (r["steps"], r["particles"]) == key}
        # the ratio targets use the FASTER C build
        assert s["numba_over_c"] == pytest.approx(nb / min(c.values()))
        assert s["numba_over_c_libc"] == pytest.approx(nb / c["libc"])
        assert s["numpy_over_c"] == pytest.approx(by[key + ("numpy", "float64")] / min(c.values()))
    pm = res["pmsm_smc"]
    assert pm["margin_x"] == pytest.approx(pm["period_us"] / max(pm["us_per_step_mean"], pm["us_per_step_max"]))


def test_every_target_verdict_is_computed_from_its_value(res):
    """Catches a verdict typed by hand or a flipped comparison."""
    assert {t["target"] for t in res["targets"]} >= {"numba_over_c", "numba_over_floor", "float32_speedup_1e5",
                                                     "threads_speedup_1e5"}
    for t in res["targets"]:
        want = TARGETS[t["target"]]
        assert (t["op"], t["bound"]) == (want.op, want.bound)
        if t["value"] is None:
            assert t["verdict"] == "not measured"
        else:
            ok = t["value"] <= t["bound"] if t["op"] in ("<=", "<") else t["value"] >= t["bound"]
            assert t["verdict"] == ("meets" if ok else "misses")
    assert check("numba_over_c", 0.5)["verdict"] == "meets"
    assert check("numba_over_c", 0.6)["verdict"] == "misses"
    assert check("threads_speedup_1e6", 1.9)["verdict"] == "meets"
    assert check("threads_speedup_1e6", 1.7)["verdict"] == "misses"
    assert check("cold_start_s", float("nan"))["verdict"] == "not measured"
    text = "\n".join(main_text(res))
    for t in res["targets"]:  # printed with its target next to it
        assert f"target {t['op']} {t['bound']:g}" in text


def test_paired_ratio_divides_within_rounds():
    """A machine that slows down between rounds must not skew the ratio: per-round ratios 1, 1, 1
    (a round at 10x the time for both timers) give 1, where the ratio of the medians would give
    0.1. Catches median(a) / median(b) in place of the per-round median."""
    assert paired_ratio([1.0, 10.0, 1.0], [1.0, 10.0, 1.0]) == 1.0
    assert paired_ratio([1.0, 10.0, 2.0], [10.0, 10.0, 20.0]) == pytest.approx(0.1)
    assert paired_ratio([1.0, 1.0, 10.0], [1.0, 10.0, 10.0]) == 1.0  # medians: 1 / 10
    assert paired_ratio([], []) is None
    assert ratio_range([1.0, 1.0, 10.0], [1.0, 10.0, 10.0]) == [0.1, 1.0]  # the rounds' spread
    assert ratio_range([1.0], [0.0]) is None
    seen = []
    out = interleaved({"a": lambda: seen.append("a") or 1.0, "b": lambda: seen.append("b") or 2.0}, 3)
    assert seen == ["a", "b"] * 3 and out == {"a": [1.0] * 3, "b": [2.0] * 3}


def test_targets_are_judged_on_the_paired_rounds(res):
    """Every target of the main section takes its value from the interleaved rounds, computed
    from the recorded timings. Catches a target still judged on section medians taken apart, or a
    paired ratio of the wrong timers."""
    pd = res["paired"]
    ns = pd["ns"]
    assert pd["rounds"] >= 5 and all(len(v) == pd["rounds"] for v in ns.values())
    got = {t["target"]: t["value"] for t in res["targets"]}
    assert got["numba_over_floor"] == pytest.approx(paired_ratio(ns["numba"], ns["floor"]))
    assert got["float32_speedup_1e5"] == pytest.approx(paired_ratio(ns["big_float64"], ns["big_float32"]))
    assert got["threads_speedup_1e5"] == pytest.approx(paired_ratio(ns["threads_1_100000"], ns["threads_all_100000"]))
    if "c_fast" in ns:
        assert got["numba_over_c"] == pytest.approx(paired_ratio(ns["numba"], ns["c_fast"]))
    lo, hi = ratio_range(ns["threads_1_100000"], ns["threads_all_100000"])
    assert pd["ratio_ranges"]["threads_speedup_100000"] == [lo, hi] and lo <= got["threads_speedup_1e5"] <= hi
    label = next(t["label"] for t in res["targets"] if t["target"] == "threads_speedup_1e5")
    assert label.endswith(f"(rounds {lo:.2f}-{hi:.2f}x)")  # the spread printed beside the median
    assert any(line.startswith("paired rounds") for line in main_text(res))


def test_without_c_the_ratios_say_not_measured(res):
    """No compiler: the C ratios are None, their target 'not measured', the note printed; no error."""
    s, targets = summarize(res["rows"], res["floors"], [], res["threads"], None,
                           (res["summary"]["config"]["steps"], res["summary"]["config"]["particles"]),
                           (res["summary"]["big_config"]["steps"], res["summary"]["big_config"]["particles"]))
    assert s["numba_over_c"] is None and s["numpy_over_c"] is None
    assert next(t for t in targets if t["target"] == "numba_over_c")["verdict"] == "not measured"
    fake = dict(res, c_rows=[], c_note="not run: no C compiler", summary=s, targets=targets)
    assert "C reference: not run: no C compiler" in "\n".join(main_text(fake))


def test_provenance_recorded(res):
    assert res["kind"] == "bench" and res["quick"] is True
    assert {"git_sha", "host", "packages", "created_utc"} <= set(res)


# --------------------------------------------------------------------------- the C reference
def test_missing_or_failing_compiler_is_a_note_not_a_traceback(monkeypatch, tmp_path):
    monkeypatch.setenv("PFBENCH_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.raises(c_reference.CUnavailable, match="not run: no C compiler"):
        c_reference.build("fast")
    monkeypatch.setenv("CC", "false")  # starts, fails: one line, not a traceback
    with pytest.raises(c_reference.CUnavailable, match="not run: C compiler failed") as ei:
        c_reference.build("fast")
    assert "\n" not in str(ei.value)


@pytest.mark.skipif(not HAVE_CC, reason="no C compiler")
@pytest.mark.parametrize("variant", sorted(c_reference.VARIANTS))
def test_c_filter_runs_and_tracks_the_state(variant):
    """The host build of pf_ob1.c filters: finite SSE, far below that of ignoring the data.

    The estimate 0 has SSE = sum x^2. A filter that ignores the measurements (mutation: every
    weight 1) gives about 0.75 sum x^2 on Ob1; the bootstrap filter about 0.1-0.35 sum x^2 (M=1000,
    N_p=500) -- half of sum x^2 separates the two."""
    r = c_reference.filter_ns(variant, 1000, 500, 1, seed=3)
    assert r["rng"] == c_reference.RNG[variant]
    assert math.isfinite(r["sse"]) and r["sse"] > 0
    assert r["sse"] < 0.5 * r["sum_x2"]
    assert r["ns_per_particle_step"] > 0 and len(r["ns_repeats"]) == 1


@pytest.mark.skipif(not HAVE_CC, reason="no C compiler")
def test_c_build_is_cached_and_keyed_on_the_sources():
    a = c_reference.build("fast")
    assert c_reference.build("fast")["path"] == a["path"]  # second call: the cached file
    assert a["path"] != c_reference.build("libc")["path"]  # flags are in the key
    assert "-O3" in a["flags"] and "-march=native" in a["flags"]


@pytest.mark.skipif(not HAVE_CC, reason="no C compiler")
def test_fast_rng_normals_are_standard_normal():
    """Moments of n = 10^6 draws of the ziggurat against N(0, 1), each within 5 standard errors
    (fixed seed): mean SE = 1/sqrt(n); sample variance SE = sqrt(2/n) (Var z^2 = 2); E z^4 = 3
    with SE sqrt(96/n) (Var z^4 = 105 - 9); P(|z| > r) for the ziggurat's tail edge r = 3.6541...
    (the tail branch) = erfc(r/sqrt 2) = 2.58e-4, binomial SE. Catches wrong tables, a lost sign
    bit, a broken tail or wedge test."""
    z = c_reference.normals(1_000_000, seed=7)
    n = z.size
    assert n == 1_000_000 and np.isfinite(z).all()
    assert abs(z.mean()) < 5 / math.sqrt(n)
    assert abs(z.var() - 1) < 5 * math.sqrt(2 / n)
    assert abs((z ** 4).mean() - 3) < 5 * math.sqrt(96 / n)
    r = 3.6541528853610088
    p = math.erfc(r / math.sqrt(2))
    assert abs(np.mean(np.abs(z) > r) - p) < 5 * math.sqrt(p * (1 - p) / n)
    assert abs(np.mean(z > 0) - 0.5) < 5 * math.sqrt(0.25 / n)


# --------------------------------------------------------------------------- scaling
def test_scaling_plan():
    for n, m in scaling.plan():
        assert m >= scaling.MIN_STEPS
        assert m == scaling.MIN_STEPS or abs(n * m - scaling.TARGET_PARTICLE_STEPS) <= n
    assert [n for n, _ in scaling.plan()] == [10 ** k for k in range(2, 8)]


def test_scaling_runs_skips_what_does_not_fit_and_plots(monkeypatch, tmp_path):
    """Tiny sizes; then a memory budget between two sizes: the larger is skipped with the reason,
    and the top is said to be limited by memory."""
    res = scaling.run_scaling(repeats=1, sizes=(100, 1000), target=2000, progress=False)
    assert {(r["engine"], r["particles"]) for r in res["rows"]} == {
        (e, n) for e in scaling.ENGINES for n in (100, 1000)}
    by = {(r["engine"], r["particles"]): r["ns_per_particle_step"] for r in res["rows"]}
    for n in (100, 1000):
        assert res["threads_speedup"][str(n)] == pytest.approx(by[("numba_1t", n)] / by[("numba_all", n)])
    assert "sizes asked" in res["top_limited_by"]
    scaling.plot(res, tmp_path / "s.png")
    assert (tmp_path / "s.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    from pfbench import models

    model = models.get("ob1")
    small = max(scaling._need(model, e, 100, 20) for e in scaling.ENGINES)
    monkeypatch.setattr(scaling, "_budget", lambda: (small, "test budget"))
    res = scaling.run_scaling(repeats=1, sizes=(100, 1000), target=2000, progress=False)
    for r in res["rows"]:  # skipped exactly when the estimate exceeds the budget
        too_big = r["memory_need_bytes"] > small
        assert (r["ns_per_particle_step"] is None) == too_big
        assert r.get("skipped", "").startswith("memory") == too_big
    assert any(r.get("skipped") for r in res["rows"] if r["particles"] == 1000)
    assert res["top_limited_by"].startswith("memory")


def test_scaling_pairs_the_thread_runs_within_rounds(monkeypatch):
    """The all-threads speed-up is the median of per-round ratios, 1 thread and all threads run back
    to back in each round. Scripted times: 1 thread 10, 30, 10; all threads 5, 10, 10 (per-round
    ratios 2, 3, 1: median 2; the medians alone give 10 / 10 = 1). Catches the speed-up taken as a
    ratio of medians, and the two engines not alternating."""
    from pfbench.bench import timing

    script = {1: [10.0, 30.0, 10.0], None: [5.0, 10.0, 10.0]}
    calls = []

    def fake(model, traj, n, backend, dtype, repeats, n_threads=None, **kw):
        calls.append(n_threads)
        return script[n_threads][sum(1 for c in calls if c == n_threads) - 1]

    monkeypatch.setattr(timing, "filter_ns", fake)
    res = scaling.run_scaling(repeats=3, sizes=(1000,), target=2000, engines=("numba_1t", "numba_all"),
                              progress=False)
    assert calls == [1, None] * 3
    by = {r["engine"]: r["ns_per_particle_step"] for r in res["rows"]}
    assert by == {"numba_1t": 10.0, "numba_all": 10.0}  # medians: a ratio of 1.0
    assert res["threads_speedup"]["1000"] == pytest.approx(2.0)  # ratios 2, 3, 1
    assert res["threads_speedup_rounds"]["1000"] == pytest.approx([1.0, 3.0])  # the spread beside it
    assert "N_p=10^3: 2.00x (rounds 1.00-3.00x)" in "\n".join(scaling.text(res))



def test_end_to_end_pairs_whole_runs_and_splits_off_the_quiet_rounds(scripted_end_to_end):
    """``end_to_end`` times whole run_filter calls, 1 thread then k threads in each round, and gives
    the speed-up over all rounds and over the quiet ones, the speed-up inside the kernel call and
    the time outside it. Catches a speed-up that is a ratio of medians, the engines not
    alternating, a busy round kept among the quiet ones, the kernel's times read from the wrong
    runs, or a target verdict that does not follow the measured speed-up."""
    res = scripted_end_to_end()
    assert res["speedup"] == pytest.approx(2.0) and res["speedup_rounds"] == pytest.approx([1.0, 3.0])
    assert res["quiet_rounds"] == 2 and res["quiet_speedup"] == pytest.approx(1.5)  # rounds 1 and 3
    assert res["kernel_speedup"] == pytest.approx(2.25) and res["kernel_speedup_rounds"] == pytest.approx([1.0, 4.0])
    assert res["median_outside_s_1_thread"] == pytest.approx(1.0)  # 1, 2, 1
    assert res["median_outside_s_threads"] == pytest.approx(1.0)  # 1, 3, 1
    assert res["kind"] == "bench_end_to_end" and res["targets"][0]["verdict"] == "meets"  # 2.0 >= 1.8
    text = scaling.end_to_end_text(res)
    assert "speed-up 2.00x" in text and "in the kernel (elapsed_s): speed-up 2.25x" in text
    assert "(target >= 1.8x: meets)" in text


# --------------------------------------------------------------------------- startup
def test_startup_cases_use_models_that_declare_the_structure():
    """mpf needs a model with linear and nonlinear states, guided one with a proposal, kalman one
    whose states are all linear (catches a case that would time an error or a one-copy MPF)."""
    from pfbench import models
    from pfbench.methods import Method

    assert {m for m, _, _ in startup.CASES} == {m.label for m in Method}
    for method, name, _ in startup.CASES:
        model = models.get(name)
        ls = tuple(getattr(model, "linear_states", None) or ())
        if method == "mpf":
            assert 0 < len(ls) < model.n_x
        elif method == "guided":
            assert getattr(model, "proposal_kind", None) in ("proposal", "optimal")
        elif method == "kalman":
            assert len(ls) == model.n_x


def test_startup_cold_is_empty_cache_warm_is_the_filled_one(monkeypatch, tmp_path):
    """With a stand-in command: the cold runs (one-process, then with the compile helper) see empty
    cache dirs of their own, the warm runs the one the helper's cold run filled, the temporary
    caches are removed, a failing command is reported (catches warm runs on a fresh cache, a cold
    run on a used one, a one-process run with the helper on, a leaked cache, a swallowed error)."""
    log = tmp_path / "log"
    monkeypatch.delenv("PFBENCH_COMPILE_HELPER", raising=False)
    script = ("import os, sys; c = os.environ['PFBENCH_CACHE_DIR']; n = os.environ['NUMBA_CACHE_DIR'];"
              "state = ('filled' if os.path.exists(c) else 'empty') + "
              "('-1proc' if os.environ.get('PFBENCH_COMPILE_HELPER') == '0' else '');"
              "os.makedirs(c, exist_ok=True); os.makedirs(n, exist_ok=True);"
              f"open({str(log)!r}, 'a').write(state + ' ' + c + chr(10));"
              "bad = '--model' in sys.argv and sys.argv[sys.argv.index('--model') + 1] == 'bad';"
              "bad and sys.stderr.write('error: boom' + chr(10)); sys.exit(2 if bad else 0)")
    monkeypatch.setattr(startup, "pfbench_command", lambda: [sys.executable, "-c", script])
    res = startup.run_startup(repeats=2, cold_repeats=1, progress=False,
                              cases=(("bootstrap", "ob1", ()), ("kalman", "bad", ())))
    lines = [ln.split(" ", 1) for ln in log.read_text().splitlines()]
    assert [s for s, _ in lines[:4]] == ["empty-1proc", "empty", "filled", "filled"]
    assert len({c for _, c in lines[1:4]}) == 1  # warm runs on the cache the cold run filled
    assert lines[0][1] != lines[1][1]
    assert not any(os.path.exists(c) for _, c in lines)
    good, bad = res["cases"]
    assert len(good["warm_runs_s"]) == 2 and good["error"] is None
    assert len(good["cold_one_process_runs_s"]) == 1
    assert good["warm_s"] == pytest.approx(float(np.median(good["warm_runs_s"])))
    assert good["compile_s"] == pytest.approx(good["cold_s"] - good["warm_s"])
    assert bad["cold_s"] is None and "boom" in bad["error"]
    assert res["targets"][1]["verdict"] == "not measured"
    assert "--steps 100 --particles 1000" in good["command"]


def test_sweep_section_pairs_rounds_against_one_worker_and_judges_each_count(monkeypatch, tmp_path):
    """Scripted command times, W = 1: 10, 12 s; W = 2: 6, 6 s; W = 4: 4, 3 s: speed-ups are
    medians of per-round ratios (W = 2: 10/6 and 12/6, median 1.83; the medians alone give 11/6),
    each W > 1 judged on speed-up / W, and W = 1 always run (the baseline). Then one real timed
    sweep (a tiny grid, 2 workers) through `pfbench sweep`. Catches a ratio of medians, a missing
    baseline, a verdict not computed from its value, and a section whose command does not run."""
    from pfbench.bench import sweep_scaling as sw

    script = {1: iter([10.0, 12.0]), 2: iter([6.0, 6.0]), 4: iter([4.0, 3.0])}
    monkeypatch.setattr(sw, "run_seconds", lambda grid=sw.GRID: 0.5)
    monkeypatch.setattr(sw, "timed_sweep", lambda runs, w, out, grid=sw.GRID: {
        "command_s": next(script[w]), "sweep_s": 1.0, "units": 3, "first_unit_s": 0.5, "threads": 1})
    res = sw.run_sweep_scaling(seconds=10, workers=[2, 4], rounds=2, progress=False)
    assert res["runs"] == 20 and [r["workers"] for r in res["rows"]] == [1, 2, 4]
    by = {r["workers"]: r for r in res["rows"]}
    assert by[2]["speedup"] == pytest.approx((10 / 6 + 12 / 6) / 2)
    assert by[4]["speedup"] == pytest.approx((10 / 4 + 12 / 3) / 2) and by[4]["efficiency"] == pytest.approx(3.25 / 4)
    assert [t["verdict"] for t in res["targets"]] == ["meets", "meets"]
    assert by[2]["speedup_rounds"] == [pytest.approx(10 / 6), pytest.approx(2.0)]
    assert any("speed-up" in line for line in sw.text(res))

    monkeypatch.undo()
    grid = dict(sw.GRID, particles=(20,), filters=(1, 2), steps=20)
    t = sw.timed_sweep(6, 2, tmp_path / "s.jsonl", grid)
    assert t["command_s"] > t["sweep_s"] > 0 and t["units"] >= 1 and t["threads"] >= 1
    assert t["first_unit_s"] is not None and 0 < t["first_unit_s"] < t["command_s"]
