"""The numba particle kernel: bootstrap, SIR, SIS and ASIR (and MultiPDF sub-filters) over all steps.

The compiled twin of :func:`pfbench.backends.numpy_backend.run_group`: the same steps, draws in the
same order and floating-point operations for everything that feeds back into the filter. The
``particle`` family's template: :func:`pfbench.backends.kernels.build` runs it per (model class,
scheme, tile layout) with the model bound to ``_transition``, ``_log_likelihood`` and the scheme to
``_resample``/``_SCHEME``. The caller draws the initial particles (the model's ``initial``).

Fused passes per step and filter (each particle is touched three times):
A. draw + propagate + log-likelihood + a = lw + ll + running max, in tiles of ``_TILE`` particles
   (:func:`_pass_a`: the model's vectorised functions on a tile view, the draws one big draw gives);
B. w = exp(a - max) over the log-weights, the running sum (cdf), moments and sum w^2
   (:func:`pfbench.backends.numba_weights.block_weights`);
C. the schemes of :data:`pfbench.resampling.MERGED` (systematic, stratified): a merge straight into
   the other particle buffer (:func:`pfbench.backends.numba_resampling.merge_gather`); every other
   scheme: its kernel's indices, then a gather;
D. ``estimate="post"``, at a step that resampled: the unweighted moments replace ``est``/``var``
   ([MultiPDF] Alg. 1 step 6; :func:`pfbench.backends.numba_weights.block_moments`).

Loops over a block or a tile run over views that start at 0 (``la[s:e]``, then ``las[i]``), so
LLVM can drop numba's negative-index test. Only pass A inlines the model, and a model's schemes share
it (:attr:`pfbench.backends.kernels.Family.shared`); passes B and C serve every model and scheme. The
driver (steps, filters, blocks) calls the passes by address (:mod:`pfbench.backends.native_call`), so
it does not compile them again.

Stream blocks (:mod:`pfbench.backends.numpy_backend`): per-block results are reduced in block order,
so :func:`run_group` and :func:`run_group_parallel` (the same function compiled with
``parallel=True``, its block loops ``prange``) agree bit for bit for any thread count.

float32 particles: float32 buffers and draws (stored exactly in the float64 tiles the model gets);
the model computes in float64 and its results are rounded when stored; weights and moments stay
float64. Not float32 arithmetic: numba types the models' float literals and float64 parameters as
float64 whatever the array dtype, where NumPy >= 2 keeps float32, so the backends would differ.
"""
import numba as _numba
import numpy as _np
from numba.extending import overload as _overload
from numba.extending import register_jitable as _register_jitable
from numba.extending import intrinsic as _intrinsic
from numba.core import types as _types
from numba.core.imputils import impl_ret_borrowed as _impl_ret_borrowed

from pfbench.backends import pcg64 as _pcg64
from pfbench.backends.kernels import binding as _binding
from pfbench.backends.kernels import twin as _twin
from pfbench.backends.native_call import caller as _caller
from pfbench.backends.numba_resampling import cumsum_into as _cumsum_into
from pfbench.backends.numba_resampling import gather as _gather
from pfbench.backends.numba_resampling import merge_gather as _merge_gather
from pfbench.backends.numba_weights import block_moments as _block_moments
from pfbench.backends.particle_work import Step as _Step
from pfbench.backends.particle_work import B_INVALID as _B_INVALID, B_MAX as _B_MAX, B_OFFSET as _B_OFFSET
from pfbench.backends.particle_work import B_SUM as _B_SUM, B_SUM_SQ as _B_SUM_SQ, F_CDF as _F_CDF, F_LAM as _F_LAM
from pfbench.backends.particle_work import F_LAM_ALL as _F_LAM_ALL, F_UNIFORMS as _F_UNIFORMS
from pfbench.backends.particle_work import F_WEIGHTS as _F_WEIGHTS
from pfbench.backends.numba_weights import block_weights as _pass_b
from pfbench.backends.numba_weights import normalised_log_weights as _normalised_log_weights
from pfbench.backends.numba_weights import valid_log_likelihood as _valid
from pfbench.methods import Method as _Method
from pfbench.models.contract import RESHAPED as _RESHAPED
from pfbench.resampling import Scheme as _Scheme

