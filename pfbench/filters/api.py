"""``pfbench.run_filter``: one entry point for bootstrap, SIR, SIS, MultiPDF and ASIR.

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
particles each; the estimate at every step is the mean of the sub-filter estimates (eq. 9).
Its ``loglik`` is log of the mean of the sub-filters' likelihood estimates (each unbiased).

Numerical trouble
-----------------
Weights are handled in log space (log-sum-exp), so an outlier that makes every likelihood
underflow in linear scale still gives finite, correctly normalised weights. NaN or +inf
log-likelihoods count as zero likelihood. If *every* particle has zero likelihood at a step,
the step is flagged in ``degenerate``, the measurement is ignored (weights kept), the filter
carries on, and ``loglik`` becomes -inf (the estimate of p(y) really is 0); estimates never
become NaN. NaN/inf measurements are rejected up front with the first bad step named.
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from .. import backends
from ..errors import PfbenchError
from ..models.base import StateSpaceModel
from ..resampling import SCHEMES

METHODS = ("bootstrap", "sir", "sis", "multipdf", "asir")
_METHOD_CODES = {"bootstrap": 0, "sir": 1, "sis": 2, "asir": 3, "multipdf": 0}
_SCHEME_CODES = {name: i for i, name in enumerate(SCHEMES)}
DTYPES = ("float64", "float32")


@dataclass
class FilterResult:
    """What :func:`run_filter` returns.

    Attributes
    ----------
    estimates : (M, n_x) posterior-mean estimates (MultiPDF: mean of the sub-filter estimates).
    sub_estimates : (N_f, M, n_x) per-sub-filter estimates (N_f = 1 for single filters).
    variances : (M, n_x) posterior variances (MultiPDF: mean of the sub-filter variances).
    loglik : estimate of log p(y_1:M) (-inf if a step was degenerate).
    loglik_increments : (M,) estimates of log p(y_t | y_1:t-1) (filter 0 for MultiPDF).
    ess : (M,) effective sample size N_eff after weighting (MultiPDF: mean over sub-filters).
    sub_ess : (N_f, M).
    n_resampled : number of resampling events (summed over sub-filters).
    degenerate : (M,) bool, steps where every likelihood was zero in some sub-filter.
    elapsed_s : wall-clock time of the filtering (compilation excluded for numba, see below).
    """

    estimates: np.ndarray
    sub_estimates: np.ndarray
    variances: np.ndarray
    loglik: float
    loglik_increments: np.ndarray
    ess: np.ndarray
    sub_ess: np.ndarray
    n_resampled: int
    degenerate: np.ndarray
    elapsed_s: float
    method: str = ""
    backend: str = ""
    dtype: str = "float64"
    n_particles: int = 0
    n_filters: int = 1
    info: dict = field(default_factory=dict)

    @property
    def n_steps(self) -> int:
        return int(self.estimates.shape[0])

    @property
    def ns_per_particle_step(self) -> float:
        return self.elapsed_s * 1e9 / max(1, self.n_particles * self.n_steps)


def _check_inputs(model, y, u):
    if not isinstance(model, StateSpaceModel):
        raise PfbenchError("model must be a pfbench StateSpaceModel (see pfbench.models.get)")
    y = np.asarray(y, dtype=np.float64)
    if y.ndim == 1:
        y = y.reshape(-1, 1) if model.n_y == 1 else y.reshape(1, -1)
    if y.ndim != 2 or y.shape[1] != model.n_y or y.shape[0] < 1:
        raise ValueError(f"y must have shape (n_steps, {model.n_y}), got {np.shape(y)}")
    bad = ~np.isfinite(y).all(axis=1)
    if bad.any():
        t = int(np.argmax(bad))
        raise ValueError(f"measurement y at step {t} is not finite ({y[t].tolist()}); "
                         "remove or interpolate bad samples first")
    u = model.input_array(u, y.shape[0])
    if not np.isfinite(u).all():
        t = int(np.argmax(~np.isfinite(u).all(axis=1)))
        raise ValueError(f"input u at step {t} is not finite")
    return np.ascontiguousarray(y), np.ascontiguousarray(u)


def streams(seed, n_filters: int, common_random_numbers: bool) -> list[np.random.Generator]:
    """The random streams of a run (see the module docstring)."""
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    if common_random_numbers or n_filters == 1:
        return [np.random.default_rng(ss)]
    return [np.random.default_rng(s) for s in ss.spawn(n_filters)]


def run_filter(model: StateSpaceModel, y, u=None, *, method: str = "bootstrap", n_particles: int,
               n_filters: int = 1, resampling: str = "systematic", ess_threshold: float | None = None,
               backend: str = "numba", dtype: str = "float64", seed=0,
               common_random_numbers: bool = False, n_threads: int | None = None) -> FilterResult:
    """Run a particle filter on measurements ``y`` (M, n_y) with inputs ``u`` (M, n_u).

    Parameters
    ----------
    method : ``bootstrap`` (resample every step, [Embedded] Alg. 1), ``sir`` (resample when
        N_eff < ``ess_threshold``, default N/2; [MultiPDF] eq. 8), ``sis`` (never resample),
        ``multipdf`` ([MultiPDF] Alg. 2) or ``asir`` ([Thesis] Alg. 6).
    n_particles : N_p, total number of particles.
    n_filters : N_f, MultiPDF sub-filters (round(N_p/N_f) particles each); 1 otherwise.
    resampling : one of :data:`pfbench.resampling.SCHEMES`.
    backend : ``numpy`` (reference) or ``numba`` (compiled; first call compiles, then cached).
    dtype : particle storage precision, ``float64`` or ``float32``.
    seed : int or ``numpy.random.SeedSequence``.
    common_random_numbers : see the module docstring.
    n_threads : threads for parallel MultiPDF sub-filters (numba, CRN off); default: all cores.
    """
    if method not in METHODS:
        raise PfbenchError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if resampling not in _SCHEME_CODES:
        raise PfbenchError(f"unknown resampling scheme {resampling!r}; choose one of {', '.join(SCHEMES)}")
    if dtype not in DTYPES:
        raise PfbenchError(f"unknown dtype {dtype!r}; choose float64 or float32")
    backends.get(backend)  # validates the name
    n_particles, n_filters = int(n_particles), int(n_filters)
    if n_particles < 1:
        raise PfbenchError(f"n_particles must be >= 1, got {n_particles}")
    if n_filters < 1:
        raise PfbenchError(f"n_filters must be >= 1, got {n_filters}")
    if method != "multipdf" and n_filters != 1:
        raise PfbenchError(f"n_filters={n_filters} needs method='multipdf'")
    if n_filters > n_particles:
        raise PfbenchError(f"n_filters ({n_filters}) cannot exceed n_particles ({n_particles})")
    n_per = int(round(n_particles / n_filters)) if method == "multipdf" else n_particles
    n_per = max(n_per, 1)
    y, u = _check_inputs(model, y, u)
    thr = 0.5 * n_per if ess_threshold is None else float(ess_threshold)
    if method == "sir" and not (0 < thr <= n_per):
        raise PfbenchError(f"ess_threshold must be in (0, {n_per}], got {thr}")

    rngs = streams(seed, n_filters, common_random_numbers)
    out, elapsed = run_groups(model, y, u, rngs, method=method, n_per=n_per, n_filters=n_filters,
                              resampling=resampling, ess_threshold=thr, backend=backend, dtype=dtype,
                              n_threads=n_threads)
    est, var, ess, inc, resampled, degen = (out[k] for k in ("est", "var", "ess", "inc", "resampled", "degen"))
    n_groups = len(rngs)
    totals = inc.sum(axis=1)
    if n_filters == 1:
        loglik = float(totals[0])
    else:
        mx = totals.max()
        loglik = float(mx + np.log(np.mean(np.exp(totals - mx)))) if np.isfinite(mx) else float(mx)
    return FilterResult(
        estimates=est.mean(axis=0), sub_estimates=est, variances=var.mean(axis=0), loglik=loglik,
        loglik_increments=inc[0].copy(), ess=ess.mean(axis=0), sub_ess=ess,
        n_resampled=int(resampled.sum()), degenerate=degen.any(axis=0), elapsed_s=elapsed,
        method=method, backend=backend, dtype=dtype, n_particles=n_per * n_filters,
        n_filters=n_filters,
        info={"n_per_filter": n_per, "ess_threshold": thr if method == "sir" else None,
              "resampling": resampling, "common_random_numbers": bool(common_random_numbers),
              "n_streams": n_groups})


def run_groups(model, y, u, rngs, *, method: str, n_per: int, n_filters: int, resampling: str,
               ess_threshold: float, backend: str, dtype: str = "float64", n_threads: int | None = None):
    """Run ``n_filters`` filters of ``n_per`` particles on validated, contiguous ``y``/``u``.

    The filters are split evenly over the random streams ``rngs`` (one group per stream, see
    :func:`streams`); on numba, groups run in parallel threads (``n_threads``; default all cores,
    1 to stay sequential). Returns ``(arrays, elapsed_s)`` with per-filter arrays ``est``/``var``
    (N_f, M, n_x), ``ess``/``inc``/``resampled``/``degen`` (N_f, M). Used by :func:`run_filter`
    and by the sweep runner.
    """
    be = backends.get(backend)
    M, n_x = y.shape[0], model.n_x
    p = model.params()
    n_groups = len(rngs)
    per_group = n_filters // n_groups
    ptype = np.float32 if dtype == "float32" else np.float64
    x = np.empty((n_filters, n_per, n_x), dtype=ptype)
    out = {"est": np.empty((n_filters, M, n_x)), "var": np.empty((n_filters, M, n_x)),
           "ess": np.empty((n_filters, M)), "inc": np.empty((n_filters, M)),
           "resampled": np.zeros((n_filters, M), dtype=np.bool_),
           "degen": np.zeros((n_filters, M), dtype=np.bool_)}
    code, scheme = _METHOD_CODES[method], _SCHEME_CODES[resampling]
    if backend == "numba":
        be.warm_up(model, p, y, u, ptype)  # compile (or load from cache) outside the timed region

    def job(gi: int):
        sl = slice(gi * per_group, (gi + 1) * per_group)
        be.run_group(model, p, rngs[gi], y, u, x[sl], code, scheme, ess_threshold, out["est"][sl],
                     out["var"][sl], out["ess"][sl], out["inc"][sl], out["resampled"][sl], out["degen"][sl])

    t0 = time.perf_counter()
    workers = min(n_groups, n_threads or _cores())
    if n_groups > 1 and backend == "numba" and workers > 1:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(job, range(n_groups)))
    else:
        for gi in range(n_groups):
            job(gi)
    return out, time.perf_counter() - t0


def _cores() -> int:
    import os

    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover
        return os.cpu_count() or 1
