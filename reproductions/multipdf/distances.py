"""multipdf Tables 6-7: distances d(k) (eq. 14) on Ob4, N_p = 300, N_f = 3, M = 100000."""
from __future__ import annotations

import numpy as np
import pandas as pd

import pfbench
from pfbench.metrics import distance
from pfbench.models import get
from pfbench.ranges import COUNT
from pfbench.recipes import recipe
from pfbench.verdicts import CONSTRUCTION, Reading, all_cases, close_to, direction, holds

from ._common import ESTIMATE, filter_kw, interval_text

#: the band of the 85.46 % claim: the paper prints one run of M = 100000 steps, whose own sampling
#: error is 0.1-0.2 point (our batch-means standard errors at M = 20000, 0.13-0.35 point for
#: shares of 3-56 %, scaled to M = 100000); 2 % relative (1.7 points) is several times that, so the
#: paper's Monte Carlo noise is not counted against it
PCT_WHY = ("2 % relative (1.7 points): several times the sampling error of the paper's single run of "
           "M = 100000 steps (0.1-0.2 point); our se from batch means of 1000 steps")

#: batch length for the claims: d(k) is autocorrelated along k, so per-step samples are not
#: independent; means over batches of BATCH steps are (nearly), and the t-interval uses those.
BATCH = 1000
OPTIONS = {"steps": (int, "time steps M (quick 20000, full 100000)", COUNT)}


def batch_means(x, batch=BATCH):
    """Means of consecutive batches of ``batch`` samples (a trailing partial batch is dropped)."""
    return batch_stat(x, np.mean, batch)


def batch_stat(x, stat, batch=BATCH):
    """``stat`` (e.g. np.mean, np.std) of consecutive batches of ``batch`` samples (a trailing
    partial batch is dropped)."""
    x = np.asarray(x, dtype=float)
    nb = x.size // batch
    return stat(x[: nb * batch].reshape(nb, batch), axis=1)


def _distances(ctx, shared=False):
    """d(k) (eq. 14) of the sub-filters, MultiPDF and BF on Ob4; ``shared``: the reading of Ob4 with
    one noise draw for both rows (the paper writes one symbol v, n; ours reads them independent)."""
    key = "d_shared" if shared else "d"
    if key in ctx.extra:
        return ctx.extra[key]
    M = ctx.option("steps", 100000 if ctx.full else 20000, int)
    model = get("ob4", shared_noise=True) if shared else get("ob4")
    tr = model.simulate(M, seed=np.random.default_rng(np.random.SeedSequence(ctx.seed, spawn_key=(7,))))
    kw = filter_kw(pfbench.run_filter)
    mp = pfbench.run_filter(model, tr.y, tr.u, method="multipdf", n_particles=300, n_filters=3,
                            backend=ctx.backend, seed=np.random.SeedSequence(ctx.seed, spawn_key=(8,)), **kw)
    bf = pfbench.run_filter(model, tr.y, tr.u, method="bootstrap", n_particles=300,
                            backend=ctx.backend, seed=np.random.SeedSequence(ctx.seed, spawn_key=(9,)), **kw)
    d = {f"PF[{l + 1}]": distance(mp.sub_estimates[l], tr.x) for l in range(3)}
    d["MultiPDF"] = distance(mp.estimates, tr.x)
    d["BF"] = distance(bf.estimates, tr.x)
    ctx.extra[key] = d
    ctx.extra["M"] = M
    return d


def _finish(ctx):
    ctx.extra.pop("d", None)
    ctx.extra.pop("d_shared", None)


@recipe("multipdf:table6", title="Distance statistics on Ob4 (Table 6)", quick_cost="~5 s",
        full_cost="~20 s", options=OPTIONS)
