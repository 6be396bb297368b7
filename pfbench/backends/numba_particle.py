"""The numba particle kernel: bootstrap, SIR, SIS and ASIR (and MultiPDF sub-filters) over all steps.

This is the compiled twin of :func:`pfbench.backends.numpy_backend.run_group`: the same steps, the
same random draws in the same order, the same floating-point operations for everything that feeds
back into the filter. It calls the model through two module globals, ``_transition`` and
``_log_likelihood`` (the initial particles come in ``x``, drawn by the caller with the model's
``initial``, as the NumPy backend draws them). As a file it is importable (they are placeholders here);
:func:`pfbench.backends.numba_backend.kernel_module` writes a copy of it per (model class,
resampling scheme) with the model's compiled functions bound to those names and the scheme bound to
``_resample``/``_SCHEME`` at the end, so numba caches the whole kernel, model inlined, on disk.

Fused passes (per step and filter; each particle is touched three times)
-------------------------------------------------------------------------
A. draw noise + propagate + log-likelihood + a = lw + ll + running max, in tiles of ``_TILE``
   particles (the model's vectorised ``transition``/``log_likelihood`` run on a tile view, so a
   model is still written once; tile-by-tile draws are the numbers one big draw gives); the
   log-weights of the common (bootstrap) step are a branch-free loop and the max keeps four
   running maxima (:func:`_max`);
B. w = exp(a - max) in place of the log-weights (a vectorised loop of its own), then the running
   sum (the cdf) with the weighted sums for the mean, the shifted second moment (shift: the
   filter's particle 0, so the one-pass variance does not cancel) and sum w^2 (N_eff) riding
   beside it, in registers (:func:`pfbench.backends.numba_weights.block_weights`);
C. resampling: systematic and stratified as a merge that writes the resampled particles straight
   into the second particle buffer (the buffers swap; no index array, no copy back;
   :func:`pfbench.backends.numba_resampling.merge_gather`); multinomial and residual draw indices
   (``_resample``) and gather.
D. ``estimate="post"`` only, at a step that resampled: the unweighted sums of the resampled
   particles per block (:func:`pfbench.backends.numba_weights.block_moments`), reduced in block
   order as pass B's sums are, replace the step's ``est``/``var`` ([MultiPDF] Alg. 1 step 6). A
   fourth touch of the particles that the default ``pre`` never makes.

Every loop over a block or a tile runs over views that start at 0 (``la[s:e]``, then
``las[i]``), not over ``range(s, e)`` on the whole array: numba gives a negative index its
Python meaning (counted from the end), and only for an index LLVM can prove non-negative does it
drop that test. Indexed from a run-time start, the exponential loop of pass B compiled to AVX-512
gathers and scatters, and every other access carried three more instructions (measured on Ob1,
N_p = 1000: 19.3 ns per particle-step with the run-time starts, 15.2 ns with the views). Indices
read from memory (ancestors) are made unsigned where they are known to be >= 0, for the same
reason. LLVM's x86 cmov-to-branch conversion is off (:mod:`pfbench.backends.codegen`): it turned
the merge's running maximum into a data-dependent branch (15.2 ns with it, 12.6 ns without).

What is compiled where. Passes B and C do not call the model: they live in ordinary cached modules
and are compiled once per process (and loaded from disk after that) for every model and scheme.
Pass A inlines the model; it does not depend on the scheme, so a scheme's module binds the
``_pass_a`` of the model's any-scheme module (``SCHEME_FREE`` in
:mod:`pfbench.backends.numba_backend`), and the schemes of a model share one compilation of it.
The driver calls all three passes through their native entry points
(:mod:`pfbench.backends.native_call`), so numba does not compile them (and the model) into the
driver again: the driver is the loop over steps, filters and blocks. A cold kernel compiles pass
A in a helper process on a second core meanwhile (:mod:`pfbench.backends.compile_helper`), passes
B and C here after the driver. Measured (Ob1, fresh caches, one process): the driver 3.8 s with
passes B and C compiled into it, 1.9 s without (so 1.9 s less for every further model or scheme
once B and C are on disk); at run time 12.4-12.8 vs 12.2-12.6 ns per particle-step (N_p = 1000,
marginal cost of 2000 steps), the same within the noise.

Stream blocks and threads
-------------------------
Particles are split into stream blocks ``[bounds[b], bounds[b + 1])`` of equal size
(:func:`pfbench.backends.numpy_backend.block_bounds`: one block up to N_p = ``BLOCK`` = 8192, else
a multiple of 16 blocks, so 2, 4, 8 or 16 threads get equal shares). With one block everything is
drawn from the filter's own generator in the single-stream order (bit-identical to the unblocked
kernel). With B > 1 blocks, block b draws its
transition noise (and stratified uniforms for its output positions) from its own generator
``brngs[b]`` (which first gave block b's initial particles,
:func:`pfbench.backends.numpy_backend.draw_initial`); systematic's one uniform and the
multinomial/residual draws come from the filter's generator. Per-block partial results (max, weight sum, moments) are reduced in
block order by one thread, and the cdf of block b is ``offset_b + running sum within b``, so the
numbers depend on (seed, N_p, block layout) only. :func:`run_group` is the serial compilation,
:func:`run_group_parallel` the same Python function compiled with ``parallel=True`` (its block
loops are ``prange``): bit-identical results for any thread count.

float32
-------
With float32 particles the noise is drawn as float32 (``standard_normal(..., dtype=float32)``, the
float32 ziggurat, inlined like the float64 one, stored exactly in the float64 tile the model gets)
and the particle buffers are float32; the model functions see float64 tiles (the stored, rounded
states, converted into a buffer allocated once per pass) and their results are rounded to float32
when stored, the rounded values kept in float64 for the log-likelihood in the same loop; weights,
log-likelihood sums and moments stay float64. Why not float32 arithmetic: the models are written
with Python float literals (``0.5 * x``) and float64 parameters, which numba types as float64
whatever the array dtype (measured: ``float32 array * 0.5`` is a float64 array in numba, float32
in NumPy >= 2), so a float32 model evaluation would differ between the backends and gain nothing
inside numba; computing in float64 and storing float32 keeps the backends in agreement. What
float32 then buys is half the particle memory and a float32 draw; what it costs is the tile
conversions. Measured (``pfbench bench``'s float32 vs float64 kernel parts, Ob1 bootstrap, 1
thread, N_p = 10^5, paired per round, 2-core AVX-512 Xeon): draws 3.6 vs 3.7 ns (the ziggurat's
table lookups and rejection test cost the same in both widths, and the 128-bit PCG64 step that
float32 halves is not the bottleneck), tile in/out 0.4 vs 0.7, model 2.8 vs 2.6, pass B 2.8 vs
3.1 (the moments convert the stored states), whole filter 12.9 vs 13.9 ns per particle-step
(0.93x: the faster the float64 kernel, the more the conversions weigh; 1.04x when it took 22 ns).
The step is bound by arithmetic and branches, not by memory (10^5 float64 particles are 0.8 MB,
cache-resident), so halving storage cannot pay more until the models are written dtype-generic
(float32 literals), as the Cortex-M compiler already does for ``--precision float``
(:mod:`pfbench.mcu.modelcode`). Even then the backends would part: numba's float32 ``exp`` and
``cos`` are LLVM's, NumPy's its own SIMD routines, and on 10^6 inputs (uniform in [-20, 5]) they
differ in 39 % of the ``exp`` results (up to 2 ulp) and 17 % of the ``cos`` results (1 ulp),
where float64 ``cos`` agrees on all of them (the weights' float64 ``exp``, which differs in 5 %,
is the engine's own :mod:`pfbench.backends.fastexp` in both backends). A differing ulp can move a
resampling decision, after which the two runs draw different particles.
"""
import numba as _numba
import numpy as _np
from numba.extending import overload as _overload
from numba.extending import register_jitable as _register_jitable
from numba.extending import intrinsic as _intrinsic
from numba.core import types as _types
from numba.core.imputils import impl_ret_borrowed as _impl_ret_borrowed

