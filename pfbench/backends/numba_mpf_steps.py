"""The marginalized filter's step math, compiled: scalar-loop twins of the vectorised helpers of
:mod:`pfbench.filters.marginalized`, the same operations in the same order (so both backends agree to
rounding), which numba compiles several times faster than array expressions.

They call no model, so they live in this ordinary cached module, compiled once per process for every
model and scheme; the MPF drivers (:mod:`pfbench.backends.numba_mpf`) call them by address
(:mod:`pfbench.backends.native_call`) instead of compiling them into themselves again. Their
arguments are the groups of :mod:`pfbench.backends.mpf_work`.
"""
import numpy as np

from pfbench.backends.cache import njit
from pfbench.backends.pcg64 import fill_normals
from pfbench.models.base import LOG_2PI
from pfbench.models.contract import RESHAPED


@njit(nogil=True, no_cpython_wrapper=True)
def sandwich(A, P, Q, AP, S):
    """Per particle ``AP`` = A P and ``S`` = A P A' + Q, for A (n, d_out, d_in), P (n, d_in, d_in): N of
    [Schon2005] Alg. 1 step 1, A^l P A^l' + Q^l of step 2. Twin of :func:`pfbench.filters.marginalized.sandwich`."""
    n = P.shape[0]
    d_out = A.shape[1]
    d_in = A.shape[2]
    for i in range(n):
        for a in range(d_out):
            for b in range(d_in):
                acc = 0.0
                for c in range(d_in):
                    acc += A[i, a, c] * P[i, c, b]
                AP[i, a, b] = acc
        for a in range(d_out):
            for b in range(d_out):
                acc = 0.0 + Q[a, b]
                for c in range(d_in):
                    acc += AP[i, a, c] * A[i, b, c]
                S[i, a, b] = acc


@njit(nogil=True, error_model="numpy", no_cpython_wrapper=True)
def condition(tn, tl, prior, fac, noise, xnew, cond, lin):
    """[Schon2005] Alg. 1 steps 1-2 up to the time update, per particle, d_n > 0: L, the lower Cholesky
    factor of N = A^n P A^n' + Q^n (pivots floored at 1e-300; N and AP = A^n P from :func:`sandwich`);
    the sample x^n_t = f^n + A^n m + L z into ``xnew``; x^l conditioned on it into ``cond``: m + P A^n'
    N^-1 (x^n_t - f^n - A^n m) and P - P A^n' N^-1 A^n P, by back substitution; the x^l transition into
    ``lin``: f^l + T (x^n_t - f^n) and A^l - T A^n with ``noise.corr``, else f^l and A^l. Twin of
    :func:`pfbench.filters.marginalized.cholesky_batch`, :func:`~pfbench.filters.marginalized.condition_nonlinear`
    and the decorrelation of :func:`~pfbench.filters.marginalized.kalman_predict`."""
    fn, An, fl, Al, m, P, T, corr = tn.f, tn.A, tl.f, tl.A, prior.m, prior.P, noise.T, noise.corr
    z, N, AP, L, w, V = fac.z, fac.N, fac.APn, fac.L, fac.w, fac.V
    mm, Pm, f, A = cond.m, cond.P, lin.f, lin.A
    n = m.shape[0]
    d_l = m.shape[1]
    d_n = fn.shape[1]
    for i in range(n):
        for j in range(d_n):
            acc = N[i, j, j]
            for k in range(j):
                acc -= L[i, j, k] * L[i, j, k]
            L[i, j, j] = np.sqrt(1e-300 if acc < 1e-300 else acc)  # np.maximum: NaN stays NaN
            for r in range(j + 1, d_n):
                acc = N[i, r, j]
                for k in range(j):
                    acc -= L[i, r, k] * L[i, j, k]
                L[i, r, j] = acc / L[i, j, j]
        for a in range(d_n):
            acc = fn[i, a]
            for c in range(d_l):
                acc += An[i, a, c] * m[i, c]
            for b in range(a + 1):
                acc += L[i, a, b] * z[i, b]
            xnew[i, a] = acc
        for a in range(d_n - 1, -1, -1):
            acc = z[i, a]
            for b in range(a + 1, d_n):
                acc -= L[i, b, a] * w[b]
            w[a] = acc / L[i, a, a]
        for a in range(d_n):
            for c in range(d_l):
                acc = AP[i, a, c]
                for b in range(a):
                    acc -= L[i, a, b] * V[b, c]
                V[a, c] = acc / L[i, a, a]
        for b in range(d_l):
            acc = m[i, b]
            for a in range(d_n):
                acc += AP[i, a, b] * w[a]
            mm[i, b] = acc
        for b in range(d_l):
            for c in range(d_l):
                acc = P[i, b, c]
                for a in range(d_n):
                    acc -= V[a, b] * V[a, c]
                Pm[i, b, c] = acc
        for a in range(d_l):
            acc = fl[i, a]
            if corr:
                for c in range(d_n):
                    acc += T[a, c] * (xnew[i, c] - fn[i, c])
            f[i, a] = acc
            for b in range(d_l):
                acc = Al[i, a, b]
                if corr:
                    for c in range(d_n):
                        acc -= T[a, c] * An[i, c, b]
                A[i, a, b] = acc


