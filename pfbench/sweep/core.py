"""Monte Carlo sweeps: specification, deterministic seeds, and the work of one chunk.

A sweep runs every configuration (method, N_p, N_f) on ``runs`` independently simulated
trajectories of one model and records the aRMSE of each (configuration, run) task
([MultiPDF] eqs. 11-13). Every method of :class:`pfbench.Method` can be swept; :func:`make_spec`
refuses a method the model does not support (one line, before any work).

Seeds (numpy ``SeedSequence`` with spawn keys, derived from one root ``seed``):

* trajectory of run r: ``SeedSequence(seed, spawn_key=(0, r))`` -- the same ground truth for
  every configuration (common random numbers across configurations, which makes the
  N_p / N_f comparisons sharper; the paper also draws a new truth per run);
* filter of configuration c on run r: ``SeedSequence(seed, spawn_key=(1, key, N_p, N_f, r))``
  with ``key`` the method's entry in :data:`SEED_KEY` (fixed forever, so stores stay valid).
  Every record keeps it (``seed`` and ``seed_key`` = the spawn key as ``"1.1.100.1.3"``) beside
  the log-likelihood estimate ``loglik``, so the variance of the log-likelihood (what PMMH users
  tune N_p by) can be read from a sweep and any run redone with ``pfbench.run_filter(...,
  seed=SeedSequence(seed, spawn_key=...))``.

So a task's result depends only on (spec, c, r): not on the worker count, the executor, the
order of completion or on interruptions.

Work unit ("chunk"): one run r and a list of configurations; the trajectory is simulated once
and every configuration is filtered on it (batched inside one worker call, which amortises
the Python overhead). The particle family (bootstrap, sir, sis, asir, multipdf) calls
:func:`pfbench.filters.particle.run_groups` directly, without :func:`pfbench.run_filter`'s
thread pool but with exactly its streams and arithmetic; mpf, guided and kalman go through
:func:`pfbench.run_filter`.
"""
from __future__ import annotations

import hashlib
import json
import time

import numpy as np

from ..errors import InputError
from ..methods import METHODS, Estimate, Method, check_backend

#: the method's part of a filter seed's spawn key. Never change an entry: it would change every
#: stored sweep's numbers. New methods take new numbers.
SEED_KEY = {"multipdf": 0, "bootstrap": 1, "mpf": 2, "sir": 3, "sis": 4, "asir": 5, "guided": 6,
            "kalman": 7}
assert set(SEED_KEY) == set(METHODS), "every Method needs a sweep seed key"
SPEC_VERSION = 1


