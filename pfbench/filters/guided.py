"""The guided particle filter: a model's own proposal, or the locally optimal one ([Doucet2000]).

A model opts in by setting ``proposal_kind`` (see :class:`pfbench.models.base.StateSpaceModel`):

``"proposal"`` - the model's own importance density q(x_t | x_{t-1}, y_t). Per step t::

    x_t^i ~ q(. | x_{t-1}^i, y_t)                        (``proposal``)
    log w_t^i = log w_{t-1}^i + log [p(y_t|x_t^i) p(x_t^i|x_{t-1}^i) / q(x_t^i|x_{t-1}^i, y_t)]
                                                         (``proposal_log_weight``)
    estimate = sum_i w_t^i x_t^i (weighted mean before resampling, as the particle kernel)
    resample when N_eff = 1 / sum_i (w_t^i)^2 < ess_threshold N_p

``"optimal"`` - the locally optimal proposal p(x_t | x_{t-1}, y_t) of [Doucet2000], whose incremental
weight p(y_t | x_{t-1}) does not depend on x_t, so the filter is *fully adapted*: weight first,
resample, then propagate ([Thesis] §4.2.1, eqs. 4.24-4.25, the order of the thesis SMC)::

    log w_t^i = log w_{t-1}^i + log p(y_t | x_{t-1}^i)   (``predictive_log_likelihood``)
    resample {x_{t-1}^i, w_t^i} when N_eff < ess_threshold N_p
    x_t^i ~ p(x_t | x_{t-1}^i, y_t)                      (``proposal``)
    estimate = sum_i w_t^i x_t^i

In both cases sum_i w_{t-1}^i exp(log-weight increment) estimates p(y_t | y_1:t-1) (the
``loglik_increments``); N_eff and ``extras["resampled"]`` are reported per step.

For models with additive Gaussian transition noise and a linear-Gaussian observation,
x_t = f(x_{t-1}, u_t) + w, w ~ N(0, Q), y_t = H x_t + v, v ~ N(0, R), the optimal proposal is
Gaussian ([Doucet2000]; [Thesis] eqs. 4.22-4.25)::

    S = (Q^-1 + H' R^-1 H)^-1,  m = S (Q^-1 f + H' R^-1 y),  x_t | x_{t-1}, y_t ~ N(m, S)
    p(y_t | x_{t-1}) = N(y_t; H f, R + H Q H')

:func:`optimal_gaussian_params` precomputes the constants (in the equivalent gain form
K = Q H' (H Q H' + R)^-1, m = f + K (y - H f), S = Q - K H Q, which also allows a singular Q) and
:func:`optimal_gaussian_proposal` / :func:`optimal_gaussian_log_predictive` are the two model
functions, callable from a model's ``proposal`` / ``predictive_log_likelihood`` under both backends
(the ``pmsm`` model uses them).

Backends and random numbers: the NumPy functions here are the readable reference, vectorised over
particles; :mod:`pfbench.backends.numba_guided` is the compiled twin. Both draw from one
``numpy.random.default_rng(seed)`` in the same order: the model's ``initial``, then per step
(own proposal) the proposal normals ``(N_p, n_proposal_noise)`` and the resampling draws if the
filter resamples, or (optimal) the resampling draws, then the proposal normals. One stream at
every N_p (no stream blocks, unlike the particle family above 8192 particles), and float64
normals whatever the particle dtype. Under the same seed the backends agree to round-off
(<= 1e-9, tested).

Per-step use from compiled code: :func:`step_functions` returns ``init`` / ``step`` functions that
run this NumPy reference when called from Python and the compiled kernel when called from a numba
function (the closed-loop PMSM simulation uses them).

Arguments: the steps take the groups of :mod:`pfbench.backends.guided_work`, as the kernel's do:
``particles`` (:class:`~pfbench.backends.guided_work.Particles`: x, lw), ``settings``
(:class:`~pfbench.backends.guided_work.Settings`: n_noise, scheme, threshold and the model's two
calls, here its NumPy functions) and ``moments`` (:class:`~pfbench.backends.guided_work.Moments`:
mean, var); a whole run fills :class:`~pfbench.backends.guided_work.Outputs`.
"""
from __future__ import annotations

