"""Verdict rules: each decides from the data by its stated rule (pfbench.verdicts)."""
import numpy as np
import pytest

from pfbench import verdicts as v


def test_direction_agrees_disagrees_and_stays_undecided():
    rng = np.random.default_rng(0)
    assert v.direction(1.0 + rng.normal(0, 0.5, 30)).verdict == v.AGREE
    assert v.direction(-1.0 + rng.normal(0, 0.5, 30)).verdict == v.DISAGREE
    assert v.direction(rng.normal(0, 0.5, 30) * 1e-3 + 0.0).verdict in (v.UNDECIDED,)  # mean ~ 0
    assert v.direction(-1.0 + rng.normal(0, 0.5, 30), sign=-1).verdict == v.AGREE
    assert v.direction([1.0]).verdict == v.UNDECIDED          # one run cannot decide


def test_direction_interval_is_the_t_interval():
    """Catches a z-interval or a missing sqrt(n): mean 1, sd 1, n = 4 -> half-width t(3) / 2."""
    x = np.array([0.0, 1.0, 1.0, 2.0]) * np.sqrt(1.5) + 1 - np.sqrt(1.5)   # mean 1, sd 1
    o = v.direction(x)
    from scipy.stats import t

    half = t.ppf(0.975, 3) * x.std(ddof=1) / 2
    assert o.interval == pytest.approx((x.mean() - half, x.mean() + half))


def test_band_verdict_three_outcomes():
    """Inside -> agree, disjoint -> disagree, straddling an edge -> undecided. Catches the old
    overlap rule (agree when the interval merely meets the band)."""
    assert v.band_verdict(1.0, 2.0, 0.0, 3.0) == v.AGREE
    assert v.band_verdict(4.0, 5.0, 0.0, 3.0) == v.DISAGREE
    assert v.band_verdict(-5.0, -4.0, 0.0, 3.0) == v.DISAGREE
    assert v.band_verdict(2.0, 4.0, 0.0, 3.0) == v.UNDECIDED        # overlaps, reaches outside
    assert v.band_verdict(-1.0, 4.0, 0.0, 3.0) == v.UNDECIDED       # wider than the band
    assert v.band_verdict(float("nan"), 1.0, 0.0, 3.0) == v.UNDECIDED


def test_close_to_three_outcomes_with_a_standard_error():
    assert v.close_to(105.0, 100.0, 0.1).verdict == v.AGREE               # a point inside [90, 110]
    assert v.close_to(115.0, 100.0, 0.1).verdict == v.DISAGREE            # a point outside
    assert v.close_to(104.0, 100.0, 0.1, se=2.0).verdict == v.AGREE       # [100.1, 107.9] inside
    assert v.close_to(115.0, 100.0, 0.1, se=3.0).verdict == v.UNDECIDED   # [109.1, 120.9] straddles 110
    assert v.close_to(125.0, 100.0, 0.1, se=3.0).verdict == v.DISAGREE    # [119.1, 130.9] outside
    assert v.close_to(100.0, 100.0, 0.1, interval=(80.0, 120.0)).verdict == v.UNDECIDED
    o = v.close_to(float("nan"), 100.0, 0.1)
    assert o.verdict == v.UNDECIDED
    assert v.close_to(104.0, 100.0, 0.1, se=2.0).band == pytest.approx((90.0, 110.0))


def test_in_band_and_no_dependence_three_outcomes():
    rng = np.random.default_rng(1)
    noise = rng.normal(0, 1, 400)
    noise = (noise - noise.mean()) / noise.std(ddof=1)                     # mean 0, sd 1: half-width 0.098
    assert v.in_band(1.0 + noise, 0.5, 1.5, "x").verdict == v.AGREE
    assert v.in_band(3.0 + noise, 0.5, 1.5, "x").verdict == v.DISAGREE
    assert v.in_band(1.45 + noise, 0.5, 1.5, "x").verdict == v.UNDECIDED    # interval [1.35, 1.55]
    assert v.no_dependence(0.05 * noise, 0.2, "d").verdict == v.AGREE
    assert v.no_dependence(0.5 + 0.05 * noise, 0.2, "d").verdict == v.DISAGREE
    # excludes 0 but lies inside the margin: an equivalence, not a dependence (old rule: disagree)
    assert v.no_dependence(0.1 + 0.01 * noise, 0.2, "d").verdict == v.AGREE
    wide = np.array([1.0, -1.0, 0.0, 1.0, -1.0, 0.0])                       # contains 0, wider than 0.2
    assert v.no_dependence(wide, 0.2, "d").verdict == v.UNDECIDED
    assert v.in_band([1.0], 0.0, 2.0, "x").verdict == v.UNDECIDED           # one run cannot decide


