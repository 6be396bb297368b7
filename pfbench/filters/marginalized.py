"""Marginalized (Rao-Blackwellized) particle filter, MPF ([MultiPDF] §5, its refs. [19, 21]).

The state splits into a nonlinear part x^n (particles) and a part x^l that enters the
transition linearly (a Kalman filter per particle)::

    x^n_t = f^n(x^n_{t-1}, u_t) + A^n x^l_{t-1} + w^n,    w^n ~ N(0, Q^n)
    x^l_t = f^l(x^n_{t-1}, u_t) + A^l x^l_{t-1} + w^l,    w^l ~ N(0, Q^l)
    y_t   = h(x^n_t, x^l_t) + e,                          e ~ N(0, diag R)

Algorithm (Schön, Gustafsson & Nordlund 2005, Alg. 1; [MultiPDF] ref. [19]) per step t:

1. sample x^n_t ~ N(f^n + A^n m, N),  N = A^n P A^n' + Q^n  (per particle, Cholesky of N);
2. Kalman time update that also uses x^n_t as a measurement of x^l_{t-1}:
   m <- A^l (m + P A^n' N^-1 (x^n_t - f^n - A^n m)) + f^l,
   P <- A^l (P - P A^n' N^-1 A^n P) A^l' + Q^l;
3. weight w ∝ p(y_t | x^n_t, Y_{t-1}) = N(y_t; h(x^n_t, m), H P H' + R) and Kalman
   measurement update, with h linearised in x^l at the predicted mean (the paper's MPF uses
   an EKF for the linear states, §1): exact when h is linear in x^l. The outputs are processed
   one at a time (R is diagonal), which equals the batch update for a fixed linearisation;
4. estimate = weighted mean of (x^n, m); systematic resampling every step (as the bootstrap
   filter of [MultiPDF] Alg. 1).

When every state is linear in the transition (Ob2, Ob3 and the linear-Gaussian model) there is
no x^n: every "particle" carries the same Kalman/EKF recursion, so the MPF is exactly the
(E)KF and its result does not depend on N_p ([MultiPDF] §5: "the performance of MPF is
independent of the number of particles") -- we run one copy. On a linear-Gaussian model the
MPF therefore equals the exact Kalman filter.

Structures are defined here for ``ob2``, ``ob3``, ``ob5`` (x^n = (x1, x3, x4), x^l = x2: the
velocity enters every equation linearly and no measurement) and ``linear_gaussian``
(diagonal R, no inputs). Ob5: the §4 constraints are applied to the sampled x^n after the
Kalman update used the unconstrained draw (they are inactive near the operating point); x2 is
not constrained.

Backends: the step is written once as vectorised NumPy helpers (``register_jitable``); the
``numpy`` driver runs them as Python and resamples with :mod:`pfbench.resampling`, the
``numba`` driver compiles them and resamples with :mod:`pfbench.backends.numba_resampling`.
Random numbers are drawn from one ``numpy.random.Generator`` in this order: x^n prior
(n, d_n) standard normals; per step the x^n noise (n, d_n) then the resampling draws. Both
backends draw the same numbers and give the same estimates.
"""
from __future__ import annotations

import math
import time

import numpy as np
from ..backends.cache import njit
from numba.extending import register_jitable

from ..backends.numba_resampling import cumsum_into, resample_into
from ..resampling import Scheme
from ..errors import PfbenchError
from ..models.ob2 import ob2_h
from ..models.ob3 import ob3_h
from ..models.ob5 import ob5_coil_factor, ob5_fem, ob5_h
from .result import FilterResult

KIND_OB2, KIND_OB3, KIND_LINEAR, KIND_OB5 = 0, 1, 2, 3
_LOG2PI = math.log(2.0 * math.pi)


# --------------------------------------------------------------------------- structure
@register_jitable
def _fn(kind, xn, u, fpar):
    """Nonlinear-part drift f^n(x^n, u) (n, d_n) without the A^n x^l term."""
    out = xn.copy()
    if kind == 3:  # Ob5: xn = (x1, x3, x4); fpar = (ts, xd, m, g)
        ts = fpar[0]
        xd = fpar[1]
        u1 = min(max(u[0], 0.00498), 1.0)
        u2 = min(max(u[1], 0.00498), 1.0)
        x1 = xn[:, 0]
        out[:, 1] = xn[:, 1] + ob5_coil_factor(x1, ts) * (2.5165 * u1 + 0.0243 - xn[:, 1])
        out[:, 2] = xn[:, 2] + ob5_coil_factor(xd - x1, ts) * (2.5165 * u2 + 0.0243 - xn[:, 2])
    return out


