"""The NumPy backend: the readable reference engine, vectorised over particles.

:func:`run_group` runs G independent particle filters (a MultiPDF group, or one filter) over
all steps, drawing every random number from one ``numpy.random.Generator`` in this order:

1. initial particles of filter 0, 1, ..., G-1 (the model's ``initial``; with several stream
   blocks, from the block streams instead, below);
2. per step t, per filter g in order:
   a. ASIR only: the first-stage resampling draws;
   b. transition noise, ``rng.standard_normal((n, n_noise), dtype=particle dtype)``;
   c. the resampling draws, if the filter resamples at this step.

Stream blocks (:func:`block_bounds`): one up to N_p = :data:`BLOCK`, else a multiple of 16 equal
blocks, so 2, 4, 8 or 16 threads get equal work. With B > 1 blocks, block b's own generator
(:func:`block_streams`) draws block b's initial particles of every filter, then per step its
transition noise (and the stratified uniforms of output block b); systematic's one uniform and the
draws of every scheme outside :data:`pfbench.resampling.MERGED` come from the filter's generator,
those schemes on the sequential running sum. Running sums restart per block and
add the block's offset, and block totals are added in block order, so the numbers depend on the seed
and N_p, never on the thread count. The numba kernel (:mod:`pfbench.backends.numba_particle`) follows
the same order with the same operations, so the two backends agree under common random numbers.

Methods (:class:`pfbench.methods.Method` codes, shared with the numba kernel): bootstrap
(resample every step, [Embedded] Alg. 1; [MultiPDF] Alg. 1), SIR (resample when N_eff <
threshold, [MultiPDF] eq. 8; [Thesis] Alg. 3), SIS (never resample, [Thesis] Alg. 2), ASIR
(auxiliary SIR, [Thesis] Alg. 6: first-stage weights p(y_t | mu_t^i) at mu_t^i = f(x_{t-1}^i)
with zero noise). :func:`weigh` is the one log-sum-exp weighting of every NumPy filter driver.
"""
from __future__ import annotations

import numpy as np

from .. import resampling
from .fastexp import exp_array as exp_weights
from ..methods import Estimate, Method
from ..models.contract import invalid_log_likelihoods, shaped


def valid_log_likelihood(ll) -> np.ndarray:
    """Log-likelihoods as float64 with NaN and +inf replaced by -inf (invalid -> weight 0)."""
    ll = np.array(ll, dtype=np.float64, copy=True).reshape(-1)
    ll[~(ll == ll) | (ll == np.inf)] = -np.inf
    return ll


def weigh(lw: np.ndarray, ll: np.ndarray, blocks=None):
    """Combine normalised log-weights with log-likelihoods, log-sum-exp style (twin of
    :func:`pfbench.backends.numba_weights.weigh`). Returns (wu, cdf, m, total, degenerate): exp(a - max a),
    its running sum (restarting per stream block of ``blocks``, slices; None: one block), the max, the
    sum, and whether every likelihood was zero (then the previous weights are kept)."""
    a = lw + ll
    m = a.max()
    degenerate = not (m > -np.inf)
    if degenerate:
        a = lw.copy()
        m = a.max()
    wu, cdf, total = _block_weights(a, m, blocks or [slice(0, a.size)])
    return wu, cdf, m, total, degenerate


def normalised_log_weights(wu: np.ndarray, total: float) -> np.ndarray:
    """log(wu / total), -inf where wu = 0."""
    with np.errstate(divide="ignore"):
        return np.log(wu) - np.log(total)


#: largest stream block (both backends): up to this N_p a filter is one block, the single-stream filter
BLOCK = 8192
#: above BLOCK the number of blocks is a multiple of this, so 1, 2, 4, 8 or 16 threads get equal shares
BALANCE = 16


