"""Resampling schemes as numba loops (the fast path of :mod:`pfbench.resampling`).

Same contract, same random draws and the same floating-point operations as the NumPy
reference, so under the same generator state both return identical indices (tested).
The engine calls the ``*_into`` kernels with the running sum of the unnormalised weights.
"""
from __future__ import annotations

import numpy as np
from .cache import njit

from ..resampling import Scheme

_STRATIFIED = int(Scheme.STRATIFIED)
_MULTINOMIAL = int(Scheme.MULTINOMIAL)
_SYSTEMATIC = int(Scheme.SYSTEMATIC)
_RESIDUAL_DETERMINISTIC = int(Scheme.RESIDUAL_DETERMINISTIC)


@njit(nogil=True)
def cumsum_into(w, cdf):
    acc = 0.0
    for i in range(w.shape[0]):
        acc += w[i]
        cdf[i] = acc
    return acc


@njit(nogil=True)
def _merge(cdf, n, start_u, stride_u, idx):
    """idx[i] = smallest j with cdf[j] > (u_i + i) / n * total, positions increasing."""
    total = cdf[n - 1]
    pos = np.empty(n)
    for i in range(n):  # vectorisable: same operations as the NumPy reference
        pos[i] = (start_u[i * stride_u] + i) / n * total
    j = 0
    for i in range(n):
        while j < n - 1 and cdf[j] <= pos[i]:
            j += 1
        idx[i] = j


@njit(nogil=True)
def systematic_into(cdf, rng, idx):
    u = np.empty(1)
    u[0] = rng.random()
    _merge(cdf, cdf.shape[0], u, 0, idx)


@njit(nogil=True)
def stratified_into(cdf, rng, idx):
    n = cdf.shape[0]
    u = rng.random(n)
    _merge(cdf, n, u, 1, idx)


@njit(nogil=True)
def _search_right(cdf, n, value):
    j = np.searchsorted(cdf, value, side="right")
    return j if j < n else n - 1


@njit(nogil=True)
def multinomial_into(cdf, rng, idx):
    n = cdf.shape[0]
    total = cdf[n - 1]
    u = rng.random(n)
    for i in range(n):
        idx[i] = _search_right(cdf, n, u[i] * total)
    idx.sort()


@njit(nogil=True)
def _residual_counts(w, total, counts, res):
    n = w.shape[0]
    s = 0
    for i in range(n):
        nw = (w[i] / total) * n  # normalise first: n / total overflows when total is subnormal
        c = np.floor(nw)
        counts[i] = np.int64(c)
        res[i] = nw - c
        s += counts[i]
    return n - s


@njit(nogil=True)
def _expand(counts, idx):
    k = 0
    for i in range(counts.shape[0]):
        for _ in range(counts[i]):
            idx[k] = i
            k += 1


@njit(nogil=True)
def residual_into(w, total, rng, idx, deterministic):
    n = w.shape[0]
    counts = np.empty(n, np.int64)
    res = np.empty(n)
    r = _residual_counts(w, total, counts, res)
    if r > 0:
        if deterministic:
            order = np.argsort(-res, kind="mergesort")
            for m in range(r):
                counts[order[m]] += 1
        else:
            rcdf = np.empty(n)
            rtotal = cumsum_into(res, rcdf)
            u = rng.random(r)
            for m in range(r):
                counts[_search_right(rcdf, n, u[m] * rtotal)] += 1
    _expand(counts, idx)


@njit(nogil=True)
def resample_into(code, w, cdf, rng, idx):
    """Dispatch on the :class:`~pfbench.resampling.Scheme` code; ``cdf`` is the running sum of ``w``."""
    if code == _SYSTEMATIC:
        systematic_into(cdf, rng, idx)
    elif code == _STRATIFIED:
        stratified_into(cdf, rng, idx)
    elif code == _MULTINOMIAL:
        multinomial_into(cdf, rng, idx)
    else:
        residual_into(w, cdf[cdf.shape[0] - 1], rng, idx, code == _RESIDUAL_DETERMINISTIC)


def resample(name: str, weights, rng: np.random.Generator) -> np.ndarray:
    """Public wrapper with the signature of :func:`pfbench.resampling.resample`."""
    from .. import resampling as ref

    code = int(Scheme.parse(name))
    w = np.ascontiguousarray(weights, dtype=np.float64)
    ref._cdf(w)  # validates the weights
    cdf = np.empty_like(w)
    cumsum_into(w, cdf)
    idx = np.empty(w.shape[0], np.int64)
    resample_into(code, w, cdf, rng, idx)
    return idx


@njit
def _regularized_jitter(x, idx, d, h, rng):
    n, n_x = x.shape
    z = rng.standard_normal((n, n_x))
    r = np.sqrt(rng.beta(n_x / 2.0, 2.0, n))
    out = np.empty((n, n_x))
    for i in range(n):
        norm = 0.0
        for a in range(n_x):
            norm += z[i, a] * z[i, a]
        norm = np.sqrt(norm)
        for a in range(n_x):
            acc = 0.0
            for b in range(n_x):
                acc += z[i, b] * (r[i] / norm) * d[a, b]
            out[i, a] = x[idx[i], a] + h * acc
    return out


def regularized(particles, weights, rng, scheme: str = "systematic", bandwidth=None):
    """Regularized resampling on the numba backend (see :func:`pfbench.resampling.regularized`)."""
    from .. import resampling as ref

    x, w, d, h = ref.regularization_setup(particles, weights, bandwidth)
    idx = resample(scheme, w, rng)
    return _regularized_jitter(x, idx, d, h, rng)
