"""Contenders of ``pfbench compare``: what a ``--contender [NAME=]SPEC`` names and how it runs.

SPEC forms
----------
``pfbench:METHOD[:key=value,...]``
    a built-in method of :func:`pfbench.run_filter`; keys ``resampling``, ``filters`` (N_f),
    ``backend``, ``ess_threshold``, ``dtype``, ``threads`` (default 1: every contender on one core).
``py:PATH.py:FUNC`` or ``py:module:FUNC``
    a Python callable ``f(model, y, u, *, n_particles, seed)`` returning a
    :class:`~pfbench.FilterResult` or a mapping with ``"estimates"`` (M x n_x) and optionally
    ``"loglik"``, ``"variances"`` (M x n_x) and ``"elapsed_s"`` (its own filtering time). ``u`` is
    None for a model without inputs.
``cmd:PROGRAM ARGS...``
    an external program (:data:`PROTOCOL`): started once per run, it reads one JSON object on
    stdin and writes one on stdout.
``particles:bootstrap|guided[:key=value,...]``
    the `particles` library's SMC on the pfbench model through a Feynman-Kac class
    (:mod:`pfbench.compare.particles_adapter`); in this process when `particles` imports, else
    out of process with the interpreter ``$PFBENCH_PARTICLES_PYTHON`` or ``.venv-particles``.
``filterpy:ekf|ukf``
    filterpy's extended / unscented Kalman filter on a linear-Gaussian model (the model's A, C, Q,
    R, x0, P0) or on a model with ``jacobians(x, u, t) -> (F, H)`` and ``cl_noise()``.

Failures
--------
A contender that raises, exits non-zero, times out or returns something malformed gives a
:class:`RunFailed` with a one-line reason; the comparison records it and goes on. A SPEC that
cannot work at all (unknown prefix or method, missing file, function or program) is an
:class:`~pfbench.errors.InputError` before anything runs.

Timing
------
``wall_s`` is measured around the call. For ``cmd:`` it includes the process start-up, which is
measured once per worker process, task and contender by two probe runs on the first step of
dataset 0 (their minimum is ``startup_s``) when the program does not report its own time; the
filter's own time ``own_s`` is the program's self-reported ``"elapsed_s"`` when it gives one
(``startup_s`` is then ``wall_s - elapsed_s``, no probe), else ``wall_s - startup_s``. For ``py:`` and
``pfbench:`` ``own_s`` is the result's ``elapsed_s`` when it has one, else ``wall_s``.
"""
from __future__ import annotations

import contextlib
import hashlib
import importlib
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError, PfbenchError

#: the ``cmd:`` protocol, as documented (README "Benchmark your own filter")
PROTOCOL = {
    "stdin": {"task": "task name", "model": "registered model name", "params": "model parameters "
              "(pfbench.models.get(model, **params) rebuilds the model)",
              "y": "M x n_y list", "u": "M x n_u list or null", "n_particles": "int", "seed": "int",
              "n_x": "int", "steps": "int"},
    "stdout": {"estimates": "M x n_x list (required)", "loglik": "number or null",
               "variances": "M x n_x list (optional)", "elapsed_s": "own filtering time (optional)",
               "n_particles": "particles actually used, if not n_particles; 0: none (optional)"},
}
#: the keys a contender's output may give (a mapping's other keys are its own, and ignored)
OUTPUT_KEYS = tuple(PROTOCOL["stdout"])
PREFIXES = ("pfbench", "py", "cmd", "particles", "filterpy")
PFBENCH_KEYS = {"resampling": str, "filters": int, "backend": str, "ess_threshold": float,
                "dtype": str, "threads": int}
DEFAULT_TIMEOUT_S = 600.0


class RunFailed(PfbenchError):
    """One run of a contender failed; the message is the one-line reason."""


class NotApplicable(RunFailed):
    """The contender cannot run the task's model at all (e.g. a Kalman filter on a nonlinear model):
    reported as not applicable to the task, not as failed runs."""


def one_line(text, limit: int = 200) -> str:
    s = " ".join(str(text).split())
    return s if len(s) <= limit else s[: limit - 3] + "..."