import inspect
import time
from typing import NamedTuple

import numpy as np
from numba.extending import overload, register_jitable

from .. import resampling as _resampling
from ..backends import numba_backend as _numba_backend
from ..backends.guided_work import Moments, Outputs, Particles, Settings
from ..backends.kernels import build
from ..backends.numpy_backend import valid_log_likelihood, normalised_log_weights, weigh
from ..errors import InputError, UnsupportedError
from ..models.base import LOG_2PI, StateSpaceModel
from ..models.contract import shaped
from ..resampling import Scheme
from ..methods import Method, check_backend, check_dtype
from .inputs import check_inputs, ess_count, seed_sequence
from .result import FilterResult, reported_ess

#: model functions each kind of proposal needs (besides ``initial``)
KINDS = {"proposal": ("proposal", "proposal_log_weight"),
         "optimal": ("proposal", "predictive_log_likelihood")}


# --------------------------------------------------------------------------- the Gaussian optimal proposal
def optimal_gaussian_params(Q, H, R) -> tuple:
    """Constants of the Gaussian locally optimal proposal for x_t = f + w, w ~ N(0, Q), y = H x + v,
    v ~ N(0, R) ([Thesis] eqs. 4.22-4.25), as a numba-friendly tuple for a model's ``params()``.

    Returns ``(H', K', L', S_y^-1, log det S_y)`` with S_y = R + H Q H' (eq. 4.25),
    K = Q H' S_y^-1, S = Q - K H Q (= (Q^-1 + H' R^-1 H)^-1, eq. 4.22, also for singular Q) and
    L the lower-triangular Cholesky factor of S (so m + L z ~ N(m, S) for standard normals z, and
    for a diagonal S normal k drives state k, as in a model's ``transition``). All float64,
    C-contiguous.
    """
    Q = np.atleast_2d(np.asarray(Q, dtype=np.float64))
    H = np.atleast_2d(np.asarray(H, dtype=np.float64))
    R = np.atleast_2d(np.asarray(R, dtype=np.float64))
    n_x, n_y = Q.shape[0], H.shape[0]
    if Q.shape != (n_x, n_x) or H.shape != (n_y, n_x) or R.shape != (n_y, n_y):
        raise InputError(f"optimal Gaussian proposal needs Q (n_x, n_x), H (n_y, n_x), R (n_y, n_y); "
                         f"got {Q.shape}, {H.shape}, {R.shape}")
    Sy = R + H @ Q @ H.T
    Syi = np.linalg.inv(Sy)
    sign, logdet = np.linalg.slogdet(Sy)
    if sign <= 0:
        raise InputError("R + H Q H' must be positive definite")
    K = Q @ H.T @ Syi
    S = Q - K @ H @ Q
    L = _psd_cholesky(0.5 * (S + S.T))
    c = np.ascontiguousarray
    return (c(H.T), c(K.T), c(L.T), c(0.5 * (Syi + Syi.T)), float(logdet))


def _psd_cholesky(S: np.ndarray) -> np.ndarray:
    """Lower-triangular L with L L' = S for a symmetric positive *semi*-definite S (zero pivots give
    zero columns, e.g. noise-free states); falls back to a symmetric square root if that fails."""
    n = S.shape[0]
    L = np.zeros_like(S)
    tol = 1e-13 * max(float(np.abs(np.diag(S)).max()), np.finfo(float).tiny)
    for j in range(n):
        d = S[j, j] - L[j, :j] @ L[j, :j]
        if d > tol:
            L[j, j] = np.sqrt(d)
            L[j + 1:, j] = (S[j + 1:, j] - L[j + 1:, :j] @ L[j, :j]) / L[j, j]
    if not np.allclose(L @ L.T, S, rtol=1e-10, atol=1e-12 * max(1.0, float(np.abs(S).max()))):
        w, v = np.linalg.eigh(S)
        if w.min() < -1e-10 * max(1.0, float(np.abs(w).max())):
            raise InputError("the optimal proposal's covariance S is not positive semi-definite")
        L = v * np.sqrt(np.clip(w, 0.0, None))
    return L


