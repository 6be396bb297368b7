"""The numba guided-filter kernel: a model's own proposal, or the locally optimal one.

This is the compiled twin of the NumPy reference in :mod:`pfbench.filters.guided`: the same steps,
the same random draws in the same order, the same weighting (:mod:`pfbench.backends.numba_weights`)
and resampling (:mod:`pfbench.backends.numba_resampling`, the scheme bound as ``_resample``). It calls the model through
four module globals, ``_initial``, ``_proposal``, ``_proposal_log_weight`` and
``_predictive_log_likelihood``. As a file it is importable (they are placeholders here);
:func:`pfbench.backends.kernels.build` (family ``"guided"``) runs it per model class with the
model's compiled functions bound to those names. A whole run takes the named groups of
:mod:`pfbench.backends.guided_work`.

Each kind of proposal has its own step and run functions, so numba only ever compiles the model
functions that kind uses (a model with its own proposal need not define
``predictive_log_likelihood`` and vice versa). A whole run starts from particles the caller drew
in NumPy; :func:`init` and the ``step_*`` functions are called one step at a time from other
compiled code (the closed-loop PMSM simulation), through
:func:`pfbench.filters.guided.step_functions`.

:func:`init`, :func:`_reweigh` and the ``step_*`` functions are ``inline="always"``: numba inlines
them into the function that calls them, so a whole run (or a closed-loop caller) is compiled and
optimised once instead of once per level (seconds less on a cold cache; the same operations). A
whole run calls the model itself by address (see "the model's calls" below): measured on the
reduced PMSM model, a cold ``pfbench run --method guided`` 4.7-5.0 s with the model inlined, 3.2-3.3 s
with the model's wrappers compiled in a helper meanwhile; the run 69.0 vs 70.0 ns per
particle-step (N_p = 1000).

Arguments shared by the step functions: ``p`` the model's ``params()``, ``rng`` the generator,
``x`` (n, n_x) particles (updated in place; their dtype is the particle dtype), ``lw`` (n,)
normalised log-weights (updated in place), ``y``/``u`` the measurement and input of step ``t``,
``n_noise`` standard normals per particle for the proposal, ``scheme`` a
:class:`~pfbench.resampling.Scheme` code, ``threshold`` the resampling threshold as a particle count
(resample when N_eff < threshold), ``mean``/``var`` (n_x,) outputs: the weighted mean and variance of
the particles of step t. They return ``(loglik increment, N_eff, resampled, degenerate)``.
"""
import numpy as _np

from pfbench.backends.kernels import binding as _binding
from pfbench.backends.native_call import caller as _caller
from pfbench.backends.numba_weights import moments as _moments
from pfbench.backends.numba_weights import normalised_log_weights as _normalised_log_weights
from pfbench.backends.numba_weights import weigh as _weigh


# ---- what :func:`pfbench.backends.kernels.build` binds for a model and a scheme
_b = _binding()
_njit = _b.jit
_initial = _b.model("initial")
_proposal = _b.model("proposal")
_proposal_log_weight = _b.model("proposal_log_weight")
_predictive_log_likelihood = _b.model("predictive_log_likelihood")
_resample = _b.resample
#: the resampling scheme's code, -1 in the any-scheme module (per-step use from compiled callers,
#: and the module a compile helper builds the model's calls from)
_SCHEME = _b.scheme
_call6 = _caller(6)
_call7 = _caller(7)

# --------------------------------------------------------------------------- the model's calls
# A whole run (``run_proposal``/``run_optimal``, in a scheme's module) calls the model through
# these, by address (:mod:`pfbench.backends.native_call`; ``addresses`` = (proposal, weight)): they
# are the model's code, compiled once per model for all schemes (``SCHEME_FREE`` in
# :mod:`pfbench.backends.numba_backend`) and, on a cold cache, in a helper process while the run
# compiles here (:mod:`pfbench.backends.compile_helper`). The any-scheme module, which serves
# per-step use from other compiled code, calls the model directly (``_SCHEME == -1``, a constant
# numba prunes on). Only ever called by address: no CPython wrapper.


@_njit(nogil=True, no_cpython_wrapper=True)
def _propose_into(x, y, u, t, noise, p, xn):
    """xn = the model's ``proposal(x, y, u, t, noise, p)``."""
    xn[:] = _proposal(x, y, u, t, noise, p)


@_njit(nogil=True, no_cpython_wrapper=True)
def _weight_into(xn, x, y, u, t, p, ll):
    """ll = the model's ``proposal_log_weight(xn, x, y, u, t, p)`` in float64."""
    ll[:] = _proposal_log_weight(xn, x, y, u, t, p)


@_njit(nogil=True, no_cpython_wrapper=True)
def _predictive_into(y, x, u, t, p, ll):
    """ll = the model's ``predictive_log_likelihood(y, x, u, t, p)`` in float64."""
    ll[:] = _predictive_log_likelihood(y, x, u, t, p)


