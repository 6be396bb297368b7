"""``pfbench.run_filter``: one entry point for every filtering method of :class:`Method`."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..models.contract import check_model, named_model_errors, needs_of
from ..methods import ARRAY_BACKENDS, Estimate, Method, check_dtype
from ..resampling import Scheme
from .inputs import check_inputs
from .result import FilterResult


def _count(value, name: str, minimum: int = 1) -> int:
    try:
        v = int(value)
        ok = v == value and not isinstance(value, (bool, np.bool_))   # True is not one particle
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok or v < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return v


def run_filter(model, y, u=None, *, method: str = "bootstrap", n_particles: int | None = None,
               n_filters: int = 1, resampling: str = "systematic", ess_threshold: float | None = None,
               backend: str = "numba", dtype: str = "float64", seed=0,
               common_random_numbers: bool = False, n_threads: int | None = None,
               store_particles: bool = False, estimate: str = "pre",
               _block: int | None = None) -> FilterResult:
    """Filter measurements ``y`` (M, n_y) with inputs ``u`` (M, n_u); returns a :class:`FilterResult`.

    Parameters
    ----------
    method : a :class:`~pfbench.methods.Method` name: ``bootstrap`` ([Embedded] Alg. 1),
        ``sir`` (resample when N_eff < ``ess_threshold`` N_p; [MultiPDF] eq. 8), ``sis``,
        ``asir`` ([Thesis] Alg. 6), ``multipdf`` ([MultiPDF] Alg. 2), ``mpf`` (marginalized PF on
        the model's declared linear-Gaussian substructure, [Schon2005]), ``guided`` (the model's
        proposal or the locally optimal one) or ``kalman`` ((extended) Kalman filter on a model
        whose every state is in its linear substructure).
    n_particles : N_p, total number of particles (required by every method but ``kalman``). A run
        whose estimated memory does not fit what the process may use is refused before anything
        is allocated (InputError with both numbers and the largest N_p that fits, see
        :mod:`pfbench.resources`).
    n_filters : N_f, MultiPDF sub-filters (round(N_p/N_f) particles each); 1 otherwise.
    resampling : a :class:`~pfbench.resampling.Scheme` name.
    ess_threshold : SIR and guided: resample when N_eff < ess_threshold * N_p; a fraction in
        (0, 1], default 0.5 (as in the ``particles`` library).
    backend : ``numpy`` (reference), ``numba`` (compiled; first call compiles, then cached) or
        ``cupy`` (bootstrap, SIR, SIS, MultiPDF on a GPU; systematic or stratified resampling; its
        own counter-based random numbers, see :mod:`pfbench.backends.array_backend`;
        ``xp-numpy`` runs the same code on NumPy).
    dtype : particle storage precision, ``float64`` or ``float32``.
    seed : int or ``numpy.random.SeedSequence``.
    common_random_numbers : one random stream for everything (see :mod:`pfbench.filters.particle`);
        the MPF, guided and Kalman filters always draw from one stream.
    n_threads : numba threads (default None: the cores free now, :func:`pfbench.procs.free_cores`,
        so a busy machine gets fewer threads instead of a collapse; 1: sequential). One filter with more than
        one stream block (N_p > :data:`pfbench.backends.numpy_backend.BLOCK`) runs its particle
        loops on them; MultiPDF without common random numbers runs its sub-filters in parallel
        instead (each on one thread). Results never depend on it.
    store_particles : particle family only: keep the weighted particles of every step (before
        resampling) in ``extras["particles"]`` (N_f, M, N, n_x) and ``extras["weights"]`` (N_f, M, N).
    estimate : where a step's point estimate (``estimates``, ``variances``) is taken (an
        :class:`~pfbench.methods.Estimate` name; the particle methods record it in
        ``info["estimate"]``).
        ``pre`` (default): the weighted mean and variance of the weighted particles, before the
        step's resampling. ``post``: the unweighted mean and variance of the particles after the
        step's resampling, as [MultiPDF] Alg. 1-2 take it (Alg. 1 step 6 after step 5; Alg. 2 step
        2e after 2d); MultiPDF averages the sub-filters' post estimates (eq. 9). At a step that does
        not resample (SIR with N_eff >= the threshold, SIS always, ASIR always: its resampling comes
        before the step's propagation) ``post`` is ``pre``. Resampling is unbiased, so ``post`` is
        ``pre`` plus zero-mean resampling noise: same random numbers, same ``loglik``, ``ess`` and
        trajectory. Particle methods only: ``post`` with mpf, guided or kalman is an InputError,
        as is ``post`` on the array backends (``cupy``, ``xp-numpy``).
    """
    m = Method.parse(method)
    est_at = Estimate.parse(estimate)
    dtype = check_dtype(dtype)      # checked for every method: the Kalman filter's too, which ignores them
    Scheme.parse(resampling)
    if n_threads is not None:
        n_threads = _count(n_threads, "n_threads")
    for flag, value in (("common_random_numbers", common_random_numbers), ("store_particles", store_particles)):
        if not isinstance(value, (bool, np.bool_)):  # 'no' was taken as True
            raise InputError(f"{flag} must be True or False, got {value!r}")
    if est_at == Estimate.POST and m.family != "particle":
        raise InputError(f"estimate='post' applies to the particle methods "
                         f"({', '.join(l for l in Method.labels() if Method.parse(l).family == 'particle')}), "
                         f"not {m.label!r}")
    if n_particles is None:
        if m.family != "kalman":
            raise InputError(f"method {m.label!r} needs n_particles")
        n_particles = 1
    n_particles = _count(n_particles, "n_particles")
    n_filters = _count(n_filters, "n_filters")
    y, u = check_inputs(model, y, u)
    check_model(model, y, u, needs_of(m.family, m.label))   # a mistake in the model's code: one line
    from ..resources import check_filter_memory  # refuse before allocating what cannot fit

    check_filter_memory(model, m.label, n_particles, n_filters=n_filters, n_steps=y.shape[0], dtype=dtype,
                        backend=backend, store_particles=store_particles, flag="n_particles")
    with named_model_errors(model, y, u, backend):
        if m.family == "particle":
            from .particle import run_particle

            return _named(model, run_particle(
                model, y, u, method=m, n_particles=n_particles, n_filters=n_filters, resampling=resampling,
                ess_threshold=ess_threshold, backend=backend, dtype=dtype, seed=seed,
                common_random_numbers=common_random_numbers, n_threads=n_threads,
                store_particles=store_particles, estimate=est_at.label, _block=_block))
        if n_filters != 1:
            raise InputError(f"n_filters={n_filters} needs method='multipdf'")
        if backend in ARRAY_BACKENDS:
            raise InputError(f"backend {backend!r} runs the particle methods bootstrap, sir, sis and "
                             f"multipdf, not {m.label!r}")
        if store_particles:
            raise InputError(f"store_particles is available for the particle methods, not {m.label!r}")
        if m.family == "mpf":
            from .marginalized import run_mpf

            return _named(model, run_mpf(model, y, u, n_particles=n_particles, resampling=resampling,
                                         backend=backend, seed=seed, dtype=dtype, ess_threshold=ess_threshold))
        if m.family == "kalman":
            from .marginalized import run_kalman

            return _named(model, run_kalman(model, y, u, backend=backend))
        from .guided import run_guided

        return _named(model, run_guided(model, y, u, n_particles=n_particles, resampling=resampling,
                                        ess_threshold=ess_threshold, backend=backend, dtype=dtype, seed=seed))


def _named(model, res: FilterResult) -> FilterResult:
    """``res`` with the model's ``state_names`` in ``info``, which :meth:`FilterResult.to_dataframe`
    names its columns by (ob3's x1..x4 were x0..x3 there)."""
    if getattr(model, "state_names", None):
        res.info.setdefault("state_names", [str(s) for s in model.state_names])
    return res
