"""Named, versioned benchmark tasks: the problems every contender of ``pfbench compare`` runs on.

A task is data (a frozen :class:`Task` in :data:`TASKS`): a registered model and its parameters,
a horizon, a fixed set of datasets, the metrics that apply and a reference where one exists.
Adding a task is adding an entry (or calling :func:`register_task` from a ``--models`` file).

Datasets
    ``data="simulated"``: dataset r (r = 0..datasets-1) is ``model.simulate(steps,
    seed=default_rng(SeedSequence(seed, spawn_key=(0, r))))``, the same trajectory seeds as run r
    of ``pfbench sweep --seed SEED`` on that model, so a task's datasets never change with the
    contenders, the worker count or the executor. ``data="real"``: one measured record shipped in
    ``pfbench/data`` (``data_file`` + ``preprocess``, no true states); run r filters it again with
    a new filter seed.
Filter seed of run r
    ``SeedSequence(seed, spawn_key=(1, r))`` as one 32-bit integer (:func:`filter_seed`): every
    contender of a task gets the same seed for the same run (a JSON number, so external programs
    get it too).
Reference
    ``"exact-loglik"``: the task's model is linear-Gaussian and the Kalman filter
    (:func:`pfbench.kalman.filter_model`) gives the exact log-likelihood and filtering moments of
    every dataset; else None.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import DataError, InputError, UnknownNameError

DATA_DIR = Path(__file__).resolve().parent / "data"
SIMULATED, REAL = "simulated", "real"
EXACT_LOGLIK = "exact-loglik"


@dataclass(frozen=True)
class Task:
    """One benchmark problem (see the module docstring)."""

    name: str
    model: str
    steps: int
    params: dict = field(default_factory=dict)
    datasets: int = 100
    data: str = SIMULATED
    data_file: str | None = None
    preprocess: str | None = None
    reference: str | None = None
    version: int = 1
    seed: int = 0
    description: str = ""
    source: str = ""

    @property
    def metrics(self) -> tuple[str, ...]:
        m = ("armse", "rmse", "coverage90") if self.data == SIMULATED else ()
        m += ("loglik", "ns_per_particle_step", "failures")
        if self.reference == EXACT_LOGLIK:
            m += ("loglik_bias", "loglik_variance", "armse_vs_exact")
        return m

    def get_model(self):
        from . import models

        return models.get(self.model, **self.params)

    def as_dict(self) -> dict:
        return {"name": self.name, "version": self.version, "model": self.model,
                "params": self.params, "steps": self.steps, "datasets": self.datasets,
                "data": self.data, "data_file": self.data_file, "reference": self.reference,
                "metrics": list(self.metrics), "seed": self.seed, "description": self.description,
                "source": self.source}


def _lg(d: int, a: float = 0.8, b: float = 0.1) -> dict:
    """A d-dimensional linear-Gaussian model: A = a I + b (super-diagonal), C = I, Q = R = I."""
    A = (a * np.eye(d) + b * np.eye(d, k=1)).tolist()
    eye = np.eye(d).tolist()
    return {"A": A, "C": eye, "Q": eye, "R": eye}


_PAPERS = "[MultiPDF] §4"
TASKS: dict[str, Task] = {}


def register_task(task: Task) -> Task:
    """Add ``task`` to the registry (a name already taken by a different task is an error)."""
    if not isinstance(task, Task):
        raise TypeError("register_task expects a pfbench.tasks.Task")
    old = TASKS.get(task.name)
    if old is not None and old != task:
        raise InputError(f"task {task.name!r} is already registered with other settings")
    if task.data not in (SIMULATED, REAL) or task.steps < 1 or task.datasets < 1:
        raise InputError(f"task {task.name!r}: data must be simulated or real, steps and datasets >= 1")
    TASKS[task.name] = task
    return task


for _t in (
    Task("ob1", "ob1", 100, description="univariate nonstationary growth model", source=_PAPERS),
    Task("ob2", "ob2", 100, description="5 states, 15 outputs", source=_PAPERS),
    *[Task(f"ob3-v{v}", "ob3", 100, {"version": v}, description=f"four-node network, version {v}",
           source=_PAPERS) for v in range(1, 6)],
    Task("ob4", "ob4", 100, description="two states with an input", source=_PAPERS),
    Task("ob5", "ob5", 200, description="magnetic levitation (MLS2EM)", source=_PAPERS),
    Task("thermal", "thermal_inertial", 200, description="heated chamber, second-order thermal model",
         source="[Embedded] eqs. 10-12"),
    Task("pmsm", "pmsm", 200, description="permanent-magnet synchronous motor", source="[Thesis] §4"),
    *[Task(f"lg-d{d}", "linear_gaussian", m, _lg(d), reference=EXACT_LOGLIK,
           description=f"linear-Gaussian, d = {d} (A = 0.8 I + 0.1 super-diagonal, C = Q = R = I)",
           source="the Kalman filter is exact") for d, m in ((2, 50), (4, 100))],
    Task("sv-gbpusd", "stochastic_volatility", 750, datasets=1, data=REAL,
         data_file="GBP_vs_USD_9798.txt", preprocess="log-returns-percent",
         description="stochastic volatility on 750 daily GBP/USD log-returns (%)",
         source="[KSC1998]; data [PACIFIC] via `particles`"),
    Task("bearings-only", "bearings_only", 24, description="bearings-only tracking",
         source="[Gordon1993] §4.2"),
    *[Task(f"lorenz96-d{d}", "lorenz96", 100, {"d": d}, description=f"Lorenz-96, d = {d}, all observed",
           source="[Lorenz1996]") for d in (10, 20, 40)],
):
    register_task(_t)


def names() -> list[str]:
    return list(TASKS)


def get(name: str) -> Task:
    try:
        return TASKS[str(name).strip()]
    except KeyError:
        from .options import did_you_mean

        raise UnknownNameError(f"unknown task {name!r}{did_you_mean(name, TASKS)}; `pfbench tasks` "
                         "lists them") from None


# --------------------------------------------------------------------------- datasets
def load_real(task: Task):
    """(y (M, n_y), u or None) of a real-data task, from ``pfbench/data/<data_file>``."""
    path = DATA_DIR / str(task.data_file)
    if not path.is_file():
        raise DataError(f"task {task.name}: data file {path} is missing (a broken installation?)")
    if task.preprocess == "log-returns-percent":
        rates = []
        for line in path.read_text(encoding="utf-8").splitlines()[2:]:
            parts = line.split()
            if len(parts) == 4 and not line.startswith("(C)"):
                rates.append(float(parts[3]))
        y = 100.0 * np.diff(np.log(np.asarray(rates)))
        return y.reshape(-1, 1), None
    raise DataError(f"task {task.name}: unknown preprocess {task.preprocess!r}")


def trajectory_seed(task: Task, run: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(task.seed, spawn_key=(0, int(run)))


def filter_seed(task: Task, run: int) -> int:
    """The filter seed every contender gets on run ``run`` (a 32-bit integer)."""
    return int(np.random.SeedSequence(task.seed, spawn_key=(1, int(run))).generate_state(1)[0])


def dataset(task: Task, run: int, model=None):
    """The :class:`~pfbench.models.Trajectory` of run ``run`` (x is NaN for real data)."""
    from .models.base import Trajectory

    model = task.get_model() if model is None else model
    if task.data == REAL:
        y, u = load_real(task)
        return Trajectory(x=np.full((y.shape[0], model.n_x), np.nan), y=y, u=u)
    if not 0 <= int(run) < task.datasets:
        raise InputError(f"task {task.name} has {task.datasets} datasets; run {run} is out of range")
    return model.simulate(task.steps, seed=np.random.default_rng(trajectory_seed(task, run)))


def exact_reference(task: Task, traj, model=None):
    """The Kalman filter's exact (loglik, means) of a dataset, or None without a reference."""
    if task.reference != EXACT_LOGLIK:
        return None
    from .filters.kalman import filter_model

    model = task.get_model() if model is None else model
    res = filter_model(model, traj.y, traj.u)
    return float(res.loglik), res.estimates


