"""The numba guided-filter kernel (the ``guided`` family's template): a model's own proposal, or the
locally optimal one; the compiled twin of :mod:`pfbench.filters.guided` (same steps and draws).

:func:`pfbench.backends.kernels.build` runs it per model class with the model's functions bound to
``_initial``, ``_proposal``, ``_proposal_log_weight`` and ``_predictive_log_likelihood``. Each kind of
proposal has its own step and run functions, so numba compiles only the model functions it uses.
:func:`init` and the ``step_*`` functions also serve per-step calls from compiled code (the PMSM closed
loop, :func:`pfbench.filters.guided.step_functions`); they are ``inline="always"``, compiled once per caller.
A step function takes ``(p, rng, particles, y, u, t, settings, moments)`` (the groups of
:mod:`pfbench.backends.guided_work`; ``particles`` updated in place, ``moments`` filled) and returns
``(loglik increment, N_eff, resampled, degenerate)``.
"""
import numpy as _np

from pfbench.backends.guided_work import Moments as _Moments
from pfbench.backends.kernels import binding as _binding
from pfbench.backends.native_call import caller as _caller
from pfbench.backends.numba_weights import moments as _moments
from pfbench.backends.numba_weights import normalised_log_weights as _normalised_log_weights
from pfbench.backends.numba_weights import weigh as _weigh
from pfbench.models.contract import RESHAPED as _RESHAPED


# ---- what :func:`pfbench.backends.kernels.build` binds for a model and a scheme
_b = _binding()
_njit = _b.jit
_initial = _b.model("initial")
_proposal = _b.model("proposal")
_proposal_log_weight = _b.model("proposal_log_weight")
_predictive_log_likelihood = _b.model("predictive_log_likelihood")
_resample = _b.resample
#: the resampling scheme's code, -1 in the any-scheme module (per-step callers, the shared functions)
_SCHEME = _b.scheme
_call6 = _caller(6)
_call7 = _caller(7)
#: a model's array of another size than in the check: refused (it would broadcast into the particles)
_RESHAPED_PROPOSAL, _RESHAPED_WEIGHT = "proposal" + _RESHAPED, "proposal_log_weight" + _RESHAPED
_RESHAPED_PREDICTIVE = "predictive_log_likelihood" + _RESHAPED

# ---- the model's calls: a whole run calls them by address (``settings.propose``, ``settings.weight``;
# scheme-free, :attr:`pfbench.backends.kernels.Family.shared`), per-step callers directly (``_SCHEME == -1``)
@_njit(nogil=True, no_cpython_wrapper=True)
def _propose_into(x, y, u, t, noise, p, xn):
    """xn = the model's ``proposal(x, y, u, t, noise, p)``, of the particles' size."""
    out = _proposal(x, y, u, t, noise, p)
    if out.shape[0] != xn.shape[0] or out.shape[1] != xn.shape[1]:
        raise ValueError(_RESHAPED_PROPOSAL)
    xn[:] = out


@_njit(nogil=True, no_cpython_wrapper=True)
def _weight_into(xn, x, y, u, t, p, ll):
    """ll = the model's ``proposal_log_weight(xn, x, y, u, t, p)`` in float64, one per particle."""
    out = _proposal_log_weight(xn, x, y, u, t, p)
    if out.shape[0] != ll.shape[0]:
        raise ValueError(_RESHAPED_WEIGHT)
    ll[:] = out


@_njit(nogil=True, no_cpython_wrapper=True)
def _predictive_into(y, x, u, t, p, ll):
    """ll = the model's ``predictive_log_likelihood(y, x, u, t, p)`` in float64, one per particle."""
    out = _predictive_log_likelihood(y, x, u, t, p)
    if out.shape[0] != ll.shape[0]:
        raise ValueError(_RESHAPED_PREDICTIVE)
    ll[:] = out


_propose_into = _b.shared("_propose_into", _propose_into)
_weight_into = _b.shared("_weight_into", _weight_into)
_predictive_into = _b.shared("_predictive_into", _predictive_into)


@_njit(nogil=True, inline="always")
def _propose(x, y, u, t, noise, p, settings):
    xn = _np.empty_like(x)
    if _SCHEME == -1:  # compile-time constant
        _propose_into(x, y, u, t, noise, p, xn)
    else:
        _call7(_propose_into, settings.propose, x, y, u, t, noise, p, xn)
    return xn