@register_jitable
def rows_times(a, b):
    """a (n, k) @ b (k, m) as float64, summed column by column over k (vectorised over the n rows:
    for the small k, m of a state-space model this is fast under both backends, cheap to compile,
    and the same floating-point operations in NumPy and numba)."""
    out = np.zeros((a.shape[0], b.shape[1]))
    for j in range(b.shape[1]):
        for i in range(a.shape[1]):
            out[:, j] += a[:, i] * b[i, j]
    return out


@register_jitable
def _residual(f, y, ht):
    """y - H f per row of f."""
    r = rows_times(f, ht)
    for j in range(y.shape[0]):
        r[:, j] = y[j] - r[:, j]
    return r


@register_jitable
def optimal_gaussian_proposal(f, y, noise, g):
    """Draw x_t ~ N(m, S) for each row of f (n, n_x) (the noise-free transition f(x_{t-1}, u_t))
    with standard normals ``noise`` (n, n_x) and ``g`` from :func:`optimal_gaussian_params`:
    m = f + K (y - H f) ([Thesis] eq. 4.23), x = m + L z (eq. 4.24). Returns float64 (n, n_x)."""
    gain = rows_times(_residual(f, y, g[0]), g[1])
    spread = rows_times(noise, g[2])
    out = np.empty(gain.shape)
    for j in range(out.shape[1]):
        out[:, j] = f[:, j] + gain[:, j] + spread[:, j]
    return out


@register_jitable
def optimal_gaussian_log_predictive(f, y, g):
    """log p(y_t | x_{t-1}) = log N(y; H f, R + H Q H') per row of f ([Thesis] eq. 4.25); (n,)."""
    r = _residual(f, y, g[0])
    w = rows_times(r, g[3])
    quad = np.zeros(f.shape[0])
    for j in range(y.shape[0]):
        quad += w[:, j] * r[:, j]
    return -0.5 * quad - 0.5 * (y.shape[0] * LOG_2PI + g[4])


def optimal_gaussian_moments(f, y, Q, H, R):
    """Dense reference in the information form of [Thesis] eqs. 4.22-4.25 for one f (n_x,):
    returns (m, S, log p(y | x_{t-1})) with S^-1 = Q^-1 + H' R^-1 H, m = S (Q^-1 f + H' R^-1 y).
    Needs an invertible Q (tests and documentation; the filter uses the gain form)."""
    f, y = np.asarray(f, dtype=np.float64), np.asarray(y, dtype=np.float64)
    Q, H, R = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (Q, H, R))
    Qi, Ri = np.linalg.inv(Q), np.linalg.inv(R)
    S = np.linalg.inv(Qi + H.T @ Ri @ H)
    m = S @ (Qi @ f + H.T @ Ri @ y)
    Sy = R + H @ Q @ H.T
    res = y - H @ f
    ll = -0.5 * res @ np.linalg.solve(Sy, res) - 0.5 * (y.size * LOG_2PI + np.linalg.slogdet(Sy)[1])
    return m, S, float(ll)


# --------------------------------------------------------------------------- contract checks
def proposal_kind(model_or_cls) -> str:
    """The model's ``proposal_kind`` after checking it defines what that kind needs, else UnsupportedError."""
    cls = model_or_cls if isinstance(model_or_cls, type) else type(model_or_cls)
    kind = getattr(cls, "proposal_kind", None)
    name = getattr(cls, "name", "") or cls.__name__
    if kind is None:
        raise UnsupportedError(
            f"model {name!r} declares no proposal, so method 'guided' cannot run it: set "
            "proposal_kind = 'proposal' (with proposal and proposal_log_weight) or 'optimal' "
            "(with proposal and predictive_log_likelihood); see pfbench.models.base.StateSpaceModel")
    if kind not in KINDS:
        raise UnsupportedError(f"model {name!r}: proposal_kind must be one of {', '.join(KINDS)}, "
                               f"got {kind!r}")
    for fn in ("initial",) + KINDS[kind]:
        if inspect.getattr_static(cls, fn) is inspect.getattr_static(StateSpaceModel, fn):
            raise UnsupportedError(f"model {name!r} has proposal_kind={kind!r} but does not define {fn}")
    return kind


