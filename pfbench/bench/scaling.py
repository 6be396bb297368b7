"""``pfbench bench --scaling``: how the cost per particle-step grows with N_p.

Ob1 bootstrap ([Embedded] Alg. 1, systematic resampling, float64) at N_p = 10^2 ... 10^7 (decades)
for four engines: numba on 1 thread, numba on all cores, NumPy, and the C reference with the fast
RNG (:mod:`pfbench.bench.c_reference`). Each size runs M = max(``min_steps``, round(target / N_p))
steps, so every run does about ``target`` particle-steps. A size whose estimated memory
(:func:`pfbench.resources.filter_memory`; for C three particle arrays) does not fit what this
process may use (:func:`pfbench.resources.memory_limits`, :data:`~pfbench.resources.USABLE_FRACTION`
of the tightest limit) is skipped, and the output says what limits the top: the range asked, or
memory (with the limit and the largest N_p that would fit).

The two numba engines run in rounds (each round one run on 1 thread, then one on all threads,
each after its own 3-step warm-up), and their speed-up is the median of the per-round ratios
(:func:`pfbench.bench.timing.paired_ratio`): two medians taken one after the other can compare a
fast phase of a shared machine with a slow one. Each time is a whole run, set-up included
(allocating and first touching the work arrays, the block streams, the initial particles): at
large N_p that is about one step's time on 1 thread. :func:`end_to_end` times what a caller
waits for, whole :func:`pfbench.run_filter` calls of a short run at large N_p on 1 and k threads,
the case where a serial set-up caps the speed-up.
"""
from __future__ import annotations

import statistics

ENGINES = {"numba_1t": "numba, 1 thread", "numba_all": "numba, all threads", "numpy": "NumPy",
           "c_fast": "C, fast RNG"}
SIZES = tuple(10 ** k for k in range(2, 8))
TARGET_PARTICLE_STEPS = 10 ** 7
MIN_STEPS = 5


def _pow10(n: int) -> str:
    """``10^k`` when ``n`` is a power of ten, else ``n``."""
    k = len(str(n)) - 1
    return f"10^{k}" if n == 10 ** k else str(n)


def plan(sizes=SIZES, target: int = TARGET_PARTICLE_STEPS, min_steps: int = MIN_STEPS) -> list[tuple[int, int]]:
    """``[(N_p, M)]`` with M = max(min_steps, round(target / N_p))."""
    return [(int(n), max(int(min_steps), int(round(target / n)))) for n in sizes]


def _budget():
    from ..resources import USABLE_FRACTION, memory_limits

    lims = memory_limits()
    if not lims:
        return None, "no memory limit found"
    lim = min(lims, key=lambda L: L.free)
    return int(lim.free * USABLE_FRACTION), lim.source


def _need(model, engine: str, n: int, m: int) -> int:
    from ..resources import filter_memory
    from .c_reference import memory_bytes

    if engine == "c_fast":
        return memory_bytes(m, n)
    backend = "numpy" if engine == "numpy" else "numba"
    return filter_memory(model, "bootstrap", n_steps=m, backend=backend).bytes(n)