@njit(nogil=True, no_cpython_wrapper=True)
def time_update(lin, cond, Q, AP, pred):
    """The time update of [Schon2005] Alg. 1 step 2 (with d_n = 0, the Kalman prediction): ``pred`` =
    f + A m, A P A' + Q per particle for f, A of ``lin`` and m, P of ``cond``; ``AP`` scratch. Twin of
    :func:`pfbench.filters.marginalized.time_update`."""
    f, A, m, P, m_pred, P_pred = lin.f, lin.A, cond.m, cond.P, pred.m, pred.P
    n = m.shape[0]
    d_l = m.shape[1]
    for i in range(n):
        for a in range(d_l):
            acc = f[i, a]
            for b in range(d_l):
                acc += A[i, a, b] * m[i, b]
            m_pred[i, a] = acc
    sandwich(A, P, Q, AP, P_pred)


@njit(nogil=True, error_model="numpy", no_cpython_wrapper=True)
def kalman_update(obs, pred, meas, t, upd, ll, post):
    """[Schon2005] Alg. 1 step 4 at step ``t``: log p(y_t | x^n_t, Y_{t-1}) per particle into ``ll`` and
    the measurement update of ``pred`` into ``post``, for h, C of ``obs`` and y_t = ``meas.yw[t]``
    (``upd``: scratch). Twin of :func:`pfbench.filters.marginalized.kalman_update`: outputs whitened
    with ``W`` when ``whiten``, one scalar at a time, residuals about the linearisation point ``m_pred``."""
    h, C, m_pred, P_pred, m, P = obs.f, obs.A, pred.m, pred.P, post.m, post.P
    y, W, rvar, whiten, logdet = meas.yw[t], meas.W, meas.rvar, meas.whiten, meas.logdet
    h0, H, PH = upd.h0, upd.H, upd.PH
    n = m_pred.shape[0]
    d_l = m_pred.shape[1]
    n_y = y.shape[0]
    for i in range(n):
        for k in range(n_y):
            if whiten:
                acc = 0.0
                for j in range(k + 1):
                    acc += W[k, j] * h[i, j]
                h0[k] = acc
                for a in range(d_l):
                    acc = 0.0
                    for j in range(k + 1):
                        acc += W[k, j] * C[i, j, a]
                    H[k, a] = acc
            else:
                h0[k] = h[i, k]
                for a in range(d_l):
                    H[k, a] = C[i, k, a]
        for a in range(d_l):
            m[i, a] = m_pred[i, a]
            for b in range(d_l):
                P[i, a, b] = P_pred[i, a, b]
        lli = 0.0
        for k in range(n_y):
            r = y[k] - h0[k]
            s = rvar[k]
            for a in range(d_l):
                r -= H[k, a] * (m[i, a] - m_pred[i, a])
                acc = 0.0
                for b in range(d_l):
                    acc += P[i, a, b] * H[k, b]
                PH[a] = acc
            for a in range(d_l):
                s += H[k, a] * PH[a]
            lli += -0.5 * (r * r / s + np.log(s)) - 0.5 * LOG_2PI
            for a in range(d_l):
                K = PH[a] / s
                m[i, a] += K * r
                for b in range(d_l):
                    P[i, a, b] -= K * PH[b]
        if whiten:
            lli -= logdet
        ll[i] = lli