def _n_noise(model_or_cls) -> int:
    """Standard normals per particle that ``proposal`` takes (``n_proposal_noise``, else ``n_noise``;
    read from the instance when given, as models may set them in ``__init__``)."""
    n = getattr(model_or_cls, "n_proposal_noise", None)
    return int(model_or_cls.n_noise if n is None else n)


def _functions(cls) -> dict:
    return {fn: getattr(inspect.getattr_static(cls, fn), "__func__", None)
            for fn in ("initial", "proposal", "proposal_log_weight", "predictive_log_likelihood")}


# --------------------------------------------------------------------------- NumPy reference steps
def _moments(x, wu, total, mean, var) -> float:
    """Weighted mean/variance into ``mean``/``var``; returns N_eff (as the particle kernel's NumPy path)."""
    m = (wu @ x) / total
    mean[:] = m
    var[:] = (wu @ (x - m) ** 2) / total
    wn = wu / total
    return float(1.0 / np.cumsum(wn * wn)[-1])


def _resample(particles, wu, scheme, rng) -> None:
    x, lw = particles
    x[:] = x[_resampling.get(Scheme(scheme))(wu, rng)]
    lw[:] = -np.log(x.shape[0])


def numpy_init(fns, p, rng, x, lw) -> None:
    """x_{-1} ~ the model's prior, equal weights (NumPy twin of ``numba_guided.init``)."""
    n = x.shape[0]
    x[:] = fns["initial"](rng, n, p)
    lw[:] = -np.log(n)


def _reweigh(particles, ll, settings, rng, moments):
    """Weigh (log-sum-exp), N_eff, then resample or keep the normalised log-weights: the part both
    kinds of step share. Returns (increment, N_eff, resampled, degenerate, wu, total), with
    ``wu``/``total`` the equal weights after a resampling."""
    x, lw = particles
    wu, _, m, total, deg = weigh(lw, ll)
    inc = -np.inf if deg else m + np.log(total)
    e = _moments(x, wu, total, *moments)
    do = bool(e < settings.threshold)
    if do:
        _resample(particles, wu, settings.scheme, rng)
        wu, total = np.ones(x.shape[0]), float(x.shape[0])
    else:
        lw[:] = normalised_log_weights(wu, total)
    return inc, e, do, bool(deg), wu, total


def numpy_step_proposal(p, rng, particles, y, u, t, settings, moments):
    """One step with the model's own proposal (see the module docstring); NumPy twin of
    ``numba_guided.step_proposal``, ``settings`` with the model's ``proposal`` and
    ``proposal_log_weight``. Returns (increment, N_eff, resampled, degenerate)."""
    x = particles.x
    noise = rng.standard_normal((x.shape[0], settings.n_noise))
    xn = np.empty_like(x)
    xn[:] = settings.propose(x, y, u, t, noise, p)
    ll = valid_log_likelihood(settings.weight(xn, x, y, u, t, p))
    x[:] = xn
    return _reweigh(particles, ll, settings, rng, moments)[:4]


def numpy_step_optimal(p, rng, particles, y, u, t, settings, moments):
    """One fully adapted step with the locally optimal proposal (see the module docstring); NumPy
    twin of ``numba_guided.step_optimal``, ``settings`` with the model's ``proposal`` and
    ``predictive_log_likelihood``. Returns (increment, N_eff, resampled, degenerate)."""
    x = particles.x
    ll = valid_log_likelihood(settings.weight(y, x, u, t, p))
    inc, e, do, deg, wu, total = _reweigh(particles, ll, settings, rng, moments)
    noise = rng.standard_normal((x.shape[0], settings.n_noise))
    xn = np.empty_like(x)
    xn[:] = settings.propose(x, y, u, t, noise, p)
    x[:] = xn
    _moments(x, wu, total, *moments)
    return inc, e, do, deg


