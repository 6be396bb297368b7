"""Heating/cooling chamber models of [Embedded] (§4.2-§4.4): ``thermal_inertial``, ``thermal_rate``,
``thermal_outdoor``.

Units and operating point (our reading, the paper does not state it)
--------------------------------------------------------------------
The two-inertial model G(s) = K / ((1 + s T1)(1 + s T2)) ([Embedded], eqs. 7-9) is read with

* inputs u1 (LED heater) and u2 (fan) in **percent** (0..100): the model uses ``u_scale * u``
  (default 1.0; ``u_scale=100`` feeds logs whose inputs are fractions 0..1 under the same reading,
  ``u_scale=0.01`` with percent inputs is the alternative reading "K per unit fraction");
* the output as **deviation from an operating point** ``op`` in degC, and the state ``x1`` kept
  as the absolute temperature, i.e. ``x1 - op`` obeys eq. 9. ``op`` defaults to the first
  measurement ``y0`` (the PF "takes into account the initial condition y(0)", §4.2), which the
  paper says should ideally equal the outdoor temperature.

With that reading the heating step response at u1 = 100 % settles K_h * 100 = 5.26 degC above
ambient (the chamber of §3 plausibly heats by 3-5 degC), while u1 in fractions would give 0.05 degC
(implausible). The cooling gain K_c = 0.2069 - y(0)/100 is ~0.012 degC/% for y(0) ~ 19.5 degC, so the
cooling model settles K_c * u2 ~ 1.2 degC above ``op`` at fan 100 % (a mismatch with the real chamber,
which cools towards ambient; the process noise has to absorb it, as §6 says it does).

Jump system (§4.2, §5.3): the operating mode travels as the third input column,
``u = (u1, u2, mode)``; mode >= 0.5 selects the heating parameters (K_h, T_h1, T_h2) driven by
u1, otherwise the cooling parameters (K_c, T_c1, T_c2) driven by u2 -- so the filter switches
parameter set at every mode change, per step.

Euler discretisation at T_s (eq. 10), with ``d = x1 - op``::

    x1(k+1) = x1(k) + T_s x2(k)                                             + v1
    x2(k+1) = x2(k) + T_s (K u(k) - d(k)) / (T1 T2) - T_s (1/T1 + 1/T2) x2(k) + v2
    y(k)    = x1(k) + n(k)

The process noise v ~ N(0, diag(var_v1, var_v2)) (variances); Appendix A gives one sigma_v^2 per test,
read as applying to both components (v ~ N(0, sigma_v^2 I)).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import register
from .base import LOG_2PI, StateSpaceModel

#: [Embedded] §4.2 heating parameters
K_H, T_H1, T_H2 = 0.0526, 36.32, 508.48
#: [Embedded] §4.2 cooling time constants; K_c = 0.2069 - y(0)/100
K_C0, T_C1, T_C2 = 0.2069, 25.00, 148.00


def cooling_gain(y0: float) -> float:
    """K_c = 0.2069 - y(0)/100 ([Embedded] §4.2)."""
    return K_C0 - float(y0) / 100.0


def default_inputs(n_steps: int, heat_fraction: float = 0.6) -> np.ndarray:
    """A heating-then-cooling input sequence (u1, u2, mode) for ``simulate()``."""
    n_heat = int(round(heat_fraction * n_steps))
    u = np.empty((n_steps, 3))
    u[:n_heat] = (100.0, 30.0, 1.0)
    u[n_heat:] = (0.0, 100.0, 0.0)
    return u


def _mode_inputs(cols: dict) -> np.ndarray:
    """(u1, u2, mode) from a log; mode from a ``mode`` column or u1 >= 50 % (heating)."""
    u1, u2 = cols["u1"], cols["u2"]
    mode = cols["mode"] if "mode" in cols else (u1 >= 50.0).astype(np.float64)
    return np.column_stack([u1, u2, mode]).astype(np.float64)


class _TwoInertial(StateSpaceModel):
    n_x, n_y, n_noise = 2, 1, 2
    n_u = 3
    state_names = ("T", "dT/dt")

    def __init__(self, y0: float = 19.5, var_v1: float = 0.010, var_v2: float | None = None,
                 var_n: float = 0.005, op: float | None = None, u_scale: float = 1.0,
                 kh: float = K_H, th1: float = T_H1, th2: float = T_H2, kc: float | None = None,
                 tc1: float = T_C1, tc2: float = T_C2, ts: float = 1.0, p0_var: float | None = None):
        # var_* are the paper's sigma^2 (variances), as in the CLI --param var_n=0.005
        if var_v1 < 0 or (var_v2 is not None and var_v2 < 0) or var_n <= 0:
            raise InputError("variances must be >= 0 (var_n > 0)")
        if min(th1, th2, tc1, tc2, ts) <= 0:
            raise InputError("time constants and T_s must be positive")
        self.y0 = float(y0)
        self.var_v1 = float(var_v1)
        self.var_v2 = float(var_v1 if var_v2 is None else var_v2)
        self.var_n = float(var_n)
        self._op = None if op is None else float(op)
        self._kc = None if kc is None else float(kc)
        self.u_scale, self.ts = float(u_scale), float(ts)
        self.kh, self.th1, self.th2, self.tc1, self.tc2 = map(float, (kh, th1, th2, tc1, tc2))
        self.p0_var = float(self.var_n if p0_var is None else p0_var)

    # the operating point and K_c follow y0 unless given explicitly
    @property
    def op(self) -> float:
        return self.y0 if self._op is None else self._op

    @property
    def kc(self) -> float:
        return cooling_gain(self.y0) if self._kc is None else self._kc

    def set_initial_measurement(self, y0: float) -> None:
        """Initialise the PF from the first measurement y(0) (§4.2)."""
        self.y0 = float(y0)

    def init_from_log(self, cols: dict) -> None:
        """Called by :func:`pfbench.plants.datalog.load_log`: y(0) from the log's first row."""
        self.set_initial_measurement(cols["y"][0])

    def params(self):
        return (self.kh, self.th1, self.th2, self.kc, self.tc1, self.tc2, self.ts, self.op,
                np.sqrt(self.var_v1), np.sqrt(self.var_v2), self.var_n, self.u_scale,
                self.y0, np.sqrt(self.p0_var))

    def inputs(self, rng, n_steps):
        return default_inputs(n_steps)

    def log_arrays(self, cols: dict):
        """(y, u) for this model from the validated columns of a log (see pfbench.plants.datalog)."""
        return cols["y"].reshape(-1, 1), _mode_inputs(cols)

    log_columns = ("u1", "u2")

    def describe(self) -> dict:
        d = super().describe()
        d.update(y0=self.y0, op=self.op, kc=self.kc, var_v1=self.var_v1, var_v2=self.var_v2,
                 var_n=self.var_n, u_scale=self.u_scale)
        return d

    @staticmethod
    def initial(rng, n, p):
        z = rng.standard_normal((n, 2))
        x = np.empty((n, 2))
        x[:, 0] = p[12] + p[13] * z[:, 0]
        x[:, 1] = 0.0 * z[:, 1]
        return x

    @staticmethod
    def transition(x, u, t, noise, p):
        if u[2] >= 0.5:
            k, t1, t2, ui = p[0], p[1], p[2], u[0]
        else:
            k, t1, t2, ui = p[3], p[4], p[5], u[1]
        ts = p[6]
        out = np.empty_like(x)
        x1 = x[:, 0]
        x2 = x[:, 1]
        out[:, 0] = x1 + ts * x2 + p[8] * noise[:, 0]
        out[:, 1] = (x2 + ts * (k * ui * p[11] - (x1 - p[7])) / (t1 * t2)
                     - ts * (1.0 / t1 + 1.0 / t2) * x2 + p[9] * noise[:, 1])
        return out

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        r = y[0] - x[:, 0]
        return -0.5 * r * r / p[10] - 0.5 * (LOG_2PI + np.log(p[10]))

    @staticmethod
    def observe(x, u, t, noise, p):
        return x[:, 0:1] + np.sqrt(p[10]) * noise


