"""Marginalized (Rao-Blackwellized) particle filter, MPF ([Schon2005] Alg. 1; [MultiPDF] §5), and
the Kalman filter it reduces to when every state is linear-Gaussian.

The filter runs on *any* model that declares a conditionally linear-Gaussian substructure
(``linear_states`` and the ``cl_*`` members of :class:`~pfbench.models.base.StateSpaceModel`)::

    x^n_t = f^n(x^n_{t-1}) + A^n(x^n_{t-1}) x^l_{t-1} + w^n
    x^l_t = f^l(x^n_{t-1}) + A^l(x^n_{t-1}) x^l_{t-1} + w^l,    (w^n, w^l) ~ N(0, Q)
    y_t   = h(x^n_t, x^l_t) + e,                                e ~ N(0, R)

x^n is carried by particles, x^l by one Kalman filter per particle. It knows no model by name.

Algorithm, per step t ([Schon2005] Alg. 1, in the order of our time convention):

1. sample x^n_t ~ N(f^n + A^n m, N), N = A^n P A^n' + Q^n (per particle, Cholesky L of N);
2. condition x^l_{t-1} on x^n_t (the "measurement" x^n_t - f^n = A^n x^l_{t-1} + w^n):
   m <- m + P A^n' N^-1 (x^n_t - f^n - A^n m), P <- P - P A^n' N^-1 A^n P; then the time update
   m <- f^l + A^l m, P <- A^l P A^l' + Q^l. A cross-covariance Q^ln between w^l and w^n is
   supported by decorrelating it: with T = Q^ln (Q^n)^-1, f^l gains T (x^n_t - f^n), A^l becomes
   A^l - T A^n and Q^l becomes Q^l - T Q^nl;
3. apply the model's optional constraints to x^n_t (:meth:`cl_constrain`; after step 2, which used
   the unconstrained draw);
4. weight w ∝ p(y_t | x^n_t, Y_{t-1}) = N(y_t; h, C P C' + R) and Kalman measurement update, with
   h and C = dh/dx^l from the model's ``cl_observation`` at the predicted mean of x^l: exact when
   y is linear in x^l, an EKF linearisation otherwise (the MPF of [MultiPDF] §5 uses an EKF for
   the linear states). The outputs are processed one scalar at a time; a full R is first whitened
   with its Cholesky factor L (y <- L^-1 y once, h <- L^-1 h, C <- L^-1 C per step), which equals
   the batch update for a fixed linearisation;
5. estimates: the full-state mean and covariance of the mixture sum_i w_i delta(x^n_i) N(m_i, P_i);
   resample every step (as the bootstrap filter of [MultiPDF] Alg. 1), with any
   :class:`~pfbench.resampling.Scheme`.

When the model has no nonlinear states (d_n = 0; Ob2, Ob3, the linear-Gaussian model) every
particle would carry the same Kalman/EKF recursion, so one copy runs and ``n_particles`` is
ignored ([MultiPDF] §5: "the performance of MPF is independent of the number of particles"); the
result then equals the exact Kalman filter on a linear-Gaussian model. :func:`run_kalman`
(``method="kalman"``) runs that same recursion and refuses models with nonlinear states.

Backends and random numbers. The ``numpy`` driver runs the step math below as vectorised NumPy
helpers (:func:`kalman_predict` = :func:`condition_nonlinear` + :func:`time_update`,
:func:`kalman_update`, :func:`mixture_moments`) with :func:`pfbench.backends.numpy_backend.weigh`
and :mod:`pfbench.resampling`. The ``numba`` driver (:mod:`pfbench.backends.numba_mpf`) compiles
their twins, the same operations on every scalar in the same order written as loops over the
particles (which numba compiles several times faster than these array expressions), with the
model's functions, :mod:`pfbench.backends.numba_weights` and the scheme's kernel of
:mod:`pfbench.backends.numba_resampling`; with d_n = 0 it compiles only the Kalman recursion
(``run_linear``: no sampling, conditioning or resampling code). Both draw from one
``numpy.random.default_rng(seed)`` in this order: the prior ``initial(rng, N_p, p)`` (only when
d_n > 0; its x^n columns are kept), then per step the x^n noise ``standard_normal((N_p, d_n))``
followed by the resampling draws. With d_n = 0 nothing is drawn. Both backends draw the same
numbers and agree to rounding (tested <= 1e-9).
"""
from __future__ import annotations

