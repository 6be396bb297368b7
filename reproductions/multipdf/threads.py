"""multipdf Figs. 12-13: computation time vs threads, PF vs MultiPDF on Ob1 ([MultiPDF] §6)."""
from __future__ import annotations

import os
import platform

import numpy as np
import pandas as pd

import pfbench
from pfbench.models import get
from pfbench.recipes import recipe

THREADS = (1, 2, 3, 5, 7, 10)


def _trimmed(times):
    t = sorted(times)
    return float(np.mean(t[1:-1])) if len(t) > 2 else float(np.mean(t))


def _timing(ctx, n_p: int, name: str):
    reps = ctx.option("repeats", 12 if ctx.full else 5, int)
    M = ctx.option("steps", 2000, int)
    model = get("ob1")
    tr = model.simulate(M, seed=ctx.seed)
    pfbench.run_filter(model, tr.y[:5], method="bootstrap", n_particles=10, backend=ctx.backend)
    rows = []
    pf = [pfbench.run_filter(model, tr.y, method="bootstrap", n_particles=n_p, backend=ctx.backend,
                             seed=i).elapsed_s for i in range(reps)]
    rows.append({"algorithm": "PF", "threads": 1, "time_ms": 1e3 * _trimmed(pf)})
    for T in THREADS:
        ts = [pfbench.run_filter(model, tr.y, method="multipdf", n_particles=n_p, n_filters=T,
                                 n_threads=T, backend=ctx.backend, seed=i).elapsed_s
              for i in range(reps)]
        rows.append({"algorithm": f"MultiPDF ({T}T)", "threads": T, "time_ms": 1e3 * _trimmed(ts)})
    df = pd.DataFrame(rows)
    ctx.write_table(name, df)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    ax.bar(df["algorithm"], df["time_ms"], color=["gray"] + ["C0"] * len(THREADS))
    ax.set_ylabel("time per run [ms]")
    ncores = len(os.sched_getaffinity(0))
    ax.set_title(f"Ob1, N_p = {n_p}, M = {M}: this host ({ncores} cores, {platform.machine()})")
    ax.tick_params(axis="x", rotation=30)
    ctx.write_figure(name, fig)
    base = df.loc[0, "time_ms"]
    best = df.iloc[1:]["time_ms"].min()
    bestT = int(df.iloc[1:].loc[df.iloc[1:]["time_ms"].idxmin(), "threads"])
    ctx.compare(f"{name}: speed-up PF / best MultiPDF", ours=float(base / best),
                paper="up to 7x (16-thread platform A), up to 2.5x (4-thread platforms)",
                note=f"best at {bestT} threads")
    ctx.compare(f"{name}: host cores", ours=ncores, paper="A: 16 threads; B, C, D: 4")
    by_t = df.iloc[1:].set_index("threads")["time_ms"]
    tc = max(t for t in THREADS if t <= max(ncores, 1))
    ctx.compare(f"{name}: time(MultiPDF 10T) / time(MultiPDF {tc}T)", ours=float(by_t[10] / by_t[tc]),
                paper=">= 1 beyond the core count (oversubscription, context switching)")
    ctx.note(f"{name}: numba kernels (not C#), M = {M} steps, {reps} repeats with best and worst "
             "dropped (paper: 12); the host is shared with other jobs, so times are noisy.")


@recipe("multipdf:fig12", title="Time vs threads, N_p = 1200 (Fig. 12)", quick_cost="~10 s",
        full_cost="~30 s", options={"repeats": (int, "timed repetitions (quick 5, full 12)"),
                                    "steps": (int, "time steps M (default 2000)")})
def fig12(ctx):
    _timing(ctx, 1200, "fig12")


@recipe("multipdf:fig13", title="Time vs threads, N_p = 1500 (Fig. 13)", quick_cost="~10 s",
        full_cost="~30 s", options={"repeats": (int, "timed repetitions (quick 5, full 12)"),
                                    "steps": (int, "time steps M (default 2000)")})
def fig13(ctx):
    _timing(ctx, 1500, "fig13")
