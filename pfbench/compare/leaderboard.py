"""The leaderboard of a comparison: ``leaderboard.md``, ``compare.json`` and one accuracy-vs-time
plot per task (``<task>.png``), all written atomically (:mod:`pfbench.io`).

Ranking: on a task with true states by mean aRMSE (lower first); on real data, where no state is
known, by the mean log-likelihood estimate (higher first). A particle filter's likelihood estimate
is unbiased, so its log falls short of the true log-likelihood by about half its variance (Jensen):
of two such filters the one with the higher mean is the one nearer the truth, and its smaller
spread (the quantity a PMMH user tunes N_p by) shows beside it. The spread alone is no ranking: a
filter that returns one wrong value every run has none. A contender without a log-likelihood, or
that failed a run, is not ranked (``–``; the failures are listed under the table with their reasons).
"""
from __future__ import annotations

from pathlib import Path


def _f(v, fmt=".4g"):
    return "—" if v is None else format(v, fmt)


def _ci(v, fmt=".3g"):
    return "" if not v else f" [{format(v[0], fmt)}, {format(v[1], fmt)}]"


def accuracy_key(task: dict) -> tuple[str, str, int]:
    """(metric, label, sign) that ranks a task's contenders: the smaller ``sign * metric`` first."""
    if task["data"] == "real":
        return "loglik", "mean log-likelihood (higher first)", -1
    return "armse", "aRMSE", 1


def ranked(task: dict, name: str) -> bool:
    """Whether a contender has a rank: it completed every run and has the ranking metric."""
    s = task["contenders"][name]
    return s["complete"] and s.get(accuracy_key(task)[0]) is not None


def _rank(task: dict) -> list[str]:
    key, _, sign = accuracy_key(task)

    def order(item):
        name, s = item
        return (not ranked(task, name), sign * s[key] if ranked(task, name) else 0.0, name)

    return [n for n, _ in sorted(task["contenders"].items(), key=order)]


def _delta(task: dict, name: str, key: str) -> str:
    """The paired difference of ``key`` against the baseline, as a cell."""
    d = (task["contenders"][name].get("vs_baseline") or {}).get(key)
    if name == task["baseline"]:
        return "baseline"
    return "—" if d is None else f"{d['mean']:+.3g}{_ci(d['ci'])} {d['verdict']} (n = {d['n']})"


def markdown(summary: dict) -> str:
    lines = ["# Leaderboard", "",
             f"{summary['runs']} runs per task and contender, N_p = {summary['n_particles']}; "
             f"baseline `{summary['baseline']}`. Intervals: 95 % t-intervals over runs (held at 0 for "
             "quantities that cannot be negative); Δ: paired difference against the baseline on the n runs "
             "both completed (a lower aRMSE and a higher log-likelihood are better). Log-lik sd: over "
             "runs; on simulated data each run is another dataset, so it holds the data's own spread "
             "too, on real data it is the estimator's alone. Time: the filter's own "
             "time per particle and step (median; per step for filters without particles). Log-lik bias: "
             "mean of log L̂ - log L against the exact value, about -var/2 for an unbiased L̂; "
             "L̂/L: its mean, 1 for an unbiased filter.", ""]
    for tname, t in summary["tasks"].items():
        key, label, _ = accuracy_key(t)
        exact = t["reference"] == "exact-loglik"
        lines += [f"## {tname}", "",
                  f"model `{t['model']}`, {t['steps']} steps, {t['data']} data"
                  + (", exact log-likelihood from the Kalman filter" if exact else "")
                  + f"; ranked by {label}.", ""]
        head = ["#", "contender"]
        if t["data"] != "real":
            head += ["aRMSE [95 %]", "Δ aRMSE vs baseline [95 %]", "cov. 90 %"]
        head += ["log-lik mean", "log-lik sd"]
        if t["data"] == "real":
            head += ["Δ log-lik vs baseline [95 %]"]
        if exact:
            head += ["log-lik bias [95 %]", "L̂/L [95 %]"]
        head += ["ns / particle-step", "runs ok / failed"]
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for i, name in enumerate(_rank(t), 1):
            s = t["contenders"][name]
            row = [str(i) if ranked(t, name) else "–", f"`{name}`"]
            if t["data"] != "real":
                cov = s.get("coverage90")
                row += [_f(s["armse"]) + _ci(s["armse_ci"]), _delta(t, name, "armse"),
                        "—" if cov is None else f"{100 * cov:.0f} %"]
            row += [_f(s["loglik"], ".6g"), _f(s["loglik_sd"], ".3g")]
            if t["data"] == "real":
                row += [_delta(t, name, "loglik")]
            if exact:
                row += [_f(s.get("loglik_bias"), ".3g") + _ci(s.get("loglik_bias_ci")),
                        _f(s.get("lik_ratio"), ".3g") + _ci(s.get("lik_ratio_ci"))]
            row += [_f(s["ns_per_particle_step"], ".3g"),
                    "does not apply" if s.get("not_applicable") and not s["runs"] else f"{s['runs']} / {s['failed']}"]
            lines.append("| " + " | ".join(row) + " |")
        if not t["contenders"][t["baseline"]]["runs"]:
            lines += ["", f"The baseline `{t['baseline']}` completed no run: no paired differences."]
        fails = [(n, s) for n, s in t["contenders"].items() if s["failed"] or s["missing"]]
        na = [(n, s["not_applicable"]) for n, s in t["contenders"].items() if s.get("not_applicable")]
        if na or fails:
            lines.append("")
            lines += [f"- `{n}` does not apply to this task: {why}" for n, why in na]
            for n, s in fails:
                why = "; ".join(f"{k} ({v}x)" for k, v in s["failures"].items())
                miss = f" {s['missing']} runs not done." if s["missing"] else ""
                lines.append(f"- `{n}` failed {s['failed']} of {t['runs']} runs: {why}.{miss}")
        lines.append("")
    done = summary["complete_contenders"]
    lines.append("Contenders that completed every run of the tasks they apply to: "
                 + (", ".join(f"`{c}`" for c in done) or "none") + ".")
    return "\n".join(lines) + "\n"