def table6(ctx):
    d = _distances(ctx)
    df = pd.DataFrame([{"filter": k, "mean_d": float(v.mean()), "std_d": float(v.std(ddof=1))}
                       for k, v in d.items()])
    ctx.write_table("table6", df)
    s = df.set_index("filter")
    comp_mean = float(s.loc[["PF[1]", "PF[2]", "PF[3]"], "mean_d"].mean())
    ctx.compare("table6: mean d, sub-filters (avg of PF[1..3])", ours=comp_mean)
    ctx.compare("table6: mean d, MultiPDF", ours=float(s.loc["MultiPDF", "mean_d"]))
    ctx.compare("table6: mean d, BF (N_p = 300)", ours=float(s.loc["BF", "mean_d"]))
    where = "[MultiPDF] §7, Table 6"
    subs = ("PF[1]", "PF[2]", "PF[3]")
    means = [(direction(batch_means(d[k]) - batch_means(d["MultiPDF"]), +1, "distance difference"),
              f"mean d_{k} - mean d_MultiPDF") for k in subs]
    stds = [(direction(batch_stat(d[k], np.std) - batch_stat(d["MultiPDF"], np.std), +1, "difference of stds"),
             f"std d_{k} - std d_MultiPDF") for k in subs]
    for o, q in means + stds:
        ctx.compare(f"table6: {q} (per batch of {BATCH} steps)", ours=o.ours,
                    note=interval_text(o))
    ctx.claim("As one can see in Table 6, the results from parallel filters provided higher mean values and "
              "standard deviations than from single ones, but statistics for estimate from MultiPDF PF are "
              "noticeably smaller", where,
              f"per sub-filter PF[1..3]: std of d_k minus std of d_MultiPDF, over batches of {BATCH} steps",
              all_cases([o for o, _ in stds], 1.0, "sub-filter standard deviation larger than MultiPDF's",
                        "each of the three sub-filters"),
              paper="> 0 for each",
              reading="the standard deviations, for each sub-filter - primary because the means follow from "
                      "the triangle inequality (a claim by construction, below); 'noticeably' names no size, "
                      "so only the direction is tested",
              others=[Reading("both statistics the sentence names", "mean and std of d_PF[k] minus those of "
                              "d_MultiPDF, k = 1..3",
                              all_cases([o for o, _ in means + stds], 1.0, "sub-filter statistic larger",
                                        "each of the three sub-filters, mean and standard deviation"))])
    sub_mean = float(np.mean([np.mean(d[k]) for k in subs]))
    ctx.claim("the mean distance of the MultiPDF estimate is below its sub-filters' (the mean part of the "
              "sentence above)", where, "mean d_MultiPDF vs the sub-filters' mean d (averaged over k = 1..3)",
              holds(float(np.mean(d["MultiPDF"])) <= sub_mean,
                    f"mean d_MultiPDF {np.mean(d['MultiPDF']):.4g} <= the sub-filters' {sub_mean:.4g}"),
              paper="smaller", kind=CONSTRUCTION,
              note="the MultiPDF estimate is the mean of its N_f exchangeable sub-filters' estimates, so by the "
                   "triangle inequality its distance is at most their mean distance at every step (and each "
                   "sub-filter's expected distance is the same): true whatever the data")
    ctx.claim("The bootstrap filter provided somewhat worse results", where,
              f"mean d_BF - d_MultiPDF (batch means of {BATCH} steps)",
              direction(batch_means(d["BF"] - d["MultiPDF"]), +1, "distance difference"), paper="> 0")
    ctx.note(f"table6: M = {ctx.extra['M']} steps (paper: 100000; quick mode uses 20000); Table 6's "
             "numbers were lost in the extraction, only its qualitative claims are compared. Point "
             f"estimate {ESTIMATE!r} resampling ([MultiPDF] Algs. 1-2: 'post').")
    _finish(ctx)


@recipe("multipdf:table7", title="Share of steps MultiPDF's d(k) is smaller (Table 7)",
        quick_cost="~5 s", full_cost="~20 s",
        options=OPTIONS)