@register_jitable
def _fl(kind, xn, u, fpar, n, d_l):
    """Linear-part drift f^l(x^n, u) (n, d_l)."""
    out = np.zeros((n, d_l))
    if kind == 3:
        ts = fpar[0]
        xd = fpar[1]
        m = fpar[2]
        g = fpar[3]
        x1 = xn[:, 0]
        f1 = ob5_fem(xn[:, 1], x1)
        f2 = ob5_fem(xn[:, 2], xd - x1)
        out[:, 0] = ts * (g - f1 / m + f2 / m)
    return out


@register_jitable
def _clip(kind, xn, fpar):
    if kind == 3:
        xn[:, 0] = np.minimum(np.maximum(xn[:, 0], 0.0), fpar[1])
        xn[:, 1] = np.minimum(np.maximum(xn[:, 1], 0.03884), 2.38)
        xn[:, 2] = np.minimum(np.maximum(xn[:, 2], 0.03884), 2.38)


@register_jitable
def _h(kind, xn, xl, ipar, mat):
    """Noise-free outputs h(x^n, x^l) (n, n_y)."""
    if kind == 0:
        return ob2_h(xl)
    if kind == 1:
        npair = ipar[1]
        return ob3_h(xl, ipar[0], mat, ipar[2:2 + npair], ipar[2 + npair:2 + 2 * npair])
    if kind == 2:
        n = xl.shape[0]
        out = np.zeros((n, mat.shape[0]))
        for k in range(mat.shape[0]):
            for a in range(mat.shape[1]):
                out[:, k] += mat[k, a] * xl[:, a]
        return out
    full = np.empty((xn.shape[0], 4))
    full[:, 0] = xn[:, 0]
    full[:, 1] = xl[:, 0]
    full[:, 2] = xn[:, 1]
    full[:, 3] = xn[:, 2]
    return ob5_h(full)


@register_jitable
def _jac(kind, xn, xl, ipar, mat, n_y):
    """dh/dx^l at (x^n, x^l): (n, n_y, d_l); central differences for Ob2/Ob3."""
    n = xl.shape[0]
    d_l = xl.shape[1]
    H = np.zeros((n, n_y, d_l))
    if kind == 2:
        for k in range(n_y):
            for a in range(d_l):
                H[:, k, a] = mat[k, a]
    elif kind == 0 or kind == 1:
        for a in range(d_l):
            eps = 1e-6 * np.maximum(1.0, np.abs(xl[:, a]))
            xp = xl.copy()
            xm = xl.copy()
            xp[:, a] += eps
            xm[:, a] -= eps
            hp = _h(kind, xn, xp, ipar, mat)
            hm = _h(kind, xn, xm, ipar, mat)
            for k in range(n_y):
                H[:, k, a] = (hp[:, k] - hm[:, k]) / (2.0 * eps)
    return H


# --------------------------------------------------------------------------- one step
@register_jitable
def _sandwich(A, P, Q):
    """Per particle: A P and A P A^T + Q, for P (n, d_in, d_in), A (d_out, d_in), Q (d_out, d_out)."""
    n = P.shape[0]
    d_out, d_in = A.shape
    AP = np.zeros((n, d_out, d_in))
    for a in range(d_out):
        for b in range(d_in):
            for c in range(d_in):
                AP[:, a, b] += A[a, c] * P[:, c, b]
    S = np.zeros((n, d_out, d_out))
    for a in range(d_out):
        for b in range(d_out):
            S[:, a, b] += Q[a, b]
            for c in range(d_in):
                S[:, a, b] += AP[:, a, c] * A[b, c]
    return AP, S


@register_jitable
def _chol(S):
    """Lower Cholesky factors of a batch of SPD matrices S (n, d, d)."""
    d = S.shape[1]
    L = np.zeros_like(S)
    for j in range(d):
        acc = S[:, j, j].copy()
        for k in range(j):
            acc -= L[:, j, k] * L[:, j, k]
        L[:, j, j] = np.sqrt(np.maximum(acc, 1e-300))
        for i in range(j + 1, d):
            acc2 = S[:, i, j].copy()
            for k in range(j):
                acc2 -= L[:, i, k] * L[:, j, k]
            L[:, i, j] = acc2 / L[:, j, j]
    return L


