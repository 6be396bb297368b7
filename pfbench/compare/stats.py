"""Metrics per (task, contender) and paired differences against a baseline contender.

Intervals are 95 % t-intervals of a mean over runs (:func:`pfbench.verdicts.t_interval`, the
rule of the scorecard). A paired difference (contender - baseline) uses only the runs on which
both completed; its verdict is ``lower`` / ``higher`` when the whole interval lies below / above
zero and ``no difference at 95 %`` when it contains zero (the scorecard's :func:`direction` rule).
A difference within floating-point rounding of the values (:data:`ROUNDING`, relative) is zero: two
builds of one filter differ in the last bits, and a zero-width interval of such differences read
as a significant "lower"; when every paired difference is zero the verdict is ``identical``.

Log-likelihood against an exact reference: ``loglik_bias`` is the mean of log L_hat - log L and
``loglik_variance`` its variance over runs. A particle filter's likelihood estimate L_hat is
unbiased, so its log has a bias of about -var/2 (Jensen) that vanishes as N_p grows; the check of
unbiasedness is ``lik_ratio``, the mean of L_hat / L with its 95 % interval, which must contain 1.
"""
from __future__ import annotations

from collections import Counter

import numpy as np

from ..verdicts import t_interval

LOWER, HIGHER, SAME, IDENTICAL = "lower", "higher", "no difference at 95 %", "identical within rounding"
#: relative size of a difference taken for rounding (float64 results of one algorithm on two backends
#: or builds agree to about 1e-15 relative; 1e-9 leaves room for summation orders over long runs)
ROUNDING = 1e-9


def _vals(recs, key):
    return np.array([np.nan if r.get(key) is None else float(r[key]) for r in recs], dtype=float)


def _mean(x):
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else None


def _ci(x, nonnegative: bool = False):
    """The 95 % t-interval of the mean of ``x``; for a quantity that cannot be negative (an aRMSE, a
    likelihood ratio) the lower end is held at 0, since no mean of it lies below."""
    ti = t_interval(x)
    if ti is None:
        return None
    return [max(ti[1], 0.0) if nonnegative else ti[1], ti[2]]


def paired(a: dict, b: dict, key: str) -> dict | None:
    """The paired difference of ``key`` between runs ``a`` and ``b`` ({run: record}), or None."""
    runs = sorted(set(a) & set(b))
    pairs = np.array([(float(a[r][key]), float(b[r][key])) for r in runs
                      if a[r].get(key) is not None and b[r].get(key) is not None], dtype=float).reshape(-1, 2)
    pairs = pairs[np.all(np.isfinite(pairs), axis=1)]
    d = pairs[:, 0] - pairs[:, 1]
    d[np.abs(d) <= ROUNDING * np.abs(pairs).max(axis=1, initial=0.0)] = 0.0
    ti = t_interval(d)
    if ti is None:
        return None
    mean, lo, hi, n = ti
    verdict = IDENTICAL if not d.any() else LOWER if hi < 0 else HIGHER if lo > 0 else SAME
    return {"mean": mean, "ci": [lo, hi], "n": n, "verdict": verdict}


def contender_stats(recs: list[dict], runs: int) -> dict:
    """Every metric of one contender on one task from its records."""
    ok = [r for r in recs if r.get("ok")]
    na = [r for r in recs if r.get("not_applicable")]
    bad = [r for r in recs if not r.get("ok") and not r.get("not_applicable")]
    out = {"runs": len(ok), "failed": len(bad), "missing": max(0, runs - len(recs)),
           "complete": len(ok) == runs, "not_applicable": na[0]["reason"] if na else None,
           "failures": dict(Counter(r.get("reason") or "unknown" for r in bad))}
    armse = _vals(ok, "armse")
    out["armse"] = _mean(armse)
    out["armse_ci"] = _ci(armse, nonnegative=True)
    rm = [r["rmse"] for r in ok if r.get("rmse")]
    out["rmse"] = np.mean(np.array(rm, dtype=float), axis=0).tolist() if rm else None
    ll = _vals(ok, "loglik")
    out["loglik"] = _mean(ll)
    out["loglik_ci"] = _ci(ll)
    fin = ll[np.isfinite(ll)]
    out["loglik_sd"] = float(fin.std(ddof=1)) if fin.size > 1 else None
    if any("loglik_error" in r for r in ok):
        err = _vals(ok, "loglik_error")
        out["loglik_bias"] = _mean(err)
        out["loglik_bias_ci"] = _ci(err)
        fe = err[np.isfinite(err)]
        out["loglik_variance"] = float(fe.var(ddof=1)) if fe.size > 1 else None
        ratio = np.exp(np.clip(err, -700.0, 700.0))   # L_hat / L: an unbiased PF has mean 1
        out["lik_ratio"] = _mean(ratio)
        out["lik_ratio_ci"] = _ci(ratio, nonnegative=True)
        out["armse_vs_exact"] = _mean(_vals(ok, "armse_vs_exact"))
    out["coverage90"] = _mean(_vals(ok, "coverage90"))
    for k in ("ns_per_particle_step", "own_s", "wall_s", "startup_s", "overhead_s"):
        v = _vals(ok, k)
        v = v[np.isfinite(v)]
        out[k] = float(np.median(v)) if v.size else None
    out["overhead"] = (out["overhead_s"] / out["own_s"]) if out["overhead_s"] is not None and out["own_s"] else None
    return out


def summarize(spec: dict, records: list[dict]) -> dict:
    """The structure ``pfbench compare --json`` prints (see :func:`pfbench.compare.leaderboard`)."""
    base = spec["baseline"]
    by: dict = {}
    for r in records:
        by.setdefault(r["task"], {}).setdefault(r["contender"], {})[r["run"]] = r
    tasks = {}
    specs = {c["name"]: c["spec"] for c in spec["contenders"]}
    for t in spec["tasks"]:
        name = t["name"]
        runs_of = by.get(name, {})
        conts = {}
        for c in spec["contenders"]:
            recs = list(runs_of.get(c["name"], {}).values())
            st = {"spec": c["spec"], **contender_stats(recs, spec["runs"])}
            if c["name"] != base:
                ok = {k: v for k, v in runs_of.get(c["name"], {}).items() if v.get("ok")}
                bok = {k: v for k, v in runs_of.get(base, {}).items() if v.get("ok")}
                st["vs_baseline"] = {k: paired(ok, bok, k) for k in ("armse", "loglik")}
            conts[c["name"]] = st
        tasks[name] = {"model": t["model"], "data": t["data"], "reference": t["reference"],
                       "steps": t["steps"], "runs": spec["runs"], "n_particles": spec["n_particles"],
                       "baseline": base, "contenders": conts}
    def done(name, t):
        s = tasks[t]["contenders"][name]
        return s["complete"] or (s["not_applicable"] is not None and not s["failed"])

    complete = [c["name"] for c in spec["contenders"]   # every task it applies to, and one at least
                if all(done(c["name"], t) for t in tasks) and any(tasks[t]["contenders"][c["name"]]["complete"]
                                                               for t in tasks)]
    return {"tasks": tasks, "contenders": specs, "baseline": base, "runs": spec["runs"],
            "n_particles": spec["n_particles"], "complete_contenders": complete}
