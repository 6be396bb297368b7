"""``pfbench compare --task T[,T...] --contender [NAME=]SPEC ... [--runs R] [--particles N]
[--out DIR] [--json] [--executor local|dask --scheduler ...]``."""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import click

from ..clitypes import OUT_DIR, complete_tasks
from ..errors import PfbenchError


@click.command("compare")
@click.option("--task", "task_names", required=True, metavar="T[,T...]", shell_complete=complete_tasks,
              help="Task name(s), comma-separated (`pfbench tasks` lists them).")
@click.option("--contender", "contenders", multiple=True, required=True, metavar="[NAME=]SPEC",
              help="pfbench:METHOD[:k=v,...], py:PATH.py:FUNC, py:module:FUNC, cmd:PROGRAM ARGS..., "
                   "particles:bootstrap|guided, filterpy:ekf|ukf (repeatable).")
@click.option("--runs", type=int, default=10, show_default=True,
              help="Runs per task and contender (datasets 0..R-1; real data: R filter seeds).")
@click.option("--particles", "n_particles", type=int, default=1000, show_default=True, help="N_p.")
@click.option("--baseline", default=None, help="Contender the others are paired against (default: the first).")
@click.option("--timeout", "timeout_s", type=float, default=None,
              help="Seconds one run of an external (cmd:, out-of-process particles:) contender may take "
                   "(default 600); pfbench: and py: contenders run in this process, with no limit.")
@click.option("--out", "out_dir", **OUT_DIR, default=None,
              help="Write leaderboard.md, compare.json, <task>.png and the resumable journal here.")
@click.option("--json", "as_json", is_flag=True, help="Print the results as one JSON object.")
@click.option("--workers", type=int, default=1, show_default=True,
              help="Local worker processes (1: in this process; more share the cores, so timings interfere).")
@click.option("--executor", type=click.Choice(["local", "dask"]), default="local", show_default=True)
@click.option("--scheduler", default=None, help="Dask scheduler address tcp://host:port.")
@click.option("--overwrite", is_flag=True, help="Start afresh even if --out holds another comparison.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def compare(task_names, contenders, runs, n_particles, baseline, timeout_s, out_dir, as_json, workers,
            executor, scheduler, overwrite, quiet):
    """Run contenders on benchmark tasks: same datasets for all, paired 95 % intervals against a
    baseline, a leaderboard. A failed run (crash, timeout, malformed output) is recorded with its
    reason and the comparison goes on; the exit code is 0 when at least one contender completed
    every run."""
    from ..io import to_json
    from . import leaderboard
    from .run import make_spec, run_compare
    from .stats import summarize

    spec = make_spec(task_names, contenders, runs=runs, n_particles=n_particles, timeout_s=timeout_s,
                     baseline=baseline)
    tmp = None
    if out_dir is None:
        tmp = tempfile.TemporaryDirectory(prefix="pfbench-compare-")
        journal = Path(tmp.name) / "journal.jsonl"
    else:
        journal = Path(out_dir) / "journal.jsonl"
    try:
        try:
            records = run_compare(spec, journal, workers=workers, executor=executor, scheduler=scheduler,
                                  progress=not (quiet or as_json), overwrite=overwrite)
        except KeyboardInterrupt:
            if out_dir is not None:
                click.echo(f"interrupted: finished runs are saved in {journal}; re-run the same "
                           "command to resume", err=True)
            sys.exit(130)
    finally:
        if tmp is not None:
            tmp.cleanup()
    summary = summarize(spec, records)
    paths = leaderboard.write(summary, out_dir) if out_dir is not None else []
    if as_json:
        click.echo(to_json(summary, indent=1))
    else:
        click.echo(leaderboard.markdown(summary), nl=False)
        if paths:
            click.echo(f"wrote {', '.join(str(p) for p in paths)}")
    if not summary["complete_contenders"]:
        raise PfbenchError("no contender completed every run (see the failures above)")