_ASIR = int(_Method.ASIR)
_BOOTSTRAP = int(_Method.BOOTSTRAP)
_SIR = int(_Method.SIR)
_SYSTEMATIC = int(_Scheme.SYSTEMATIC)  # the schemes the merge serves (pfbench.resampling.MERGED),
_STRATIFIED = int(_Scheme.STRATIFIED)  # compared one by one below, so a scheme's kernel drops the other branch
#: particles per tile of the fused pass A: its noise, states and likelihoods stay in L1/L2; the model's arrays cost once per tile
_TILE = 1024
#: a model's array of another shape than in the check: refused (rows are read/stored by index)
_RESHAPED_TRANSITION = "transition" + _RESHAPED
_RESHAPED_LOG_LIKELIHOOD = "log_likelihood" + _RESHAPED
_prange = _numba.prange
#: passes A, B and C called through their addresses (:mod:`pfbench.backends.native_call`)
_call_a = _caller(7)
_call_b = _caller(2)
_call_c = _caller(3)

# ---- what :func:`pfbench.backends.kernels.build` binds for a model and a scheme
_b = _binding()
_njit = _b.jit
_transition = _b.model("transition")
_log_likelihood = _b.model("log_likelihood")
_resample = _b.resample
#: the resampling scheme code (-1: chosen at run time, ``_resample`` is ``any_scheme``)
_SCHEME = _b.scheme
#: the model's tiles are typed column-major (:func:`_column_major`; one state, one noise component)
_F_TILES = _b.f_tiles


def _normals(rng, k, n_noise, like):  # pragma: no cover - compiled through the overload below
    return rng.standard_normal((k, n_noise), dtype=like.dtype).astype(_np.float64)


@_overload(_normals)
def _normals_impl(rng, k, n_noise, like):
    """(k, n_noise) standard normals drawn in the particle dtype, as ``rng.standard_normal`` gives
    them, in a float64 array for the model (float32 draws are exact in float64)."""
    fill = _pcg64.fill_normals_f32 if like.dtype == _numba.types.float32 else _pcg64.fill_normals

    def impl(rng, k, n_noise, like):
        out = _np.empty((k, n_noise))
        fill(rng, out)
        return out
    return impl


@_intrinsic
def _column_major(typingctx, a):
    """The same (n, 1) C-contiguous array typed column-major ('F'); no copy. numba lowers an array
    expression over a C array with the trailing axis (length 1) innermost, and LLVM vectorises inner
    loops only; typed 'F', the rows are the inner loop. Only valid for a trailing axis of length 1."""
    if not isinstance(a, _types.Array) or a.ndim != 2 or a.layout != "C":
        return None
    ret = a.copy(layout="F")

    def codegen(context, builder, signature, args):
        return _impl_ret_borrowed(context, builder, signature.return_type, args[0])

    return ret(a), codegen


def _tile_buffer(xs, k):  # pragma: no cover - compiled through the overload below
    return _np.empty((min(k, _TILE), xs.shape[1]))


@_overload(_tile_buffer)
def _tile_buffer_impl(xs, k):
    """A float64 (tile, n_x) buffer for the model's tiles (float32 particles), once per pass; ``xs`` for float64."""
    if xs.dtype == _numba.types.float64:
        return lambda xs, k: xs
    return lambda xs, k: _np.empty((min(k, _TILE), xs.shape[1]))


def _tile64(xs, s, e, buf):  # pragma: no cover - compiled through the overload below
    return xs[s:e].astype(_np.float64)


@_overload(_tile64)
def _tile64_impl(xs, s, e, buf):
    """The states of particles [s, e) as float64: a view of ``xs``, or (float32) converted into ``buf``."""
    if xs.dtype == _numba.types.float64:
        return lambda xs, s, e, buf: xs[s:e]

    def impl(xs, s, e, buf):
        k = (e - s) * xs.shape[1]
        src = xs[s:e].reshape(k)  # one flat loop (vectorised), whatever n_x
        dst = buf[:e - s].reshape(k)
        for i in range(k):
            dst[i] = src[i]
        return buf[:e - s]
    return impl


def _typed_as_tiles(a):  # pragma: no cover - compiled through the overload below
    return a


@_overload(_typed_as_tiles)
def _typed_as_tiles_impl(a):
    """A float32-path buffer typed as the tiles (column-major when ``_F_TILES``): one array type for the model."""
    if _F_TILES:
        return lambda a: _column_major(a)
    return lambda a: a


def _store(xd, xn, buf):  # pragma: no cover - compiled through the overload below
    xd[:] = xn
    return xd.astype(_np.float64)