def make_spec(model: str, *, configs=None, particles=(100,), filters=(1,), methods=("multipdf",),
              runs: int = 10, steps: int = 100, seed: int = 0, backend: str = "numba",
              params: dict | None = None, resampling: str = "systematic", estimate: str = "pre") -> dict:
    """A normalised sweep specification (a plain JSON-able dict).

    ``model`` is a model spec (``"ob3:v4"`` = ``"ob3"`` with ``params={"version": 4}``; the spec
    stores the name and the parameters). ``configs``: explicit list of (method, n_particles,
    n_filters); otherwise the product methods x particles x filters (only multipdf uses N_f > 1).
    ``methods`` are :class:`pfbench.Method` names; a method the model does not support is an
    error here (see :func:`check_supported`). ``resampling`` holds for every configuration,
    ``estimate`` (``pre`` or ``post``, see :func:`pfbench.run_filter`) for those of the particle
    methods: mpf, guided and kalman configurations take their own estimate (the marginalized PF's
    weighted one before resampling, [Schon2005] Alg. 1), so a MultiPDF-vs-MPF sweep can run
    MultiPDF with ``post`` (:func:`estimate_for`). The filter seeds do not depend on ``estimate``,
    so a ``pre`` and a ``post`` sweep with the same seed run the same filters on the same random
    numbers (paired); a spec without ``estimate`` (an older store) means ``pre``.
    """
    from .. import models
    from ..resampling import Scheme

    if not isinstance(model, str):  # a model object: its class's registered name, parameters apart
        raise InputError(f"model must be a registered model spec such as 'ob3:v4' (parameters in params=), "
                         f"got {type(model).__name__}")
    model, params = models.parse_spec(model, params)
    models.get(model, **params)  # validates the parameters
    # one value where a list is meant: particles=1000, methods="bootstrap" (it was split into letters)
    particles, filters = (v if np.iterable(v) else [v] for v in (particles, filters))
    methods = [methods] if isinstance(methods, str) else methods
    if configs is None and any(int(f) != 1 for f in filters) and all(
            Method.parse(m) != Method.MULTIPDF for m in methods):
        raise InputError(f"--filters {','.join(str(f) for f in filters)}: only multipdf has sub-filters, and "
                         f"no method here is multipdf ({', '.join(Method.parse(m).label for m in methods)})")
    if configs is None:
        configs = []
        for m in methods:
            for n_p in particles:
                for n_f in (filters if Method.parse(m) == Method.MULTIPDF else (1,)):
                    configs.append((m, int(n_p), int(n_f)))
    out, seen = [], set()
    for m, n_p, n_f in configs:
        m = Method.parse(m).label
        n_p, n_f = int(n_p), int(n_f)
        if n_p < 1 or n_f < 1 or n_f > n_p:
            raise InputError(f"bad configuration N_p={n_p}, N_f={n_f} (need 1 <= N_f <= N_p)")
        if m != "multipdf" and n_f != 1:
            raise InputError(f"method {m} needs N_f = 1")
        key = (m, n_p, n_f)
        if key not in seen:
            seen.add(key)
            out.append(list(key))
    if not out:
        raise InputError("the sweep has no configurations")
    if int(runs) < 1 or int(steps) < 1:
        raise InputError("--runs and --steps must be >= 1")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or int(seed) < 0:
        raise InputError(f"--seed must be an integer >= 0 (a root seed of numpy's SeedSequence), got {seed!r}")
    check_backend(backend)
    estimate = Estimate.parse(estimate).label
    from ..methods import ARRAY_BACKENDS

    if backend in ARRAY_BACKENDS:  # before any work: the methods it runs, and a GPU for cupy
        from ..backends import array_backend, cupy_backend

        for m, _, _ in out:
            array_backend.check_supported(Method.parse(m), Scheme.parse(resampling), backend)
        if estimate == Estimate.POST.label:
            raise InputError(f"--estimate post is not available on backend {backend!r} (use pre, or "
                             f"backend numpy or numba)")
        if backend == "cupy":
            cupy_backend.import_cupy()
    resampling = Scheme.parse(resampling).label
    spec = {"spec_version": SPEC_VERSION, "model": model, "params": params, "configs": out,
            "runs": int(runs), "steps": int(steps), "seed": int(seed), "backend": backend,
            "resampling": resampling, "estimate": estimate, "code": code_fingerprint(model)}
    check_supported(spec)
    return spec


def check_supported(spec: dict) -> None:
    """Raise the filter's own one-line error if the model cannot run one of the spec's methods.

    Runs each method once on a 2-step simulation with the NumPy backend (milliseconds, nothing
    to compile), so that an unsupported method (e.g. mpf on a model without a declared
    linear-Gaussian substructure) fails before any sweep work or store is written.
    """
    from .. import models
    from ..filters import run_filter

    model = models.get(spec["model"], **spec["params"])
    traj = model.simulate(2, seed=0)
    for m in dict.fromkeys(c[0] for c in spec["configs"]):
        run_filter(model, traj.y, traj.u, method=m, n_particles=2, backend="numpy",
                   resampling=spec["resampling"], estimate=estimate_for(spec, m), seed=0)


def estimate_of(spec: dict) -> str:
    """The spec's ``estimate`` (``pre`` for a spec written before the option existed)."""
    return spec.get("estimate", "pre")


def estimate_for(spec: dict, method: str) -> str:
    """The estimate a configuration of ``method`` runs with: the spec's for the particle methods,
    ``pre`` (the method's own) for mpf, guided and kalman."""
    return estimate_of(spec) if Method.parse(method).family == "particle" else "pre"


def model_label(spec: dict) -> str:
    """The full model spec of a sweep as a user names it (``ob3:v4``, ``ob4 shared_noise=true``):
    the spec keeps name and parameters apart, and a table showing only the name would say ``ob3``
    for every version."""
    from ..models import format_spec

    return format_spec(spec["model"], spec.get("params"))


def code_fingerprint(model: str) -> str:
    """Hash of the sources that determine a task's numbers (model, engine, MPF, this file)."""
    from .. import models
    from ..backends.cache import package_fingerprint
    from ..sources import model_digest

    h = hashlib.sha256(package_fingerprint().encode())
    h.update(model_digest(models.model_class(model)).encode())  # with the user's code its functions reach
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
    return np.random.SeedSequence(spec["seed"], spawn_key=(1, SEED_KEY[m], int(n_p), int(n_f),
                                                           int(run)))


