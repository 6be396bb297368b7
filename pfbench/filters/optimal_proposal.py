"""SMC with the optimal proposal for the PMSM drive ([Thesis], thesis §4.2.1, eqs. 4.22-4.25).

For a model x_t = g(x_{t-1}, u_{t-1}) + w, y_t = H x_t + v with Gaussian w ~ N(0, Q),
v ~ N(0, R) the optimal importance density is Gaussian (eqs. 4.22-4.24)::

    S^-1 = Q^-1 + H' R^-1 H,   m_t = S (Q^-1 g(x_{t-1}) + H' R^-1 y_t),
    x_t | x_{t-1}, y_t ~ N(m_t, S)

and the incremental weight is the predictive likelihood (eq. 4.25)::

    p(y_t | x_{t-1}) = N(y_t; H g(x_{t-1}), R + H Q H').

Following the thesis, the particles carry only the unobservable (omega, theta); the currents
are the measured ones ("observed currents used directly"), i.e. i_{t-1} := y_{t-1} inside g.
Since H has zero columns for (omega, theta) and Q is diagonal, the (omega, theta) block of
the optimal proposal equals the prior block of the transition, so one step is:

1. weight:  log w_i += log N(y_t; H g(y_{t-1}, omega_i, theta_i, u_{t-1}), R + diag(Q_ia, Q_ib));
2. normalise, N_eff = 1 / sum w_i^2; if N_eff < threshold (12 = N/5 in Table 4.2; N/3 in
   Fig. 4.7) resample with *deterministic residual* resampling (thesis §2.5.2, Table 4.2);
3. propagate: omega_i <- d omega_i + e (y_b cos theta_i - y_a sin theta_i) + sqrt(q_w) z,
   theta_i <- wrap(theta_i + dt omega_i + sqrt(q_th_filter) z').

**Inflated theta variance.** The thesis uses a larger process variance on theta inside the
filter than the true 1e-10 ("we use sigma_theta^2 = 10^-? instead of true 10^-10"; the exponent
was lost in the extraction). Our default is ``q_theta_filter = 1e-6`` (std 1e-3 rad per step,
~1 electrical degree over 17 steps); it is a parameter.

Initial particles: theta equidistant on [-pi, pi] (theta_i = -pi + 2 pi (i + 1/2) / N, thesis
§4.4.4), omega ~ U(-0.01, 0.01) drawn from the filter's generator.

Point estimates for control (``point_mode``): 0 = posterior mean (theta: circular mean
atan2(sum w sin, sum w cos)); 1 = one random sample from the weighted particles (one uniform
from the point-estimate generator); 2 = maximum of the particle approximation, computed as
the particle with the largest weighted Gaussian-kernel density estimate, where theta
differences are wrapped to (-pi, pi] before entering the kernel (so the two ends of the
circle are neighbours) and the bandwidths are h = sigma N^(-1/6) (Silverman's rule in 2-D)
with sigma the weighted standard deviation of omega and the circular standard deviation
sqrt(-2 ln R) of theta, floored at 1e-3.

Backends: every function here is written with scalar loops and ``math`` functions and
decorated with ``register_jitable``: under the ``numpy`` backend it runs as plain Python with
the NumPy reference resampler :func:`pfbench.resampling.residual_deterministic`, under
``numba`` it is compiled and resamples with :func:`pfbench.backends.numba_resampling.resample_into`
(scheme code 4). Random numbers come from the same ``numpy.random.Generator`` calls, so the
two backends give identical results (tested).
"""
from __future__ import annotations

import math
import time

import numpy as np
from ..backends.cache import njit
from numba.extending import overload, register_jitable

from .. import resampling as _ref
from ..backends.numba_resampling import cumsum_into, resample_into
from ..errors import PfbenchError

LOG_2PI = math.log(2.0 * math.pi)

#: default inflated theta process variance of the filter (thesis §4.2.1; exponent lost, see above)
Q_THETA_FILTER = 1e-6

