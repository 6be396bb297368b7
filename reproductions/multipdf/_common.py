"""Shared helpers of the multipdf recipes: run a sweep into a resumable store and summarise."""
from __future__ import annotations

import time

import numpy as np

from pfbench.sweep import make_spec, run_sweep, summarize_frame
from pfbench.sweep.runner import cores
from pfbench.errors import PfbenchError
from pfbench.sweep.store import Store, journal_path


#: the --option keys that :func:`sweep` and its helpers read (declare them on every recipe using it)
OPTIONS = {"runs": (int, "Monte Carlo runs per configuration (see the recipe's quick/full counts)"),
           "workers": (int, "worker processes of the sweep (default: all cores)")}


def workers(ctx) -> int:
    return ctx.option("workers", cores(), int)


def sweep(ctx, name: str, model: str, *, params=None, particles, filters, runs_quick: int,
          runs_full: int, steps: int = 100, extra_configs=()):
    """Run the (resumable) sweep of a recipe; returns (summary frame, spec, wall seconds).

    The store is results/multipdf/sweeps/<name>-<quick|full>.jsonl: an interrupted recipe
    resumes; a store written by other code or another grid is replaced.
    """
    runs = ctx.option("runs", runs_full if ctx.full else runs_quick, int)
    configs = [("multipdf", p, f) for p in particles for f in filters if f <= p]
    configs += list(extra_configs)
    spec = make_spec(model, params=params or {}, configs=configs, runs=runs, steps=steps,
                     seed=ctx.seed, backend=ctx.backend)
    out = ctx.out_dir / "sweeps" / f"{name}-{'full' if ctx.full else 'quick'}.jsonl"
    overwrite = False
    if journal_path(out).exists():
        try:
            st = Store.read(out)
            overwrite = st.spec != spec
        except PfbenchError:
            overwrite = True
    t0 = time.perf_counter()
    rep = run_sweep(spec, out, workers=workers(ctx), progress=not ctx.quiet, overwrite=overwrite)
    wall = time.perf_counter() - t0
    st = Store.read(out)
    frame = st.frame()
    summ = summarize_frame(frame, spec)
    ctx.outputs.append(str(out))
    ctx.extra.setdefault("sweeps", {})[name] = {
        "tasks": rep.total, "new_tasks": rep.done_now, "wall_s": round(wall, 2),
        "tasks_per_s": round(rep.tasks_per_s, 2) if rep.done_now else None,
        "worker_seconds": round(float(sum(c["wall_s"] for c in st.chunks)), 2), "runs": runs}
    return summ, spec, wall, st


def full_time_estimate(ctx, st, runs_full: int) -> float:
    """Seconds a --full run would take on this host (measured worker-seconds x scale / cores)."""
    ws = float(sum(c["wall_s"] for c in st.chunks))
    return ws * runs_full / max(1, st.spec["runs"]) / max(1, workers(ctx))


def nf_table(summ):
    """Pivot: rows N_p, columns N_f, values mean aRMSE (MultiPDF only)."""
    s = summ[summ["method"] == "multipdf"]
    return s.pivot(index="n_particles", columns="n_filters", values="armse_mean")


def claims(ctx, fig_name, summ, paper_claim: str):
    """Record which N_f is best (per N_p and on average) next to the paper's claim."""
    tab = nf_table(summ)
    best_per_np = tab.idxmin(axis=1)
    rel = tab.div(tab[1], axis=0)  # aRMSE relative to N_f = 1 (the bootstrap filter)
    mean_rel = rel.mean(axis=0)
    best_avg = int(mean_rel.idxmin())
    ctx.compare(f"{fig_name}: best N_f (mean aRMSE/aRMSE(N_f=1) over N_p)", ours=best_avg,
                paper=paper_claim,
                note="per N_p best: " + ", ".join(f"{int(n)}->{int(b)}" for n, b in best_per_np.items()))
    for nf, v in mean_rel.items():
        if nf != 1:
            ctx.compare(f"{fig_name}: aRMSE(N_f={nf}) / aRMSE(N_f=1), mean over N_p", ours=float(v))
    return tab, best_avg, mean_rel


def plot(ctx, name, summ, title):
    from pfbench.sweep import plot_summary

    fig = plot_summary(summ, title)
    ctx.write_figure(name, fig)


def significance(summ, nf_a, nf_b):
    """Fraction of N_p where N_f=nf_a is better than nf_b with non-overlapping 95 % bands."""
    s = summ[summ["method"] == "multipdf"].set_index(["n_particles", "n_filters"])
    nps = sorted({i[0] for i in s.index})
    hits = 0
    for n in nps:
        if (n, nf_a) in s.index and (n, nf_b) in s.index:
            hits += s.loc[(n, nf_a), "armse_hi"] < s.loc[(n, nf_b), "armse_lo"]
    return hits / max(1, len(nps))


__all__ = ["OPTIONS", "sweep", "claims", "plot", "nf_table", "full_time_estimate", "significance", "np"]