_NUMPY_STEPS = {"proposal": numpy_step_proposal, "optimal": numpy_step_optimal}


def _numpy_calls(model, fns, kind) -> dict:
    """The model's two NumPy functions of a ``kind`` as the :class:`Settings` fields ``propose``, ``weight``,
    each result checked at every step (:func:`~pfbench.models.contract.shaped`): a proposal of another
    shape would otherwise broadcast into the particles unseen. Both weight functions take the
    particles second and the step second to last."""
    propose_name, weight_name = KINDS[kind]
    propose, weight = fns[propose_name], fns[weight_name]

    def checked_propose(x, y, u, t, noise, p):
        return shaped(model, propose_name, propose(x, y, u, t, noise, p), x.shape, f"at step {t}")

    def checked_weight(*args):
        return shaped(model, weight_name, weight(*args), (args[1].shape[0],), f"at step {args[-2]}")

    return {"propose": checked_propose, "weight": checked_weight}


# --------------------------------------------------------------- per-step functions for compiled callers
class StepFunctions(NamedTuple):
    """``init(p, rng, x, lw)`` and ``step(p, rng, particles, y, u, t, settings, moments) -> (increment,
    N_eff, resampled, degenerate)`` of one model class, with the groups of
    :mod:`pfbench.backends.guided_work` (a caller's ``settings`` need no call addresses:
    ``Settings(n_noise, scheme, threshold, 0, 0)``, all five fields in compiled code); ``kind`` and
    ``n_noise`` of the model."""

    init: object
    step: object
    kind: str
    n_noise: int


_STEPS: dict[type, StepFunctions] = {}


def step_functions(model_cls) -> StepFunctions:
    """Per-step guided-filter functions of a model class, for code that runs the filter one step at a
    time (e.g. inside a closed loop).

    Called from Python they run the NumPy reference; called from a numba-compiled function they
    compile to the model's guided kernel (:func:`pfbench.backends.kernels.build`,
    family ``"guided"``), so one loop body serves both backends. Reference them as module globals
    of the compiled caller, and call this at import of the caller's module: it imports the kernel
    module, which numba needs (by name) to load the caller from its disk cache in a new process.
    """
    cls = model_cls if isinstance(model_cls, type) else type(model_cls)
    if cls in _STEPS:
        return _STEPS[cls]
    kind = proposal_kind(cls)
    fns = _functions(cls)
    np_step, calls = _NUMPY_STEPS[kind], _numpy_calls(cls, fns, kind)
    module = build("guided", cls)
    kernel_init, kernel_step = module.init, getattr(module, f"step_{kind}")

    def init(p, rng, x, lw):
        numpy_init(fns, p, rng, x, lw)

    def step(p, rng, particles, y, u, t, settings, moments):
        return np_step(p, rng, particles, y, u, t, settings._replace(**calls), moments)

    @overload(init)
    def _init_numba(p, rng, x, lw):
        def impl(p, rng, x, lw):
            kernel_init(p, rng, x, lw)
        return impl

    @overload(step)
    def _step_numba(p, rng, particles, y, u, t, settings, moments):
        def impl(p, rng, particles, y, u, t, settings, moments):
            return kernel_step(p, rng, particles, y, u, t, settings, moments)
        return impl

    _STEPS[cls] = StepFunctions(init, step, kind, _n_noise(cls))
    return _STEPS[cls]


# --------------------------------------------------------------------------- whole runs
def _run_numpy(model, kind, p, rng, y, u, particles, out, settings):
    fns = _functions(type(model))
    step, settings = _NUMPY_STEPS[kind], settings._replace(**_numpy_calls(model, fns, kind))
    numpy_init(fns, p, rng, *particles)
    for t in range(y.shape[0]):
        out.inc[t], out.ess[t], out.resampled[t], out.degen[t] = step(
            p, rng, particles, y[t], u[t], t, settings, Moments(out.est[t], out.var[t]))


