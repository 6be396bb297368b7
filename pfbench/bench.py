"""``pfbench bench``: engine speed as ns per particle-step and as ratios measured in one run.

What is timed (all single-threaded unless stated, median of ``--repeats``):

* Ob1 bootstrap ([Embedded] Alg. 1) at (M, N_p) = (1000, 1000), (500, 1000), (500, 500) and
  N_p = 100000 (M = 100), each backend x dtype;
* the *irreducible work* floor in the same run: one standard-normal draw and one exp per
  particle-step, as a numba loop and as vectorised NumPy, so results read as ratios;
* MultiPDF ([MultiPDF] Alg. 2) on numba with N_f = 2 at N_p = 200000: 1 thread vs all cores;
* the PMSM SMC step with the optimal proposal (thesis §4.2.1, 60 particles) against the
  drive's 125 us sampling period;
* optionally the ``particles`` library's bootstrap filter on the same model, run by
  ``scripts/bench_particles.py`` in its own environment (``.venv-particles``; it pins an older
  NumPy), when that environment exists (``make bench`` creates it).

Compilation is excluded: every configuration runs once untimed first.
"""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import click
import numpy as np

CONFIGS = ((1000, 1000), (500, 1000), (500, 500), (100, 100_000))


def _floor_kernel():
    from .backends.cache import njit

    @njit(nogil=True)
    def floor_numba(rng, n, m):
        acc = 0.0
        for _ in range(m):
            z = rng.standard_normal(n)
            for i in range(n):
                acc += np.exp(-0.5 * z[i] * z[i])
        return acc

    return floor_numba


def floor_ns(n: int, m: int, repeats: int, backend: str) -> float:
    """ns per particle-step of one normal draw + one exp (the irreducible work of a PF step)."""
    rng = np.random.default_rng(0)
    if backend == "numba":
        f = _floor_kernel()
        f(rng, 8, 2)
        run = lambda: f(rng, n, m)  # noqa: E731
    else:
        def run():
            acc = 0.0
            for _ in range(m):
                z = rng.standard_normal(n)
                acc += np.exp(-0.5 * z * z).sum()
            return acc
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e9 / (n * m)


def filter_ns(model, traj, n: int, backend: str, dtype: str, repeats: int, method="bootstrap",
              n_filters=1, n_threads=None) -> float:
    from .filters import run_filter

    kw = dict(method=method, n_particles=n, n_filters=n_filters, backend=backend, dtype=dtype,
              n_threads=n_threads)
    run_filter(model, traj.y[:3], None, seed=0, **kw)  # compile / warm up
    times = [run_filter(model, traj.y, None, seed=r, **kw).elapsed_s for r in range(repeats)]
    return statistics.median(times) * 1e9 / (n * traj.n_steps)


def particles_ns(m: int, n: int, repeats: int) -> dict | None:
    """Run scripts/bench_particles.py in .venv-particles if present; None otherwise."""
    root = Path(__file__).resolve().parent.parent
    py = root / ".venv-particles" / "bin" / "python"
    script = root / "scripts" / "bench_particles.py"
    if not (py.exists() and script.exists()):
        return None
    r = subprocess.run([str(py), str(script), "--steps", str(m), "--particles", str(n),
                        "--repeats", str(repeats)], capture_output=True, text=True, timeout=1800)
    if r.returncode != 0:
        return {"error": r.stderr.strip().splitlines()[-1] if r.stderr.strip() else "failed"}
    return json.loads(r.stdout.strip().splitlines()[-1])