def exc_reason(exc: BaseException) -> str:
    first = (str(exc).strip().splitlines() or [""])[0]
    return one_line(f"{type(exc).__name__}: {first}" if first else type(exc).__name__)


@dataclass
class Output:
    """What one run of a contender gave, normalised."""

    estimates: np.ndarray
    loglik: float | None = None
    variances: np.ndarray | None = None
    wall_s: float = 0.0
    own_s: float | None = None
    startup_s: float | None = None
    n_particles: int | None = None


def normalise(raw, n_steps: int, n_x: int, wall_s: float) -> Output:
    """A FilterResult or mapping -> :class:`Output`; anything malformed is a :class:`RunFailed`."""
    from ..filters.result import FilterResult

    if isinstance(raw, FilterResult):
        return Output(np.asarray(raw.estimates, dtype=float), checked_loglik(float(raw.loglik)),
                      np.asarray(raw.variances, dtype=float), wall_s, float(raw.elapsed_s),
                      n_particles=int(raw.n_particles))
    if not isinstance(raw, dict) and hasattr(raw, "keys") and hasattr(raw, "__getitem__"):
        raw = {k: raw[k] for k in raw.keys()}
    if not isinstance(raw, dict):
        raise RunFailed(f"malformed output: expected a FilterResult or a mapping with 'estimates', "
                        f"got {type(raw).__name__}")
    import difflib

    for key in raw:  # a misspelled key was an output silently left out
        near = difflib.get_close_matches(str(key), OUTPUT_KEYS, n=1, cutoff=0.75)
        if key not in OUTPUT_KEYS and near:
            raise RunFailed(f"malformed output: unknown key {key!r} (did you mean {near[0]!r}?)")
    if "estimates" not in raw:
        raise RunFailed("malformed output: no 'estimates'")

    def arr(key):
        try:
            a = np.asarray(raw[key], dtype=float)
        except (TypeError, ValueError):
            raise RunFailed(f"malformed output: '{key}' is not a numeric array") from None
        if a.ndim == 1 and n_x == 1:
            a = a.reshape(-1, 1)
        if a.shape != (n_steps, n_x):
            raise RunFailed(f"malformed output: '{key}' has shape {a.shape}, expected ({n_steps}, {n_x})")
        return a

    est = arr("estimates")
    if not np.all(np.isfinite(est)):
        raise RunFailed(f"non-finite estimates ({int((~np.isfinite(est)).sum())} entries)")
    var = arr("variances") if raw.get("variances") is not None else None
    if var is not None and not np.all(np.isfinite(var) & (var >= 0)):
        raise RunFailed(f"malformed output: {int((~(np.isfinite(var) & (var >= 0))).sum())} variances are "
                        "negative or not finite")
    ll = _number(raw, "loglik")
    if ll is not None:
        ll = checked_loglik(ll)
    own = _number(raw, "elapsed_s")
    if own is not None and not 0.0 <= own <= wall_s:  # a time the call cannot have taken
        raise RunFailed(f"malformed output: 'elapsed_s' {own:g} s is not within the call's {wall_s:.3g} s")
    n_p = _number(raw, "n_particles")
    if n_p is not None and not (n_p == int(n_p) and n_p >= 0):  # 0: a filter without particles
        raise RunFailed(f"malformed output: 'n_particles' must be an integer >= 0, got {n_p:g}")
    return Output(est, ll, var, wall_s, own, n_particles=None if n_p is None else int(n_p))


def _number(raw: dict, key: str) -> float | None:
    """``raw[key]`` as a float, None when absent or null; any other type is a malformed output."""
    v = raw.get(key)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
        raise RunFailed(f"malformed output: {key!r} must be a number or null, got {v!r:.40}")
    return float(v)


def checked_loglik(ll: float) -> float:
    """A run's log-likelihood; NaN or -inf is a failed run (it was left out of the means unseen, so a
    filter that collapsed on a hard run looked better than one that did not)."""
    if not np.isfinite(ll):
        why = ("every particle weight zero at some step" if ll == -np.inf else
               "not a number" if np.isnan(ll) else "not finite")
        raise RunFailed(f"log-likelihood {ll} ({why})")
    return ll