@_njit(nogil=True, inline="always")
def _weight(xn, x, y, u, t, p, settings):
    ll = _np.empty(x.shape[0])
    if _SCHEME == -1:
        _weight_into(xn, x, y, u, t, p, ll)
    else:
        _call7(_weight_into, settings.weight, xn, x, y, u, t, p, ll)
    return ll


@_njit(nogil=True, inline="always")
def _predictive(y, x, u, t, p, settings):
    ll = _np.empty(x.shape[0])
    if _SCHEME == -1:
        _predictive_into(y, x, u, t, p, ll)
    else:
        _call6(_predictive_into, settings.weight, y, x, u, t, p, ll)
    return ll


@_njit(nogil=True, inline="always")
def init(p, rng, x, lw):
    """x_{-1} ~ the model's prior, equal weights."""
    n = x.shape[0]
    x[:] = _initial(rng, n, p)
    lw[:] = -_np.log(n)


@_njit(nogil=True, inline="always")
def _reweigh(particles, ll, settings, rng, moments, wu, cdf):
    """Twin of ``pfbench.filters.guided._reweigh``: weigh, N_eff, then resample (``wu`` equal weights after)
    or keep the normalised log-weights. Returns (increment, N_eff, resampled, degenerate, total)."""
    x, lw = particles
    n = x.shape[0]
    m, total, deg = _weigh(lw, ll, wu, cdf)
    inc = -_np.inf if deg else m + _np.log(total)
    e = _moments(x, wu, total, moments.mean, moments.var)
    do = e < settings.threshold
    if do:  # resample and gather in place (inline: one compiled function less on a cold cache)
        idx = _np.empty(n, _np.int64)
        _resample(settings.scheme, wu, cdf, rng, idx)
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
def step_proposal(p, rng, particles, y, u, t, settings, moments):
    """The model's own proposal: x_t ~ q(. | x_{t-1}, y_t), weight by ``proposal_log_weight``,
    estimate (weighted mean before resampling), resample when N_eff < threshold ([Doucet2000])."""
    x = particles.x
    n = x.shape[0]
    noise = rng.standard_normal((n, settings.n_noise))
    xn = _propose(x, y, u, t, noise, p, settings)
    ll = _weight(xn, x, y, u, t, p, settings)
    x[:] = xn
    inc, e, do, deg, _ = _reweigh(particles, ll, settings, rng, moments, _np.empty(n), _np.empty(n))
    return inc, e, do, deg


@_njit(nogil=True, inline="always")
def step_optimal(p, rng, particles, y, u, t, settings, moments):
    """The locally optimal proposal, fully adapted ([Doucet2000]; [Thesis] eqs. 4.24-4.25): weight by
    p(y_t | x_{t-1}), resample when N_eff < threshold, propagate x_t ~ p(x_t | x_{t-1}, y_t); the
    estimate is the weighted mean of the propagated particles."""
    x = particles.x
    n = x.shape[0]
    wu = _np.empty(n)
    ll = _predictive(y, x, u, t, p, settings)
    inc, e, do, deg, total = _reweigh(particles, ll, settings, rng, moments, wu, _np.empty(n))
    noise = rng.standard_normal((n, settings.n_noise))
    x[:] = _propose(x, y, u, t, noise, p, settings)
    _moments(x, wu, total, moments.mean, moments.var)
    return inc, e, do, deg


@_njit(nogil=True)
def run_proposal(p, rng, y, u, particles, out, settings):
    """All M steps with the model's own proposal, filling ``out``, from ``particles`` drawn by the caller
    with the model's NumPy ``initial`` (:func:`pfbench.filters.guided.numpy_init`; the kernel continues
    that stream); ``settings`` holds the addresses of ``_propose_into`` and ``_weight_into``."""
    for t in range(y.shape[0]):
        out.inc[t], out.ess[t], out.resampled[t], out.degen[t] = step_proposal(
            p, rng, particles, y[t], u[t], t, settings, _Moments(out.est[t], out.var[t]))


@_njit(nogil=True)
def run_optimal(p, rng, y, u, particles, out, settings):
    """All M steps with the locally optimal proposal, as :func:`run_proposal` (``settings`` with the
    addresses of ``_propose_into`` and ``_predictive_into``)."""
    for t in range(y.shape[0]):
        out.inc[t], out.ess[t], out.resampled[t], out.degen[t] = step_optimal(
            p, rng, particles, y[t], u[t], t, settings, _Moments(out.est[t], out.var[t]))