@register_jitable
def _predict(kind, xn, m, P, z, u, An, Al, Qn, Ql, fpar):
    """Steps 1-2: returns (x^n_t, m_pred, P_pred)."""
    n = m.shape[0]
    d_l = m.shape[1]
    d_n = xn.shape[1]
    fl = _fl(kind, xn, u, fpar, n, d_l)
    mm = m.copy()
    Pm = P.copy()
    xnew = xn.copy()
    if d_n > 0:
        fnv = _fn(kind, xn, u, fpar)
        AP, N = _sandwich(An, P, Qn)
        L = _chol(N)
        for a in range(d_n):
            acc = fnv[:, a].copy()
            for c in range(d_l):
                acc += An[a, c] * m[:, c]
            for b in range(a + 1):
                acc += L[:, a, b] * z[:, b]
            xnew[:, a] = acc
        # w = N^-1 e = L^-T z (back substitution), V = L^-1 AP (forward substitution)
        w = np.zeros((n, d_n))
        for a in range(d_n - 1, -1, -1):
            acc = z[:, a].copy()
            for b in range(a + 1, d_n):
                acc -= L[:, b, a] * w[:, b]
            w[:, a] = acc / L[:, a, a]
        V = np.zeros((n, d_n, d_l))
        for a in range(d_n):
            for c in range(d_l):
                acc = AP[:, a, c].copy()
                for b in range(a):
                    acc -= L[:, a, b] * V[:, b, c]
                V[:, a, c] = acc / L[:, a, a]
        for b in range(d_l):
            for a in range(d_n):
                mm[:, b] += AP[:, a, b] * w[:, a]
        for b in range(d_l):
            for c in range(d_l):
                for a in range(d_n):
                    Pm[:, b, c] -= V[:, a, b] * V[:, a, c]
    m_pred = fl.copy()
    for a in range(d_l):
        for b in range(d_l):
            m_pred[:, a] += Al[a, b] * mm[:, b]
    _, P_pred = _sandwich(Al, Pm, Ql)
    return xnew, m_pred, P_pred


@register_jitable
def _update(kind, xn, m_pred, P_pred, y, R, ipar, mat):
    """Step 3: log p(y_t | x^n_t, Y_{t-1}) per particle and the Kalman measurement update."""
    n = m_pred.shape[0]
    d_l = m_pred.shape[1]
    n_y = y.shape[0]
    h0 = _h(kind, xn, m_pred, ipar, mat)
    H = _jac(kind, xn, m_pred, ipar, mat, n_y)
    m = m_pred.copy()
    P = P_pred.copy()
    ll = np.zeros(n)
    for k in range(n_y):
        r = y[k] - h0[:, k]
        PH = np.zeros((n, d_l))
        s = np.full(n, R[k])
        for a in range(d_l):
            r -= H[:, k, a] * (m[:, a] - m_pred[:, a])
            for b in range(d_l):
                PH[:, a] += P[:, a, b] * H[:, k, b]
        for a in range(d_l):
            s += H[:, k, a] * PH[:, a]
        ll += -0.5 * (r * r / s + np.log(s)) - 0.5 * 1.8378770664093453
        for a in range(d_l):
            K = PH[:, a] / s
            m[:, a] += K * r
            for b in range(d_l):
                P[:, a, b] -= K * PH[:, b]
    return ll, m, P


@register_jitable
def _weigh(ll, wu):
    """wu = exp(ll - max) (NaN -> 0); returns (max, total)."""
    mx = -np.inf
    for i in range(ll.shape[0]):
        v = ll[i]
        if not (v == v) or v == np.inf:
            ll[i] = -np.inf
        elif v > mx:
            mx = v
    if not (mx > -np.inf):  # degenerate: keep uniform weights
        for i in range(ll.shape[0]):
            wu[i] = 1.0
        return -np.inf, float(ll.shape[0])
    for i in range(ll.shape[0]):
        wu[i] = np.exp(ll[i] - mx)
    total = 0.0
    for i in range(ll.shape[0]):
        total += wu[i]
    return mx, total


@register_jitable
def _moments(wu, total, xn, m, P, idx_n, idx_l, est, var):
    d_n = xn.shape[1]
    d_l = m.shape[1]
    for a in range(d_n):
        mu = np.sum(wu * xn[:, a]) / total
        est[idx_n[a]] = mu
        var[idx_n[a]] = np.sum(wu * (xn[:, a] - mu) ** 2) / total
    for a in range(d_l):
        mu = np.sum(wu * m[:, a]) / total
        est[idx_l[a]] = mu
        var[idx_l[a]] = np.sum(wu * (P[:, a, a] + (m[:, a] - mu) ** 2)) / total


