"""The numba marginalized-PF kernel ([Schon2005] Alg. 1): the compiled twin of
``pfbench.filters.marginalized._run_numpy``.

Same steps, same random draws in the same order (the prior ``_initial`` when d_n > 0, then per
step the x^n noise and the resampling draws), the same step math. The NumPy backend runs the
vectorised helpers of :mod:`pfbench.filters.marginalized`; their compiled twins here are written
as scalar loops over the particles, into work arrays the kernel allocates once before its time
loop, with the same operations on every scalar in the same order, so both backends agree to
rounding: :func:`_sandwich` (``sandwich``), :func:`_condition` (``cholesky_batch``, then
``condition_nonlinear`` and the decorrelation of ``kalman_predict``), :func:`_time_update`,
:func:`_kalman_update` and :func:`_mixture_moments`; ``kalman_predict`` is :func:`_sandwich`,
:func:`_condition`, :func:`_time_update` in :func:`run`. numba compiles such loops several times
faster than array expressions (each of which becomes a broadcast loop with a temporary). Each
helper is a function of its own, called by the entry point directly: a compiled function costs a
fixed ~0.2 s, and every caller optimises the machine code of all it calls once more, so the
helpers are few and call nothing but :func:`_sandwich`. Weighting, moments and resampling are the
package's one compiled versions (:mod:`pfbench.backends.numba_weights`,
:mod:`pfbench.backends.numba_resampling`, the scheme bound as ``_resample``). The model is called
through the module globals ``_initial``, ``_cl_transition``, ``_cl_observation`` and
``_cl_constrain`` (placeholders here), once per step on all particles;
:func:`pfbench.backends.numba_backend.kernel_module` writes a copy of this file per model class
with the model's compiled functions bound to those names, so numba caches the whole kernel on disk.

Two entry points, so a call compiles only what it runs: :func:`run` for models with nonlinear
states (d_n > 0) and :func:`run_linear` for d_n = 0 (the ``kalman`` method and the MPF on a fully
linear model), which needs no prior draw, no x^n sampling or conditioning, no resampling and no
particle weighting.
"""
import numpy as _np

from pfbench.backends.cache import njit as _njit
from pfbench.backends.numba_weights import moments as _moments
from pfbench.backends.numba_weights import valid_log_likelihood as _valid
from pfbench.backends.numba_weights import weigh as _weigh
from pfbench.models.base import LOG_2PI as _LOG2PI


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


# --------------------------------------------------------------------------- the step math
@_njit(nogil=True)
def _sandwich(A, P, Q, AP, S):
    """Per particle: ``AP`` = A P and ``S`` = A P A' + Q, written into AP (n, d_out, d_in) and S
    (n, d_out, d_out), for A (n, d_out, d_in), P (n, d_in, d_in), Q (d_out, d_out): N = A^n P A^n'
    + Q^n of [Schon2005] Alg. 1 step 1 and A^l P A^l' + Q^l of step 2. The twin of
    :func:`pfbench.filters.marginalized.sandwich`."""
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


@_njit(nogil=True, error_model="numpy")
def _condition(fn, An, fl, Al, m, P, z, N, AP, T, corr, L, w, V, xnew, mm, Pm, f, A):
    """[Schon2005] Alg. 1 steps 1-2 up to the time update, for d_n > 0, per particle: the lower
    Cholesky factor ``L`` of N = A^n P A^n' + Q^n (pivots floored at 1e-300; the upper triangle
    is neither written nor read); the sample x^n_t = f^n + A^n m + L z into ``xnew``; x^l_{t-1}
    conditioned on it, ``mm`` = m + P A^n' N^-1 (x^n_t - f^n - A^n m) and ``Pm`` = P - P A^n'
    N^-1 A^n P (by back substitution N^-1 (...) = L^-T z and V = L^-1 A^n P); and the x^l
    transition into ``f``, ``A``: with ``corr`` (a cross-covariance Q^ln) f = f^l + T (x^n_t - f^n)
    and A = A^l - T A^n, T = Q^ln (Q^n)^-1, else f^l and A^l. ``N`` and ``AP`` = A^n P come from
    :func:`_sandwich`; ``w`` (d_n,) and ``V`` (d_n, d_l) are scratch. The twin of
    :func:`pfbench.filters.marginalized.cholesky_batch`,
    :func:`~pfbench.filters.marginalized.condition_nonlinear` and the decorrelation of
    :func:`~pfbench.filters.marginalized.kalman_predict`."""
    n = m.shape[0]
    d_l = m.shape[1]
    d_n = fn.shape[1]
    for i in range(n):
        for j in range(d_n):
            acc = N[i, j, j]
            for k in range(j):
                acc -= L[i, j, k] * L[i, j, k]
            L[i, j, j] = _np.sqrt(1e-300 if acc < 1e-300 else acc)  # np.maximum: NaN stays NaN
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


