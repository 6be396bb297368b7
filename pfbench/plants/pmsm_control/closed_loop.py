"""Closed-loop simulation of the sensorless PMSM start-up ([Thesis], thesis §4.4).

One run: x^(0) from the prior (§4.4.1), then for t = 0..M-1

    t > 0:  x_t = g(x_{t-1}, u_{t-1}) + w_{t-1}, w ~ N(0, Q)   (true Q, theta variance 1e-10)
            y_t = H x_t + v_t
            estimator update with y_t
            u_t = controller(measured currents y_t, estimate, omega_ref)

Random streams (per run, from ``SeedSequence([seed, run])`` spawned 3 ways): the plant (x^(0),
then per step 4 process + 2 measurement normals), the filter (initial particles and proposal
noise) and the point estimate (one uniform per step for the "random sample" estimate). The
plant stream is the same whatever estimator / controller / point estimate is used, so the
comparisons of Figs. 4.7 and 4.9 use identical random numbers in all variants.
``LoopConfig.filter_stream = k`` (k >= 0) replaces the filter and point-estimate streams by those of
``SeedSequence([seed, run, k])`` while keeping the plant stream: the same plant noise with other
random numbers inside the particle filter (Fig. 4.5).

The SMC is the reduced PMSM model + the generic guided filter (:mod:`.smc`), stepped inside the
loop. The SMC run is one compiled numba function (``backend="numba"``, calling the compiled guided
kernel) or the same code in plain Python (``backend="numpy"``, the NumPy guided step; equal to
round-off). The EKF run (eq. 4.26 Jacobian, helpers of :mod:`pfbench.kalman`) is Python only.
Batches of runs go to worker processes that die with their parent (:func:`pfbench.procs.worker_pool`).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from ...backends.cache import njit
from ...backends.interrupts import held

from ...errors import PfbenchError
from ...filters.inputs import ess_count
from ...models.pmsm import Q_THETA_FILTER, Pmsm, jacobian, pmsm_step, wrap_angle
from ...procs import usable_cores, worker_pool
from .cautious import cautious_control, cc_constants
from .loss import FailureCriterion, estimation_failed, reference_speed, tracking_loss
from .pi import PIGains, pi_dq_control
from .smc import ESS_FRACTION, guided_init, point_code, scheme_code, smc_model, smc_update, smc_workspace

CONTROLLERS = {"pi": 0, "cc": 1, "cec": 2}


def _closed_loop_smc_py(mp, p, scheme, threshold, cp, consts, S, w_ref, x0, n, point_mode, controller,
                        rng_plant, rng_filter, rng_point, xs, ys, us, est, spread, ess, res,
                        store, hist_om, hist_th, hist_w):
    M = w_ref.shape[0]
    particles, lw, wn, om, th, pe, mean, var, ured = smc_workspace(n)
    integ = np.zeros(3)
    x = np.empty(4)
    xn = np.empty(4)
    u = np.zeros(2)
    one_om = np.empty(1)
    one_th = np.empty(1)
    one_w = np.ones(1)
    sq0, sq1, sq2, sq3 = math.sqrt(mp[6]), math.sqrt(mp[7]), math.sqrt(mp[8]), math.sqrt(mp[9])
    sr0, sr1 = math.sqrt(mp[10]), math.sqrt(mp[11])
    guided_init(p, rng_filter, particles, lw)
    for k in range(4):
        x[k] = x0[k]
    for t in range(M):
        if t > 0:
            z = rng_plant.standard_normal(4)
            pmsm_step(x, u, mp, xn)
            x[0] = xn[0] + sq0 * z[0]
            x[1] = xn[1] + sq1 * z[1]
            x[2] = xn[2] + sq2 * z[2]
            x[3] = wrap_angle(xn[3] + sq3 * z[3])
        zv = rng_plant.standard_normal(2)
        ys[t, 0] = x[0] + sr0 * zv[0]
        ys[t, 1] = x[1] + sr1 * zv[1]
        k = max(t - 1, 0)
        _, ess[t], res[t] = smc_update(p, rng_filter, rng_point, particles, lw, wn, om, th, pe, mean, var,
                                       ured, t, ys[t], ys[k], us[k], scheme, threshold, point_mode)
        if controller == 0:
            pi_dq_control(ys[t, 0], ys[t, 1], pe[0], pe[1], w_ref[t], integ, cp, u)
        elif controller == 1:
            cautious_control(ys[t, 0], ys[t, 1], om, th, wn, w_ref, t, consts, S, mp, cp, u)
        else:
            one_om[0] = pe[0]
            one_th[0] = pe[1]
            cautious_control(ys[t, 0], ys[t, 1], one_om, one_th, one_w, w_ref, t, consts, S, mp,
                             cp, u)
        for k in range(4):
            xs[t, k] = x[k]
        us[t, 0] = u[0]
        us[t, 1] = u[1]
        est[t, 0] = pe[0]
        est[t, 1] = pe[1]
        spread[t, 0] = pe[2]
        spread[t, 1] = pe[3]
        spread[t, 2] = pe[4]
        if store:
            for i in range(n):
                hist_om[t, i] = om[i]
                hist_th[t, i] = th[i]
                hist_w[t, i] = wn[i]


_closed_loop_smc_nb = njit(nogil=True)(_closed_loop_smc_py)


@dataclass
class Scenario:
    """§4.4.1: ramp 0 -> ``omega_final`` over ``ramp_s``, hold ``hold_s`` (0.1 s; 0.4 s in Fig. 4.9)."""

    ramp_s: float = 0.1
    hold_s: float = 0.1
    omega_final: float = 10.0

    def n_steps(self, dt: float) -> int:
        return int(round((self.ramp_s + self.hold_s) / dt))

    def reference(self, dt: float) -> np.ndarray:
        return reference_speed(self.n_steps(dt), dt, self.omega_final, self.ramp_s)


@dataclass
class LoopConfig:
    """Everything one closed-loop run needs (picklable, sent to worker processes)."""

    estimator: str = "smc"            # smc | ekf
    n_particles: int = 60
    ess_threshold: float = ESS_FRACTION  # resample when N_eff < this * N (Table 4.2: 12 of 60)
    resampling: str = "residual_deterministic"  # Table 4.2
    point: str = "mean"               # mean | sample | max | max_weight  (SMC)
    controller: str = "pi"            # pi | cc | cec
    horizon: int = 80                 # CC/CEC horizon n
    q_theta_filter: float = Q_THETA_FILTER
    theta_prior: str = "equidistant"  # SMC: equidistant | uniform | gaussian
    theta_offset: float | None = None  # gaussian prior mean = theta_true(0) + offset (Fig. 4.6)
    theta_prior_sd: float = math.pi / math.sqrt(3.0)  # EKF prior sd (= sd of U(-pi, pi))
    scenario: Scenario = field(default_factory=Scenario)
    gains: PIGains = field(default_factory=PIGains)
    model_kw: dict = field(default_factory=dict)
    backend: str = "numba"
    store_particles: bool = False
    filter_stream: int | None = None  # k >= 0: filter/point streams of SeedSequence([seed, run, k])


def _streams(seed, run, filter_stream=None):
    ss = np.random.SeedSequence([int(seed), int(run)])
    plant, filt, point = [np.random.default_rng(s) for s in ss.spawn(3)]
    if filter_stream is not None:
        if int(filter_stream) < 0:
            raise PfbenchError(f"filter_stream must be >= 0, got {filter_stream}")
        filt, point = [np.random.default_rng(s) for s in
                       np.random.SeedSequence([int(seed), int(run), int(filter_stream)]).spawn(2)]
    return plant, filt, point


def run_once(cfg: LoopConfig, seed: int = 0, run: int = 0) -> dict:
    """One closed-loop run; returns the trajectories and the summary (loss, failed)."""
    if cfg.controller not in CONTROLLERS:
        raise PfbenchError(f"unknown controller {cfg.controller!r}; choose pi, cc or cec")
    mode = point_code(cfg.point)
    scheme = scheme_code(cfg.resampling)
    model = Pmsm(**cfg.model_kw)
    mp = model.param_array()
    cp = cfg.gains.array(model)
    cp[7] = cfg.gains.gamma
    rng_plant, rng_filter, rng_point = _streams(seed, run, cfg.filter_stream)
    x0 = Pmsm.initial(rng_plant, 1, model.params())[0].copy()
    w_ref = cfg.scenario.reference(model.dt)
    M = w_ref.shape[0]
    if cfg.theta_offset is not None:
        th_mu, th_mode = wrap_angle(x0[3] + cfg.theta_offset), "gaussian"
    else:
        th_mu, th_mode = 0.0, cfg.theta_prior
    t0 = time.perf_counter()
    if cfg.estimator == "smc":
        p = smc_model(model, q_theta_filter=cfg.q_theta_filter, theta_prior=th_mode, theta_mu=th_mu,
                      theta_sd=cfg.theta_prior_sd).params()
        consts, S = cc_constants(mp, cfg.horizon)
        n = int(cfg.n_particles)
        threshold = ess_count(cfg.ess_threshold, n)
        xs, ys, us = np.empty((M, 4)), np.empty((M, 2)), np.empty((M, 2))
        est, spread = np.empty((M, 2)), np.empty((M, 3))
        ess, res = np.empty(M), np.zeros(M, dtype=np.bool_)
        hs = (M, n) if cfg.store_particles else (1, 1)
        hist = [np.zeros(hs), np.zeros(hs), np.zeros(hs)]
        fn = _closed_loop_smc_nb if cfg.backend == "numba" else _closed_loop_smc_py
        with held():  # numba unboxes the generators (pfbench.backends.interrupts.held)
            fn(mp, p, scheme, threshold, cp, consts, S, w_ref, x0, n, mode, CONTROLLERS[cfg.controller],
               rng_plant, rng_filter, rng_point, xs, ys, us, est, spread, ess, res,
               cfg.store_particles, *hist)
        out = {"x": xs, "y": ys, "u": us, "est": est, "spread": spread, "ess": ess,
               "resampled": res}
        if cfg.store_particles:
            out.update(hist_omega=hist[0], hist_theta=hist[1], hist_w=hist[2])
    elif cfg.estimator == "ekf":
        out = _run_ekf(model, mp, cp, w_ref, x0, rng_plant, cfg, th_mu)
    else:
        raise PfbenchError(f"unknown estimator {cfg.estimator!r}; choose smc or ekf")
    out["elapsed_s"] = time.perf_counter() - t0
    out["omega_ref"] = w_ref
    out["x0"] = x0
    out["loss"] = float(tracking_loss(out["u"], out["x"][:, 2], w_ref, cfg.gains.gamma).sum())
    out["failed"] = estimation_failed(out["x"][:, 3], out["est"][:, 1], out["x"][:, 2], w_ref,
                                      FailureCriterion(dt=model.dt))
    return out


def _run_ekf(model, mp, cp, w_ref, x0, rng_plant, cfg, th_mu):
    """EKF in the loop (thesis §4.2.2): Jacobian eq. 4.26, PI on the EKF mean."""
    from ...filters.kalman import ekf_predict, ekf_update

    M = w_ref.shape[0]
    Q = np.diag(model.q)
    R = np.diag(model.r)
    H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])

    def f(x, u, t):
        out = np.empty(4)
        pmsm_step(x, u, mp, out)
        return out

    def F(x, u, t):
        return jacobian(x, mp)

    def h(x, u, t):
        return x[:2]

    def Hj(x, u, t):
        return H

    hw = model.prior_halfwidth
    xh = np.array([0.0, 0.0, 0.0, th_mu])
    P = np.diag([hw * hw / 3, hw * hw / 3, hw * hw / 3, cfg.theta_prior_sd ** 2])
    sq, sr = np.sqrt(model.q), np.sqrt(model.r)
    xs, ys, us = np.empty((M, 4)), np.empty((M, 2)), np.empty((M, 2))
    est, sd = np.empty((M, 2)), np.empty((M, 2))
    x = x0.copy()
    u = np.zeros(2)
    integ = np.zeros(3)
    xn = np.empty(4)
    for t in range(M):
        if t > 0:
            z = rng_plant.standard_normal(4)
            pmsm_step(x, u, mp, xn)
            x = xn + sq * z
            x[3] = wrap_angle(x[3])
            xh, P = ekf_predict(xh, P, f, F, Q, u=u, t=t)
        zv = rng_plant.standard_normal(2)
        ys[t] = x[:2] + sr * zv
        xh, P, _, _ = ekf_update(xh, P, ys[t], h, Hj, R, t=t)
        xh = np.array(xh, dtype=np.float64)
        xh[3] = wrap_angle(xh[3])
        u = np.zeros(2)
        pi_dq_control(xh[0], xh[1], xh[2], xh[3], w_ref[t], integ, cp, u)
        xs[t], us[t] = x, u
        est[t] = xh[2], xh[3]
        sd[t] = math.sqrt(max(P[2, 2], 0.0)), math.sqrt(max(P[3, 3], 0.0))
    return {"x": xs, "y": ys, "u": us, "est": est, "sd": sd}


def _batch_worker(args):
    cfg, seed, runs = args
    rows = []
    for r in runs:
        o = run_once(cfg, seed, r)
        k = max(1, int(round(0.05 / 125e-6)))
        rows.append((r, o["loss"], o["failed"], o["elapsed_s"],
                     float(np.abs(np.angle(np.exp(1j * (o["est"][-k:, 1] - o["x"][-k:, 3])))).mean()),
                     float(np.abs(o["est"][-k:, 0] - o["x"][-k:, 2]).mean())))
    return rows


def run_batch(cfg: LoopConfig, n_runs: int, seed: int = 0, workers: int | None = None,
              progress=None) -> dict:
    """``n_runs`` closed-loop runs (run r uses streams SeedSequence([seed, r])) in worker
    processes. Returns arrays ``loss``, ``failed``, ``theta_err`` (final-window mean |error|),
    ``omega_err`` and the mean wall time per run step ``us_per_step``."""
    workers = workers or min(2, usable_cores())
    runs = list(range(int(n_runs)))
    chunk = max(1, min(25, len(runs) // (4 * workers) or 1))
    chunks = [runs[i:i + chunk] for i in range(0, len(runs), chunk)]
    jobs = [(cfg, seed, c) for c in chunks]
    rows = []
    if workers <= 1 or len(chunks) == 1:
        it = map(_batch_worker, jobs)
        for rr in (progress(it, total=len(jobs)) if progress else it):
            rows.extend(rr)
    else:
        with worker_pool(workers) as pool:  # workers die with this process (also on kill -9 or Ctrl-C)
            it = pool.map(_batch_worker, jobs)
            for rr in (progress(it, total=len(jobs)) if progress else it):
                rows.extend(rr)
    rows.sort()
    arr = np.array(rows, dtype=np.float64).reshape(-1, 6)
    M = cfg.scenario.n_steps(Pmsm(**cfg.model_kw).dt)
    return {"run": arr[:, 0].astype(int), "loss": arr[:, 1], "failed": arr[:, 2].astype(bool),
            "theta_err": arr[:, 4], "omega_err": arr[:, 5],
            "us_per_step": float(np.median(arr[:, 3]) * 1e6 / M)}