import time

import numpy as np

from .. import resampling as _resampling
from ..backends.mpf_work import outputs
from ..backends.numpy_backend import valid_log_likelihood, weigh
from ..errors import InputError, ModelError, UnsupportedError
from ..models.base import LOG_2PI as _LOG2PI, StateSpaceModel
from ..models.contract import PROBE, call, call_returning, defined, linear_indices, name_of, returned, shaped
from ..resampling import Scheme
from ..methods import check_backend, check_dtype
from .inputs import check_inputs, seed_sequence
from .result import FilterResult, reported_ess

_CL_FUNCTIONS = ("cl_transition", "cl_observation", "cl_noise", "cl_prior")
_NEEDED = {fn: "the marginalized PF" for fn in ("initial", "cl_transition", "cl_constrain", "cl_observation")}


# --------------------------------------------------------------------------- the step math
def sandwich(A, P, Q):
    """Per particle: A P and A P A' + Q, for A (n, d_out, d_in), P (n, d_in, d_in), Q (d_out, d_out)."""
    n = P.shape[0]
    d_out = A.shape[1]
    d_in = A.shape[2]
    AP = np.zeros((n, d_out, d_in))
    for a in range(d_out):
        for b in range(d_in):
            for c in range(d_in):
                AP[:, a, b] += A[:, a, c] * P[:, c, b]
    S = np.zeros((n, d_out, d_out))
    for a in range(d_out):
        for b in range(d_out):
            S[:, a, b] += Q[a, b]
            for c in range(d_in):
                S[:, a, b] += AP[:, a, c] * A[:, b, c]
    return AP, S


def cholesky_batch(S):
    """Lower Cholesky factors of a batch of SPD matrices S (n, d, d) (pivots floored at 1e-300)."""
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


def condition_nonlinear(fn, An, m, P, z, Qn):
    """Step 1 and the first half of step 2 of the module docstring ([Schon2005] Alg. 1), for
    d_n > 0: sample x^n_t = f^n + A^n m + L z (L L' = N = A^n P A^n' + Q^n) and condition
    x^l_{t-1} on it. Returns (x^n_t (n, d_n), m (n, d_l), P (n, d_l, d_l)) conditioned."""
    n = m.shape[0]
    d_l = m.shape[1]
    d_n = fn.shape[1]
    mm = m.copy()
    Pm = P.copy()
    xnew = np.zeros((n, d_n))
    AP, N = sandwich(An, P, Qn)
    L = cholesky_batch(N)
    for a in range(d_n):  # x^n_t = f^n + A^n m + L z
        acc = fn[:, a].copy()
        for c in range(d_l):
            acc += An[:, a, c] * m[:, c]
        for b in range(a + 1):
            acc += L[:, a, b] * z[:, b]
        xnew[:, a] = acc
    # N^-1 (x^n_t - f^n - A^n m) = L^-T z (back substitution); V = L^-1 A^n P (forward)
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
    return xnew, mm, Pm


def time_update(f, A, m, P, Q):
    """The linear-Gaussian time update (second half of step 2): m_pred = f + A m and
    P_pred = A P A' + Q per particle, for f (n, d_l), A (n, d_l, d_l), Q (d_l, d_l).
    With d_n = 0 this is the whole prediction of the Kalman filter."""
    d_l = m.shape[1]
    m_pred = f.copy()
    for a in range(d_l):
        for b in range(d_l):
            m_pred[:, a] += A[:, a, b] * m[:, b]
    _, P_pred = sandwich(A, P, Q)
    return m_pred, P_pred


