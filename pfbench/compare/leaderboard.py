"""The leaderboard of a comparison: ``leaderboard.md``, ``compare.json`` and one accuracy-vs-time
plot per task (``<task>.png``), all written atomically (:mod:`pfbench.io`).

Ranking: on a task with true states by mean aRMSE (lower first); on real data by the standard
deviation of the log-likelihood estimate over runs (lower first: the quantity a PMMH user tunes
N_p by). A contender that failed a run is ranked after every complete one and its failures are
listed under the table with their reasons.
"""
from __future__ import annotations

from pathlib import Path


def _f(v, fmt=".4g"):
    return "—" if v is None else format(v, fmt)


def _ci(v, fmt=".3g"):
    return "" if not v else f" [{format(v[0], fmt)}, {format(v[1], fmt)}]"


def accuracy_key(task: dict) -> tuple[str, str]:
    """(metric, label) that ranks a task's contenders."""
    if task["data"] == "real":
        return "loglik_sd", "sd of log-likelihood"
    return "armse", "aRMSE"


def _rank(task: dict) -> list[str]:
    key, _ = accuracy_key(task)

    def order(item):
        name, s = item
        v = s.get(key)
        return (not s["complete"], v is None, v if v is not None else 0.0, name)

    return [n for n, _ in sorted(task["contenders"].items(), key=order)]


def markdown(summary: dict) -> str:
    lines = ["# Leaderboard", "",
             f"{summary['runs']} runs per task and contender, N_p = {summary['n_particles']}; "
             f"baseline `{summary['baseline']}`. Intervals: 95 % t-intervals over runs; Δ: paired "
             "difference against the baseline on the runs both completed. Time: the filter's own "
             "time per particle and step (median; per step for filters without particles). Log-lik bias: "
             "mean of log L̂ - log L against the exact value, about -var/2 for an unbiased L̂; "
             "L̂/L: its mean, 1 for an unbiased filter.", ""]
    for tname, t in summary["tasks"].items():
        key, label = accuracy_key(t)
        exact = t["reference"] == "exact-loglik"
        lines += [f"## {tname}", "",
                  f"model `{t['model']}`, {t['steps']} steps, {t['data']} data"
                  + (", exact log-likelihood from the Kalman filter" if exact else "")
                  + f"; ranked by {label}.", ""]
        head = ["#", "contender"]
        if t["data"] != "real":
            head += ["aRMSE [95 %]", "Δ aRMSE vs baseline [95 %]", "cov. 90 %"]
        head += ["log-lik mean", "log-lik sd"]
        if exact:
            head += ["log-lik bias [95 %]", "L̂/L [95 %]"]
        head += ["ns / particle-step", "runs ok / failed"]
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for i, name in enumerate(_rank(t), 1):
            s = t["contenders"][name]
            row = [str(i) if s["complete"] else "–", f"`{name}`"]
            if t["data"] != "real":
                d = (s.get("vs_baseline") or {}).get("armse")
                dtxt = "baseline" if name == t["baseline"] else (
                    "—" if d is None else f"{d['mean']:+.3g}{_ci(d['ci'])} {d['verdict']}")
                cov = s.get("coverage90")
                row += [_f(s["armse"]) + _ci(s["armse_ci"]), dtxt,
                        "—" if cov is None else f"{100 * cov:.0f} %"]
            row += [_f(s["loglik"], ".6g"), _f(s["loglik_sd"], ".3g")]
            if exact:
                row += [_f(s.get("loglik_bias"), ".3g") + _ci(s.get("loglik_bias_ci")),
                        _f(s.get("lik_ratio"), ".3g") + _ci(s.get("lik_ratio_ci"))]
            row += [_f(s["ns_per_particle_step"], ".3g"), f"{s['runs']} / {s['failed']}"]
            lines.append("| " + " | ".join(row) + " |")
        fails = [(n, s) for n, s in t["contenders"].items() if s["failed"] or s["missing"]]
        if fails:
            lines.append("")
            for n, s in fails:
                why = "; ".join(f"{k} ({v}x)" for k, v in s["failures"].items())
                miss = f" {s['missing']} runs not done." if s["missing"] else ""
                lines.append(f"- `{n}` failed {s['failed']} of {t['runs']} runs: {why}.{miss}")
        lines.append("")
    done = summary["complete_contenders"]
    lines.append("Contenders that completed every run: " + (", ".join(f"`{c}`" for c in done) or "none") + ".")
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
    """Accuracy (aRMSE with its 95 % interval, or sd of the log-likelihood) vs the filter's own
    time per run, with the Pareto front."""
    from ..plotting import OURS, PAPER, label, subplots

    key, ylabel = accuracy_key(task)
    fig, ax = subplots(figsize=(5.2, 3.6))
    pts, names = [], []
    for name, s in task["contenders"].items():
        if s.get(key) is None or not s.get("own_s"):
            continue
        x, y = s["own_s"], s[key]
        ci = s.get("armse_ci") if key == "armse" else None
        yerr = [[y - ci[0]], [ci[1] - y]] if ci else None
        ax.errorbar([x], [y], yerr=yerr, fmt="o", ms=5, capsize=3,
                    color=OURS if s["complete"] else "grey")
        ax.annotate(name, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
        pts.append((x, y))
        names.append(name)
    if pts:
        front = pareto(pts)
        ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "--", color=PAPER, lw=1,
                label="Pareto front")
        ax.legend(loc="best")
        ax.set_xscale("log")
    label(ax, "filter time per run [s] (median, log scale)", ylabel,
          f"{tname}: accuracy vs time (N_p = {task['n_particles']}, {task['runs']} runs)")
    return fig


def write(summary: dict, out_dir, plots: bool = True) -> list[Path]:
    """Write leaderboard.md, compare.json and <task>.png into ``out_dir``; returns the paths."""
    from .. import io

    out = Path(out_dir)
    paths = [io.write_text(out / "leaderboard.md", markdown(summary)),
             io.write_json(out / "compare.json", summary)]
    if plots:
        for tname, task in summary["tasks"].items():
            paths.append(io.write_figure(out / f"{tname}.png", plot_task(tname, task)))
    return paths
