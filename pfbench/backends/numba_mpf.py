"""The numba marginalized-PF kernel ([Schon2005] Alg. 1): the compiled twin of
``pfbench.filters.marginalized._run_numpy``.

Same steps, same random draws in the same order (the prior ``_initial`` when d_n > 0, then per
step the x^n noise and the resampling draws), the same step math: the ``register_jitable`` helpers
of :mod:`pfbench.filters.marginalized` are compiled in here. Weighting, moments and resampling are
the package's one compiled versions (:mod:`pfbench.backends.numba_weights`,
:func:`pfbench.backends.numba_resampling.resample_into`). The model is called through the module
globals ``_initial``, ``_cl_transition``, ``_cl_observation`` and ``_cl_constrain`` (placeholders
here); :func:`pfbench.backends.numba_backend.kernel_module` writes a copy of this file per model
class with the model's compiled functions bound to those names, so numba caches the whole kernel,
model inlined, on disk.
"""
import numpy as _np

from pfbench.backends.cache import njit as _njit
from pfbench.backends.numba_resampling import resample_into as _resample_into
from pfbench.backends.numba_weights import moments as _moments
from pfbench.backends.numba_weights import weigh as _weigh
from pfbench.filters.marginalized import kalman_predict as _kalman_predict
from pfbench.filters.marginalized import kalman_update as _kalman_update
from pfbench.filters.marginalized import mixture_moments as _mixture_moments


def _initial(rng, n, p):  # pragma: no cover - bound per model in the generated module
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _cl_transition(xn, u, t, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _cl_observation(xn, xl, u, t, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _cl_constrain(xn, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


@_njit(nogil=True)
def run(p, rng, y, u, n, idx_n, idx_l, Qn, Ql, T, corr, W, rvar, whiten, logdet, m0, P0, scheme,
        est, cov, ess, inc, degen):
    """Run the MPF over all steps with ``n`` particles (one random stream, documented order).

    ``y`` (M, n_y) are the (whitened, if ``whiten``) measurements; ``idx_n``/``idx_l`` the state
    indices of x^n/x^l; the noise and whitening arrays as prepared by
    ``pfbench.filters.marginalized.structure``; ``scheme`` a :class:`~pfbench.resampling.Scheme`
    code. Fills est (M, n_x), cov (M, n_x, n_x), ess, inc, degen (M,).
    """
    d_n = idx_n.shape[0]
    d_l = idx_l.shape[0]
    M = y.shape[0]
    xn = _np.zeros((n, d_n))
    if d_n > 0:
        x0 = _initial(rng, n, p)
        for i in range(n):
            for a in range(d_n):
                xn[i, a] = x0[i, idx_n[a]]
    m = _np.empty((n, d_l))
    P = _np.empty((n, d_l, d_l))
    for i in range(n):
        m[i] = m0
        P[i] = P0
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
        if d_n > 0:
            z = rng.standard_normal((n, d_n))
        else:
            z = _np.zeros((n, 0))
        fn, An, fl, Al = _cl_transition(xn, ut, t, p)
        xs, m_pred, P_pred = _kalman_predict(fn, An, fl, Al, m, P, z, Qn, Ql, T, corr)
        xs = _cl_constrain(xs, p)
        h, C = _cl_observation(xs, m_pred, ut, t, p)
        ll, m, P = _kalman_update(h, C, m_pred, P_pred, y[t], W, rvar, whiten, logdet)
        mx, total, deg = _weigh(lw, ll, wu, cdf)
        degen[t] = deg
        inc[t] = -_np.inf if deg else mx + _np.log(total)
        ess[t] = _moments(xs, wu, total, mean_n, var_n)
        _moments(m, wu, total, mean_l, var_l)
        _mixture_moments(wu, total, mean_n, mean_l, xs, m, P, idx_n, idx_l, est[t], cov[t])
        if d_n > 0:
            _resample_into(scheme, wu, cdf, rng, idx)
            m2 = _np.empty_like(m)
            P2 = _np.empty_like(P)
            for i in range(n):
                for a in range(d_n):
                    xn[i, a] = xs[idx[i], a]
                m2[i] = m[idx[i]]
                P2[i] = P[idx[i]]
            m = m2
            P = P2