def kalman_predict(fn, An, fl, Al, m, P, z, Qn, Ql, T, corr):
    """Steps 1-2 of the module docstring ([Schon2005] Alg. 1): sample x^n_t and predict x^l_t.

    ``fn, An, fl, Al`` from the model's ``cl_transition`` at x^n_{t-1}; ``m`` (n, d_l), ``P``
    (n, d_l, d_l): x^l_{t-1} | Y_{t-1}; ``z`` (n, d_n) standard normals; ``Qn`` (d_n, d_n); ``Ql``
    (d_l, d_l) the (decorrelated) x^l noise covariance; ``T`` (d_l, d_n) = Q^ln (Q^n)^-1, used
    when ``corr``. Returns (x^n_t (n, d_n), m_pred (n, d_l), P_pred (n, d_l, d_l)).
    :func:`condition_nonlinear` (d_n > 0) followed by :func:`time_update`.
    """
    n = m.shape[0]
    d_l = m.shape[1]
    d_n = fn.shape[1]
    if d_n > 0:
        xnew, mm, Pm = condition_nonlinear(fn, An, m, P, z, Qn)
    else:
        xnew = np.zeros((n, d_n))
        mm = m.copy()
        Pm = P.copy()
    A = Al
    f = fl
    if corr:  # decorrelated noise: f^l + T (x^n_t - f^n), A^l - T A^n
        A = Al.copy()
        f = fl.copy()
        for a in range(d_l):
            for c in range(d_n):
                f[:, a] += T[a, c] * (xnew[:, c] - fn[:, c])
                for b in range(d_l):
                    A[:, a, b] -= T[a, c] * An[:, c, b]
    m_pred, P_pred = time_update(f, A, mm, Pm, Ql)
    return xnew, m_pred, P_pred


def kalman_update(h, C, m_pred, P_pred, y, W, rvar, whiten, logdet):
    """Step 4: log p(y_t | x^n_t, Y_{t-1}) per particle (n,) and the measurement update (m, P).

    ``h`` (n, n_y), ``C`` (n, n_y, d_l): the model's ``cl_observation`` at ``m_pred``; ``y``
    (n_y,) the (whitened, if ``whiten``) measurement; ``W`` (n_y, n_y) = L^-1 (lower triangular)
    with L L' = R, used when ``whiten``; ``rvar`` (n_y,) the variances of the (whitened) outputs;
    ``logdet`` = log det L. Scalar outputs are processed one at a time, residuals taken about the
    fixed linearisation point ``m_pred``.
    """
    n = m_pred.shape[0]
    d_l = m_pred.shape[1]
    n_y = y.shape[0]
    h0 = h
    H = C
    if whiten:
        h0 = np.zeros((n, n_y))
        H = np.zeros((n, n_y, d_l))
        for k in range(n_y):
            for j in range(k + 1):
                h0[:, k] += W[k, j] * h[:, j]
                for a in range(d_l):
                    H[:, k, a] += W[k, j] * C[:, j, a]
    m = m_pred.copy()
    P = P_pred.copy()
    ll = np.zeros(n)
    for k in range(n_y):
        r = y[k] - h0[:, k]
        PH = np.zeros((n, d_l))
        s = np.full(n, rvar[k])
        for a in range(d_l):
            r -= H[:, k, a] * (m[:, a] - m_pred[:, a])
            for b in range(d_l):
                PH[:, a] += P[:, a, b] * H[:, k, b]
        for a in range(d_l):
            s += H[:, k, a] * PH[:, a]
        ll += -0.5 * (r * r / s + np.log(s)) - 0.5 * _LOG2PI
        for a in range(d_l):
            K = PH[:, a] / s
            m[:, a] += K * r
            for b in range(d_l):
                P[:, a, b] -= K * PH[:, b]
    if whiten:
        ll -= logdet
    return ll, m, P


def mixture_moments(wu, total, mean_n, mean_l, xn, m, P, idx_n, idx_l, est, cov):
    """Full-state mean ``est`` (n_x,) and covariance ``cov`` (n_x, n_x) of the MPF posterior
    sum_i w_i delta(x^n_i) N(m_i, P_i), w_i = wu_i / total, given the weighted means of x^n
    (``mean_n``) and of the m_i (``mean_l``): cov = sum_i w_i (d_i d_i' + [0 0; 0 P_i])."""
    n = wu.shape[0]
    d_n = idx_n.shape[0]
    d_l = idx_l.shape[0]
    n_x = d_n + d_l
    dev = np.empty((n, n_x))
    for a in range(d_n):
        est[idx_n[a]] = mean_n[a]
        dev[:, idx_n[a]] = xn[:, a] - mean_n[a]
    for a in range(d_l):
        est[idx_l[a]] = mean_l[a]
        dev[:, idx_l[a]] = m[:, a] - mean_l[a]
    for i in range(n_x):
        for j in range(i + 1):
            c = np.sum(wu * dev[:, i] * dev[:, j]) / total
            cov[i, j] = c
            cov[j, i] = c
    for a in range(d_l):
        for b in range(a + 1):
            c = np.sum(wu * (0.5 * (P[:, a, b] + P[:, b, a]))) / total
            cov[idx_l[a], idx_l[b]] += c
            if a != b:
                cov[idx_l[b], idx_l[a]] += c