# filter parameter array layout (``fp``)
FP_QW, FP_QTH, FP_VA, FP_VB, FP_THR, FP_THMODE, FP_THMU, FP_THSD, FP_WHW = range(9)
FP_SIZE = 9


def filter_params(model, *, ess_threshold=12.0, q_theta_filter=Q_THETA_FILTER,
                  theta_prior="equidistant", theta_mu=0.0, theta_sd=1.0) -> np.ndarray:
    """Pack the SMC parameters into a float64 array for the kernels.

    theta_prior : ``equidistant`` (thesis §4.4.4), ``uniform`` (random U(-pi, pi)) or
        ``gaussian`` (N(theta_mu, theta_sd^2), wrapped; used for Fig. 4.6).
    """
    modes = {"equidistant": 0, "uniform": 1, "gaussian": 2}
    if theta_prior not in modes:
        raise PfbenchError(f"unknown theta_prior {theta_prior!r}; choose one of {', '.join(modes)}")
    fp = np.zeros(FP_SIZE)
    fp[FP_QW] = model.q[2]
    fp[FP_QTH] = float(q_theta_filter)
    fp[FP_VA] = model.r[0] + model.q[0]     # R + H Q H' (eq. 4.25)
    fp[FP_VB] = model.r[1] + model.q[1]
    fp[FP_THR] = float(ess_threshold)
    fp[FP_THMODE] = modes[theta_prior]
    fp[FP_THMU] = float(theta_mu)
    fp[FP_THSD] = float(theta_sd)
    fp[FP_WHW] = model.prior_halfwidth
    return fp


# ----- resampling: NumPy reference in Python, numba loop version when compiled ---------------
def resample_det(w, rng):
    """Deterministic residual resampling of unnormalised weights ``w`` (thesis §2.5.2)."""
    return _ref.residual_deterministic(w)


@overload(resample_det)
def _resample_det_nb(w, rng):
    def impl(w, rng):
        n = w.shape[0]
        cdf = np.empty(n)
        cumsum_into(w, cdf)
        idx = np.empty(n, np.int64)
        resample_into(4, w, cdf, rng, idx)
        return idx
    return impl


@register_jitable
def _wrap(th):
    return th - 2.0 * math.pi * math.ceil((th - math.pi) / (2.0 * math.pi))


@register_jitable
def smc_init(rng, om, th, lw, fp):
    """Initial particles (see module docstring); draws N uniforms for omega (+ N for theta)."""
    n = om.shape[0]
    hw = fp[FP_WHW]
    z = rng.random(n)
    for i in range(n):
        om[i] = hw * (2.0 * z[i] - 1.0)
        lw[i] = -math.log(n)
    mode = int(fp[FP_THMODE])
    if mode == 0:
        for i in range(n):
            th[i] = -math.pi + 2.0 * math.pi * (i + 0.5) / n
    elif mode == 1:
        z2 = rng.random(n)
        for i in range(n):
            th[i] = math.pi * (2.0 * z2[i] - 1.0)
    else:
        z2 = rng.standard_normal(n)
        for i in range(n):
            th[i] = _wrap(fp[FP_THMU] + fp[FP_THSD] * z2[i])


