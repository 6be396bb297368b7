"""The compiled resampling helpers against NumPy."""
import numpy as np

from pfbench.backends.numba_resampling import _search_right


def test_search_right_is_numpys_searchsorted():
    """The hand-written binary search returns ``np.searchsorted(cdf, v, side="right")`` clamped to
    n - 1, for ties, values outside the range, zero-weight runs (repeated cdf values), infinities
    and NaN (sorted last by NumPy). Catches: ``<`` for ``<=`` (ties go left), a search over [0, n)
    instead of the whole array, an off-by-one in the halving, NaN compared as IEEE (never <=)."""
    rng = np.random.default_rng(3)
    cases = []
    for n in (1, 2, 3, 7, 64, 513):
        w = rng.random(n) * (rng.random(n) < 0.7)  # runs of zero weights: repeated cdf values
        cdf = np.cumsum(w)
        cases.append(cdf)
        cases.append(np.concatenate([cdf, [np.inf, np.nan, np.nan]]))
    for cdf in cases:
        values = np.concatenate([cdf[: min(len(cdf), 40)], rng.random(40) * (np.nanmax(cdf[np.isfinite(cdf)], initial=1.0) + 1),
                                 [-1.0, 0.0, np.inf, -np.inf, np.nan]])
        for n in {len(cdf), max(1, len(cdf) - 3)}:
            for v in values:
                expect = min(int(np.searchsorted(cdf, v, side="right")), n - 1)
                assert _search_right(cdf, n, v) == expect, (len(cdf), n, v)
