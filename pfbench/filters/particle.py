"""Bootstrap, SIR, SIS, ASIR and MultiPDF: the particle filters run by the bootstrap-family kernel.

Random numbers
--------------
Every random number comes from ``numpy.random.Generator`` objects, consumed in the order
documented in :mod:`pfbench.backends.numpy_backend`; numba draws bit-identical numbers from the
same generators, so both backends give the same estimates.

* ``common_random_numbers=True``: one stream, ``numpy.random.default_rng(seed)``; the N_f
  MultiPDF sub-filters take their draws from it in turn at every step (so they run one after
  the other). Use it to compare backends or methods on exactly the same random numbers.
* ``common_random_numbers=False`` (default): with one filter, the same single stream; with
  N_f > 1, sub-filter l draws from its own stream ``default_rng(SeedSequence(seed).spawn(N_f)[l])``
  so the sub-filters can run in parallel threads (numba releases the GIL). Still reproducible
  for a given (seed, N_f), and still identical across backends.

MultiPDF ([MultiPDF] Alg. 2): N_f independent bootstrap sub-filters with round(N_p / N_f)
particles each; the estimate at every step is the mean of the sub-filter estimates (eq. 9; each
taken before or after resampling, ``run_filter``'s ``estimate``), the variance is the law of
total variance over the sub-filters, and ``loglik`` is the log of the mean of the sub-filters'
(unbiased) likelihood estimates, with increments that sum to it. When
round(N_p / N_f) * N_f differs from N_p, ``n_particles`` reports the particles actually used and
``info["n_particles_requested"]`` the request (each sub-filter is off by at most half a particle).

Numerical trouble
-----------------
Weights are handled in log space (log-sum-exp), so an outlier that makes every likelihood
underflow in linear scale still gives finite, correctly normalised weights. NaN or +inf
log-likelihoods count as zero likelihood and are counted on the numpy and numba backends
(``info``: ``invalid_log_likelihoods``, ``invalid_steps``, ``first_invalid_step``; ``pfbench run``
and sweeps warn of them): they are the model's trouble, often a state the model did not expect.
If *every* particle has zero likelihood at a step, the step is flagged in ``degenerate``, the
measurement is ignored (weights kept), the filter carries on, its ``ess`` is reported as 0, and
``loglik`` becomes -inf (the estimate of p(y) really is 0); estimates never become NaN. NaN/inf
measurements are rejected up front with the first bad step named.
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .. import backends
from ..backends.numpy_backend import BLOCK, block_streams
from ..backends.particle_work import outputs
from ..errors import InputError
from ..procs import free_cores, numba_threads
from ..resampling import Scheme
from ..methods import ARRAY_BACKENDS, Estimate, Method, check_backend, check_dtype
from .inputs import ess_count, seed_sequence
from .result import FilterResult, invalid_info, mixture_loglik_increments, reported_ess, total_variance


def streams(seed, n_filters: int, common_random_numbers: bool) -> list[np.random.Generator]:
    """The random streams of a run (see the module docstring)."""
    ss = seed_sequence(seed)
    if common_random_numbers or n_filters == 1:
        return [np.random.default_rng(ss)]
    return [np.random.default_rng(s) for s in ss.spawn(n_filters)]


def split_particles(n_particles: int, n_filters: int) -> int:
    """Particles per MultiPDF sub-filter, round(N_p / N_f) (at least 1)."""
    return max(int(round(n_particles / n_filters)), 1)


def run_particle(model, y, u, *, method: Method, n_particles: int, n_filters: int = 1,
                 resampling="systematic", ess_threshold=None, backend: str = "numba",
                 dtype: str = "float64", seed=0, common_random_numbers: bool = False,
                 n_threads: int | None = None, store_particles: bool = False, estimate: str = "pre",
                 _block: int | None = None) -> FilterResult:
    """Run a bootstrap-family filter on validated ``y``/``u`` (see :func:`pfbench.run_filter`)."""
    method = Method.parse(method)
    scheme = Scheme.parse(resampling)
    estimate = Estimate.parse(estimate).label
    check_backend(backend)
    check_dtype(dtype)
    if method != Method.MULTIPDF and n_filters != 1:
        raise InputError(f"n_filters={n_filters} needs method='multipdf'")
    if n_filters > n_particles:
        raise InputError(f"n_filters ({n_filters}) cannot exceed n_particles ({n_particles})")
    n_per = split_particles(n_particles, n_filters) if method == Method.MULTIPDF else n_particles
    if method != Method.SIR and ess_threshold is not None:
        raise InputError(f"ess_threshold applies to method 'sir' only (got method {method.label!r})")
    thr = ess_count(ess_threshold, n_per)
    extra = {}
    if backend in ARRAY_BACKENDS:  # the array-namespace kernel: NumPy (xp-numpy) or a GPU (cupy)
        if estimate == Estimate.POST.label:
            raise InputError(f"estimate='post' is not available on backend {backend!r} (use 'pre', or "
                             f"backend 'numpy' or 'numba')")
        from ..backends import cupy_backend

        out, elapsed, extra = cupy_backend.run_groups(
            model, y, u, seed_sequence(seed), backend=backend, method=method, n_per=n_per,
            n_filters=n_filters, resampling=scheme, ess_threshold=thr, dtype=dtype,
            store_particles=store_particles)
        n_streams = 1
    else:
        rngs = streams(seed, n_filters, common_random_numbers)
        out, elapsed = run_groups(model, y, u, rngs, method=method, n_per=n_per, n_filters=n_filters,
                                  resampling=scheme, ess_threshold=thr, backend=backend, dtype=dtype,
                                  n_threads=n_threads, store_particles=store_particles, estimate=estimate,
                                  block=_block)
        n_streams = len(rngs)
    est, var, inc = out["est"], out["var"], out["inc"]
    ess = reported_ess(out["ess"], out["degen"])
    resampled = out["resampled"] | (method == Method.ASIR)  # ASIR resamples in its first stage, every step
    increments = mixture_loglik_increments(inc)
    mean, variance = total_variance(est, var)
    info = {"n_per_filter": n_per, "ess_threshold": thr if method == Method.SIR else None,
            "resampling": scheme.label, "estimate": estimate,
            "common_random_numbers": bool(common_random_numbers), "n_streams": n_streams,
            "threads": out.get("threads", 1), **extra,
            **(invalid_info(out["invalid"].sum(axis=0)) if "invalid" in out else {})}
    if n_per * n_filters != n_particles:
        info["n_particles_requested"] = n_particles
        info["note"] = (f"N_p = {n_particles} does not split evenly into {n_filters} sub-filters: "
                        f"{n_filters} x {n_per} = {n_per * n_filters} particles were used")
    return FilterResult(
        estimates=mean, variances=variance, loglik=float(increments.sum()),
        loglik_increments=increments, ess=ess.mean(axis=0), n_resampled=int(resampled.sum()),
        degenerate=out["degen"].any(axis=0), elapsed_s=elapsed, method=method.label, backend=backend,
        dtype=dtype, n_particles=n_per * n_filters, n_filters=n_filters, sub_estimates=est,
        sub_variances=var, sub_ess=ess, info=info,
        extras={"resampled": resampled, **({"particles": out["particles"], "weights": out["weights"]}
                                                  if store_particles else {})})


def run_groups(model, y, u, rngs, *, method, n_per: int, n_filters: int, resampling,
               ess_threshold: float, backend: str, dtype: str = "float64", n_threads: int | None = None,
               store_particles: bool = False, estimate: str = "pre", block: int | None = None):
    """Run ``n_filters`` filters of ``n_per`` particles on validated, contiguous ``y``/``u``.

    The filters are split evenly over the random streams ``rngs`` (one group per stream, see
    :func:`streams`); on numba, groups run in parallel threads (``n_threads``; default the free
    cores, :func:`pfbench.procs.free_cores`; 1 to stay sequential). Returns ``(arrays, elapsed_s)``
    with per-filter arrays ``est``/``var`` (N_f, M, n_x), ``ess``/``inc``/``resampled``/``degen``
    (N_f, M), and ``threads``, the threads the run used. ``method`` is a particle-family
    :class:`Method` (MultiPDF sub-filters run as bootstrap), ``resampling`` a :class:`Scheme` and
    ``ess_threshold`` a particle count. ``store_particles`` adds ``particles`` (N_f, M, n, n_x) and
    ``weights`` (N_f, M, n), the normalised weighted particles of every step before resampling.
    ``estimate``: ``pre`` or ``post`` (an :class:`~pfbench.methods.Estimate` name, see
    :func:`pfbench.run_filter`); ``post`` is handed to the backend's ``run_group`` as
    ``estimate="post"`` (``pre`` is not passed: the backends' default).
    ``block``: the largest stream block (default :data:`pfbench.backends.numpy_backend.BLOCK`;
    :func:`~pfbench.backends.numpy_backend.block_bounds` gives the layout; a run with one block is
    the single-stream filter, see :mod:`pfbench.backends.numba_particle`).
    A single group (one filter, or MultiPDF with common random numbers) runs its block loops on
    ``n_threads`` threads on numba; several groups run in a thread pool of serial kernels.
    Used by :func:`run_particle` and by the sweep runner.
    """
    be = backends.get(backend)
    M, n_x = y.shape[0], model.n_x
    p = model.params()
    n_groups = len(rngs)
    per_group = n_filters // n_groups
    ptype = np.float32 if dtype == "float32" else np.float64
    out = outputs(n_filters, M, n_per, n_x, ptype, store_particles)
    method = Method.parse(method)
    if method.family != "particle":
        raise InputError(f"run_groups runs the particle methods, not {method.label!r}")
    code = int(Method.BOOTSTRAP if method == Method.MULTIPDF else method)  # MultiPDF sub-filters
    scheme = int(Scheme.parse(resampling))
    block = int(block or BLOCK)
    at = {"estimate": "post"} if Estimate.parse(estimate) == Estimate.POST else {}
    brngs = [block_streams(r, r.bit_generator.seed_seq, n_per, block) for r in rngs]
    # the threads it may use, where there are groups or stream blocks to spread over them on numba:
    # those asked for, else the free cores (free_cores reads /proc), at most numba's
    spread = backend == "numba" and (n_groups > 1 or len(brngs[0]) > 1)
    threads = min(n_threads or free_cores(), numba_threads()) if spread else 1
    workers = min(n_groups, threads)
    pooled = n_groups > 1 and workers > 1
    # one filter at a time may use every core; pooled sub-filters run serial kernels (no oversubscription)
    inner = 1 if n_groups > 1 else threads
    if backend == "numba":  # compile (or load from cache) outside the timed region
        be.warm_up(model, p, y, u, ptype, scheme, parallel=len(brngs[0]) > 1 and inner != 1)

    def job(gi: int):
        sl = slice(gi * per_group, (gi + 1) * per_group)
        be.run_group(model, p, rngs[gi], y, u, out.rows(sl), code, scheme, ess_threshold, brngs=brngs[gi],
                     n_threads=inner, block=block, **at)

    t0 = time.perf_counter()
    if pooled:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(job, range(n_groups)))
    else:
        for gi in range(n_groups):
            job(gi)
    elapsed = time.perf_counter() - t0
    return {"est": out.est, "var": out.var, "ess": out.ess, "inc": out.inc, "resampled": out.resampled,
            "degen": out.degen, "invalid": out.invalid, "particles": out.hist_x, "weights": out.hist_w,
            "threads": workers if pooled else inner}, elapsed