@register_jitable
def smc_step(rng, om, th, lw, wbuf, y_prev, y, u_prev, mp, fp):
    """One SMC step with the optimal proposal (eqs. 4.22-4.25); updates particles in place.

    Returns (log p(y_t | y_1:t-1) estimate, resampled flag, N_eff before resampling).
    ``lw`` holds normalised log-weights on exit; ``wbuf`` is scratch (n,).
    """
    n = om.shape[0]
    a, b, c, d, e, dt = mp[0], mp[1], mp[2], mp[3], mp[4], mp[5]
    va = fp[FP_VA]
    vb = fp[FP_VB]
    const = -0.5 * (2.0 * LOG_2PI + math.log(va) + math.log(vb))
    mx = -math.inf
    for i in range(n):
        s = math.sin(th[i])
        co = math.cos(th[i])
        ra = y[0] - (a * y_prev[0] + b * om[i] * s + c * u_prev[0])
        rb = y[1] - (a * y_prev[1] - b * om[i] * co + c * u_prev[1])
        v = lw[i] + const - 0.5 * (ra * ra / va + rb * rb / vb)
        wbuf[i] = v
        if v > mx:
            mx = v
    tot = 0.0
    for i in range(n):
        wbuf[i] = math.exp(wbuf[i] - mx)
        tot += wbuf[i]
    inc = mx + math.log(tot)
    s2 = 0.0
    for i in range(n):
        wn = wbuf[i] / tot
        s2 += wn * wn
        lw[i] = math.log(wn) if wn > 0.0 else -math.inf
    ess = 1.0 / s2
    resampled = ess < fp[FP_THR]
    if resampled:
        idx = resample_det(wbuf, rng)
        o2 = om.copy()
        t2 = th.copy()
        for i in range(n):
            om[i] = o2[idx[i]]
            th[i] = t2[idx[i]]
            lw[i] = -math.log(n)
    z = rng.standard_normal(2 * n)
    sw = math.sqrt(fp[FP_QW])
    sth = math.sqrt(fp[FP_QTH])
    for i in range(n):
        s = math.sin(th[i])
        co = math.cos(th[i])
        w_old = om[i]
        om[i] = d * w_old + e * (y_prev[1] * co - y_prev[0] * s) + sw * z[2 * i]
        th[i] = _wrap(th[i] + dt * w_old + sth * z[2 * i + 1])
    return inc, resampled, ess


@register_jitable
def weights_from_log(lw, wn):
    """Normalised linear weights from log-weights (into ``wn``)."""
    n = lw.shape[0]
    mx = -math.inf
    for i in range(n):
        if lw[i] > mx:
            mx = lw[i]
    tot = 0.0
    for i in range(n):
        wn[i] = math.exp(lw[i] - mx)
        tot += wn[i]
    for i in range(n):
        wn[i] /= tot


@register_jitable
def _weighted_moments(om, th, wn):
    """Weighted mean of omega and the weighted sums of sin/cos theta (circular mean)."""
    mw = 0.0
    ss = 0.0
    cs = 0.0
    for i in range(om.shape[0]):
        mw += wn[i] * om[i]
        ss += wn[i] * math.sin(th[i])
        cs += wn[i] * math.cos(th[i])
    return mw, ss, cs


@register_jitable
def point_estimate(om, th, wn, mode, rng_point, out):
    """(omega, theta) point estimate into ``out`` (2,): 0 mean, 1 random sample, 2 maximum.

    Also returns the spread (omega_min, omega_max, max |wrap(theta_i - theta_hat)|) over the
    particles with normalised weight >= 1e-4 via out[2:5], for plotting bounds.
    """
    n = om.shape[0]
    if mode == 1:
        u = rng_point.random()
        acc = 0.0
        j = n - 1
        for i in range(n):
            acc += wn[i]
            if acc > u:
                j = i
                break
        out[0] = om[j]
        out[1] = th[j]
    elif mode == 2:
        mw, ss, cs = _weighted_moments(om, th, wn)
        vw = 0.0
        for i in range(n):
            vw += wn[i] * (om[i] - mw) * (om[i] - mw)
        rbar = math.sqrt(ss * ss + cs * cs)
        sth = math.sqrt(-2.0 * math.log(rbar)) if 0.0 < rbar < 1.0 else (0.0 if rbar >= 1.0 else math.pi)
        fac = n ** (-1.0 / 6.0)
        hw = max(math.sqrt(vw) * fac, 1e-3)
        hth = max(sth * fac, 1e-3)
        dens = np.zeros(n)
        for k in range(n):
            dens[k] += wn[k]
            for i in range(k + 1, n):
                dw = (om[k] - om[i]) / hw
                dd = th[k] - th[i]          # both in (-pi, pi]: one correction wraps it
                if dd > math.pi:
                    dd -= 2.0 * math.pi
                elif dd <= -math.pi:
                    dd += 2.0 * math.pi
                dth = dd / hth
                q = dw * dw + dth * dth
                if q < 40.0:
                    kv = math.exp(-0.5 * q)
                    dens[k] += wn[i] * kv
                    dens[i] += wn[k] * kv
        best = -1.0
        j = 0
        for k in range(n):
            if dens[k] > best:
                best = dens[k]
                j = k
        out[0] = om[j]
        out[1] = th[j]
    else:
        mw, ss, cs = _weighted_moments(om, th, wn)
        out[0] = mw
        out[1] = math.atan2(ss, cs)
    lo = math.inf
    hi = -math.inf
    sp = 0.0
    for i in range(n):
        if wn[i] < 1e-4:          # bounds of the distribution: particles with weight >= 1e-4
            continue
        lo = min(lo, om[i])
        hi = max(hi, om[i])
        sp = max(sp, abs(_wrap(th[i] - out[1])))
    out[2] = lo
    out[3] = hi
    out[4] = sp


