"""Ob5: Inteco MLS2EM magnetic levitation, two electromagnets ([MultiPDF] §4, Fig. 2, Table 3).

Continuous model (vendor manual; parameters recovered in [Recovered])::

    dx1 = x2                                     x1: ball distance from the upper magnet (m, down +)
    dx2 = -Fem1/m + g + Fem2/m                   x2: velocity (m/s)
    dx3 = (ki u1 + ci - x3) / fi(x1)             x3: upper-coil current (A)
    dx4 = (ki u2 + ci - x4) / fi(xd - x1)        x4: lower-coil current (A)
    Fem1 = x3^2 (FemP1/FemP2) exp(-x1/FemP2),  Fem2 = x4^2 (FemP1/FemP2) exp(-(xd - x1)/FemP2)
    fi(z) = (fiP1/fiP2) exp(-z/fiP2)
    y1 = x1 + n1,  y2 = Fem1 + n2

Discretisation: Euler at T_s = 0.1 ms ([MultiPDF] §4), additive Gaussian process noise, then the
constraints of §4: 0 <= x1 <= xd, i_min = 0.03884 <= x3, x4 <= 2.38 (inputs are clipped to
[u_min, 1] = [0.00498, 1]).

Euler stability (README note). The mechanical part x1, x2 is an exact double integrator over
one step apart from the force, whose open-loop pole sqrt(g/FemP2) ~ 41 rad/s gives
T_s * 41 = 0.004 << 2: Euler is accurate there. Each coil is a first-order lag
x' = x + (T_s/fi) (target - x), stable iff T_s/fi < 2 (monotone iff T_s/fi <= 1). The upper coil
has T_s/fi(x1) <= 0.11 for x1 <= 16 mm (the manual's bound), but the lower coil's inductance
fi(xd - x1) is tiny while the ball is far from it: T_s/fi(xd - x1) >= 1 whenever
xd - x1 >= fiP2 ln(fiP1/(fiP2 T_s)) = 26.2 mm, i.e. at the 9 mm operating point (ratio ~1.5 for
xd = 37 mm) and up to ~10 near x1 = 0. We therefore use Euler with the step factor capped:
``a = min(T_s/fi, 1)`` -- plain Euler wherever it is monotone, and "the current reaches its
target within the step" where the coil's time constant is shorter than T_s (what exact
zero-order-hold integration gives up to exp(-T_s/fi) <= 0.37 of the last step's gap). The capped
map has |1 - a| < 1 everywhere, so the discrete coil dynamics are stable for every x1 in [0, xd].

Stabilising input. The levitated ball is open-loop unstable, so :meth:`Ob5.simulate` runs the
plant in closed loop: at every step the controller sees the *true* previous state and sets
``u1`` from a PD law on the position (desired force m (g + kp (x1 - r) + kd x2)), inverted
through Fem1 to a current set-point i*, plus a proportional current loop (gain ``kc``),
clipped to [u_min, 1]; ``u2`` is a constant bias (``u2``). The filter receives the resulting
``u`` as a known input, as with any input-driven model. :meth:`Ob5.inputs` returns the input
of the same controller on the noise-free trajectory (the open-loop replay of the nominal run).

Choices (the noise levels of Table 3 were lost in the extraction; all are parameters):
process noise std per step ``q_std`` = (1e-6 m, 1e-3 m/s, 1e-3 A, 1e-3 A); measurement noise
std ``r_std`` = (1e-4 m, 1e-2 N); xd = 0.037 m; reference r = 9 mm; prior x^(0) ~ N(x_eq, diag
``p0_std``^2) around the equilibrium at 9 mm (about 0.93 A in the upper coil).
"""
from __future__ import annotations

import numpy as np
from numba.extending import register_jitable

from . import register
from .base import StateSpaceModel, gaussian_loglik_diag

# Vendor constants ([Recovered])
M_BALL = 0.0571
G = 9.81
FEMP1 = 1.7521e-2
FEMP2 = 5.8231e-3
FIP1 = 1.4142e-4
FIP2 = 4.5626e-3
CI = 0.0243
KI = 2.5165
I_MIN = 0.03884
I_MAX = 2.38
U_MIN = 0.00498
U_MAX = 1.0
TS = 1e-4


def equilibrium_current(x1: float, m: float = M_BALL, g: float = G, fem2: float = 0.0) -> float:
    """Upper-coil current with Fem1 = m g + Fem2 at ball position x1 (A) (dx2 = 0)."""
    return float(np.sqrt((m * g + fem2) * FEMP2 / FEMP1 * np.exp(x1 / FEMP2)))


@register_jitable
def ob5_fem(i, z):
    """Electromagnet force i^2 (FemP1/FemP2) exp(-z/FemP2) (N)."""
    return i * i * (1.7521e-2 / 5.8231e-3) * np.exp(-z / 5.8231e-3)


