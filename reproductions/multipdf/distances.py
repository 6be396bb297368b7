"""multipdf Tables 6-7: distances d(k) (eq. 14) on Ob4, N_p = 300, N_f = 3, M = 100000."""
from __future__ import annotations

import numpy as np
import pandas as pd

import pfbench
from pfbench.metrics import distance
from pfbench.models import get
from pfbench.recipes import recipe
from pfbench.verdicts import close_to, direction, holds

#: batch length for the claims: d(k) is autocorrelated along k, so per-step samples are not
#: independent; means over batches of BATCH steps are (nearly), and the t-interval uses those.
BATCH = 1000


def batch_means(x, batch=BATCH):
    """Means of consecutive batches of ``batch`` samples (a trailing partial batch is dropped)."""
    x = np.asarray(x, dtype=float)
    nb = x.size // batch
    return x[: nb * batch].reshape(nb, batch).mean(axis=1)


def _distances(ctx):
    if "d" in ctx.extra:
        return ctx.extra["d"]
    M = ctx.option("steps", 100000 if ctx.full else 20000, int)
    model = get("ob4")
    tr = model.simulate(M, seed=np.random.default_rng(np.random.SeedSequence(ctx.seed, spawn_key=(7,))))
    mp = pfbench.run_filter(model, tr.y, tr.u, method="multipdf", n_particles=300, n_filters=3,
                            backend=ctx.backend, seed=np.random.SeedSequence(ctx.seed, spawn_key=(8,)))
    bf = pfbench.run_filter(model, tr.y, tr.u, method="bootstrap", n_particles=300,
                            backend=ctx.backend, seed=np.random.SeedSequence(ctx.seed, spawn_key=(9,)))
    d = {f"PF[{l + 1}]": distance(mp.sub_estimates[l], tr.x) for l in range(3)}
    d["MultiPDF"] = distance(mp.estimates, tr.x)
    d["BF"] = distance(bf.estimates, tr.x)
    ctx.extra["d"] = d
    ctx.extra["M"] = M
    return d


def _finish(ctx):
    ctx.extra.pop("d", None)


@recipe("multipdf:table6", title="Distance statistics on Ob4 (Table 6)", quick_cost="~5 s",
        full_cost="~20 s", options={"steps": (int, "time steps M (quick 20000, full 100000)")})
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
    for k in ("PF[1]", "PF[2]", "PF[3]"):
        ctx.claim("the results from parallel filters provided higher mean values ... statistics for "
                  "estimate from MultiPDF PF are noticeably smaller", where,
                  f"mean d_{k} - d_MultiPDF (batch means of {BATCH} steps)",
                  direction(batch_means(d[k] - d["MultiPDF"]), +1, "distance difference"), paper="> 0")
    ctx.claim("The bootstrap filter provided somewhat worse results", where,
              f"mean d_BF - d_MultiPDF (batch means of {BATCH} steps)",
              direction(batch_means(d["BF"] - d["MultiPDF"]), +1, "distance difference"), paper="> 0")
    ctx.note(f"table6: M = {ctx.extra['M']} steps (paper: 100000; quick mode uses 20000); Table 6's "
             "numbers were lost in the extraction, only its qualitative claims are compared.")
    _finish(ctx)


@recipe("multipdf:table7", title="Share of steps MultiPDF's d(k) is smaller (Table 7)",
        quick_cost="~5 s", full_cost="~20 s",
        options={"steps": (int, "time steps M (quick 20000, full 100000)")})
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
    ind = batch_means(100.0 * (mp < comp_min))
    se = float(ind.std(ddof=1) / np.sqrt(ind.size)) if ind.size > 1 else 0.0
    ctx.claim("in 85.46% of cases, the distance between the real and the estimated point (for "
              "MultiPDF PF) is lower than the minimum obtained by the independently operating "
              "components", "[MultiPDF] §3 (Table 7 lost)",
              "% steps d_MultiPDF < min(d_PF[1..3])",
              close_to(float(s["d_MultiPDF < min(d_PF[1..3])"]), 85.46, 0.02, se=se,
                       why=f"2 % relative (1.7 points) for our reading of Ob4's noises (independent "
                           f"per component, pfbench/models/ob4.py); se from batch means of {BATCH} steps"), paper=85.46)
    ctx.claim("A comparison of distances for MultiPDF and BF slightly favors BF", where,
              f"% steps d_MultiPDF < d_BF minus 50 (batch means of {BATCH} steps)",
              direction(batch_means(100.0 * (mp < d["BF"]) - 50.0), -1, "share minus 50 %"),
              paper="< 50 %")
    share_max = float(s["d_MultiPDF < max(d_PF[1..3])"])
    ctx.claim("almost always the result from one of the parallel filters is farther from the true "
              "value than in the case of the MultiPDF PF result", where,
              "% steps d_MultiPDF < max(d_PF[1..3])",
              holds(share_max >= 95.0, f"share {share_max:.2f} % >= 95 % ('almost always')"),
              paper="almost always")
    ctx.compare("table7: % steps d_MultiPDF < median of its components",
                ours=float(s["d_MultiPDF < median(d_PF[1..3])"]), unit="%")
    ours = float(s["d_MultiPDF < min(d_PF[1..3])"])
    ctx.note("table7: the mean of N_f estimates is closer than the *best* of them only when the "
             "sub-filter errors point in different directions; with 3 sub-filters of similar "
             f"quality we measure {ours:.1f} % (paper 85.46 %). Note the mean is always at most "
             "as far as the *worst* component (triangle inequality).")
    _finish(ctx)