def run_bench(repeats: int = 5, quick: bool = False, with_particles: bool = True,
              progress: bool = True) -> dict:
    from . import models
    from .provenance import provenance

    model = models.get("ob1")
    rows = []
    configs = CONFIGS if not quick else ((200, 1000), (20, 100_000))
    jobs = [(m, n, be, dt) for (m, n) in configs for be in ("numba", "numpy") for dt in ("float64", "float32")]
    from tqdm.auto import tqdm

    bar = tqdm(total=len(jobs) + len(configs) * 2 + 2, desc="bench", disable=not progress, file=sys.stderr,
               leave=False)
    for m, n in configs:
        traj = model.simulate(m, seed=1)
        reps = repeats if n <= 1000 else max(1, repeats // 2)
        fl_nb = floor_ns(n, m, reps, "numba")
        bar.update()
        fl_np = floor_ns(n, m, reps, "numpy")
        bar.update()
        for be in ("numba", "numpy"):
            for dt in ("float64", "float32"):
                ns = filter_ns(model, traj, n, be, dt, reps if be == "numba" else max(1, reps // 2))
                bar.update()
                rows.append({"steps": m, "particles": n, "backend": be, "dtype": dt, "ns_per_particle_step": ns,
                             "floor_numba_ns": fl_nb, "floor_numpy_ns": fl_np, "ratio_to_floor": ns / fl_nb})
    # MultiPDF parallel speed-up
    n_mp = 200_000 if not quick else 50_000
    traj = model.simulate(50 if not quick else 30, seed=2)
    mp_reps = max(3, repeats // 2)  # short runs: thread start-up noise needs a few repeats
    one = filter_ns(model, traj, n_mp, "numba", "float64", mp_reps, "multipdf", 2, n_threads=1)
    bar.update()
    two = filter_ns(model, traj, n_mp, "numba", "float64", mp_reps, "multipdf", 2, n_threads=2)
    bar.update()
    bar.close()
    multipdf = {"particles": n_mp, "filters": 2, "ns_1_thread": one, "ns_2_threads": two,
                "speedup": one / two, "cores": os.cpu_count()}
    # PMSM SMC with the optimal proposal (thesis §4.2.1): must fit the drive's 125 us period
    from .plants.pmsm_control.smc import step_time_us

    pmsm = {"particles": 60, "period_us": 125.0,
            "us_per_step_mean": step_time_us(n_particles=60, point="mean", repeats=max(1, repeats // 2)),
            "us_per_step_max": step_time_us(n_particles=60, point="max", repeats=max(1, repeats // 2))}
    pmsm["margin_x"] = pmsm["period_us"] / max(pmsm["us_per_step_mean"], pmsm["us_per_step_max"])
    part = particles_ns(1000, 1000, max(1, repeats // 2)) if with_particles else None
    by = {(r["steps"], r["particles"], r["backend"], r["dtype"]): r["ns_per_particle_step"] for r in rows}
    summary = {}
    key = configs[0]
    nb = by[(key[0], key[1], "numba", "float64")]
    summary["numba_over_floor_MN1000"] = nb / rows[0]["floor_numba_ns"]
    big = configs[-1]
    summary["numpy_over_numba_N100000"] = (by[(big[0], big[1], "numpy", "float64")]
                                          / by[(big[0], big[1], "numba", "float64")])
    summary["numpy_ns_N1000"] = by[(key[0], key[1], "numpy", "float64")]
    summary["float32_over_float64_numba"] = by[(key[0], key[1], "numba", "float32")] / nb
    if part and "ns_per_particle_step" in part:
        summary["particles_ns_N1000"] = part["ns_per_particle_step"]
        summary["particles_over_numba"] = part["ns_per_particle_step"] / nb
        summary["particles_over_numpy"] = part["ns_per_particle_step"] / summary["numpy_ns_N1000"]
    return provenance(kind="bench", repeats=repeats, quick=quick, rows=rows, multipdf=multipdf,
                      pmsm_smc=pmsm, particles_library=part, summary=summary)


@click.command()
@click.option("--repeats", type=click.IntRange(1, 100), default=5, show_default=True,
              help="Timed repetitions per configuration (medians are reported).")
@click.option("--quick", is_flag=True, help="Smaller configurations (a smoke run).")
@click.option("--no-particles", is_flag=True, help="Skip the `particles` library comparison.")
@click.option("--out", "out_path", type=click.Path(dir_okay=False), default="results/bench/bench.json",
              show_default=True)
@click.option("--json", "as_json", is_flag=True)
def bench(repeats, quick, no_particles, out_path, as_json):
    """Time Ob1 bootstrap on both backends and dtypes against the irreducible-work floor."""
    from .io import write_json
    from .resources import check_writable, path_error

    check_writable(out_path, "--out")  # before minutes of timing, not after
    res = run_bench(repeats=repeats, quick=quick, with_particles=not no_particles)
    try:
        write_json(out_path, res)
    except OSError as exc:  # e.g. the disk filled up meanwhile
        raise path_error(exc, out_path, "--out") from None
    if as_json:
        from .io import to_json

        click.echo(to_json(res))
        return
    click.echo(f"{'M':>6} {'N_p':>7} {'backend':>7} {'dtype':>8} {'ns/p-step':>10} {'x floor':>8}")
    for r in res["rows"]:
        click.echo(f"{r['steps']:>6} {r['particles']:>7} {r['backend']:>7} {r['dtype']:>8} "
                   f"{r['ns_per_particle_step']:>10.1f} {r['ratio_to_floor']:>8.2f}")
    r0 = res["rows"][0]
    click.echo(f"floor (1 normal + 1 exp per particle-step): numba {r0['floor_numba_ns']:.1f} ns, "
               f"numpy {r0['floor_numpy_ns']:.1f} ns")
    mp = res["multipdf"]
    click.echo(f"MultiPDF N_p={mp['particles']} N_f=2 numba: 1 thread {mp['ns_1_thread']:.1f} ns, "
               f"2 threads {mp['ns_2_threads']:.1f} ns, speed-up {mp['speedup']:.2f}x on {mp['cores']} cores")
    pm = res["pmsm_smc"]
    click.echo(f"PMSM SMC, 60 particles, numba: {pm['us_per_step_mean']:.1f} us/step (mean estimate), "
               f"{pm['us_per_step_max']:.1f} us/step (maximum); period 125 us, margin {pm['margin_x']:.1f}x")
    if res["particles_library"]:
        click.echo(f"particles library: {res['particles_library']}")
    for k, v in res["summary"].items():
        click.echo(f"{k}: {v:.3g}")
    click.echo(f"-> {out_path}")