@_overload(_store)
def _store_impl(xd, xn, buf):
    """Store the new states ``xn`` into ``xd`` (the tile's particles) and return them as stored, in
    float64: ``xn`` itself, or (float32) rounded into ``buf``, typed as :func:`_unstored` returns."""
    if xd.dtype == _numba.types.float64:
        def impl(xd, xn, buf):
            if xd.shape[1] == 1:  # no inner loop of one iteration
                for i in range(xn.shape[0]):
                    xd[i, 0] = xn[i, 0]
            else:
                for i in range(xn.shape[0]):
                    for c in range(xd.shape[1]):
                        xd[i, c] = xn[i, c]
            return xn
        return impl

    def impl32(xd, xn, buf):
        k = xn.shape[0]
        dst = xd.reshape(k * xd.shape[1])
        back = buf[:k].reshape(k * xd.shape[1])
        if xd.shape[1] == 1:  # one flat loop (vectorised)
            for i in range(k):
                v = _np.float32(xn[i, 0])
                dst[i] = v
                back[i] = v
        else:
            for i in range(k):
                for c in range(xd.shape[1]):
                    v = _np.float32(xn[i, c])
                    dst[i * xd.shape[1] + c] = v
                    back[i * xd.shape[1] + c] = v
        return _typed_as_tiles(buf[:k])
    return impl32


def _unstored(xs, xn, buf):  # pragma: no cover - compiled through the overload below
    return xn


@_overload(_unstored)
def _unstored_impl(xs, xn, buf):
    """ASIR's first stage: the new states, not stored, typed as :func:`_store` returns them (float32:
    copied unrounded into ``buf``)."""
    if xs.dtype == _numba.types.float64:
        return lambda xs, xn, buf: xn

    def impl32(xs, xn, buf):
        k = xn.shape[0]
        for i in range(k):
            for c in range(xn.shape[1]):
                buf[i, c] = xn[i, c]
        return _typed_as_tiles(buf[:k])
    return impl32


@_njit(nogil=True, no_cpython_wrapper=True)
def _pass_a(p, brng, y, u, work, settings, step):
    """Pass A on stream block ``step.b`` of filter ``step.g`` at step ``step.t``: draw + propagate +
    log-likelihood + a = lw + ll into the log-weight row; returns max a. ``step.first`` (ASIR's first
    stage): zero noise, states not stored, log-likelihoods into ``lam_all``; ``step.asir``: ll - lam."""
    t = step.t
    g = step.g
    yt = y[t]
    ut = u[t]
    xs = work.xs[work.gstate[0, g], g]
    i0 = work.bounds[step.b]
    i1 = work.bounds[step.b + 1]
    n_noise = settings.n_noise
    lw = work.lw[g]
    flat = work.gstate[1, g] == 1
    mlogn = -_np.log(xs.shape[0])
    first = step.first
    asir = step.asir
    fw = work.fwork
    la = fw[_F_WEIGHTS]
    lam = fw[_F_LAM] if fw.shape[0] > _F_LAM else la
    lam_out = fw[_F_LAM_ALL] if fw.shape[0] > _F_LAM else la
    m = -_np.inf
    bad = 0
    bin_ = _tile_buffer(xs, i1 - i0)  # float32: the model's input and the stored states, in float64
    bout = _tile_buffer(xs, i1 - i0)
    for s in range(i0, i1, _TILE):
        e = min(s + _TILE, i1)
        k = e - s
        if first:
            noise = _np.empty((k, n_noise))
            for i in range(k):
                for c in range(n_noise):
                    noise[i, c] = 0.0
        else:
            noise = _normals(brng, k, n_noise, xs)
        if _F_TILES:  # a compile-time constant: numba prunes the other branch
            xn = _transition(_column_major(_tile64(xs, s, e, bin_)), ut, t, _column_major(noise), p)
        else:
            xn = _transition(_tile64(xs, s, e, bin_), ut, t, noise, p)
        if xn.shape[0] != k or xn.shape[1] != xs.shape[1]:
            raise ValueError(_RESHAPED_TRANSITION)
        # one type in both branches, so one likelihood call site (each is an inlined copy of the
        # model), and no any-layout array that a reassigned ``xn`` would unify to
        if first:
            xl = _unstored(xs, xn, bout)
        else:
            xl = _store(xs[s:e], xn, bout)
        ll = _log_likelihood(yt, xl, ut, t, p)
        if ll.shape[0] != k:
            raise ValueError(_RESHAPED_LOG_LIKELIHOOD)
        for i in range(k):  # NaN or +inf: the model's trouble, counted (weight zero)
            bad += not (ll[i] < _np.inf)
        las = la[s:e]  # the tile's rows as views from 0: no negative-index wraparound in the loops
        lws = lw[s:e]
        if first or asir:
            lams = lam[s:e]
            louts = lam_out[s:e]
            for i in range(k):
                v = _valid(_np.float64(ll[i]))
                if asir and v > -_np.inf:
                    v = _valid(v - lams[i])
                if first:
                    louts[i] = v
                las[i] = mlogn + v if flat else lws[i] + v
        elif flat:  # the bootstrap step: branch-free loops that vectorise
            for i in range(k):
                las[i] = mlogn + _valid(_np.float64(ll[i]))
        else:
            for i in range(k):
                las[i] = lws[i] + _valid(_np.float64(ll[i]))
        m = _max(las, m)
    work.bwork[_B_INVALID, step.b] = bad
    return m


