"""Simulated heating/cooling chamber (the *plant*) for [Embedded] §3-§5.3.

This is deliberately **not** the filter's model (eqs. 10/12): a continuous-time lumped thermal
network integrated with RK4 at ``dt`` = 0.1 s, containing what §6 says the simple models ignore:

* a heater node (10 W LED on its heatsink; the effective heat reaching the air is ``p_max`` W,
  with a mild PWM/driver nonlinearity P = p_max (u1/100)^``heater_exp``);
* two air zones: a hot zone above the heater and the bulk air around the sensor, mixed by the fan
  (mixing conductance grows with u2). With the fan low, hot air stratifies above the heater;
  a jump of the fan to 100 % mixes it towards the sensor. **The "sudden increase in the air
  temperature around the thermometer" that §5.2 reports at the start of cooling is NOT reproduced
  at the sensor:** the fan never runs below 30 %, where the mixing conductance is already
  ``g_mix0 + 0.3 g_mix1`` = 0.22 W/K, so the hot zone is only a few tenths of a degree above the
  bulk air; the simulated bump is ~0.04 degC in the bulk air and, after the sensor's 8 s lag,
  ~0.01-0.02 degC at the sensor element -- below the 0.0625 degC step, so the quantised log never
  shows it (:func:`mixing_bump` measures it). The chamber's airflow is not described in [Embedded],
  so we do not retune the mixing to make a bump appear;
* the case walls (slow, the dominant time constant) with natural convection to the room whose
  conductance grows mildly with the temperature difference (nonlinear);
* fan ventilation with room air (conductance grows with u2) and a little fan-motor heat;
* the room (ambient) temperature drifting slowly (sinusoid + Ornstein-Uhlenbeck) around ``ambient``;
* a DS18B20 with a first-order thermal lag ``tau_sensor`` and small analogue noise, quantised to
  0.0625 degC and read once per second; an outdoor DS18B20 the same way (column ``t_out``).

Inputs are clipped to the hardware ranges: u1 in [0, 100] %, u2 in [30, 100] % (the fan does not
run below 30 %, §5.2). Every parameter is a field of :class:`ChamberParams`; the defaults were
chosen once for physical plausibility (heating at 100 % settles ~4-5 degC above ambient with the fan
at 30 %; time constants of minutes) and are *not* tuned to make any filter look good.

Scenarios (§5.2, §5.3): :func:`heating_cooling` and :func:`heating_normal` return a
:class:`ChamberRun` with the 1 s log (time_s, y, u1, u2, t_out, mode) and the true sensor-site air
temperature ``truth`` of the sensor element (unquantised; for errors against the truth -- a real
log has none) and the bulk air temperature ``air``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import NumericalError

RESOLUTION = 0.0625          # DS18B20 12-bit resolution, degC
FAN_MIN, FAN_MAX = 30.0, 100.0
BASE_TEMPERATURE = 19.875    # cooling target of §5.2, degC


@dataclass(frozen=True)
class ChamberParams:
    """Plant parameters (SI: J/K, W/K, W, s, degC)."""

    ambient: float = 19.5            # mean room temperature
    drift_amp: float = 0.08          # slow sinusoidal room drift amplitude
    drift_period: float = 5400.0     # s
    drift_ou_sigma: float = 0.03     # stationary std of the OU part of the room drift
    drift_ou_tau: float = 900.0      # s
    p_max: float = 2.6               # heat from the LED at u1 = 100 %
    heater_exp: float = 1.1          # P = p_max (u1/100)^heater_exp
    c_heater: float = 25.0           # LED + heatsink
    c_hot: float = 4.0               # hot air zone (+ nearby parts)
    c_bulk: float = 8.0              # bulk air + sensor surroundings
    c_wall: float = 260.0            # ABS/steel case
    g_heater: float = 0.35           # heater -> hot zone
    g_mix0: float = 0.04             # hot zone <-> bulk, fan off
    g_mix1: float = 0.6              # extra mixing at fan 100 %
    g_hot_wall: float = 0.08
    g_bulk_wall0: float = 0.25       # bulk -> wall, natural
    g_bulk_wall1: float = 0.45       # extra forced convection at fan 100 %
    g_vent0: float = 0.02            # leakage to the room
    g_vent1: float = 0.9             # ventilation with room air at fan 100 %
    g_wall_room: float = 0.35        # natural convection outside at dT = 0
    g_wall_room_nl: float = 0.06     # relative increase per degC of wall-room difference
    fan_heat: float = 0.04           # W at fan 100 %
    tau_sensor: float = 8.0          # DS18B20 (TO-92) thermal lag, s
    sensor_noise: float = 0.01       # analogue noise before quantisation, degC std
    resolution: float = RESOLUTION
    dt: float = 0.1                  # integration step, s
    ts: float = 1.0                  # sensor read period, s


@dataclass
class ChamberRun:
    """A simulated experiment sampled every ``ts`` seconds."""

    time_s: np.ndarray
    y: np.ndarray              # quantised indoor measurement
    u1: np.ndarray
    u2: np.ndarray
    t_out: np.ndarray          # quantised outdoor measurement
    mode: np.ndarray           # 1 heating, 0 cooling/normal (the jump system's mode)
    truth: np.ndarray          # true temperature of the sensor element (what y measures, unquantised)
    air: np.ndarray            # bulk air temperature around the sensor (no sensor lag)
    ambient: np.ndarray        # true room temperature
    info: dict = field(default_factory=dict)

    def frame(self):
        """The log as a DataFrame with the columns of :mod:`pfbench.plants.datalog`."""
        import pandas as pd

        return pd.DataFrame({"time_s": self.time_s, "y": self.y, "u1": self.u1, "u2": self.u2,
                             "t_out": self.t_out, "mode": self.mode})

    def columns(self) -> dict:
        return {"time_s": self.time_s, "y": self.y, "u1": self.u1, "u2": self.u2,
                "t_out": self.t_out, "mode": self.mode}


def quantise(t, resolution: float = RESOLUTION):
    """DS18B20 reading: nearest multiple of the resolution (0.0625 degC)."""
    return np.round(np.asarray(t, dtype=np.float64) / resolution) * resolution


def clip_inputs(u1: float, u2: float) -> tuple[float, float]:
    """Hardware ranges: heater 0-100 %, fan 30-100 % (§3, §5.2)."""
    return float(min(max(u1, 0.0), 100.0)), float(min(max(u2, FAN_MIN), FAN_MAX))


class Chamber:
    """The plant. ``state`` = (T_heater, T_hot, T_bulk, T_wall, T_sensor), degC."""

    def __init__(self, params: ChamberParams | None = None, seed: int = 0, **overrides):
        self.p = replace(params or ChamberParams(), **overrides)
        self.rng = np.random.default_rng(seed)
        self.t = 0.0
        self._ou = 0.0
        self._phase = float(self.rng.uniform(0.0, 2.0 * np.pi))
        self.state = self.steady_state(0.0, FAN_MIN, self.p.ambient)

    # ----- physics ---------------------------------------------------------------------
    def _deriv(self, s, u1, u2, t_room):
        p = self.p
        th, tz, tb, tw, tsn = s
        f = u2 / 100.0
        g_mix = p.g_mix0 + p.g_mix1 * f
        g_bw = p.g_bulk_wall0 + p.g_bulk_wall1 * f
        g_vent = p.g_vent0 + p.g_vent1 * f
        g_wr = p.g_wall_room * (1.0 + p.g_wall_room_nl * abs(tw - t_room))
        q_hz = p.g_heater * (th - tz)
        q_zb = g_mix * (tz - tb)
        q_zw = p.g_hot_wall * (tz - tw)
        q_bw = g_bw * (tb - tw)
        return np.array([
            (p.p_max * (u1 / 100.0) ** p.heater_exp - q_hz) / p.c_heater,
            (q_hz - q_zb - q_zw) / p.c_hot,
            (q_zb - q_bw - g_vent * (tb - t_room) + p.fan_heat * f) / p.c_bulk,
            (q_bw + q_zw - g_wr * (tw - t_room)) / p.c_wall,
            (tb - tsn) / p.tau_sensor,
        ])

    def steady_state(self, u1: float, u2: float, t_room: float) -> np.ndarray:
        """Equilibrium state for constant inputs and room temperature (damped fixed-point RK4)."""
        u1, u2 = clip_inputs(u1, u2)
        s = np.full(5, float(t_room))
        h = 2.0   # pseudo-time step, s: stable for the stiffest node (c_hot / conductances)
        for _ in range(200000):
            k = self._rk4(s, u1, u2, t_room, h)
            if np.max(np.abs(k - s)) < 1e-10:
                return k
            s = k
        raise NumericalError("chamber steady state did not converge")  # pragma: no cover

    def _rk4(self, s, u1, u2, t_room, h):
        k1 = self._deriv(s, u1, u2, t_room)
        k2 = self._deriv(s + 0.5 * h * k1, u1, u2, t_room)
        k3 = self._deriv(s + 0.5 * h * k2, u1, u2, t_room)
        k4 = self._deriv(s + h * k3, u1, u2, t_room)
        return s + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)

    def room(self) -> float:
        p = self.p
        return p.ambient + p.drift_amp * np.sin(2 * np.pi * self.t / p.drift_period + self._phase) + self._ou

    def advance(self, u1: float, u2: float, duration: float) -> None:
        """Integrate ``duration`` seconds with constant (clipped) inputs."""
        u1, u2 = clip_inputs(u1, u2)
        p = self.p
        n = int(round(duration / p.dt))
        a = np.exp(-p.dt / p.drift_ou_tau)
        b = p.drift_ou_sigma * np.sqrt(1.0 - a * a)
        for _ in range(n):
            self.state = self._rk4(self.state, u1, u2, self.room(), p.dt)
            self._ou = a * self._ou + b * self.rng.standard_normal()
            self.t += p.dt

    def read(self) -> tuple[float, float]:
        """(indoor, outdoor) DS18B20 readings now: lagged sensor + noise, quantised."""
        p = self.p
        z = self.rng.standard_normal(2) * p.sensor_noise
        return (float(quantise(self.state[4] + z[0], p.resolution)),
                float(quantise(self.room() + z[1], p.resolution)))

    def steady_gain(self, u1: float = 100.0, u2: float = FAN_MIN) -> float:
        """Steady-state sensor temperature rise above the room for constant inputs, degC."""
        return float(self.steady_state(u1, u2, self.p.ambient)[4] - self.p.ambient)


def _run(chamber: Chamber, controller, n_max: int, stop=None) -> ChamberRun:
    """Sample-and-hold loop at ts: read, decide inputs (controller(k, y) -> u1, u2, mode), hold."""
    p = chamber.p
    rows = []
    for k in range(n_max):
        y, t_out = chamber.read()
        truth, room = float(chamber.state[4]), chamber.room()
        u1, u2, mode = controller(k, y)
        u1, u2 = clip_inputs(u1, u2)
        rows.append((k * p.ts, y, u1, u2, t_out, mode, truth, room, float(chamber.state[2])))
        if stop is not None and stop(k, y):
            break
        chamber.advance(u1, u2, p.ts)
    a = np.array(rows, dtype=np.float64)
    return ChamberRun(time_s=a[:, 0], y=a[:, 1], u1=a[:, 2], u2=a[:, 3], t_out=a[:, 4],
                      mode=a[:, 5], truth=a[:, 6], ambient=a[:, 7], air=a[:, 8])


def mixing_bump(run: "ChamberRun", window_s: int = 60) -> dict:
    """Rise of the temperature above its value at the heating->cooling switch within ``window_s``
    samples after it (the §5.2 "mixing bump"), in the bulk air (``air``), at the sensor element
    (``truth``) and in the quantised measurement (``y``); degC, 0 if it only falls."""
    k = run.info.get("k_switch")
    if k is None:
        return {"air": float("nan"), "sensor": float("nan"), "measured": float("nan")}
    sl = slice(k, k + int(window_s))
    return {name: float(np.max(v[sl]) - v[k]) for name, v in
            (("air", run.air), ("sensor", run.truth), ("measured", run.y))}


def heating_cooling(set_temp: float = 22.5, ambient: float = 19.5, seed: int = 0,
                    base: float = BASE_TEMPERATURE, max_s: int = 4000, tail_s: int = 0,
                    params: ChamberParams | None = None, **overrides) -> ChamberRun:
    """§5.2: heater 100 % (fan 30 %) until y >= set_temp, then heater 0 %, fan 100 % until
    y <= base (19.875 degC) -- or ``max_s`` seconds in all; ``tail_s`` extra cooling seconds."""
    ch = Chamber(params, seed=seed, ambient=ambient, **overrides)
    st = {"phase": "heat", "k_switch": None, "k_end": None}

    def controller(k, y):
        if st["phase"] == "heat" and y >= set_temp:
            st["phase"], st["k_switch"] = "cool", k
        if st["phase"] == "heat":
            return 100.0, FAN_MIN, 1.0
        return 0.0, FAN_MAX, 0.0

    def stop(k, y):
        if st["phase"] == "cool" and y <= base and st["k_end"] is None:
            st["k_end"] = k
        return st["k_end"] is not None and k >= st["k_end"] + tail_s

    run = _run(ch, controller, max_s, stop)
    run.info = {"scenario": "heating_cooling", "set_temp": set_temp, "ambient": ambient, "seed": seed,
                "base": base, "k_switch": st["k_switch"], "k_end": st["k_end"],
                "reached_base": st["k_end"] is not None}
    return run


def heating_normal(set_temp: float = 21.5, hysteresis: float = 0.52, u_high: float = 90.0,
                   u_low: float = 10.0, fan: float = FAN_MIN, duration_s: int = 1200,
                   ambient: float = 19.5, seed: int = 0, params: ChamberParams | None = None,
                   **overrides) -> ChamberRun:
    """§5.3: two-position control with hysteresis (width 0.52 degC around 21.5 degC), u1 90 % / 10 %,
    about 20 minutes; mode 1 (heating parameters) while u1 = u_high, else 0."""
    ch = Chamber(params, seed=seed, ambient=ambient, **overrides)
    st = {"on": True, "switches": 0}

    def controller(k, y):
        on = st["on"]
        if on and y >= set_temp + hysteresis / 2:
            on = False
        elif not on and y <= set_temp - hysteresis / 2:
            on = True
        if on != st["on"]:
            st["switches"] += 1
            st["on"] = on
        return (u_high, fan, 1.0) if on else (u_low, fan, 0.0)

    run = _run(ch, controller, int(duration_s))
    run.info = {"scenario": "heating_normal", "set_temp": set_temp, "hysteresis": hysteresis,
                "ambient": ambient, "seed": seed, "mode_switches": st["switches"]}
    return run
