"""The NumPy backend: the readable reference engine, vectorised over particles.

:func:`run_group` runs G independent particle filters (a MultiPDF group, or one filter) over
all steps, drawing every random number from one ``numpy.random.Generator`` in this order:

1. initial particles of filter 0, 1, ..., G-1 (the model's ``initial``);
2. per step t, per filter g in order:
   a. ASIR only: the first-stage resampling draws;
   b. transition noise, ``rng.standard_normal((n, n_noise))``;
   c. the resampling draws, if the filter resamples at this step.

The numba backend (:mod:`pfbench.backends.numba_particle`) follows the same order with the same
operations, which is what makes the two backends agree under common random numbers.

Methods (:class:`pfbench.filters.methods.Method` codes, shared with the numba kernel): bootstrap
(resample every step, [Embedded] Alg. 1; [MultiPDF] Alg. 1), SIR (resample when N_eff <
threshold, [MultiPDF] eq. 8; [Thesis] Alg. 3), SIS (never resample, [Thesis] Alg. 2), ASIR
(auxiliary SIR, [Thesis] Alg. 6: first-stage weights p(y_t | mu_t^i) at mu_t^i = f(x_{t-1}^i)
with zero noise).

:func:`weigh` is the NumPy backend's one log-sum-exp weighting; every NumPy filter driver
(particle, marginalized, guided) calls it.
"""
from __future__ import annotations

import numpy as np

from .. import resampling
from ..filters.methods import Method


def _clean(ll) -> np.ndarray:
    """Log-likelihoods as float64 with NaN and +inf replaced by -inf (invalid -> weight 0)."""
    ll = np.array(ll, dtype=np.float64, copy=True).reshape(-1)
    ll[~(ll == ll) | (ll == np.inf)] = -np.inf
    return ll


def weigh(lw: np.ndarray, ll: np.ndarray):
    """Combine normalised log-weights with log-likelihoods, log-sum-exp style (the NumPy twin of
    :func:`pfbench.backends.numba_weights.weigh`).

    Returns (wu, cdf, m, total, degenerate): unnormalised weights exp(a - max a), their
    running sum, the max, the sum, and whether every likelihood was zero (then the previous
    weights are kept). The normalised log-weights are only needed when the filter does not
    resample (:func:`normalised_log_weights`), so they are not computed here.
    """
    a = lw + ll
    m = a.max()
    degenerate = not (m > -np.inf)
    if degenerate:
        a = lw.copy()
        m = a.max()
    wu = np.exp(a - m)
    cdf = np.cumsum(wu)
    return wu, cdf, m, cdf[-1], degenerate


def normalised_log_weights(wu: np.ndarray, total: float) -> np.ndarray:
    """log(wu / total), -inf where wu = 0."""
    with np.errstate(divide="ignore"):
        return np.log(wu) - np.log(total)


def run_group(model, p, rng, y, u, x, method: int, scheme: int, ess_threshold: float,
              est, var, ess, inc, resampled, degen, hist_x=None, hist_w=None) -> None:
    """NumPy twin of the numba ``run_group``; fills the output arrays in place (``hist_x``/``hist_w``:
    the weighted particles of every step, when given with M rows)."""
    store = hist_x is not None and hist_x.shape[1] > 0
    fns = model.kernel_functions()
    initial, transition, log_likelihood = fns["initial"], fns["transition"], fns["log_likelihood"]
    resample = resampling.get(resampling.Scheme(scheme))
    G, n, n_x = x.shape
    n_noise = model.n_noise
    logn = np.log(n)
    lw = np.full((G, n), -logn)
    for g in range(G):
        x[g] = initial(rng, n, p)
    for t in range(y.shape[0]):
        yt, ut = y[t], u[t]
        for g in range(G):
            xg = x[g]
            first = 0.0
            if method == Method.ASIR:  # first stage
                mu = transition(xg, ut, t, np.zeros((n, n_noise)), p)
                lam_all = _clean(log_likelihood(yt, mu, ut, t, p))
                wu, _, m1, tot1, deg1 = weigh(lw[g], lam_all)
                first = m1 + np.log(tot1)
                if deg1:
                    lam_all[:] = 0.0
                idx = resample(wu, rng)
                xg[:] = xg[idx]
                lam = lam_all[idx]
                lw[g] = -logn
            noise = rng.standard_normal((n, n_noise))
            xg[:] = transition(xg, ut, t, noise, p)
            ll = _clean(log_likelihood(yt, xg, ut, t, p))
            if method == Method.ASIR:
                ll = _clean(ll - lam)
            wu, _, m, total, deg = weigh(lw[g], ll)
            if store:
                hist_x[g, t] = xg
                hist_w[g, t] = wu / total
            degen[g, t] = deg
            inc[g, t] = (-np.inf if deg else m + np.log(total)) + first
            mean = (wu @ xg) / total
            est[g, t] = mean
            var[g, t] = (wu @ (xg - mean) ** 2) / total
            wn = wu / total
            e = 1.0 / np.cumsum(wn * wn)[-1]
            ess[g, t] = e
            do = method == Method.BOOTSTRAP or (method == Method.SIR and e < ess_threshold)
            if do:
                xg[:] = xg[resample(wu, rng)]
                lw[g] = -logn
            else:
                lw[g] = normalised_log_weights(wu, total)
            resampled[g, t] = do
