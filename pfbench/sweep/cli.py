"""``pfbench sweep``: run a Monte Carlo grid (``pfbench sweep [run] --model ...``) and
``pfbench sweep summarize STORE [--json]``.

A grid file (YAML or TOML) holds any of the command-line options as a mapping (``model: ob3:v4``,
``particles: [100, 200]``, ``method: [multipdf, mpf]``, ``runs: 100``, ...); model parameters go
in ``params: {version: 4}`` or as ``param: ["version=4"]`` texts, read by the same
:func:`pfbench.options.parse_key_values` as ``--param``. Command-line options win.
"""
from __future__ import annotations

import sys
from pathlib import Path

import click

from ..errors import DataError, InputError
from ..clitypes import OUT_FILE, ChoiceList, NonEmptyPath, complete_models
from ..methods import BACKENDS, ESTIMATES, METHODS
from ..options import check_known, comma_list, parse_key_values, typed
from ..resampling import SCHEMES


def _ints(value, name: str) -> list[int]:
    """``"100,200"`` (command line) or ``[100, 200]`` / ``100`` (grid file) -> [100, 200]."""
    if isinstance(value, (list, tuple)):
        vals = [typed(v, int, name) for v in value]
        if not vals:
            raise InputError(f"{name} is empty")
        return vals
    return [typed(v, int, name) for v in comma_list(value, name)]


def _check_grid_keys(opts: dict, where: str) -> None:
    """Unknown grid-file keys: an error listing the valid keys, with "did you mean" if one is close."""
    check_known(opts, GRID_KEYS, "a grid-file key", flag=where)


def _grid_file(path: str) -> dict:
    p = Path(path)
    if not p.is_file():
        raise InputError(f"grid file {p} does not exist")
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"cannot read grid file {p}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        if p.suffix == ".toml":
            import tomllib

            return tomllib.loads(text)
        import yaml

        data = yaml.safe_load(text)
    except Exception as exc:  # noqa: BLE001 - parser errors of either format
        raise DataError(f"cannot parse grid file {p}: {' '.join(str(exc).split())}") from None
    if not isinstance(data, dict):
        raise DataError(f"grid file {p} must hold a mapping of options")
    opts = {str(k).replace("-", "_"): v for k, v in data.items()}
    _check_grid_keys(opts, f"grid file {p}")
    return opts


_OPTIONS = [
    click.option("--grid", "grid", type=NonEmptyPath(dir_okay=False), default=None,
                 help="YAML/TOML file with any of these options (command-line options win)."),
    click.option("--model", default=None, shell_complete=complete_models,
                 help="Model, optionally with a variant: ob1, ob3:v4 (`pfbench models` lists them)."),
    click.option("--param", "param", multiple=True, metavar="KEY=VALUE",
                 help="Model parameter (repeatable; JSON-typed, as `pfbench run --param`)."),
    click.option("--particles", default=None, help="N_p values, e.g. 100,200,500,1000."),
    click.option("--filters", default=None, help="N_f values (MultiPDF), e.g. 1,2,3,5,10."),
    click.option("--method", type=ChoiceList(METHODS), default=None, metavar="METHOD[,METHOD...]",
                 help=f"One or a comma-separated list of: {', '.join(METHODS)} (default multipdf)."),
    click.option("--runs", type=int, default=None, help="Monte Carlo runs per configuration."),
    click.option("--steps", type=int, default=None, help="Time steps M per run."),
    click.option("--backend", type=click.Choice(BACKENDS), default=None,
                 help="numba (default), numpy or cupy (a GPU)."),
    click.option("--resampling", type=click.Choice(SCHEMES), default=None,
                 help="Resampling scheme of every configuration (default systematic)."),
    click.option("--estimate", type=click.Choice(ESTIMATES), default=None,
                 help="Point estimate of a step: pre (default; weighted, before resampling) or post "
                      "(the resampled particles, [MultiPDF] Alg. 1-2) for the particle methods; mpf, "
                      "guided and kalman keep their own."),
    click.option("--seed", type=int, default=None, help="Root seed, an integer >= 0 (default 0)."),
    click.option("--out", **OUT_FILE, default=None, help="Store: X.parquet (journal X.parquet.journal) or X.jsonl; "
                                             "one sweep at a time may write it."),
    click.option("--workers", type=int, default=None,
                 help="Worker processes, >= 1 (default: all cores; 0 or less is an error)."),
    click.option("--executor", type=click.Choice(["local", "dask"]), default=None),
    click.option("--scheduler", default=None, help="Dask scheduler address tcp://host:port."),
    click.option("--overwrite", is_flag=True, help="Start afresh even if --out holds another sweep."),
    click.option("--quiet", is_flag=True, help="No progress bar."),
    click.option("--json", "as_json", is_flag=True, help="Print the outcome (store, tasks done, speed) as JSON."),
]


def _with_options(f):
    for opt in reversed(_OPTIONS):
        f = opt(f)
    return f


#: keys a grid file may hold (the options above, plus ``params`` as a mapping)
GRID_KEYS = ("model", "param", "params", "particles", "filters", "method", "runs", "steps", "backend",
             "resampling", "estimate", "seed", "out", "workers", "executor", "scheduler", "overwrite", "quiet")