_WARM: set = set()


def _run_numba(model, kind, p, rng, y, u, particles, out, settings):
    numpy_init(_functions(type(model)), p, rng, *particles)  # in NumPy, as the reference: the kernel continues
    _numba_backend.run_guided(model, kind, p, rng, y, u, particles, out, settings)


def _warm_up(model, kind, p, y, u, particles, out, settings) -> None:
    """Compile (or load) the kernel outside the timed region: one step and one particle (copies), on a
    throwaway generator."""
    key = (type(model), kind, particles.x.dtype.str, settings.scheme, tuple(type(v).__name__ for v in p))
    if key in _WARM:
        return
    _run_numba(model, kind, p, np.random.default_rng(0), y[:1], u[:1], Particles(*(a[:1].copy() for a in particles)),
               Outputs(*(a[:1].copy() for a in out)), settings._replace(threshold=0.5))
    _WARM.add(key)


def run_guided(model, y, u=None, *, n_particles: int, resampling="systematic", ess_threshold=None,
               backend: str = "numba", dtype: str = "float64", seed=0) -> FilterResult:
    """Run the guided filter with the model's proposal (see the module docstring).

    Parameters
    ----------
    model : a :class:`~pfbench.models.base.StateSpaceModel` with ``proposal_kind`` set; otherwise
        :class:`~pfbench.errors.UnsupportedError`.
    y, u : measurements (M, n_y) and inputs (M, n_u).
    n_particles : N_p.
    resampling : a :class:`~pfbench.resampling.Scheme` name.
    ess_threshold : resample when N_eff < ess_threshold * N_p; a fraction in (0, 1], default 0.5.
    backend : ``numpy`` (reference) or ``numba``.
    dtype : particle storage, ``float64`` or ``float32`` (weights are always float64).
    seed : int or ``numpy.random.SeedSequence``; one stream, see the module docstring.

    Returns a :class:`~pfbench.filters.result.FilterResult` with ``method="guided"``,
    ``extras["resampled"]`` (M,) bool and ``info`` (``proposal_kind``, ``resampling``,
    ``ess_threshold`` as a particle count).
    """
    kind = proposal_kind(model)
    check_backend(backend)
    check_dtype(dtype)
    scheme = Scheme.parse(resampling)
    try:
        n = int(n_particles)
        ok = n == n_particles and n >= 1
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise InputError(f"n_particles must be an integer >= 1, got {n_particles!r}")
    threshold = ess_count(ess_threshold, n)
    y, u = check_inputs(model, y, u)
    rng = np.random.default_rng(seed_sequence(seed))
    M, n_x = y.shape[0], model.n_x
    p = model.params()
    settings = Settings(_n_noise(model), int(scheme), float(threshold))
    particles = Particles(np.empty((n, n_x), dtype=np.float32 if dtype == "float32" else np.float64), np.empty(n))
    out = Outputs(np.empty((M, n_x)), np.empty((M, n_x)), np.empty(M), np.empty(M), np.zeros(M, np.bool_),
                  np.zeros(M, np.bool_))
    if backend == "numba":
        _warm_up(model, kind, p, y, u, particles, out, settings)
        run = _run_numba
    else:
        run = _run_numpy
    t0 = time.perf_counter()
    run(model, kind, p, rng, y, u, particles, out, settings)
    elapsed = time.perf_counter() - t0
    return FilterResult(
        estimates=out.est, variances=out.var, loglik=float(out.inc.sum()), loglik_increments=out.inc,
        ess=reported_ess(out.ess, out.degen), n_resampled=int(out.resampled.sum()), degenerate=out.degen,
        elapsed_s=elapsed,
        method=Method.GUIDED.label, backend=backend, dtype=dtype, n_particles=n, n_filters=1,
        extras={"resampled": out.resampled},
        info={"proposal_kind": kind, "resampling": scheme.label, "ess_threshold": threshold,
              "n_proposal_noise": settings.n_noise})