from pfbench.backends import pcg64 as _pcg64
from pfbench.backends.cache import njit as _njit
from pfbench.backends.native_call import caller as _caller
from pfbench.backends.numba_resampling import cumsum_into as _cumsum_into
from pfbench.backends.numba_resampling import gather as _gather
from pfbench.backends.numba_resampling import merge_gather as _merge_gather
from pfbench.backends.numba_resampling import ESTIMATE_TILE as _ESTIMATE_TILE
from pfbench.backends.numba_weights import block_moments as _block_moments
from pfbench.backends.numba_weights import block_weights as _pass_b
from pfbench.backends.numba_weights import normalised_log_weights as _normalised_log_weights
from pfbench.backends.numba_weights import valid_log_likelihood as _valid
from pfbench.filters.methods import Method as _Method
from pfbench.resampling import Scheme as _Scheme

_ASIR = int(_Method.ASIR)
_BOOTSTRAP = int(_Method.BOOTSTRAP)
_SIR = int(_Method.SIR)
_SYSTEMATIC = int(_Scheme.SYSTEMATIC)  # the schemes the merge serves
_STRATIFIED = int(_Scheme.STRATIFIED)
#: particles per tile of the fused pass A (the tile's noise, new states and likelihoods stay in L1/L2).
#: Each tile allocates the model's result arrays (and frees them), a fixed cost per tile: measured
#: on Ob1, 1 thread, N_p = 1000, marginal cost of 2000 steps, 12.2 ns per particle-step with tiles
#: of 512, 11.8-11.9 with 1024; 2048 and 4096 within the noise of 1024 (8 KB per float64 column)
_TILE = 1024
#: resampling scheme code bound by kernel_module (-1: chosen at run time through ``_resample``)
_SCHEME = -1
#: bound by kernel_module: True when the model has one state and one noise component, whose tiles
#: are handed to the model typed column-major (:func:`_column_major`)
_F_TILES = False
_prange = _numba.prange
#: pass A called through its address (:mod:`pfbench.backends.native_call`)
_call_a = _caller(17)
#: passes B and C (systematic/stratified) called through their addresses
_call_b = _caller(12)
_call_c = _caller(15)


