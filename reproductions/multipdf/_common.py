"""Shared helpers of the multipdf recipes: run a sweep into a resumable store and summarise."""
from __future__ import annotations

import time

import numpy as np

from pfbench.sweep import make_spec, run_sweep, summarize_frame
from pfbench.procs import usable_cores
from pfbench.errors import PfbenchError
from pfbench.sweep.store import Store, journal_path


#: the --option keys that :func:`sweep` and its helpers read (declare them on every recipe using it)
OPTIONS = {"runs": (int, "Monte Carlo runs per configuration (see the recipe's quick/full counts)"),
           "workers": (int, "worker processes of the sweep (default: all cores)")}


def workers(ctx) -> int:
    return ctx.option("workers", usable_cores(), int)


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


def full_time_estimate(ctx, st, runs_full: int, steps_full: int | None = None) -> float:
    """Seconds a --full run would take on this host (measured worker-seconds x scale / cores);
    ``steps_full``: the --full horizon when it differs from the measured sweep's."""
    ws = float(sum(c["wall_s"] for c in st.chunks))
    scale = (steps_full / st.spec["steps"]) if steps_full else 1.0
    return ws * scale * runs_full / max(1, st.spec["runs"]) / max(1, workers(ctx))


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


# ----- per-run data and the claims' rules ------------------------------------------------------
# Every run r of a sweep shares its ground truth across all configurations (the sweep seeds the
# truth by run), so aRMSE differences between configurations are paired per run.

def per_run(st):
    """Wide frame: index run, columns (method, n_particles, n_filters), values per-run aRMSE."""
    f = st.frame()
    return f.pivot_table(index="run", columns=["method", "n_particles", "n_filters"], values="armse")


def mean_over(wide, cols):
    """Per-run mean of the aRMSE over the configurations ``cols`` (a list of column keys)."""
    return wide[list(cols)].mean(axis=1)


def mpdf_cols(wide, nf=None, np_=None):
    """MultiPDF columns of ``wide`` with N_f == nf and/or N_p == np_ (None: any)."""
    return [c for c in wide.columns if c[0] == "multipdf" and (nf is None or c[2] == nf)
            and (np_ is None or c[1] == np_)]


def nf_vs_bf(wide, nfs):
    """Per-run [mean over N_p and N_f in nfs of aRMSE] - [mean over the same N_p of aRMSE(N_f=1)].

    Only N_p values at which every N_f in ``nfs`` exists enter (so both terms average the same N_p).
    """
    nps = sorted({c[1] for c in mpdf_cols(wide)})
    nps = [p for p in nps if all(("multipdf", p, f) in wide.columns for f in list(nfs) + [1])]
    a = mean_over(wide, [("multipdf", p, f) for p in nps for f in nfs])
    b = mean_over(wide, [("multipdf", p, 1) for p in nps])
    return (a - b).to_numpy(), nps


def best_set_rule(wide, in_set, all_nf):
    """Optimum-N_f claim: per-run difference aRMSE(best N_f outside the set) - aRMSE(best N_f in it).

    "Best" = lowest mean (over runs and the N_p where every N_f exists) aRMSE; a positive mean
    difference supports the paper's optimum. Returns (samples, best_in, best_out, argmin).
    """
    nps = sorted({c[1] for c in mpdf_cols(wide)})
    nps = [p for p in nps if all(("multipdf", p, f) in wide.columns for f in all_nf)]
    by_nf = {f: mean_over(wide, [("multipdf", p, f) for p in nps]) for f in all_nf}
    means = {f: float(v.mean()) for f, v in by_nf.items()}
    argmin = min(means, key=means.get)
    inside = [f for f in all_nf if f in in_set]
    outside = [f for f in all_nf if f not in in_set]
    b_in = min(inside, key=means.get)
    b_out = min(outside, key=means.get)
    return (by_nf[b_out] - by_nf[b_in]).to_numpy(), b_in, b_out, argmin