@register_jitable
def _init(rng, n, kind, mn0, sn0, m0, P0, fpar):
    d_n = mn0.shape[0]
    d_l = m0.shape[0]
    xn = np.zeros((n, d_n))
    if d_n > 0:
        z = rng.standard_normal((n, d_n))
        for a in range(d_n):
            xn[:, a] = mn0[a] + sn0[a] * z[:, a]
        _clip(kind, xn, fpar)
    m = np.zeros((n, d_l))
    P = np.zeros((n, d_l, d_l))
    for i in range(n):
        m[i] = m0
        P[i] = P0
    return xn, m, P


# --------------------------------------------------------------------------- drivers
def _run_numpy(rng, n, kind, y, u, fpar, ipar, mat, An, Al, Qn, Ql, R, mn0, sn0, m0, P0,
               idx_n, idx_l, scheme, est, var, inc):
    from .. import resampling

    resample = resampling.get(scheme)
    xn, m, P = _init(rng, n, kind, mn0, sn0, m0, P0, fpar)
    d_n = xn.shape[1]
    wu = np.empty(n)
    for t in range(y.shape[0]):
        z = rng.standard_normal((n, d_n)) if d_n > 0 else np.zeros((n, 0))
        xn, m_pred, P_pred = _predict(kind, xn, m, P, z, u[t], An, Al, Qn, Ql, fpar)
        _clip(kind, xn, fpar)
        ll, m, P = _update(kind, xn, m_pred, P_pred, y[t], R, ipar, mat)
        mx, total = _weigh(ll, wu)
        inc[t] = mx + np.log(total) - np.log(n)
        _moments(wu, total, xn, m, P, idx_n, idx_l, est[t], var[t])
        if d_n > 0:
            idx = resample(wu, rng)
            xn, m, P = xn[idx], m[idx], P[idx]


@njit(nogil=True)
def _run_numba(rng, n, kind, y, u, fpar, ipar, mat, An, Al, Qn, Ql, R, mn0, sn0, m0, P0,
               idx_n, idx_l, scheme, est, var, inc):
    xn, m, P = _init(rng, n, kind, mn0, sn0, m0, P0, fpar)
    d_n = xn.shape[1]
    wu = np.empty(n)
    cdf = np.empty(n)
    idx = np.empty(n, np.int64)
    for t in range(y.shape[0]):
        if d_n > 0:
            z = rng.standard_normal((n, d_n))
        else:
            z = np.zeros((n, 0))
        xn, m_pred, P_pred = _predict(kind, xn, m, P, z, u[t], An, Al, Qn, Ql, fpar)
        _clip(kind, xn, fpar)
        ll, m, P = _update(kind, xn, m_pred, P_pred, y[t], R, ipar, mat)
        mx, total = _weigh(ll, wu)
        inc[t] = mx + np.log(total) - np.log(n)
        _moments(wu, total, xn, m, P, idx_n, idx_l, est[t], var[t])
        if d_n > 0:
            cumsum_into(wu, cdf)
            resample_into(scheme, wu, cdf, rng, idx)
            xn2 = np.empty_like(xn)
            m2 = np.empty_like(m)
            P2 = np.empty_like(P)
            for i in range(n):
                xn2[i] = xn[idx[i]]
                m2[i] = m[idx[i]]
                P2[i] = P[idx[i]]
            xn, m, P = xn2, m2, P2


