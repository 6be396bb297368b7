"""Paper claims as data, with verdicts computed from our numbers by a stated rule.

A recipe records every claim of the paper it tests with :meth:`pfbench.recipes.RecipeContext.claim`,
passing one of the rules below; the rule computes the verdict from the data, so no verdict string
is ever typed by hand. The report counts them per paper (the scorecard).

Verdicts: ``agree``, ``disagree``, ``undecided`` (our data cannot tell at this scale), and
``not reproducible`` (the claim needs something we do not have, e.g. the paper's measured data;
the rule says why).

Rules (all at a 95 % level):

* :func:`direction` - the paper says a quantity is positive (or negative), e.g. "MultiPDF with
  N_f = 10 beats the PF": from per-run paired differences, the 95 % t-interval of their mean.
  agree if it lies entirely on the paper's side of zero, disagree if entirely on the other side,
  undecided if it contains zero.
* :func:`no_dependence` - the paper says a paired difference is "not significant": disagree if
  the 95 % t-interval of its mean excludes 0, agree if it lies within a stated equivalence margin,
  undecided otherwise.
* :func:`close_to` - a numeric claim: agree if |ours - paper| <= tol |paper| (tol stated by the
  recipe, with its reason), widened by 1.96 standard errors when ours is a Monte Carlo mean;
  disagree otherwise.
* :func:`proportion` - a rate (e.g. "fails in 8 % of runs"): the 95 % Wilson interval of k/n; agree
  if it meets [p - tol, p + tol], disagree if it lies outside, undecided if the interval is wider
  than 4 tol (too few runs to tell).
* :func:`holds` - a qualitative claim decided by a computed boolean (e.g. "the EKF converges to the
  wrong angle in this run"): agree / disagree from the test the recipe computed and describes.
* :func:`not_reproducible` - with the reason.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

AGREE, DISAGREE, UNDECIDED, NOT_REPRODUCIBLE = "agree", "disagree", "undecided", "not reproducible"
VERDICTS = (AGREE, DISAGREE, UNDECIDED, NOT_REPRODUCIBLE)
Z95 = 1.959963984540054


@dataclass(frozen=True)
class Outcome:
    """A computed verdict with the rule that produced it and the numbers behind it."""

    verdict: str
    rule: str
    ours: float | str | None = None
    interval: tuple[float, float] | None = None
    n: int | None = None

    def as_dict(self) -> dict:
        d = asdict(self)
        if self.interval is not None:
            d["interval"] = [float(v) for v in self.interval]
        return d


def _t95(dof: int) -> float:
    from scipy.stats import t

    return float(t.ppf(0.975, dof))


def direction(samples, sign: int = +1, what: str = "difference") -> Outcome:
    """Paired differences ``samples`` (one per run) whose mean the paper says has sign ``sign``."""
    x = np.asarray(samples, dtype=float).ravel()
    x = x[np.isfinite(x)]
    n = x.size
    if n < 2:
        return Outcome(UNDECIDED, f"fewer than 2 finite runs of the {what}", n=n)
    mean = float(x.mean())
    half = _t95(n - 1) * float(x.std(ddof=1)) / math.sqrt(n)
    lo, hi = mean - half, mean + half
    want = "> 0" if sign > 0 else "< 0"
    rule = f"95 % t-interval of the mean {what} over {n} runs; the paper says {want}"
    if (sign > 0 and lo > 0) or (sign < 0 and hi < 0):
        verdict = AGREE
    elif (sign > 0 and hi < 0) or (sign < 0 and lo > 0):
        verdict = DISAGREE
    else:
        verdict = UNDECIDED
    return Outcome(verdict, rule, mean, (lo, hi), n)


def no_dependence(diffs, margin: float, what: str) -> Outcome:
    """Equivalence: the paper says a paired difference is "not significant". Disagree if the 95 %
    t-interval of the mean difference excludes 0 (a significant dependence), agree if it lies within
    +-``margin``, undecided otherwise (the interval of :func:`direction`)."""
    d = direction(diffs, +1, what)
    if d.interval is None:
        return d
    lo, hi = d.interval
    rule = (f"95 % t-interval of the mean {what} over {d.n} runs: disagree if it excludes 0, agree if "
            f"it lies within ±{margin:g}, undecided otherwise")
    if lo > 0 or hi < 0:
        verdict = DISAGREE
    elif -margin <= lo and hi <= margin:
        verdict = AGREE
    else:
        verdict = UNDECIDED
    return Outcome(verdict, rule, d.ours, d.interval, d.n)


def close_to(ours: float, paper: float, tol: float, se: float = 0.0, why: str = "") -> Outcome:
    """Numeric claim: agree if |ours - paper| <= tol |paper| + 1.96 se (``why``: the tolerance's reason)."""
    ours, paper = float(ours), float(paper)
    if not (math.isfinite(ours) and math.isfinite(paper)):
        return Outcome(UNDECIDED, "ours or the paper's value is not finite", ours)
    bound = tol * abs(paper) + Z95 * float(se)
    rule = f"|ours - paper| <= {tol:.0%} of the paper's value" + (" + 1.96 se" if se else "")
    if why:
        rule += f" ({why})"
    verdict = AGREE if abs(ours - paper) <= bound else DISAGREE
    return Outcome(verdict, rule, ours, (ours - Z95 * se, ours + Z95 * se) if se else None)


def wilson(k: int, n: int) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion k/n."""
    if n <= 0:
        return 0.0, 1.0
    p = k / n
    den = 1 + Z95 ** 2 / n
    centre = (p + Z95 ** 2 / (2 * n)) / den
    half = Z95 * math.sqrt(p * (1 - p) / n + Z95 ** 2 / (4 * n * n)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


def proportion(k: int, n: int, paper: float, tol: float) -> Outcome:
    """A rate k/n against the paper's rate ``paper`` with tolerance ``tol`` (absolute)."""
    lo, hi = wilson(int(k), int(n))
    rule = (f"95 % Wilson interval of {k}/{n} against the paper's {paper:.1%} ± {tol:.1%}; "
            f"undecided when the interval is wider than {4 * tol:.1%}")
    if hi < paper - tol or lo > paper + tol:
        verdict = DISAGREE
    elif hi - lo > 4 * tol:
        verdict = UNDECIDED
    else:
        verdict = AGREE
    return Outcome(verdict, rule, k / n if n else None, (lo, hi), int(n))


def holds(value: bool, test: str) -> Outcome:
    """A qualitative claim decided by a computed test, described in ``test``."""
    return Outcome(AGREE if bool(value) else DISAGREE, test, str(bool(value)))


def not_reproducible(why: str) -> Outcome:
    return Outcome(NOT_REPRODUCIBLE, why)