# --------------------------------------------------------------------------- filtering
def run_particle_family(model, y, u, method: str, n_particles: int, n_filters: int, seed,
                        backend: str = "numba", resampling: str = "systematic", estimate: str = "pre",
                        want_loglik: bool = False):
    """Estimates of a particle-family method (bootstrap, sir, sis, asir, multipdf), equal to
    ``pfbench.run_filter(..., method=method, estimate=estimate)`` (same streams, kernels and
    default ESS threshold) but without its per-call thread pool. Returns (est, sub_est), and with
    ``want_loglik`` the log-likelihood estimate and the log-likelihoods the model returned as NaN
    or +inf (None where the backend does not count them) as third and fourth items."""
    from ..filters.inputs import ess_count
    from ..filters.particle import run_groups, split_particles, streams
    from ..methods import ARRAY_BACKENDS
    from ..models.contract import named_model_errors

    m = Method.parse(method)
    n_per = split_particles(n_particles, n_filters) if m == Method.MULTIPDF else int(n_particles)
    with named_model_errors(model, y, u, backend):   # the model's exceptions named, as run_filter does
        if backend in ARRAY_BACKENDS:  # cupy: the array-namespace kernel, its own Philox draws
            if Estimate.parse(estimate) == Estimate.POST:
                raise InputError(f"estimate='post' is not available on backend {backend!r}")
            from ..backends.cupy_backend import run_groups as run_array
            from ..filters.inputs import seed_sequence

            out, _, _ = run_array(model, y, u, seed_sequence(seed), backend=backend, method=m, n_per=n_per,
                                  n_filters=n_filters, resampling=resampling,
                                  ess_threshold=ess_count(None, n_per), dtype="float64")
        else:
            out, _ = run_groups(model, y, u, streams(seed, n_filters, False), method=m, n_per=n_per,
                                n_filters=n_filters, resampling=resampling,
                                ess_threshold=ess_count(None, n_per), backend=backend, n_threads=1,
                                estimate=estimate)
    est = out["est"]
    if want_loglik:
        from ..filters.result import mixture_loglik_increments

        invalid = int(out["invalid"].sum()) if "invalid" in out else None
        return est.mean(axis=0), est, float(mixture_loglik_increments(out["inc"]).sum()), invalid
    return est.mean(axis=0), est


def run_multipdf(model, y, u, n_particles: int, n_filters: int, seed, backend: str = "numba",
                 resampling: str = "systematic"):
    """MultiPDF (bootstrap for N_f = 1) estimates, see :func:`run_particle_family`."""
    return run_particle_family(model, y, u, "multipdf", n_particles, n_filters, seed, backend,
                               resampling)


_CACHE: dict = {}


def _model(spec: dict):
    from .. import models

    key = (spec["model"], json.dumps(spec["params"], sort_keys=True))
    if key not in _CACHE:
        _CACHE[key] = models.get(spec["model"], **spec["params"])
    return _CACHE[key]


def run_chunk(spec: dict, run: int, config_indices) -> list[dict]:
    """Simulate run ``run`` and filter it with each configuration; one record per task."""
    from ..filters import run_filter
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
        if Method.parse(m).family == "particle":
            est, _, ll, invalid = run_particle_family(model, y, u, m, n_p, n_f, seed, spec["backend"],
                                                      spec["resampling"], estimate_for(spec, m), want_loglik=True)
        else:
            res = run_filter(model, y, u, method=m, n_particles=n_p, backend=spec["backend"],
                             seed=seed, resampling=spec["resampling"])
            est, ll, invalid = res.estimates, float(res.loglik), res.info.get("invalid_log_likelihoods")
        dt = time.perf_counter() - t0
        r = rmse(est, traj.x)
        out.append({"key": task_key(ci, run), "config": int(ci), "run": int(run), "method": m,
                    "n_particles": int(n_p), "n_filters": int(n_f),
                    "armse": float(np.mean(r)), "rmse": [float(v) for v in r],
                    "elapsed_s": dt, "loglik": ll, "invalid_loglik": invalid, "seed": int(spec["seed"]),
                    "seed_key": ".".join(str(k) for k in seed.spawn_key)})
    return out


def warm_up(spec: dict) -> None:
    """Compile (or load from cache) the kernels a spec needs, on one tiny run."""
    mini = dict(spec, steps=2, configs=[[m, 2, 1] for m in dict.fromkeys(c[0] for c in spec["configs"])])
    run_chunk(mini, 0, range(len(mini["configs"])))
