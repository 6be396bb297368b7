"""The numba marginalized-PF kernel ([Schon2005] Alg. 1), the ``mpf`` family's template: the compiled
twin of ``pfbench.filters.marginalized._run_numpy``, with the same draws in the same order and the same
step math (:mod:`pfbench.backends.numba_mpf_steps`; weights and resampling from
:mod:`pfbench.backends.numba_weights` and :mod:`pfbench.backends.numba_resampling`, the scheme bound as
``_resample``). :func:`pfbench.backends.kernels.build` runs it per model class with the model's
functions bound to ``_cl_transition``, ``_cl_observation`` and ``_cl_constrain``; the drivers take the
groups of :mod:`pfbench.backends.mpf_work`.

Two drivers, so a call compiles only what it runs: :func:`run` (d_n > 0) and :func:`run_linear`
(d_n = 0: the ``kalman`` method and the MPF of a fully linear model; no draws, no resampling).
"""
import numpy as _np

from pfbench.backends.kernels import binding as _binding
from pfbench.backends.numba_weights import moments as _moments
from pfbench.backends.numba_weights import valid_log_likelihood as _valid
from pfbench.backends.numba_weights import weigh as _weigh
from pfbench.backends.numba_mpf_steps import condition as _condition
from pfbench.backends.numba_mpf_steps import kalman_update as _kalman_update
from pfbench.backends.numba_mpf_steps import mixture_moments as _mixture_moments
from pfbench.backends.numba_mpf_steps import sandwich as _sandwich
from pfbench.backends.numba_mpf_steps import time_update as _time_update
from pfbench.backends.numba_mpf_steps import CONSTRAIN as _CONSTRAIN, OBSERVATION as _OBSERVATION, TRANSITION as _TRANSITION
from pfbench.backends.numba_mpf_steps import copy_into as _copy_into
from pfbench.backends.numba_mpf_steps import normals_into as _normals_into
from pfbench.backends.native_call import caller as _caller

_call2 = _caller(2)
_call4 = _caller(4)
_call5 = _caller(5)
_call7 = _caller(7)
_call8 = _caller(8)

#: what :func:`run` calls by address, in its ``addresses``' order (types: numba_backend's ``_run_calls``, ``_step_calls``)
RUN_CALLS = ("_cl_transition", "_cl_observation", "_cl_constrain", "_transition_into", "_observation_into",
             "_constrain_into", "_normals_into", "_sandwich", "_condition", "_time_update", "_kalman_update", "_weigh",
             "_moments", "_mixture_moments")
(_A_CL_TRANSITION, _A_CL_OBSERVATION, _A_CL_CONSTRAIN, _A_TRANSITION, _A_OBSERVATION, _A_CONSTRAIN, _A_NORMALS,
 _A_SANDWICH, _A_CONDITION, _A_TIME_UPDATE, _A_KALMAN_UPDATE, _A_WEIGH, _A_MOMENTS,
 _A_MIXTURE_MOMENTS) = range(len(RUN_CALLS))


# ---- what :func:`pfbench.backends.kernels.build` binds for a model and a scheme
_b = _binding()
_njit = _b.jit
_cl_transition = _b.model("cl_transition")
_cl_observation = _b.model("cl_observation")
_cl_constrain = _b.model("cl_constrain")
_resample = _b.resample


# ---- the model's calls: :func:`run` calls these three by address (scheme-free, compiled once per model);
# each calls the model by address in turn and copies its result into the kernel's float64 C arrays (a
# ValueError for another shape), so the drivers and step math see one array type for every model.
@_njit(nogil=True, no_cpython_wrapper=True)
def _transition_into(xn, u, t, p, tn, tl, model_address):
    """``cl_transition(xn, u, t, p)`` into f^n, A^n (``tn``) and f^l, A^l (``tl``,
    :class:`~pfbench.backends.mpf_work.Affine`)."""
    a, b, c, d = _call4(_cl_transition, model_address, xn, u, t, p)
    _copy_into(a, tn.f, _TRANSITION)
    _copy_into(b, tn.A, _TRANSITION)
    _copy_into(c, tl.f, _TRANSITION)
    _copy_into(d, tl.A, _TRANSITION)


