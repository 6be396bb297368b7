"""Reading sweeps of the rtd recipes: a verdict decided at guessed values (noise levels, Q/R ratios
the chapter does not state) is scored only when every plausible value gives the same verdict."""
from __future__ import annotations

from pfbench.verdicts import Outcome, Reading, same_for_every


def swept(primary: Outcome, sweep: list[Reading], guessed: str) -> tuple[Outcome, list[Reading]]:
    """``(outcome, others)``: :func:`pfbench.verdicts.same_for_every` over the sweep (the primary
    outcome when every sweep point gives its verdict, else not reproducible, decided by the
    ``guessed`` values), with the sweep points as sensitivity rows."""
    return same_for_every(primary, sweep, guessed), list(sweep)