# --------------------------------------------------------------------------- contenders
@dataclass
class Contender:
    """A parsed ``[NAME=]SPEC``; :meth:`run` filters one dataset."""

    name: str
    spec: str
    kind: str = ""
    options: dict = field(default_factory=dict)

    def describe(self) -> dict:
        return {"name": self.name, "spec": self.spec, "kind": self.kind}

    def warm_up(self, task, model, traj) -> None:
        """Load / compile what the runs need, outside their timing (default: nothing)."""

    def run(self, task, model, y, u, *, n_particles: int, seed: int, timeout: float | None) -> Output:
        raise NotImplementedError


class PfbenchContender(Contender):
    def __init__(self, name, spec, method, options):
        from ..methods import Method
        from ..options import check_known, typed

        super().__init__(name, spec, "pfbench", {})
        self.method = Method.parse(method).label
        check_known(options, PFBENCH_KEYS, "a pfbench: contender option", flag=f"--contender {spec}:")
        self.options = {k: typed(v, PFBENCH_KEYS[k], f"--contender {spec}: {k}") for k, v in options.items()}
        self._check(spec)

    def _check(self, spec: str) -> None:
        """The options' values, refused up front as `pfbench run` refuses them (not as a failure of
        every run)."""
        from ..methods import check_backend, check_dtype
        from ..resampling import Scheme

        o = self.options
        try:
            for key, check in (("backend", check_backend), ("dtype", check_dtype), ("resampling", Scheme.parse)):
                if key in o:
                    check(o[key])
        except InputError as exc:
            raise InputError(f"--contender {spec}: {exc}") from None
        for key in ("filters", "threads"):
            if o.get(key, 1) < 1:
                raise InputError(f"--contender {spec}: {key} must be >= 1, got {o[key]}")
        if not 0.0 < o.get("ess_threshold", 0.5) <= 1.0:
            raise InputError(f"--contender {spec}: ess_threshold must be a fraction in (0, 1], got {o['ess_threshold']}")
        for key, method in (("filters", "multipdf"), ("ess_threshold", "sir")):  # as run_filter refuses them
            if key in o and self.method != method and (key != "filters" or o[key] != 1):
                raise InputError(f"--contender {spec}: {key} applies to pfbench:{method} only")

    def _kw(self):
        o = self.options
        return dict(method=self.method, n_filters=o.get("filters", 1),
                    resampling=o.get("resampling", "systematic"), ess_threshold=o.get("ess_threshold"),
                    backend=o.get("backend", "numba"), dtype=o.get("dtype", "float64"),
                    n_threads=o.get("threads", 1))

    def warm_up(self, task, model, traj):
        from ..filters import run_filter

        kw = self._kw()
        run_filter(model, traj.y[:2], None if traj.u is None else traj.u[:2],
                   n_particles=max(2, kw["n_filters"]), seed=0, **kw)

    def run(self, task, model, y, u, *, n_particles, seed, timeout):
        from ..errors import UnsupportedError
        from ..filters import run_filter

        t0 = time.perf_counter()
        try:
            res = run_filter(model, y, u, n_particles=n_particles, seed=seed, **self._kw())
        except UnsupportedError as exc:
            raise NotApplicable(str(exc)) from None
        return normalise(res, y.shape[0], model.n_x, time.perf_counter() - t0)


_PY_MODULES: dict[str, object] = {}


def _load_py(target: str, spec: str):
    if target.endswith(".py"):
        path = Path(target).expanduser()
        if not path.is_file():
            raise InputError(f"--contender {spec}: file {target!r} does not exist")
        key = str(path.resolve())
        if key not in _PY_MODULES:
            from ..models import import_path

            name = f"pfbench_user_contenders.m{hashlib.sha1(key.encode()).hexdigest()[:10]}_{path.stem}"
            try:
                _PY_MODULES[key] = import_path(name, key)
            except (Exception, SystemExit) as exc:  # noqa: BLE001 - the user's code (sys.exit too): one line
                raise InputError(f"--contender {spec}: {target} failed to import: {exc_reason(exc)}") from None
        return _PY_MODULES[key]
    if os.getcwd() not in sys.path:  # a module of the current folder, as `python -m` finds it
        sys.path.append(os.getcwd())
    try:
        return importlib.import_module(target)
    except Exception as exc:  # noqa: BLE001
        raise InputError(f"--contender {spec}: cannot import module {target!r}: {exc_reason(exc)}") from None


