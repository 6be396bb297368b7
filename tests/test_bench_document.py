"""`pfbench bench --document`: docs/PERFORMANCE.md rendered from the benchmarks' JSON files.

The result files here are small and synthetic, but where it is cheap they come from the benchmark
code itself with its timers replaced by scripted times (so the page reads the fields the
benchmarks really write). Scripted times have medians unlike their means, so a page that shows a
mean, or the wrong field, fails. No benchmark runs."""
import json
import statistics

import pytest
from click.testing import CliRunner

from pfbench.bench import document, summarize
from pfbench.errors import DataError
from pfbench.provenance import provenance

NOTES = """## Recorded by hand

Kept *exactly*: trailing spaces   
| a | b |
|---|---|
| 1.5x | ≥ 10 |

Tried and not taken: `OMP_WAIT_POLICY=passive`.
"""


def _write(folder, name, data):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_text(json.dumps(data))


def _notes(tmp_path):
    p = tmp_path / "notes.md"
    p.write_text(NOTES)
    return p


def _section(page, title):
    """The text of the generated section whose heading starts with ``### title``."""
    body = page.split(f"### {title}", 1)[1]
    return body.split("\n### ", 1)[0].split("\n## ", 1)[0]


def _scripted(monkeypatch, script, used=None):
    """Replace :func:`pfbench.bench.timing.filter_ns` by one returning ``script[n_threads]`` in turn
    (and, asked for the threads it ran on, reporting ``used[n_threads]`` in turn)."""
    from pfbench.bench import timing

    calls = {}

    def fake(model, traj, n, backend, dtype, repeats, method="bootstrap", n_filters=1, n_threads=None,
             threads=None):
        i = calls[n_threads] = calls.get(n_threads, -1) + 1
        if threads is not None:
            threads.append(used[n_threads][i % len(used[n_threads])])
        seq = script[n_threads]
        return seq[i % len(seq)]

    monkeypatch.setattr(timing, "filter_ns", fake)


# --------------------------------------------------------------------------- synthetic result files
def busy_json(monkeypatch):
    """:func:`pfbench.bench.busy.run_busy`, no processes spun, default / 1 thread = 1, 2, 9 per round
    (median 2, mean 4); the default ran on 4, 4, 3 threads in the quiet rounds and on 1 in the busy ones."""
    from pfbench.bench import busy

    _scripted(monkeypatch, {None: [10.0, 20.0, 90.0], 1: [10.0]}, used={None: [4, 4, 3, 1, 1, 1]})
    monkeypatch.setattr(busy, "_spinners", lambda count: [])
    monkeypatch.setattr(busy.time, "sleep", lambda s: None)
    return busy.run_busy(rounds=3, steps=5, sizes=(1000,))


def scaling_json(monkeypatch):
    """:func:`pfbench.bench.scaling.run_scaling` on the two numba engines: 1 thread 10, 30, 10
    (median 10, mean 16.7), all threads 4, 8, 5 (median 5); per-round speed-ups 2.5, 3.75, 2."""
    from pfbench.bench import scaling

    _scripted(monkeypatch, {1: [10.0, 30.0, 10.0], None: [4.0, 8.0, 5.0]})
    return scaling.run_scaling(repeats=3, sizes=(1000,), target=2000, engines=("numba_1t", "numba_all"),
                               progress=False, gpu=False)


def startup_json(monkeypatch):
    """:func:`pfbench.bench.startup.run_startup` with scripted wall times: one process 5, cold 4,
    warm 1.0, 1.1, 3.0 (median 1.1, mean 1.7)."""
    from pfbench.bench import startup

    times = iter([5.0, 4.0, 1.0, 1.1, 3.0])
    monkeypatch.setattr(startup, "_timed", lambda cmd, cache, helper=True: (next(times), None))
    return provenance(**startup.run_startup(repeats=3, cases=(("bootstrap", "ob1", ()),), progress=False))