def run_scaling(repeats: int = 3, sizes=SIZES, target: int = TARGET_PARTICLE_STEPS,
                min_steps: int = MIN_STEPS, engines=tuple(ENGINES), progress: bool = True,
                gpu: bool = True) -> dict:
    """Time every engine at every size; returns the table, the top's limit and the ratios."""
    from ..progress import progress_bar

    from .. import models
    from ..errors import InputError
    from ..provenance import provenance
    from ..resources import filter_memory, fmt_bytes
    from . import c_reference
    from .report import check
    from .timing import filter_ns, interleaved, paired_ratio, ratio_range

    model = models.get("ob1")
    budget, source = _budget()
    jobs = plan(sizes, target, min_steps)
    rows = []
    c_note = None
    bar = progress_bar(show=progress, total=len(jobs) * len(engines), desc="bench --scaling", leave=False)
    paired, spread = {}, {}  # N_p -> median over rounds of the 1-thread / all-threads time; its [min, max]
    for n, m in jobs:
        traj = None
        numba_rows = {}
        for eng in engines:
            bar.set_postfix_str(f"N_p={_pow10(n)} {eng}")
            row = {"particles": n, "steps": m, "engine": eng, "label": ENGINES[eng],
                   "ns_per_particle_step": None}
            need = _need(model, eng, n, m)
            row["memory_need_bytes"] = need
            if budget is not None and need > budget:
                row["skipped"] = (f"memory: needs about {fmt_bytes(need)}, a run may plan on "
                                  f"{fmt_bytes(budget)} ({source})")
            elif eng == "c_fast":
                if c_note is None:
                    try:
                        r = c_reference.filter_ns("fast", m, n, repeats)
                        row["ns_per_particle_step"] = r["ns_per_particle_step"]
                        row["rng"] = r["rng"]
                    except c_reference.CUnavailable as exc:
                        c_note = str(exc)
                if c_note is not None:
                    row["skipped"] = c_note
            elif eng == "numpy":
                traj = traj or model.simulate(m, seed=1)
                try:
                    row["ns_per_particle_step"] = filter_ns(model, traj, n, "numpy", "float64", max(1, repeats))
                except InputError as exc:  # run_filter's own memory check refused it
                    row["skipped"] = f"refused: {exc}"
            else:  # the numba engines: timed below, in rounds
                numba_rows[eng] = row
            rows.append(row)
            if eng not in numba_rows:
                bar.update()
        if numba_rows:
            bar.set_postfix_str(f"N_p={_pow10(n)} " + " / ".join(numba_rows))
            traj = traj or model.simulate(m, seed=1)
            measures = {eng: (lambda k=(1 if eng == "numba_1t" else None):
                              filter_ns(model, traj, n, "numba", "float64", 1, n_threads=k))
                        for eng in numba_rows}
            try:  # 1 thread and all threads back to back in each round: their ratio sees one machine
                times = interleaved(measures, repeats)
            except InputError as exc:
                for row in numba_rows.values():
                    row["skipped"] = f"refused: {exc}"
            else:
                for eng, row in numba_rows.items():
                    row["ns_per_particle_step"] = statistics.median(times[eng])
                if len(times) == 2:
                    paired[n] = paired_ratio(times["numba_1t"], times["numba_all"])
                    spread[n] = ratio_range(times["numba_1t"], times["numba_all"])
            bar.update(len(numba_rows))
    bar.close()

    largest = {e: max((r["particles"] for r in rows if r["engine"] == e and r["ns_per_particle_step"] is not None),
                      default=None) for e in engines}
    skipped_mem = [r for r in rows if str(r.get("skipped", "")).startswith(("memory", "refused"))]
    if skipped_mem:
        first = skipped_mem[0]
        why = first["skipped"].split(": ", 1)[-1]
        limited = f"memory: from N_p = {first['particles']} on ({first['label']}): {why}"
    else:
        fits = (filter_memory(model, "bootstrap", n_steps=min_steps, backend="numpy").largest(budget)
                if budget is not None else None)
        limited = (f"the sizes asked (largest N_p = {max(n for n, _ in jobs)}); memory would allow the "
                   f"NumPy backend up to about N_p = {fits:.2g} ({source})" if fits is not None
                   else f"the sizes asked (largest N_p = {max(n for n, _ in jobs)})")
    by = {(r["engine"], r["particles"]): r["ns_per_particle_step"] for r in rows}

    def ratio(a, b):
        return a / b if a is not None and b is not None and b > 0 else None

    growth = ratio(by.get(("numba_1t", 10 ** 6)), by.get(("numba_1t", 10 ** 3)))
    speedup = {n: paired.get(n) for n, _ in jobs}
    targets = [check("ns_1e6_over_1e3", growth),
               check("threads_speedup_1e6", speedup.get(10 ** 6)),
               check("threads_speedup_1e5", speedup.get(10 ** 5))]
    gpu = gpu_section(model, sizes, target, min_steps, repeats) if gpu else {"skipped": "not asked"}
    rows += gpu.pop("rows", [])
    shown = {e: ENGINES[e] for e in engines}
    if any(r["engine"] == "cupy" for r in rows):
        shown["cupy"] = GPU_LABEL
    return provenance(kind="bench_scaling", repeats=repeats, target_particle_steps=target,
                      min_steps=min_steps, engines=shown, rows=rows, gpu=gpu,
                      largest_particles_run=largest, top_limited_by=limited,
                      memory_budget_bytes=budget, memory_budget_source=source,
                      numba_1t_ns_1e6_over_1e3=growth,
                      threads_speedup={str(n): s for n, s in speedup.items()},
                      threads_speedup_rounds={str(n): spread.get(n) for n in speedup},
                      c_note=c_note, targets=targets)


