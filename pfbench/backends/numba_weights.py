"""Log-sum-exp weighting and weighted moments for the numba backend: the one compiled weighting
that every numba filter kernel (particle, marginalized, guided) calls. The NumPy twin is
:func:`pfbench.backends.numpy_backend.weigh`; both do the same floating-point operations in the
same order, which is what makes the backends agree under common random numbers.
"""
from __future__ import annotations

import numpy as np

from numba.extending import register_jitable

from .cache import njit
from .fastexp import exp_scalar


@register_jitable
def valid_log_likelihood(v):
    """``v``, or -inf (zero likelihood) where it is NaN or +inf: the rule every numba kernel applies
    to a log-likelihood (branch-free, so the loops that call it still vectorise)."""
    return v if v < np.inf else -np.inf


@njit(nogil=True, error_model="numpy")
def weigh(lw, ll, wu, cdf):
    """a = lw + ll -> wu = exp(a - max a) and its running sum cdf; returns (max, total, degenerate).

    ``lw`` are the normalised log-weights before this step, ``ll`` the log-likelihoods (or
    incremental log-weights). NaN and +inf in ``ll`` count as -inf (zero likelihood) and are
    overwritten so in ``ll``. If every likelihood is zero, the previous weights are kept and
    ``degenerate`` is True. The exponential is :func:`pfbench.backends.fastexp.exp_scalar` in a loop
    of its own, compiled with ``error_model="numpy"`` (no zero-division check, which would stop
    LLVM from vectorising it).
    """
    n = lw.shape[0]
    m = -np.inf
    for i in range(n):
        v = valid_log_likelihood(ll[i])
        ll[i] = v
        a = lw[i] + v
        wu[i] = a
        if a > m:
            m = a
    degenerate = not (m > -np.inf)
    if degenerate:
        m = -np.inf
        for i in range(n):
            wu[i] = lw[i]
            if lw[i] > m:
                m = lw[i]
    for i in range(n):  # a loop of its own: it vectorises (the running sum below cannot)
        wu[i] = exp_scalar(wu[i] - m)
    acc = 0.0
    for i in range(n):
        acc += wu[i]
        cdf[i] = acc
    return m, acc, degenerate


@njit(nogil=True)
def normalised_log_weights(wu, total, lw):
    """lw = log(wu / total), -inf where wu = 0."""
    lt = np.log(total)
    for i in range(wu.shape[0]):
        lw[i] = np.log(wu[i]) - lt if wu[i] > 0.0 else -np.inf


@njit(nogil=True)
def moments(xg, wu, total, mean_out, var_out):
    """Weighted mean and variance per state component; returns N_eff = 1 / sum w_i^2."""
    n, n_x = xg.shape
    s2 = 0.0
    for i in range(n):
        wn = wu[i] / total
        s2 += wn * wn
    for a in range(n_x):
        acc = 0.0
        for i in range(n):
            acc += wu[i] * xg[i, a]
        mean = acc / total
        acc2 = 0.0
        for i in range(n):
            d = xg[i, a] - mean
            acc2 += wu[i] * d * d
        mean_out[a] = mean
        var_out[a] = acc2 / total
    return 1.0 / s2