def bench_json():
    """A ``bench.json`` as :func:`pfbench.bench.run_bench` writes it, its summary and targets
    computed by the real :func:`pfbench.bench.summarize`."""
    key, big = (1000, 1000), (100, 100_000)
    ns = {("numba", "float64"): 25.0, ("numba", "float32"): 20.0, ("numpy", "float64"): 80.0,
          ("numpy", "float32"): 70.0}
    floors = [{"steps": m, "particles": n, "numba_ns": 10.0, "engine_ns": 8.0, "numpy_ns": 30.0,
               "breakdown_ns": {"normal": 5.0, "normal_engine": 4.0, "exp": 5.0, "exp_engine": 3.0,
                                "memory_pass": 0.5}} for m, n in (key, big)]
    rows = [{"steps": m, "particles": n, "backend": be, "dtype": dt, "threads": 1 if be == "numba" else None,
             "ns_per_particle_step": v * (1 if n == 1000 else 0.8), "floor_numba_ns": 10.0, "floor_numpy_ns": 30.0,
             "ratio_to_floor": v * (1 if n == 1000 else 0.8) / 10.0}
            for m, n in (key, big) for (be, dt), v in ns.items()]
    c_rows = [{"variant": "fast", "steps": 1000, "particles": 1000, "ns_per_particle_step": 40.0,
               "compiler": "cc 14", "flags": "-O3 -march=native"}]
    threads = [{"steps": 100, "particles": 100_000, "ns_1_thread": 22.0, "ns_all_threads": 11.5,
                "speedup": 22.0 / 11.5, "cores": 2}]
    paired = {"rounds": 3, "ns": {"numba": [12.0, 13.0, 50.0], "floor": [6.0, 6.5, 7.0]},
              "ratios": {"numba_over_c": None, "numba_over_floor": 2.0, "float32_speedup_big": 1.2,
                         "threads_speedup_100000": 1.9},
              "ratio_ranges": {"numba_over_floor": [1.9, 7.1]}}
    part = {"version": "0.4", "ns_per_particle_step": 300.0}
    s, targets = summarize(rows, floors, c_rows, threads, part, key, big, paired)
    parts = {"steps": 1000, "particles": 1000, "dtype": "float64", "normals": 4.1, "model": 3.3, "transition_c": 1.0,
             "transition_f": 0.5, "convert": 0.2, "pass_a": 9.0, "exp": 2.0, "pass_b": 4.0, "resample": 6.0,
             "filter": 25.0, "rest": 6.0}
    dparts = {"float64": dict(parts, particles=100_000), "float32": dict(parts, dtype="float32", particles=100_000,
                                                                         pass_a=7.25),
              "speedup": {k: 1.25 for k in parts if k not in ("steps", "particles", "dtype")}}
    return provenance(kind="bench", repeats=5, quick=False, rows=rows, floors=floors, c_rows=c_rows, c_note=None,
                      threads=threads, multipdf={"particles": 200_000, "filters": 2, "ns_1_thread": 30.0,
                                                 "ns_2_threads": 16.0, "speedup": 1.875, "cores": 2},
                      pmsm_smc={"particles": 60, "period_us": 125.0, "us_per_step_mean": 20.0,
                                "us_per_step_max": 25.0, "margin_x": 5.0},
                      kernel_parts=parts, dtype_parts=dparts, particles_library=part, paired=paired, summary=s,
                      targets=targets)


def gpu_json():
    """A ``gpu.json`` as ``scripts/gpu_bench.py`` writes it."""
    return {"sections": {"gpu_ob1_bootstrap": [
        {"particles": 10 ** 8, "steps": 30, "dtype": "float32", "ns_per_particle_step": 0.091, "setup_s": 1.0},
        {"particles": 10 ** 8, "steps": 30, "dtype": "float64", "ns_per_particle_step": 0.092, "setup_s": 1.0}],
        "numba_all_cores": [{"particles": 10 ** 6, "steps": 200, "dtype": "float32", "ns_per_particle_step": 1.77}],
        "d2d_bandwidth": {"bytes_per_s": 2.99e12, "ns_per_float32_copy": 0.00268},
        "gpu_1e9_float32": {"skipped": "needs 90 GiB"},
        "summary": {"target_ns_f32_1e8": 0.06, "ns_f32_1e8": 0.091, "meets_0_06": False,
                    "speedup_vs_numba_all_cores": 19.5}},
        "errors": {}, "backend": "cupy", "gpu": {"cupy": "14.2", "gpu": "NVIDIA H100 80GB HBM3"}, "cpu_cores": 16,
        **provenance(kind="bench_gpu")}


