"""Run a task x contender grid on the sweep machinery (:mod:`pfbench.sweep.runner`).

The grid is a spec with ``kind = "compare"``: its configurations are the (task, contender) pairs
and its runs the datasets, so the journal, resumption, local worker processes and the Dask
executor are the sweep's, unchanged. A work unit is one run r: each task's dataset r is made
once and every contender of the unit filters it (same y, u and seed for all of them).

One record per (task, contender, run): ``ok`` and the one-line ``reason`` of a failure; the
filter seed; ``armse`` and ``rmse`` (simulated tasks); ``loglik``; with an exact reference
``loglik_ref`` (the Kalman filter's), ``loglik_error`` = loglik - loglik_ref and
``armse_vs_exact`` (aRMSE of the estimates against the exact filtering means); ``coverage90``
(share of the (t, state) pairs whose true state lies in est ± 1.645 sd, from the reported
variances); ``wall_s`` (around the call), ``own_s`` (the filter's own time, see
:mod:`.contenders`), ``startup_s`` (cmd: only), ``overhead_s`` (the compare's own time for the
record beyond the call: checking the output, metrics, the record) and ``ns_per_particle_step`` (from ``own_s``).
"""
from __future__ import annotations

import hashlib
import json
import time

import numpy as np

from .. import tasks as _tasks
from ..errors import InputError
from .contenders import NotApplicable, RunFailed, parse, parse_all

SPEC_VERSION = 1
Z90 = 1.6448536269514722


def make_spec(task_names, contender_texts, *, runs: int = 10, n_particles: int = 1000,
              timeout_s: float | None = None, baseline: str | None = None) -> dict:
    """The JSON-able compare spec (validates every task and contender first)."""
    from ..options import comma_list

    names = comma_list(task_names, "--task") if isinstance(task_names, str) else list(task_names)
    tlist = [_tasks.get(n) for n in dict.fromkeys(names)]
    contenders = parse_all([contender_texts] if isinstance(contender_texts, str) else contender_texts)
    runs = _whole(runs, "--runs")
    for t in tlist:
        if t.data == _tasks.SIMULATED and runs > t.datasets:
            raise InputError(f"task {t.name} has {t.datasets} datasets; --runs {runs} asks for more")
    n_particles = _whole(n_particles, "--particles")
    if timeout_s is not None and not float(timeout_s) > 0:
        raise InputError(f"--timeout must be > 0 seconds, got {timeout_s!r}")
    names_c = [c.name for c in contenders]
    if baseline is not None and baseline not in names_c:
        raise InputError(f"--baseline {baseline!r} is not a contender ({', '.join(names_c)})")
    return {"kind": "compare", "spec_version": SPEC_VERSION,
            "tasks": [t.as_dict() for t in tlist],
            "contenders": [c.describe() for c in contenders],
            "configs": [[t.name, c.name] for t in tlist for c in contenders],
            "runs": runs, "n_particles": n_particles,
            "timeout_s": None if timeout_s is None else float(timeout_s),
            "baseline": baseline or names_c[0], "code": _code_fingerprint(contenders, tlist)}


def _whole(value, flag: str) -> int:
    """``value`` as an integer >= 1, never rounded (2.5) nor a bool; an InputError otherwise."""
    import numbers

    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise InputError(f"{flag} must be an integer >= 1, got {value!r}")
    return int(value)


def _code_fingerprint(contenders, tasks=()) -> str:
    """pfbench's package fingerprint plus the sources of the tasks' models and of the contenders: a
    py: file and the user's code its function reaches (:func:`pfbench.sources.digest`), and the
    files a cmd: line names (its script; a changed one was reused silently). A changed model or
    contender is refused on resume instead of mixing runs of two versions."""
    import os

    from .. import models
    from ..backends.cache import package_fingerprint
    from ..sources import digest, file_hash, model_digest

    h = hashlib.sha256(package_fingerprint().encode())
    for t in tasks:
        h.update(model_digest(models.model_class(t.model)).encode())
    for c in contenders:
        if getattr(c, "func", None) is not None:
            h.update(digest([c.func]).encode())
        files = [c.target] if c.kind == "py" and c.target.endswith(".py") else [
            a for a in getattr(c, "argv", []) if os.sep in a or a.endswith(".py")]
        for path in files:
            try:
                h.update(file_hash(path).encode())
            except OSError:
                pass
    return h.hexdigest()[:16]


# --------------------------------------------------------------------------- worker side
_CACHE: dict = {}


def _state(spec: dict):
    """(tasks by name, contenders by name) of a spec, parsed once per process."""
    key = hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()
    if key not in _CACHE:
        tasks = {t["name"]: _tasks.get(t["name"]) for t in spec["tasks"]}
        for t in spec["tasks"]:
            if tasks[t["name"]].as_dict() != t:
                raise InputError(f"task {t['name']} changed since this comparison started; use another --out")
        conts = {}
        for c in spec["contenders"]:
            conts[c["name"]] = parse(c["spec"])
            conts[c["name"]].name = c["name"]
        _CACHE.clear()
        _CACHE[key] = (tasks, conts, {})
    return _CACHE[key]