@register("thermal_inertial")
class ThermalInertial(_TwoInertial):
    """Two-inertial jump model, [Embedded] eqs. 7-10 (see the module docstring for units).

    Parameters (variances, not standard deviations): ``var_v1``, ``var_v2`` (default = var_v1),
    ``var_n``; ``y0`` first measurement (PF initial mean, K_c and default operating point);
    ``op`` operating point; ``u_scale`` input units; ``kh, th1, th2, kc, tc1, tc2, ts``.
    Inputs u = (u1 %, u2 %, mode), mode 1 = heating, 0 = cooling.
    """


@register("thermal_outdoor")
class ThermalOutdoor(_TwoInertial):
    """§4.3: the two-inertial model with output y = T_in - T_out.

    The state x1 is the indoor-outdoor difference (operating point 0, so with no input it decays
    to T_in = T_out); logs give y = y_log - t_out (column ``t_out`` required). The initial mean is
    y(0) - t_out(0), K_c still uses the indoor y(0). Estimate of T_in = x1 + t_out.
    """

    log_columns = ("u1", "u2", "t_out")

    def __init__(self, y0: float = 0.2, t_in0: float = 19.5, **kw):
        kw.setdefault("op", 0.0)
        super().__init__(y0=y0, **kw)
        self.t_in0 = float(t_in0)

    @property
    def kc(self) -> float:
        return cooling_gain(self.t_in0) if self._kc is None else self._kc

    def init_from_log(self, cols: dict) -> None:
        self.t_in0 = float(cols["y"][0])
        self.set_initial_measurement(cols["y"][0] - cols["t_out"][0])

    def log_arrays(self, cols: dict):
        return (cols["y"] - cols["t_out"]).reshape(-1, 1), _mode_inputs(cols)


