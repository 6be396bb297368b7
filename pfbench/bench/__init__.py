"""``pfbench bench``: engine speed as ns per particle-step and as ratios measured in one run.

Sections (each writes its JSON into the directory of ``--out``, default ``results/bench/``):

* **main** (``bench.json``), all single-threaded unless stated, medians of ``--repeats``:

  - Ob1 bootstrap ([Embedded] Alg. 1, systematic) at (M, N_p) = (1000, 1000), (500, 1000),
    (500, 500) and (100, 100000), numba on 1 thread and NumPy, float64 and float32;
  - the C reference in the same run (:mod:`pfbench.bench.c_reference`): the project's pf_ob1.c
    built for this host at -O3 -march=native, once with its own libc RNG and once with a fast RNG;
  - the irreducible-work floor (1 normal + 1 exp per particle-step) and its breakdown
    (:mod:`pfbench.bench.floor`), and each part of the particle kernel timed alone
    (:mod:`pfbench.bench.passes`), once more in float32 and float64 at the large N_p (where the
    float32 target is judged: the measured account of what float32 gains and what it pays);
  - numba on all cores vs 1 thread at N_p = 10^5 and 10^6;
  - MultiPDF ([MultiPDF] Alg. 2), N_f = 2: 1 thread vs all cores;
  - the PMSM SMC step with the optimal proposal ([Thesis] §4.2.1, 60 particles) against the
    drive's 125 us sampling period;
  - the ``particles`` library's bootstrap filter (``scripts/bench_particles.py`` in
    ``.venv-particles``, when it exists; ``make bench`` creates it);
  - the timings behind the targets once more in interleaved rounds (:func:`paired_rounds`: every
    timer once per round), so that each target's ratio is a median of ratios taken back to back on
    the same machine speed;
  - every ratio printed next to its target with a computed verdict (:mod:`pfbench.bench.report`).

* **startup** (``startup.json``, :mod:`pfbench.bench.startup`): cold and warm wall time of
  ``pfbench run`` per method.
* **scaling** (``scaling.json``, ``scaling.png``, :mod:`pfbench.bench.scaling`): ns per
  particle-step for N_p = 10^2 ... 10^7.
* **busy** (``busy.json``, :mod:`pfbench.bench.busy`): the default thread count against one
  thread with 2 x (cores) other processes spinning.
* **sweep** (``sweep.json``, :mod:`pfbench.bench.sweep_scaling`): a sweep of about a minute on one
  worker (``--sweep-seconds``; 10 s with ``--quick``) on 1, 2 and all cores' workers
  (``--sweep-workers``): wall times and speed-ups.

``pfbench bench`` runs main + startup (``--quick``: main only, small), ``--scaling`` and/or
``--startup`` / ``--busy`` / ``--sweep`` run only those sections, ``--all`` runs all five. Compilation is excluded from
every timing but the startup section's: each configuration runs once untimed first.

``--document`` (:mod:`pfbench.bench.document`) then renders docs/PERFORMANCE.md from every JSON in
the folder of ``--out`` and the kept docs/performance_notes.md; alone it runs no benchmark, so the
page can be regenerated from existing results (``make bench`` ends with it).
"""
from __future__ import annotations

import os
from pathlib import Path

import click

from ..clitypes import OUT_FILE, positive_float
from ..errors import InputError
from .floor import breakdown_ns, floor_ns
from .timing import filter_ns, interleaved, paired_ratio, particles_ns, ratio_range

CONFIGS = ((1000, 1000), (500, 1000), (500, 500), (100, 100_000))
QUICK_CONFIGS = ((200, 1000), (20, 100_000))
#: (M, N_p) of the numba all-threads vs 1-thread comparison
THREAD_CONFIGS = ((100, 100_000), (20, 1_000_000))
QUICK_THREAD_CONFIGS = ((20, 100_000),)


def _ratio(a, b):
    return a / b if a is not None and b is not None and b > 0 else None