_pass_a = _b.shared("_pass_a", _pass_a)  # compiled once per model, for every scheme


@_register_jitable
def _moments(work, out, total, g, t):
    """est[g, t] and var[g, t] from the per-block sums of w x and w (x - x_0)^2 (x_0: the filter's
    particle 0), added in block order, over ``total``."""
    xs = work.xs[work.gstate[0, g], g]
    bsx, bsxx = work.bmom[0], work.bmom[1]
    nb = work.bounds.shape[0] - 1
    for c in range(xs.shape[1]):
        sx = 0.0
        sxx = 0.0
        for b in range(nb):
            sx += bsx[b, c]
            sxx += bsxx[b, c]
        mean = sx / total
        d = mean - _np.float64(xs[0, c])
        out.est[g, t, c] = mean
        out.var[g, t, c] = max(sxx / total - d * d, 0.0)


@_register_jitable
def _max(a, m):
    """max(m, max(a)) for ``a`` without NaN, in four running maxima that do not wait on each other."""
    m0 = m
    m1 = m
    m2 = m
    m3 = m
    n = a.shape[0]
    i = 0
    while i + 4 <= n:
        v0 = a[i]
        v1 = a[i + 1]
        v2 = a[i + 2]
        v3 = a[i + 3]
        m0 = v0 if v0 > m0 else m0
        m1 = v1 if v1 > m1 else m1
        m2 = v2 if v2 > m2 else m2
        m3 = v3 if v3 > m3 else m3
        i += 4
    while i < n:
        v0 = a[i]
        m0 = v0 if v0 > m0 else m0
        i += 1
    m0 = m1 if m1 > m0 else m0
    m2 = m3 if m3 > m2 else m2
    return m2 if m2 > m0 else m0


