"""Resampling schemes as numba loops (the fast path of :mod:`pfbench.resampling`).

Same contract, same random draws and the same floating-point operations as the NumPy
reference, so under the same generator state both return identical indices (tested).
The filter kernels call one scheme kernel (:data:`KERNELS`) with the running sum of the
unnormalised weights. The particle kernel's resampling pass (:func:`merge_gather` for systematic
and stratified, :func:`gather` after an index scheme) is here too: it calls no model, so every
model compiles against one cached copy.
"""
from __future__ import annotations

import numpy as np
from numba.extending import register_jitable

from .cache import njit

from ..resampling import Scheme
from .particle_work import ESTIMATE_TILE, F_CDF, F_LAM, F_LAM_ALL, F_UNIFORMS, F_WEIGHTS

_SYSTEMATIC, _STRATIFIED, _MULTINOMIAL, _RESIDUAL, _RESIDUAL_DETERMINISTIC = (
    int(Scheme.SYSTEMATIC), int(Scheme.STRATIFIED), int(Scheme.MULTINOMIAL), int(Scheme.RESIDUAL),
    int(Scheme.RESIDUAL_DETERMINISTIC))



@njit(nogil=True)
def cumsum_into(w, cdf):
    """cdf = the running sum of ``w`` (NumPy's ``cumsum`` order); returns the total."""
    acc = 0.0
    for i in range(w.shape[0]):
        acc += w[i]
        cdf[i] = acc
    return acc


@register_jitable
def _position(ui, i, n, total):
    """Output position i of systematic/stratified resampling, (u_i + i) / n * total, in the
    operations of :mod:`pfbench.resampling`."""
    return (ui + i) / n * total


@register_jitable
def _nonneg(i):
    """An index known to be >= 0 (a particle index read from memory), as unsigned: numba then
    drops the negative-index wraparound test."""
    return np.uint64(i)


@njit(nogil=True, inline="always")
def _merge(cdf, n, start_u, stride_u, idx):
    """idx[i] = smallest j with cdf[j] > (u_i + i) / n * total, positions increasing."""
    total = cdf[n - 1]
    pos = np.empty(n)
    for i in range(n):  # vectorisable: same operations as the NumPy reference
        pos[i] = _position(start_u[i * stride_u], i, n, total)
    j = 0
    for i in range(n):
        while j < n - 1 and cdf[j] <= pos[i]:
            j += 1
        idx[i] = j


@njit(nogil=True, inline="always")
def _search_right(cdf, n, value):
    """Smallest j with cdf[j] > value (n - 1 if none): ``np.searchsorted(cdf, value, "right")``
    on the sorted ``cdf``, written out because numba's generic searchsorted (NaN-aware comparisons
    typed for complex numbers too) is slow to compile. The comparison is NumPy's sort order (NaN
    above everything), so the result is NumPy's for every input."""
    lo = 0
    hi = cdf.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if cdf[mid] <= value or value != value:
            lo = mid + 1
        else:
            hi = mid
    return lo if lo < n else n - 1


@njit(nogil=True, inline="always")
def _expand(counts, idx):
    k = 0
    for i in range(counts.shape[0]):
        for _ in range(counts[i]):
            idx[k] = i
            k += 1


@njit(nogil=True, inline="always")
def _decreasing_order(v):
    """Indices that sort ``v`` (no NaN) in decreasing order, ties by the lower index: the same as
    ``np.argsort(-v, kind="mergesort")`` (a stable bottom-up merge sort, written out because
    numba's generic argsort costs seconds to compile)."""
    n = v.shape[0]
    a = np.arange(n)
    b = np.empty(n, np.int64)
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i, j, k = lo, mid, lo
            while i < mid and j < hi:
                if v[a[j]] > v[a[i]]:  # only a strictly larger right element overtakes: stable
                    b[k] = a[j]
                    j += 1
                else:
                    b[k] = a[i]
                    i += 1
                k += 1
            while i < mid:
                b[k] = a[i]
                i += 1
                k += 1
            while j < hi:
                b[k] = a[j]
                j += 1
                k += 1
        a, b = b, a
        width *= 2
    return a


