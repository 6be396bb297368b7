"""Estimation-quality metrics ([MultiPDF] eqs. 11-14)."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .errors import InputError


def _pair(est, truth):
    """(estimates, truth) as (M, n_x) float arrays of one shape, at least one step; ``est`` may be a
    :class:`~pfbench.FilterResult` (its estimates) or a :class:`~pfbench.models.base.Trajectory`
    ``truth`` (its states)."""
    if hasattr(est, "estimates") and hasattr(est, "loglik"):   # a FilterResult
        est = est.estimates
    if hasattr(truth, "x") and hasattr(truth, "x0"):            # a Trajectory
        truth = truth.x
    try:
        est = np.asarray(est, dtype=np.float64)
        truth = np.asarray(truth, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"estimates and truth must be numeric arrays: {exc}") from None
    if est.ndim == 1:
        est = est[:, None]
    if truth.ndim == 1:
        truth = truth[:, None]
    if est.shape != truth.shape or est.ndim != 2:
        raise InputError(f"estimates {est.shape} and truth {truth.shape} must both be (n_steps, n_x)")
    if est.shape[0] < 1:
        raise InputError("estimates and truth have no steps")
    return est, truth


def mse(est, truth) -> np.ndarray:
    """MSE_j = (1/M) sum_k (x_hat_j^(k) - x_j^(k))^2 per state ([MultiPDF] eq. 13)."""
    est, truth = _pair(est, truth)
    return np.mean((est - truth) ** 2, axis=0)


def rmse(est, truth) -> np.ndarray:
    """RMSE_j = sqrt(MSE_j) per state ([MultiPDF] eq. 12)."""
    return np.sqrt(mse(est, truth))


def armse(est, truth) -> float:
    """aRMSE = (1/N_x) sum_j RMSE_j ([MultiPDF] eq. 11)."""
    return float(np.mean(rmse(est, truth)))


def distance(est, truth) -> np.ndarray:
    """d^(k) = ||x_hat^(k) - x^(k)||_2 per step ([MultiPDF] eq. 14)."""
    est, truth = _pair(est, truth)
    return np.sqrt(np.sum((est - truth) ** 2, axis=1))


class Interval(NamedTuple):
    """A mean, its band [lo, hi], and how many values were left out as NaN or infinite."""

    mean: float
    lo: float
    hi: float
    dropped: int


def mean_interval(values, z: float = 2.0) -> Interval:
    """Mean and the paper's band mean +- z sigma / sqrt(m) ([MultiPDF] §5; z = 2 for ~95 %) over
    the finite values; ``dropped`` counts the others (a diverged run), so that a caller can say
    that the mean is over fewer runs than were made, never hide it."""
    v = np.asarray(values, dtype=np.float64)
    finite = v[np.isfinite(v)]
    dropped, m = int(v.size - finite.size), finite.size
    if m == 0:
        return Interval(float("nan"), float("nan"), float("nan"), dropped)
    mu = float(finite.mean())
    half = z * float(finite.std(ddof=1)) / np.sqrt(m) if m > 1 else float("nan")
    return Interval(mu, mu - half, mu + half, dropped)
