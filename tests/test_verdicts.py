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


def test_close_to_uses_the_stated_tolerance_and_standard_error():
    assert v.close_to(105.0, 100.0, 0.1).verdict == v.AGREE
    assert v.close_to(115.0, 100.0, 0.1).verdict == v.DISAGREE
    assert v.close_to(115.0, 100.0, 0.1, se=3.0).verdict == v.AGREE       # 10 + 1.96 * 3 > 15
    assert v.close_to(float("nan"), 100.0, 0.1).verdict == v.UNDECIDED


def test_proportion_wilson_interval_and_undecided_when_too_few_runs():
    assert v.proportion(80, 1000, 0.08, 0.02).verdict == v.AGREE
    assert v.proportion(4, 1000, 0.08, 0.02).verdict == v.DISAGREE
    assert v.proportion(1, 10, 0.08, 0.02).verdict == v.UNDECIDED           # interval ~ [0.02, 0.40]
    lo, hi = v.wilson(80, 1000)
    assert lo < 0.08 < hi and hi - lo == pytest.approx(0.0336, abs=1e-3)


def test_holds_and_not_reproducible():
    assert v.holds(True, "t").verdict == v.AGREE and v.holds(False, "t").verdict == v.DISAGREE
    assert v.not_reproducible("data lost").verdict == v.NOT_REPRODUCIBLE


def test_no_dependence_rule():
    assert v.no_dependence(np.zeros(10), 0.2, "d").verdict == v.AGREE          # interval [0, 0]
    assert v.no_dependence(np.ones(10) * 0.5 + np.linspace(-0.01, 0.01, 10), 0.2, "d").verdict == v.DISAGREE
    wide = np.array([1.0, -1.0, 0.0, 1.0, -1.0, 0.0])                       # contains 0, wider than 0.2
    assert v.no_dependence(wide, 0.2, "d").verdict == v.UNDECIDED