@njit(nogil=True, inline="always")
def residual_into(w, total, rng, idx, deterministic):
    """Residual resampling of ``w`` (sum ``total``) into ``idx``: floor(N w_i / total) copies each,
    the remainder to the largest residuals (``deterministic``) or drawn multinomially."""
    n = w.shape[0]
    counts = np.empty(n, np.int64)
    res = np.empty(n)
    s = 0
    for i in range(n):
        nw = (w[i] / total) * n  # normalise first: n / total overflows when total is subnormal
        c = np.floor(nw)
        counts[i] = np.int64(c)
        res[i] = nw - c
        s += counts[i]
    r = n - s
    if r > 0:
        if deterministic:
            order = _decreasing_order(res)
            for m in range(r):
                counts[order[m]] += 1
        else:
            rcdf = np.empty(n)
            rtotal = cumsum_into(res, rcdf)
            u = rng.random(r)
            for m in range(r):
                counts[_search_right(rcdf, n, u[m] * rtotal)] += 1
    _expand(counts, idx)


# One kernel per scheme with the common signature ``(code, w, cdf, rng, idx)``: ``cdf`` is the
# running sum of the unnormalised weights ``w``, ``code`` the scheme's :class:`Scheme` code (read by
# :func:`any_scheme` only). :func:`pfbench.backends.kernels.build` binds the one a run uses to the
# kernel's ``_resample``, so a run never compiles the others; ``any_scheme`` serves callers that
# pick the scheme at run time. Every compiled function is a fixed cost of a cold compile, so the
# kernels and their loops are inlined into the caller (``inline="always"``).
@njit(nogil=True, inline="always")
def systematic(code, w, cdf, rng, idx):
    """[Thesis] Alg. 4 / [Embedded] Alg. 1 step 5: one uniform, N evenly spaced pointers."""
    u = np.empty(1)
    u[0] = rng.random()
    _merge(cdf, cdf.shape[0], u, 0, idx)


@njit(nogil=True, inline="always")
def stratified(code, w, cdf, rng, idx):
    """One uniform per stratum ((u_i + i) / N)."""
    n = cdf.shape[0]
    u = rng.random(n)
    _merge(cdf, n, u, 1, idx)


@njit(nogil=True, inline="always")
def multinomial(code, w, cdf, rng, idx):
    """N independent draws from the weights, returned sorted (counted per particle and expanded:
    the same indices as sorting them, without compiling a sort)."""
    n = cdf.shape[0]
    total = cdf[n - 1]
    u = rng.random(n)
    counts = np.zeros(n, np.int64)
    for i in range(n):
        counts[_search_right(cdf, n, u[i] * total)] += 1
    _expand(counts, idx)


@njit(nogil=True, inline="always")
def residual(code, w, cdf, rng, idx):
    """Residual resampling, remainder drawn multinomially."""
    residual_into(w, cdf[cdf.shape[0] - 1], rng, idx, False)


@njit(nogil=True, inline="always")
def residual_deterministic(code, w, cdf, rng, idx):
    """Residual resampling, remainder given to the largest residuals."""
    residual_into(w, cdf[cdf.shape[0] - 1], rng, idx, True)


@njit(nogil=True, inline="always")
def any_scheme(code, w, cdf, rng, idx):
    """Dispatch on the :class:`~pfbench.resampling.Scheme` code (compiles every scheme); a code
    without a branch here raises, so a new scheme cannot run another one's kernel."""
    if code == _SYSTEMATIC:
        systematic(code, w, cdf, rng, idx)
    elif code == _STRATIFIED:
        stratified(code, w, cdf, rng, idx)
    elif code == _MULTINOMIAL:
        multinomial(code, w, cdf, rng, idx)
    elif code == _RESIDUAL or code == _RESIDUAL_DETERMINISTIC:
        residual_into(w, cdf[cdf.shape[0] - 1], rng, idx, code == _RESIDUAL_DETERMINISTIC)
    else:
        raise ValueError("any_scheme: a resampling scheme code without a kernel here")