@_njit(nogil=True)
def _time_update(f, A, m, P, Q, AP, m_pred, P_pred):
    """The linear-Gaussian time update of [Schon2005] Alg. 1 step 2: ``m_pred`` = f + A m and
    ``P_pred`` = A P A' + Q per particle (``AP`` (n, d_l, d_l) scratch). With d_n = 0 this is the
    whole prediction of the Kalman filter. The twin of
    :func:`pfbench.filters.marginalized.time_update`."""
    n = m.shape[0]
    d_l = m.shape[1]
    for i in range(n):
        for a in range(d_l):
            acc = f[i, a]
            for b in range(d_l):
                acc += A[i, a, b] * m[i, b]
            m_pred[i, a] = acc
    _sandwich(A, P, Q, AP, P_pred)


@_njit(nogil=True, error_model="numpy")
def _kalman_update(h, C, m_pred, P_pred, y, W, rvar, whiten, logdet, h0, H, PH, ll, m, P):
    """[Schon2005] Alg. 1 step 4: log p(y_t | x^n_t, Y_{t-1}) per particle into ``ll`` (n,) and the
    measurement update into ``m`` (n, d_l), ``P`` (n, d_l, d_l); ``h0`` (n_y,), ``H`` (n_y, d_l),
    ``PH`` (d_l,) are scratch. Arguments as for :func:`pfbench.filters.marginalized.kalman_update`
    (its twin): the outputs whitened with ``W`` when ``whiten`` and processed one scalar at a time,
    residuals taken about the fixed linearisation point ``m_pred``."""
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
            lli += -0.5 * (r * r / s + _np.log(s)) - 0.5 * _LOG2PI
            for a in range(d_l):
                K = PH[a] / s
                m[i, a] += K * r
                for b in range(d_l):
                    P[i, a, b] -= K * PH[b]
        if whiten:
            lli -= logdet
        ll[i] = lli


@_njit(nogil=True, error_model="numpy")
def _mixture_moments(wu, total, mean_n, mean_l, xn, m, P, idx_n, idx_l, dev, est, cov):
    """[Schon2005] Alg. 1 step 5: the full-state mean ``est`` (n_x,) and covariance ``cov`` (n_x,
    n_x) of the MPF posterior sum_i w_i delta(x^n_i) N(m_i, P_i), w_i = wu_i / total, given the
    weighted means of x^n (``mean_n``) and of the m_i (``mean_l``): cov = sum_i w_i (d_i d_i' +
    [0 0; 0 P_i]); ``dev`` (n, n_x) scratch for the d_i. The twin of
    :func:`pfbench.filters.marginalized.mixture_moments`."""
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