def _offline_py(y, u, mp, fp, n, mode, rng, rng_point, est, ess, inc, res, spread):
    """Open-loop filtering of given currents ``y`` (M, 2) with inputs ``u`` (M, 2)."""
    om = np.empty(n)
    th = np.empty(n)
    lw = np.empty(n)
    wb = np.empty(n)
    wn = np.empty(n)
    pe = np.empty(5)
    smc_init(rng, om, th, lw, fp)
    M = y.shape[0]
    for t in range(M):
        if t > 0:
            inc[t], res[t], ess[t] = smc_step(rng, om, th, lw, wb, y[t - 1], y[t], u[t - 1], mp, fp)
        else:
            inc[t] = 0.0
            res[t] = False
            ess[t] = n
        weights_from_log(lw, wn)
        point_estimate(om, th, wn, mode, rng_point, pe)
        est[t, 0] = pe[0]
        est[t, 1] = pe[1]
        spread[t, 0] = pe[2]
        spread[t, 1] = pe[3]
        spread[t, 2] = pe[4]


_offline_nb = njit(nogil=True)(_offline_py)
POINT_MODES = {"mean": 0, "sample": 1, "max": 2}


def run_optimal_proposal(model, y, u, *, n_particles=60, ess_threshold=12.0, point="mean",
                         backend="numba", seed=0, q_theta_filter=Q_THETA_FILTER,
                         theta_prior="equidistant", theta_mu=0.0, theta_sd=1.0) -> dict:
    """Filter measured currents ``y`` (M, 2) given voltages ``u`` (M, 2) (open loop).

    ``u[t]`` is the input applied between step t and t+1 (``x_{t+1} = g(x_t, u[t])``), which
    is the convention of the closed loop; note that ``Pmsm.simulate`` uses
    ``x_t = g(x_{t-1}, u[t])``, i.e. pass ``u[1:]`` shifted (see the tests).

    Returns a dict with ``estimates`` (M, 2) [omega, theta], ``ess``, ``loglik_increments``,
    ``resampled`` (M,) bool, ``spread`` (M, 3) and ``elapsed_s`` / ``us_per_step``.
    """
    if backend not in ("numba", "numpy"):
        raise PfbenchError(f"unknown backend {backend!r}; choose numba or numpy")
    if point not in POINT_MODES:
        raise PfbenchError(f"unknown point estimate {point!r}; choose mean, sample or max")
    y = np.ascontiguousarray(y, dtype=np.float64)
    u = np.ascontiguousarray(u, dtype=np.float64)
    if y.ndim != 2 or y.shape[1] != 2 or u.shape != y.shape:
        raise ValueError("y and u must both have shape (M, 2)")
    M = y.shape[0]
    mp = model.param_array()
    fp = filter_params(model, ess_threshold=ess_threshold, q_theta_filter=q_theta_filter,
                       theta_prior=theta_prior, theta_mu=theta_mu, theta_sd=theta_sd)
    ss = np.random.SeedSequence(seed)
    s_f, s_p = ss.spawn(2)
    rng, rng_point = np.random.default_rng(s_f), np.random.default_rng(s_p)
    est = np.empty((M, 2))
    ess = np.empty(M)
    inc = np.empty(M)
    res = np.zeros(M, dtype=np.bool_)
    spread = np.empty((M, 3))
    fn = _offline_nb if backend == "numba" else _offline_py
    if backend == "numba":  # compile outside the timed region
        _offline_nb(y[:2], u[:2], mp, fp, int(n_particles), POINT_MODES[point],
                    np.random.default_rng(0), np.random.default_rng(1), est[:2].copy(),
                    ess[:2].copy(), inc[:2].copy(), res[:2].copy(), spread[:2].copy())
    t0 = time.perf_counter()
    fn(y, u, mp, fp, int(n_particles), POINT_MODES[point], rng, rng_point, est, ess, inc, res, spread)
    elapsed = time.perf_counter() - t0
    return {"estimates": est, "ess": ess, "loglik_increments": inc, "resampled": res,
            "spread": spread, "elapsed_s": elapsed, "us_per_step": elapsed * 1e6 / M}