def pareto(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points not dominated in (time, error), both lower-is-better, by time."""
    idx = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], float("inf")
    for i in idx:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def plot_task(tname: str, task: dict):
    """Accuracy (aRMSE, or the mean log-likelihood on real data, with its 95 % interval) vs the
    filter's own time per run, with the Pareto front."""
    from ..plotting import OURS, PAPER, label, subplots

    key, ylabel, sign = accuracy_key(task)
    fig, ax = subplots(figsize=(5.2, 3.6))
    pts, names = [], []
    for name, s in task["contenders"].items():
        if s.get(key) is None or not s.get("own_s"):
            continue
        x, y = s["own_s"], s[key]
        ci = s.get(f"{key}_ci")
        yerr = [[y - ci[0]], [ci[1] - y]] if ci else None
        ax.errorbar([x], [y], yerr=yerr, fmt="o", ms=5, capsize=3,
                    color=OURS if s["complete"] else "grey")
        ax.annotate(name, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
        pts.append((x, y))
        names.append(name)
    if pts:
        front = pareto([(x, sign * y) for x, y in pts])
        ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "--", color=PAPER, lw=1,
                label="Pareto front")
        ax.legend(loc="best")
        ax.set_xscale("log")
    label(ax, "filter time per run [s] (median, log scale)", ylabel,
          f"{tname}: accuracy vs time (N_p = {task['n_particles']}, {task['runs']} runs)")
    return fig


def write(summary: dict, out_dir, plots: bool = True) -> list[Path]:
    """Write leaderboard.md, compare.json and <task>.png into ``out_dir``; returns the paths. The plots
    of tasks the comparison there had before (``--overwrite`` with other tasks) are removed, so no
    picture outlives the leaderboard it belonged to."""
    import json

    from .. import io

    out = Path(out_dir)
    try:
        before = set(json.loads((out / "compare.json").read_text()).get("tasks", {}))
    except (OSError, ValueError, AttributeError):
        before = set()
    for old in before - set(summary["tasks"]):
        (out / f"{old}.png").unlink(missing_ok=True)
    paths = [io.write_text(out / "leaderboard.md", markdown(summary)),
             io.write_json(out / "compare.json", summary)]
    if plots:
        for tname, task in summary["tasks"].items():
            paths.append(io.write_figure(out / f"{tname}.png", plot_task(tname, task)))
    return paths