# --------------------------------------------------------------------------- structure
def _declares_structure(model) -> bool:
    if getattr(model, "linear_states", None) is None:
        return False
    cls = type(model)
    return all(getattr(cls, f) is not getattr(StateSpaceModel, f) for f in _CL_FUNCTIONS)


def _psd(a: np.ndarray, what: str, definite: bool) -> None:
    if a.size == 0:
        return
    if not np.all(np.isfinite(a)):
        raise InputError(f"{what} must be finite, got {a.tolist()}")
    if not np.allclose(a, a.T, rtol=1e-10, atol=1e-12 * max(1.0, float(np.abs(a).max()))):
        raise InputError(f"{what} must be symmetric")
    if definite:
        try:
            np.linalg.cholesky(0.5 * (a + a.T))
        except np.linalg.LinAlgError:
            raise InputError(f"{what} must be positive definite") from None
    else:
        w = np.linalg.eigvalsh(0.5 * (a + a.T))
        if w.min() < -1e-12 * float(np.abs(w).max()):
            raise InputError(f"{what} must be positive semi-definite")


def structure(model, y, u, method: str = "mpf") -> dict:
    """The validated linear-Gaussian split of ``model`` (UnsupportedError if it declares none).

    Returns the index arrays ``idx_n``/``idx_l``, the noise blocks (``Qn``, decorrelated ``Ql``,
    ``T``, ``corr``), the measurement whitening (``W``, ``rvar``, ``whiten``, ``logdet``, the
    whitened measurements ``yw``) and the x^l prior (``m0``, ``P0``). The model's functions are
    called once on a probe block to check what they return (:func:`structure_check`) and that they
    describe the model of its ``transition`` and ``observe`` (:func:`check_agreement`; ``method``
    names the method in that message).
    """
    name = f"model {name_of(model)!r}"
    if not _declares_structure(model):
        raise UnsupportedError(
            f"{name} declares no conditionally linear-Gaussian substructure, which method "
            "'mpf'/'kalman' needs: set `linear_states` (indices of the states x^l that enter the "
            "transition and measurement linearly) and implement cl_transition, cl_observation, "
            "cl_noise and cl_prior (see pfbench.models.base.StateSpaceModel)")
    n_x, n_y = int(model.n_x), int(model.n_y)
    idx_l = linear_indices(model)
    idx_n = np.array([i for i in range(n_x) if i not in set(idx_l.tolist())], dtype=np.int64)
    d_n, d_l = idx_n.size, idx_l.size
    Q, R = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in call_returning(model, "cl_noise", ("Q", "R")))
    if Q.shape != (n_x, n_x) or R.shape != (n_y, n_y):
        raise InputError(f"{name}: cl_noise() must return Q ({n_x}, {n_x}) and R ({n_y}, {n_y}), "
                         f"got {Q.shape} and {R.shape}")
    _psd(Q, f"{name}: Q", False)
    _psd(R, f"{name}: R", True)
    Qn, Ql, Qnl = Q[np.ix_(idx_n, idx_n)], Q[np.ix_(idx_l, idx_l)], Q[np.ix_(idx_n, idx_l)]
    _psd(Qn, f"{name}: the noise covariance Q^n of the nonlinear states", True)
    corr = bool(np.any(Qnl != 0.0))
    T = np.zeros((d_l, d_n))
    if corr:  # w^l = T w^n + wbar, T = Q^ln (Q^n)^-1, Cov wbar = Q^l - T Q^nl
        T = np.linalg.solve(Qn, Qnl).T
        Ql = Ql - T @ Qnl
    m0, P0 = call_returning(model, "cl_prior", ("m0", "P0"))
    m0 = np.asarray(m0, dtype=np.float64).reshape(-1)
    P0 = np.atleast_2d(np.asarray(P0, dtype=np.float64))
    if m0.shape != (d_l,) or P0.shape != (d_l, d_l):
        raise InputError(f"{name}: cl_prior() must return m0 ({d_l},) and P0 ({d_l}, {d_l}), "
                         f"got {m0.shape} and {P0.shape}")
    _psd(P0, f"{name}: the prior covariance P0 of x^l", False)
    if not np.all(np.isfinite(m0)):
        raise InputError(f"{name}: the prior mean m0 of x^l must be finite, got {m0.tolist()}")
    whiten = bool(np.count_nonzero(R - np.diag(np.diag(R))))
    if whiten:
        L = np.linalg.cholesky(R)
        W = np.tril(np.linalg.inv(L))  # L^-1 is lower triangular; tril drops rounding noise
        rvar, logdet = np.ones(n_y), float(np.sum(np.log(np.diag(L))))
        yw = np.ascontiguousarray(y @ W.T)
    else:
        W, rvar, logdet, yw = np.eye(n_y), np.diag(R).copy(), 0.0, y
    _check_shapes(model, u, idx_n, idx_l, m0, method)
    c = np.ascontiguousarray
    return dict(idx_n=idx_n, idx_l=idx_l, d_n=d_n, d_l=d_l, Qn=c(Qn), Ql=c(Ql), T=c(T), corr=corr,
                W=c(W), rvar=c(rvar), whiten=whiten, logdet=logdet, yw=c(yw), m0=c(m0), P0=c(P0))