def run_bench(repeats: int = 5, quick: bool = False, with_particles: bool = True, progress: bool = True,
              with_c: bool = True) -> dict:
    """The main section (see the module docstring); returns the provenance record written to
    ``bench.json``."""
    from ..progress import progress_bar

    from .. import models
    from ..provenance import provenance
    from . import c_reference

    model = models.get("ob1")
    configs = QUICK_CONFIGS if quick else CONFIGS
    thread_cfgs = QUICK_THREAD_CONFIGS if quick else THREAD_CONFIGS
    n_jobs = len(configs) * (3 + 4 + 2) + 2 * len(thread_cfgs) + 2 + 1 + 1 + 1 + 1 + 1
    bar = progress_bar(show=progress, total=n_jobs, desc="bench", leave=False)
    rows, floors, c_rows = [], [], []
    c_note = None if with_c else "not run: --no-c"
    for m, n in configs:
        traj = model.simulate(m, seed=1)
        reps = repeats if n <= 1000 else max(1, repeats // 2)
        bar.set_postfix_str(f"M={m} N_p={n} floor")
        fl = {"steps": m, "particles": n, "numba_ns": floor_ns(n, m, reps, "numba"),
              "engine_ns": floor_ns(n, m, reps, "engine")}
        bar.update()
        fl["numpy_ns"] = floor_ns(n, m, reps, "numpy")
        bar.update()
        fl["breakdown_ns"] = breakdown_ns(n, m, reps)
        bar.update()
        floors.append(fl)
        for be in ("numba", "numpy"):
            for dt in ("float64", "float32"):
                bar.set_postfix_str(f"M={m} N_p={n} {be} {dt}")
                ns = filter_ns(model, traj, n, be, dt, reps if be == "numba" else max(1, reps // 2),
                               n_threads=1 if be == "numba" else None)
                bar.update()
                rows.append({"steps": m, "particles": n, "backend": be, "dtype": dt,
                             "threads": 1 if be == "numba" else None, "ns_per_particle_step": ns,
                             "floor_numba_ns": fl["numba_ns"], "floor_numpy_ns": fl["numpy_ns"],
                             "ratio_to_floor": ns / fl["numba_ns"]})
        for variant in c_reference.VARIANTS:
            bar.set_postfix_str(f"M={m} N_p={n} C {variant}")
            if c_note is None:
                try:
                    c_rows.append(c_reference.filter_ns(variant, m, n, reps))
                except c_reference.CUnavailable as exc:
                    c_note = str(exc)
            bar.update()
    threads = []
    for m, n in thread_cfgs:
        traj = model.simulate(m, seed=1)
        reps = max(1, repeats // 2)
        bar.set_postfix_str(f"N_p={n} threads")
        one = filter_ns(model, traj, n, "numba", "float64", reps, n_threads=1)
        bar.update()
        every = filter_ns(model, traj, n, "numba", "float64", reps, n_threads=None)
        bar.update()
        threads.append({"steps": m, "particles": n, "ns_1_thread": one, "ns_all_threads": every,
                        "speedup": one / every, "cores": os.cpu_count()})
    # MultiPDF: sub-filters in parallel
    n_mp = 200_000 if not quick else 50_000
    traj = model.simulate(50 if not quick else 30, seed=2)
    mp_reps = max(3, repeats // 2)  # short runs: thread start-up noise needs a few repeats
    bar.set_postfix_str("MultiPDF")
    one = filter_ns(model, traj, n_mp, "numba", "float64", mp_reps, "multipdf", 2, n_threads=1)
    two = filter_ns(model, traj, n_mp, "numba", "float64", mp_reps, "multipdf", 2, n_threads=2)
    bar.update(2)
    multipdf = {"particles": n_mp, "filters": 2, "ns_1_thread": one, "ns_2_threads": two,
                "speedup": one / two, "cores": os.cpu_count()}
    # PMSM SMC with the optimal proposal ([Thesis] §4.2.1): must fit the drive's 125 us period
    from ..plants.pmsm_control.smc import step_time_us

    bar.set_postfix_str("PMSM SMC")
    pmsm = {"particles": 60, "period_us": 125.0,
            "us_per_step_mean": step_time_us(n_particles=60, point="mean", repeats=max(1, repeats // 2)),
            "us_per_step_max": step_time_us(n_particles=60, point="max", repeats=max(1, repeats // 2))}
    pmsm["margin_x"] = pmsm["period_us"] / max(pmsm["us_per_step_mean"], pmsm["us_per_step_max"])
    bar.update()
    key, big = configs[0], configs[-1]
    bar.set_postfix_str("paired rounds")
    paired = paired_rounds(model, key, big, thread_cfgs, max(5, repeats), c_note is None and bool(c_rows))
    bar.update()
    bar.set_postfix_str("kernel parts")
    from .passes import dtype_parts, passes_ns

    parts = passes_ns(key[1], key[0], max(3, repeats))
    bar.update()
    bar.set_postfix_str(f"kernel parts float32 vs float64 N_p={big[1]}")
    dparts = dtype_parts(big[1], big[0], max(3, repeats))
    bar.update()
    bar.set_postfix_str("particles library")
    part = particles_ns(key[0], key[1], max(1, repeats // 2)) if with_particles else None
    bar.update()
    bar.close()

    s, targets = summarize(rows, floors, c_rows, threads, part, key, big, paired)
    return provenance(kind="bench", repeats=repeats, quick=quick, rows=rows, floors=floors, c_rows=c_rows,
                      c_note=c_note, threads=threads, multipdf=multipdf, pmsm_smc=pmsm, kernel_parts=parts,
                      dtype_parts=dparts, particles_library=part, paired=paired, summary=s, targets=targets)


def paired_rounds(model, key, big, thread_cfgs, rounds: int, with_c: bool) -> dict:
    """The timings behind the targets, taken in interleaved rounds (:func:`interleaved`): numba
    float64 1 thread, the floor and the C reference (fast RNG) at ``key``; numba float64 and
    float32 at ``big``; 1 thread and all threads at each of ``thread_cfgs``. Each timer is one run
    (compilation excluded). Returns ``{"rounds": R, "ns": name -> R timings, "ratios": name ->
    median of the per-round ratios, "ratio_ranges": name -> [smallest, largest] per-round ratio}``
    (the targets print the range beside the median: on a shared machine the all-threads runs of
    one round can be 30 % slower than the next round's while the 1-thread runs are not)."""
    from . import c_reference

    (m, n), (mb, nbig) = key, big
    tk, tb = model.simulate(m, seed=1), model.simulate(mb, seed=1)
    measures = {"numba": lambda: filter_ns(model, tk, n, "numba", "float64", 1, n_threads=1),
                "floor": lambda: floor_ns(n, m, 1, "numba")}
    if with_c:
        measures["c_fast"] = lambda: c_reference.filter_ns("fast", m, n, 1)["ns_per_particle_step"]
    measures["big_float64"] = lambda: filter_ns(model, tb, nbig, "numba", "float64", 1, n_threads=1)
    measures["big_float32"] = lambda: filter_ns(model, tb, nbig, "numba", "float32", 1, n_threads=1)
    for mt, nt in thread_cfgs:
        tt = model.simulate(mt, seed=1)
        measures[f"threads_1_{nt}"] = lambda tt=tt, nt=nt: filter_ns(model, tt, nt, "numba", "float64", 1, n_threads=1)
        measures[f"threads_all_{nt}"] = lambda tt=tt, nt=nt: filter_ns(model, tt, nt, "numba", "float64", 1,
                                                                     n_threads=None)
    ns = interleaved(measures, rounds)
    pairs = {"numba_over_c": ("numba", "c_fast"), "numba_over_floor": ("numba", "floor"),
             "float32_speedup_big": ("big_float64", "big_float32"),
             **{f"threads_speedup_{nt}": (f"threads_1_{nt}", f"threads_all_{nt}") for _, nt in thread_cfgs}}
    ratios = {k: paired_ratio(ns[a], ns[b]) if b in ns else None for k, (a, b) in pairs.items()}
    ranges = {k: ratio_range(ns[a], ns[b]) if b in ns else None for k, (a, b) in pairs.items()}
    return {"rounds": int(rounds), "ns": ns, "ratios": ratios, "ratio_ranges": ranges}


def summarize(rows, floors, c_rows, threads, part, key, big, paired=None) -> tuple[dict, list]:
    """The ratios of the main section (all from timings of the same run) and the targets with
    computed verdicts. ``key`` = (M, N_p) of the headline configuration, ``big`` the large one.
    With ``paired`` (:func:`paired_rounds`) the targets are judged on its per-round ratios, which
    a change of the machine's speed between two sections cannot skew; the ratios of the section
    medians stay in the summary beside them."""
    from .report import TARGETS, check

    by = {(r["steps"], r["particles"], r["backend"], r["dtype"]): r["ns_per_particle_step"] for r in rows}
    cby = {(r["steps"], r["particles"], r["variant"]): r["ns_per_particle_step"] for r in c_rows}
    nb, npy = by[key + ("numba", "float64")], by[key + ("numpy", "float64")]
    c_fast, c_libc = cby.get(key + ("fast",)), cby.get(key + ("libc",))
    c_best = min((v for v in (c_fast, c_libc) if v is not None), default=None)
    fl0 = floors[0]
    s = {"config": {"steps": key[0], "particles": key[1]}, "big_config": {"steps": big[0], "particles": big[1]},
         "numba_ns": nb, "numpy_ns": npy, "floor_numba_ns": fl0["numba_ns"],
         "c_fast_ns": c_fast, "c_libc_ns": c_libc, "c_best_ns": c_best,
         "c_best_variant": None if c_best is None else ("fast" if c_best == c_fast else "libc"),
         "numba_over_c": _ratio(nb, c_best), "numba_over_c_libc": _ratio(nb, c_libc),
         "numpy_over_c": _ratio(npy, c_best), "c_libc_over_c_fast": _ratio(c_libc, c_fast),
         "numba_over_floor": nb / fl0["numba_ns"], "floor_engine_ns": fl0["engine_ns"],
         "numba_over_floor_engine": nb / fl0["engine_ns"],
         "numpy_over_numba_big": by[big + ("numpy", "float64")] / by[big + ("numba", "float64")],
         "float32_over_float64_numba": by[key + ("numba", "float32")] / nb,
         "float32_speedup_big": by[big + ("numba", "float64")] / by[big + ("numba", "float32")]}
    if part and "ns_per_particle_step" in part:
        s["particles_ns"] = part["ns_per_particle_step"]
        s["particles_over_numba"] = part["ns_per_particle_step"] / nb
        s["particles_over_numpy"] = part["ns_per_particle_step"] / npy
    for t in threads:
        s[f"threads_speedup_{t['particles']:.0e}".replace("+0", "")] = t["speedup"]
    m_lab = f"M={key[0]}, N_p={key[1]}"
    unpaired = {"numba_over_c": s["numba_over_c"], "numba_over_floor": s["numba_over_floor"],
                "float32_speedup_big": s["float32_speedup_big"],
                **{f"threads_speedup_{t['particles']}": t["speedup"] for t in threads}}
    src, how = (paired["ratios"], f", paired over {paired['rounds']} rounds") if paired else (unpaired, "")
    spread = paired.get("ratio_ranges", {}) if paired else {}

    def how_of(k):  # the rounds' spread beside the median they give
        r = spread.get(k)
        return how + (f" (rounds {r[0]:.2f}-{r[1]:.2f}x)" if r else "")
    if paired:
        s["paired"] = dict(src)
    c_lab = "fast" if paired else (s["c_best_variant"] or "n/a")
    targets = [check("numba_over_c", src.get("numba_over_c"),
                     f"numba float64 1 thread / C ({c_lab} RNG), {m_lab}{how_of('numba_over_c')}"),
               check("numba_over_floor", src["numba_over_floor"],
                     f"numba float64 1 thread / floor, {m_lab}{how_of('numba_over_floor')}"),
               check("float32_speedup_1e5", src["float32_speedup_big"] if big[1] == 100_000 else None,
                     f"{TARGETS['float32_speedup_1e5'].label}{how_of('float32_speedup_big')}")]
    for t in threads:
        k = {100_000: "threads_speedup_1e5", 1_000_000: "threads_speedup_1e6"}.get(t["particles"])
        if k:
            name = f"threads_speedup_{t['particles']}"
            targets.append(check(k, src.get(name), f"{TARGETS[k].label}{how_of(name)}"))
    return s, targets


def _f(v, spec=".1f", none="n/a"):
    return none if v is None else format(v, spec)


def main_text(res: dict) -> list[str]:
    """The main section as printed lines."""
    from .report import fmt

    out = [f"{'M':>6} {'N_p':>7} {'engine':>22} {'dtype':>8} {'ns/p-step':>10} {'x floor':>8}"]
    for r in res["rows"]:
        eng = f"{r['backend']}" + (", 1 thread" if r["threads"] == 1 else "")
        out.append(f"{r['steps']:>6} {r['particles']:>7} {eng:>22} {r['dtype']:>8} "
                   f"{r['ns_per_particle_step']:>10.1f} {r['ratio_to_floor']:>8.2f}")
    floor_by = {(f["steps"], f["particles"]): f["numba_ns"] for f in res["floors"]}
    for c in res["c_rows"]:
        out.append(f"{c['steps']:>6} {c['particles']:>7} {'C ' + c['variant'] + ' RNG':>22} {'float64':>8} "
                   f"{c['ns_per_particle_step']:>10.1f} "
                   f"{c['ns_per_particle_step'] / floor_by[(c['steps'], c['particles'])]:>8.2f}")
    if res["c_rows"]:
        from .c_reference import RNG

        c0 = res["c_rows"][0]
        out.append(f"C reference: pfbench/mcu/c/pf_ob1.c via host_bench.c, {c0['compiler']}, {c0['flags']}; "
                   + "; ".join(f"{v} RNG = {RNG[v]}" for v in RNG))
    if res["c_note"]:
        out.append(f"C reference: {res['c_note']}")
    for f in res["floors"]:
        b = f["breakdown_ns"]
        out.append(f"floor M={f['steps']} N_p={f['particles']} (1 normal + 1 exp per particle-step): numba "
                   f"{f['numba_ns']:.1f} ns (library normal and exp), {f['engine_ns']:.1f} ns (the engine's "
                   f"inlined normal and vectorised exp), numpy {f['numpy_ns']:.1f} ns; parts (numba): normal "
                   f"{b['normal']:.1f} (library) or {b['normal_engine']:.1f} (engine) + exp {b['exp']:.1f} "
                   f"(library) or {b['exp_engine']:.1f} ns (engine), one memory pass "
                   f"{b['memory_pass']:.2f} ns")
    for t in res["threads"]:
        out.append(f"numba float64 N_p={t['particles']} M={t['steps']}: 1 thread {t['ns_1_thread']:.1f} ns, "
                   f"all {t['cores']} cores {t['ns_all_threads']:.1f} ns, speed-up {t['speedup']:.2f}x")
    mp = res["multipdf"]
    out.append(f"MultiPDF N_p={mp['particles']} N_f=2 numba: 1 thread {mp['ns_1_thread']:.1f} ns, "
               f"2 threads {mp['ns_2_threads']:.1f} ns, speed-up {mp['speedup']:.2f}x on {mp['cores']} cores")
    pm = res["pmsm_smc"]
    out.append(f"PMSM SMC, 60 particles, numba: {pm['us_per_step_mean']:.1f} us/step (mean estimate), "
               f"{pm['us_per_step_max']:.1f} us/step (maximum); period 125 us, margin {pm['margin_x']:.1f}x")
    s = res["summary"]
    part = res["particles_library"]
    if part is None:
        out.append("particles library: not run (no .venv-particles; `make bench` creates it)")
    elif "ns_per_particle_step" not in part:
        out.append(f"particles library: failed: {part.get('error')}")
    else:
        out.append(f"particles library {part.get('version', '?')}: {part['ns_per_particle_step']:.1f} ns "
                   f"= {s['particles_over_numba']:.1f}x numba, {s['particles_over_numpy']:.2f}x numpy")
    cfg, big = s["config"], s["big_config"]
    out.append(f"ratios (M={cfg['steps']}, N_p={cfg['particles']} unless noted): numba/C "
               f"{_f(s['numba_over_c'], '.2f')} (C {s['c_best_variant'] or 'n/a'} RNG), numba/C libc RNG "
               f"{_f(s['numba_over_c_libc'], '.2f')}, numpy/C {_f(s['numpy_over_c'], '.2f')}, numba/floor "
               f"{s['numba_over_floor']:.2f} (library normal and exp; {s['numba_over_floor_engine']:.2f} against "
               f"the floor with the engine's own), float32/float64 time {s['float32_over_float64_numba']:.2f}; "
               f"at N_p={big['particles']}: numpy/numba {s['numpy_over_numba_big']:.2f}, float32 speed-up "
               f"{s['float32_speedup_big']:.2f}x")
    fl = res["floors"][0]
    b = fl["breakdown_ns"]
    rest = s["numba_ns"] - b["normal_engine"] - b["exp_engine"]
    out.append(f"where the ns go (numba float64 1 thread, M={cfg['steps']}, N_p={cfg['particles']}: "
               f"{s['numba_ns']:.1f} ns): the kernel's own normal {b['normal_engine']:.1f} + exp "
               f"{b['exp_engine']:.1f} (timed alone; the library's cost {b['normal']:.1f} + {b['exp']:.1f} = the "
               f"floor {fl['numba_ns']:.1f}); the other {rest:.1f} ns are the rest of the step "
               f"(transition, likelihood arithmetic, weight normalisation, moments, resampling); one pass "
               f"over the particles costs {b['memory_pass']:.2f} ns at this N_p")
    pd = res.get("paired")
    if pd:
        import statistics

        med = {k: statistics.median(v) for k, v in pd["ns"].items()}
        out.append(f"paired rounds ({pd['rounds']} rounds, every timer once per round, ratios within a round; "
                   "the targets below use these): median ns " + ", ".join(f"{k} {v:.1f}" for k, v in med.items())
                   + "; ratios " + ", ".join(f"{k} {_f(v, '.2f')}" for k, v in pd["ratios"].items()))
    if res.get("kernel_parts"):
        from .passes import passes_text

        out.append(passes_text(res["kernel_parts"]))
    if res.get("dtype_parts"):
        from .passes import dtype_text

        out.append(dtype_text(res["dtype_parts"]))
    out.extend(fmt(t) for t in res["targets"])
    return out


def _section_paths(out_path) -> dict:
    d = Path(out_path).parent
    return {"bench": Path(out_path), "startup": d / "startup.json", "scaling": d / "scaling.json",
            "scaling_png": d / "scaling.png", "busy": d / "busy.json", "sweep": d / "sweep.json",
            "end_to_end": d / "end_to_end.json"}


@click.command()
@click.option("--repeats", type=click.IntRange(1, 100), default=5, show_default=True,
              help="Timed repetitions per configuration (medians are reported).")
@click.option("--quick", is_flag=True, help="Smaller configurations (a smoke run).")
@click.option("--scaling", is_flag=True, help="Only (or also, with --startup) the N_p = 10^2..10^7 scaling "
              "section: scaling.json and scaling.png beside --out.")
@click.option("--startup", is_flag=True, help="Only (or also, with --scaling) the cold/warm start per method: "
              "startup.json beside --out.")
@click.option("--busy", is_flag=True, help="Only (or also) the default thread count vs 1 thread with "
              "2 x (cores) busy processes: busy.json beside --out.")
@click.option("--sweep", "sweep", is_flag=True, help="Only (or also) a sweep's speed-up on 1, 2 and all cores' "
              "workers: sweep.json beside --out.")
@click.option("--end-to-end", "end_to_end", is_flag=True, help="Only (or also) whole run_filter calls at "
              "N_p = 10^6, M = 12 on 1 and 2 threads, set-up included: end_to_end.json beside --out.")
@click.option("--sweep-workers", default=None, metavar="W[,W...]",
              help="Worker counts of --sweep (default 1, 2 and the usable cores; 1 is always run).")
@click.option("--sweep-seconds", type=click.FloatRange(min=1.0), default=None, callback=positive_float("sweep-seconds"),
              help="Size of the --sweep sweep in seconds on 1 worker (default 60; 10 with --quick).")
@click.option("--all", "run_all", is_flag=True, help="Main, startup, scaling, busy, sweep and end-to-end sections.")
@click.option("--cold-repeats", type=click.IntRange(1, 20), default=1, show_default=True,
              help="Cold starts per method (each on a fresh, empty cache; expensive).")
@click.option("--no-particles", is_flag=True, help="Skip the `particles` library comparison.")
@click.option("--no-c", is_flag=True, help="Skip the C reference.")
@click.option("--out", "out_path", **OUT_FILE, default="results/bench/bench.json",
              show_default=True, help="Main JSON; the other sections write beside it.")
@click.option("--document", is_flag=True, help="Then regenerate docs/PERFORMANCE.md from every JSON beside "
              "--out and docs/performance_notes.md; alone, run no benchmark (the page from existing results).")
@click.option("--json", "as_json", is_flag=True, help="Print the results as one JSON object by section.")
def bench(repeats, quick, scaling, startup, busy, sweep, end_to_end, sweep_workers, sweep_seconds, run_all,
          cold_repeats, no_particles, no_c, out_path, document, as_json):
    """Time the engine against the floor, the C reference and the `particles` library; cold/warm
    start per method (--startup); cost vs N_p (--scaling); whole short runs at large N_p
    (--end-to-end); regenerate docs/PERFORMANCE.md (--document)."""
    from ..io import to_json, write_json
    from ..resources import check_writable, path_error

    if sweep_workers is not None:
        from ..options import comma_list, typed

        sweep_workers = [typed(w, int, "--sweep-workers") for w in comma_list(sweep_workers, "--sweep-workers")]
        if min(sweep_workers) < 1:
            raise InputError(f"--sweep-workers must be integers >= 1, got {min(sweep_workers)}")
    if run_all:
        sections = ["bench", "startup", "scaling", "busy", "sweep", "end_to_end"]
    elif scaling or startup or busy or sweep or end_to_end:
        sections = [s for s, on in (("startup", startup), ("scaling", scaling), ("busy", busy), ("sweep", sweep),
                                    ("end_to_end", end_to_end)) if on]
    elif document and not quick:  # the page alone, from the results already there
        sections = []
    else:
        sections = ["bench"] if quick else ["bench", "startup"]
    paths = _section_paths(out_path)
    for s in sections:
        check_writable(paths[s], "--out")  # before minutes of timing, not after
    if document:
        from . import document as doc

        doc.check_notes()
        where = paths["bench"].parent
        if not sections and not any(where.glob("*.json")):   # a mistyped --out: a page of "not measured"
            raise InputError(f"--document: no benchmark results in {where} (give the --out of an earlier "
                             "`pfbench bench`, or run one)")
        check_writable(doc.DOC, "--document")
    results, lines = {}, []

    def save(name, res):
        try:
            write_json(paths[name], res)
        except OSError as exc:  # e.g. the disk filled up meanwhile
            raise path_error(exc, paths[name], "--out") from None
        results[name] = res

    if "bench" in sections:
        res = run_bench(repeats=repeats, quick=quick, with_particles=not no_particles, with_c=not no_c)
        save("bench", res)
        lines += main_text(res) + [f"-> {paths['bench']}"]
        if not as_json:
            click.echo("\n".join(lines))
            lines = []
    if "startup" in sections:
        from .startup import CASES, run_startup, text

        cases = CASES[:1] if quick else CASES
        res = run_startup(repeats=1 if quick else repeats, cold_repeats=cold_repeats, cases=cases)
        from ..provenance import provenance

        res = provenance(**res)
        save("startup", res)
        lines += ["", "cold and warm start per method:", *text(res), f"-> {paths['startup']}"]
        if not as_json:
            click.echo("\n".join(lines))
            lines = []
    if "scaling" in sections:
        from .scaling import ENGINES, SIZES, plot, run_scaling, text

        kw = dict(sizes=SIZES[:4], target=10 ** 6) if quick else {}
        engines = tuple(e for e in ENGINES if not (no_c and e == "c_fast"))
        res = run_scaling(repeats=max(1, min(repeats, 3)), engines=engines, **kw)
        save("scaling", res)
        plot(res, paths["scaling_png"])
        lines += ["", "cost vs N_p (Ob1 bootstrap, float64):", *text(res),
                  f"-> {paths['scaling']}, {paths['scaling_png']}"]
    if "busy" in sections:
        from .busy import run_busy, text as busy_text

        res = run_busy(rounds=3 if quick else max(repeats, 3))
        save("busy", res)
        lines += ["", "default threads on a busy machine (Ob1 bootstrap, M = 200, medians of 3):", *busy_text(res),
                  f"-> {paths['busy']}"]
    if "sweep" in sections:
        from .sweep_scaling import QUICK_SECONDS, SECONDS, run_sweep_scaling, text as sweep_text

        seconds = sweep_seconds or (QUICK_SECONDS if quick else SECONDS)
        res = run_sweep_scaling(seconds=seconds, workers=sweep_workers, rounds=max(1, min(repeats, 3)))
        save("sweep", res)
        lines += ["", "a sweep on 1 worker and on several:", *sweep_text(res), f"-> {paths['sweep']}"]
    if "end_to_end" in sections:
        from .scaling import end_to_end_text, run_end_to_end

        res = run_end_to_end(rounds=3 if quick else max(repeats, 9))
        save("end_to_end", res)
        lines += ["", "whole runs, set-up included:", end_to_end_text(res), f"-> {paths['end_to_end']}"]
    if document:
        res = doc.write(results_dir=paths["bench"].parent)
        missing = [k for k, files in res["kinds"].items() if not files]
        results["document"] = res
        lines += [""] * bool(sections) + [f"-> {res['path']} (from {paths['bench'].parent}/*.json and {doc.NOTES}"
                  + (f"; not measured: {', '.join(missing)}" if missing else "") + ")"]
    if as_json:
        click.echo(to_json(results))
    elif lines:
        click.echo("\n".join(lines))
