"""`pfbench bench` (quick mode): every figure it reports is there and is computed from the timings
of the same run. No wall-clock value is asserted (timings belong in the benchmark itself)."""
import math

import pytest

from pfbench.bench import run_bench


@pytest.fixture(scope="module")
def res():
    return run_bench(repeats=1, quick=True, with_particles=False, progress=False)


def test_rows_cover_backends_and_dtypes(res):
    assert {(r["backend"], r["dtype"]) for r in res["rows"]} == {
        (b, d) for b in ("numba", "numpy") for d in ("float64", "float32")}
    for r in res["rows"]:
        assert math.isfinite(r["ns_per_particle_step"]) and r["ns_per_particle_step"] > 0


def test_ratios_are_computed_from_the_same_run(res):
    """Catches a ratio computed from the wrong pair of timings (or typed in)."""
    for r in res["rows"]:
        assert r["ratio_to_floor"] == pytest.approx(r["ns_per_particle_step"] / r["floor_numba_ns"])
    mp = res["multipdf"]
    assert mp["speedup"] == pytest.approx(mp["ns_1_thread"] / mp["ns_2_threads"])
    by = {(r["steps"], r["particles"], r["backend"], r["dtype"]): r for r in res["rows"]}
    first, last = res["rows"][0], res["rows"][-1]
    small = by[(first["steps"], first["particles"], "numba", "float64")]
    big = (last["steps"], last["particles"])
    s = res["summary"]
    assert s["numba_over_floor_MN1000"] == pytest.approx(small["ns_per_particle_step"] / small["floor_numba_ns"])
    assert s["numpy_over_numba_N100000"] == pytest.approx(
        by[big + ("numpy", "float64")]["ns_per_particle_step"] / by[big + ("numba", "float64")]["ns_per_particle_step"])
    assert s["float32_over_float64_numba"] == pytest.approx(
        by[(first["steps"], first["particles"], "numba", "float32")]["ns_per_particle_step"]
        / small["ns_per_particle_step"])
    pm = res["pmsm_smc"]
    assert pm["margin_x"] == pytest.approx(pm["period_us"] / max(pm["us_per_step_mean"], pm["us_per_step_max"]))


def test_provenance_recorded(res):
    assert res["kind"] == "bench" and res["quick"] is True
    assert {"git_sha", "host", "packages", "created_utc"} <= set(res)
