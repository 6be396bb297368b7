"""One plotting style for every recipe figure: ours beside the paper's, labelled, with units.

Recipes make their figures with :func:`subplots` (the shared style: size of text, grid, colours)
and draw the paper's published value or curve with :func:`paper_value` / :func:`paper_curve`, so a
reader sees the two side by side in the same colours in every figure. :func:`label` sets an axis'
labels with units and refuses an empty one, so no panel goes out unlabelled.
"""
from __future__ import annotations

#: colours: ours, the paper's, and a second series of ours (e.g. another method)
OURS, PAPER, OTHER = "#1f77b4", "#d62728", "#2ca02c"

STYLE = {
    "figure.dpi": 100,
    "savefig.dpi": 110,
    "font.size": 9,
    "axes.titlesize": 9,
    "axes.labelsize": 9,
    "legend.fontsize": 8,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "lines.linewidth": 1.2,
    "axes.spines.top": False,
    "axes.spines.right": False,
}


def subplots(nrows: int = 1, ncols: int = 1, **kwargs):
    """``matplotlib.pyplot.subplots`` in the shared style (constrained layout unless given)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    kwargs.setdefault("layout", "constrained")
    # for the whole process, not a context: labels, legends and the saved file's dpi are styled
    # after this call returns (recipe figures are the only ones a pfbench process draws)
    matplotlib.rcParams.update(STYLE)
    return plt.subplots(nrows, ncols, **kwargs)


def label(ax, xlabel: str, ylabel: str, title: str | None = None) -> None:
    """Axis labels (say the unit, e.g. "time [s]"); an empty label is a bug in the recipe."""
    if not str(xlabel).strip() or not str(ylabel).strip():
        raise ValueError("every axis of a recipe figure needs a label (with its unit)")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title is not None:
        ax.set_title(title)


def paper_value(ax, value: float, text: str = "paper", axis: str = "y", **kwargs) -> None:
    """The paper's published value as a dashed line (horizontal for ``axis="y"``)."""
    kw = {"color": PAPER, "ls": "--", "lw": 1.0, "label": text, **kwargs}
    (ax.axhline if axis == "y" else ax.axvline)(value, **kw)


def paper_curve(ax, x, y, text: str = "paper", **kwargs) -> None:
    """The paper's published curve (points read from its figure or table), in the paper's colour."""
    kw = {"color": PAPER, "ls": "--", "marker": "s", "ms": 3, "label": text, **kwargs}
    ax.plot(x, y, **kw)


def band(ax, x, lo, hi, text: str, color: str = OURS, **kwargs) -> None:
    """A shaded interval (say what it is in ``text``, e.g. "95 % interval over 100 runs")."""
    ax.fill_between(x, lo, hi, color=color, alpha=0.2, lw=0, label=text, **kwargs)