def structure_check(model, n: int, d_n: int, d_l: int, n_y: int):
    """``check(fn, out, step=None)``: ``out``, what the structure function ``fn`` returned on n
    particles at ``step`` (None: in the check before the run), as a tuple of its arrays, else a
    ModelError naming the model, the function, the result and the step. Both backends check the
    probe before the run; the NumPy driver checks every step; the compiled one copies each result
    into an array of the expected shape and refuses another
    (:func:`pfbench.backends.numba_mpf_steps.copy_into`)."""
    returns = {"cl_transition": (("f^n", "A^n", "f^l", "A^l"), ((n, d_n), (n, d_n, d_l), (n, d_l), (n, d_l, d_l))),
               "cl_constrain": ((None,), ((n, d_n),)),
               "cl_observation": (("h", "C"), ((n, n_y), (n, n_y, d_l)))}

    def check(fn: str, out, step: int | None = None) -> tuple:
        names, shapes = returns[fn]
        arrays = (out,) if names == (None,) else returned(model, fn, out, names)
        for label, arr, shape in zip(names, arrays, shapes):
            a = np.asarray(arr)
            if a.shape != shape:
                at = f"at step {step}" if step is not None else "in the check before the run"
                raise ModelError(f"model {name_of(model)!r}: {fn}(){f' ({label})' if label else ''} returned "
                                 f"an array of shape {a.shape} {at}, expected {shape} (n = {n} particles, "
                                 f"d_n = {d_n}, d_l = {d_l}, n_y = {n_y})")
        return arrays

    return check


def _check_shapes(model, u, idx_n, idx_l, m0, method: str) -> None:
    """Call the model's structure functions once on a probe block, check what they return, and that
    they describe the model of ``transition`` and ``observe`` (:func:`check_agreement`) on the probe
    and on the probe moved one step (a fixed initial state, Ob2's 0, makes every term vanish)."""
    p = model.params()
    n, d_n, d_l = PROBE, idx_n.size, idx_l.size
    check = structure_check(model, n, d_n, d_l, int(model.n_y))
    have = defined(model)
    x = None
    if d_n or "initial" in have:  # the Kalman family draws no x^n: initial may refuse (None)
        x = call(model, "initial", _NEEDED if d_n else {}, np.random.default_rng(0), n, p)
        x = None if x is None and not d_n else shaped(model, "initial", x, (n, int(model.n_x))).astype(np.float64)
    xn = np.ascontiguousarray(x[:, idx_n]) if d_n else np.zeros((n, 0))
    check("cl_transition", call(model, "cl_transition", _NEEDED, xn, u[0], 0, p))
    check("cl_constrain", call(model, "cl_constrain", _NEEDED, xn.copy(), p))
    check("cl_observation", call(model, "cl_observation", _NEEDED, xn, np.tile(m0, (n, 1)), u[0], 0, p))
    if x is None or "transition" not in have:
        return
    noise = np.random.default_rng(1).standard_normal((n, int(model.n_noise)))
    moved = call(model, "transition", {}, x.copy(), u[0], 0, noise, p)  # copies: a model may write its input
    for at in (x,) if moved is None else (x, shaped(model, "transition", moved, x.shape).astype(np.float64)):
        check_agreement(model, at, u[0], p, idx_n, idx_l, method, observe="observe" in have)