def pytest_json():
    """pytest-benchmark's ``--benchmark-json`` layout: median 0.02 s, mean 0.5 s."""
    return {"machine_info": {"cpu": {"brand_raw": "Test CPU 9000", "count": 8}, "system": "Linux",
                             "release": "6.1", "python_version": "3.11.7"},
            "commit_info": {"id": "abc123", "dirty": True},
            "benchmarks": [{"name": "test_ob1_bootstrap[float64-numba]", "extra_info": {"particle_steps": 10 ** 6},
                            "stats": {"median": 0.02, "mean": 0.5, "rounds": 5}}],
            "datetime": "2026-01-02T03:04:05+00:00", "version": "5.3.1"}


# --------------------------------------------------------------------------- tests
def test_missing_kinds_say_not_measured_with_their_command(monkeypatch, tmp_path):
    """Only busy.json: every other kind is one 'not measured in this run: <command>' line, busy is
    not (catches a missing kind silently dropped from the page, or busy reported missing)."""
    res = tmp_path / "results"
    _write(res, "busy.json", busy_json(monkeypatch))
    page = document.render(res, _notes(tmp_path))
    for kind in document.KINDS.values():
        line = f"not measured in this run: `{kind.command}`"
        assert (line in _section(page, kind.title)) == (kind.name != "bench_busy"), kind.name
    assert "not measured in this run: `pfbench bench --busy`" not in page
    assert "not measured in this run: `OUT=results/bench bash scripts/gpu_check.sh` (on a machine with" in page


def test_no_results_folder_is_all_not_measured(tmp_path):
    page = document.render(tmp_path / "nothing", _notes(tmp_path))
    assert page.count("not measured in this run: ") == len(document.KINDS)


def test_kept_part_is_verbatim_and_last(tmp_path):
    """The notes, trailing spaces and all, end the page exactly once (catches the kept part being
    reflowed, stripped, or dropped)."""
    page = document.render(tmp_path / "nothing", _notes(tmp_path))
    assert page.endswith("\n\n" + NOTES)
    assert page.count("Kept *exactly*: trailing spaces   \n") == 1


def test_every_section_states_machine_date_sha_and_command(monkeypatch, tmp_path, scripted_end_to_end):
    res = tmp_path / "results"
    for name, data in (("busy.json", busy_json(monkeypatch)), ("scaling.json", scaling_json(monkeypatch)),
                       ("startup.json", startup_json(monkeypatch)), ("bench.json", bench_json()),
                       ("gpu.json", gpu_json()), ("pytest-benchmark.json", pytest_json()),
                       ("sweep.json", sweep_json()), ("end_to_end.json", scripted_end_to_end())):
        _write(res, name, data)
        data = json.loads((res / name).read_text())
        kind = document.KINDS[document.kind_of(data)]
        sec = _section(document.render(res, _notes(tmp_path)), kind.title)
        assert f"Regenerate: `{kind.command}`" in sec, name
        if name == "pytest-benchmark.json":
            assert "Test CPU 9000 (8 cores" in sec and "2026-01-02T03:04:05+00:00" in sec and "git abc123-dirty" in sec
        else:
            assert data["host"]["cpu"] in sec and data["created_utc"] in sec, name
            assert f"git {data['git_sha']}" in sec, name
    assert "not measured in this run" not in document.render(res, _notes(tmp_path))


def test_busy_table_shows_the_medians_of_the_rounds(monkeypatch, tmp_path):
    """Per-round ratios 1, 2, 9: median 2 (mean 4), range 1-9, worst round over 1.5: misses."""
    res = tmp_path / "r"
    data = busy_json(monkeypatch)
    assert data["sizes"]["1000"]["busy"] == pytest.approx([1.0, 2.0, 9.0])
    _write(res, "busy.json", data)
    sec = _section(document.render(res, _notes(tmp_path)), "Default thread count")
    assert "| 10^3 | 2.00x | 1.00-9.00x | 2.00x | 1.00-9.00x | 3-4 | 1 | misses |" in sec
    del data["sizes"]["1000"]["default_threads"]  # a file from before the threads were kept
    _write(res, "busy.json", data)
    sec = _section(document.render(res, _notes(tmp_path)), "Default thread count")
    assert "| 10^3 | 2.00x | 1.00-9.00x | 2.00x | 1.00-9.00x | - | - | misses |" in sec