@register("thermal_rate")
class ThermalRate(StateSpaceModel):
    """Model-free double integrator, [Embedded] eqs. 11-12::

        x1(k+1) = 2 x1(k) - x2(k) + v1,   x2(k+1) = x1(k) + v2,   y(k) = x1(k) + n(k)

    ``var_v1`` = 1e-6, ``var_v2`` = 0, ``var_n`` = 0.0225 (variances, §4.4). Autonomous
    (n_u = 0); initialised at x1 = x2 = y0 (+ N(0, p0_var) on x1, copied to x2: zero initial rate).
    """

    n_x, n_y, n_u, n_noise = 2, 1, 0, 2
    state_names = ("T", "T_prev")
    log_columns = ()

    def __init__(self, y0: float = 19.5, var_v1: float = 1e-6, var_v2: float = 0.0,
                 var_n: float = 0.0225, p0_var: float | None = None):
        if var_v1 < 0 or var_v2 < 0 or var_n <= 0:
            raise InputError("variances must be >= 0 (var_n > 0)")
        self.y0, self.var_v1, self.var_v2, self.var_n = map(float, (y0, var_v1, var_v2, var_n))
        self.p0_var = float(self.var_n if p0_var is None else p0_var)

    def set_initial_measurement(self, y0: float) -> None:
        self.y0 = float(y0)

    def init_from_log(self, cols: dict) -> None:
        self.set_initial_measurement(cols["y"][0])

    def params(self):
        return (np.sqrt(self.var_v1), np.sqrt(self.var_v2), self.var_n, self.y0, np.sqrt(self.p0_var))

    def log_arrays(self, cols: dict):
        return cols["y"].reshape(-1, 1), None

    def describe(self) -> dict:
        d = super().describe()
        d.update(y0=self.y0, var_v1=self.var_v1, var_v2=self.var_v2, var_n=self.var_n)
        return d

    @staticmethod
    def initial(rng, n, p):
        z = rng.standard_normal((n, 2))
        x = np.empty((n, 2))
        x[:, 0] = p[3] + p[4] * z[:, 0]
        x[:, 1] = x[:, 0] + 0.0 * z[:, 1]
        return x

    @staticmethod
    def transition(x, u, t, noise, p):
        out = np.empty_like(x)
        out[:, 0] = 2.0 * x[:, 0] - x[:, 1] + p[0] * noise[:, 0]
        out[:, 1] = x[:, 0] + p[1] * noise[:, 1]
        return out

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        r = y[0] - x[:, 0]
        return -0.5 * r * r / p[2] - 0.5 * (LOG_2PI + np.log(p[2]))

    @staticmethod
    def observe(x, u, t, noise, p):
        return x[:, 0:1] + np.sqrt(p[2]) * noise
