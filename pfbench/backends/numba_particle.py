"""The numba particle kernel: bootstrap, SIR, SIS and ASIR (and MultiPDF sub-filters) over all steps.

This is the compiled twin of :func:`pfbench.backends.numpy_backend.run_group`: the same steps, the
same random draws in the same order, the same floating-point operations for everything that feeds
back into the filter. It calls the model through three module globals, ``_initial``,
``_transition`` and ``_log_likelihood``. As a file it is importable (they are placeholders here);
:func:`pfbench.backends.numba_backend.kernel_module` writes a copy of it per model class with the
model's compiled functions bound to those names at the end, so numba can cache the whole kernel,
model inlined, on disk.
"""
import numpy as _np

from pfbench.backends.cache import njit as _njit
from pfbench.backends.numba_resampling import resample_into as _resample_into
from pfbench.backends.numba_weights import moments as _moments
from pfbench.backends.numba_weights import normalised_log_weights as _normalised_log_weights
from pfbench.backends.numba_weights import weigh as _weigh
from pfbench.filters.methods import Method as _Method

_ASIR = int(_Method.ASIR)
_BOOTSTRAP = int(_Method.BOOTSTRAP)
_SIR = int(_Method.SIR)


def _initial(rng, n, p):  # pragma: no cover - bound per model in the generated module
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _transition(x, u, t, noise, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


def _log_likelihood(y, x, u, t, p):  # pragma: no cover - bound per model
    raise NotImplementedError("bound per model by pfbench.backends.numba_backend.kernel_module")


@_njit(nogil=True)
def run_group(p, rng, y, u, x, n_noise, method, scheme, ess_threshold, est, var, ess, inc, resampled,
              degen, hist_x, hist_w):
    """Run a group of G independent filters over all steps (one random stream, documented order).

    x: (G, n, n_x) particle buffer (its dtype is the particle dtype); outputs (G, M, ...).
    hist_x (G, M, n, n_x), hist_w (G, M, n): the weighted particles of every step (before
    resampling) when their second dimension is M; pass (G, 0, ...) arrays to store nothing.
    method: a :class:`~pfbench.filters.methods.Method` code of the particle family (MultiPDF runs
    bootstrap sub-filters); scheme: a :class:`~pfbench.resampling.Scheme` code; ess_threshold:
    a particle count.
    """
    G = x.shape[0]
    n = x.shape[1]
    n_x = x.shape[2]
    M = y.shape[0]
    logn = _np.log(n)
    lw = _np.full((G, n), -logn)
    wu = _np.empty(n)
    cdf = _np.empty(n)
    idx = _np.empty(n, _np.int64)
    buf = _np.empty((n, n_x), x.dtype)
    lam = _np.zeros(n)
    for g in range(G):
        x[g] = _initial(rng, n, p)
    for t in range(M):
        yt = y[t]
        ut = u[t]
        for g in range(G):
            xg = x[g]
            lwg = lw[g]
            first = 0.0
            if method == _ASIR:  # first stage, [Thesis] Alg. 6
                mu = _transition(xg, ut, t, _np.zeros((n, n_noise)), p)
                lam_all = _log_likelihood(yt, mu, ut, t, p).astype(_np.float64)
                m1, tot1, deg1 = _weigh(lwg, lam_all, wu, cdf)
                first = m1 + _np.log(tot1)
                if deg1:
                    for i in range(n):
                        lam_all[i] = 0.0
                _resample_into(scheme, wu, cdf, rng, idx)
                for i in range(n):
                    for a in range(n_x):
                        buf[i, a] = xg[idx[i], a]
                    lam[i] = lam_all[idx[i]]
                xg[:] = buf
                lwg[:] = -logn
            noise = rng.standard_normal((n, n_noise))
            xg[:] = _transition(xg, ut, t, noise, p)
            ll = _log_likelihood(yt, xg, ut, t, p).astype(_np.float64)
            if method == _ASIR:
                for i in range(n):
                    v = ll[i]
                    ll[i] = v - lam[i] if v == v and v != _np.inf else -_np.inf
            m, total, deg = _weigh(lwg, ll, wu, cdf)
            if hist_x.shape[1] > 0:
                for i in range(n):
                    hist_w[g, t, i] = wu[i] / total
                    for a in range(n_x):
                        hist_x[g, t, i, a] = xg[i, a]
            degen[g, t] = deg
            inc[g, t] = (-_np.inf if deg else m + _np.log(total)) + first
            e = _moments(xg, wu, total, est[g, t], var[g, t])
            ess[g, t] = e
            do = method == _BOOTSTRAP or (method == _SIR and e < ess_threshold)
            if do:
                _resample_into(scheme, wu, cdf, rng, idx)
                for i in range(n):
                    for a in range(n_x):
                        buf[i, a] = xg[idx[i], a]
                xg[:] = buf
                lwg[:] = -logn
            else:
                _normalised_log_weights(wu, total, lwg)
            resampled[g, t] = do
