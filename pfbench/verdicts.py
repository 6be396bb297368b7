"""Paper claims as data, with verdicts computed from our numbers by a stated rule.

A recipe records every claim of the paper it tests with :meth:`pfbench.recipes.RecipeContext.claim`,
passing one of the rules below; the rule computes the verdict from the data, so no verdict string
is ever typed by hand. The report counts them per paper (the scorecard).

Verdicts
--------
``agree``
    our 95 % interval lies wholly inside the band that the paper's statement allows (or, for a
    direction, wholly on the paper's side of zero): the data could have shown otherwise and did not.
``disagree``
    our 95 % interval lies wholly outside that band (or wholly on the other side of zero).
``undecided``
    the interval straddles an edge of the band: our data cannot tell at this scale.
``not reproducible``
    the claim needs something we do not have (the paper's measured data, its program, a lost
    equation, a plant whose asymmetry we cannot simulate); the rule says why.

Claim kinds
-----------
``finding`` (:data:`FINDING`)
    a result of the paper, scored in the scorecard. One paper sentence is one finding; where the
    sentence admits several readings, the recipe scores its declared primary reading and lists the
    others as sensitivity rows (:class:`Reading`).
``setup check`` (:data:`SETUP`)
    a parameter or equation that the paper states and the recipe uses (e.g. the degree of a
    transfer function the paper prints): shown with its recipe, never scored.
``by construction`` (:data:`CONSTRUCTION`)
    true whatever the data (e.g. a triangle inequality, a quantity fixed by the plant, a number
    derived from the very table it is compared with): shown with the reason, never counted as
    agreement.

Rules (all at a 95 % level; each takes its tolerance band from the recipe, with the reason)
--------------------------------------------------------------------------------------------
* :func:`direction` - the paper says a quantity is positive (or negative): the 95 % t-interval of
  the mean of per-run paired differences, agree if wholly on the paper's side of 0, disagree if
  wholly on the other side, undecided if it contains 0.
* :func:`close_to` - a number: the band is paper ± tol |paper|; our interval is ours ± 1.96 se
  (a point when ``se`` is 0, e.g. a deterministic computation) or the one given. Equivalence test:
  agree when the interval lies inside the band (two one-sided tests, each at 2.5 %), disagree when
  it lies wholly outside, undecided otherwise.
* :func:`in_band` - the same decision for the t-interval of the mean of per-run samples against
  a band [lo, hi] given directly.
* :func:`no_dependence` - the paper says a paired difference is "not significant": :func:`in_band`
  with the band ±margin around 0.
* :func:`proportion` - a rate (e.g. "fails in 8 % of runs"): the 95 % Wilson (or exact
  Clopper-Pearson) interval of k/n from :func:`scipy.stats.binomtest` against paper ± tol, with the
  same three outcomes.
* :func:`all_cases` - one sentence about many cases, decided by the share of cases whose own
  rule agrees (every case by default: an intersection-union test).
* :func:`same_for_every` - a verdict reached at values the paper lost or never stated counts only
  when a computed sweep over the plausible values gives the same verdict; else not reproducible.
* :func:`holds` - a qualitative claim decided by a computed, deterministic test the recipe
  describes (agree / disagree).
* :func:`not_reproducible` - with the reason.

With many decisions at 95 %, some are wrong by chance: :func:`expected_false` gives the number the
scorecard states.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

AGREE, DISAGREE, UNDECIDED, NOT_REPRODUCIBLE = "agree", "disagree", "undecided", "not reproducible"
VERDICTS = (AGREE, DISAGREE, UNDECIDED, NOT_REPRODUCIBLE)
FINDING, SETUP, CONSTRUCTION = "finding", "setup check", "by construction"
KINDS = (FINDING, SETUP, CONSTRUCTION)
LEVEL = 0.95
Z95 = 1.959963984540054

#: one paragraph per verdict word and claim kind, as the report prints them
DEFINITIONS = {
    AGREE: "our 95 % interval lies wholly inside the band the paper's statement allows (for a "
           "direction: wholly on the paper's side of zero), so the data could have shown otherwise "
           "and did not.",
    DISAGREE: "our 95 % interval lies wholly outside that band (or wholly on the other side of zero).",
    UNDECIDED: "the interval straddles an edge of the band: at this number of runs our data cannot "
               "tell (for a range that is not of random runs, such as an emulation's best-worst "
               "timing: the answer lies within what that range leaves open).",
    NOT_REPRODUCIBLE: "the claim rests on something we do not have (the paper's measured data or "
                      "program, a lost equation, a guessed noise level, a plant asymmetry a "
                      "simulation cannot have); the rule gives the reason.",
    FINDING: "a result of the paper, scored. One sentence of the paper is one finding; where it "
             "admits several readings the recipe scores its declared primary reading and shows the "
             "others beneath as sensitivity rows (\"depends on reading\" when their verdicts differ).",
    SETUP: "a parameter or equation the paper states and the recipe uses: shown with the recipe, "
           "never scored.",
    CONSTRUCTION: "true whatever the data (e.g. a triangle inequality, or a number derived from the "
                  "very table it is compared with): shown with the reason, never counted as agreement.",
}


@dataclass(frozen=True)
class Outcome:
    """A computed verdict with the rule that produced it and the numbers behind it."""

    verdict: str
    rule: str
    ours: float | str | None = None
    interval: tuple[float, float] | None = None
    n: int | None = None
    band: tuple[float, float] | None = None
    random: bool = True   # False: the interval is a deterministic range, not a 95 % interval

    @property
    def statistical(self) -> bool:
        """Whether the verdict is a decision from a 95 % interval of random data (it can be wrong
        by chance; :func:`expected_false`)."""
        return self.interval is not None and self.random and self.verdict in (AGREE, DISAGREE)

    def as_dict(self) -> dict:
        d = asdict(self)
        for key in ("interval", "band"):
            if d[key] is not None:
                d[key] = [float(v) for v in d[key]]
        return d


@dataclass(frozen=True)
class Reading:
    """One other reading of a claim's sentence (a sensitivity row beneath the primary reading):
    what the reading is, what it measures and its computed outcome."""

    reading: str
    quantity: str
    outcome: Outcome

    def as_dict(self) -> dict:
        return {"reading": self.reading, "quantity": self.quantity, **self.outcome.as_dict()}


def _t95(dof: int) -> float:
    from scipy.stats import t

    return float(t.ppf(0.5 + LEVEL / 2, dof))


def band_verdict(lo: float, hi: float, band_lo: float, band_hi: float) -> str:
    """Three outcomes of an interval [lo, hi] against a band [band_lo, band_hi]: agree when the
    interval lies inside the band, disagree when the two do not meet, undecided otherwise."""
    if not all(math.isfinite(v) for v in (lo, hi)) or math.isnan(band_lo) or math.isnan(band_hi):
        return UNDECIDED
    if band_lo <= lo and hi <= band_hi:
        return AGREE
    if hi < band_lo or lo > band_hi:
        return DISAGREE
    return UNDECIDED


def t_interval(samples) -> tuple[float, float, float, int] | None:
    """(mean, lo, hi, n): the 95 % t-interval of the mean of the finite ``samples``; None with
    fewer than 2 finite samples."""
    x = np.asarray(samples, dtype=float).ravel()
    x = x[np.isfinite(x)]
    if x.size < 2:
        return None
    mean = float(x.mean())
    half = _t95(x.size - 1) * float(x.std(ddof=1)) / math.sqrt(x.size)
    return mean, mean - half, mean + half, int(x.size)


def direction(samples, sign: int = +1, what: str = "difference") -> Outcome:
    """Paired differences ``samples`` (one per run) whose mean the paper says has sign ``sign``."""
    ti = t_interval(samples)
    if ti is None:
        n = int(np.isfinite(np.asarray(samples, dtype=float)).sum())
        return Outcome(UNDECIDED, f"fewer than 2 finite runs of the {what}", n=n)
    mean, lo, hi, n = ti
    want = "> 0" if sign > 0 else "< 0"
    rule = f"95 % t-interval of the mean {what} over {n} runs; the paper says {want}"
    if (sign > 0 and lo > 0) or (sign < 0 and hi < 0):
        verdict = AGREE
    elif (sign > 0 and hi < 0) or (sign < 0 and lo > 0):
        verdict = DISAGREE
    else:
        verdict = UNDECIDED
    return Outcome(verdict, rule, mean, (lo, hi), n)


def in_band(samples, lo: float, hi: float, what: str, why: str = "") -> Outcome:
    """The paper says the mean of ``samples`` lies in [lo, hi] (``why``: the band's reason): the 95 %
    t-interval of the mean against the band (:func:`band_verdict`)."""
    ti = t_interval(samples)
    if ti is None:
        return Outcome(UNDECIDED, f"fewer than 2 finite runs of the {what}", band=(lo, hi))
    mean, ilo, ihi, n = ti
    rule = (f"95 % t-interval of the mean {what} over {n} runs inside [{lo:.4g}, {hi:.4g}]: agree if "
            "wholly inside, disagree if wholly outside, undecided otherwise")
    if why:
        rule += f" ({why})"
    return Outcome(band_verdict(ilo, ihi, lo, hi), rule, mean, (ilo, ihi), n, (lo, hi))


def no_dependence(diffs, margin: float, what: str) -> Outcome:
    """The paper says a paired difference is "not significant": :func:`in_band` with the
    equivalence margin ±``margin`` (agree only when the whole interval lies within it)."""
    return in_band(diffs, -margin, margin, what, f"equivalence margin ±{margin:g}")


def close_to(ours: float, paper: float, tol: float, se: float = 0.0, why: str = "",
             interval: tuple[float, float] | None = None, interval_is: str = "our 95 % interval") -> Outcome:
    """Numeric claim: ours against the band paper ± tol |paper| (``why``: the tolerance's reason).

    Our interval is ``interval`` when given, else ours ± 1.96 ``se`` (a point when ``se`` is 0).
    ``interval_is`` names a given interval that is not a 95 % interval of random runs (e.g. "the
    best-worst range of the pipeline timing"); such a verdict is not counted among the interval
    decisions that can be wrong by chance.
    """
    ours, paper = float(ours), float(paper)
    if not (math.isfinite(ours) and math.isfinite(paper)):
        return Outcome(UNDECIDED, "ours or the paper's value is not finite", ours)
    band = (paper - tol * abs(paper), paper + tol * abs(paper))
    if interval is None:
        interval = (ours - Z95 * float(se), ours + Z95 * float(se))
    lo, hi = float(interval[0]), float(interval[1])
    point = lo == hi
    rule = (f"{'ours' if point else interval_is} within {tol * 100:.3g} % of the paper's value "
            f"({'agree if inside, disagree otherwise' if point else 'agree if wholly inside, disagree if wholly outside, undecided otherwise'})")
    if why:
        rule += f" ({why})"
    return Outcome(band_verdict(lo, hi, *band), rule, ours, None if point else (lo, hi), band=band,
                   random=interval_is == "our 95 % interval")


def proportion_interval(k: int, n: int, method: str = "wilson") -> tuple[float, float]:
    """95 % interval of a proportion k/n (:func:`scipy.stats.binomtest`; ``method`` ``wilson`` or
    ``exact`` for Clopper-Pearson)."""
    if n <= 0:
        return 0.0, 1.0
    from scipy.stats import binomtest

    ci = binomtest(int(k), int(n)).proportion_ci(LEVEL, method=method)
    return float(ci.low), float(ci.high)


def wilson(k: int, n: int) -> tuple[float, float]:
    """95 % Wilson score interval of k/n."""
    return proportion_interval(k, n, "wilson")


def proportion(k: int, n: int, paper: float, tol: float, method: str = "wilson") -> Outcome:
    """A rate k/n against the paper's rate ``paper`` ± ``tol`` (absolute): the 95 % interval
    (:func:`proportion_interval`) against the band (:func:`band_verdict`)."""
    lo, hi = proportion_interval(int(k), int(n), method)
    band = (max(0.0, paper - tol), min(1.0, paper + tol))
    rule = (f"95 % {method} interval of {k}/{n} inside the paper's {paper:.1%} ± {tol:.1%}: agree if "
            "wholly inside, disagree if wholly outside, undecided otherwise")
    return Outcome(band_verdict(lo, hi, *band), rule, k / n if n else None, (lo, hi), int(n), band)


def all_cases(cases, share: float = 1.0, what: str = "the sentence",
              why: str = "the sentence says it holds in every case") -> Outcome:
    """One sentence about many cases (objects, versions, comparisons), decided by the cases' own
    outcomes. ``cases``: Outcomes, or (label, Outcome) pairs whose labels the rule lists.

    With a of n cases agreeing and x disagreeing, the share of cases where the statement holds is at
    least a/n and at most (n - x)/n; the sentence agrees when that whole range lies in [``share``, 1],
    disagrees when it lies wholly below ``share``, undecided otherwise (:func:`band_verdict`).
    ``share`` = 1 ("in every case", "both A and B") is an intersection-union test: agree only when
    every case agrees (valid at 95 % without correction), disagree when one case disagrees; a
    smaller share reads "almost always" (``why``: the reason for it). A case that is not
    reproducible makes the sentence not reproducible.
    """
    pairs = [c if isinstance(c, tuple) else (None, c) for c in cases]
    n = len(pairs)
    if n == 0:
        raise ValueError("all_cases needs at least one case")
    nr = [o for _, o in pairs if o.verdict == NOT_REPRODUCIBLE]
    if nr:
        return Outcome(NOT_REPRODUCIBLE, f"{len(nr)} of {n} cases not reproducible: {nr[0].rule}")
    a = sum(o.verdict == AGREE for _, o in pairs)
    x = sum(o.verdict == DISAGREE for _, o in pairs)
    lo, hi = a / n, (n - x) / n
    rule = (f"{what}: {a} of {n} cases agree and {x} disagree by their own rule, so the share of cases "
            f"where it holds is in [{lo:.3g}, {hi:.3g}]; the sentence needs >= {share:.3g} ({why}): "
            "agree if that whole range does, disagree if none of it does, undecided otherwise")
    if any(label is not None for label, _ in pairs):
        rule += " (" + "; ".join(f"{label}: {o.verdict}" for label, o in pairs) + ")"
    # n stays None: it counts cases, not runs (the scorecard reads n as runs)
    return Outcome(band_verdict(lo, hi, share, 1.0), rule, a / n, (lo, hi), None, (share, 1.0))


def same_for_every(primary: Outcome, sweep, guessed: str) -> Outcome:
    """A verdict reached at values the paper lost or never stated (a noise level, an equation, a
    particle count): ``primary`` (at our values) when every point of the computed ``sweep``
    (:class:`Reading` rows, other plausible values) gives the same verdict, else not reproducible,
    with every point's verdict in the reason (``guessed``: what the values are)."""
    sweep = list(sweep)
    if all(r.outcome.verdict == primary.verdict for r in sweep):
        return primary
    pts = "; ".join(f"{r.reading}: {r.outcome.verdict}" for r in sweep)
    return not_reproducible(f"decided by the {guessed}, which the paper does not give: at our values "
                            f"{primary.verdict}; {pts}")


def holds(value: bool, test: str) -> Outcome:
    """A qualitative claim decided by a computed, deterministic test, described in ``test``."""
    return Outcome(AGREE if bool(value) else DISAGREE, test, str(bool(value)))


def not_reproducible(why: str) -> Outcome:
    return Outcome(NOT_REPRODUCIBLE, why)


def expected_false(n_decisions: int, level: float = LEVEL) -> float:
    """How many of ``n_decisions`` interval decisions at ``level`` are expected to be wrong by
    chance if every one sat at its rule's error rate: (1 - level) n, an upper estimate (an
    equivalence or direction decision errs with at most 2.5 % when the truth is at the edge)."""
    return (1.0 - level) * n_decisions