def table() -> list[dict]:
    """Every task as a plain dict (the rows of ``pfbench tasks --json``)."""
    return [t.as_dict() for t in TASKS.values()]


# --------------------------------------------------------------------------- CLI
def _cli():
    import click

    @click.command("tasks")
    @click.option("--json", "as_json", is_flag=True, help="One JSON object per task, in a list.")
    def tasks_cmd(as_json):
        """The benchmark tasks of `pfbench compare`: model, horizon, datasets, reference."""
        if as_json:
            from .io import to_json

            click.echo(to_json(table(), indent=1))
            return
        w = max(len(n) for n in TASKS)
        click.echo(f"{'TASK'.ljust(w)}  {'model':<22} {'steps':>5} {'datasets':>8}  {'data':<9} reference")
        for t in TASKS.values():
            model = t.model + ("".join(f" {k}={v}" for k, v in t.params.items()
                                       if not isinstance(v, list)))
            click.echo(f"{t.name.ljust(w)}  {model:<22} {t.steps:>5} {t.datasets:>8}  {t.data:<9} "
                       f"{t.reference or '-'}")
        click.echo("`pfbench tasks --json` adds parameters, metrics and sources.")

    return tasks_cmd


def __getattr__(name):  # the click command, built on first use (`pfbench tasks`)
    if name == "tasks_cmd":
        globals()["tasks_cmd"] = cmd = _cli()
        return cmd
    raise AttributeError(name)
