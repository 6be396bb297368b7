"""The state-space model base class shared by both backends.

A model is written **once**, as four vectorised NumPy functions over a block of particles.
The NumPy backend calls them as they are; the numba backend compiles the very same functions
with ``numba.njit`` (array expressions are fused into one loop, so they run as fast as
hand-written loops). What a model needs for numba:

* the four functions are ``@staticmethod`` s using only NumPy features numba supports
  (arithmetic, ``np.cos``/``np.exp``/..., slicing, ``np.empty``/``np.zeros``, loops, ``@``);
* every model parameter travels in the tuple returned by :meth:`StateSpaceModel.params`
  (float scalars and float64 arrays; ints for switches), never through ``self``;
* no Python objects, dicts or exceptions inside the functions;
* helper functions they call are decorated with ``numba.extending.register_jitable``
  (plain Python under NumPy, compiled under numba), like :func:`gaussian_loglik_diag`.

Time-index convention (0-based ``t = 0..M-1`` for arrays; paper step ``k = t + 1``)::

    x_{-1} ~ initial(...)                         # the prior p(x^(0))
    x_t    = transition(x_{t-1}, u[t], t, v_t)    # x^(k) = f(x^(k-1), u^(k-1), k-1) + v
    y_t    ~ p(y | x_t)  via log_likelihood(y[t], x_t, u[t], t)
    y_t    = observe(x_t, u[t], t, n_t)           # simulation only

so a model whose paper equation reads ``x^(k+1) = f(x^(k), k)`` uses ``t`` for ``k``.

Minimal custom model (runs on both backends)::

    import numpy as np
    from pfbench.models import StateSpaceModel, register

    @register("growth")
    class Growth(StateSpaceModel):
        n_x, n_y, n_noise = 1, 1, 1
        def __init__(self, q=10.0, r=1.0):
            self.q, self.r = q, r
        def params(self):
            return (self.q, self.r)
        @staticmethod
        def initial(rng, n, p):
            return 0.1 + np.zeros((n, 1))
        @staticmethod
        def transition(x, u, t, noise, p):
            return 0.5 * x + 25 * x / (1 + x * x) + 8 * np.cos(1.2 * t) + np.sqrt(p[0]) * noise
        @staticmethod
        def log_likelihood(y, x, u, t, p):
            r = y[0] - x[:, 0] ** 2 / 20
            return -0.5 * r * r / p[1] - 0.5 * np.log(2 * np.pi * p[1])
        @staticmethod
        def observe(x, u, t, noise, p):
            return x ** 2 / 20 + np.sqrt(p[1]) * noise
"""
from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np
from numba.extending import register_jitable

from ..errors import InputError, ModelError

LOG_2PI = float(np.log(2.0 * np.pi))


@dataclass(frozen=True)
class Trajectory:
    """A simulated (or loaded) trajectory.

    Attributes
    ----------
    x : (n_steps, n_x) true states x_t, t = 0..M-1 (paper k = 1..M); NaN if unknown (real logs).
    y : (n_steps, n_y) measurements.
    u : (n_steps, n_u) inputs, or None for autonomous models.
    x0 : (n_x,) the initial state x^(0) the simulation started from.
    """

    x: np.ndarray
    y: np.ndarray
    u: np.ndarray | None
    x0: np.ndarray | None = None

    @property
    def n_steps(self) -> int:
        return int(self.y.shape[0])


