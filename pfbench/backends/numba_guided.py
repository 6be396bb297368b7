"""The numba guided-filter kernel: a model's own proposal, or the locally optimal one.

This is the compiled twin of the NumPy reference in :mod:`pfbench.filters.guided`: the same steps,
the same random draws in the same order, the same weighting (:mod:`pfbench.backends.numba_weights`)
and resampling (:mod:`pfbench.backends.numba_resampling`, the scheme bound as ``_resample``). It calls the model through
four module globals, ``_initial``, ``_proposal``, ``_proposal_log_weight`` and
``_predictive_log_likelihood``. As a file it is importable (they are placeholders here);
:func:`pfbench.backends.numba_backend.kernel_module` (family ``"guided"``) writes a copy of it per
model class with the model's compiled functions bound to those names at the end.

Each kind of proposal has its own step and run functions, so numba only ever compiles the model
functions that kind uses (a model with its own proposal need not define
``predictive_log_likelihood`` and vice versa). A whole run starts from particles the caller drew
in NumPy; :func:`init` and the ``step_*`` functions are called one step at a time from other
compiled code (the closed-loop PMSM simulation), through
:func:`pfbench.filters.guided.step_functions`.

:func:`init`, :func:`_reweigh` and the ``step_*`` functions are ``inline="always"``: numba inlines
them into the function that calls them, so a whole run (or a closed-loop caller) is compiled and
optimised once instead of once per level (seconds less on a cold cache; the same operations).

Arguments shared by the step functions: ``p`` the model's ``params()``, ``rng`` the generator,
``x`` (n, n_x) particles (updated in place; their dtype is the particle dtype), ``lw`` (n,)
normalised log-weights (updated in place), ``y``/``u`` the measurement and input of step ``t``,
``n_noise`` standard normals per particle for the proposal, ``scheme`` a
:class:`~pfbench.resampling.Scheme` code, ``threshold`` the resampling threshold as a particle count
(resample when N_eff < threshold), ``mean``/``var`` (n_x,) outputs: the weighted mean and variance of
the particles of step t. They return ``(loglik increment, N_eff, resampled, degenerate)``.
"""
import numpy as _np

from pfbench.backends.cache import njit as _njit
from pfbench.backends.numba_weights import moments as _moments
from pfbench.backends.numba_weights import normalised_log_weights as _normalised_log_weights
from pfbench.backends.numba_weights import weigh as _weigh


def _initial(rng, n, p):  # pragma: no cover - bound per model in the generated module
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _proposal(x_prev, y, u, t, noise, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _proposal_log_weight(x, x_prev, y, u, t, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _predictive_log_likelihood(y, x_prev, u, t, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _resample(code, w, cdf, rng, idx):  # pragma: no cover - bound per run by kernel_module
    raise NotImplementedError("bound per scheme by pfbench.backends.numba_backend.kernel_module")


@_njit(nogil=True, inline="always")
def init(p, rng, x, lw):
    """x_{-1} ~ the model's prior, equal weights."""
    n = x.shape[0]
    x[:] = _initial(rng, n, p)
    lw[:] = -_np.log(n)


@_njit(nogil=True, inline="always")
def _reweigh(x, lw, ll, scheme, threshold, rng, mean, var, wu, cdf):
    """Weigh (log-sum-exp), N_eff, then resample or keep the normalised log-weights (twin of
    ``pfbench.filters.guided._reweigh``). Returns (increment, N_eff, resampled, degenerate, total);
    ``wu`` holds equal weights after a resampling."""
    n = x.shape[0]
    m, total, deg = _weigh(lw, ll, wu, cdf)
    inc = -_np.inf if deg else m + _np.log(total)
    e = _moments(x, wu, total, mean, var)
    do = e < threshold
    if do:  # resample and gather in place (inline: one compiled function less on a cold cache)
        idx = _np.empty(n, _np.int64)
        _resample(scheme, wu, cdf, rng, idx)
        buf = x.copy()
        for i in range(n):
            for a in range(x.shape[1]):
                x[i, a] = buf[idx[i], a]
        lw[:] = -_np.log(n)
        wu[:] = 1.0
        total = float(n)
    else:
        _normalised_log_weights(wu, total, lw)
    return inc, e, do, deg, total


@_njit(nogil=True, inline="always")
def step_proposal(p, rng, x, lw, y, u, t, n_noise, scheme, threshold, mean, var):
    """The model's own proposal: x_t ~ q(. | x_{t-1}, y_t), weight by ``proposal_log_weight``,
    estimate (weighted mean before resampling), resample when N_eff < threshold ([Doucet2000])."""
    n = x.shape[0]
    noise = rng.standard_normal((n, n_noise))
    xn = _np.empty_like(x)
    xn[:] = _proposal(x, y, u, t, noise, p)
    ll = _proposal_log_weight(xn, x, y, u, t, p).astype(_np.float64)
    x[:] = xn
    inc, e, do, deg, _ = _reweigh(x, lw, ll, scheme, threshold, rng, mean, var, _np.empty(n), _np.empty(n))
    return inc, e, do, deg


@_njit(nogil=True, inline="always")
def step_optimal(p, rng, x, lw, y, u, t, n_noise, scheme, threshold, mean, var):
    """The locally optimal proposal, fully adapted order ([Doucet2000]; [Thesis] eqs. 4.24-4.25):
    weight by p(y_t | x_{t-1}), resample when N_eff < threshold, then propagate
    x_t ~ p(x_t | x_{t-1}, y_t); the estimate is the weighted mean of the propagated particles."""
    n = x.shape[0]
    wu = _np.empty(n)
    ll = _predictive_log_likelihood(y, x, u, t, p).astype(_np.float64)
    inc, e, do, deg, total = _reweigh(x, lw, ll, scheme, threshold, rng, mean, var, wu, _np.empty(n))
    noise = rng.standard_normal((n, n_noise))
    xn = _np.empty_like(x)
    xn[:] = _proposal(x, y, u, t, noise, p)
    x[:] = xn
    _moments(x, wu, total, mean, var)
    return inc, e, do, deg


@_njit(nogil=True)
def run_proposal(p, rng, y, u, x, lw, n_noise, scheme, threshold, est, var, ess, inc, resampled, degen):
    """All M steps with the model's own proposal; outputs (M, ...) filled in place.

    ``x``, ``lw``: the initial particles and log-weights, drawn from ``rng`` by the caller with the
    model's NumPy ``initial`` (:func:`pfbench.filters.guided.numpy_init`, the NumPy reference's
    draw; the kernel continues the same stream), so a whole run does not compile the model's
    ``initial`` (measured: 1.55 s of a cold start on the reduced PMSM model)."""
    for t in range(y.shape[0]):
        inc[t], ess[t], resampled[t], degen[t] = step_proposal(
            p, rng, x, lw, y[t], u[t], t, n_noise, scheme, threshold, est[t], var[t])


@_njit(nogil=True)
def run_optimal(p, rng, y, u, x, lw, n_noise, scheme, threshold, est, var, ess, inc, resampled, degen):
    """All M steps with the locally optimal proposal; outputs (M, ...) filled in place (``x``,
    ``lw`` initialised by the caller, as for :func:`run_proposal`)."""
    for t in range(y.shape[0]):
        inc[t], ess[t], resampled[t], degen[t] = step_optimal(
            p, rng, x, lw, y[t], u[t], t, n_noise, scheme, threshold, est[t], var[t])