_propose_into = _b.shared("_propose_into", _propose_into)
_weight_into = _b.shared("_weight_into", _weight_into)
_predictive_into = _b.shared("_predictive_into", _predictive_into)


@_njit(nogil=True, inline="always")
def _propose(x, y, u, t, noise, p, addresses):
    xn = _np.empty_like(x)
    if _SCHEME == -1:  # compile-time constant
        xn[:] = _proposal(x, y, u, t, noise, p)
    else:
        _call7(_propose_into, addresses[0], x, y, u, t, noise, p, xn)
    return xn


@_njit(nogil=True, inline="always")
def _weight(xn, x, y, u, t, p, addresses):
    if _SCHEME == -1:
        return _proposal_log_weight(xn, x, y, u, t, p).astype(_np.float64)
    ll = _np.empty(x.shape[0])
    _call7(_weight_into, addresses[1], xn, x, y, u, t, p, ll)
    return ll


@_njit(nogil=True, inline="always")
def _predictive(y, x, u, t, p, addresses):
    if _SCHEME == -1:
        return _predictive_log_likelihood(y, x, u, t, p).astype(_np.float64)
    ll = _np.empty(x.shape[0])
    _call6(_predictive_into, addresses[1], y, x, u, t, p, ll)
    return ll


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
def step_proposal(p, rng, x, lw, y, u, t, n_noise, scheme, threshold, mean, var, addresses=None):
    """The model's own proposal: x_t ~ q(. | x_{t-1}, y_t), weight by ``proposal_log_weight``,
    estimate (weighted mean before resampling), resample when N_eff < threshold ([Doucet2000]).
    ``addresses``: see "the model's calls" above (unused in the any-scheme module)."""
    n = x.shape[0]
    noise = rng.standard_normal((n, n_noise))
    xn = _propose(x, y, u, t, noise, p, addresses)
    ll = _weight(xn, x, y, u, t, p, addresses)
    x[:] = xn
    inc, e, do, deg, _ = _reweigh(x, lw, ll, scheme, threshold, rng, mean, var, _np.empty(n), _np.empty(n))
    return inc, e, do, deg


@_njit(nogil=True, inline="always")
def step_optimal(p, rng, x, lw, y, u, t, n_noise, scheme, threshold, mean, var, addresses=None):
    """The locally optimal proposal, fully adapted order ([Doucet2000]; [Thesis] eqs. 4.24-4.25):
    weight by p(y_t | x_{t-1}), resample when N_eff < threshold, then propagate
    x_t ~ p(x_t | x_{t-1}, y_t); the estimate is the weighted mean of the propagated particles.
    ``addresses`` as for :func:`step_proposal`."""
    n = x.shape[0]
    wu = _np.empty(n)
    ll = _predictive(y, x, u, t, p, addresses)
    inc, e, do, deg, total = _reweigh(x, lw, ll, scheme, threshold, rng, mean, var, wu, _np.empty(n))
    noise = rng.standard_normal((n, n_noise))
    xn = _propose(x, y, u, t, noise, p, addresses)
    x[:] = xn
    _moments(x, wu, total, mean, var)
    return inc, e, do, deg


@_njit(nogil=True)
def run_proposal(p, rng, y, u, x, lw, out, settings):
    """All M steps with the model's own proposal; ``out`` (a
    :class:`~pfbench.backends.guided_work.Outputs`, (M, ...) arrays) filled in place.

    ``x``, ``lw``: the initial particles and log-weights, drawn from ``rng`` by the caller with the
    model's NumPy ``initial`` (:func:`pfbench.filters.guided.numpy_init`, the NumPy reference's
    draw; the kernel continues the same stream), so a whole run does not compile the model's
    ``initial`` (measured: 1.55 s of a cold start on the reduced PMSM model). ``settings``: a
    :class:`~pfbench.backends.guided_work.Settings`, with the native entry points of
    ``_propose_into`` and ``_weight_into``."""
    addresses = (settings.propose, settings.weight)
    n_noise, scheme, threshold = settings.n_noise, settings.scheme, settings.threshold
    for t in range(y.shape[0]):
        out.inc[t], out.ess[t], out.resampled[t], out.degen[t] = step_proposal(
            p, rng, x, lw, y[t], u[t], t, n_noise, scheme, threshold, out.est[t], out.var[t], addresses)


@_njit(nogil=True)
def run_optimal(p, rng, y, u, x, lw, out, settings):
    """All M steps with the locally optimal proposal; ``out`` filled in place (``x``, ``lw``
    initialised by the caller, as for :func:`run_proposal`; ``settings`` holds the addresses of
    ``_propose_into`` and ``_predictive_into``)."""
    addresses = (settings.propose, settings.weight)
    n_noise, scheme, threshold = settings.n_noise, settings.scheme, settings.threshold
    for t in range(y.shape[0]):
        out.inc[t], out.ess[t], out.resampled[t], out.degen[t] = step_optimal(
            p, rng, x, lw, y[t], u[t], t, n_noise, scheme, threshold, out.est[t], out.var[t], addresses)
