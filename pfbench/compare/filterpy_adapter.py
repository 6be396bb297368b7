"""filterpy's extended and unscented Kalman filters as contenders (``filterpy:ekf|ukf``).

They need a model with Gaussian noise whose matrices filterpy can use: a linear-Gaussian model
(attributes A, C, Q, R, x0, P0, and B, D with inputs, as :class:`~pfbench.models.linear_gaussian.
LinearGaussian`), where the EKF is the exact Kalman filter. To other models they do not apply
(:class:`~pfbench.compare.contenders.NotApplicable`, naming what is missing). Time: the filter loop only (``elapsed_s``).
"""
from __future__ import annotations

import time

import numpy as np


def run_filterpy(model, y, u, alg: str) -> dict:
    from .contenders import NotApplicable

    missing = [a for a in ("A", "C", "Q", "R", "x0", "P0") if not hasattr(model, a)]
    if missing:
        raise NotApplicable(f"filterpy:{alg} needs a linear-Gaussian model; {model.name!r} lacks "
                        f"{', '.join(missing)}")
    A, C, Q, R = (np.asarray(getattr(model, k), dtype=float) for k in ("A", "C", "Q", "R"))
    n_x, n_y = A.shape[0], C.shape[0]
    M = y.shape[0]
    u = model.input_array(u, M)
    B = np.asarray(getattr(model, "B", np.zeros((n_x, 0))), dtype=float)
    D = np.asarray(getattr(model, "D", np.zeros((n_y, 0))), dtype=float)
    est, var = np.empty((M, n_x)), np.empty((M, n_x))
    ll = 0.0
    t0 = time.perf_counter()
    if alg == "ekf":
        from filterpy.kalman import ExtendedKalmanFilter

        f = ExtendedKalmanFilter(dim_x=n_x, dim_z=n_y)
        f.x, f.P, f.F, f.Q, f.R = np.asarray(model.x0, float).copy(), np.asarray(model.P0, float).copy(), A, Q, R
        for t in range(M):
            f.x = A @ f.x + B @ u[t]
            f.P = A @ f.P @ A.T + Q
            off = D @ u[t]
            f.update(y[t], HJacobian=lambda x: C, Hx=lambda x, off=off: C @ x + off)
            ll += float(f.log_likelihood)
            est[t], var[t] = f.x, np.diag(f.P)
    else:
        from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

        pts = MerweScaledSigmaPoints(n_x, alpha=1.0, beta=2.0, kappa=0.0)
        state = {"t": 0}
        f = UnscentedKalmanFilter(dim_x=n_x, dim_z=n_y, dt=1.0, points=pts,
                                  fx=lambda x, dt: A @ x + B @ u[state["t"]],
                                  hx=lambda x: C @ x + D @ u[state["t"]])
        f.x, f.P, f.Q, f.R = np.asarray(model.x0, float).copy(), np.asarray(model.P0, float).copy(), Q, R
        for t in range(M):
            state["t"] = t
            f.predict()
            f.update(y[t])
            ll += float(f.log_likelihood)
            est[t], var[t] = f.x, np.diag(f.P)
    return {"estimates": est, "variances": var, "loglik": ll, "elapsed_s": time.perf_counter() - t0,
            "n_particles": 0}