def _transition(x, u, t, noise, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _log_likelihood(y, x, u, t, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _resample(code, w, cdf, rng, idx):  # pragma: no cover - bound per run by kernel_module
    raise NotImplementedError("bound per scheme by pfbench.backends.numba_backend.kernel_module")


def _normals(rng, k, n_noise, like):  # pragma: no cover - compiled through the overload below
    return rng.standard_normal((k, n_noise), dtype=like.dtype).astype(_np.float64)


@_overload(_normals)
def _normals_impl(rng, k, n_noise, like):
    """(k, n_noise) standard normals drawn in the particle dtype (float32: NumPy's float32
    ziggurat), the numbers ``rng.standard_normal`` gives, as a float64 array for the model
    (:func:`pfbench.backends.pcg64.fill_normals`; float32 draws are stored exactly in float64, so
    there is no float32 array to convert)."""
    fill = _pcg64.fill_normals_f32 if like.dtype == _numba.types.float32 else _pcg64.fill_normals

    def impl(rng, k, n_noise, like):
        out = _np.empty((k, n_noise))
        fill(rng, out)
        return out
    return impl


@_intrinsic
def _column_major(typingctx, a):
    """The same (n, 1) C-contiguous array typed column-major ('F'); no copy.

    An (n, 1) contiguous array is both row- and column-major, but numba lowers an array expression
    over a C array as two nested loops with the trailing axis (length 1) innermost, and LLVM
    vectorises inner loops only: the model's arithmetic then runs one particle at a time (Ob1's
    transition: 2.2 ns per particle on (512, 1) C tiles, 0.6 ns on the same memory typed 'F', same
    bits). Typed 'F', the rows are the inner loop. Only valid for a trailing axis of length 1.
    """
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
    """float32 particles: a float64 (tile, n_x) buffer for the tiles the model sees, allocated once
    per pass. float64 particles need none (the model sees the particle buffer itself): ``xs``."""
    if xs.dtype == _numba.types.float64:
        return lambda xs, k: xs
    return lambda xs, k: _np.empty((min(k, _TILE), xs.shape[1]))


def _tile64(xs, s, e, buf):  # pragma: no cover - compiled through the overload below
    return xs[s:e].astype(_np.float64)


@_overload(_tile64)
def _tile64_impl(xs, s, e, buf):
    """The states of particles [s, e) as float64 for the model: a view of ``xs`` (float64), or
    converted into ``buf`` (float32)."""
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
    """A C-contiguous float32-path buffer typed as the kernel types its tiles: column-major
    (:func:`_column_major`) when ``_F_TILES``, so the model sees one array type."""
    if _F_TILES:
        return lambda a: _column_major(a)
    return lambda a: a


def _store(xd, xn, buf):  # pragma: no cover - compiled through the overload below
    xd[:] = xn
    return xd.astype(_np.float64)


@_overload(_store)
def _store_impl(xd, xn, buf):
    """Store the new states ``xn`` into ``xd`` (the tile's particles, a view) and return them as
    stored, in float64, for the log-likelihood: ``xn`` itself (float64), or rounded to float32 and
    back into ``buf`` (typed as the tiles, so it has the type :func:`_unstored` gives: one
    likelihood call site)."""
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
    """ASIR's first stage: the new states, not stored, for the log-likelihood, with the type
    :func:`_store` returns: ``xn`` (float64 particles), or copied unrounded into ``buf`` (float32)."""
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
def _pass_a(p, brng, yt, ut, t, xs, i0, i1, n_noise, lw, flat, mlogn, first, lam, asir, lam_out, la):
    """Pass A on particles [i0, i1): draw + propagate + log-likelihood + a = lw + ll; returns max a.

    ``first`` (ASIR first stage): zero noise, the states are not stored and the cleaned
    log-likelihoods go to ``lam_out``; ``asir`` (second stage): ll - lam. ``flat``: every lw is
    -log n (after resampling), so it is not read.
    """
    m = -_np.inf
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
        # one type in both branches (a float32 buffer typed as the tiles), so one likelihood call
        # site: a reassigned ``xn`` would unify the model's output and the buffer to an any-layout
        # array, which nothing vectorises, and every call site is another inlined copy to compile
        if first:
            xl = _unstored(xs, xn, bout)
        else:
            xl = _store(xs[s:e], xn, bout)
        ll = _log_likelihood(yt, xl, ut, t, p)
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
    return m


@_register_jitable
def _moments(bsx, bsxx, nb, total, xs, est, var, g, t):
    """est[g, t] and var[g, t] from the per-block sums of w x and w (x - x_0)^2 (x_0 = ``xs[0]``,
    the shift the blocks used), added in block order, over the total weight ``total``."""
    for c in range(xs.shape[1]):
        sx = 0.0
        sxx = 0.0
        for b in range(nb):
            sx += bsx[b, c]
            sxx += bsxx[b, c]
        mean = sx / total
        d = mean - _np.float64(xs[0, c])
        est[g, t, c] = mean
        var[g, t, c] = max(sxx / total - d * d, 0.0)


@_register_jitable
def _max(a, m):
    """max(m, max(a)) for ``a`` without NaN: four running maxima, so the comparisons do not wait
    on each other (a max is exact in any order; LLVM does not vectorise the reduction itself)."""
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


def _run_group(p, rng, brngs, y, u, x, n_noise, method, scheme, ess_threshold, bounds, est, var, ess, inc,
               resampled, degen, hist_x, hist_w, xs, lw, fwork, iwork, bwork, bmom, gstate, post, pass_a_address,
               pass_b_address, merge_address):
    """Run a group of G independent filters over all steps (random streams in documented order).

    x: (G, n, n_x) particle buffer (its dtype is the particle dtype) that receives the final
    particles; the initial particles (the model's ``initial``, drawn by the caller:
    :func:`pfbench.backends.numpy_backend.draw_initial`) come in the first of the two buffers ``xs[0]``; outputs (G, M, ...).
    rng: the group's generator; brngs: a list of the B block generators (``[rng]`` when B = 1);
    bounds: (B + 1,) block starts, then n. hist_x (G, M, n, n_x), hist_w (G, M, n): the weighted
    particles of every step (before resampling) when their second dimension
    is M; pass (G, 0, ...) arrays to store nothing. method: a
    :class:`~pfbench.filters.methods.Method` code of the particle family (MultiPDF runs bootstrap
    sub-filters); scheme: a :class:`~pfbench.resampling.Scheme` code; ess_threshold: a particle
    count. xs ... gstate: work arrays (:func:`pfbench.backends.numba_backend.work_arrays`), allocated
    by the caller because every array constructor compiled here is another 0.1 s of a cold start.
    post: ``estimate="post"``: at a step that resamples, ``est``/``var`` are overwritten with the
    unweighted moments of the resampled particles (pass D); a run-time flag, so one compilation
    serves both and the default path only tests it at the steps that resample.
    pass_a_address, pass_b_address, merge_address: the native entry points of ``_pass_a``,
    ``_pass_b`` and ``_merge_gather`` for the argument types of their calls here
    (:func:`pfbench.backends.numba_backend.pass_a_types`, ``pass_b_types``, ``merge_types``;
    :mod:`pfbench.backends.native_call`): the driver calls the passes without compiling them into
    itself again.
    """
    G = x.shape[0]
    n = x.shape[1]
    n_x = x.shape[2]
    M = y.shape[0]
    nb = bounds.shape[0] - 1
    logn = _np.log(n)
    mlogn = -logn
    cur = gstate[0]
    flat = gstate[1]  # 1: every log-weight is -log n (after resampling), so lw is not read yet
    for g in range(G):
        flat[g] = 1
        cur[g] = 0
    # la: the log-weights, then (pass B, in place) the weights, then the merge's scratch; ub: the
    # stratified uniforms (a row systematic touches once); ASIR's two lambda rows exist only for
    # ASIR (nothing else touches them)
    ub, cdf, la = fwork[0], fwork[1], fwork[2]
    asir_rows = fwork.shape[0] > 3
    lam = fwork[3] if asir_rows else la
    lam_all = fwork[4] if asir_rows else la
    idx = iwork[:n]
    kk = iwork[n:]  # per block, the merge's marks of one estimate tile
    bmax, bsum, bs2, off = bwork[0], bwork[1], bwork[2], bwork[3]
    bsx, bsxx = bmom[0], bmom[1]
    if method == _ASIR:
        for i in range(n):
            lam[i] = 0.0
    for t in range(M):
        yt = y[t]
        ut = u[t]
        for g in range(G):
            lwg = lw[g]
            first = 0.0
            for stage in range(2 if method == _ASIR else 1):
                fs = method == _ASIR and stage == 0  # first stage, [Thesis] Alg. 6
                src = xs[cur[g], g]
                for b in _prange(nb):  # pass A through its address: not compiled into the driver
                    bmax[b] = _call_a(_pass_a, pass_a_address, p, brngs[b], yt, ut, t, src, bounds[b],
                                      bounds[b + 1], n_noise, lwg, flat[g] == 1, mlogn, fs, lam,
                                      method == _ASIR and not fs, lam_all, la)
                m = -_np.inf
                for b in range(nb):
                    if bmax[b] > m:
                        m = bmax[b]
                deg = not (m > -_np.inf)
                if deg:  # every likelihood zero: keep the previous weights
                    for i in range(n):
                        la[i] = mlogn if flat[g] == 1 else lwg[i]
                        if la[i] > m:
                            m = la[i]
                for b in _prange(nb):
                    _call_b(_pass_b, pass_b_address, la, m, cdf, src, bounds[b], bounds[b + 1], not fs,
                            _np.int64(b), bsum, bs2, bsx, bsxx)  # b: unsigned in a prange
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
                    if hist_x.shape[1] > 0:
                        for i in range(n):
                            hist_w[g, t, i] = la[i] / total
                            for c in range(n_x):
                                hist_x[g, t, i, c] = src[i, c]
                    degen[g, t] = deg
                    inc[g, t] = (-_np.inf if deg else m + _np.log(total)) + first
                    s2 = 0.0
                    for b in range(nb):
                        s2 += bs2[b]
                    _moments(bsx, bsxx, nb, total, src, est, var, g, t)
                    e = total * total / s2
                    ess[g, t] = e
                    do = method == _BOOTSTRAP or (method == _SIR and e < ess_threshold)
                    resampled[g, t] = do
                if do:
                    dst = xs[1 - cur[g], g]
                    if (_SCHEME == _SYSTEMATIC or _SCHEME == _STRATIFIED  # pruned at compile time
                            or (_SCHEME == -1 and (scheme == _SYSTEMATIC or scheme == _STRATIFIED))):
                        strat = scheme == _STRATIFIED
                        uu = 0.0
                        if not strat:
                            _pcg64.fill_uniforms(rng, ub[:1])
                            uu = ub[0]
                        for b in _prange(nb):
                            i0 = bounds[b]
                            i1 = bounds[b + 1]
                            ubb = ub[i0:i1]
                            if strat:
                                _pcg64.fill_uniforms(brngs[b], ubb)
                            _call_c(_merge_gather, merge_address, cdf, n, uu, ubb, strat, i0, i1, src, dst,
                                    lam_all, lam, fs, idx, la,  # la (the weights) is free now
                                    kk[b * _ESTIMATE_TILE:(b + 1) * _ESTIMATE_TILE])
                    else:
                        if nb > 1:  # the index schemes see the sequential running sum
                            _cumsum_into(la, cdf)
                        _resample(scheme, la, cdf, rng, idx)
                        for b in _prange(nb):
                            _gather(idx, bounds[b], bounds[b + 1], src, dst, lam_all, lam, fs)
                    cur[g] = 1 - cur[g]
                    flat[g] = 1
                    if post and not fs:  # estimate="post" ([MultiPDF] Alg. 1 step 6): pass D
                        new = xs[cur[g], g]
                        for b in _prange(nb):
                            _block_moments(new, bounds[b], bounds[b + 1], _np.int64(b), bsx, bsxx)
                        _moments(bsx, bsxx, nb, _np.float64(n), new, est, var, g, t)
                elif not fs:
                    _normalised_log_weights(la, total, lwg)
                    flat[g] = 0
    for g in range(G):  # the final particles, block by block (on every thread: 16 MB at N_p = 10^6)
        fin = xs[cur[g], g]
        xg = x[g]
        for b in _prange(nb):
            xb = xg[bounds[b]:bounds[b + 1]]
            fb = fin[bounds[b]:bounds[b + 1]]
            for i in range(xb.shape[0]):
                for c in range(n_x):
                    xb[i, c] = fb[i, c]


def _named(func, name):
    """A copy of ``func`` under another name (its own dispatcher and cache entry)."""
    import types

    f = types.FunctionType(func.__code__, func.__globals__, name, func.__defaults__, func.__closure__)
    f.__qualname__ = name
    f.__doc__ = func.__doc__
    return f


#: the serial compilation (MultiPDF thread pools, small N_p, ``n_threads=1``)
run_group = _njit(nogil=True)(_named(_run_group, "run_group"))
#: the same function with its block loops over all numba threads (compiled on first use)
run_group_parallel = _njit(nogil=True, parallel=True)(_named(_run_group, "run_group_parallel"))