@njit(nogil=True, error_model="numpy")
def merge_gather(work, settings, step):
    """Systematic/stratified resampling of the output positions [i0, i1) of stream block ``step.b``
    of filter ``step.g``, writing the selected particles (and, in ASIR's first stage, its
    first-stage log-likelihoods ``lam``) into the other particle buffer ([Thesis] Alg. 4;
    [Embedded] Alg. 1 step 5): pass C of the particle kernel
    (:mod:`pfbench.backends.numba_particle`; the groups are those of
    :mod:`pfbench.backends.particle_work`; stratified when ``settings.scheme`` says so, the
    systematic uniform is ``step.u``).

    Output i takes ancestor a(i) = the smallest j with cdf[j] > position_i (n - 1 if none), where
    position_i = (u_i + i) / n * total (u_i = u, or ``ub[i - i0]`` when stratified): the operations
    of :mod:`pfbench.resampling`. A sequential merge walks j with two data-dependent branches per
    particle, which mispredict when the weights are uneven. Here the walk is branch-free: positions
    increase with i, so the outputs whose ancestor is <= j are the prefix [0, K_j) with K_j =
    #{i : position_i < cdf[j]}; output K_j is marked as starting ancestor j + 1 (a later,
    zero-weight j overwrites the same mark), and a running maximum over the marks gives a(i). Same
    ancestors as the merge for any weights (tested against it).

    K_j comes from x_j = cdf[j] n / total - shift (shift = u; stratified: 0.5) as floor(x_j) + 1, in
    tiles of ``ESTIMATE_TILE`` j in a loop of their own, which vectorises (``error_model="numpy"``:
    no zero-division check in the way).

    * Systematic: this is exact unless x_j lies within ``tol`` = (n + 2) 2^-49 of an integer. Proof:
      with unit roundoff 2^-53 and no underflow (1e-250 < total < 1e250; the kernel's weights have
      total >= 1), the computed position_i is (u + i) total / n (1 + t_i) with |t_i| <= 3.01 2^-53,
      so position_i < cdf[j] exactly when i < X_j - (u + i) t_i, X_j = cdf[j] n / total - u in
      real arithmetic; the computed x_j is within (3.01 n + 1.02) 2^-53 of X_j (cdf[j] <= total),
      and |(u + i) t_i| <= 3.01 n 2^-53. Both errors together stay below (n + 2) 2^-50, so an x_j
      farther than that from every integer compares with every i as the exact test does: K_j =
      floor(x_j) + 1. The fraction x_j - floor(x_j) is exact for x_j >= 0 and within 2^-54 for
      -1 < x_j < 0 (x_j >= -u), which ``tol``, twice the bound, leaves room for. A tile with no
      x_j that close needs no positions at all.
    * Stratified (the positions carry their own uniforms, so the count is only within one), and a
      systematic tile with an x_j near an integer: the block's positions are computed into ``pos``
      [i0, i1) and each estimate is corrected by exact comparisons with them.

    Scratch: the ancestor row and (the weights are no longer needed) the log-weight row [i0, i1),
    and the block's own estimate tile of marks (one tile's counts, so it stays in L1 instead of a
    row of N_p).
    """
    g = step.g
    cur = work.gstate[0, g]
    src = work.xs[cur, g]
    dst = work.xs[1 - cur, g]
    b = step.b
    i0 = work.bounds[b]
    i1 = work.bounds[b + 1]
    fw = work.fwork
    cdf = fw[F_CDF]
    n = cdf.shape[0]
    u = step.u
    strat = settings.scheme == _STRATIFIED
    ub = fw[F_UNIFORMS, i0:i1]
    with_lam = step.first
    anc = work.iwork[:n]
    pos = fw[F_WEIGHTS]
    kk = work.iwork[n + b * ESTIMATE_TILE:n + (b + 1) * ESTIMATE_TILE]
    n_x = src.shape[1]
    total = cdf[n - 1]
    nb = i1 - i0
    j0 = _search_right(cdf, n, _position(ub[0] if strat else u, i0, n, total))  # where a sequential
    j1 = _search_right(cdf, n, _position(ub[nb - 1] if strat else u, i1 - 1, n, total))  # merge is
    ab = anc[i0:i1]  # the block's outputs from 0: k = i - i0
    pb = pos[i0:i1]
    db = dst[i0:i1]
    for k in range(nb):
        ab[k] = j0
    scale = n / total
    shift = 0.5 if strat else u
    tol = (n + 2) * 2.0 ** -49 if not strat and 1e-250 < total < 1e250 else 1.0  # 1.0: never exact
    have_pos = False
    for s in range(j0, j1, ESTIMATE_TILE):  # here i0 < K_j <= i1 - 1
        e = min(s + ESTIMATE_TILE, j1)
        cs = cdf[s:e]
        ks = kk[:e - s]  # K_j - i0
        near = 0
        for q in range(e - s):
            x = cs[q] * scale - shift
            f = np.floor(x)
            near += np.int64(not (x - f > tol and x - f < 1.0 - tol))
            ks[q] = min(max(np.int64(f) + 1 - i0, 1), nb - 1)
        if near == 0:
            for q in range(e - s):
                ab[_nonneg(ks[q])] = s + q + 1
            continue
        if not have_pos:
            for k in range(nb):
                pb[k] = _position(ub[k] if strat else u, i0 + k, n, total)
            have_pos = True
        for q in range(e - s):
            c = cs[q]
            k = ks[q]
            while k > 1 and pb[k - 1] >= c:
                k -= 1
            while k < nb - 1 and pb[k] < c:
                k += 1
            ab[k] = s + q + 1
    a = j0
    if n_x == 1 and not with_lam:  # the common case, without an inner loop of one iteration
        for k in range(nb):
            a = max(a, ab[k])
            db[k, 0] = src[_nonneg(a), 0]
    else:
        for k in range(nb):
            a = max(a, ab[k])
            for c in range(n_x):
                db[k, c] = src[_nonneg(a), c]
            if with_lam:
                ab[k] = a
    if with_lam and fw.shape[0] > F_LAM:  # ASIR's first stage: its log-likelihoods follow the particles
        # (a loop of its own: the two rows used inside the gather made every loop here slower)
        for k in range(nb):
            fw[F_LAM, i0 + k] = fw[F_LAM_ALL, _nonneg(ab[k])]


