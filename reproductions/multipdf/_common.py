"""Shared helpers of the multipdf recipes: run a sweep into a resumable store and summarise."""
from __future__ import annotations

import time

import numpy as np

from pfbench.sweep import make_spec, run_sweep, summarize_frame
from pfbench.procs import usable_cores
from pfbench.ranges import COUNT
from pfbench.errors import PfbenchError
from pfbench.sweep.store import Store, journal_path, spec_hash
from pfbench.verdicts import NOT_REPRODUCIBLE, Outcome, Reading, same_for_every

#: Where each (sub-)filter takes its point estimate. [MultiPDF] Alg. 1 step 6 and Alg. 2 step 2e
#: compute it AFTER the resampling step ("post": the plain mean of the resampled particles);
#: pfbench's default is the weighted mean before resampling ("pre"); the two differ by the
#: resampling noise only (same expectation). The recipes follow the paper ("post", ``run_filter``'s
#: ``estimate`` option).
ESTIMATE = "post"


def filter_kw(run_filter=None) -> dict:
    """Keyword arguments for ``pfbench.run_filter`` that select :data:`ESTIMATE`."""
    return {"estimate": ESTIMATE}


#: the --option keys that :func:`sweep` and its helpers read (declare them on every recipe using it)
OPTIONS = {"runs": (int, "Monte Carlo runs per configuration (see the recipe's quick/full counts)", COUNT),
           "workers": (int, "worker processes of the sweep (default: all cores)", COUNT)}


def workers(ctx) -> int:
    return ctx.option("workers", usable_cores(), int)


def sweep_spec(ctx, name: str, model: str, *, params=None, particles, filters, runs_quick: int,
               runs_full: int, steps: int = 100, extra_configs=()):
    """(spec, store path) of the sweep :func:`sweep` runs."""
    runs = ctx.option("runs", runs_full if ctx.full else runs_quick, int)
    configs = [("multipdf", p, f) for p in particles for f in filters if f <= p]
    configs += list(extra_configs)
    spec = make_spec(model, params=params or {}, configs=configs, runs=runs, steps=steps,
                     seed=ctx.seed, backend=ctx.backend, estimate=ESTIMATE)
    out = ctx.out_dir / "sweeps" / f"{name}-{'full' if ctx.full else 'quick'}.jsonl"
    return spec, out


def reuse_or_sweep(ctx, name: str, model: str, **kw):
    """Per-run frame (:func:`per_run`) of the sweep that recipe ``name`` runs, for a sentence of the
    paper that spans several figures and is scored by this recipe only.

    The sweeps are deterministic (the spec holds seed, runs, grid and a fingerprint of the code), so
    when recipe ``name``'s store in --out has exactly this spec and is complete it is read as it is
    (and not listed as an output of this recipe); otherwise this recipe runs the same spec into its
    own store ``<this recipe>_<name>`` (same numbers, more time).
    """
    spec, out = sweep_spec(ctx, name, model, **kw)
    try:
        if journal_path(out).exists():
            st = Store.read(out)
            if spec_hash(st.spec) == spec_hash(spec) and st.complete:
                ctx.extra.setdefault("sweeps_read", []).append(out.name)
                return per_run(st)
    except PfbenchError:
        pass
    _s, _spec, _w, st = sweep(ctx, f"{ctx.recipe.name}_{name}", model, **kw)
    return per_run(st)


def sweep(ctx, name: str, model: str, *, params=None, particles, filters, runs_quick: int,
          runs_full: int, steps: int = 100, extra_configs=()):
    """Run the (resumable) sweep of a recipe; returns (summary frame, spec, wall seconds).

    The store is results/multipdf/sweeps/<name>-<quick|full>.jsonl: an interrupted recipe
    resumes; a store written by other code or another grid is replaced.
    """
    spec, out = sweep_spec(ctx, name, model, params=params, particles=particles, filters=filters,
                           runs_quick=runs_quick, runs_full=runs_full, steps=steps,
                           extra_configs=extra_configs)
    runs = spec["runs"]
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
    dropped = int(summ["dropped"].sum())
    if dropped:
        ctx.note(f"{name}: {dropped} run(s) with a NaN or infinite aRMSE are left out of the means "
                 "and intervals (column dropped of the summary).")
    ctx.outputs.append(str(out))
    ctx.extra.setdefault("sweeps", {})[name] = {
        "tasks": rep.total, "new_tasks": rep.done_now, "wall_s": round(wall, 2),
        "tasks_per_s": round(rep.tasks_per_s, 2) if rep.done_now else None,
        "worker_seconds": round(float(sum(c["wall_s"] for c in st.chunks)), 2), "runs": runs,
        "dropped": dropped}
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