@_njit(nogil=True, no_cpython_wrapper=True)
def _observation_into(xn, xl, u, t, p, obs, model_address):
    """``cl_observation(xn, xl, u, t, p)`` into h, C (``obs``)."""
    a, b = _call5(_cl_observation, model_address, xn, xl, u, t, p)
    _copy_into(a, obs.f, _OBSERVATION)
    _copy_into(b, obs.A, _OBSERVATION)


@_njit(nogil=True, no_cpython_wrapper=True)
def _constrain_into(xn, p, out, model_address):
    """``cl_constrain(xn, p)`` into ``out``."""
    _copy_into(_call2(_cl_constrain, model_address, xn, p), out, _CONSTRAIN)


_transition_into = _b.shared("_transition_into", _transition_into)
_observation_into = _b.shared("_observation_into", _observation_into)
_constrain_into = _b.shared("_constrain_into", _constrain_into)


# --------------------------------------------------------------------------- entry points
@_njit(nogil=True)
def run(p, rng, u, st, out, work, scheme, addresses):
    """All steps of the MPF from the prior x^n particles ``work.xn`` (n, d_n), updated in place; the
    caller draws them from ``rng`` with the model's NumPy ``initial`` and the kernel continues that stream.

    ``st``: :class:`~pfbench.backends.mpf_work.Structure` (``st.meas.yw`` the measurements, whitened
    if ``whiten``); ``out``: :class:`~pfbench.backends.mpf_work.Outputs`, filled; ``work``:
    :class:`~pfbench.backends.mpf_work.Work`; ``scheme``: a :class:`~pfbench.resampling.Scheme` code;
    ``addresses``: the entry points of :data:`RUN_CALLS`, in order. Everything it calls per step goes
    by address, so it compiles as a loop of calls and a cold start compiles the pieces on two cores
    (:func:`pfbench.backends.numba_backend.native_addresses`).

    Per step ([Schon2005] Alg. 1): the x^n noise, ``cl_transition``, steps 1-2 (``sandwich``,
    ``condition``, ``time_update``), step 3 (``cl_constrain``), step 4 (``cl_observation``,
    ``kalman_update``, the weights), step 5 (moments, ``mixture_moments``, resampling).
    """
    # every group and array the loop uses, taken out of the groups once: the loop is then the same
    # statements as on plain arguments (each field read in it is compile time, once per statement)
    xn, xnew, xs, prior, cond, pred, tn, tl, lin = (work.xn, work.xnew, work.xs, work.prior, work.cond, work.pred,
                                                    work.tn, work.tl, work.lin)
    fac, APl, obs, upd, wts, mom = work.fac, work.APl, work.obs, work.upd, work.wts, work.mom
    m, P, mm, Pm, m_pred, An = prior.m, prior.P, cond.m, cond.P, pred.m, tn.A
    z, APn, N = fac.z, fac.APn, fac.N
    ll, lw, wu, cdf, idx = wts.ll, wts.lw, wts.wu, wts.cdf, wts.idx
    mean_n, var_n, mean_l, var_l = mom.mean_n, mom.var_n, mom.mean_l, mom.var_l
    m0, P0, split, noise, meas = st.prior.m, st.prior.P, st.split, st.noise, st.meas
    Qn, Ql = noise.Qn, noise.Ql
    est, cov, ess, inc, degen = out.est, out.cov, out.ess, out.inc, out.degen
    d_n = split.n.shape[0]
    d_l = split.l.shape[0]
    n = xn.shape[0]
    for i in range(n):
        for a in range(d_l):
            m[i, a] = m0[a]
            for b in range(d_l):
                P[i, a, b] = P0[a, b]
    lw0 = -_np.log(n)
    for i in range(n):
        lw[i] = lw0
    for t in range(meas.yw.shape[0]):
        ut = u[t]
        _call2(_normals_into, addresses[_A_NORMALS], rng, z)
        _call7(_transition_into, addresses[_A_TRANSITION], xn, ut, t, p, tn, tl, addresses[_A_CL_TRANSITION])
        _call5(_sandwich, addresses[_A_SANDWICH], An, P, Qn, APn, N)
        _call8(_condition, addresses[_A_CONDITION], tn, tl, prior, fac, noise, xnew, cond, lin)
        _call5(_time_update, addresses[_A_TIME_UPDATE], lin, cond, Ql, APl, pred)
        _call4(_constrain_into, addresses[_A_CONSTRAIN], xnew, p, xs, addresses[_A_CL_CONSTRAIN])
        _call7(_observation_into, addresses[_A_OBSERVATION], xs, m_pred, ut, t, p, obs, addresses[_A_CL_OBSERVATION])
        _call7(_kalman_update, addresses[_A_KALMAN_UPDATE], obs, pred, meas, t, upd, ll, cond)
        mx, total, deg = _call4(_weigh, addresses[_A_WEIGH], lw, ll, wu, cdf)
        degen[t] = deg
        inc[t] = -_np.inf if deg else mx + _np.log(total)
        ess[t] = _call5(_moments, addresses[_A_MOMENTS], xs, wu, total, mean_n, var_n)
        _call5(_moments, addresses[_A_MOMENTS], mm, wu, total, mean_l, var_l)
        _call8(_mixture_moments, addresses[_A_MIXTURE_MOMENTS], wu, total, mom, xs, cond, split, est[t], cov[t])
        _resample(scheme, wu, cdf, rng, idx)
        for i in range(n):
            j = idx[i]
            for a in range(d_n):
                xn[i, a] = xs[j, a]
            for a in range(d_l):
                m[i, a] = mm[j, a]
                for b in range(d_l):
                    P[i, a, b] = Pm[j, a, b]