# --------------------------------------------------------------------------- entry points
@_njit(nogil=True)
def run(p, rng, y, u, n, idx_n, idx_l, Qn, Ql, T, corr, W, rvar, whiten, logdet, m0, P0, scheme,
        est, cov, ess, inc, degen):
    """Run the MPF over all steps with ``n`` particles (one random stream, documented order).

    ``y`` (M, n_y) are the (whitened, if ``whiten``) measurements; ``idx_n``/``idx_l`` the state
    indices of x^n/x^l (d_n > 0; :func:`run_linear` serves d_n = 0); the noise and whitening
    arrays as prepared by ``pfbench.filters.marginalized.structure``; ``scheme`` a
    :class:`~pfbench.resampling.Scheme` code. Fills est (M, n_x), cov (M, n_x, n_x), ess, inc,
    degen (M,).

    Per step ([Schon2005] Alg. 1): the x^n noise, the model's ``cl_transition``, steps 1-2
    (:func:`_sandwich`, :func:`_condition`, :func:`_time_update`), step 3 (``cl_constrain``), step
    4 (``cl_observation``, :func:`_kalman_update`, the weights), step 5 (moments,
    :func:`_mixture_moments`, resampling).
    """
    d_n = idx_n.shape[0]
    d_l = idx_l.shape[0]
    n_y = y.shape[1]
    xn = _np.empty((n, d_n))
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
    xnew = _np.empty((n, d_n))
    APn = _np.empty((n, d_n, d_l))
    N = _np.empty((n, d_n, d_n))
    L = _np.empty((n, d_n, d_n))
    w = _np.empty(d_n)
    V = _np.empty((d_n, d_l))
    f = _np.empty((n, d_l))
    A = _np.empty((n, d_l, d_l))
    APl = _np.empty((n, d_l, d_l))
    mm = _np.empty((n, d_l))
    Pm = _np.empty((n, d_l, d_l))
    m_pred = _np.empty((n, d_l))
    P_pred = _np.empty((n, d_l, d_l))
    h0 = _np.empty(n_y)
    H = _np.empty((n_y, d_l))
    PH = _np.empty(d_l)
    dev = _np.empty((n, d_n + d_l))
    ll = _np.empty(n)
    lw = _np.empty(n)
    lw0 = -_np.log(n)
    for i in range(n):
        lw[i] = lw0
    wu = _np.empty(n)
    cdf = _np.empty(n)
    idx = _np.empty(n, _np.int64)
    mean_n = _np.empty(d_n)
    var_n = _np.empty(d_n)
    mean_l = _np.empty(d_l)
    var_l = _np.empty(d_l)
    for t in range(y.shape[0]):
        ut = u[t]
        z = rng.standard_normal((n, d_n))
        fn, An, fl, Al = _cl_transition(xn, ut, t, p)
        _sandwich(An, P, Qn, APn, N)
        _condition(fn, An, fl, Al, m, P, z, N, APn, T, corr, L, w, V, xnew, mm, Pm, f, A)
        _time_update(f, A, mm, Pm, Ql, APl, m_pred, P_pred)
        xs = _cl_constrain(xnew, p)
        h, C = _cl_observation(xs, m_pred, ut, t, p)
        _kalman_update(h, C, m_pred, P_pred, y[t], W, rvar, whiten, logdet, h0, H, PH, ll, mm, Pm)
        mx, total, deg = _weigh(lw, ll, wu, cdf)
        degen[t] = deg
        inc[t] = -_np.inf if deg else mx + _np.log(total)
        ess[t] = _moments(xs, wu, total, mean_n, var_n)
        _moments(mm, wu, total, mean_l, var_l)
        _mixture_moments(wu, total, mean_n, mean_l, xs, mm, Pm, idx_n, idx_l, dev, est[t], cov[t])
        _resample(scheme, wu, cdf, rng, idx)
        for i in range(n):
            j = idx[i]
            for a in range(d_n):
                xn[i, a] = xs[j, a]
            for a in range(d_l):
                m[i, a] = mm[j, a]
                for b in range(d_l):
                    P[i, a, b] = Pm[j, a, b]


@_njit(nogil=True)
def run_linear(p, y, u, idx_l, Ql, W, rvar, whiten, logdet, m0, P0, est, cov, ess, inc, degen):
    """The d_n = 0 case of :func:`run` (every state in x^l): one Kalman/EKF recursion, no random
    numbers, no resampling; the same operations as :func:`run` with one particle, compiled without
    the x^n sampling, conditioning and resampling it never runs. Arguments as for :func:`run`.

    The one copy's weight is exp(0) = 1 whatever its likelihood, so the weighting of :func:`run`
    reduces to: increment = log p(y_t | Y_{t-1}) (-inf, and ``degen`` set, when that is -inf, +inf
    or NaN, as :func:`~pfbench.backends.numba_weights.weigh` decides), N_eff = 1, the mean of x^l
    = the copy's own."""
    d_l = idx_l.shape[0]
    n_y = y.shape[1]
    xn = _np.empty((1, 0))
    idx_n = _np.empty(0, _np.int64)
    mean_n = _np.empty(0)
    m = _np.empty((1, d_l))
    P = _np.empty((1, d_l, d_l))
    for a in range(d_l):
        m[0, a] = m0[a]
        for b in range(d_l):
            P[0, a, b] = P0[a, b]
    AP = _np.empty((1, d_l, d_l))
    m_pred = _np.empty((1, d_l))
    P_pred = _np.empty((1, d_l, d_l))
    h0 = _np.empty(n_y)
    H = _np.empty((n_y, d_l))
    PH = _np.empty(d_l)
    dev = _np.empty((1, d_l))
    ll = _np.empty(1)
    wu = _np.empty(1)
    wu[0] = 1.0
    mean_l = _np.empty(d_l)
    for t in range(y.shape[0]):
        ut = u[t]
        _, _, fl, Al = _cl_transition(xn, ut, t, p)
        _time_update(fl, Al, m, P, Ql, AP, m_pred, P_pred)
        h, C = _cl_observation(xn, m_pred, ut, t, p)
        _kalman_update(h, C, m_pred, P_pred, y[t], W, rvar, whiten, logdet, h0, H, PH, ll, m, P)
        v = _valid(ll[0])
        deg = not (v > -_np.inf)
        degen[t] = deg
        inc[t] = -_np.inf if deg else v
        ess[t] = 1.0
        for a in range(d_l):
            mean_l[a] = m[0, a]
        _mixture_moments(wu, 1.0, mean_n, mean_l, xn, m, P, idx_n, idx_l, dev, est[t], cov[t])