GPU_LABEL = "CuPy, GPU"


def gpu_section(model, sizes, target: int, min_steps: int, repeats: int) -> dict:
    """The ``cupy`` rows (float64, ``sizes`` and 10^8 if the device memory allows) and the copy
    bandwidth floor, or ``{"skipped": reason}`` without CuPy or a GPU."""
    from ..backends import cupy_backend
    from ..errors import InputError
    from ..filters import run_filter

    try:
        cp = cupy_backend.import_cupy()
    except InputError as exc:
        return {"skipped": str(exc)}
    bw = cupy_backend.d2d_bandwidth(cp)
    out = {"gpu": cupy_backend.gpu_info(), "d2d_bytes_per_s": bw, "floor_ns_float64": 16e9 / bw, "rows": []}
    free = cp.cuda.Device().mem_info[0]
    for n, m in plan(sorted(set(sizes) | {10 ** 8}), target, min_steps):
        row = {"particles": n, "steps": m, "engine": "cupy", "label": GPU_LABEL, "ns_per_particle_step": None}
        need = cupy_backend.device_memory_need(model, n, 1, "float64", "bootstrap", True)
        if need > free * cupy_backend.DEVICE_FRACTION:
            row["skipped"] = f"GPU memory: needs about {need / 2**30:.1f} GiB, {free / 2**30:.1f} GiB free"
        else:
            traj = model.simulate(m, seed=1)
            run_filter(model, traj.y[:3], n_particles=n, backend="cupy")  # kernels built and checked
            loop = [run_filter(model, traj.y, n_particles=n, backend="cupy", seed=r).info["loop_s"]
                    for r in range(max(1, repeats))]
            row["ns_per_particle_step"] = statistics.median(loop) * 1e9 / (n * m)
        out["rows"].append(row)
    return out