def check_agreement(model, x, u0, p, idx_n, idx_l, method: str, observe: bool = True) -> None:
    """The declared structure ([Schon2005] eq. 3) is the model that ``transition`` and ``observe``
    describe (the simulator's and the particle methods'), else ``method`` filters another model than
    the one that made the data: a ModelError naming the function, the first state (output) that
    differs and both values.

    At the states ``x`` (n, n_x), t = 0 and ``u0``, with zero noise: the x^n columns of
    ``transition`` are cl_constrain(f^n + A^n x^l) (the MPF constrains its draw of x^n, as a
    transition constrains its result), the x^l columns f^l + A^l x^l, and ``observe`` is h of
    cl_observation at the particles' own x^l. Zero noise gives the noise-free part exactly when the
    noise enters as a matrix times standard normals, as the structure's Gaussian noise does.
    Tolerance: 1e-9 (about 4.5e6 ulp) of the largest magnitude of the terms in that column, for sums
    in another order; non-finite values are not compared (the noise checks name them)."""
    n, d_n, d_l = x.shape[0], idx_n.size, idx_l.size
    xn, xl = np.ascontiguousarray(x[:, idx_n]), np.ascontiguousarray(x[:, idx_l])

    def times(A, v):  # per particle: A v
        return np.einsum("nij,nj->ni", A, v)

    def floats(fn, names, shapes, *args):  # None where a shape is wrong: structure_check names it
        out = call_returning(model, fn, names, *args)
        out = [np.asarray(v) for v in ((out,) if names is None else out)]
        ok = all(v.dtype.kind in "fiu" and v.shape == s for v, s in zip(out, shapes))
        return [v.astype(np.float64) for v in out] if ok else None

    def compare(fn, mine, cl_fn, theirs, terms, where, how):
        scale = np.maximum(np.maximum(np.abs(mine), np.abs(theirs)), terms).max(axis=0)
        bad = np.isfinite(mine) & np.isfinite(theirs) & (np.abs(mine - theirs) > 1e-9 * scale)
        if bad.any():
            j, i = np.argwhere(bad.T)[0]  # the lowest state (output) that differs
            raise ModelError(f"model {name_of(model)!r}: {fn}() and {cl_fn}() disagree: with zero noise {where(j)} is "
                             f"{mine[i, j]:.12g} by {fn}, {theirs[i, j]:.12g} by {cl_fn} ({how(j)}); method "
                             f"{method!r} would filter another model")

    mine = call(model, "transition", {}, x.copy(), u0, 0, np.zeros((n, int(model.n_noise))), p)
    tr = mine is not None and floats("cl_transition", ("f^n", "A^n", "f^l", "A^l"),
                                     ((n, d_n), (n, d_n, d_l), (n, d_l), (n, d_l, d_l)), xn, u0, 0, p)
    xc = tr and floats("cl_constrain", None, ((n, d_n),), tr[0] + times(tr[1], xl), p)
    if xc:
        f_n, A_n, f_l, A_l = tr
        cl, terms = np.empty(x.shape), np.empty(x.shape)
        cl[:, idx_n], terms[:, idx_n] = xc[0], np.abs(f_n) + times(np.abs(A_n), np.abs(xl))
        cl[:, idx_l], terms[:, idx_l] = f_l + times(A_l, xl), np.abs(f_l) + times(np.abs(A_l), np.abs(xl))
        part = {int(k): f"x^n[{c}]" for c, k in enumerate(idx_n)} | {int(k): f"x^l[{c}]" for c, k in enumerate(idx_l)}
        compare("transition", shaped(model, "transition", mine, x.shape), "cl_transition", cl, terms,
                lambda j: f"state {j} ({part[j]})",
                lambda j: "f^l + A^l x^l" if j in idx_l else "cl_constrain(f^n + A^n x^l)")
    n_y = int(model.n_y)
    mine = call(model, "observe", {}, x.copy(), u0, 0, np.zeros((n, int(model.obs_noise_dim))), p) if observe else None
    ob = mine is not None and floats("cl_observation", ("h", "C"), ((n, n_y), (n, n_y, d_l)), xn, xl, u0, 0, p)
    if ob:
        compare("observe", shaped(model, "observe", mine, (n, n_y)), "cl_observation", ob[0],
                times(np.abs(ob[1]), np.abs(xl)), lambda j: f"output {j}", lambda j: "h at the particle's own x^l")