#: the functions :func:`run_linear` calls by address, in the order of its ``addresses``
LINEAR_CALLS = ("_time_update", "_kalman_update", "_mixture_moments")


@_njit(nogil=True)
def run_linear(p, u, st, out, work, addresses):
    """The d_n = 0 case of :func:`run`: one Kalman/EKF recursion on one copy (its x^l in ``work.cond``),
    no random numbers, no resampling; arguments as for :func:`run` (``addresses``: :data:`LINEAR_CALLS`).

    The copy's weight is 1, so the increment is log p(y_t | Y_{t-1}) (-inf, ``degen`` set, when
    invalid, as :func:`~pfbench.backends.numba_weights.weigh` decides) and N_eff = 1. The model is
    called directly, so LLVM optimises it for the one copy and the empty x^n; the step math by
    address, so a cold start compiles it in a helper meanwhile.
    """
    d_l = st.split.l.shape[0]
    xn = _np.empty((1, 0))
    cond, pred, lin, obs, wts, mom = work.cond, work.pred, work.lin, work.obs, work.wts, work.mom
    m, P, m0, P0 = cond.m, cond.P, st.prior.m, st.prior.P
    for a in range(d_l):
        m[0, a] = m0[a]
        for b in range(d_l):
            P[0, a, b] = P0[a, b]
    wts.wu[0] = 1.0
    mean_l = mom.mean_l
    for t in range(st.meas.yw.shape[0]):
        ut = u[t]
        _, _, fl_, Al_ = _cl_transition(xn, ut, t, p)
        _copy_into(fl_, lin.f, _TRANSITION)
        _copy_into(Al_, lin.A, _TRANSITION)
        _call5(_time_update, addresses[0], lin, cond, st.noise.Ql, work.APl, pred)
        h_, C_ = _cl_observation(xn, pred.m, ut, t, p)
        _copy_into(h_, obs.f, _OBSERVATION)
        _copy_into(C_, obs.A, _OBSERVATION)
        _call7(_kalman_update, addresses[1], obs, pred, st.meas, t, work.upd, wts.ll, cond)
        v = _valid(wts.ll[0])
        deg = not (v > -_np.inf)
        out.degen[t] = deg
        out.inc[t] = -_np.inf if deg else v
        out.ess[t] = 1.0
        for a in range(d_l):
            mean_l[a] = m[0, a]
        _call8(_mixture_moments, addresses[2], wts.wu, 1.0, mom, work.xs, cond, st.split, out.est[t], out.cov[t])
