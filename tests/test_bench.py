"""`pfbench bench` (quick mode) produces every figure it reports; the filter costs more than the
irreducible work it contains (one normal draw and one exp per particle-step)."""
import math

from pfbench.bench import run_bench


def test_quick_bench_structure_and_floor():
    res = run_bench(repeats=1, quick=True, with_particles=False, progress=False)
    assert {r["backend"] for r in res["rows"]} == {"numba", "numpy"}
    assert {r["dtype"] for r in res["rows"]} == {"float64", "float32"}
    for r in res["rows"]:
        assert r["ns_per_particle_step"] > 0 and math.isfinite(r["ns_per_particle_step"])
        if r["backend"] == "numba":
            assert r["ratio_to_floor"] > 1.0
    assert res["multipdf"]["speedup"] > 0
    assert 0 < res["pmsm_smc"]["us_per_step_mean"] < res["pmsm_smc"]["period_us"] * 100
    assert "numba_over_floor_MN1000" in res["summary"]
