"""Resistance temperature detector (RTD) models of [RTD] (Ulin-Avila & Ponce-Hernandez, 2021).

* the identified second-order model: continuous transfer function (eq. 52)
  ``G(s) = (2.278 s + 0.1711) / (s^2 + 2.488 s + 0.1695)`` (poles -2.4179, -0.0701), discretised
  with a zero-order hold at Ts = 0.1 s, and the N4SID innovation model of eq. 54 (signs lost in
  the text extraction, see :data:`EQ54_SIGNS`);
* the first-order RC reduction (eq. 51) whose time constant is fitted by log-linear least squares
  (eqs. 55-56), with the amplifier gain 260 of §6 as the output gain;
* the thermal-bath step experiments of §7 and the two-predictor boundary layer of §8.

Choices where the chapter is silent or the extraction is damaged (all are parameters):

* Ts = 0.1 s: the fast pole -2.4179 maps to exp(-0.24179) = 0.785, the smallest eigenvalue of the
  eq. 54 A matrix (0.788) at this sampling time; no other Ts fits.
* Fig. 5 noise levels Q = 2.3 (input noise, degC^2, enters through B as in the chapter's
  ``lsim(systv, U + w)``) and R = 1 (degC^2): the values of the MATLAB time-varying Kalman example the
  chapter says it modified ([55]); the constant input is the 38 degC of the identification (§4.1).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataError, InputError
from ..filters.kalman import steady_state_kf, time_varying_kf

TF_NUM = (2.278, 0.1711)                 # eq. 52 numerator
TF_DEN = (1.0, 2.488, 0.1695)            # eq. 52 denominator
PAPER_POLES = (-2.4179, -0.0701)         # §6
TS = 0.1                                 # sampling time [s] (see module docstring)
AMP_GAIN = 260.0                         # amplifier gain, §6 (C = 260 in the Arduino code)
U_STEP = 38.0                            # identification input [degC], §4.1

# eq. 54 magnitudes; the minus signs were lost in the text extraction.
EQ54_A = np.array([[0.8342, 0.08908], [0.0942, 0.9716]])
EQ54_B = np.array([0.01966, 0.03341])
EQ54_C = np.array([7.966, 0.3005])
EQ54_K = np.array([0.006289, 0.2834])
#: Sign choice for A21: with all entries positive A has an eigenvalue 1.0175 (unstable), so A21 < 0
#: is the only single-sign flip that gives a stable identified model (eigenvalues 0.903 +- 0.061j).
EQ54_SIGNS = {"A21": -1.0}


@dataclass
class DiscreteModel:
    """x[k+1] = A x[k] + B u[k],  y[k] = C x[k] (single input, single output)."""

    A: np.ndarray
    B: np.ndarray   # (n_x, 1)
    C: np.ndarray   # (1, n_x)
    Ts: float

    @property
    def poles_z(self) -> np.ndarray:
        return np.linalg.eigvals(self.A)

    @property
    def poles_s(self) -> np.ndarray:
        return np.log(self.poles_z.astype(complex)) / self.Ts

    @property
    def dc_gain(self) -> float:
        n = self.A.shape[0]
        return float((self.C @ np.linalg.solve(np.eye(n) - self.A, self.B))[0, 0])

    def simulate(self, u, w=None, x0=None) -> np.ndarray:
        """Noise-free output for input ``u + w`` (``lsim`` of the chapter); returns y (n,)."""
        u = np.asarray(u, dtype=np.float64).ravel()
        if w is not None:
            u = u + np.asarray(w, dtype=np.float64).ravel()
        x = np.zeros(self.A.shape[0]) if x0 is None else np.asarray(x0, dtype=np.float64).copy()
        y = np.empty(u.shape[0])
        b, c = self.B[:, 0], self.C[0]
        for k in range(u.shape[0]):
            y[k] = c @ x
            x = self.A @ x + b * u[k]
        return y

    def steady_state_x(self, u: float) -> np.ndarray:
        n = self.A.shape[0]
        return np.linalg.solve(np.eye(n) - self.A, self.B[:, 0] * u)


def tf_poles() -> np.ndarray:
    """Roots of the eq. 52 denominator s^2 + 2.488 s + 0.1695 (sorted, most negative first)."""
    return np.sort(np.roots(TF_DEN).real)


def identified_model(Ts: float = TS) -> DiscreteModel:
    """Eq. 52 transfer function as a discrete state-space model (zero-order hold, controllable form)."""
    from scipy.signal import cont2discrete, tf2ss

    A, B, C, D = tf2ss(TF_NUM, TF_DEN)
    Ad, Bd, Cd, _, _ = cont2discrete((A, B, C, D), Ts, method="zoh")
    return DiscreteModel(np.asarray(Ad), np.asarray(Bd).reshape(-1, 1), np.asarray(Cd).reshape(1, -1), Ts)


def eq54_model(signs: dict | None = None, Ts: float = TS) -> DiscreteModel:
    """The N4SID model of eq. 54 with the sign choice :data:`EQ54_SIGNS` (override with ``signs``,
    keys "A12", "A21", "B1", "B2", "C2" mapped to +-1)."""
    s = {"A12": 1.0, "A21": 1.0, "B1": 1.0, "B2": 1.0, "C2": 1.0, **EQ54_SIGNS, **(signs or {})}
    A = EQ54_A.copy(); A[0, 1] *= s["A12"]; A[1, 0] *= s["A21"]
    B = EQ54_B.copy(); B[0] *= s["B1"]; B[1] *= s["B2"]
    C = EQ54_C.copy(); C[1] *= s["C2"]
    return DiscreteModel(A, B.reshape(-1, 1), C.reshape(1, -1), Ts)


def tf_bode(w=None):
    """Bode data of the eq. 52 transfer function ([RTD] Fig. 3), via ``scipy.signal.bode``.

    ``w``: angular frequencies in rad/s (default 200 log-spaced points over 1e-3 .. 1e2 rad/s, two
    decades either side of the poles). Returns ``(w, magnitude_dB, phase_deg)``.
    """
    from scipy.signal import bode

    w = np.logspace(-3, 2, 200) if w is None else np.asarray(w, dtype=np.float64).ravel()
    if w.size == 0 or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise InputError("tf_bode: frequencies must be finite and positive")
    w, mag, phase = bode((TF_NUM, TF_DEN), w=w)
    return np.asarray(w), np.asarray(mag), np.asarray(phase)


def tf_step(t, amplitude: float = U_STEP) -> np.ndarray:
    """Continuous step response of eq. 52 to a step of ``amplitude`` at t = 0 (``scipy.signal.step``);
    the model curve of [RTD] Figs. 2 and 4 (input held at 38 degC, §4.1)."""
    from scipy.signal import step

    t = np.asarray(t, dtype=np.float64).ravel()
    if t.size < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0) or t[0] < 0:
        raise InputError("tf_step: t must be finite, non-negative and strictly increasing")
    _, y = step((TF_NUM, TF_DEN), T=t)
    return float(amplitude) * np.asarray(y)


# ----------------------------------------------------------------------------- RC reduction

@dataclass
class RCFit:
    """y = amp * exp(rate * t) fitted by log-linear least squares; tau = -1 / rate."""

    amp: float
    rate: float
    n_points: int

    @property
    def tau(self) -> float:
        return float("inf") if self.rate == 0 else -1.0 / self.rate


def fit_exponential(t, y) -> RCFit:
    """Log-linear least squares of [RTD] eqs. 55-56.

    ``ln y_i = c + B t_i`` (eq. 55), ``B = (n S_ty - S_t S_y) / (n S_tt - S_t^2)``,
    ``c = (S_tt S_y - S_t S_ty) / (n S_tt - S_t^2)`` (eq. 56), ``A = exp(c)``.
    Requires y > 0.
    """
    t = np.asarray(t, dtype=np.float64).ravel()
    y = np.asarray(y, dtype=np.float64).ravel()
    if t.shape != y.shape or t.size < 2:
        raise InputError("fit_exponential: need at least two (t, y) pairs of equal length")
    if np.any(~np.isfinite(y)) or np.any(y <= 0):
        raise InputError("fit_exponential: y must be positive (log-linear fit)")
    Y = np.log(y)
    n = t.size
    st, sy, stt, sty = t.sum(), Y.sum(), (t * t).sum(), (t * Y).sum()
    den = n * stt - st * st
    if den == 0:
        raise InputError("fit_exponential: all t are equal")
    B = (n * sty - st * sy) / den
    c = (stt * sy - st * sty) / den
    return RCFit(float(np.exp(c)), float(B), n)


def fit_rc_step(t, y, y_final: float, y_start: float | None = None, frac: tuple = (0.05, 0.95)) -> RCFit:
    """RC time constant of a step response: eqs. 55-56 applied to ``|y_final - y|``.

    Only the points where the response has covered between ``frac[0]`` and ``frac[1]`` of the step
    are used (the log of the noise floor near the end would bias the slope).
    """
    t = np.asarray(t, dtype=np.float64).ravel()
    y = np.asarray(y, dtype=np.float64).ravel()
    y0 = y[0] if y_start is None else y_start
    step = y_final - y0
    if step == 0:
        raise InputError("fit_rc_step: the response has no step")
    progress = (y - y0) / step
    sel = (progress >= frac[0]) & (progress <= frac[1])
    if sel.sum() < 3:
        raise InputError("fit_rc_step: fewer than 3 points inside the fit window")
    return fit_exponential(t[sel] - t[sel][0], np.abs(y_final - y[sel]))


def rc_model(tau: float, Ts: float = TS, gain: float = 1.0) -> DiscreteModel:
    """First-order RC model (eq. 51) discretised exactly: a = exp(-Ts/tau), b = 1 - a, c = gain.

    The state is the sensor temperature seen through the RC lag with unit DC gain from the bath
    temperature u; ``gain`` is the amplifier gain of the readings (260 for ADC counts, 1 for degC).
    """
    if not np.isfinite(tau) or tau <= 0:
        raise InputError(f"rc_model: the time constant must be positive, got {tau}")
    a = float(np.exp(-Ts / tau))
    return DiscreteModel(np.array([[a]]), np.array([[1.0 - a]]), np.array([[gain]]), Ts)


# ----------------------------------------------------------------------------- experiments

def simulate_fig5(n: int = 600, Qu: float = 2.3, R: float = 1.0, u: float = U_STEP, seed: int = 0,
                  model: DiscreteModel | None = None):
    """The simulation of [RTD] §4.2.1 / §5: second-order model driven by ``U + w`` (w ~ N(0, Qu)),
    measured with v ~ N(0, R); time-varying KF with ``Q = B Qu B^T`` and ``P0 = B Qu B^T``.

    Returns a dict of arrays: t, u, y_true, y_meas, yest, errcov, gain (first gain component).
    """
    m = identified_model() if model is None else model
    rng = np.random.default_rng(seed)
    w = np.sqrt(Qu) * rng.standard_normal(n)
    v = np.sqrt(R) * rng.standard_normal(n)
    U = np.full(n, float(u))
    y_true = m.simulate(U, w)
    y_meas = y_true + v
    Qx = Qu * (m.B @ m.B.T)
    ex = time_varying_kf(m.A, m.B, m.C, Qx, [[R]], U, y_meas).extras
    return {"t": np.arange(n) * m.Ts, "u": U, "y_true": y_true, "y_meas": y_meas, "yest": ex["yest"][:, 0],
            "errcov": ex["errcov"][:, 0, 0], "gain": ex["gains"][:, 0, 0], "model": m, "Qx": Qx}


def fig5_runs(n: int = 600, Qu: float = 2.3, R: float = 1.0, seeds=(0,), u: float = U_STEP,
              model: DiscreteModel | None = None) -> dict:
    """:func:`simulate_fig5` for many seeds at once (same noise draws per seed, so each row equals
    that seed's run): the filter's gains do not depend on the data, so they are computed once and
    the runs advance together. Returns t, y_true (runs, n), yest (runs, n) and errcov (n,)."""
    m = identified_model() if model is None else model
    seeds = list(seeds)
    W, V = np.empty((len(seeds), n)), np.empty((len(seeds), n))
    for i, s in enumerate(seeds):
        rng = np.random.default_rng(s)
        W[i] = np.sqrt(Qu) * rng.standard_normal(n)
        V[i] = np.sqrt(R) * rng.standard_normal(n)
    A, b, c = m.A, m.B[:, 0], m.C[0]
    Qx = Qu * (m.B @ m.B.T)
    P = Qx.copy()                                   # the chapter's Ptv = B*Q*B'
    gains, errcov = np.empty((n, A.shape[0])), np.empty(n)
    for k in range(n):
        Mk = P @ c / (c @ P @ c + R)
        P = P - np.outer(Mk, c @ P)
        P = 0.5 * (P + P.T)
        gains[k], errcov[k] = Mk, c @ P @ c
        P = A @ P @ A.T + Qx
        P = 0.5 * (P + P.T)
    x = np.zeros((len(seeds), A.shape[0])); xh = np.zeros_like(x)
    y_true, yest = np.empty((len(seeds), n)), np.empty((len(seeds), n))
    for k in range(n):
        y_true[:, k] = x @ c
        x = x @ A.T + np.outer(u + W[:, k], b)
        xh = xh + np.outer(y_true[:, k] + V[:, k] - xh @ c, gains[k])
        yest[:, k] = xh @ c
        xh = xh @ A.T + u * b
    return {"t": np.arange(n) * m.Ts, "y_true": y_true, "yest": yest, "errcov": errcov}


def bath_profile(T_low: float = 25.0, T_high: float = 38.0, t_hold: float = 60.0, Ts: float = TS):
    """Thermal-bath input: T_low for 5 s, step up to T_high for t_hold, step down to T_low for t_hold."""
    n0, n1 = int(round(5.0 / Ts)), int(round(t_hold / Ts))
    u = np.concatenate([np.full(n0, T_low), np.full(n1, T_high), np.full(n1, T_low)])
    return np.arange(u.size) * Ts, u


def simulate_bath(R: float = 0.05, T_low: float = 25.0, T_high: float = 38.0, t_hold: float = 60.0,
                  seed: int = 0, model: DiscreteModel | None = None):
    """Sensor readings of a thermal-bath step up / step down (§7): the second-order model of eq. 52
    started at equilibrium at T_low, plus white measurement noise N(0, R). Returns t, u, y_true, y_meas."""
    m = identified_model() if model is None else model
    t, u = bath_profile(T_low, T_high, t_hold, m.Ts)
    x0 = m.steady_state_x(T_low) / m.dc_gain  # sensor in equilibrium reading T_low
    y_true = m.simulate(u / m.dc_gain, x0=x0)  # unit DC gain: the sensor settles at the bath temperature
    rng = np.random.default_rng(seed)
    return t, u, y_true, y_true + np.sqrt(R) * rng.standard_normal(t.size)


@dataclass
class BoundaryLayer:
    """Output of :func:`boundary_layer`: KF estimate and the two one-step predictors."""

    kf: np.ndarray          # time-varying KF estimate C x[n|n] (the chapter's cyan line)
    pred_a: np.ndarray      # predictor A: C x[n+1|n] with (Q_a, R_a), shifted to be aligned with time n+1
    pred_b: np.ndarray
    gains: tuple            # steady-state gains (M_a, M_b)


def boundary_layer(y, u, rc: DiscreteModel, qr_a=(1.0, 0.05), qr_b=(1e-4, 0.05), qr_kf=(1e-4, 1.0),
                   ) -> BoundaryLayer:
    """Two first-order steady-state Kalman predictors with different (Q, R) ([RTD] §6.1, §8) and the
    time-varying KF, on the RC model ``rc`` driven by the bath temperature u.

    Q enters as ``B Q B`` like the chapter's code (``P = A*P*A + B*Q*B``). The predictors output
    ``C x[n+1|n]``; they are returned aligned with the reading they predict (element n is the
    prediction of y_n made at n-1; element 0 is the filter's initial value).
    """
    y = np.asarray(y, dtype=np.float64).ravel()
    u = np.asarray(u, dtype=np.float64).ravel()
    c = rc.C[0, 0]
    x0 = [y[0] / c]
    b2 = float(rc.B[0, 0] ** 2)
    out, gains = [], []
    for Q, R in (qr_a, qr_b):
        ex = steady_state_kf(rc.A, rc.B, rc.C, [[Q * b2]], [[R]], u, y, x0=x0).extras
        out.append(np.concatenate([[y[0]], ex["ypred"][:-1, 0]]))
        gains.append(float(ex["gains"][0, 0, 0]))
    Q, R = qr_kf
    kf = time_varying_kf(rc.A, rc.B, rc.C, [[Q * b2]], [[R]], u, y, x0=x0, P0=[[Q * b2]])
    return BoundaryLayer(kf.extras["yest"][:, 0], out[0], out[1], tuple(gains))


def envelope_fraction(y_ref, p1, p2, mask=None) -> float:
    """Fraction of samples (within ``mask``) where y_ref lies between p1 and p2 (inclusive)."""
    y_ref, p1, p2 = (np.asarray(a, dtype=np.float64).ravel() for a in (y_ref, p1, p2))
    lo, hi = np.minimum(p1, p2), np.maximum(p1, p2)
    inside = (y_ref >= lo) & (y_ref <= hi)
    if mask is not None:
        inside = inside[np.asarray(mask, dtype=bool)]
    return float(inside.mean()) if inside.size else float("nan")


def predictor_trace(y, u, rc: DiscreteModel, ratio: float) -> np.ndarray:
    """The one-step steady-state Kalman predictor of :func:`boundary_layer` for the ratio
    ``ratio`` = Q/R (a scalar filter's gain depends on Q/R only), as a first-order linear recursion
    (``scipy.signal.lfilter``): ``x[k+1] = a (1 - M c) x[k] + a M y[k] + b u[k]``, ``M`` the DARE gain.
    Aligned like :class:`BoundaryLayer` (element k is c x[k|k-1]; element 0 is y[0])."""
    from scipy.signal import lfilter

    from ..filters.dare import dare_scalar

    y = np.asarray(y, dtype=np.float64).ravel()
    u = np.asarray(u, dtype=np.float64).ravel()
    a, b, c = float(rc.A[0, 0]), float(rc.B[0, 0]), float(rc.C[0, 0])
    if not np.isfinite(ratio) or ratio <= 0:
        raise InputError(f"predictor_trace: the ratio Q/R must be positive, got {ratio}")
    P = dare_scalar(a, c, float(ratio) * b * b, 1.0)
    M = P * c / (c * c * P + 1.0)
    alpha = a * (1.0 - M * c)
    x0 = y[0] / c
    z = lfilter([1.0], [1.0, -alpha], a * M * y + b * u, zi=[alpha * x0])[0]
    return c * np.concatenate([[x0], z[:-1]])


def kf_trace(y, u, rc: DiscreteModel, ratio: float) -> np.ndarray:
    """The time-varying KF estimate C x[n|n] of :func:`boundary_layer` (Q = ratio R through B,
    P0 = B Q B as the chapter's code) as a scalar loop: the first-order filter's gain depends on Q/R
    only, so R = 1."""
    y = np.asarray(y, dtype=np.float64).ravel()
    u = np.asarray(u, dtype=np.float64).ravel()
    a, b, c = float(rc.A[0, 0]), float(rc.B[0, 0]), float(rc.C[0, 0])
    if not np.isfinite(ratio) or ratio <= 0:
        raise InputError(f"kf_trace: the ratio Q/R must be positive, got {ratio}")
    q = float(ratio) * b * b
    x, P = y[0] / c, q
    out = np.empty(y.size)
    for k in range(y.size):
        M = P * c / (c * c * P + 1.0)
        x = x + M * (y[k] - c * x)
        P = (1.0 - M * c) * P
        out[k] = c * x
        x = a * x + b * u[k]
        P = a * a * P + q
    return out


#: Q/R ratios the calibration of the two predictors chooses from (log grid, 10^-4 .. 10^6)
CALIBRATION_RATIOS = tuple(float(v) for v in np.logspace(-4, 6, 21))


@dataclass
class Calibration:
    """The two predictors' Q/R ratios chosen by :func:`calibrate_predictors`."""

    ratio_a: float      # the larger Q/R (follows the readings)
    ratio_b: float      # the smaller Q/R (follows the RC model)
    fraction: float     # fraction of the calibration samples inside the layer
    width: float        # mean width of the layer over those samples


def calibrate_predictors(y, u, rc: DiscreteModel, y_ref, mask, ratios=CALIBRATION_RATIOS) -> Calibration:
    """Calibrate the two predictors first ([RTD] §8: "the system needs to be calibrated first in
    order to have the two Kalman filters enveloping the required solution"; §6, Fig. 6: two filters
    "with different Q and R to calibrate the desired response"): over every pair of ``ratios``
    (Q/R of predictor A > that of predictor B), the pair whose layer holds ``y_ref`` for the largest
    fraction of the ``mask`` samples, the narrowest layer among equals (so the calibration does not
    simply take the two extremes)."""
    mask = np.asarray(mask, dtype=bool)
    if mask.sum() < 2:
        raise InputError("calibrate_predictors: fewer than 2 calibration samples")
    ratios = sorted(float(r) for r in ratios)
    if len(ratios) < 2:
        raise InputError("calibrate_predictors: need at least two Q/R ratios")
    ref = np.asarray(y_ref, dtype=np.float64).ravel()[mask]
    tr = [predictor_trace(y, u, rc, r)[mask] for r in ratios]
    best = None
    for i in range(len(ratios)):
        for j in range(i):
            lo, hi = np.minimum(tr[i], tr[j]), np.maximum(tr[i], tr[j])
            frac = float(np.mean((ref >= lo) & (ref <= hi)))
            width = float(np.mean(hi - lo))
            key = (-frac, width)
            if best is None or key < best[0]:
                best = (key, Calibration(ratios[i], ratios[j], frac, width))
    return best[1]


# ----------------------------------------------------------------------------- data logs

def load_log(path) -> dict:
    """Read a thermal-bath CSV log: columns ``t`` (s) and ``y`` (reading), optional ``u`` (bath
    temperature / set-point, same units as y). Raises DataError (a PfbenchError) with one line on
    bad files.

    Without ``u`` the set-point is reconstructed: the run is split at the (smoothed) maximum; before
    it the target is the mean of the readings within 2 % of the maximum level's last tenth, after it
    the mean of the last 10 % of the readings.
    """
    import pandas as pd

    p = Path(path)
    if not p.is_file():
        raise DataError(f"data file not found: {p}")
    try:
        df = pd.read_csv(p)
    except Exception as exc:  # pandas raises several types (ParserError, UnicodeDecodeError, ...)
        raise DataError(f"cannot parse {p} as CSV: {str(exc).splitlines()[0] if str(exc) else exc}") from None
    df.columns = [str(c).strip().lower() for c in df.columns]
    for col in ("t", "y"):
        if col not in df.columns:
            raise DataError(f"{p}: missing column {col!r} (need t, y and optionally u)")
    cols = ["t", "y"] + (["u"] if "u" in df.columns else [])
    try:
        arr = {c: pd.to_numeric(df[c], errors="raise").to_numpy(dtype=np.float64) for c in cols}
    except (ValueError, TypeError):
        raise DataError(f"{p}: non-numeric values in columns {cols}") from None
    if len(arr["t"]) < 20:
        raise DataError(f"{p}: need at least 20 rows, got {len(arr['t'])}")
    if not all(np.all(np.isfinite(v)) for v in arr.values()):
        raise DataError(f"{p}: NaN or inf values")
    dt = np.diff(arr["t"])
    if np.any(dt <= 0):
        raise DataError(f"{p}: column t must be strictly increasing")
    if np.ptp(dt) > 0.01 * np.median(dt):
        raise DataError(f"{p}: column t must be uniformly sampled (dt varies from {dt.min():g} to {dt.max():g})")
    arr["Ts"] = float(np.median(dt))
    if "u" not in arr:
        arr["u"] = reconstruct_setpoint(arr["y"])
        arr["u_reconstructed"] = True
    else:
        arr["u_reconstructed"] = False
    return arr


def reconstruct_setpoint(y) -> np.ndarray:
    """Piecewise-constant set-point of an up-then-down bath run (see :func:`load_log`)."""
    y = np.asarray(y, dtype=np.float64)
    n = y.size
    k = max(1, n // 50)
    ys = np.convolve(y, np.ones(k) / k, mode="same")
    i_max = int(np.argmax(ys[k:n - k])) + k
    hi = float(np.mean(y[max(0, i_max - n // 10):i_max + 1]))
    lo = float(np.mean(y[-max(2, n // 10):]))
    u = np.full(n, lo)
    # the step up starts where the reading first leaves its initial level
    start = float(np.mean(y[:max(2, n // 50)]))
    thr = start + 0.1 * (hi - start)
    i_up = int(np.argmax(ys >= thr)) if np.any(ys >= thr) else 0
    # the step down starts where the reading leaves the plateau
    after = np.nonzero(ys[i_max:] <= hi - 0.1 * (hi - lo))[0]
    i_down = i_max + (int(after[0]) if after.size else n - i_max)
    u[:i_up] = start
    u[i_up:i_down] = hi
    return u