def test_scaling_table_shows_medians_and_paired_speedup(monkeypatch, tmp_path):
    res = tmp_path / "r"
    _write(res, "scaling.json", scaling_json(monkeypatch))
    sec = _section(document.render(res, _notes(tmp_path)), "Cost per particle-step")
    assert "| N_p | M | numba, 1 thread | numba, all threads |" in sec
    assert "| 10^3 | 5 | 10.0 | 5.00 |" in sec  # medians, not means (16.7, 5.67)
    assert "N_p = 10^3: 2.50x (rounds 2.00-3.75x)" in sec  # median of per-round ratios, not 10 / 5


def test_startup_table_shows_the_medians(monkeypatch, tmp_path):
    res = tmp_path / "r"
    _write(res, "startup.json", startup_json(monkeypatch))
    sec = _section(document.render(res, _notes(tmp_path)), "Cold and warm start")
    assert "| bootstrap | ob1 | 4.00 | 5.00 | 1.10 | 2.90 |  |" in sec  # warm median 1.1, not mean 1.7
    assert "cold start, bootstrap on ob1 | 4.00 s | < 5.00 s | meets |" in sec


def test_bench_tables_show_the_json_values(tmp_path):
    """The main section's rows, the C row over its floor, the ratios of the summary, the targets with
    their computed verdicts, the paired medians, threads and the float32 parts."""
    res = tmp_path / "r"
    data = bench_json()
    _write(res, "bench.json", data)
    sec = _section(document.render(res, _notes(tmp_path)), "Engine against the C reference")
    assert "| 1000 | 10^3 | numba, 1 thread | float64 | 25.0 | 2.50x |" in sec
    assert "| 100 | 10^5 | numpy | float32 | 56.0 | 5.60x |" in sec
    assert "| 1000 | 10^3 | C, fast RNG | float64 | 40.0 | 4.00x |" in sec
    assert "| numba / C (fast RNG) | 0.625x |" in sec  # 25 / 40 from the summary
    verdict = next(t for t in data["targets"] if t["target"] == "numba_over_floor")
    assert f"| {verdict['label']} | 2.00x | <= 2.00x | {verdict['verdict']} |" in sec
    assert f"numba {statistics.median([12.0, 13.0, 50.0]):.1f}" in sec  # 13.0, not the mean 25.0
    assert "| 10^5 | 100 | 22.0 | 11.5 | 2 | 1.91x |" in sec
    assert "| pass A | 9.00 | 7.25 | 1.25x |" in sec
    assert "`particles` library 0.4: 300 ns" in sec


def test_gpu_and_pytest_sections(tmp_path):
    res = tmp_path / "r"
    _write(res, "gpu.json", gpu_json())
    _write(res, "pytest-benchmark.json", pytest_json())
    page = document.render(res, _notes(tmp_path))
    gpu = _section(page, "GPU")
    assert "NVIDIA H100 80GB HBM3, CuPy 14.2" in gpu
    assert "| 10^8 | 30 | 0.0910 | 0.0920 |" in gpu
    assert "19.5x (target >= 10x)" in gpu and "(misses)" in gpu
    pt = _section(page, "pytest-benchmark")
    assert "| test_ob1_bootstrap[float64-numba] | 0.0200 | 20.0 | 5 |" in pt  # the median, not the mean


@pytest.mark.parametrize("text, why", [("{not json", "not valid JSON"), ('{"kind": "bogus"}', "kind 'bogus'"),
                                       ("[1, 2]", "no known layout"), ('{"kind": "bench"}', "field 'floors'"),
                                       ('{"section": "busy", "target": 1.5, "sizes": {"10": 3}}', "bench_busy")])
def test_garbage_is_one_line_naming_the_file(tmp_path, text, why):
    res = tmp_path / "r"
    res.mkdir()
    (res / "odd.json").write_text(text)
    with pytest.raises(DataError) as exc:
        document.render(res, _notes(tmp_path))
    msg = str(exc.value)
    assert str(res / "odd.json") in msg and why in msg and "\n" not in msg


