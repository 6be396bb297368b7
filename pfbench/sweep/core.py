"""Monte Carlo sweeps: specification, deterministic seeds, and the work of one chunk.

A sweep runs every configuration (method, N_p, N_f) on ``runs`` independently simulated
trajectories of one model and records the aRMSE of each (configuration, run) task
([MultiPDF] eqs. 11-13).

Seeds (numpy ``SeedSequence`` with spawn keys, derived from one root ``seed``):

* trajectory of run r: ``SeedSequence(seed, spawn_key=(0, r))`` -- the same ground truth for
  every configuration (common random numbers across configurations, which makes the
  N_p / N_f comparisons sharper; the paper also draws a new truth per run);
* filter of configuration c on run r: ``SeedSequence(seed, spawn_key=(1, method, N_p, N_f, r))``.

So a task's result depends only on (spec, c, r): not on the worker count, the executor, the
order of completion or on interruptions.

Work unit ("chunk"): one run r and a list of configurations; the trajectory is simulated once
and every configuration is filtered on it (batched inside one worker call, which amortises
the Python overhead; the filters themselves are the compiled numba kernels, called directly
without :func:`pfbench.run_filter`'s thread pool but with exactly its streams and arithmetic).
"""
from __future__ import annotations

import hashlib
import json
import time

import numpy as np

from ..errors import PfbenchError

METHODS = ("multipdf", "bootstrap", "mpf")
_METHOD_KEY = {"multipdf": 0, "bootstrap": 1, "mpf": 2}
SPEC_VERSION = 1


def make_spec(model: str, *, configs=None, particles=(100,), filters=(1,), methods=("multipdf",),
              runs: int = 10, steps: int = 100, seed: int = 0, backend: str = "numba",
              params: dict | None = None, resampling: str = "systematic") -> dict:
    """A normalised sweep specification (a plain JSON-able dict).

    ``configs``: explicit list of (method, n_particles, n_filters); otherwise the product
    methods x particles x filters (bootstrap and mpf use N_f = 1 only).
    """
    from .. import models

    cls = models.model_class(model)  # validates the name
    params = dict(params or {})
    try:
        cls(**params)
    except (TypeError, ValueError) as exc:
        raise PfbenchError(f"bad parameters for model {model!r}: {exc}") from None
    if configs is None:
        configs = []
        for m in methods:
            for n_p in particles:
                for n_f in (filters if m == "multipdf" else (1,)):
                    configs.append((m, int(n_p), int(n_f)))
    out, seen = [], set()
    for m, n_p, n_f in configs:
        if m not in METHODS:
            raise PfbenchError(f"unknown sweep method {m!r}; choose one of {', '.join(METHODS)}")
        n_p, n_f = int(n_p), int(n_f)
        if n_p < 1 or n_f < 1 or n_f > n_p:
            raise PfbenchError(f"bad configuration N_p={n_p}, N_f={n_f} (need 1 <= N_f <= N_p)")
        if m != "multipdf" and n_f != 1:
            raise PfbenchError(f"method {m} needs N_f = 1")
        key = (m, n_p, n_f)
        if key not in seen:
            seen.add(key)
            out.append(list(key))
    if not out:
        raise PfbenchError("the sweep has no configurations")
    if int(runs) < 1 or int(steps) < 1:
        raise PfbenchError("--runs and --steps must be >= 1")
    if backend not in ("numba", "numpy"):
        raise PfbenchError(f"unknown backend {backend!r}; choose numba or numpy")
    return {"spec_version": SPEC_VERSION, "model": model, "params": params, "configs": out,
            "runs": int(runs), "steps": int(steps), "seed": int(seed), "backend": backend,
            "resampling": resampling, "code": code_fingerprint(model)}


def code_fingerprint(model: str) -> str:
    """Hash of the sources that determine a task's numbers (model, engine, MPF, this file)."""
    import inspect
    import sys

    from .. import models
    from ..backends.cache import package_fingerprint

    cls = models.model_class(model)
    h = hashlib.sha256(package_fingerprint().encode())
    h.update(inspect.getsource(sys.modules[cls.__module__]).encode())
    return h.hexdigest()[:16]