def optimal_proposal_moments(x_prev, u, y, mp, q, r):
    """Full-state optimal proposal of eqs. 4.22-4.25 for one previous state (reference/tests).

    Returns (m (4,), S (4, 4), log p(y | x_prev)) for x_t | x_{t-1}, y_t ~ N(m, S) with
    S^-1 = Q^-1 + H' R^-1 H, m = S (Q^-1 g(x_{t-1}) + H' R^-1 y) and
    p(y | x_{t-1}) = N(y; H g(x_{t-1}), R + H Q H').
    """
    from ..models.pmsm import pmsm_step

    g = np.empty(4)
    pmsm_step(np.asarray(x_prev, dtype=np.float64), np.asarray(u, dtype=np.float64), mp, g)
    Q, R = np.diag(q), np.diag(r)
    H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    Qi = np.diag(1.0 / np.asarray(q))
    Ri = np.linalg.inv(R)
    S = np.linalg.inv(Qi + H.T @ Ri @ H)
    m = S @ (Qi @ g + H.T @ Ri @ np.asarray(y))
    Sy = R + H @ Q @ H.T
    res = np.asarray(y) - H @ g
    ll = -0.5 * res @ np.linalg.solve(Sy, res) - 0.5 * (2 * LOG_2PI + np.linalg.slogdet(Sy)[1])
    return m, S, float(ll)


def shift_inputs(u_sim):
    """Convert ``Pmsm.simulate`` inputs (x_t = g(x_{t-1}, u[t])) to the filter convention
    (x_{t+1} = g(x_t, u[t])): u_f[t] = u_sim[t + 1], last row zero."""
    u_sim = np.asarray(u_sim, dtype=np.float64)
    return np.vstack([u_sim[1:], np.zeros((1, u_sim.shape[1]))])


def step_time_us(n_particles=60, n_steps=4000, point="max", seed=0, repeats=3) -> float:
    """Measured wall time of one SMC step (weights, resampling, proposal, point estimate) on
    the numba backend, in microseconds (best of ``repeats``)."""
    from ..models.pmsm import Pmsm

    m = Pmsm()
    tr = m.simulate(n_steps, seed=seed)
    y, u = tr.y, shift_inputs(tr.u)
    best = math.inf
    for r in range(repeats):
        out = run_optimal_proposal(m, y, u, n_particles=n_particles, point=point, seed=seed + r)
        best = min(best, out["us_per_step"])
    return best
