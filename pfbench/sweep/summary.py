"""Per-configuration summaries of a sweep and the aRMSE-vs-N_p plot ([MultiPDF] Figs. 3-11)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..methods import Method
from ..metrics import mean_interval

if TYPE_CHECKING:  # loaded by the functions that make frames (a sweep worker needs none)
    import pandas as pd

#: legend labels; other methods show their name
_LABEL = {"bootstrap": "BF", "mpf": "MPF"}
#: line styles of the single-filter references (MultiPDF lines use the colour cycle)
_STYLE = {"mpf": dict(ls="--", color="k"), "bootstrap": dict(ls=":", color="gray"),
          "kalman": dict(ls="-.", color="tab:brown")}


def _order(method: str) -> int:
    """Table order of :class:`Method` (bootstrap first, multipdf before mpf, ...)."""
    return int(Method.parse(method))


def summarize_frame(frame: pd.DataFrame, spec: dict | None = None) -> pd.DataFrame:
    """Per (method, N_p, N_f): runs, aRMSE mean and the paper's 95 % interval
    mean +- 2 sigma / sqrt(m) ([MultiPDF] §5) over the runs with a finite aRMSE (``dropped``: how
    many were not, e.g. a diverged filter), and filter runs per second per core; ``model`` is the
    full model spec (:func:`~pfbench.sweep.core.model_label`: ``ob3:v4``, not ``ob3``);
    ``estimate`` is the one the configuration ran with (:func:`~pfbench.sweep.core.estimate_for`;
    ``pre`` without a spec or for an older store)."""
    import pandas as pd

    from .core import estimate_for, model_label

    rows = []
    if frame.empty:
        return pd.DataFrame(columns=["model", "method", "n_particles", "n_filters", "estimate", "runs",
                                     "dropped", "armse_mean", "armse_lo", "armse_hi", "runs_per_s"])
    for (m, n_p, n_f), g in frame.groupby(["method", "n_particles", "n_filters"], sort=True):
        iv = mean_interval(g["armse"].to_numpy())
        el = float(g["elapsed_s"].sum())
        rows.append({"model": model_label(spec) if spec else "", "method": m, "n_particles": int(n_p),
                     "n_filters": int(n_f), "estimate": estimate_for(spec or {}, m), "runs": int(len(g)),
                     "dropped": iv.dropped, "armse_mean": iv.mean, "armse_lo": iv.lo, "armse_hi": iv.hi,
                     "runs_per_s": len(g) / el if el > 0 else float("nan")})
    out = pd.DataFrame(rows)
    out["_o"] = out["method"].map(_order)
    return out.sort_values(["_o", "n_filters", "n_particles"]).drop(columns="_o").reset_index(drop=True)


def throughput(chunks: list, n_records: int) -> dict:
    """Tasks per worker-second from the journal's work-unit wall times."""
    wall = float(sum(c.get("wall_s", 0.0) for c in chunks))
    return {"tasks": n_records, "worker_seconds": wall,
            "tasks_per_worker_s": n_records / wall if wall > 0 else float("nan")}


def plot_summary(summary: pd.DataFrame, title: str = "", ax=None):
    """aRMSE vs N_p, one line per N_f (MultiPDF; N_f = 1 is the bootstrap filter), 95 % bands;
    every other method (bootstrap, MPF, SIR, ...) as an extra line. Returns the figure."""
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
    else:
        fig = ax.figure
    groups = []
    for (m, n_f), g in summary.groupby(["method", "n_filters"], sort=False):
        label = f"N_f = {n_f}" if m == "multipdf" else _LABEL.get(m, m)
        groups.append((m, n_f, label, g.sort_values("n_particles")))
    groups.sort(key=lambda t: (t[0] != "multipdf", _order(t[0]), t[1]))
    for m, n_f, label, g in groups:
        x = g["n_particles"].to_numpy()
        style = _STYLE.get(m, {})
        line, = ax.plot(x, g["armse_mean"], marker="o", ms=3, label=label, **style)
        lo, hi = g["armse_lo"].to_numpy(), g["armse_hi"].to_numpy()
        if np.isfinite(lo).all():
            ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.18, lw=0)
    ax.set_xlabel("N_p (total particles)")
    ax.set_ylabel("aRMSE")
    if title:
        ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    return fig