@njit(nogil=True)
def gather(idx, i0, i1, src, dst, lam_src, lam_dst, with_lam):
    """dst[i] = src[idx[i]] for i in [i0, i1) (and ``lam_dst[i] = lam_src[idx[i]]`` when
    ``with_lam``): pass C of the particle kernel after an index scheme."""
    n_x = src.shape[1]
    for i in range(i0, i1):
        j = idx[i]
        for c in range(n_x):
            dst[i, c] = src[j, c]
        if with_lam:
            lam_dst[i] = lam_src[j]


#: :class:`~pfbench.resampling.Scheme` -> name of its kernel in this module (None: ``any_scheme``)
KERNELS = {None: "any_scheme", Scheme.SYSTEMATIC: "systematic", Scheme.STRATIFIED: "stratified",
           Scheme.MULTINOMIAL: "multinomial", Scheme.RESIDUAL: "residual",
           Scheme.RESIDUAL_DETERMINISTIC: "residual_deterministic"}


def kernel_name(scheme) -> str:
    """Name of the kernel of a :class:`Scheme` code (None: any scheme)."""
    return KERNELS[None if scheme is None else Scheme(scheme)]


def resample(name: str, weights, rng: np.random.Generator) -> np.ndarray:
    """Public wrapper with the signature of :func:`pfbench.resampling.resample`."""
    from .. import resampling as ref

    code = int(Scheme.parse(name))
    w = np.ascontiguousarray(weights, dtype=np.float64)
    ref._cdf(w)  # validates the weights
    cdf = np.empty_like(w)
    cumsum_into(w, cdf)
    idx = np.empty(w.shape[0], np.int64)
    globals()[kernel_name(code)](code, w, cdf, rng, idx)
    return idx

