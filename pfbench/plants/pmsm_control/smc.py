"""The thesis SMC of the PMSM drive ([Thesis] §4.2.1, Table 4.2) = the reduced PMSM model's
proposal + the generic guided filter, plus the thesis point estimates used for control.

* The filter: :class:`pfbench.models.pmsm.PmsmReduced` (particles carry (omega, theta); the
  measured currents stand in for the current states; locally optimal proposal, eqs. 4.22-4.25)
  run by the generic guided kernel one step at a time (:func:`pfbench.filters.guided.step_functions`),
  with the thesis settings: 60 particles, resample when N_eff < 12 (= 0.2 N), deterministic
  residual resampling (Table 4.2); the inflated theta variance and the theta priors are
  parameters of the model.
* Point estimates for control (``point``): ``mean`` = posterior mean (theta: circular mean
  atan2(sum w sin, sum w cos)); ``sample`` = one random sample from the weighted particles (one
  uniform from the point-estimate generator); ``max`` = maximum of the particle approximation,
  computed as the particle with the largest weighted Gaussian-kernel density estimate, where theta
  differences are wrapped to (-pi, pi] before entering the kernel (so the two ends of the circle
  are neighbours) and the bandwidths are h = sigma N^(-1/6) (Silverman's rule in 2-D) with sigma
  the weighted standard deviation of omega and the circular standard deviation sqrt(-2 ln R) of
  theta, floored at 1e-3; ``max_weight`` = the other reading of "maximum" ([Thesis] §4.4.5 does
  not say which): the particle with the largest normalised weight (first one on ties). Also the spread (omega range and max theta distance of the particles
  with weight >= 1e-4) for plotting bounds.

Time convention of :func:`run_smc` (the closed loop's): ``u[t]`` is the input applied between step t
and t+1; at t = 0 the estimate is the prior's, at t >= 1 one guided step with y_t and inputs
(u[t-1], y[t-1]). ``Pmsm.simulate`` uses x_t = g(x_{t-1}, u[t]); :func:`shift_inputs` converts.

Backends: the loops here are plain Python functions (``register_jitable`` helpers): under
``numpy`` they run as Python with the NumPy guided step, under ``numba`` they are compiled and call
the compiled guided kernel. Random numbers come from the same generator calls, so the backends agree
to round-off (tested).
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba.extending import register_jitable

from ...backends.cache import njit
from ...backends.interrupts import held
from ...backends.guided_work import Moments, Particles, Settings
from ...backends.numba_weights import weigh as _weigh
from ...errors import InputError
from ...filters.guided import step_functions
from ...filters.inputs import ess_count, seed_sequence
from ...models.pmsm import Q_THETA_FILTER, Pmsm, PmsmReduced, wrap_angle
from ...resampling import Scheme

POINT_MODES = {"mean": 0, "sample": 1, "max": 2, "max_weight": 3}
#: Table 4.2: resample when N_eff < 12 of N = 60 particles
ESS_FRACTION = 0.2

_GUIDED = step_functions(PmsmReduced)
guided_init = _GUIDED.init
guided_step = _GUIDED.step
N_NOISE = _GUIDED.n_noise

__all__ = ["POINT_MODES", "ESS_FRACTION", "Q_THETA_FILTER", "smc_model", "point_code", "scheme_code",
           "guided_init", "guided_step", "smc_update", "smc_workspace", "weights_from_log", "point_estimate", "run_smc",
           "shift_inputs", "step_time_us"]


def smc_model(model: Pmsm | None = None, *, q_theta_filter=Q_THETA_FILTER, theta_prior="equidistant",
              theta_mu=0.0, theta_sd=1.0) -> PmsmReduced:
    """The reduced model the SMC runs for the plant ``model`` (default :class:`Pmsm` ()): same
    parameters, the filter's theta variance and prior."""
    m = model or Pmsm()
    kw = dict(a=m.a, b=m.b, c=m.c, d=m.d, e=m.e, dt=m.dt, q=m.q, r=m.r, u_max=m.u_max,
              prior_halfwidth=m.prior_halfwidth)
    return PmsmReduced(q_theta_filter=q_theta_filter, theta_prior=theta_prior, theta_mu=theta_mu,
                       theta_sd=theta_sd, **kw)