# --------------------------------------------------------------------------- drivers
def _run_numpy(model, p, rng, n, s, u, scheme, out) -> None:
    """The NumPy reference driver (vectorised over particles; one Python loop over steps), filling
    ``out`` (:class:`pfbench.backends.mpf_work.Outputs`)."""
    est, cov, ess, inc, degen = out.est, out.cov, out.ess, out.inc, out.degen
    cls = type(model)
    cl_transition, cl_observation, cl_constrain = cls.cl_transition, cls.cl_observation, cls.cl_constrain
    resample = _resampling.get(Scheme(scheme))
    idx_n, idx_l, d_n = s["idx_n"], s["idx_l"], s["d_n"]
    yw = s["yw"]
    if d_n:
        xn = _initial_xn(model, rng, n, p, idx_n)
    else:
        xn = np.zeros((n, 0))
    m = np.tile(s["m0"], (n, 1))
    P = np.tile(s["P0"], (n, 1, 1))
    lw = np.full(n, -np.log(n))
    check = structure_check(model, n, d_n, s["d_l"], yw.shape[1])
    for t in range(yw.shape[0]):
        z = rng.standard_normal((n, d_n)) if d_n else np.zeros((n, 0))
        fn, An, fl, Al = check("cl_transition", cl_transition(xn, u[t], t, p), t)
        xn, m_pred, P_pred = kalman_predict(fn, An, fl, Al, m, P, z, s["Qn"], s["Ql"], s["T"], s["corr"])
        xn, = check("cl_constrain", cl_constrain(xn, p), t)
        h, C = check("cl_observation", cl_observation(xn, m_pred, u[t], t, p), t)
        ll, m, P = kalman_update(h, C, m_pred, P_pred, yw[t], s["W"], s["rvar"], s["whiten"], s["logdet"])
        wu, _, mx, total, deg = weigh(lw, valid_log_likelihood(ll))
        degen[t] = deg
        inc[t] = -np.inf if deg else mx + np.log(total)
        wn = wu / total
        ess[t] = 1.0 / np.cumsum(wn * wn)[-1]
        mixture_moments(wu, total, (wu @ xn) / total, (wu @ m) / total, xn, m, P, idx_n, idx_l,
                        est[t], cov[t])
        if d_n:
            idx = resample(wu, rng)
            xn, m, P = xn[idx], m[idx], P[idx]


def _initial_xn(model, rng, n: int, p, idx_n) -> np.ndarray:
    """The x^n components of n draws of the model's prior (step 1 of the draw order; both backends)."""
    return np.ascontiguousarray(np.asarray(model.initial(rng, n, p), dtype=np.float64)[:, idx_n])


_WARM: set = set()


def _run_numba(model, p, rng, n, s, u, scheme, out) -> None:
    from ..backends import numba_backend

    xn = _initial_xn(model, rng, n, p, s["idx_n"]) if s["d_n"] else None  # in NumPy, as the reference
    numba_backend.run_mpf(model, p, rng, xn, s, u, scheme, out)


def _warm_up(model, p, n, s, u, scheme) -> None:
    """Compile (or load) the numba kernel outside the timed region, on one step and a throwaway
    generator (the caller's stream is not touched)."""
    import numba

    key = (type(model), str(numba.typeof(p)), scheme if s["d_n"] else None)
    if key in _WARM:
        return
    n_x = model.n_x
    s1 = dict(s, yw=s["yw"][:1])
    _run_numba(model, p, np.random.default_rng(0), min(n, 2), s1, u[:1], scheme, outputs(1, n_x))
    _WARM.add(key)


def _filter(model, y, u, *, n, backend, resampling, seed, method="mpf"):
    """Run the recursion with ``n`` particles for ``method`` (its name in messages); returns
    (structure, arrays, elapsed_s)."""
    check_backend(backend)
    scheme = int(Scheme.parse(resampling))
    y, u = check_inputs(model, y, u)
    s = structure(model, y, u, method)
    if s["d_n"] == 0:
        n = 1
    rng = np.random.default_rng(seed_sequence(seed))
    M, n_x = y.shape[0], model.n_x
    out = outputs(M, n_x)
    p = model.params()
    if backend == "numba":
        _warm_up(model, p, n, s, u, scheme)
    run = _run_numba if backend == "numba" else _run_numpy
    t0 = time.perf_counter()
    run(model, p, rng, n, s, u, scheme, out)
    return s, n, out, time.perf_counter() - t0