@register_jitable
def ob5_coil_factor(z, ts):
    """Capped Euler factor min(T_s / fi(z), 1) of a coil at gap z (see the module docstring)."""
    fi = (1.4142e-4 / 4.5626e-3) * np.exp(-z / 4.5626e-3)
    return np.minimum(ts / fi, 1.0)


@register_jitable
def ob5_step(x, u, p, noise):
    """Euler step + noise + constraints for particles x (n, 4); noise (n, 4) standard normals."""
    ts = p[0]
    xd = p[1]
    m = p[2]
    g = p[3]
    qs = p[4]
    u1 = min(max(u[0], 0.00498), 1.0)
    u2 = min(max(u[1], 0.00498), 1.0)
    x1 = x[:, 0]
    x2 = x[:, 1]
    x3 = x[:, 2]
    x4 = x[:, 3]
    f1 = ob5_fem(x3, x1)
    f2 = ob5_fem(x4, xd - x1)
    out = np.empty_like(x)
    out[:, 0] = x1 + ts * x2 + qs[0] * noise[:, 0]
    out[:, 1] = x2 + ts * (g - f1 / m + f2 / m) + qs[1] * noise[:, 1]
    out[:, 2] = x3 + ob5_coil_factor(x1, ts) * (2.5165 * u1 + 0.0243 - x3) + qs[2] * noise[:, 2]
    out[:, 3] = x4 + ob5_coil_factor(xd - x1, ts) * (2.5165 * u2 + 0.0243 - x4) + qs[3] * noise[:, 3]
    out[:, 0] = np.minimum(np.maximum(out[:, 0], 0.0), xd)
    out[:, 2] = np.minimum(np.maximum(out[:, 2], 0.03884), 2.38)
    out[:, 3] = np.minimum(np.maximum(out[:, 3], 0.03884), 2.38)
    return out


@register_jitable
def ob5_h(x):
    """Noise-free outputs (n, 2): ball position x1 and upper-magnet force Fem1."""
    h = np.empty((x.shape[0], 2))
    h[:, 0] = x[:, 0]
    h[:, 1] = ob5_fem(x[:, 2], x[:, 0])
    return h