class StateSpaceModel:
    """Base class of every model (see the module docstring for the contract).

    Class attributes
    ----------------
    name : registry name (set by :func:`pfbench.models.register`).
    n_x : state dimension.
    n_y : measurement dimension.
    n_u : input dimension (0 for autonomous models).
    n_noise : number of standard-normal draws per particle and step that ``transition`` takes.
    n_obs_noise : number of standard-normal draws per step that ``observe`` takes (default n_y).
    """

    name: str = ""
    n_x: int = 1
    n_y: int = 1
    n_u: int = 0
    n_noise: int = 1
    n_obs_noise: int | None = None
    #: names of the state components, for tables and plots
    state_names: tuple[str, ...] | None = None

    # ----- the model, as vectorised functions ------------------------------------------
    def params(self) -> tuple:
        """Parameters as a numba-friendly tuple (floats, ints, float64 arrays)."""
        return ()

    @staticmethod
    def initial(rng, n, p):  # pragma: no cover - abstract
        """Draw ``n`` particles from the prior p(x^(0)); returns (n, n_x)."""
        raise NotImplementedError

    @staticmethod
    def transition(x, u, t, noise, p):  # pragma: no cover - abstract
        """Propagate particles ``x`` (n, n_x) with standard-normal ``noise`` (n, n_noise)."""
        raise NotImplementedError

    @staticmethod
    def log_likelihood(y, x, u, t, p):  # pragma: no cover - abstract
        """log p(y_t | x_t) for each particle; returns (n,)."""
        raise NotImplementedError

    @staticmethod
    def observe(x, u, t, noise, p):  # pragma: no cover - abstract
        """Measurement y_t = h(x_t) + noise for simulation; returns (n, n_y)."""
        raise NotImplementedError

    # ----- optional structure: conditionally linear-Gaussian substructure (method="mpf") ------
    #: Indices of the states x^l that form a conditionally linear-Gaussian substructure
    #: ([Schon2005] eq. 3); the other states, in increasing index order, are x^n (the particles).
    #: None: no structure declared. A model that sets it (as a class or instance attribute)
    #: implements :meth:`cl_transition`, :meth:`cl_observation`, :meth:`cl_noise` and
    #: :meth:`cl_prior` (and may override :meth:`cl_constrain`); ``pfbench.run_filter(...,
    #: method="mpf")`` then runs the marginalized PF of :mod:`pfbench.filters.marginalized`, and
    #: ``method="kalman"`` the same recursion when every state is in x^l. The model in full::
    #:
    #:     x^n_t = f^n(x^n_{t-1}) + A^n(x^n_{t-1}) x^l_{t-1} + w^n
    #:     x^l_t = f^l(x^n_{t-1}) + A^l(x^n_{t-1}) x^l_{t-1} + w^l,   (w^n, w^l) ~ N(0, Q)
    #:     y_t   = h(x^n_t, x^l_t) + e,                               e ~ N(0, R)
    #:
    #: The ``cl_*`` staticmethods follow the rules of the four model functions (vectorised over
    #: particles, parameters in ``p``, numba-compilable); the numba backend compiles them. They
    #: must describe the model of ``transition`` and ``observe``: methods mpf and kalman check
    #: that on a probe block (:func:`pfbench.filters.marginalized.check_agreement`).
    linear_states: tuple[int, ...] | None = None

    @staticmethod
    def cl_transition(xn, u, t, p):  # pragma: no cover - optional
        """The transition given x^n_{t-1} = ``xn`` (n, d_n) ([Schon2005] eq. 3a-3b)::

            x^n_t = f^n + A^n x^l_{t-1} + w^n,   x^l_t = f^l + A^l x^l_{t-1} + w^l

        Returns (f^n (n, d_n), A^n (n, d_n, d_l), f^l (n, d_l), A^l (n, d_l, d_l)), one matrix per
        particle (they may depend on x^n_{t-1}, ``u`` = u[t] and ``t``). With d_n = 0, ``xn`` is
        (n, 0) and f^n, A^n are empty arrays of those shapes.
        """
        raise NotImplementedError

    @staticmethod
    def cl_observation(xn, xl, u, t, p):  # pragma: no cover - optional
        """The measurement linearised in x^l at ``xl`` (n, d_l): y_t = h + C (x^l_t - xl) + e.

        Returns (h (n, n_y), C (n, n_y, d_l)) with h = h(x^n_t, xl) and C = dh/dx^l at ``xl``. The
        filter calls it at the predicted mean of x^l (an EKF linearisation, as the MPF of
        [MultiPDF] §5); it is exact, and C independent of ``xl``, when y is linear in x^l
        (h = h(x^n) + C(x^n) xl, [Schon2005] eq. 3c). A model without an analytic Jacobian can
        build C column by column with :func:`central_difference_points`.
        """
        raise NotImplementedError

    @staticmethod
    def cl_constrain(xn, p):
        """Optional hard constraints on freshly sampled x^n_t (n, d_n); returns the constrained
        array (default: unchanged). The filter applies them after the Kalman time update has used
        the unconstrained draw and before the measurement update."""
        return xn

    def cl_noise(self):  # pragma: no cover - optional
        """(Q (n_x, n_x), R (n_y, n_y)): covariances of (w^n, w^l) in full-state order and of e.

        Q^n (the x^n block) must be positive definite when d_n > 0; a cross-covariance between
        w^n and w^l is allowed (the filter decorrelates it, as [Schon2005] does). R may be full
        (positive definite): the filter whitens the measurement with its Cholesky factor.
        """
        raise NotImplementedError

    def cl_prior(self):  # pragma: no cover - optional
        """(m0 (d_l,), P0 (d_l, d_l)): Gaussian prior of x^l, independent of x^n; x^n starts from
        the x^n columns of :meth:`initial` (not drawn when d_n = 0)."""
        raise NotImplementedError

    # ----- optional structure: a proposal (method="guided") ---------------------------
    #: How the model helps ``method="guided"`` (:mod:`pfbench.filters.guided`):
    #:
    #: * None: not supported (UnsupportedError);
    #: * ``"proposal"``: the model's own importance density q(x_t | x_{t-1}, y_t), sampled by
    #:   :meth:`proposal` and weighted by :meth:`proposal_log_weight`; per step the filter proposes,
    #:   weights, estimates, then resamples if N_eff is low;
    #: * ``"optimal"``: the locally optimal proposal p(x_t | x_{t-1}, y_t) ([Doucet2000]), sampled by
    #:   :meth:`proposal`, whose weight p(y_t | x_{t-1}) is :meth:`predictive_log_likelihood`; per
    #:   step the filter weights, resamples if N_eff is low, then proposes (fully adapted).
    #:
    #: The functions follow the rules of the four model functions (vectorised over particles,
    #: parameters in ``p``, numba-compilable) and the time convention above (``y``, ``u`` are
    #: ``y[t]``, ``u[t]``; ``x_prev`` is x_{t-1}). Models with additive Gaussian transition noise
    #: and a linear-Gaussian observation can build both ``"optimal"`` functions from
    #: :func:`pfbench.filters.guided.optimal_gaussian_proposal` and
    #: :func:`~pfbench.filters.guided.optimal_gaussian_log_predictive` (as ``pmsm`` does).
    proposal_kind: str | None = None
    #: standard normals per particle and step that :meth:`proposal` takes (None: ``n_noise``)
    n_proposal_noise: int | None = None

    @staticmethod
    def proposal(x_prev, y, u, t, noise, p):  # pragma: no cover - optional
        """Draw x_t ~ q(x_t | x_{t-1} = ``x_prev``, y_t) (n, n_x) with standard normals ``noise``
        (n, n_proposal_noise); for ``proposal_kind = "optimal"`` q is p(x_t | x_{t-1}, y_t)."""
        raise NotImplementedError

    @staticmethod
    def proposal_log_weight(x, x_prev, y, u, t, p):  # pragma: no cover - optional
        """Incremental log-weight of proposed particles ``x`` = x_t from ``x_prev`` = x_{t-1},
        log p(y_t | x_t) + log p(x_t | x_{t-1}) - log q(x_t | x_{t-1}, y_t); (n,). Constants may
        not be dropped: the weights also estimate the likelihood p(y_t | y_1:t-1)."""
        raise NotImplementedError

    @staticmethod
    def predictive_log_likelihood(y, x_prev, u, t, p):  # pragma: no cover - optional
        """log p(y_t | x_{t-1}) per particle of ``x_prev`` (the weight of the locally optimal
        proposal, normalised in y_t); (n,)."""
        raise NotImplementedError

    # ----- non-kernel helpers ----------------------------------------------------------
    def inputs(self, rng: np.random.Generator, n_steps: int) -> np.ndarray | None:
        """Input sequence for a simulation (n_steps, n_u); None for autonomous models."""
        return None

    @property
    def obs_noise_dim(self) -> int:
        return self.n_y if self.n_obs_noise is None else self.n_obs_noise

    def simulate(self, n_steps: int, seed: int | np.random.Generator | None = 0) -> Trajectory:
        """Simulate ``n_steps`` steps of the model with ``numpy.random.default_rng(seed)``.

        Draw order: inputs (if any), x^(0) from the prior, then per step the transition
        noise (n_noise) and the measurement noise (n_obs_noise).
        """
        import numbers

        if isinstance(n_steps, bool) or not isinstance(n_steps, numbers.Integral) or n_steps < 1:
            raise InputError(f"n_steps must be an integer >= 1, got {n_steps!r}")  # 2.7 ran 2 steps
        n_steps = int(n_steps)
        try:
            rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        except (TypeError, ValueError):
            raise InputError(f"seed must be a non-negative integer (or a sequence of them), a "
                             f"numpy.random.Generator or None, got {seed!r}") from None
        u = self.inputs(rng, n_steps)
        u_arr = self.input_array(u, n_steps)
        from .contract import check_model, named_model_errors, shaped   # a mistake reads as one line

        check_model(self, np.zeros((1, self.n_y)), u_arr[:1],
                    {fn: "simulate()" for fn in ("initial", "transition", "observe")})
        p = self.params()
        n_x, n_y = self.n_x, self.n_y
        with named_model_errors(self, None, None, "numpy"):   # and at a later step too
            x = shaped(self, "initial", self.initial(rng, 1, p), (1, n_x), "for one particle")
            x0 = x[0].copy()
            xs = np.empty((n_steps, n_x))
            ys = np.empty((n_steps, n_y))
            for t in range(n_steps):
                v = rng.standard_normal((1, self.n_noise))
                x = shaped(self, "transition", self.transition(x, u_arr[t], t, v, p), (1, n_x), f"at step {t}")
                n = rng.standard_normal((1, self.obs_noise_dim))
                ys[t] = shaped(self, "observe", self.observe(x, u_arr[t], t, n, p), (1, n_y), f"at step {t}")[0]
                xs[t] = x[0]
        _check_simulated(self, x0, xs, ys)
        return Trajectory(x=xs, y=ys, u=u, x0=x0)

    def input_array(self, u, n_steps: int) -> np.ndarray:
        """Inputs as a C-contiguous float64 (n_steps, n_u) array (n_u may be 0)."""
        if u is None:
            if self.n_u:
                from .contract import name_of

                raise InputError(f"model {name_of(self)!r} needs inputs u of shape (n_steps, {self.n_u})")
            return np.zeros((n_steps, 0))
        u = np.ascontiguousarray(u, dtype=np.float64)
        if not self.n_u and u.size:
            from .contract import name_of

            raise InputError(f"model {name_of(self)!r} takes no inputs: pass u=None")
        if u.ndim == 1:
            u = u.reshape(-1, 1)
        if u.shape != (n_steps, self.n_u):
            raise InputError(f"inputs u must have shape ({n_steps}, {self.n_u}), got {u.shape}")
        return u

    def kernel_functions(self) -> dict:
        """The four model functions, as plain Python functions (for backends and tracing)."""
        cls = type(self)
        return {name: inspect.getattr_static(cls, name).__func__
                for name in ("initial", "transition", "log_likelihood", "observe")}

    def describe(self) -> dict:
        return {"name": self.name, "n_x": self.n_x, "n_y": self.n_y, "n_u": self.n_u,
                "n_noise": self.n_noise}

    def __repr__(self) -> str:
        return f"<model {self.name or type(self).__name__}: n_x={self.n_x}, n_y={self.n_y}, n_u={self.n_u}>"


