"""``pfbench sweep``: run a Monte Carlo grid (``pfbench sweep [run] --model ...``) and
``pfbench sweep summarize STORE [--json]``."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from ..errors import PfbenchError


def _ints(text: str, name: str) -> list[int]:
    try:
        vals = [int(v) for v in str(text).replace(" ", "").split(",") if v]
    except ValueError:
        raise PfbenchError(f"{name} must be a comma-separated list of integers, got {text!r}") from None
    if not vals:
        raise PfbenchError(f"{name} is empty")
    return vals


def _grid_file(path: str) -> dict:
    p = Path(path)
    if not p.is_file():
        raise PfbenchError(f"grid file {p} does not exist")
    text = p.read_text()
    try:
        if p.suffix == ".toml":
            import tomllib

            return tomllib.loads(text)
        import yaml

        data = yaml.safe_load(text)
    except Exception as exc:  # noqa: BLE001 - parser errors of either format
        raise PfbenchError(f"cannot parse grid file {p}: {exc}") from None
    if not isinstance(data, dict):
        raise PfbenchError(f"grid file {p} must hold a mapping of options")
    return data


_OPTIONS = [
    click.option("--grid", "grid", type=click.Path(dir_okay=False), default=None,
                 help="YAML/TOML file with any of these options (command-line options win)."),
    click.option("--model", default=None, help="Model name (see `pfbench models`)."),
    click.option("--version", "version", type=int, default=None, help="Model version (Ob3: 1-5)."),
    click.option("--param", "param", multiple=True, help="Model parameter KEY=VALUE (JSON value)."),
    click.option("--particles", default=None, help="N_p values, e.g. 100,200,500,1000."),
    click.option("--filters", default=None, help="N_f values (MultiPDF), e.g. 1,2,3,5,10."),
    click.option("--method", default=None,
                 help="multipdf, bootstrap, mpf, or a comma-separated list of them."),
    click.option("--runs", type=int, default=None, help="Monte Carlo runs per configuration."),
    click.option("--steps", type=int, default=None, help="Time steps M per run."),
    click.option("--backend", default=None, help="numba (default) or numpy."),
    click.option("--seed", type=int, default=None, help="Root seed (default 0)."),
    click.option("--out", default=None, help="Store: X.parquet (journal X.parquet.journal) or X.jsonl."),
    click.option("--workers", type=int, default=None, help="Worker processes (default: all cores)."),
    click.option("--executor", type=click.Choice(["local", "dask"]), default=None),
    click.option("--scheduler", default=None, help="Dask scheduler address tcp://host:port."),
    click.option("--overwrite", is_flag=True, help="Start afresh even if --out holds another sweep."),
    click.option("--quiet", is_flag=True, help="No progress bar."),
]


def _with_options(f):
    for opt in reversed(_OPTIONS):
        f = opt(f)
    return f


def _do_run(kw: dict) -> None:
    from .core import make_spec
    from .runner import run_sweep

    grid = _grid_file(kw.pop("grid")) if kw.get("grid") else {}
    kw.pop("grid", None)
    opts = {k.replace("-", "_"): v for k, v in grid.items()}
    opts.update({k: v for k, v in kw.items() if v is not None and v is not False and v != ()})
    if not opts.get("model"):
        raise PfbenchError("give --model (or a --grid file); `pfbench sweep --help` lists the options")
    if not opts.get("out"):
        raise PfbenchError("give --out STORE (e.g. results/sweeps/ob1.parquet)")
    params = dict(opts.get("params") or {})
    for item in opts.get("param", ()):
        if "=" not in item:
            raise PfbenchError(f"--param expects KEY=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        try:
            params[k] = json.loads(v)
        except ValueError:
            params[k] = v
    if opts.get("version") is not None:
        params["version"] = int(opts["version"])
    as_list = lambda v, name: v if isinstance(v, list) else _ints(v, name)  # noqa: E731
    methods = opts.get("method", "multipdf")
    methods = methods if isinstance(methods, list) else [m.strip() for m in str(methods).split(",")]
    spec = make_spec(opts["model"], params=params, methods=methods,
                     particles=as_list(opts.get("particles", "100"), "--particles"),
                     filters=as_list(opts.get("filters", "1"), "--filters"),
                     runs=int(opts.get("runs", 10)), steps=int(opts.get("steps", 100)),
                     seed=int(opts.get("seed", 0)), backend=opts.get("backend", "numba"))
    try:
        rep = run_sweep(spec, opts["out"], workers=opts.get("workers"),
                        executor=opts.get("executor", "local"), scheduler=opts.get("scheduler"),
                        progress=not opts.get("quiet"), overwrite=bool(opts.get("overwrite")))
    except KeyboardInterrupt:
        from .store import journal_path

        click.echo(f"interrupted: finished tasks are saved in {journal_path(opts['out'])}; "
                   "re-run the same command to resume", err=True)
        sys.exit(130)
    click.echo(f"{rep.done_before + rep.done_now}/{rep.total} tasks in {rep.store} "
               f"({rep.done_now} new in {rep.wall_s:.1f} s, {rep.tasks_per_s:.1f} tasks/s)")


@click.group(invoke_without_command=True)
@_with_options
@click.pass_context
def sweep(ctx, **kw):
    """Monte Carlo aRMSE sweeps over (method, N_p, N_f) x runs, resumable, local or Dask.

    `pfbench sweep --model ob3 --version 4 --particles 100,200 --filters 1,2,5 --runs 100
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
    from .summary import plot_summary, summarize_frame, throughput

    frame, spec, chunks = load_frame(store)
    summ = summarize_frame(frame, spec)
    tp = throughput(chunks, len(frame))
    if as_json:
        click.echo(json.dumps(json.loads(summ.to_json(orient="records")), indent=1))
    else:
        click.echo(summ.to_csv(index=False), nl=False)
    click.echo(f"# {tp['tasks']} tasks, {tp['tasks_per_worker_s']:.1f} runs/s per worker "
               f"({tp['worker_seconds']:.1f} worker-seconds)", err=True)
    if plot and not summ.empty:
        title = spec["model"] + "".join(f" {k}={v}" for k, v in spec.get("params", {}).items())
        path = io.write_figure(str(store) + ".summary.png", plot_summary(summ, title))
        click.echo(f"# plot: {path}", err=True)