def table7(ctx):
    d = _distances(ctx)
    mp = d["MultiPDF"]
    comp_min = np.minimum(np.minimum(d["PF[1]"], d["PF[2]"]), d["PF[3]"])
    rows = [{"event": f"d_MultiPDF < d_{k}", "percent": 100.0 * float(np.mean(mp < d[k]))}
            for k in ("PF[1]", "PF[2]", "PF[3]", "BF")]
    rows.append({"event": "d_MultiPDF < min(d_PF[1..3])", "percent": 100.0 * float(np.mean(mp < comp_min))})
    stack = np.vstack([d["PF[1]"], d["PF[2]"], d["PF[3]"]])
    rows.append({"event": "d_MultiPDF < median(d_PF[1..3])",
                 "percent": 100.0 * float(np.mean(mp < np.median(stack, axis=0)))})
    rows.append({"event": "d_MultiPDF < max(d_PF[1..3])",
                 "percent": 100.0 * float(np.mean(mp < stack.max(axis=0)))})
    df = pd.DataFrame(rows)
    ctx.write_table("table7", df)
    s = df.set_index("event")["percent"]
    ctx.compare("table7: % steps d_MultiPDF < min of its components",
                ours=float(s["d_MultiPDF < min(d_PF[1..3])"]), paper=85.46, unit="%",
                note="paper value from the text (§3); Table 7 itself was lost")
    ctx.compare("table7: % steps d_MultiPDF < d_BF", ours=float(s["d_MultiPDF < d_BF"]), unit="%")
    ctx.compare("table7: % steps d_MultiPDF < max of its components", ours=float(s["d_MultiPDF < max(d_PF[1..3])"]),
                unit="%")
    where = "[MultiPDF] §7, Table 7"

    def share_rule(event, label):
        ind = batch_means(100.0 * event)
        se = float(ind.std(ddof=1) / np.sqrt(ind.size)) if ind.size > 1 else 0.0
        ours = 100.0 * float(np.mean(event))
        return close_to(ours, 85.46, 0.02, se=se, why=PCT_WHY), f"% steps d_MultiPDF < {label}"

    o, q = share_rule(mp < comp_min, "min(d_PF[1..3])")
    o_med, q_med = share_rule(mp < np.median(stack, axis=0), "median(d_PF[1..3])")
    ds = _distances(ctx, shared=True)
    o_sh, q_sh = share_rule(ds["MultiPDF"] < np.minimum(np.minimum(ds["PF[1]"], ds["PF[2]"]), ds["PF[3]"]),
                            "min(d_PF[1..3]), Ob4 with one noise draw for both rows")
    o_pair, q_pair = share_rule(np.mean(np.vstack([mp < d[k] for k in ("PF[1]", "PF[2]", "PF[3]")]), axis=0),
                                "d_PF[k], averaged over k = 1..3")
    ctx.claim("for a two-dimensional system (with two state variables) in 85.46% of cases, the distance "
              "between the real and the estimated point (on the trajectory for MultiPDF PF) is lower than "
              "the minimum obtained by the independently operating components", "[MultiPDF] §3 (Table 7 lost)",
              q, o, paper=85.46,
              reading="lower than the smallest of the three sub-filters' distances - primary because it is "
                      "the sentence's literal 'lower than the minimum'",
              others=[Reading("lower than the median sub-filter distance", q_med, o_med),
                      Reading("lower than one sub-filter's distance (Table 7's per-filter events, averaged)",
                              q_pair, o_pair),
                      Reading("Ob4's v and n one draw shared by both rows (the paper writes one symbol)",
                              q_sh, o_sh)],
              note="our per-filter shares: " + ", ".join(
                  f"{k} {s['d_MultiPDF < d_' + k]:.1f} %" for k in ("PF[1]", "PF[2]", "PF[3]")))
    a = direction(batch_means(100.0 * (mp < d["BF"]) - 50.0), -1, "share minus 50 %")
    b = direction(batch_means(d["BF"] - mp), +1, "distance difference")
    ctx.claim("A comparison of distances for MultiPDF and BF slightly favors BF, but as one can see in "
              "Table 6, the mean distance for MultiPDF PF is generally smaller than for BF", where,
              f"(1) % steps d_MultiPDF < d_BF minus 50, (2) mean d_BF - d_MultiPDF (batch means of {BATCH} steps)",
              all_cases([a, b], 1.0, "(1) < 0 and (2) > 0", "both clauses of the sentence"),
              paper="(1) < 0, (2) > 0",
              reading="both clauses: BF closer in more than half of the steps, yet MultiPDF's mean distance "
                      "smaller - primary because the sentence states both",
              others=[Reading("the first clause only (BF closer in more than half of the steps)",
                              "% steps d_MultiPDF < d_BF minus 50", a)])
    share_max = float(s["d_MultiPDF < max(d_PF[1..3])"])
    ctx.claim("almost always the result from one of the parallel filters is farther from the true "
              "value than in the case of the MultiPDF PF result", where,
              "% steps d_MultiPDF < max(d_PF[1..3])",
              holds(share_max >= 95.0, f"share {share_max:.2f} % >= 95 % ('almost always')"),
              paper="almost always", kind=CONSTRUCTION,
              note="the MultiPDF estimate is the mean of the sub-filters' estimates, so by the triangle "
                   "inequality d_MultiPDF = |mean_l x_l - x| <= mean_l |x_l - x| <= max_l d_PF[l], with "
                   "equality only when every sub-filter estimate is the same point: true whatever the data")
    ctx.compare("table7: % steps d_MultiPDF < median of its components",
                ours=float(s["d_MultiPDF < median(d_PF[1..3])"]), unit="%")
    ours = float(s["d_MultiPDF < min(d_PF[1..3])"])
    ctx.note(f"table7: point estimate {ESTIMATE!r} resampling ([MultiPDF] Algs. 1-2: 'post').")
    ctx.note("table7: the mean of N_f estimates is closer than the *best* of them only when the "
             "sub-filter errors point in different directions; with 3 sub-filters of similar "
             f"quality we measure {ours:.1f} % (paper 85.46 %). Note the mean is always at most "
             "as far as the *worst* component (triangle inequality).")
    _finish(ctx)