def _dataset(spec, task, run):
    tasks, conts, data = _state(spec)
    key = (task.name, run)
    if key not in data:
        model = task.get_model()
        traj = _tasks.dataset(task, 0 if task.data == _tasks.REAL else run, model)
        ref = _tasks.exact_reference(task, traj, model)
        if len(data) > 64:
            data.clear()
        data[key] = (model, traj, model.input_array(traj.u, traj.n_steps) if model.n_u else None, ref)
    return data[key]


def warm_up(spec: dict) -> None:
    """Compile / load every contender on a 2-step slice of each task's first dataset."""
    tasks, conts, _ = _state(spec)
    for tname, cname in spec["configs"]:
        task = tasks[tname]
        model, traj, u, _ = _dataset(spec, task, 0)
        try:
            conts[cname].warm_up(task, *_own_copies(model, traj))
        except Exception:  # noqa: BLE001 - the timed runs report what is wrong
            pass


def _own_copies(model, *arrays):
    """A contender's own copies of the model and the data: one that changed them in place (``y[:] =
    0``, ``model.R *= 100``) changed every later contender's data and the reference it is scored
    against, unseen."""
    import copy

    return (copy.deepcopy(model), *(a if a is None else copy.deepcopy(a) for a in arrays))


def run_chunk(spec: dict, run: int, config_indices) -> list[dict]:
    """Run ``run`` of each (task, contender) in ``config_indices``; one record each."""
    from ..metrics import rmse

    tasks, conts, _ = _state(spec)
    out = []
    for ci in config_indices:
        tname, cname = spec["configs"][ci]
        task, cont = tasks[tname], conts[cname]
        model, traj, u, ref = _dataset(spec, task, run)
        seed = _tasks.filter_seed(task, run)
        n_p = int(spec["n_particles"])
        rec = {"key": f"{ci}:{run}", "config": int(ci), "run": int(run), "task": tname,
               "contender": cname, "seed": seed, "n_particles": n_p, "ok": False, "reason": None}
        startup = None
        own_model, own_y, own_u = _own_copies(model, traj.y, u)
        t0 = time.perf_counter()
        try:
            res = cont.run(task, own_model, own_y, own_u, n_particles=n_p, seed=seed,
                           timeout=spec.get("timeout_s"))
        except NotApplicable as exc:
            rec.update(reason=str(exc), not_applicable=True)
        except RunFailed as exc:
            rec["reason"] = str(exc)
        except Exception as exc:  # noqa: BLE001 - a contender's bug is a failed run, not ours
            from .contenders import exc_reason

            rec["reason"] = exc_reason(exc)
        else:
            own = res.own_s
            if not hasattr(cont, "startup"):
                own = res.wall_s if own is None else own
            elif own is not None:  # an external program: its start-up is reported apart
                startup = res.wall_s - own
            else:
                t1 = time.perf_counter()
                startup = cont.startup(task, model, traj, n_p, spec.get("timeout_s"))
                t0 += time.perf_counter() - t1  # the probe is not the compare's overhead
                # a run no longer than the start-up probes has no time of its own (it was 0 ns)
                own = res.wall_s if not np.isfinite(startup) else (
                    res.wall_s - startup if res.wall_s > startup else None)
            has_truth = bool(np.all(np.isfinite(traj.x)))
            r = rmse(res.estimates, traj.x) if has_truth else None
            cov = None
            if has_truth and res.variances is not None:
                sd = np.sqrt(np.clip(res.variances, 0.0, None))
                cov = float(np.mean(np.abs(res.estimates - traj.x) <= Z90 * sd))
            n_eff = res.n_particles if res.n_particles is not None else n_p
            rec.update(ok=True, armse=None if r is None else float(np.mean(r)),
                       rmse=None if r is None else [float(v) for v in r],
                       loglik=res.loglik, coverage90=cov, wall_s=res.wall_s, own_s=own,
                       startup_s=startup, n_particles_used=int(n_eff),
                       ns_per_particle_step=None if own is None else own * 1e9 / (max(1, n_eff) * traj.n_steps))
            if ref is not None:
                rec["loglik_ref"] = ref[0]
                rec["loglik_error"] = None if res.loglik is None else res.loglik - ref[0]
                rec["armse_vs_exact"] = float(np.mean(rmse(res.estimates, ref[1])))
            rec["overhead_s"] = max(0.0, time.perf_counter() - t0 - res.wall_s)
        out.append(rec)
    return out


def run_compare(spec: dict, journal, *, workers: int = 1, executor: str = "local",
                scheduler: str | None = None, progress: bool = True, overwrite: bool = False):
    """Run (or resume) ``spec`` into the journal ``journal`` (.jsonl); returns the records. The
    baseline is not part of the journal's spec: it only pairs the results, so another ``--baseline``
    resumes the same runs."""
    from ..sweep.runner import run_sweep
    from ..sweep.store import Store

    spec = {k: v for k, v in spec.items() if k != "baseline"}
    run_sweep(spec, journal, workers=workers, executor=executor, scheduler=scheduler,
              progress=progress, overwrite=overwrite)
    return list(Store.read(journal).records.values())