def _do_run(kw: dict) -> None:
    from .core import make_spec
    from .runner import run_sweep

    as_json = kw.pop("as_json", False)
    grid = _grid_file(kw.pop("grid")) if kw.get("grid") else {}
    kw.pop("grid", None)
    opts = dict(grid)
    opts.update({k: v for k, v in kw.items() if v is not None and v is not False and v != ()})
    if not opts.get("model"):
        raise InputError("give --model (or a --grid file); `pfbench sweep --help` lists the options")
    if not opts.get("out"):
        raise InputError("give --out STORE (e.g. results/sweeps/ob1.parquet)")
    out = typed(opts["out"], str, "out")
    # a grid's overwrite: 'no' is text, not false: refused rather than taken as true (a sweep thrown away)
    overwrite, quiet = (typed(opts.get(k, False), bool, k) for k in ("overwrite", "quiet"))
    params = opts.get("params") or {}
    if not isinstance(params, dict):
        raise InputError("params (grid file) must be a mapping of model parameters")
    params = dict(params)
    texts = opts.get("param", ())
    texts = [texts] if isinstance(texts, str) else list(texts)
    for k, v in parse_key_values(texts, "--param").items():
        if k in params and params[k] != v:
            raise InputError(f"model parameter {k} is given twice ({params[k]!r} and {v!r})")
        params[k] = v
    spec = make_spec(opts["model"], params=params, methods=comma_list(opts.get("method", "multipdf"), "--method"),
                     particles=_ints(opts.get("particles", "100"), "--particles"),
                     filters=_ints(opts.get("filters", "1"), "--filters"),
                     runs=typed(opts.get("runs", 10), int, "--runs"),
                     steps=typed(opts.get("steps", 100), int, "--steps"),
                     seed=typed(opts.get("seed", 0), int, "--seed"),
                     backend=str(opts.get("backend", "numba")), resampling=str(opts.get("resampling", "systematic")),
                     estimate=str(opts.get("estimate", "pre")))
    try:
        workers = opts.get("workers")
        rep = run_sweep(spec, out, workers=None if workers is None else typed(workers, int, "--workers"),
                        executor=opts.get("executor", "local"), scheduler=opts.get("scheduler"),
                        progress=not quiet, overwrite=overwrite)
    except KeyboardInterrupt:
        from .store import journal_path

        click.echo(f"interrupted: finished tasks are saved in {journal_path(out)}; "
                   "re-run the same command to resume", err=True)
        sys.exit(130)
    if rep.non_finite_loglik:
        from ..filters.result import NON_FINITE_WHY

        click.echo(f"warning: {rep.non_finite_loglik} of {rep.done_before + rep.done_now} tasks have a log-likelihood "
                   f"of -inf or NaN: at some step {NON_FINITE_WHY}; their aRMSE is kept", err=True)
    if rep.tasks_with_invalid_loglik:
        from ..filters.result import INVALID_WHY

        click.echo(f"warning: in {rep.tasks_with_invalid_loglik} of {rep.done_before + rep.done_now} tasks the "
                   "model's log_likelihood returned NaN or +inf for some particles, which got weight zero (the "
                   f"store's invalid_loglik column counts them; {INVALID_WHY})", err=True)
    if as_json:
        from ..io import to_json

        click.echo(to_json({"store": str(rep.store), "total": rep.total, "done": rep.done_before + rep.done_now,
                            "done_now": rep.done_now, "wall_s": rep.wall_s,
                            "tasks_per_s": rep.tasks_per_s if rep.done_now else None,
                            "non_finite_loglik": rep.non_finite_loglik,
                            "tasks_with_invalid_loglik": rep.tasks_with_invalid_loglik}))
        return
    click.echo(f"{rep.done_before + rep.done_now}/{rep.total} tasks in {rep.store} "
               f"({rep.done_now} new in {rep.wall_s:.1f} s, {rep.tasks_per_s:.1f} tasks/s)")


@click.group(invoke_without_command=True)
@_with_options
@click.pass_context
def sweep(ctx, **kw):
    """Monte Carlo aRMSE sweeps over (method, N_p, N_f) x runs, resumable, local or Dask.

    `pfbench sweep --model ob3:v4 --particles 100,200 --filters 1,2,5 --runs 100
    --out results/sweeps/ob3v4.parquet` (same as `pfbench sweep run ...`).
    """
    if ctx.invoked_subcommand is None:
        _do_run(kw)


@sweep.command("run")
@_with_options
def run_cmd(**kw):
    """Run (or resume) a sweep."""
    _do_run(kw)


@sweep.command("summarize")
@click.argument("store")
@click.option("--json", "as_json", is_flag=True, help="One JSON list instead of CSV.")
@click.option("--plot/--no-plot", default=True, help="Write STORE.summary.png (aRMSE vs N_p).")
def summarize_cmd(store, as_json, plot):
    """Per configuration: runs, aRMSE mean and 95 % interval (mean +- 2 sigma/sqrt(m))."""
    from .. import io
    from .store import load_frame
    from .core import model_label
    from .summary import plot_summary, summarize_frame, throughput

    from ..procs import writer_of

    frame, spec, chunks = load_frame(store)
    writer = writer_of(store)
    if writer:
        click.echo(f"# note: {store} is being written by {writer}: these are the runs done so far", err=True)
    summ = summarize_frame(frame, spec)
    tp = throughput(chunks, len(frame))
    if as_json:
        from ..io import to_json

        click.echo(to_json(summ.to_dict(orient="records"), indent=1))
    else:
        click.echo(summ.to_csv(index=False), nl=False)
    click.echo(f"# {tp['tasks']} tasks, {tp['tasks_per_worker_s']:.1f} runs/s per worker "
               f"({tp['worker_seconds']:.1f} worker-seconds)", err=True)
    dropped = int(summ["dropped"].sum()) if not summ.empty else 0
    if dropped:
        click.echo(f"# warning: {dropped} run(s) with a NaN or infinite aRMSE are left out of the "
                   "means and intervals (column dropped)", err=True)
    if plot and not summ.empty:
        path = io.write_figure(str(store) + ".summary.png", plot_summary(summ, model_label(spec)))
        click.echo(f"# plot: {path}", err=True)