class PyContender(Contender):
    def __init__(self, name, spec, body):
        super().__init__(name, spec, "py", {})
        target, sep, func = body.rpartition(":")
        if not sep or not target or not func:
            raise InputError(f"--contender {spec}: expected py:PATH.py:FUNC or py:module:FUNC")
        self.target, self.func_name = target, func
        self.func = self._resolve()

    def _resolve(self):
        mod = _load_py(self.target, self.spec)
        f = getattr(mod, self.func_name, None)
        if not callable(f):
            where = getattr(mod, "__file__", None) or "built in"
            raise InputError(f"--contender {self.spec}: {self.target} ({where}) has no function {self.func_name!r}")
        return f

    def __getstate__(self):
        d = dict(self.__dict__)
        d.pop("func", None)
        return d

    def __setstate__(self, d):
        self.__dict__.update(d)
        self.func = self._resolve()

    def warm_up(self, task, model, traj):
        try:
            with _user_code():
                self.func(model, traj.y[:2], None if traj.u is None else traj.u[:2], n_particles=2, seed=0)
        except (Exception, SystemExit):  # noqa: BLE001 - the timed runs report it
            pass

    def run(self, task, model, y, u, *, n_particles, seed, timeout):
        t0 = time.perf_counter()
        try:
            with _user_code():
                raw = self.func(model, y, u, n_particles=n_particles, seed=seed)
        except RunFailed:
            raise
        except (Exception, SystemExit) as exc:  # noqa: BLE001 - the user's code (sys.exit too): a failed run
            raise RunFailed(exc_reason(exc)) from None
        wall = time.perf_counter() - t0
        return normalise(raw, y.shape[0], model.n_x, wall)


@contextlib.contextmanager
def _user_code():
    """Around a ``py:`` contender's call: what it prints goes to standard error (standard output
    carries the comparison's own output, ``--json``), and ``os._exit`` in this process is a failed
    run instead of the end of pfbench with that exit status and no output (a child it forks exits
    as it asked)."""
    real, pid = os._exit, os.getpid()

    def refused(status=0):
        if os.getpid() != pid:
            real(status)
        raise RunFailed(f"called os._exit({status}), which would end the comparison")

    os._exit = refused
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        os._exit = real


def request(task, model, y, u, n_particles: int, seed: int) -> dict:
    """The JSON object an external contender reads (see :data:`PROTOCOL`)."""
    return {"task": task.name, "model": task.model, "params": task.params,
            "y": np.asarray(y).tolist(), "u": None if u is None else np.asarray(u).tolist(),
            "n_particles": int(n_particles), "seed": int(seed), "n_x": int(model.n_x),
            "steps": int(np.asarray(y).shape[0])}