def _run_group(p, rng, brngs, y, u, out, work, settings):
    """Run a group of G independent filters over all steps (random streams in the documented order).

    ``rng``: the group's generator; ``brngs``: the B block generators (``[rng]`` when B = 1); ``out``,
    ``work`` (the initial particles in the first buffer), ``settings``: the groups of
    :mod:`pfbench.backends.particle_work`. ``settings.post`` is a run-time flag, so one compilation
    serves both estimates and the default tests it only at the steps that resample.
    """
    x = out.x
    G = x.shape[0]
    n = x.shape[1]
    n_x = x.shape[2]
    M = y.shape[0]
    bounds = work.bounds
    nb = bounds.shape[0] - 1
    method = settings.method
    scheme = settings.scheme
    mlogn = -_np.log(n)
    cur = work.gstate[0]
    flat = work.gstate[1]  # 1: every log-weight is -log n (after resampling), so lw is not read yet
    for g in range(G):
        flat[g] = 1
        cur[g] = 0
    # la: the log-weights, then (pass B, in place) the weights, then the merge's scratch; ub: the
    # stratified uniforms; ASIR's two lambda rows exist only for ASIR (nothing else touches them)
    fw = work.fwork
    ub, cdf, la = fw[_F_UNIFORMS], fw[_F_CDF], fw[_F_WEIGHTS]
    lam = fw[_F_LAM] if fw.shape[0] > _F_LAM else la
    lam_all = fw[_F_LAM_ALL] if fw.shape[0] > _F_LAM else la
    idx = work.iwork[:n]
    bmax, bsum, bs2, off = work.bwork[_B_MAX], work.bwork[_B_SUM], work.bwork[_B_SUM_SQ], work.bwork[_B_OFFSET]
    if method == _ASIR:
        for i in range(n):
            lam[i] = 0.0
    for t in range(M):
        for g in range(G):
            lwg = work.lw[g]
            first = 0.0
            for stage in range(2 if method == _ASIR else 1):
                fs = method == _ASIR and stage == 0  # first stage, [Thesis] Alg. 6
                src = work.xs[cur[g], g]
                for b in _prange(nb):  # pass A through its address: not compiled into the driver
                    bmax[b] = _call_a(_pass_a, settings.pass_a, p, brngs[b], y, u, work, settings,
                                      _Step(t, g, _np.int64(b), fs, method == _ASIR and not fs, 0.0, 0.0))
                m = -_np.inf
                for b in range(nb):
                    out.invalid[g, t] += work.bwork[_B_INVALID, b]  # the model's NaN or +inf log-likelihoods
                    if bmax[b] > m:
                        m = bmax[b]
                deg = not (m > -_np.inf)
                if deg:  # every likelihood zero: keep the previous weights
                    for i in range(n):
                        la[i] = mlogn if flat[g] == 1 else lwg[i]
                        if la[i] > m:
                            m = la[i]
                for b in _prange(nb):
                    _call_b(_pass_b, settings.pass_b, work, _Step(t, g, _np.int64(b), fs, False, m, 0.0))
                total = 0.0
                for b in range(nb):
                    off[b] = total
                    total += bsum[b]
                if nb > 1:
                    for b in _prange(nb):
                        cb = cdf[bounds[b]:bounds[b + 1]]
                        for i in range(cb.shape[0]):
                            cb[i] += off[b]
                if fs:
                    first = m + _np.log(total)
                    if deg:
                        for i in range(n):
                            lam_all[i] = 0.0
                    do = True
                else:
                    if out.hist_x.shape[1] > 0:
                        for i in range(n):
                            out.hist_w[g, t, i] = la[i] / total
                            for c in range(n_x):
                                out.hist_x[g, t, i, c] = src[i, c]
                    out.degen[g, t] = deg
                    out.inc[g, t] = (-_np.inf if deg else m + _np.log(total)) + first
                    s2 = 0.0
                    for b in range(nb):
                        s2 += bs2[b]
                    _moments(work, out, total, g, t)
                    e = total * total / s2
                    out.ess[g, t] = e
                    do = method == _BOOTSTRAP or (method == _SIR and e < settings.ess_threshold)
                    out.resampled[g, t] = do
                if do:
                    dst = work.xs[1 - cur[g], g]
                    if (_SCHEME == _SYSTEMATIC or _SCHEME == _STRATIFIED  # pruned at compile time
                            or (_SCHEME == -1 and (scheme == _SYSTEMATIC or scheme == _STRATIFIED))):
                        strat = scheme == _STRATIFIED
                        uu = 0.0
                        if not strat:
                            _pcg64.fill_uniforms(rng, ub[:1])
                            uu = ub[0]
                        for b in _prange(nb):
                            if strat:
                                _pcg64.fill_uniforms(brngs[b], ub[bounds[b]:bounds[b + 1]])
                            _call_c(_merge_gather, settings.merge, work, settings,
                                    _Step(t, g, _np.int64(b), fs, False, m, uu))
                    else:
                        if nb > 1:  # the index schemes see the sequential running sum
                            _cumsum_into(la, cdf)
                        _resample(scheme, la, cdf, rng, idx)
                        for b in _prange(nb):
                            _gather(idx, bounds[b], bounds[b + 1], src, dst, lam_all, lam, fs)
                    cur[g] = 1 - cur[g]
                    flat[g] = 1
                    if settings.post and not fs:  # estimate="post" ([MultiPDF] Alg. 1 step 6): pass D
                        for b in _prange(nb):
                            _block_moments(work, _Step(t, g, _np.int64(b), fs, False, m, 0.0))
                        _moments(work, out, _np.float64(n), g, t)
                elif not fs:
                    _normalised_log_weights(la, total, lwg)
                    flat[g] = 0
    for g in range(G):  # the final particles, block by block (on every thread: 16 MB at N_p = 10^6)
        fin = work.xs[cur[g], g]
        xg = x[g]
        for b in _prange(nb):
            xb = xg[bounds[b]:bounds[b + 1]]
            fb = fin[bounds[b]:bounds[b + 1]]
            for i in range(xb.shape[0]):
                for c in range(n_x):
                    xb[i, c] = fb[i, c]


#: the serial compilation (MultiPDF thread pools, small N_p, ``n_threads=1``)
run_group = _njit(nogil=True)(_twin(_run_group, "run_group"))
#: the same function with its block loops over all numba threads (compiled on first use)
run_group_parallel = _njit(nogil=True, parallel=True)(_twin(_run_group, "run_group_parallel"))