def test_cli_document_alone_runs_no_benchmark_and_is_reproducible(monkeypatch, tmp_path):
    """`pfbench bench --document`: the page from the files already there (no section runs), written
    where `make bench` expects it; again, byte for byte the same; garbage is exit 2 with one line."""
    import pfbench.bench as bench_mod
    from pfbench.cli import main

    monkeypatch.setattr(bench_mod, "run_bench", lambda **kw: pytest.fail("--document ran a benchmark"))
    monkeypatch.chdir(tmp_path)
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "performance_notes.md").write_text(NOTES)
    _write(tmp_path / "results" / "bench", "busy.json", busy_json(monkeypatch))
    r = CliRunner().invoke(main, ["bench", "--document"])
    assert r.exit_code == 0, r.output
    page = (tmp_path / "docs" / "PERFORMANCE.md").read_text()
    assert page == document.render("results/bench", "docs/performance_notes.md")
    assert ("not measured: bench, bench_startup, bench_scaling, bench_sweep, bench_end_to_end, bench_gpu, "
            "pytest_benchmark") in r.output
    assert CliRunner().invoke(main, ["bench", "--document"]).exit_code == 0
    assert (tmp_path / "docs" / "PERFORMANCE.md").read_text() == page

    (tmp_path / "results" / "bench" / "junk.json").write_text("{")
    r = CliRunner().invoke(main, ["bench", "--document"])
    assert r.exit_code == 2
    assert r.stderr.startswith("error: results/bench/junk.json: not valid JSON")
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.output
    assert (tmp_path / "docs" / "PERFORMANCE.md").read_text() == page  # the old page stays
    # a mistyped --out (no results there) rewrote the page with every section "not measured"
    r = CliRunner().invoke(main, ["bench", "--document", "--out", "nosuch/bench.json"])
    assert r.exit_code == 2 and "no benchmark results in nosuch" in r.stderr
    assert (tmp_path / "docs" / "PERFORMANCE.md").read_text() == page


def test_cli_document_without_notes_is_an_error(monkeypatch, tmp_path):
    from pfbench.cli import main

    monkeypatch.chdir(tmp_path)
    r = CliRunner().invoke(main, ["bench", "--document"])
    assert r.exit_code == 2 and "docs/performance_notes.md" in r.stderr and "missing" in r.stderr



def sweep_json():
    """A ``bench_sweep`` result: W = 2's stored speed-up (the median of per-round ratios) is 1.5x,
    where the ratio of the median command times is 10 / 8 = 1.25x."""
    rows = [{"workers": 1, "command_s": [10.0, 12.0, 9.0], "command_median_s": 10.0, "speedup": 1.0,
             "speedup_rounds": [1.0, 1.0], "efficiency": 1.0},
            {"workers": 2, "command_s": [8.0, 6.0, 9.0], "command_median_s": 8.0, "speedup": 1.5,
             "speedup_rounds": [1.0, 2.0], "efficiency": 0.75}]
    from pfbench.bench.report import check

    target = check("sweep_efficiency", 0.75, "sweep on 2 workers: speed-up / 2")
    return provenance(kind="bench_sweep", grid={"model": "ob1", "method": "multipdf", "particles": [100],
                                                "filters": [1], "steps": 10},
                      seconds_asked=60.0, run_s=0.5, runs=4, tasks=4, rounds=3, cores=2, rows=rows, targets=[target])


def test_sweep_table_shows_the_paired_speedup(tmp_path):
    """The speed-up column is the median of the per-round ratios the sweep bench stored, not the
    ratio of the median times; speed-up / W follows it. Catches a page that recomputes the speed-up
    from the medians or shows another row's value."""
    _write(tmp_path / "r", "sweep.json", sweep_json())
    sec = _section(document.render(tmp_path / "r", _notes(tmp_path)), "A sweep on 1 and on W workers")
    assert "| 2 | 8.00 | 1.50x | 1.00x-2.00x | 0.750 |" in sec


def test_end_to_end_table_shows_medians_and_both_speedups(scripted_end_to_end, tmp_path):
    """The rows give the median whole-run, in-kernel and outside times in ms, the speed-ups the
    stored medians of per-round ratios. Catches means for medians, the two speed-ups swapped, or
    the target's verdict dropped."""
    _write(tmp_path / "r", "end_to_end.json", scripted_end_to_end())  # 1 thread median 10 s (mean 16.7)
    sec = _section(document.render(tmp_path / "r", _notes(tmp_path)), "Whole short runs at large N_p")
    assert "| 1 | 10000 | 9000 | 1000 |" in sec
    assert "| 2 | 10000 | 7000 | 1000 |" in sec
    assert "whole runs 2.00x (1.00x-3.00x), in the kernel 2.25x (1.00x-4.00x)" in sec
    assert "2 of 3 rounds quiet" in sec and "meets" in sec