@njit(nogil=True, error_model="numpy", no_cpython_wrapper=True)
def mixture_moments(wu, total, mom, xn, post, split, est, cov):
    """[Schon2005] Alg. 1 step 5: mean ``est`` and covariance ``cov`` of the posterior sum_i w_i
    delta(x^n_i) N(m_i, P_i), w_i = wu_i / total, from the weighted means in ``mom``: cov = sum_i w_i
    (d_i d_i' + [0 0; 0 P_i]), ``mom.dev`` scratch. Twin of :func:`pfbench.filters.marginalized.mixture_moments`."""
    mean_n, mean_l, dev, m, P, idx_n, idx_l = mom.mean_n, mom.mean_l, mom.dev, post.m, post.P, split.n, split.l
    n = wu.shape[0]
    d_n = idx_n.shape[0]
    d_l = idx_l.shape[0]
    n_x = d_n + d_l
    for a in range(d_n):
        est[idx_n[a]] = mean_n[a]
        for i in range(n):
            dev[i, idx_n[a]] = xn[i, a] - mean_n[a]
    for a in range(d_l):
        est[idx_l[a]] = mean_l[a]
        for i in range(n):
            dev[i, idx_l[a]] = m[i, a] - mean_l[a]
    for r in range(n_x):
        for c in range(r + 1):
            acc = 0.0
            for i in range(n):
                acc += wu[i] * dev[i, r] * dev[i, c]
            v = acc / total
            cov[r, c] = v
            cov[c, r] = v
    for a in range(d_l):
        for b in range(a + 1):
            acc = 0.0
            for i in range(n):
                acc += wu[i] * (0.5 * (P[i, a, b] + P[i, b, a]))
            v = acc / total
            cov[idx_l[a], idx_l[b]] += v
            if a != b:
                cov[idx_l[b], idx_l[a]] += v


#: ``copy_into``'s codes of the structure function it copies from, and their (constant) messages
TRANSITION, OBSERVATION, CONSTRAIN = 0, 1, 2
_RESHAPED_TRANSITION = "cl_transition" + RESHAPED
_RESHAPED_OBSERVATION = "cl_observation" + RESHAPED
_RESHAPED_CONSTRAIN = "cl_constrain" + RESHAPED


@njit(nogil=True)
def copy_into(src, dst, fn):
    """dst[...] = src for a float64 C ``dst`` and ``src`` of its shape, any dtype and layout: one flat
    loop, as the inner axes (d_n, d_l, n_y) are too short for nested ones. ``src`` of another shape
    (a model whose structure function ``fn``, a code above, changed the shapes it returns after the
    check before the run) is a ValueError naming ``fn``
    (:func:`pfbench.models.contract.compiled_model_code` names the model)."""
    if src.shape != dst.shape:
        if fn == TRANSITION:
            raise ValueError(_RESHAPED_TRANSITION)
        if fn == OBSERVATION:
            raise ValueError(_RESHAPED_OBSERVATION)
        raise ValueError(_RESHAPED_CONSTRAIN)
    s = np.ascontiguousarray(src).reshape(src.size)
    d = dst.reshape(dst.size)
    for i in range(d.size):
        d[i] = s[i]


@njit(nogil=True, no_cpython_wrapper=True)
def normals_into(rng, out):
    """``out`` (float64, C) filled as ``rng.standard_normal(out.shape)`` would: the MPF's x^n noise,
    a function of its own so the driver calls the draws by address."""
    fill_normals(rng, out)
