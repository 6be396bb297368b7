"""The one result type of every filter in pfbench: particle filters, MultiPDF, the marginalized PF,
the guided filter and the Kalman family all return a :class:`FilterResult`."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError


#: why a run's log-likelihood is not finite, and where to look; ``pfbench run`` and sweeps say it
NON_FINITE_WHY = ("every particle's likelihood was zero, NaN or infinite (check the model's log_likelihood and "
                  "transition, or the measurement at that step)")


#: what to do about log-likelihoods a model returned as NaN or +inf; ``pfbench run`` and sweeps say it
INVALID_WHY = "check the model's log_likelihood and transition at those states"


def invalid_info(per_step) -> dict:
    """``info`` entries for the log-likelihoods the model returned as NaN or +inf, each a particle
    given weight zero (``per_step``: their number at each step): the count, and where there are any
    the steps with one and the first of them. Counted by bootstrap, SIR, SIS, ASIR and MultiPDF on
    the numpy and numba backends (ASIR: both stages); the other methods and backends have no entry."""
    per_step = np.asarray(per_step)
    steps = np.flatnonzero(per_step)
    if steps.size == 0:
        return {"invalid_log_likelihoods": 0}
    return {"invalid_log_likelihoods": int(per_step.sum()), "invalid_steps": int(steps.size),
            "first_invalid_step": int(steps[0])}


def invalid_message(info: dict) -> str | None:
    """What ``pfbench run`` says of :func:`invalid_info`'s entries; None when there are none."""
    if not info.get("invalid_log_likelihoods"):
        return None
    return (f"log_likelihood returned NaN or +inf {info['invalid_log_likelihoods']} time(s) at "
            f"{info['invalid_steps']} step(s), first at step {info['first_invalid_step']}: those particles got "
            f"weight zero ({INVALID_WHY})")


def reported_ess(ess: np.ndarray, degenerate: np.ndarray) -> np.ndarray:
    """N_eff as a result reports it: 0 where the step was degenerate (NaN, a filter without
    particles, stays NaN). The filter kept the previous weights there (N_eff of those, often N_p,
    decides its resampling), but no particle explained the measurement, and a full N_eff would
    hide the step where it lost track."""
    return np.where(degenerate & ~np.isnan(ess), 0.0, ess)