def plot(res: dict, path) -> None:
    """ns per particle-step vs N_p (log-log), one line per engine, to ``path`` (PNG, atomic)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from ..io import write_figure

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for eng, label in res["engines"].items():
        pts = [(r["particles"], r["ns_per_particle_step"]) for r in res["rows"]
               if r["engine"] == eng and r["ns_per_particle_step"] is not None]
        if pts:
            ax.plot(*zip(*pts), marker="o", label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("N_p (particles)")
    ax.set_ylabel("ns per particle-step")
    ax.set_title("Ob1 bootstrap, float64: cost per particle-step vs N_p")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    write_figure(path, fig)


def text(res: dict) -> list[str]:
    """The table and ratios as printed lines."""
    from .report import fmt

    engines = list(res["engines"])
    sizes = sorted({r["particles"] for r in res["rows"]})
    by = {(r["engine"], r["particles"]): r for r in res["rows"]}
    out = [f"{'N_p':>9} {'M':>7} " + " ".join(f"{res['engines'][e]:>19}" for e in engines)]
    for n in sizes:
        cells = []
        for e in engines:
            r = by.get((e, n))
            v = None if r is None else r["ns_per_particle_step"]
            cells.append(f"{v:>19.1f}" if v is not None else f"{'skipped':>19}")
        m = next(r["steps"] for r in res["rows"] if r["particles"] == n)
        out.append(f"{n:>9} {m:>7} " + " ".join(cells))
    out.append("(ns per particle-step, median of the repeats; M chosen for about "
               f"{_pow10(res['target_particle_steps'])} particle-steps per run, at least {res['min_steps']} steps)")
    if res.get("c_note"):
        out.append(f"C: {res['c_note']}")
    for r in res["rows"]:
        if r.get("skipped") and r["engine"] != "c_fast":
            out.append(f"skipped {r['label']} at N_p = {r['particles']}: {r['skipped']}")
    out.append(f"top of the range limited by: {res['top_limited_by']}")
    g = res.get("gpu") or {}
    if g.get("d2d_bytes_per_s"):
        out.append(f"GPU {g['gpu'].get('gpu')}: device-to-device copy {g['d2d_bytes_per_s'] / 1e9:.0f} GB/s, "
                   f"the floor of one float64 pass: {g['floor_ns_float64']:.4f} ns per particle")
    elif g.get("skipped"):
        out.append(f"GPU column skipped: {g['skipped']}")
    rounds = res.get("threads_speedup_rounds", {})
    sp = ", ".join(f"N_p={_pow10(int(n))}: {v:.2f}x" + (f" (rounds {rounds[n][0]:.2f}-{rounds[n][1]:.2f}x)"
                                                          if rounds.get(n) else "")
                   for n, v in res["threads_speedup"].items() if v is not None)
    out.append(f"numba all threads vs 1 thread (median of per-round ratios): {sp}")
    out.extend(fmt(t) for t in res["targets"])
    return out


def _busy_s() -> float | None:
    """CPU seconds every process has used since boot (``/proc/stat``; None without it)."""
    import os

    try:
        with open("/proc/stat") as f:
            fields = f.readline().split()[1:]
    except OSError:
        return None
    idle = int(fields[3]) + int(fields[4])  # idle, iowait
    return (sum(int(v) for v in fields[:8]) - idle) / os.sysconf("SC_CLK_TCK")


def end_to_end(n: int = 10 ** 6, steps: int = 12, rounds: int = 9, threads: int = 2,
               method: str = "bootstrap", quiet: float = 0.05) -> dict:
    """Wall time of whole :func:`pfbench.run_filter` calls (Ob1, numba, float64) on 1 and on
    ``threads`` threads, paired in ``rounds`` interleaved rounds (:func:`pfbench.bench.timing.interleaved`).

    Why beside the table above: a short run at large N_p pays its set-up (the block streams, the
    initial draw, first touch of the work arrays, the output arrays, the checks) once, so its
    speed-up from threads is below the per-step one unless the set-up runs on the threads too; this
    times everything the caller waits for, where ``elapsed_s`` leaves out what precedes the kernel
    call. Each run's ``elapsed_s`` (the kernel call and what the backend sets up for it) is kept
    beside its wall time, so the result also says how much of a shortfall lies outside the kernel.
    A round is quiet when the CPU time other processes used during it is below ``quiet`` of
    its wall time (``/proc/stat`` less this process): one busy core halves a 2-thread run's speed,
    so the speed-up is also given over the quiet rounds alone. Returns the per-round seconds and
    others' CPU fraction, the medians and the median per-round ratios."""
    import time

    from .. import models
    from ..filters import run_filter
    from .timing import paired_ratio, ratio_range

    model = models.get("ob1")
    traj = model.simulate(steps, seed=1)
    kw = dict(method=method, n_particles=int(n), backend="numba", dtype="float64")
    for k in (1, threads):  # compile / warm up outside the rounds
        run_filter(model, traj.y[:3], None, seed=0, n_threads=k, **kw)
    wall, kernel, others = ([], []), ([], []), []  # [0]: 1 thread, [1]: ``threads``
    for _ in range(max(int(rounds), 1)):
        b0, c0, w0 = _busy_s(), time.process_time(), time.perf_counter()
        for i, k in enumerate((1, threads)):
            t0 = time.perf_counter()
            res = run_filter(model, traj.y, None, seed=0, n_threads=k, **kw)
            wall[i].append(time.perf_counter() - t0)
            kernel[i].append(float(res.elapsed_s))
        b1, c1, w1 = _busy_s(), time.process_time(), time.perf_counter()
        others.append(None if b0 is None else max(0.0, (b1 - b0) - (c1 - c0)) / (w1 - w0))
    one, many = wall
    outside = [[w - e for w, e in zip(wall[i], kernel[i])] for i in (0, 1)]
    calm = [r for r, o in enumerate(others) if o is not None and o < quiet]
    res = {"particles": int(n), "steps": int(steps), "threads": int(threads), "rounds": len(one),
           "s_1_thread": one, "s_threads": many, "others_cpu_fraction": others,
           "kernel_s_1_thread": kernel[0], "kernel_s_threads": kernel[1],
           "median_s_1_thread": statistics.median(one), "median_s_threads": statistics.median(many),
           "median_outside_s_1_thread": statistics.median(outside[0]),
           "median_outside_s_threads": statistics.median(outside[1]),
           "speedup": paired_ratio(one, many), "speedup_rounds": ratio_range(one, many),
           "kernel_speedup": paired_ratio(*kernel), "kernel_speedup_rounds": ratio_range(*kernel),
           "quiet_rounds": len(calm)}
    if calm:
        q1, qk = [one[r] for r in calm], [many[r] for r in calm]
        res.update(quiet_median_s_1_thread=statistics.median(q1), quiet_median_s_threads=statistics.median(qk),
                   quiet_speedup=paired_ratio(q1, qk), quiet_speedup_rounds=ratio_range(q1, qk))
    return res


