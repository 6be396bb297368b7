"""Scenario, tracking loss and the failure definition ([Thesis], thesis §4.1.2, §4.4.1).

Tracking loss (eq. 4.16-4.17): sum_t u_t' Gamma u_t + (x_t - xbar_t)' Xi (x_t - xbar_t) with
Gamma = gamma I (gamma = 0.1, the value quoted in §4.3.2) and Xi = diag(0, 0, 1, 0), i.e.
gamma |u_t|^2 + (omega_t - omega_ref_t)^2, accumulated over the whole run.

Estimation failure (our explicit definition; the thesis only says "process of estimation
fails"): over the final ``window_s`` seconds (default 0.05 s = 400 steps) of the run,
the mean absolute wrapped theta error |wrap(theta_hat - theta)| exceeds ``theta_tol``
(default pi/2: the estimate sits on the wrong mode, typically pi away, Fig. 4.2), **or** the
true mean speed differs from the reference by more than ``omega_tol`` (default 50 % of the
final reference: the drive did not reach the set point, e.g. turns in the wrong direction).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def reference_speed(n_steps: int, dt: float = 125e-6, omega_final: float = 10.0,
                    ramp_s: float = 0.1) -> np.ndarray:
    """omega_ref: linear ramp from 0 to ``omega_final`` over ``ramp_s`` seconds, then hold
    (§4.4.1; hold 0.1 s -> 1600 steps in total, Fig. 4.9 holds 0.4 s -> 4000 steps)."""
    t = np.arange(int(n_steps)) * dt
    return omega_final * np.minimum(t / ramp_s, 1.0)


def tracking_loss(u, omega, omega_ref, gamma: float = 0.1) -> np.ndarray:
    """Per-step loss of eq. 4.16: gamma |u_t|^2 + (omega_t - omega_ref_t)^2 (sum it for the total)."""
    u = np.asarray(u, dtype=np.float64)
    e = np.asarray(omega, dtype=np.float64) - np.asarray(omega_ref, dtype=np.float64)
    return gamma * np.sum(u * u, axis=-1) + e * e


def wrap(th):
    th = np.asarray(th, dtype=np.float64)
    return th - 2 * np.pi * np.ceil((th - np.pi) / (2 * np.pi))


@dataclass(frozen=True)
class FailureCriterion:
    window_s: float = 0.05
    theta_tol: float = np.pi / 2
    omega_tol_frac: float = 0.5
    dt: float = 125e-6


def estimation_failed(theta_true, theta_hat, omega_true, omega_ref,
                      crit: FailureCriterion = FailureCriterion()) -> bool:
    """The failure definition of the module docstring for one run (arrays over time)."""
    k = max(1, int(round(crit.window_s / crit.dt)))
    th_err = np.abs(wrap(np.asarray(theta_hat)[-k:] - np.asarray(theta_true)[-k:])).mean()
    w_ref = np.asarray(omega_ref)[-k:]
    w_err = np.abs(np.asarray(omega_true)[-k:].mean() - w_ref.mean())
    return bool(th_err > crit.theta_tol or w_err > crit.omega_tol_frac * abs(w_ref[-1]))