class CmdContender(Contender):
    def __init__(self, name, spec, body, env: dict | None = None, kind: str = "cmd"):
        super().__init__(name, spec, kind, {})
        try:
            self.argv = shlex.split(body)
        except ValueError as exc:
            raise InputError(f"--contender {spec}: {exc}") from None
        if not self.argv:
            raise InputError(f"--contender {spec}: no program given")
        prog = self.argv[0]
        if shutil.which(prog) is None and not (os.sep in prog and os.access(prog, os.X_OK)):
            raise InputError(f"--contender {spec}: program {prog!r} not found or not executable")
        self.env = env
        self._startup: dict = {}

    def _call(self, payload: dict, timeout: float | None):
        """Run the program once on ``payload``: (its JSON output, wall time). It runs in a session of
        its own, so a timeout (``DEFAULT_TIMEOUT_S`` unless given) ends the processes it started too
        (they ran on, orphaned, and slowed later runs); output that is not UTF-8 is read with
        replacement characters."""
        import signal

        text = json.dumps(payload, allow_nan=False)
        env = None if self.env is None else {**os.environ, **self.env}
        timeout = DEFAULT_TIMEOUT_S if timeout is None else timeout
        t0 = time.perf_counter()
        try:
            proc = subprocess.Popen(self.argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                    text=True, encoding="utf-8", errors="replace", env=env, start_new_session=True)
        except OSError as exc:
            raise RunFailed(f"cannot start {self.argv[0]}: {exc.strerror or exc}") from None
        try:
            stdout, stderr = proc.communicate(text, timeout=timeout)
        except BaseException as exc:  # a timeout, or Ctrl-C, which a program in its own session does not get
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except OSError:
                pass
            proc.communicate()
            if isinstance(exc, subprocess.TimeoutExpired):
                raise RunFailed(f"timed out after {timeout:g} s") from None
            raise
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            last = (stderr.strip().splitlines() or [""])[-1]
            code = (f"killed by signal {-proc.returncode}" if proc.returncode < 0
                    else f"exit code {proc.returncode}")
            raise RunFailed(one_line(code + (f": {last}" if last else "")))
        try:
            out = json.loads(stdout)
        except ValueError:
            raise RunFailed(one_line(f"malformed output: stdout is not one JSON object "
                                     f"({stdout.strip()[:60]!r})")) from None
        return out, wall

    def startup(self, task, model, traj, n_particles: int, timeout: float | None) -> float:
        key = (task.name, int(n_particles))
        if key not in self._startup:
            y1 = traj.y[:1]
            u1 = None if traj.u is None else traj.u[:1]
            walls = []
            for _ in range(2):
                try:
                    walls.append(self._call(request(task, model, y1, u1, n_particles, 0), timeout)[1])
                except RunFailed:
                    walls.append(float("nan"))
                    break
            finite = [w for w in walls if np.isfinite(w)]
            self._startup[key] = min(finite) if finite else float("nan")
        return self._startup[key]

    def run(self, task, model, y, u, *, n_particles, seed, timeout):
        raw, wall = self._call(request(task, model, y, u, n_particles, seed), timeout)
        out = normalise(raw, y.shape[0], model.n_x, wall)
        return out


class ParticlesContender(Contender):
    """`particles` in this process when importable, else out of process (:class:`CmdContender`)."""

    ALGS = ("bootstrap", "guided")

    def __init__(self, name, spec, body):
        super().__init__(name, spec, "particles", {})
        alg, _, opts = body.partition(":")
        if alg not in self.ALGS:
            raise InputError(f"--contender {spec}: choose particles:bootstrap or particles:guided")
        from ..options import check_known, parse_key_values, typed

        options = parse_key_values([o for o in opts.split(",") if o], f"--contender {spec}")
        check_known(options, ("resampling", "ess_threshold"), "a particles: contender option",
                    flag=f"--contender {spec}:")
        if "ess_threshold" in options:
            options["ess_threshold"] = typed(options["ess_threshold"], float, f"--contender {spec}: ess_threshold")
        self.alg, self.options = alg, options
        self.remote = None
        try:
            import particles  # noqa: F401
        except ImportError:
            python = particles_python()
            if python is None:
                raise InputError(f"--contender {spec}: the `particles` library is not importable here "
                                 "(it pins NumPy < 2) and no interpreter that has it was found: run "
                                 "`make .venv-particles/.installed-stamp` or set "
                                 "PFBENCH_PARTICLES_PYTHON") from None
            root = str(Path(__file__).resolve().parents[2])
            argv = [python, "-m", "pfbench.compare.particles_adapter", alg,
                    json.dumps(options, sort_keys=True)]
            self.remote = CmdContender(name, spec, shlex.join(argv), kind="particles",
                                       env={"PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", ""),
                                            "PFBENCH_COMPILE_HELPER": "0"})

    def startup(self, task, model, traj, n_particles, timeout):
        return None if self.remote is None else self.remote.startup(task, model, traj, n_particles, timeout)

    def run(self, task, model, y, u, *, n_particles, seed, timeout):
        if self.remote is not None:
            return self.remote.run(task, model, y, u, n_particles=n_particles, seed=seed, timeout=timeout)
        from .particles_adapter import run_particles

        t0 = time.perf_counter()
        try:
            raw = run_particles(model, y, u, self.alg, n_particles=n_particles, seed=seed, **self.options)
        except Exception as exc:  # noqa: BLE001
            raise RunFailed(exc_reason(exc)) from None
        return normalise(raw, y.shape[0], model.n_x, time.perf_counter() - t0)


