"""The `particles` library (N. Chopin) as a contender: its SMC on any pfbench model, through a
Feynman-Kac class built from the model's own functions (the public model contract).

* ``bootstrap``: M_t = the model's transition, G_t = its likelihood; resampling every step
  (``ess_threshold`` < 1 makes it resample when ESS < ess_threshold N, as `particles` does).
* ``guided``: M_t = the model's proposal, G_t = its weight (``proposal_kind = "proposal"``:
  :meth:`proposal_log_weight`; ``"optimal"``: the predictive likelihood p(y_t | x_{t-1})), the
  state carried as [x_t, x_{t-1}] so that G_0 sees the prior draw; ESS threshold 0.5 by default.

Random numbers: the model's noise comes from ``numpy.random.default_rng(seed)``, the library's
resampling from NumPy's global generator seeded with ``seed``.

`particles` pins NumPy < 2, so where it does not import, pfbench runs this module out of process
(``python -m pfbench.compare.particles_adapter ALG OPTIONS_JSON``) with an interpreter that has
it: the ``cmd:`` protocol (one JSON object on stdin and one on stdout).
"""
from __future__ import annotations

import json
import sys
import time

import numpy as np


def _fk_class():
    import particles

    class PfbenchFK(particles.FeynmanKac):
        def __init__(self, model, y, u, guided, rng):
            super().__init__(T=y.shape[0])
            self.model, self.y, self.guided, self.rng = model, y, guided, rng
            self.u = model.input_array(u, y.shape[0])
            self.p = model.params()
            self.n_x = model.n_x
            kind = model.proposal_kind
            if guided and kind not in ("proposal", "optimal"):
                raise ValueError(f"model {model.name!r} has no proposal (proposal_kind is None)")
            self.kind = kind
            self.n_noise = (model.n_proposal_noise or model.n_noise) if guided else model.n_noise

        def _move(self, t, xp):
            m = self.model
            noise = self.rng.standard_normal((xp.shape[0], self.n_noise))
            if self.guided:
                x = m.proposal(xp, self.y[t], self.u[t], t, noise, self.p)
                return np.hstack((np.asarray(x, dtype=float), xp))
            return np.asarray(m.transition(xp, self.u[t], t, noise, self.p), dtype=float)

        def M0(self, N):
            x0 = np.asarray(self.model.initial(self.rng, N, self.p), dtype=float).reshape(N, self.n_x)
            return self._move(0, x0)

        def M(self, t, xp):
            return self._move(t, xp[:, : self.n_x] if self.guided else xp)

        def logG(self, t, xp, x):
            m, y, u, p = self.model, self.y[t], self.u[t], self.p
            if not self.guided:
                return m.log_likelihood(y, x, u, t, p)
            cur, prev = x[:, : self.n_x], x[:, self.n_x:]
            if self.kind == "optimal":
                return m.predictive_log_likelihood(y, prev, u, t, p)
            return m.proposal_log_weight(cur, prev, y, u, t, p)

    return PfbenchFK


def run_particles(model, y, u, alg: str = "bootstrap", *, n_particles: int, seed: int,
                  resampling: str = "systematic", ess_threshold: float | None = None) -> dict:
    """Run `particles`' SMC on ``model``; a mapping of the ``py:`` contract (plus ``elapsed_s``)."""
    import particles

    y = np.ascontiguousarray(y, dtype=float)
    rng = np.random.default_rng(seed)
    np.random.seed(int(seed) % 2 ** 32)
    fk = _fk_class()(model, y, u, alg == "guided", rng)
    ess = ess_threshold if ess_threshold is not None else (1.0 if alg == "bootstrap" else 0.5)
    smc = particles.SMC(fk=fk, N=int(n_particles), resampling=resampling, ESSrmin=ess,
                        store_history=False, collect="off", verbose=False)
    M, n_x = y.shape[0], model.n_x
    est, var = np.empty((M, n_x)), np.empty((M, n_x))
    t0 = time.perf_counter()
    for t in range(M):
        next(smc)
        W = smc.W
        x = smc.X[:, :n_x]
        mu = W @ x
        est[t], var[t] = mu, W @ (x - mu) ** 2
    elapsed = time.perf_counter() - t0
    return {"estimates": est, "variances": var, "loglik": float(smc.logLt), "elapsed_s": elapsed,
            "n_particles": int(n_particles)}


def main(argv=None) -> None:
    """The ``cmd:`` protocol: one request on stdin, one answer on stdout."""
    argv = sys.argv[1:] if argv is None else argv
    alg = argv[0] if argv else "bootstrap"
    options = json.loads(argv[1]) if len(argv) > 1 else {}
    req = json.loads(sys.stdin.read())
    from pfbench import models

    model = models.get(req["model"], **req["params"])
    y = np.asarray(req["y"], dtype=float).reshape(-1, model.n_y)
    u = None if req.get("u") is None else np.asarray(req["u"], dtype=float)
    if y.shape[0] > 1:  # the library's numba resampling compiles on first use: not in the timing
        run_particles(model, y[:2], None if u is None else u[:2], alg, n_particles=8, seed=0, **options)
    out = run_particles(model, y, u, alg, n_particles=req["n_particles"], seed=req["seed"], **options)
    out = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in out.items()}
    if not np.isfinite(out["loglik"]):
        out["loglik"] = None
    sys.stdout.write(json.dumps(out))


if __name__ == "__main__":
    main()