#: the band the figures draw and what it is ([MultiPDF] §5: "standard deviations with 95 %
#: probability in both directions from the mean", sigma / sqrt(m) of m runs)
BAND_TEXT = "shaded (each line's colour): 95 % interval of the mean over {runs} runs, mean ± 2 s/√runs ([MultiPDF] §5)"
_MARK = {"mpf": "s", "bootstrap": "^"}


def plot(ctx, name, summ, title, yunit="state units"):
    """aRMSE vs N_p, one line per N_f (N_f = 1 is the bootstrap filter) and one per other method,
    each with its band (:data:`BAND_TEXT`), in the shared style (:mod:`pfbench.plotting`). The
    paper's figure values were lost in the extraction, so no paper curve can be drawn beside ours."""
    from pfbench import plotting

    fig, ax = plotting.subplots(figsize=(6.4, 4.2))
    runs = int(summ["runs"].max())
    first = True
    for (m, n_f), g in sorted(summ.groupby(["method", "n_filters"]), key=lambda t: (t[0][0] != "multipdf", t[0])):
        g = g.sort_values("n_particles")
        x = g["n_particles"].to_numpy()
        lab = f"MultiPDF, N_f = {n_f}" + (" (bootstrap PF)" if n_f == 1 else "") if m == "multipdf" \
            else {"mpf": "marginalized PF (MPF)"}.get(m, m)
        line, = ax.plot(x, g["armse_mean"], marker=_MARK.get(m, "o"), ms=3, label=lab,
                        ls="--" if m != "multipdf" else "-")
        lo, hi = g["armse_lo"].to_numpy(), g["armse_hi"].to_numpy()
        if np.isfinite(lo).all():
            plotting.band(ax, x, lo, hi, BAND_TEXT.format(runs=runs) if first else "_nolegend_",
                          color=line.get_color())
            first = False
    ax.set_xscale("log")
    plotting.label(ax, "N_p, total number of particles [-]", f"aRMSE, eq. 11 [{yunit}]", title)
    ax.legend(fontsize=7)
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


__all__ = ["OPTIONS", "ESTIMATE", "sweep", "claims", "plot", "nf_table", "full_time_estimate", "significance", "np"]


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


# ----- sentences about many cases, and the lost Ob5 noise levels -----------------------------------

def interval_text(o) -> str:
    """An outcome's verdict with its 95 % interval, for a comparison row's note."""
    iv = "no interval" if o.interval is None else f"95 % interval [{o.interval[0]:.3g}, {o.interval[1]:.3g}]"
    return f"{o.verdict}, {iv}"


def over_noise_levels(by_level):
    """Ob5's noise levels were lost ([MultiPDF] Table 3): ``by_level`` is [(factor, Outcome)] for
    the swept measurement-noise factors, the first one our primary reading. Returns (outcome,
    reading, others) for :meth:`~pfbench.recipes.RecipeContext.claim`: the first level's outcome
    when every level gives the same verdict (the guess does not decide it; said in ``reading``),
    else not reproducible with every level as a sensitivity row."""
    (s0, o0), rest = by_level[0], by_level[1:]
    others = [Reading(f"measurement noise std x {s:g}", f"noise x {s:g}", o) for s, o in rest]
    levels = ", ".join(f"x {s:g}" for s, _ in by_level)
    if same_for_every(o0, others, "Ob5 noise level") is o0:
        reading = (f"measurement noise std x {s0:g} (our value; [MultiPDF] Table 3 lost) - primary "
                   f"because every swept level ({levels}) gives the same verdict, so the guessed "
                   "noise level does not decide it")
        return o0, reading, others
    verdicts = ", ".join(f"x {s:g}: {o.verdict}" for s, o in by_level)
    out = Outcome(NOT_REPRODUCIBLE, "decided by Ob5's noise level, which [MultiPDF] Table 3 gave and the "
                  f"extraction lost: the verdict changes with the swept level ({verdicts})")
    reading = "the paper's noise level (lost) - primary because it is the sentence's own setting"
    return out, reading, [Reading(f"measurement noise std x {s0:g}", f"noise x {s0:g}", o0)] + others