def spec_hash(spec: dict) -> str:
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:16]


def n_tasks(spec: dict) -> int:
    return len(spec["configs"]) * spec["runs"]


def task_key(config_index: int, run: int) -> str:
    return f"{config_index}:{run}"


def trajectory_seed(spec: dict, run: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(spec["seed"], spawn_key=(0, int(run)))


def filter_seed(spec: dict, config, run: int) -> np.random.SeedSequence:
    m, n_p, n_f = config
    return np.random.SeedSequence(spec["seed"], spawn_key=(1, _METHOD_KEY[m], int(n_p), int(n_f),
                                                           int(run)))


# --------------------------------------------------------------------------- filtering
def run_multipdf(model, y, u, n_particles: int, n_filters: int, seed, backend: str = "numba",
                 resampling: str = "systematic"):
    """MultiPDF / bootstrap estimates, equal to ``pfbench.run_filter(..., method="multipdf")``
    (same streams, same kernels) but without its per-call thread pool. Returns (est, sub_est)."""
    from ..filters.particle import run_groups, streams

    n_per = max(int(round(n_particles / n_filters)), 1)
    out, _ = run_groups(model, y, u, streams(seed, n_filters, False), method="multipdf", n_per=n_per,
                        n_filters=n_filters, resampling=resampling, ess_threshold=0.5 * n_per,
                        backend=backend, n_threads=1)
    est = out["est"]
    return est.mean(axis=0), est


_CACHE: dict = {}


def _model(spec: dict):
    from .. import models

    key = (spec["model"], json.dumps(spec["params"], sort_keys=True))
    if key not in _CACHE:
        _CACHE[key] = models.get(spec["model"], **spec["params"])
    return _CACHE[key]


def run_chunk(spec: dict, run: int, config_indices) -> list[dict]:
    """Simulate run ``run`` and filter it with each configuration; one record per task."""
    from ..filters.marginalized import run_mpf
    from ..metrics import rmse

    model = _model(spec)
    traj = model.simulate(spec["steps"], seed=np.random.default_rng(trajectory_seed(spec, run)))
    u = model.input_array(traj.u, traj.n_steps)
    y = np.ascontiguousarray(traj.y)
    out = []
    for ci in config_indices:
        cfg = spec["configs"][ci]
        m, n_p, n_f = cfg
        seed = filter_seed(spec, cfg, run)
        t0 = time.perf_counter()
        if m == "mpf":
            est = run_mpf(model, y, u, n_particles=n_p, backend=spec["backend"], seed=seed,
                          resampling=spec["resampling"]).estimates
        else:
            est, _ = run_multipdf(model, y, u, n_p, n_f, seed, spec["backend"], spec["resampling"])
        dt = time.perf_counter() - t0
        r = rmse(est, traj.x)
        out.append({"key": task_key(ci, run), "config": int(ci), "run": int(run), "method": m,
                    "n_particles": int(n_p), "n_filters": int(n_f),
                    "armse": float(np.mean(r)), "rmse": [float(v) for v in r],
                    "elapsed_s": dt})
    return out


def warm_up(spec: dict) -> None:
    """Compile (or load from cache) the kernels a spec needs, on one tiny run."""
    mini = dict(spec, steps=2)
    methods = {c[0] for c in spec["configs"]}
    cfgs = [i for i, c in enumerate(spec["configs"]) if c[0] in methods]
    picked, seen = [], set()
    for i in cfgs:
        if spec["configs"][i][0] not in seen:
            seen.add(spec["configs"][i][0])
            picked.append(i)
    mini["configs"] = [[c[0], 2 if c[0] != "mpf" else 2, 1] for c in
                       (spec["configs"][i] for i in picked)]
    run_chunk(mini, 0, range(len(mini["configs"])))