@register("ob5")
class Ob5(StateSpaceModel):
    """MLS2EM magnetic levitation ([MultiPDF] Ob5); see the module docstring for every choice."""

    n_x, n_y, n_u, n_noise = 4, 2, 2, 4
    state_names = ("x1", "x2", "x3", "x4")

    def __init__(self, xd: float = 0.037, ts: float = TS, q_std=(1e-6, 1e-3, 1e-3, 1e-3),
                 r_std=(1e-4, 1e-2), x1_ref: float = 0.009, p0_std=(1e-4, 1e-3, 1e-2, 1e-2),
                 u2: float = 0.2, kp: float = 900.0, kd: float = 60.0, kc: float = 5.0,
                 m: float = M_BALL, g: float = G):
        if not 0.0 < x1_ref < xd:
            raise ValueError("x1_ref must lie in (0, xd)")
        self.xd, self.ts, self.m, self.g = float(xd), float(ts), float(m), float(g)
        self.q_std = np.asarray(q_std, dtype=np.float64).reshape(4)
        self.r_std = np.asarray(r_std, dtype=np.float64).reshape(2)
        self.p0_std = np.asarray(p0_std, dtype=np.float64).reshape(4)
        if np.any(self.q_std < 0) or np.any(self.p0_std < 0) or np.any(self.r_std <= 0):
            raise ValueError("standard deviations must be >= 0 (r_std > 0)")
        self.x1_ref, self.u2 = float(x1_ref), float(np.clip(u2, U_MIN, U_MAX))
        self.kp, self.kd, self.kc = float(kp), float(kd), float(kc)
        x4 = float(np.clip(KI * self.u2 + CI, I_MIN, I_MAX))
        fem2 = float(ob5_fem(x4, self.xd - self.x1_ref))
        self.x_eq = np.array([self.x1_ref, 0.0, equilibrium_current(self.x1_ref, m, g, fem2), x4])

    def params(self):
        return (self.ts, self.xd, self.m, self.g, self.q_std, self.r_std ** 2, self.x_eq,
                self.p0_std)

    # ----- the four model functions --------------------------------------------------
    @staticmethod
    def initial(rng, n, p):
        x = p[6] + rng.standard_normal((n, 4)) * p[7]
        x[:, 0] = np.minimum(np.maximum(x[:, 0], 0.0), p[1])
        x[:, 2] = np.minimum(np.maximum(x[:, 2], 0.03884), 2.38)
        x[:, 3] = np.minimum(np.maximum(x[:, 3], 0.03884), 2.38)
        return x

    @staticmethod
    def transition(x, u, t, noise, p):
        return ob5_step(x, u, p, noise)

    @staticmethod
    def log_likelihood(y, x, u, t, p):
        return gaussian_loglik_diag(y - ob5_h(x), p[5])

    @staticmethod
    def observe(x, u, t, noise, p):
        return ob5_h(x) + np.sqrt(p[5]) * noise

    # ----- linear-Gaussian structure (method="mpf") -------------------------------------
    #: the velocity x2 enters every equation linearly and no measurement: x^l = x2, and
    #: x^n = (x1, x3, x4) are the particles ([MultiPDF] §5: "one linear and three nonlinear")
    linear_states = (1,)

    @staticmethod
    def cl_transition(xn, u, t, p):
        """The Euler step of :func:`ob5_step` split as f^n + A^n x2 and f^l + A^l x2, x^n = (x1, x3, x4)."""
        ts = p[0]
        xd = p[1]
        n = xn.shape[0]
        u1 = min(max(u[0], 0.00498), 1.0)
        u2 = min(max(u[1], 0.00498), 1.0)
        x1 = xn[:, 0]
        fn = xn.copy()
        fn[:, 1] = xn[:, 1] + ob5_coil_factor(x1, ts) * (2.5165 * u1 + 0.0243 - xn[:, 1])
        fn[:, 2] = xn[:, 2] + ob5_coil_factor(xd - x1, ts) * (2.5165 * u2 + 0.0243 - xn[:, 2])
        An = np.zeros((n, 3, 1))
        An[:, 0, 0] = ts
        fl = np.empty((n, 1))
        fl[:, 0] = ts * (p[3] - ob5_fem(xn[:, 1], x1) / p[2] + ob5_fem(xn[:, 2], xd - x1) / p[2])
        return fn, An, fl, np.ones((n, 1, 1))

    @staticmethod
    def cl_observation(xn, xl, u, t, p):
        """y = (x1, Fem1(x3, x1)) does not depend on x2: C = 0."""
        h = np.empty((xn.shape[0], 2))
        h[:, 0] = xn[:, 0]
        h[:, 1] = ob5_fem(xn[:, 1], xn[:, 0])
        return h, np.zeros((xn.shape[0], 2, 1))

    @staticmethod
    def cl_constrain(xn, p):
        """The §4 constraints of :func:`ob5_step` on (x1, x3, x4); x2 is not constrained."""
        out = xn.copy()
        out[:, 0] = np.minimum(np.maximum(xn[:, 0], 0.0), p[1])
        out[:, 1] = np.minimum(np.maximum(xn[:, 1], 0.03884), 2.38)
        out[:, 2] = np.minimum(np.maximum(xn[:, 2], 0.03884), 2.38)
        return out

    def cl_noise(self):
        return np.diag(self.q_std ** 2), np.diag(self.r_std ** 2)

    def cl_prior(self):
        return self.x_eq[[1]].copy(), np.array([[self.p0_std[1] ** 2]])

    # ----- stabilising controller ------------------------------------------------------
    def control(self, x: np.ndarray) -> np.ndarray:
        """u = (u1, u2) from the state x (4,): PD force law -> current set-point -> coil loop."""
        x1, x2, x3, x4 = (float(v) for v in x)
        fem2 = float(ob5_fem(x4, self.xd - x1))
        f_des = self.m * (self.g + self.kp * (x1 - self.x1_ref) + self.kd * x2) + fem2
        f_des = max(f_des, 0.0)
        i_des = float(np.sqrt(f_des * FEMP2 / FEMP1 * np.exp(x1 / FEMP2)))
        target = i_des + self.kc * (i_des - x3)
        u1 = (target - CI) / KI
        return np.array([min(max(u1, U_MIN), U_MAX), self.u2])

    def inputs(self, rng, n_steps):
        """Inputs of the controller on the noise-free closed-loop run from x_eq."""
        p = self.params()
        x = self.x_eq.reshape(1, 4).copy()
        u = np.empty((n_steps, 2))
        zero = np.zeros((1, 4))
        for t in range(n_steps):
            u[t] = self.control(x[0])
            x = ob5_step(x, u[t], p, zero)
        return u

    def simulate(self, n_steps: int, seed=0):
        """Closed-loop simulation (true-state feedback); draw order: x^(0), then per step the
        transition noise (4) and the measurement noise (2)."""
        from .base import Trajectory

        if int(n_steps) < 1:
            raise ValueError("n_steps must be >= 1")
        n_steps = int(n_steps)
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        p = self.params()
        x = self.initial(rng, 1, p)
        x0 = x[0].copy()
        xs, ys, us = np.empty((n_steps, 4)), np.empty((n_steps, 2)), np.empty((n_steps, 2))
        for t in range(n_steps):
            us[t] = self.control(x[0])
            x = ob5_step(x, us[t], p, rng.standard_normal((1, 4)))
            ys[t] = self.observe(x, us[t], t, rng.standard_normal((1, 2)), p)[0]
            xs[t] = x[0]
        return Trajectory(x=xs, y=ys, u=us, x0=x0)
