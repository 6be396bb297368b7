"""Reading sweeps of the rtd recipes: a verdict decided at guessed values (noise levels, Q/R ratios
the chapter does not state) is scored only when every plausible value gives the same verdict."""
from __future__ import annotations

from pfbench.verdicts import Outcome, Reading, not_reproducible


def _ours(o: Outcome) -> str:
    if isinstance(o.ours, float):
        return f"{o.ours:.3g}"
    return "-" if o.ours is None else str(o.ours)


def swept(primary: Outcome, sweep: list[Reading], guessed: str) -> tuple[Outcome, list[Reading]]:
    """``(outcome, others)``: the primary outcome with the sweep as its sensitivity rows when every
    sweep point gives the primary's verdict; otherwise ``not reproducible`` (the verdict is decided
    by the ``guessed`` values), the sweep's verdicts in the reason and no sensitivity rows (the
    sweep points are values of the set-up, not readings of the sentence)."""
    if all(r.outcome.verdict == primary.verdict for r in sweep):
        return primary, list(sweep)
    pts = "; ".join(f"{r.reading}: {r.outcome.verdict} (ours {_ours(r.outcome)})" for r in sweep)
    return not_reproducible(f"the verdict is decided by the {guessed}, which the chapter does not state: at "
                            f"the defaults {primary.verdict} (ours {_ours(primary)}); {pts}"), []