def point_code(point: str) -> int:
    if point not in POINT_MODES:
        raise InputError(f"unknown point estimate {point!r}; choose {', '.join(POINT_MODES)}")
    return POINT_MODES[point]


def scheme_code(resampling) -> int:
    return int(Scheme.parse(resampling))


@register_jitable
def weights_from_log(lw, wn):
    """Normalised linear weights from log-weights (into ``wn``), by the engine's log-sum-exp
    weighting (:func:`pfbench.backends.numba_weights.weigh` with zero log-likelihoods)."""
    n = lw.shape[0]
    cdf = np.empty(n)
    _, total, _ = _weigh(lw, np.zeros(n), wn, cdf)
    for i in range(n):
        wn[i] /= total


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
    """(omega, theta) point estimate into ``out`` (2,): 0 mean, 1 random sample, 2 maximum
    (kernel-density mode), 3 maximum (highest-weight particle).

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
    elif mode == 3:
        j = 0
        for k in range(1, n):
            if wn[k] > wn[j]:
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
        sp = max(sp, abs(wrap_angle(th[i] - out[1])))
    out[2] = lo
    out[3] = hi
    out[4] = sp


@register_jitable
def split_particles(x, om, th):
    """Copy the (n, 2) particles into contiguous omega / theta arrays."""
    for i in range(x.shape[0]):
        om[i] = x[i, 0]
        th[i] = x[i, 1]


@register_jitable
def smc_workspace(n):
    """The state and scratch arrays of :func:`smc_update` for ``n`` particles:
    (x (n, 2), lw, wn, om, th (n,), pe (5,), mean, var (2,), ured (4,))."""
    return (np.empty((n, 2)), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(5),
            np.empty(2), np.empty(2), np.empty(4))


@register_jitable
def smc_update(p, rng, rng_point, x, lw, wn, om, th, pe, mean, var, ured, t, y_t, y_prev, u_prev,
               scheme, threshold, mode):
    """One step of the thesis SMC at step t, shared by the offline filter and the closed loop: the
    generic guided step on the reduced model (inputs (u_{t-1}, y_{t-1}); nothing at t = 0, the
    prior), then the normalised weights ``wn``, the particles as ``om``/``th`` and the point
    estimate with its spread in ``pe``. Returns (log-likelihood increment, N_eff, resampled). The
    guided step's groups (:mod:`pfbench.backends.guided_work`) are built here, in compiled code too."""
    n = x.shape[0]
    inc = 0.0
    e = float(n)
    r = False
    if t > 0:
        ured[0] = u_prev[0]
        ured[1] = u_prev[1]
        ured[2] = y_prev[0]
        ured[3] = y_prev[1]
        settings = Settings(N_NOISE, scheme, threshold, 0, 0)  # every field: numba fills in no defaults
        inc, e, r, _ = guided_step(p, rng, Particles(x, lw), y_t, ured, t, settings, Moments(mean, var))
    weights_from_log(lw, wn)
    split_particles(x, om, th)
    point_estimate(om, th, wn, mode, rng_point, pe)
    return inc, e, r


def _offline_py(p, y, u, n, scheme, threshold, mode, rng, rng_point, est, ess, inc, res, spread):
    """Open-loop SMC of measured currents ``y`` (M, 2) with inputs ``u`` (M, 2) (u[t]: t -> t+1)."""
    x, lw, wn, om, th, pe, mean, var, ured = smc_workspace(n)
    guided_init(p, rng, x, lw)
    for t in range(y.shape[0]):
        k = max(t - 1, 0)
        inc[t], ess[t], res[t] = smc_update(p, rng, rng_point, x, lw, wn, om, th, pe, mean, var, ured,
                                            t, y[t], y[k], u[k], scheme, threshold, mode)
        est[t, 0] = pe[0]
        est[t, 1] = pe[1]
        spread[t, 0] = pe[2]
        spread[t, 1] = pe[3]
        spread[t, 2] = pe[4]