def run_mpf(model, y, u=None, *, n_particles: int = 100, resampling: str = "systematic",
            backend: str = "numba", seed=0, dtype: str = "float64",
            ess_threshold=None) -> FilterResult:
    """Marginalized particle filter ([Schon2005] Alg. 1; see the module docstring).

    Parameters
    ----------
    model : a model declaring ``linear_states`` and the ``cl_*`` members (else UnsupportedError).
    y, u : measurements (M, n_y) and inputs (M, n_u).
    n_particles : N_p particles for x^n; ignored (one copy, ``n_particles`` 1 in the result, with
        ``info["n_particles_requested"]`` and ``info["note"]``) when every state is linear.
    resampling : a :class:`~pfbench.resampling.Scheme` name; the filter resamples every step.
    backend : ``numpy`` or ``numba``; seed : int or ``numpy.random.SeedSequence``.
    dtype, ess_threshold : accepted for :func:`pfbench.run_filter`; only ``float64`` and ``None``.

    Returns
    -------
    FilterResult
        method ``"mpf"``; estimates, variances and covariances in full-state order; ``ess`` the
        N_eff of the MPF weights; ``loglik_increments`` estimates of log p(y_t | y_1:t-1).
    """
    check_dtype(dtype)
    if dtype != "float64":
        raise InputError("method 'mpf' runs in float64 only")
    if ess_threshold is not None:
        raise InputError("method 'mpf' resamples at every step; ess_threshold does not apply")
    if isinstance(n_particles, bool) or int(n_particles) != n_particles or int(n_particles) < 1:
        raise InputError(f"n_particles must be an integer >= 1, got {n_particles!r}")
    s, n, out, elapsed = _filter(model, y, u, n=int(n_particles), backend=backend,
                                 resampling=resampling, seed=seed)
    info = {"resampling": Scheme.parse(resampling).label, "n_nonlinear": int(s["d_n"]),
            "linear_states": [int(i) for i in s["idx_l"]], "noise_cross_covariance": s["corr"],
            "whitened_measurement": s["whiten"]}
    if s["d_n"] == 0:
        info["n_particles_requested"] = int(n_particles)
        info["note"] = ("every state is linear-Gaussian (d_n = 0): all particles would carry the "
                        "same Kalman/EKF recursion, so one copy ran and N_p is ignored ([MultiPDF] "
                        "§5: the performance of MPF is independent of the number of particles)")
    return _result(out, elapsed, method="mpf", backend=backend, n_particles=n,
                   n_resampled=out.inc.shape[0] if s["d_n"] else 0, info=info)


def run_kalman(model, y, u=None, *, backend: str = "numba") -> FilterResult:
    """Kalman filter on a model whose every state is in its linear substructure (d_n = 0): the MPF
    recursion with one copy, i.e. the exact KF when the measurement is linear in the state and an
    EKF (linearised at the predicted mean) otherwise. UnsupportedError if the model has nonlinear
    states (use method 'mpf'). Returns a FilterResult with method ``"kalman"``, ``n_particles`` 0,
    ``ess`` NaN and the covariances filled."""
    y, u = check_inputs(model, y, u)
    if _declares_structure(model):
        d_n = model.n_x - linear_indices(model).size
        if d_n > 0:
            raise UnsupportedError(
                f"method 'kalman' needs every state of model {name_of(model)!r} "
                f"in its linear substructure, but {d_n} state(s) are nonlinear "
                f"(linear_states = {tuple(model.linear_states)}); use method 'mpf'")
    s, _, out, elapsed = _filter(model, y, u, n=1, backend=backend, resampling="systematic", seed=0,
                                 method="kalman")
    out.ess[:] = np.nan
    info = {"linear_states": [int(i) for i in s["idx_l"]], "whitened_measurement": s["whiten"]}
    return _result(out, elapsed, method="kalman", backend=backend, n_particles=0, n_resampled=0,
                   info=info)


def _result(out, elapsed, *, method, backend, n_particles, n_resampled, info) -> FilterResult:
    cov = out.cov
    inc = out.inc
    return FilterResult(
        estimates=out.est, variances=np.diagonal(cov, axis1=1, axis2=2).copy(),
        loglik=float(inc.sum()), loglik_increments=inc, ess=reported_ess(out.ess, out.degen),
        n_resampled=int(n_resampled),
        degenerate=out.degen, elapsed_s=elapsed, method=method, backend=backend, dtype="float64",
        n_particles=int(n_particles), n_filters=1, covariances=cov, info=info)