@register_jitable
def central_difference_points(xl, a):
    """(xl + eps e_a, xl - eps e_a, 2 eps) with eps = 1e-6 max(1, |xl[:, a]|) per particle: the
    points of a central-difference Jacobian column C[:, :, a] = (h(x+) - h(x-)) / (2 eps), for a
    :meth:`StateSpaceModel.cl_observation` whose measurement is nonlinear in x^l."""
    eps = 1e-6 * np.maximum(1.0, np.abs(xl[:, a]))
    xp = xl.copy()
    xm = xl.copy()
    xp[:, a] += eps
    xm[:, a] -= eps
    return xp, xm, 2.0 * eps


@register_jitable
def difference_column(C, a, hp, hm, two_eps):
    """C[:, :, a] = (h(x+) - h(x-)) / (2 eps), the column of :func:`central_difference_points`."""
    for k in range(C.shape[1]):
        C[:, k, a] = (hp[:, k] - hm[:, k]) / two_eps


@register_jitable
def scaled_identities(n, d, scale):
    """n copies of scale * I_d, (n, d, d): a per-particle A^l = scale I for :meth:`cl_transition`."""
    out = np.zeros((n, d, d))
    for i in range(d):
        out[:, i, i] = scale
    return out


@register_jitable
def gaussian_loglik_diag(resid, var):
    """Sum over columns of log N(resid; 0, var) for resid (n, m) and var (m,).

    ``register_jitable``: a plain Python function when called from Python (the NumPy backend,
    operation counting), compiled when called from a numba kernel. Model helpers should use it.
    """
    out = np.zeros(resid.shape[0])
    for j in range(resid.shape[1]):
        r = resid[:, j]
        out += -0.5 * r * r / var[j] - 0.5 * (LOG_2PI + np.log(var[j]))
    return out


def _check_simulated(model, x0, xs, ys) -> None:
    """A simulation with a NaN or infinite state or measurement is the model's error, named here
    (a filter run would otherwise refuse the measurements as if they were a user's bad data)."""
    from .contract import name_of

    if not np.isfinite(x0).all():
        what, value = "initial() drew a non-finite state", x0
    else:
        steps = [(int(np.flatnonzero(~np.isfinite(a).all(axis=1))[0]), i) for i, a in enumerate((xs, ys))
                 if not np.isfinite(a).all()]
        if not steps:
            return
        t, i = min(steps)
        what = f"{('transition()', 'observe()')[i]} gave a non-finite {('state', 'measurement')[i]} at step {t}"
        value = (xs, ys)[i][t]
    raise ModelError(f"model {name_of(model)!r}: simulate(): {what} ({value.tolist()}); "
                     "check the model and its parameters")