def test_proportion_three_outcomes_from_scipy_intervals():
    """Catches the overlap rule: 9/100 against 2 % ± 3 % (interval 4.8-16.2 %) overlaps the band
    [0, 5 %] but reaches outside it, so it is undecided, not agree."""
    assert v.proportion(80, 1000, 0.08, 0.02).verdict == v.AGREE          # [6.5, 9.9] inside [6, 10]
    assert v.proportion(4, 1000, 0.08, 0.02).verdict == v.DISAGREE
    assert v.proportion(9, 100, 0.02, 0.03).verdict == v.UNDECIDED
    assert v.proportion(1, 10, 0.08, 0.02).verdict == v.UNDECIDED
    lo, hi = v.wilson(80, 1000)
    assert lo < 0.08 < hi and hi - lo == pytest.approx(0.0336, abs=1e-3)
    from scipy.stats import binomtest

    ci = binomtest(9, 100).proportion_ci(0.95, method="exact")
    assert v.proportion_interval(9, 100, "exact") == pytest.approx((ci.low, ci.high))
    assert v.proportion(9, 100, 0.02, 0.03).interval == pytest.approx((0.048, 0.162), abs=1e-3)


def test_holds_and_not_reproducible():
    assert v.holds(True, "t").verdict == v.AGREE and v.holds(False, "t").verdict == v.DISAGREE
    assert v.not_reproducible("data lost").verdict == v.NOT_REPRODUCIBLE


def test_statistical_decisions_and_the_expected_number_wrong():
    assert v.close_to(104.0, 100.0, 0.1, se=2.0).statistical
    assert not v.close_to(105.0, 100.0, 0.1).statistical                   # a deterministic point
    assert not v.holds(True, "t").statistical
    assert not v.proportion(9, 100, 0.02, 0.03).statistical                # undecided decides nothing
    assert v.expected_false(170) == pytest.approx(8.5)


def test_every_word_and_kind_is_defined():
    assert set(v.DEFINITIONS) == set(v.VERDICTS) | set(v.KINDS)


def _o(verdict):
    return v.Outcome(verdict, "test", 0.0, (0.0, 0.0))


def test_all_cases():
    """One sentence about many cases: agree only when enough cases agree, disagree when too many
    disagree. Catches a rule that agrees on a majority where the sentence says 'each', and one that
    ignores a disagreeing case."""
    A, D, U = v.AGREE, v.DISAGREE, v.UNDECIDED
    each = lambda vs: v.all_cases([_o(x) for x in vs], 1.0, "w", "why").verdict
    assert each([A, A, A]) == A
    assert each([A, A, U]) == U
    assert each([A, A, D]) == D
    most = lambda vs: v.all_cases([_o(x) for x in vs], 0.9, "w", "why").verdict
    assert most([A] * 9 + [D]) == A                 # 90 % agree: 'almost every'
    assert most([A] * 8 + [U, D]) == U              # 80-90 %: cannot tell
    assert most([A] * 8 + [D, D]) == D              # at most 80 %
    o = v.all_cases([_o(A), v.not_reproducible("lost")], 1.0, "w", "why")
    assert o.verdict == v.NOT_REPRODUCIBLE and "lost" in o.rule
    labelled = v.all_cases([("loss", _o(A)), ("identification", _o(U))])
    assert labelled.verdict == U and "loss: agree; identification: undecided" in labelled.rule


def test_same_for_every():
    """A verdict reached at guessed values counts only when every swept value gives it. Catches the
    primary's verdict kept when one sweep point says otherwise."""
    agree, against = _o(v.AGREE), _o(v.DISAGREE)
    assert v.same_for_every(agree, [v.Reading("Q x 10", "q", agree)], "Q") is agree
    o = v.same_for_every(agree, [v.Reading("Q x 10", "q", agree), v.Reading("Q / 10", "q", against)], "Q")
    assert o.verdict == v.NOT_REPRODUCIBLE and "Q / 10: disagree" in o.rule


def test_a_deterministic_range_is_not_counted_as_a_chance_decision():
    """close_to with a best-worst range: decided the same way, named as such, and not among the
    decisions that can be wrong by chance (catches the range printed as a 95 % interval)."""
    o = v.close_to(32.0, 33.0, 0.1, interval=(31.0, 34.0), interval_is="the best-worst range")
    assert o.verdict == v.AGREE and o.rule.startswith("the best-worst range within 10 %")
    assert not o.statistical and v.close_to(32.0, 33.0, 0.1, interval=(31.0, 34.0)).statistical
