"""The array-namespace particle kernel: one code path for NumPy (CPU, tests) and CuPy (GPU).

Every function here takes the array namespace ``xp`` (``numpy`` or ``cupy``) and works on arrays
of that namespace; :func:`run_groups` runs bootstrap ([Embedded] Alg. 1), SIR ([MultiPDF] eq. 8),
SIS ([Thesis] Alg. 2) and MultiPDF ([MultiPDF] Alg. 2: the N_f sub-filters as one (N_f, N_p)
batch, every step one call of the model's functions on all N_f x N_p particles). The model's own
``transition`` and ``log_likelihood`` run unchanged on ``xp`` arrays: NumPy's ufuncs dispatch to
CuPy through ``__array_ufunc__``. On CuPy, :mod:`pfbench.backends.cupy_backend` replaces three
steps (:class:`Steps`) by fused kernels; the algorithm and its order stay here.

Backends: ``backend="cupy"`` runs this module with ``xp = cupy``; ``backend="xp-numpy"`` runs
the very same code with ``xp = numpy``, which is how the CPU tests cover it. Neither is the
NumPy reference (:mod:`pfbench.backends.numpy_backend`) bit for bit: that one draws from
``numpy.random.Generator`` streams in a fixed order, which a GPU cannot reproduce.

Random numbers
--------------
Counter-based, so that any particle's draws can be computed by any thread in any order:
Philox4x64-10 (the generator of ``numpy.random.Philox``, :func:`philox4x64`) keyed by two words
of ``SeedSequence(seed).generate_state``. The counter of a draw is (particle index i within its
sub-filter, step t, kind, sub-filter f): kind ``k`` (0, 1, ...) gives the normals 4k..4k+3 of
the particle by Box-Muller (:func:`normals`), kind :data:`UNIFORM` the resampling uniform(s)
(:func:`uniforms`). NumPy and CuPy compute the same words; the normals agree to the last bits of
``log``/``cos``/``sin`` of the two libraries. The initial particles come from the model's own
``initial`` with ``numpy.random.default_rng(seed)`` on the host (the NumPy backend's first draws).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..methods import Method
from ..resampling import Scheme

#: Philox4x64 multipliers and Weyl key increments (Random123; numpy.random.Philox)
PHILOX_M = (0xD2E7470EE14C6C93, 0xCA5A826395121157)
PHILOX_W = (0x9E3779B97F4A7C15, 0xBB67AE8584CAA73B)
#: counter word 2 of the resampling uniforms (normals use 0, 1, ...: four normals each)
UNIFORM = 1 << 32
#: the methods and schemes this kernel runs
METHODS = (Method.BOOTSTRAP, Method.SIR, Method.SIS, Method.MULTIPDF)
SCHEMES = (Scheme.SYSTEMATIC, Scheme.STRATIFIED)
_M32 = 0xFFFFFFFF
_TWO53 = 2.0 ** -53


def check_supported(method: Method, scheme: Scheme, backend: str) -> None:
    """InputError (one line) for a method or scheme this kernel does not run."""
    if method not in METHODS:
        raise InputError(f"backend {backend!r} runs methods {', '.join(m.label for m in METHODS)}, "
                         f"not {method.label!r}")
    if scheme not in SCHEMES:
        raise InputError(f"backend {backend!r} resamples {' or '.join(s.label for s in SCHEMES)}, "
                         f"not {scheme.label!r}")


def philox_key(seed_seq: np.random.SeedSequence) -> tuple[int, int]:
    """The two Philox key words of a run: ``seed_seq.generate_state(2, uint64)``."""
    k = seed_seq.generate_state(2, np.uint64)
    return int(k[0]), int(k[1])


def _mulhilo(xp, a, b: int):
    """(hi, lo) 64-bit words of the 128-bit product of uint64 array ``a`` and constant ``b``."""
    u = xp.uint64
    m32, s32 = u(_M32), u(32)
    a_lo, a_hi = a & m32, a >> s32
    b_lo, b_hi = u(b & _M32), u(b >> 32)
    ll, lh, hl = a_lo * b_lo, a_lo * b_hi, a_hi * b_lo
    mid = (ll >> s32) + (lh & m32) + (hl & m32)
    hi = a_hi * b_hi + (lh >> s32) + (hl >> s32) + (mid >> s32)
    return hi, a * u(b)


def philox4x64(xp, c0, c1, c2, c3, key: tuple[int, int]):
    """Philox4x64-10 of the counters (c0, c1, c2, c3) (uint64 arrays or scalars, broadcast) under
    ``key``: four uint64 arrays, the words ``numpy.random.Philox(counter=c - 1, key=key)`` gives."""
    u = xp.uint64
    c = [xp.asarray(v, dtype=xp.uint64) for v in (c0, c1, c2, c3)]
    c = list(xp.broadcast_arrays(*c))
    k0, k1 = key
    for r in range(10):
        if r:
            k0, k1 = (k0 + PHILOX_W[0]) & 0xFFFFFFFFFFFFFFFF, (k1 + PHILOX_W[1]) & 0xFFFFFFFFFFFFFFFF
        hi0, lo0 = _mulhilo(xp, c[0], PHILOX_M[0])
        hi1, lo1 = _mulhilo(xp, c[2], PHILOX_M[1])
        c = [hi1 ^ c[1] ^ u(k0), lo1, hi0 ^ c[3] ^ u(k1), lo0]
    return c


def unit(xp, w):
    """A uint64 word as a float64 in [0, 1): the top 53 bits times 2^-53."""
    return (w >> xp.uint64(11)).astype(xp.float64) * _TWO53


def normals(xp, key, n_rows: int, n: int, t: int, n_noise: int) -> "np.ndarray":
    """(n_rows * n, n_noise) float64 standard normals of step ``t`` for ``n_rows`` sub-filters of
    ``n`` particles: normals 4k..4k+3 of particle i of sub-filter f are the Box-Muller pairs
    (w0, w1), (w2, w3) of Philox(i, t, k, f): r = sqrt(-2 log u), u = (w0 >> 11 + 1) 2^-53 in
    (0, 1], and r cos / r sin of 2 pi (w1 >> 11) 2^-53."""
    i = xp.arange(n, dtype=xp.uint64)[None, :]
    f = xp.arange(n_rows, dtype=xp.uint64)[:, None]
    cols = []
    for k in range(-(-n_noise // 4)):
        w = philox4x64(xp, i, t, k, f, key)
        for j in range(min(4, n_noise - 4 * k)):
            if j % 2 == 0:  # a Box-Muller pair: r cos a, then r sin a
                r = xp.sqrt(-2.0 * xp.log(unit(xp, w[j]) + _TWO53))
                a = (2.0 * math.pi) * unit(xp, w[j + 1])
                cols.append((r * xp.cos(a)).reshape(-1))
            else:
                cols.append((r * xp.sin(a)).reshape(-1))
    return xp.stack(cols, axis=1)


def uniforms(xp, key, n_rows: int, n: int, t: int):
    """(n_rows, n) float64 uniforms in [0, 1) of step ``t``: word 0 of Philox(i, t, UNIFORM, f)
    (systematic uses column 0 only, stratified all). A few words (systematic's one per row) are
    computed on the host and copied: on a GPU the many tiny kernel launches of the Philox rounds
    cost more than the copy (the same words: NumPy and CuPy compute Philox alike)."""
    if xp is not np and n_rows * n <= SMALL:
        return xp.asarray(uniforms(np, key, n_rows, n, t))
    i = xp.arange(n, dtype=xp.uint64)[None, :]
    f = xp.arange(n_rows, dtype=xp.uint64)[:, None]
    return unit(xp, philox4x64(xp, i, t, UNIFORM, f, key)[0])


# --------------------------------------------------------------------------- the three steps
def model_step(xp, fns, p, key, x, yt, ut, t: int):
    """Propagate and weigh: x (F, n, n_x) in the particle dtype is replaced by transition(x, u_t,
    t, noise) (noise rounded to the particle dtype, model arithmetic in float64, as on the other
    backends); returns the log-likelihoods (F, n) float64 of the stored (rounded) particles with
    NaN and +inf as -inf ([Embedded] Alg. 1 steps 2-3)."""
    F, n, n_x = x.shape
    ptype = x.dtype
    z = fns.get("normals", normals)(xp, key, F, n, t, fns["n_noise"]).astype(ptype).astype(xp.float64)
    xf = x.reshape(F * n, n_x).astype(xp.float64)
    x[...] = xp.asarray(fns["transition"](xf, ut, t, z, p)).reshape(F, n, n_x)
    ll = xp.asarray(fns["log_likelihood"](yt, x.reshape(F * n, n_x).astype(xp.float64), ut, t, p),
                    dtype=xp.float64).reshape(F, n)
    return xp.where((ll == ll) & (ll != xp.inf), ll, -xp.inf)


def weigh(xp, x, ll, lw):
    """Log-sum-exp weighting of every row ([MultiPDF] eq. 8): a = lw + ll (lw None: uniform
    weights), m = max a per row; a row whose every likelihood is zero keeps its weights
    (degenerate). Returns ``(cdf, total, m, mean, var, ess, degenerate)``: the running sum of
    w = exp(a - m) per row (F, n; for :func:`resample` only), its last element (F,), the max
    (F,), the weighted mean and variance (F, n_x), N_eff = (sum w)^2 / sum w^2 (F,) and the flags
    (F,)."""
    a, m, degen = shifted(xp, ll, lw)
    w = xp.exp(a - m[:, None])
    cdf = xp.cumsum(w, axis=1)
    total = cdf[:, -1]
    xf = x.astype(xp.float64)
    mean = xp.einsum("fn,fnk->fk", w, xf) / total[:, None]
    var = xp.einsum("fn,fnk->fk", w, (xf - mean[:, None, :]) ** 2) / total[:, None]
    ess = total * total / xp.einsum("fn,fn->f", w, w)
    return cdf, total, m, mean, var, ess, degen


def shifted(xp, ll, lw):
    """(a, m, degenerate): the log-weights a = lw + ll (lw None: ll), their max per row, and the
    rows whose every likelihood is zero, where a is lw instead (the weights are kept)."""
    a = ll if lw is None else lw + ll
    m = row_max(xp, a)
    degen = ~(m > -xp.inf)
    if bool(degen.any()):
        a = xp.where(degen[:, None], xp.zeros_like(ll) if lw is None else lw, a)
        m = row_max(xp, a)
    return a, m, degen


#: at most this many rows are reduced one by one (:func:`row_max`), at most this many words are
#: drawn on the host (:func:`uniforms`)
SMALL = 64


def row_max(xp, a):
    """The max of each row of a (F, n) array. For a few long rows on a GPU, row by row: CuPy gives
    an ``axis=1`` reduction one thread block per row, which leaves a long row to one block, while a
    whole-array reduction spreads over the device (docs/PERFORMANCE.md has the timings)."""
    if xp is np or a.shape[0] > SMALL:
        return a.max(axis=1)
    return xp.stack([a[f].max() for f in range(a.shape[0])])


def ancestors(xp, cdf, u, f: int):
    """Ancestor indices of row ``f``: the smallest j with cdf[f, j] > (u[f, i] + i) / n *
    cdf[f, -1], clamped to n - 1: :func:`pfbench.resampling.systematic`'s positions when u[f] is
    one uniform, ``stratified``'s when it is n."""
    n = cdf.shape[1]
    pos = (u[f] + xp.arange(n, dtype=xp.float64)) / n * cdf[f, -1]
    return xp.minimum(xp.searchsorted(cdf[f], pos, side="right"), n - 1)


def resample(xp, x, cdf, u, rows=None):
    """Systematic / stratified resampling and gather ([Embedded] Alg. 1 step 5) of the rows
    ``rows`` (None: all) of x (F, n, n_x), in place (:func:`ancestors`); returns x."""
    for f in range(x.shape[0]) if rows is None else rows:
        x[f] = x[f][ancestors(xp, cdf, u, f)]
    return x


@dataclass
class Steps:
    """The three steps of one particle-filter step, as functions of :func:`run_groups`'s arrays.
    The defaults are this module's namespace functions; :mod:`pfbench.backends.cupy_backend`
    gives fused CuPy kernels for the same contracts (and says which in ``info``). ``resample``
    returns the resampled particles (in place, or a second buffer)."""

    model_step: object = model_step
    weigh: object = weigh
    resample: object = resample
    normals: object = None  # None: :func:`normals`
    info: dict | None = None


def initial_particles(model, p, seed_seq, n_rows: int, n: int, ptype) -> np.ndarray:
    """(n_rows, n, n_x) initial particles on the host: ``model.initial`` with
    ``numpy.random.default_rng(seed_seq)``, row after row (the NumPy backend's first draws)."""
    rng = np.random.default_rng(seed_seq)
    init = model.kernel_functions()["initial"]
    x = np.empty((n_rows, n, model.n_x), dtype=ptype)
    for f in range(n_rows):
        x[f] = np.asarray(init(rng, n, p)).reshape(n, model.n_x)
    return x


def device_params(xp, p):
    """The model's parameter tuple with every NumPy array moved to ``xp`` (scalars unchanged)."""
    if xp is np:
        return p
    return tuple(xp.asarray(v) if isinstance(v, np.ndarray) else v for v in p)


def run_groups(xp, model, y, u, seed_seq, *, method, n_per: int, n_filters: int, resampling,
               ess_threshold: float, dtype: str = "float64", steps: Steps | None = None):
    """Run ``n_filters`` filters of ``n_per`` particles as one (N_f, N_p) batch on namespace ``xp``.

    Returns ``(out, elapsed_s, info)`` with the per-filter host arrays of
    :func:`pfbench.filters.particle.run_groups` (``est``, ``var`` (N_f, M, n_x), ``ess``, ``inc``,
    ``resampled``, ``degen`` (N_f, M)) and ``info`` (``setup_s``: initial particles and their
    transfer; ``loop_s``: the M steps, synchronised; the steps' own ``info``). ``method`` runs
    as in :mod:`pfbench.backends.numpy_backend`: bootstrap (and MultiPDF sub-filters) resample
    every step, SIR when N_eff < ``ess_threshold`` (a particle count), SIS never.
    """
    method, scheme = Method.parse(method), Scheme.parse(resampling)
    steps = steps or Steps()
    F, n, M = int(n_filters), int(n_per), y.shape[0]
    ptype = np.float32 if dtype == "float32" else np.float64
    code = Method.BOOTSTRAP if method == Method.MULTIPDF else method
    sync = _synchroniser(xp)
    p = model.params()
    fns = {"transition": model.kernel_functions()["transition"], "n_noise": int(model.n_noise),
           "log_likelihood": model.kernel_functions()["log_likelihood"], "normals": steps.normals or normals}
    key = philox_key(seed_seq)
    t0 = time.perf_counter()
    x = xp.asarray(initial_particles(model, p, seed_seq, F, n, ptype))
    pd = device_params(xp, p)
    yd, ud = xp.asarray(y), xp.asarray(u)
    est, var = xp.empty((F, M, model.n_x)), xp.empty((F, M, model.n_x))
    ess, inc = xp.empty((F, M)), xp.empty((F, M))
    degen = xp.zeros((F, M), dtype=xp.bool_)
    resampled = np.zeros((F, M), dtype=np.bool_)
    lw = None  # None: every row's weights are uniform (1/n)
    logn = math.log(n)
    sync()
    t1 = time.perf_counter()
    for t in range(M):
        ll = steps.model_step(xp, fns, pd, key, x, yd[t], ud[t], t)  # x updated in place
        cdf, total, m, mean, v, e, dg = steps.weigh(xp, x, ll, lw)
        est[:, t], var[:, t], ess[:, t], degen[:, t] = mean, v, e, dg
        inc[:, t] = xp.where(dg, -xp.inf, m + xp.log(total) - (logn if lw is None else 0.0))
        if code == Method.BOOTSTRAP:
            rows = None
        elif code == Method.SIR:
            rows = [int(f) for f in np.flatnonzero(_host(xp, e) < ess_threshold)]
        else:
            rows = []
        if rows is None or rows:
            uu = uniforms(xp, key, F, 1 if scheme == Scheme.SYSTEMATIC else n, t)
            x = steps.resample(xp, x, cdf, uu, rows)
            resampled[range(F) if rows is None else rows, t] = True
        if rows is None:
            lw = None
        else:  # normalised log-weights a - m - log(total) = log(w / total); 1/n where resampled
            a, _, _ = shifted(xp, ll, lw)
            lw_new = a - (m + xp.log(total))[:, None]
            if rows:
                lw_new[xp.asarray(rows)] = -logn
            lw = lw_new
    sync()
    t2 = time.perf_counter()
    out = {"est": _host(xp, est), "var": _host(xp, var), "ess": _host(xp, ess), "inc": _host(xp, inc),
           "resampled": resampled, "degen": _host(xp, degen)}
    info = {"setup_s": t1 - t0, "loop_s": t2 - t1, **(steps.info or {})}
    return out, time.perf_counter() - t0, info


def _host(xp, a):
    return a if xp is np else xp.asnumpy(a)


def _synchroniser(xp):
    if xp is np:
        return lambda: None
    return lambda: xp.cuda.get_current_stream().synchronize()