def run_end_to_end(rounds: int = 9, threads: int = 2) -> dict:
    """``pfbench bench --end-to-end``: :func:`end_to_end` as a provenance record (kind
    ``bench_end_to_end``) with its target checked."""
    from ..provenance import provenance
    from .report import check

    res = end_to_end(rounds=rounds, threads=threads)
    label = (f"whole run_filter calls, N_p = {_pow10(res['particles'])}, M = {res['steps']}: "
             f"{res['threads']} threads vs 1 (speed-up)")
    return provenance(kind="bench_end_to_end", **res, targets=[check("end_to_end_speedup", res["speedup"], label)])


def end_to_end_text(res: dict) -> str:
    """The lines for :func:`end_to_end`'s result."""
    k = res["threads"]
    lo, hi = res["speedup_rounds"]
    out = [f"end to end, Ob1 numba float64, N_p = {_pow10(res['particles'])}, M = {res['steps']}, "
           f"{res['rounds']} rounds: 1 thread {res['median_s_1_thread'] * 1e3:.1f} ms, {k} threads "
           f"{res['median_s_threads'] * 1e3:.1f} ms (medians); speed-up {res['speedup']:.2f}x (median of "
           f"per-round ratios, rounds {lo:.2f}-{hi:.2f}x)"]
    if res.get("kernel_speedup") is not None:
        klo, khi = res["kernel_speedup_rounds"]
        out.append(f"  in the kernel (elapsed_s): speed-up {res['kernel_speedup']:.2f}x (rounds {klo:.2f}-{khi:.2f}x); "
                   f"outside it: 1 thread {res['median_outside_s_1_thread'] * 1e3:.1f} ms, {k} threads "
                   f"{res['median_outside_s_threads'] * 1e3:.1f} ms (medians)")
    if res.get("quiet_rounds"):
        lo, hi = res["quiet_speedup_rounds"]
        out.append(f"  {res['quiet_rounds']} quiet rounds (other processes < 5 % CPU): 1 thread "
                   f"{res['quiet_median_s_1_thread'] * 1e3:.1f} ms, {k} threads "
                   f"{res['quiet_median_s_threads'] * 1e3:.1f} ms; speed-up {res['quiet_speedup']:.2f}x "
                   f"(rounds {lo:.2f}-{hi:.2f}x)")
    else:
        out.append("  no quiet round: other processes used the cores throughout")
    from .report import fmt

    out.extend(fmt(t) for t in res.get("targets", ()))
    return "\n".join(out)