@dataclass
class FilterResult:
    """What every filter returns.

    Attributes
    ----------
    estimates : (M, n_x) posterior means E[x_t | y_1:t] (MultiPDF: the mean of the N_f sub-filter
        estimates, [MultiPDF] eq. 9).
    variances : (M, n_x) posterior variances. MultiPDF: the law of total variance over the
        equally weighted sub-filters, mean of the sub-filter variances (within) plus the variance
        of the sub-filter means (between).
    loglik : estimate of log p(y_1:M); -inf if a step was degenerate.
    loglik_increments : (M,) estimates of log p(y_t | y_1:t-1); they sum to ``loglik``.
    ess : (M,) effective sample size N_eff = 1 / sum w_i^2 after weighting ([MultiPDF] eq. 8);
        0 on a degenerate step (of that sub-filter); MultiPDF: mean over the sub-filters; NaN for
        Kalman filters (no particles).
    n_resampled : number of resampling events (summed over sub-filters; ASIR: one per step, its
        first stage).
    degenerate : (M,) bool, steps where every likelihood was zero (in some sub-filter).
    elapsed_s : wall-clock time of the filtering (numba compilation excluded).
    method, backend, dtype : what ran.
    n_particles : N_p actually used (after the MultiPDF split; 1 when a marginalized PF needs
        only one copy; 0 for Kalman filters). ``info["n_particles_requested"]`` says what was asked
        for when the two differ, with the reason in ``info["note"]``.
    n_filters : N_f.
    sub_estimates, sub_variances : (N_f, M, n_x) per sub-filter (N_f = 1 for single filters).
    sub_ess : (N_f, M).
    covariances : (M, n_x, n_x) posterior covariances where the filter has them (Kalman family,
        marginalized PF), else None.
    extras : family-specific arrays (Kalman: ``pred_means``, ``pred_covs``, ``innovations``,
        ``innovation_covs``, ``gains``; guided: ``resampled``; ...).
    info : settings and bookkeeping (resampling scheme, thresholds, streams, notes; a particle
        filter's ``threads``: the threads it ran on, the free cores by default).
    """

    estimates: np.ndarray
    variances: np.ndarray
    loglik: float
    loglik_increments: np.ndarray
    ess: np.ndarray
    n_resampled: int
    degenerate: np.ndarray
    elapsed_s: float
    method: str = ""
    backend: str = ""
    dtype: str = "float64"
    n_particles: int = 0
    n_filters: int = 1
    sub_estimates: np.ndarray | None = None
    sub_variances: np.ndarray | None = None
    sub_ess: np.ndarray | None = None
    covariances: np.ndarray | None = None
    extras: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        """One line (the dataclass's repr printed every array: 50 000 characters for M = 300)."""
        return (f"FilterResult(method={self.method!r}, backend={self.backend!r}, dtype={self.dtype!r}, "
                f"n_particles={self.n_particles}, n_filters={self.n_filters}, n_steps={self.n_steps}, "
                f"loglik={self.loglik:.6g}, n_resampled={self.n_resampled}, elapsed_s={self.elapsed_s:.3g})")

    def __post_init__(self):
        if self.sub_estimates is None:
            self.sub_estimates = self.estimates[None]
        if self.sub_variances is None:
            self.sub_variances = self.variances[None]
        if self.sub_ess is None:
            self.sub_ess = np.asarray(self.ess)[None]

    @property
    def n_steps(self) -> int:
        return int(self.estimates.shape[0])

    @property
    def ns_per_particle_step(self) -> float:
        """Wall time per particle and step in ns (per step for Kalman filters)."""
        return self.elapsed_s * 1e9 / max(1, max(self.n_particles, 1) * self.n_steps)

    def first_nonfinite_step(self) -> int | None:
        """The first step t whose log-likelihood increment is not finite (every particle had a zero,
        NaN or infinite likelihood there, or the model diverged), None if every step is finite."""
        bad = np.flatnonzero(~np.isfinite(np.asarray(self.loglik_increments, dtype=np.float64)))
        return int(bad[0]) if bad.size else None

    def to_dataframe(self, names=None):
        """One row per step: ``step``, the estimate and variance of each state (``<name>`` and
        ``<name>_var``; ``names`` default: the model's ``state_names`` as :func:`pfbench.run_filter`
        keeps them in ``info``, else ``x0, x1, ...``), ``ess``, ``loglik_increment`` and ``degenerate``
        (a pandas DataFrame)."""
        import pandas as pd

        n_x = self.estimates.shape[1]
        names = names if names is not None else self.info.get("state_names") or [f"x{i}" for i in range(n_x)]
        names = [names] if isinstance(names, str) else list(names)
        if len(names) != n_x:
            raise InputError(f"{len(names)} names for {n_x} states")
        cols = {"step": np.arange(self.n_steps)}
        for i, name in enumerate(names):
            cols[name] = self.estimates[:, i]
            cols[f"{name}_var"] = self.variances[:, i]
        cols["ess"] = np.asarray(self.ess, dtype=np.float64)
        cols["loglik_increment"] = np.asarray(self.loglik_increments, dtype=np.float64)
        cols["degenerate"] = np.asarray(self.degenerate, dtype=bool)
        return pd.DataFrame(cols)


def total_variance(sub_estimates: np.ndarray, sub_variances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and variance of an equal-weight mixture of N_f sub-filter posteriors.

    mean = (1/N_f) sum_l mu_l; var = (1/N_f) sum_l sigma_l^2 + (1/N_f) sum_l (mu_l - mean)^2, the
    law of total variance (within plus between).
    """
    mean = sub_estimates.mean(axis=0)
    between = ((sub_estimates - mean) ** 2).mean(axis=0)
    return mean, sub_variances.mean(axis=0) + between


def mixture_loglik_increments(sub_increments: np.ndarray) -> np.ndarray:
    """Increments of log (1/N_f) sum_l p_hat_l(y_1:t) for sub-filter increments (N_f, M).

    Each sub-filter's likelihood estimate is unbiased, so their mean is too; its log at step t
    minus its log at t-1 is the increment, and the increments sum to the log of the mean over the
    whole record (telescoping). With N_f = 1 this returns the sub-filter's own increments.
    """
    inc = np.asarray(sub_increments, dtype=np.float64)
    if inc.shape[0] == 1:
        return inc[0].copy()
    cum = np.cumsum(inc, axis=1)                      # log p_hat_l(y_1:t)
    mx = cum.max(axis=0)
    finite = np.isfinite(mx)
    with np.errstate(invalid="ignore", divide="ignore"):
        lmean = np.where(finite, mx + np.log(np.mean(np.exp(cum - np.where(finite, mx, 0.0)), axis=0)), mx)
    out = np.diff(lmean, prepend=0.0)
    out[~np.isfinite(lmean)] = -np.inf
    return out
