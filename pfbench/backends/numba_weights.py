"""Log-sum-exp weighting and weighted moments for the numba backend: the one compiled weighting
that every numba filter kernel (particle, marginalized, guided) calls. The NumPy twin is
:func:`pfbench.backends.numpy_backend.weigh`; both do the same floating-point operations in the
same order, which is what makes the backends agree under common random numbers. The particle
kernel's pass B (:func:`block_weights`: the same exponential and running sum, per stream block,
with the moments) is here too: it calls no model, so every model compiles against one cached copy.
"""
from __future__ import annotations

import numpy as np

from numba.extending import register_jitable

from .cache import njit
from .fastexp import exp_scalar
from .particle_work import B_SUM, B_SUM_SQ, F_CDF, F_WEIGHTS


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
    ``degenerate`` is True. The exponentials vectorise as :mod:`pfbench.backends.fastexp` describes.
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


@njit(nogil=True, error_model="numpy")
def block_weights(work, step):
    """Pass B of the particle kernel (:mod:`pfbench.backends.numba_particle`) on stream block
    ``step.b`` of filter ``step.g`` (:class:`~pfbench.backends.particle_work.Work`,
    :class:`~pfbench.backends.particle_work.Step`): w = exp(a - m) in place of the log-weights a
    (``m = step.m``), the block's running sum (cdf), and, except in ASIR's first stage, the block's
    sums of w x, w (x - x_0)^2 and w^2 ([Thesis] eq. 2.14 for N_eff).

    In place: the weights overwrite the cache lines just read, one array fewer streamed through
    the caches every step, and a loop over one array needs no run-time overlap test in front of
    its vectorised body.

    * The exponentials are a loop of their own, which vectorises (:mod:`pfbench.backends.fastexp`).
    * The running sum is the one strictly sequential chain (the cdf feeds the resampling, so it
      is the NumPy reference's ``cumsum`` order). It waits one add's latency per particle, so
      sum w^2 and the first state component's two moment sums ride along in the same loop for
      free, each in a register (a sum accumulated in the ``bsx`` array would wait on a store and a
      reload every particle). Further components get a pass of their own with four partial sums
      (:func:`_sums4`). The moments feed nothing back (estimates only), so their order is free.

    The loops run over views of the block that start at 0 (see
    :mod:`pfbench.backends.numba_particle`).
    """
    xs = work.xs[work.gstate[0, step.g], step.g]
    b = step.b
    i0 = work.bounds[b]
    i1 = work.bounds[b + 1]
    mom = not step.first
    bsum, bs2, bsx, bsxx = work.bwork[B_SUM], work.bwork[B_SUM_SQ], work.bmom[0], work.bmom[1]
    n_x = xs.shape[1]
    w = work.fwork[F_WEIGHTS, i0:i1]  # views that start at 0 (see above)
    cb = work.fwork[F_CDF, i0:i1]
    x = xs[i0:i1]
    m = step.m
    for k in range(w.shape[0]):
        w[k] = exp_scalar(w[k] - m)
    acc = 0.0
    s2 = 0.0
    sx = 0.0
    sxx = 0.0
    shift = np.float64(xs[0, 0])
    for k in range(w.shape[0]):
        wk = w[k]
        acc += wk
        cb[k] = acc
        s2 += wk * wk  # chains beside the first: free
        v = np.float64(x[k, 0])
        d = v - shift
        sx += wk * v
        sxx += wk * (d * d)
    bsum[b] = acc
    bs2[b] = s2 if mom else 0.0
    bsx[b, 0] = sx if mom else 0.0
    bsxx[b, 0] = sxx if mom else 0.0
    for c in range(1, n_x):
        if mom:
            bsx[b, c], bsxx[b, c] = _sums4(w, x[:, c], np.float64(xs[0, c]))
        else:
            bsx[b, c] = 0.0
            bsxx[b, c] = 0.0


@njit(nogil=True, error_model="numpy")
def block_moments(work, step):
    """The particle kernel's ``estimate="post"`` pass on stream block ``step.b`` of filter
    ``step.g``'s resampled particles: the block's unweighted sums of x and (x - x_0)^2 per
    component into the block moments (x_0: the filter's particle 0, the shift of
    :func:`block_weights`), reduced in block order by the driver as the weighted sums are, with
    N_p for the total weight. Not called on the default ``pre`` path."""
    xs = work.xs[work.gstate[0, step.g], step.g]
    b = step.b
    x = xs[work.bounds[b]:work.bounds[b + 1]]  # a view that starts at 0 (see block_weights)
    for c in range(xs.shape[1]):
        work.bmom[0, b, c], work.bmom[1, b, c] = _sums4(None, x[:, c], np.float64(xs[0, c]))


@register_jitable
def _sums4(w, v, shift):
    """(sum w_i v_i, sum w_i (v_i - shift)^2) over the block in one pass over ``w`` and ``v``, each
    with four partial sums so the adds do not wait on each other (the order differs from a plain
    loop in the last bits: the estimates, which feed nothing back). ``w`` None: every weight 1 (the
    ``estimate="post"`` pass over resampled particles)."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    q0 = 0.0
    q1 = 0.0
    q2 = 0.0
    q3 = 0.0
    n = v.shape[0]
    i = 0
    while i + 4 <= n:
        v0 = np.float64(v[i])
        v1 = np.float64(v[i + 1])
        v2 = np.float64(v[i + 2])
        v3 = np.float64(v[i + 3])
        if w is None:  # unweighted: the type of ``w`` decides, at compile time
            w0 = w1 = w2 = w3 = 1.0
        else:
            w0 = w[i]
            w1 = w[i + 1]
            w2 = w[i + 2]
            w3 = w[i + 3]
        s0 += w0 * v0
        s1 += w1 * v1
        s2 += w2 * v2
        s3 += w3 * v3
        d0 = v0 - shift
        d1 = v1 - shift
        d2 = v2 - shift
        d3 = v3 - shift
        q0 += w0 * (d0 * d0)
        q1 += w1 * (d1 * d1)
        q2 += w2 * (d2 * d2)
        q3 += w3 * (d3 * d3)
        i += 4
    while i < n:
        v0 = np.float64(v[i])
        d0 = v0 - shift
        w0 = 1.0 if w is None else w[i]
        s0 += w0 * v0
        q0 += w0 * (d0 * d0)
        i += 1
    return (s0 + s1) + (s2 + s3), (q0 + q1) + (q2 + q3)