def n_blocks(n: int, block: int = BLOCK) -> int:
    """Number of stream blocks of a filter of ``n`` particles: 1 up to ``block``, else the smallest
    multiple of :data:`BALANCE` (at most ``n``) whose blocks hold at most ``block`` particles."""
    if n <= block:
        return 1
    return min(n, BALANCE * -(-n // (BALANCE * block)))


def block_bounds(n: int, block: int = BLOCK) -> np.ndarray:
    """Start of every stream block, then n: (B + 1,) int64 with B = :func:`n_blocks`; block b is
    [(b n) // B, ((b + 1) n) // B), so block sizes differ by at most one particle."""
    return _bounds(n, n_blocks(n, block))


def _bounds(n: int, nb: int) -> np.ndarray:
    """The starts of ``nb`` blocks of ``n`` particles, then n (block sizes differ by at most one)."""
    return (np.arange(nb + 1, dtype=np.int64) * n) // nb


def block_streams(rng, seed_seq, n: int, block: int = BLOCK) -> list:
    """The stream-block generators of a filter of ``n`` particles: ``[rng]`` for one block, else
    ``default_rng(SeedSequence(entropy, spawn_key=seed_seq.spawn_key + (0x5EB10C, b)))`` for block b,
    derived from the filter's SeedSequence without spawning from (mutating) it."""
    nb = n_blocks(n, block)
    if nb == 1:
        return [rng]
    if seed_seq is None:
        raise ValueError("a multi-block filter needs its SeedSequence")
    return [np.random.default_rng(np.random.SeedSequence(seed_seq.entropy, spawn_key=tuple(seed_seq.spawn_key)
                                                         + (0x5EB10C, b), pool_size=seed_seq.pool_size))
            for b in range(nb)]


def _block_weights(a: np.ndarray, m: float, blocks):
    """w = exp(a - m) (:func:`pfbench.backends.fastexp.exp_array`, the numba kernels' bits), the cdf as
    block offset + running sum within the block, and the block sums added in block order."""
    wu = exp_weights(a - m)
    cdf = np.empty_like(wu)
    total = 0.0
    for sl in blocks:
        cdf[sl] = total + np.cumsum(wu[sl])
        total = cdf[sl.stop - 1]
    return wu, cdf, total


def _resample_into(scheme, wu, cdf, rng, brngs, blocks):
    """Ancestor indices: systematic/stratified on the block cdf (stratified uniforms of block b from
    stream b), the other schemes as :mod:`pfbench.resampling` on the filter's stream."""
    n = wu.size
    if len(blocks) == 1 or scheme not in resampling.MERGED:
        return resampling.get(scheme)(wu, rng)
    if scheme == resampling.Scheme.SYSTEMATIC:
        u = np.full(n, rng.random())
    else:
        u = np.concatenate([r.random(sl.stop - sl.start) for r, sl in zip(brngs, blocks)])
    positions = (u + np.arange(n)) / n * cdf[-1]
    return np.minimum(np.searchsorted(cdf, positions, side="right"), n - 1)


def draw_initial(initial, p, rng, x, brngs=None) -> None:
    """The initial particles of a group into ``x`` (G, N_p, n_x), in the documented draw order (both
    backends call this). One block (``brngs`` None or of length 1): x[g] = initial(rng, N_p, p). B > 1
    blocks: x[g, block b] = initial(brngs[b], size of block b, p), so a block's particles depend on its
    own stream alone, as its transition noise does."""
    G, n = x.shape[0], x.shape[1]
    if brngs is None or len(brngs) == 1:
        for g in range(G):
            x[g] = initial(rng, n, p)
        return
    bounds = _bounds(n, len(brngs))
    for b, r in enumerate(brngs):
        for g in range(G):
            x[g, bounds[b]:bounds[b + 1]] = initial(r, int(bounds[b + 1] - bounds[b]), p)


def run_group(model, p, rng, y, u, out, method: int, scheme: int, ess_threshold: float, *, brngs=None,
              n_threads=None, block: int | None = None, estimate: str = "pre") -> None:
    """Run G filters over all steps, filling ``out`` (:class:`pfbench.backends.particle_work.Outputs`:
    the final particles ``x`` (G, N_p, n_x), ``est`` ... ``degen``, and the weighted particles of every
    step in ``hist_x``/``hist_w`` when they have M rows) in place. ``method``: a
    :class:`~pfbench.methods.Method` code of the particle family; ``scheme``: a
    :class:`~pfbench.resampling.Scheme` code; ``ess_threshold``: a particle count (SIR). ``brngs``:
    :func:`block_streams` (None: one block); ``n_threads`` is ignored. ``estimate``: ``pre`` (weighted
    moments before resampling) or ``post`` (at a step that resamples, the resampled particles'
    moments; :func:`pfbench.run_filter`)."""
    x, est, var, ess, inc = out.x, out.est, out.var, out.ess, out.inc
    resampled, degen, invalid, hist_x, hist_w = out.resampled, out.degen, out.invalid, out.hist_x, out.hist_w
    store = hist_x.shape[1] > 0
    fns = model.kernel_functions()
    initial, transition, log_likelihood = fns["initial"], fns["transition"], fns["log_likelihood"]
    scheme = resampling.Scheme(scheme)
    G, n, n_x = x.shape
    if brngs is None:  # no stream blocks given: the whole population is one block
        blocks, brngs = [slice(0, n)], [rng]
    else:
        bounds = block_bounds(n, int(block or BLOCK))
        blocks, brngs = [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])], list(brngs)
        if len(brngs) != len(blocks):
            raise ValueError(f"{len(brngs)} block streams for {len(blocks)} blocks")  # a caller bug
    post = Estimate.parse(estimate) == Estimate.POST
    ptype = x.dtype  # float32 particles: float32 normals and storage, model arithmetic in float64
    n_noise = model.n_noise
    logn = np.log(n)
    lw = np.full((G, n), -logn)
    draw_initial(initial, p, rng, x, brngs)
    xs, ls = (n, n_x), (n,)   # the shapes of the model's states and log-likelihoods, checked every step
    for t in range(y.shape[0]):
        yt, ut, at = y[t], u[t], f"at step {t}"
        for g in range(G):
            xg = x[g]
            first = 0.0
            if method == Method.ASIR:  # first stage
                mu = shaped(model, "transition", transition(xg.astype(np.float64), ut, t, np.zeros((n, n_noise)), p), xs, at)
                raw = shaped(model, "log_likelihood", log_likelihood(yt, mu, ut, t, p), ls, at)
                invalid[g, t] += invalid_log_likelihoods(raw)
                lam_all = valid_log_likelihood(raw)
                wu, cdf, m1, tot1, deg1 = weigh(lw[g], lam_all, blocks)
                first = m1 + np.log(tot1)
                if deg1:
                    lam_all[:] = 0.0
                idx = _resample_into(scheme, wu, cdf, rng, brngs, blocks)
                xg[:] = xg[idx]
                lam = lam_all[idx]
                lw[g] = -logn
            # transition noise: block b from its own stream (one block: the filter's stream)
            noise = np.concatenate([r.standard_normal((sl.stop - sl.start, n_noise), dtype=ptype)
                                    for r, sl in zip(brngs, blocks)])
            xg[:] = shaped(model, "transition", transition(xg.astype(np.float64), ut, t, noise.astype(np.float64), p), xs, at)
            raw = shaped(model, "log_likelihood", log_likelihood(yt, xg.astype(np.float64), ut, t, p), ls, at)
            invalid[g, t] += invalid_log_likelihoods(raw)
            ll = valid_log_likelihood(raw)
            if method == Method.ASIR:
                ll = valid_log_likelihood(ll - lam)
            wu, cdf, m, total, deg = weigh(lw[g], ll, blocks)
            if store:
                hist_x[g, t] = xg
                hist_w[g, t] = wu / total
            degen[g, t] = deg
            inc[g, t] = (-np.inf if deg else m + np.log(total)) + first
            xf = xg.astype(np.float64)
            mean = (wu @ xf) / total
            est[g, t] = mean
            var[g, t] = (wu @ (xf - mean) ** 2) / total
            e = total * total / (wu @ wu)  # N_eff = 1 / sum (w_i / total)^2
            ess[g, t] = e
            do = method == Method.BOOTSTRAP or (method == Method.SIR and e < ess_threshold)
            if do:
                xg[:] = xg[_resample_into(scheme, wu, cdf, rng, brngs, blocks)]
                lw[g] = -logn
                if post:  # [MultiPDF] Alg. 1 step 6: the estimate of the resampled particles
                    xf = xg.astype(np.float64)
                    mean = xf.mean(axis=0)
                    est[g, t] = mean
                    var[g, t] = ((xf - mean) ** 2).mean(axis=0)
            else:
                lw[g] = normalised_log_weights(wu, total)
            resampled[g, t] = do
