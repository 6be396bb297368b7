"""The numba marginalized-PF kernel ([Schon2005] Alg. 1): the compiled twin of
``pfbench.filters.marginalized._run_numpy``.

Same steps, same random draws in the same order (the prior ``_initial`` when d_n > 0, then per
step the x^n noise and the resampling draws), the same step math: the ``register_jitable`` helpers
of :mod:`pfbench.filters.marginalized` are compiled in here. Weighting, moments and resampling are
the package's one compiled versions (:mod:`pfbench.backends.numba_weights`,
:mod:`pfbench.backends.numba_resampling`, the scheme bound as ``_resample``). The model is called through the module
globals ``_initial``, ``_cl_transition``, ``_cl_observation`` and ``_cl_constrain`` (placeholders
here); :func:`pfbench.backends.numba_backend.kernel_module` writes a copy of this file per model
class with the model's compiled functions bound to those names, so numba caches the whole kernel,
model inlined, on disk.

Two entry points, so a call compiles only what it runs: :func:`run` for models with nonlinear
states (d_n > 0) and :func:`run_linear` for d_n = 0 (the ``kalman`` method and the MPF on a fully
linear model), which needs no prior draw, no x^n sampling or conditioning and no resampling.
Their shared measurement step :func:`_measure` is ``inline="always"`` (compiled once, inside the
kernel that calls it).
"""
import numpy as _np

from pfbench.backends.cache import njit as _njit
from pfbench.backends.numba_weights import moments as _moments
from pfbench.backends.numba_weights import weigh as _weigh
from pfbench.filters.marginalized import kalman_predict as _kalman_predict
from pfbench.filters.marginalized import kalman_update as _kalman_update
from pfbench.filters.marginalized import mixture_moments as _mixture_moments
from pfbench.filters.marginalized import time_update as _time_update


def _initial(rng, n, p):  # pragma: no cover - bound per model in the generated module
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _cl_transition(xn, u, t, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _cl_observation(xn, xl, u, t, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _cl_constrain(xn, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _resample(code, w, cdf, rng, idx):  # pragma: no cover - bound per run by kernel_module
    raise NotImplementedError("bound per scheme by pfbench.backends.numba_backend.kernel_module")


@_njit(nogil=True, inline="always")
def _measure(p, t, ut, yt, xs, m_pred, P_pred, W, rvar, whiten, logdet, idx_n, idx_l, lw, wu, cdf,
             mean_n, var_n, mean_l, var_l, est, cov, ess, inc, degen):
    """Steps 4-5 of step ``t``: weigh by p(y_t | x^n_t, Y_{t-1}), Kalman measurement update, the
    increment, N_eff and the mixture moments into est[t], cov[t]. Returns the updated (m, P)."""
    h, C = _cl_observation(xs, m_pred, ut, t, p)
    ll, m, P = _kalman_update(h, C, m_pred, P_pred, yt, W, rvar, whiten, logdet)
    mx, total, deg = _weigh(lw, ll, wu, cdf)
    degen[t] = deg
    inc[t] = -_np.inf if deg else mx + _np.log(total)
    ess[t] = _moments(xs, wu, total, mean_n, var_n)
    _moments(m, wu, total, mean_l, var_l)
    _mixture_moments(wu, total, mean_n, mean_l, xs, m, P, idx_n, idx_l, est[t], cov[t])
    return m, P


@_njit(nogil=True)
def run(p, rng, y, u, n, idx_n, idx_l, Qn, Ql, T, corr, W, rvar, whiten, logdet, m0, P0, scheme,
        est, cov, ess, inc, degen):
    """Run the MPF over all steps with ``n`` particles (one random stream, documented order).

    ``y`` (M, n_y) are the (whitened, if ``whiten``) measurements; ``idx_n``/``idx_l`` the state
    indices of x^n/x^l (d_n > 0; :func:`run_linear` serves d_n = 0); the noise and whitening
    arrays as prepared by ``pfbench.filters.marginalized.structure``; ``scheme`` a
    :class:`~pfbench.resampling.Scheme` code. Fills est (M, n_x), cov (M, n_x, n_x), ess, inc,
    degen (M,).
    """
    d_n = idx_n.shape[0]
    d_l = idx_l.shape[0]
    M = y.shape[0]
    xn = _np.zeros((n, d_n))
    x0 = _initial(rng, n, p)
    for i in range(n):
        for a in range(d_n):
            xn[i, a] = x0[i, idx_n[a]]
    m = _np.empty((n, d_l))
    P = _np.empty((n, d_l, d_l))
    for i in range(n):
        for a in range(d_l):
            m[i, a] = m0[a]
            for b in range(d_l):
                P[i, a, b] = P0[a, b]
    lw = _np.full(n, -_np.log(n))
    wu = _np.empty(n)
    cdf = _np.empty(n)
    idx = _np.empty(n, _np.int64)
    mean_n = _np.empty(d_n)
    var_n = _np.empty(d_n)
    mean_l = _np.empty(d_l)
    var_l = _np.empty(d_l)
    for t in range(M):
        ut = u[t]
        z = rng.standard_normal((n, d_n))
        fn, An, fl, Al = _cl_transition(xn, ut, t, p)
        xs, m_pred, P_pred = _kalman_predict(fn, An, fl, Al, m, P, z, Qn, Ql, T, corr)
        xs = _cl_constrain(xs, p)
        m, P = _measure(p, t, ut, y[t], xs, m_pred, P_pred, W, rvar, whiten, logdet, idx_n, idx_l, lw,
                        wu, cdf, mean_n, var_n, mean_l, var_l, est, cov, ess, inc, degen)
        _resample(scheme, wu, cdf, rng, idx)
        m2 = _np.empty_like(m)
        P2 = _np.empty_like(P)
        for i in range(n):
            j = idx[i]
            for a in range(d_n):
                xn[i, a] = xs[j, a]
            for a in range(d_l):
                m2[i, a] = m[j, a]
                for b in range(d_l):
                    P2[i, a, b] = P[j, a, b]
        m = m2
        P = P2


@_njit(nogil=True)
def run_linear(p, y, u, idx_l, Ql, W, rvar, whiten, logdet, m0, P0, est, cov, ess, inc, degen):
    """The d_n = 0 case of :func:`run` (every state in x^l): one Kalman/EKF recursion, no random
    numbers, no resampling; the same operations as :func:`run` with one particle, compiled without
    the x^n sampling, conditioning and resampling it never runs. Arguments as for :func:`run`."""
    d_l = idx_l.shape[0]
    xn = _np.zeros((1, 0))
    idx_n = _np.zeros(0, _np.int64)
    m = _np.empty((1, d_l))
    P = _np.empty((1, d_l, d_l))
    for a in range(d_l):
        m[0, a] = m0[a]
        for b in range(d_l):
            P[0, a, b] = P0[a, b]
    lw = _np.full(1, -_np.log(1))
    wu = _np.empty(1)
    cdf = _np.empty(1)
    mean_n = _np.empty(0)
    var_n = _np.empty(0)
    mean_l = _np.empty(d_l)
    var_l = _np.empty(d_l)
    for t in range(y.shape[0]):
        ut = u[t]
        _, _, fl, Al = _cl_transition(xn, ut, t, p)
        m_pred, P_pred = _time_update(fl, Al, m, P, Ql)
        m, P = _measure(p, t, ut, y[t], xn, m_pred, P_pred, W, rvar, whiten, logdet, idx_n, idx_l, lw,
                        wu, cdf, mean_n, var_n, mean_l, var_l, est, cov, ess, inc, degen)