_offline_nb = njit(nogil=True)(_offline_py)


def run_smc(model, y, u, *, n_particles=60, ess_threshold=ESS_FRACTION, point="mean",
            resampling="residual_deterministic", backend="numba", seed=0,
            q_theta_filter=Q_THETA_FILTER, theta_prior="equidistant", theta_mu=0.0,
            theta_sd=1.0) -> dict:
    """The thesis SMC on measured currents ``y`` (M, 2) given voltages ``u`` (M, 2) (open loop,
    ``u[t]`` applied between t and t+1; see :func:`shift_inputs`) of the plant ``model``.

    ``ess_threshold`` is a fraction of N (0.2: 12 of 60, Table 4.2). Streams: SeedSequence(seed)
    spawned twice, the filter's and the point estimate's. Returns a dict with ``estimates`` (M, 2)
    [omega, theta] (point estimates), ``ess``, ``loglik_increments``, ``resampled`` (M,) bool,
    ``spread`` (M, 3) and ``elapsed_s`` / ``us_per_step`` (compilation excluded).
    """
    if backend not in ("numba", "numpy"):
        raise InputError(f"unknown backend {backend!r}; choose numba or numpy")
    mode = point_code(point)
    y = np.ascontiguousarray(y, dtype=np.float64)
    u = np.ascontiguousarray(u, dtype=np.float64)
    if y.ndim != 2 or y.shape[1] != 2 or u.shape != y.shape:
        raise InputError("y and u must both have shape (M, 2)")
    n = int(n_particles)
    thr = ess_count(ess_threshold, n)
    p = smc_model(model, q_theta_filter=q_theta_filter, theta_prior=theta_prior, theta_mu=theta_mu,
                  theta_sd=theta_sd).params()
    M = y.shape[0]
    s_f, s_p = seed_sequence(seed).spawn(2)
    rng, rng_point = np.random.default_rng(s_f), np.random.default_rng(s_p)
    est, spread = np.empty((M, 2)), np.empty((M, 3))
    ess, inc = np.empty(M), np.empty(M)
    res = np.zeros(M, dtype=np.bool_)
    scheme = scheme_code(resampling)
    fn = _offline_nb if backend == "numba" else _offline_py
    if backend == "numba":  # compile outside the timed region
        with held():
            _offline_nb(p, y[:2], u[:2], n, scheme, thr, mode, np.random.default_rng(0),
                        np.random.default_rng(1), est[:2].copy(), ess[:2].copy(), inc[:2].copy(),
                        res[:2].copy(), spread[:2].copy())
    t0 = time.perf_counter()
    with held():  # numba unboxes the generators (pfbench.backends.interrupts.held)
        fn(p, y, u, n, scheme, thr, mode, rng, rng_point, est, ess, inc, res, spread)
    elapsed = time.perf_counter() - t0
    return {"estimates": est, "ess": ess, "loglik_increments": inc, "resampled": res,
            "spread": spread, "elapsed_s": elapsed, "us_per_step": elapsed * 1e6 / M}


def shift_inputs(u_sim):
    """Convert ``Pmsm.simulate`` inputs (x_t = g(x_{t-1}, u[t])) to the convention of
    :func:`run_smc` (x_{t+1} = g(x_t, u[t])): u_f[t] = u_sim[t + 1], last row zero."""
    u_sim = np.asarray(u_sim, dtype=np.float64)
    return np.vstack([u_sim[1:], np.zeros((1, u_sim.shape[1]))])


def step_time_us(n_particles=60, n_steps=4000, point="max", seed=0, repeats=3) -> float:
    """Measured wall time of one SMC step (weights, resampling, proposal, point estimate) on
    the numba backend, in microseconds (best of ``repeats``); for benchmarks, not tests."""
    m = Pmsm()
    tr = m.simulate(n_steps, seed=seed)
    y, u = tr.y, shift_inputs(tr.u)
    best = math.inf
    for r in range(repeats):
        out = run_smc(m, y, u, n_particles=n_particles, point=point, seed=seed + r)
        best = min(best, out["us_per_step"])
    return best