# --------------------------------------------------------------------------- structures
def structure(model) -> dict:
    """The MPF split of a supported model (see the module docstring)."""
    f = np.float64
    name = model.name
    if name == "ob2":
        d = 5
        return dict(kind=KIND_OB2, idx_n=np.zeros(0, np.int64), idx_l=np.arange(d),
                    An=np.zeros((0, d)), Al=model.a * np.eye(d), Qn=np.zeros((0, 0)),
                    Ql=model.q * np.eye(d), R=np.asarray(model.r, f), mn0=np.zeros(0),
                    sn0=np.zeros(0), m0=np.zeros(d), P0=np.zeros((d, d)), fpar=np.zeros(1),
                    ipar=np.zeros(1, np.int64), mat=np.zeros((1, 1)))
    if name == "ob3":
        d = 4
        ipar = np.concatenate([[model.version, len(model.pi)], model.pi, model.pj]).astype(np.int64)
        return dict(kind=KIND_OB3, idx_n=np.zeros(0, np.int64), idx_l=np.arange(d),
                    An=np.zeros((0, d)), Al=model.a * np.eye(d), Qn=np.zeros((0, 0)),
                    Ql=model.q * np.eye(d), R=np.full(model.n_y, model.r), mn0=np.zeros(0),
                    sn0=np.zeros(0), m0=np.zeros(d), P0=np.eye(d) / 3.0,  # x^(0) ~ U[-1, 1]
                    fpar=np.zeros(1), ipar=ipar, mat=np.ascontiguousarray(model.mu, f))
    if name == "linear_gaussian":
        if model.n_u:
            raise PfbenchError("MPF on linear_gaussian supports models without inputs only")
        if np.count_nonzero(model.R - np.diag(np.diag(model.R))):
            raise PfbenchError("MPF needs a diagonal measurement covariance R")
        d = model.n_x
        return dict(kind=KIND_LINEAR, idx_n=np.zeros(0, np.int64), idx_l=np.arange(d),
                    An=np.zeros((0, d)), Al=np.array(model.A, f), Qn=np.zeros((0, 0)),
                    Ql=np.array(model.Q, f), R=np.diag(model.R).astype(f), mn0=np.zeros(0),
                    sn0=np.zeros(0), m0=np.array(model.x0, f), P0=np.array(model.P0, f),
                    fpar=np.zeros(1), ipar=np.zeros(1, np.int64),
                    mat=np.ascontiguousarray(model.C, f))
    if name == "ob5":
        q, s0, xe = model.q_std, model.p0_std, model.x_eq
        return dict(kind=KIND_OB5, idx_n=np.array([0, 2, 3]), idx_l=np.array([1]),
                    An=np.array([[model.ts], [0.0], [0.0]]), Al=np.eye(1),
                    Qn=np.diag(q[[0, 2, 3]] ** 2), Ql=np.array([[q[1] ** 2]]),
                    R=model.r_std ** 2, mn0=xe[[0, 2, 3]].copy(), sn0=s0[[0, 2, 3]].copy(),
                    m0=xe[[1]].copy(), P0=np.array([[s0[1] ** 2]]),
                    fpar=np.array([model.ts, model.xd, model.m, model.g]),
                    ipar=np.zeros(1, np.int64), mat=np.zeros((1, 1)))
    raise PfbenchError(f"no marginalized-PF structure for model {name!r} "
                       "(supported: ob2, ob3, ob5, linear_gaussian)")


def run_mpf(model, y, u=None, *, n_particles: int = 100, backend: str = "numba", seed=0,
            resampling: str = "systematic") -> FilterResult:
    """Run the marginalized PF; returns a :class:`~pfbench.filters.api.FilterResult`.

    ``n_particles`` is ignored (one Kalman/EKF copy) for models without nonlinear states.
    ``seed``: int or ``numpy.random.SeedSequence``.
    """
    from .inputs import check_inputs as _check_inputs

    if backend not in ("numpy", "numba"):
        raise PfbenchError(f"unknown backend {backend!r}; choose numpy or numba")
    if resampling not in ("systematic", "stratified", "multinomial"):
        raise PfbenchError("MPF resampling must be systematic, stratified or multinomial")
    s = structure(model)
    y, u = _check_inputs(model, y, u)
    n = int(n_particles) if len(s["idx_n"]) else 1
    if n < 1:
        raise PfbenchError(f"n_particles must be >= 1, got {n_particles}")
    M = y.shape[0]
    est = np.zeros((M, model.n_x))
    var = np.zeros((M, model.n_x))
    inc = np.zeros(M)
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    rng = np.random.default_rng(ss)
    c = np.ascontiguousarray
    args = (rng, n, int(s["kind"]), y, u, c(s["fpar"], np.float64), c(s["ipar"], np.int64),
            c(s["mat"], np.float64), c(s["An"], np.float64).reshape(len(s["idx_n"]), len(s["idx_l"])),
            c(s["Al"], np.float64), c(s["Qn"], np.float64).reshape(len(s["idx_n"]), len(s["idx_n"])),
            c(s["Ql"], np.float64), c(s["R"], np.float64), c(s["mn0"], np.float64),
            c(s["sn0"], np.float64), c(s["m0"], np.float64), c(s["P0"], np.float64),
            c(s["idx_n"], np.int64), c(s["idx_l"], np.int64))
    t0 = time.perf_counter()
    if backend == "numba":
        _run_numba(*args, int(Scheme.parse(resampling)), est, var, inc)
    else:
        _run_numpy(*args, resampling, est, var, inc)
    elapsed = time.perf_counter() - t0
    return FilterResult(estimates=est, sub_estimates=est[None].copy(), variances=var,
                        loglik=float(inc.sum()), loglik_increments=inc, ess=np.full(M, float(n)),
                        sub_ess=np.full((1, M), float(n)), n_resampled=M if n > 1 else 0,
                        degenerate=~np.isfinite(inc), elapsed_s=elapsed, method="mpf",
                        backend=backend, n_particles=n, n_filters=1,
                        info={"structure": model.name, "n_nonlinear": int(len(s["idx_n"]))})