def particles_python() -> str | None:
    """An interpreter that can import `particles`: $PFBENCH_PARTICLES_PYTHON, else
    ``.venv-particles/bin/python`` in the current directory or the source tree."""
    env = os.environ.get("PFBENCH_PARTICLES_PYTHON")
    if env:
        return env
    for root in (Path.cwd(), Path(__file__).resolve().parents[2]):
        p = root / ".venv-particles" / "bin" / "python"
        if p.is_file():
            return str(p)
    return None


class FilterpyContender(Contender):
    ALGS = ("ekf", "ukf")

    def __init__(self, name, spec, body):
        super().__init__(name, spec, "filterpy", {})
        if body not in self.ALGS:
            raise InputError(f"--contender {spec}: choose filterpy:ekf or filterpy:ukf")
        try:
            import filterpy  # noqa: F401
        except ImportError:
            raise InputError(f"--contender {spec}: filterpy is not installed (pip install filterpy)") from None
        self.alg = body

    def run(self, task, model, y, u, *, n_particles, seed, timeout):
        from .filterpy_adapter import run_filterpy

        t0 = time.perf_counter()
        try:
            raw = run_filterpy(model, y, u, self.alg)
        except RunFailed:
            raise
        except Exception as exc:  # noqa: BLE001
            raise RunFailed(exc_reason(exc)) from None
        return normalise(raw, y.shape[0], model.n_x, time.perf_counter() - t0)


_NAME = re.compile(r"^[A-Za-z0-9_.+-]+$")


def split_name(text: str) -> tuple[str | None, str]:
    """``"NAME=SPEC"`` -> (NAME, SPEC); ``"SPEC"`` -> (None, SPEC). A NAME has no ':' (so the
    ``=`` of ``pfbench:sir:ess_threshold=0.3`` is not taken for one)."""
    head, sep, rest = text.partition("=")
    if sep and _NAME.match(head.strip()) and head.strip() not in PREFIXES:
        return head.strip(), rest.strip()
    return None, text.strip()


def default_name(spec: str) -> str:
    prefix, _, body = spec.partition(":")
    if prefix == "pfbench":
        method, _, opts = body.partition(":")
        return "-".join([method] + [o.partition("=")[2] for o in opts.split(",") if o.strip()])
    if prefix == "py":
        return body.rpartition(":")[2]
    if prefix == "cmd":
        argv = body.split()
        return Path(argv[-1] if argv and argv[0].startswith("python") and len(argv) > 1 else
                    (argv[0] if argv else "cmd")).stem
    return spec


def parse(text: str) -> Contender:
    """One ``--contender [NAME=]SPEC`` -> a :class:`Contender` (InputError if it cannot work)."""
    name, spec = split_name(str(text))
    prefix, sep, body = spec.partition(":")
    if not sep or prefix not in PREFIXES or not body.strip():
        raise InputError(f"--contender {text!r}: SPEC must be pfbench:METHOD[:k=v,...], py:PATH.py:FUNC, "
                         "py:module:FUNC, cmd:PROGRAM ARGS..., particles:bootstrap|guided or "
                         "filterpy:ekf|ukf")
    name = name or default_name(spec)
    if prefix == "pfbench":
        method, _, opts = body.partition(":")
        from ..options import parse_key_values

        options = parse_key_values([o for o in opts.split(",") if o.strip()], f"--contender {spec}")
        return PfbenchContender(name, spec, method.strip(), options)
    if prefix == "py":
        return PyContender(name, spec, body.strip())
    if prefix == "cmd":
        return CmdContender(name, spec, body.strip())
    if prefix == "particles":
        return ParticlesContender(name, spec, body.strip())
    return FilterpyContender(name, spec, body.strip())


def parse_all(texts) -> list[Contender]:
    out = [parse(t) for t in texts]
    if not out:
        raise InputError("give at least one --contender [NAME=]SPEC")
    seen: dict = {}
    for c in out:
        if c.name in seen:
            raise InputError(f"two contenders are called {c.name!r} ({seen[c.name]} and {c.spec}); "
                             "name them: --contender NAME=SPEC")
        seen[c.name] = c.spec
    return out
