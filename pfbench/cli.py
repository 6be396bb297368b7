"""The ``pfbench`` command line (click).

Error policy (one place, :meth:`PfbenchGroup.main`):

* a user error -- a :class:`~pfbench.errors.PfbenchError` (bad value, name, option, file, a
  method the model does not support) or a click usage error -- is one line ``error: ...`` on
  stderr and exit code 2 (``pfbench --debug ...`` adds the traceback);
* running out of memory (a ``MemoryError`` that the checks before allocating did not foresee) is
  one line and exit code 2;
* an ``OSError`` on a user-chosen path (read-only file system, no permission, disk full, a parent
  that is a file, ...; see :func:`_is_path_fault`) is one line naming the path and what to do,
  exit code 2 -- a safety net: the places that write user-named files raise a DataError already.
  An OSError without a file name, with another errno or on a file inside the package is a bug;
* Ctrl-C ends with exit code 130;
* anything else is a bug in pfbench: its traceback and exit code 1;
* a crash of compiled code (a segmentation fault: a model indexing out of its arrays, which numba
  does not check, or a bug) prints the Python stack of every thread (:mod:`faulthandler`), so it
  says which call it came from instead of ending the process in silence.

Subcommand groups of the subsystems (``pfbench mcu``, ``pfbench sweep``, ``pfbench bench``) live
next to their code and are added here. Every ``KEY=VALUE`` flag is read by
:func:`pfbench.options.parse_key_values`; every ``--model`` by :func:`pfbench.models.parse_spec`.
"""
from __future__ import annotations

import faulthandler
import importlib
import math
import os
import sys
import traceback
from pathlib import Path

import click

from .clitypes import (OUT_DIR, OUT_FILE, ChoiceList, NonEmptyPath, complete_models, complete_papers,
                       complete_recipes, positive_int)
from .errors import InputError, PfbenchError
from .methods import BACKENDS, DTYPES, ESTIMATES, METHODS
from .options import parse_key_values
from .progress import compile_notice
from .resampling import SCHEMES

DEBUG_ENV = "PFBENCH_DEBUG"


def _one_line(msg: str) -> str:
    return " ".join(str(msg).split())


def _bug() -> None:
    """Print the traceback of the exception being handled (a bug in pfbench) and exit 1."""
    traceback.print_exc()
    click.echo("error: internal error in pfbench (a bug; the traceback above shows where). "
               "Please report it.", err=True)
    sys.exit(1)


def _is_path_fault(exc: OSError) -> bool:
    """An OSError the user or the system caused on a path they chose, not a bug.

    It must name a file, have an errno of an unusable path (read-only file system, no permission,
    disk full, not a directory, ... :data:`pfbench.resources.PATH_ERRNOS`) and the file must lie
    outside the installed pfbench package (a missing or unreadable package file is a bug or a
    broken installation, and keeps its traceback).
    """
    from pathlib import Path

    from .resources import PATH_ERRNOS

    if exc.filename is None or exc.errno not in PATH_ERRNOS:
        return False
    try:
        Path(os.fsdecode(exc.filename)).resolve().relative_to(Path(__file__).resolve().parent)
    except (ValueError, OSError, TypeError):
        return True
    return False


class PfbenchGroup(click.Group):
    """The root group: applies the error policy of the module docstring, and imports the
    subcommand groups of the subsystems (:data:`SUBSYSTEMS`) only when one is used (or listed by
    ``--help``), so ``pfbench run`` does not pay for importing pandas and the benchmark code."""

    debug = False

    def list_commands(self, ctx):
        return sorted(set(super().list_commands(ctx)) | set(SUBSYSTEMS))

    def get_command(self, ctx, cmd_name):
        if cmd_name not in self.commands and cmd_name in SUBSYSTEMS:
            _add_subsystem_command(cmd_name)
        return super().get_command(ctx, cmd_name)

    def main(self, args=None, prog_name=None, **extra):  # noqa: D401
        self.debug = os.environ.get(DEBUG_ENV, "") not in ("", "0")
        try:
            faulthandler.enable(file=sys.__stderr__)
        except (AttributeError, ValueError, OSError):  # no standard error to write to
            pass
        try:
            rv = super().main(args=args, prog_name=prog_name, standalone_mode=False, **extra)
        except click.exceptions.NoArgsIsHelpError as exc:
            click.echo(exc.ctx.get_help() if exc.ctx else str(exc))
            sys.exit(0)
        except click.UsageError as exc:
            hint = ""
            if exc.ctx is not None:
                hint = f" (see '{exc.ctx.command_path} --help')"
            message = exc.format_message()
            if isinstance(exc, click.NoSuchOption) and exc.option_name in ROOT_OPTIONS:
                message, hint = (f"{exc.option_name} is an option of pfbench itself: give it before the "
                                 f"command, as in {ROOT_OPTIONS[exc.option_name]}"), ""
            click.echo(f"error: {_one_line(message)}{hint}", err=True)
            sys.exit(2)
        except click.exceptions.Exit as exc:
            sys.exit(exc.exit_code)
        except click.Abort as exc:
            if isinstance(exc.__cause__, EOFError):  # click wraps an EOFError as Abort: not a Ctrl-C
                _bug()
            click.echo("error: interrupted", err=True)
            sys.exit(130)
        except KeyboardInterrupt:
            click.echo("error: interrupted", err=True)
            sys.exit(130)
        except click.ClickException as exc:
            click.echo(f"error: {_one_line(exc.format_message())}", err=True)
            sys.exit(2)
        except PfbenchError as exc:
            if self.debug:
                traceback.print_exc()
            click.echo(f"error: {_one_line(exc)}", err=True)
            sys.exit(2)
        except MemoryError:
            if self.debug:
                traceback.print_exc()
            click.echo("error: out of memory; use fewer particles/steps (or fewer --workers) or raise the "
                       "memory limit", err=True)
            sys.exit(2)
        except OSError as exc:  # a user-named path that cannot be used; any other OSError is a bug
            if not _is_path_fault(exc):
                _bug()
            if self.debug:
                traceback.print_exc()
            from .resources import os_error_message

            click.echo(f"error: {_one_line(os_error_message(exc))}", err=True)
            sys.exit(2)
        except Exception:  # noqa: BLE001 - anything else is a bug: show where it happened
            _bug()
        if isinstance(rv, int):
            sys.exit(rv)
        sys.exit(0)


#: the root group's options a user may put after the command by mistake, with how to write them
ROOT_OPTIONS = {"--models": "`pfbench --models FILE.py run ...` (or set PFBENCH_MODELS=FILE.py)",
                "--debug": "`pfbench --debug run ...` (or set PFBENCH_DEBUG=1)", "--version": "`pfbench --version`"}


def _set_debug(ctx, param, value):
    if value:
        ctx.find_root().command.debug = True
    return value


@click.group(cls=PfbenchGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="pfbench", prog_name="pfbench")
@click.option("--debug", is_flag=True, expose_value=False, is_eager=True, callback=_set_debug,
              help=f"Show the traceback of user errors too (or set {DEBUG_ENV}=1).")
@click.option("--models", "model_files", multiple=True, metavar="FILE.py",
              help="Import your own model file(s) (classes decorated with @register) so their "
                   "names work in every --model (repeatable; or set PFBENCH_MODELS).")
def main(model_files):
    """pfbench: particle and Kalman filter benchmarks and paper reproductions.

    \b
    Quick start:
      pfbench list                      # the paper figures/tables we reproduce
      pfbench reproduce fig5            # one recipe, quick mode (--full: paper scale)
      pfbench run --model ob1 --method bootstrap --particles 1000 --steps 1000
      pfbench run --model ob3:v4 --method mpf --particles 200
      pfbench models                    # the models: dimensions, supported methods
      pfbench info                      # CPU, cores, numba threading layer, versions
      pfbench --models my_model.py mcu emulate --model my_growth
    """
    _check_numba_environment()
    if model_files:
        from . import models

        models.load_files(model_files)
        # worker processes (sweeps, the MCU compiler) find the files through the environment
        os.environ[models.MODELS_ENV] = os.pathsep.join(
            [os.path.abspath(f) for f in model_files]
            + [p for p in os.environ.get(models.MODELS_ENV, "").split(os.pathsep) if p])


#: the values numba takes for NUMBA_THREADING_LAYER (a layer, or a rule for choosing one)
NUMBA_LAYERS = ("default", "safe", "threadsafe", "forksafe", "tbb", "omp", "workqueue")


def _check_numba_environment() -> None:
    """numba's settings from the environment, checked before numba reads them: NUMBA_NUM_THREADS=0
    made numba's import fail (a traceback read as a pfbench bug), an unknown threading layer failed
    only when the threads started, and junk was a warning with a traceback."""
    threads = os.environ.get("NUMBA_NUM_THREADS")
    if threads is not None and not (threads.strip().isdigit() and int(threads) > 0):
        raise InputError(f"NUMBA_NUM_THREADS={threads!r}: numba needs a positive integer (unset it to use "
                         "every core; pfbench run --threads limits one run)")
    layer = os.environ.get("NUMBA_THREADING_LAYER")
    if layer is not None and layer.strip().lower() not in NUMBA_LAYERS:
        raise InputError(f"NUMBA_THREADING_LAYER={layer!r}: numba knows {', '.join(NUMBA_LAYERS)} "
                         "(unset it for the default)")


# --------------------------------------------------------------------------- run
MODEL_HELP = ("Registered model, optionally with a variant: ob1, ob3:v4 (= --param version=4); "
              "`pfbench models` lists them.")
PARAM_HELP = "Model parameter KEY=VALUE (repeatable; JSON-typed: 3 int, 0.5 float, true, text)."


TRUTH_STREAM = "numpy.random.SeedSequence(seed, spawn_key=(1,))"


def truth_stream(seed: int):
    """The generator of ``pfbench run``'s simulated truth when no --truth-seed is given: derived
    from the filter's seed but apart from its stream (:data:`TRUTH_STREAM`)."""
    import numpy as np

    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(1,)))


@main.command()
@click.option("--model", "model_name", required=True, help=MODEL_HELP, shell_complete=complete_models)
@click.option("--method", type=click.Choice(METHODS), default="bootstrap", show_default=True,
              help="Filter: the particle methods, mpf (marginalized PF on the model's linear "
                   "substructure), guided (the model's proposal) or kalman.")
@click.option("--particles", type=int, default=1000, show_default=True, callback=positive_int("particles"),
              help="N_p, total number of particles.")
@click.option("--filters", type=int, default=1, show_default=True, callback=positive_int("filters"),
              help="N_f, MultiPDF sub-filters.")
@click.option("--steps", type=int, default=1000, show_default=True, callback=positive_int("steps"),
              help="M, number of time steps to simulate (with --data: filter the log's first M rows).")
@click.option("--resampling", type=click.Choice(SCHEMES), default="systematic", show_default=True)
@click.option("--ess-threshold", type=float, default=None,
              help="sir / guided: resample when N_eff < this fraction of N_p, in (0, 1] (default 0.5).")
@click.option("--estimate", type=click.Choice(ESTIMATES), default="pre", show_default=True,
              help="Point estimate of a step: pre (weighted, before resampling) or post (the resampled "
                   "particles, as [MultiPDF] Alg. 1-2; particle methods only).")
@click.option("--backend", type=click.Choice(BACKENDS), default="numba", show_default=True)
@click.option("--dtype", type=click.Choice(DTYPES), default="float64", show_default=True)
@click.option("--threads", type=int, default=None, callback=positive_int("threads"),
              help="numba threads for one filter's particle loops (default: the cores not busy with other "
                   "processes now; 1: sequential).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the filter's random numbers.")
@click.option("--truth-seed", type=click.IntRange(min=0), default=None,
              help="Seed of the simulated truth (default: a stream derived from --seed, apart from the "
                   "filter's, so the filter never shares the truth's noise).")
@click.option("--param", "params", multiple=True, metavar="KEY=VALUE", help=PARAM_HELP)
@click.option("--data", type=NonEmptyPath(dir_okay=False), default=None,
              help="CSV log (time_s, y..., u...) to filter instead of a simulation.")
@click.option("--out", "out_file", **OUT_FILE, default=None,
              help="Write the per-step estimates, variances, ESS and log-likelihood increments to this "
                   ".csv or .parquet file (and the run's provenance to <file>.json).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--strict", is_flag=True, help="A non-finite log-likelihood, or one the model returned as NaN or "
              "+inf for some particles, is an error (exit 2), not a warning.")
def run(model_name, method, particles, filters, steps, resampling, ess_threshold, estimate, backend, dtype,
        threads, seed, truth_seed, params, data, out_file, as_json, strict):
    """Simulate a model, run a filter, print aRMSE, log-likelihood and speed."""
    import numpy as np

    from . import metrics, models
    from .filters import run_filter

    name, kw = models.parse_spec(model_name, parse_key_values(params, "--param"))
    model = models.get(name, **kw)
    _refuse_unused(method, data)
    if out_file and Path(out_file).suffix.lower() not in (".csv", ".parquet"):
        raise click.BadParameter(f"{out_file}: the file must end in .csv or .parquet", param_hint="'--out'")
    if out_file:
        from .resources import check_writable

        check_writable(Path(out_file), "--out")
    if filters > 1 and method != "multipdf":
        raise click.BadParameter(f"--filters {filters} needs --method multipdf", param_hint="'--filters'")
    if filters > particles:
        raise click.BadParameter(f"{filters} sub-filters for {particles} particles: need --filters <= --particles",
                                 param_hint="'--filters'")
    if not data:  # check before you spend: refuse what cannot fit before simulating/allocating
        from .resources import check_filter_memory

        check_filter_memory(model, method, particles, n_filters=filters, n_steps=steps, dtype=dtype,
                            backend=backend)
    if data:
        from .plants.datalog import load_log

        traj = load_log(data, model, max_rows=steps if _given("steps") else None)
        if _given("steps"):
            traj = _first_rows(traj, steps, data)
    else:
        traj = model.simulate(steps, seed=truth_stream(seed) if truth_seed is None else truth_seed)
    with compile_notice():
        res = run_filter(model, traj.y, traj.u, method=method, n_particles=particles, n_filters=filters,
                         resampling=resampling, ess_threshold=ess_threshold, backend=backend, dtype=dtype,
                         seed=seed, n_threads=threads, estimate=estimate)
    from .procs import numba_threads

    if threads is not None and threads > numba_threads():
        click.echo(f"note: --threads {threads}: numba has {numba_threads()} threads here (NUMBA_NUM_THREADS, "
                   "the cores), so the run used at most that many", err=True)
    have_truth = bool(np.all(np.isfinite(traj.x)))
    out = {
        "model": name, "params": kw, "method": method, "backend": backend, "dtype": dtype,
        "n_particles": res.n_particles, "n_filters": res.n_filters, "n_steps": traj.n_steps,
        "seed": seed, "truth_seed": None if data else (truth_seed if truth_seed is not None else
                                                      f"derived from --seed {seed} ({TRUTH_STREAM})"),
        "resampling": resampling, "estimate": estimate,
        "armse": metrics.armse(res.estimates, traj.x) if have_truth else None,
        "rmse": metrics.rmse(res.estimates, traj.x).tolist() if have_truth else None,
        "loglik": res.loglik, "n_resampled": res.n_resampled,
        "n_degenerate_steps": int(res.degenerate.sum()),
        "elapsed_s": res.elapsed_s,
        "ns_per_particle_step": res.ns_per_particle_step,
    }
    if "threads" in res.info:
        out["threads"] = res.info["threads"]
    if method == "kalman":  # no particles: what is printed for a particle filter would be noise here
        for key in ("n_particles", "resampling", "estimate", "n_resampled", "n_degenerate_steps"):
            del out[key]
        out["ns_per_step"] = out.pop("ns_per_particle_step")
    if "n_particles_requested" in res.info:
        out["n_particles_requested"] = res.info["n_particles_requested"]
    if res.info.get("note"):
        out["note"] = res.info["note"]
    bad = res.first_nonfinite_step()
    if bad is not None:
        from .filters.result import NON_FINITE_WHY

        why = f"the log-likelihood is {res.loglik} from step {bad} on: there {NON_FINITE_WHY}"
        if strict:
            raise PfbenchError(why)
        click.echo(f"warning: {why}", err=True)
    from .filters.result import invalid_message

    if "invalid_log_likelihoods" in res.info:
        out["invalid_log_likelihoods"] = res.info["invalid_log_likelihoods"]
    invalid = invalid_message(res.info)
    if invalid:
        if strict:
            raise PfbenchError(invalid)
        click.echo(f"warning: {invalid}", err=True)
    if out_file:
        from . import io
        from .provenance import provenance

        frame = res.to_dataframe(getattr(model, "state_names", None))
        (io.write_parquet if Path(out_file).suffix.lower() == ".parquet" else io.write_csv)(out_file, frame)
        from .sources import file_hash

        data_in = {"data": str(data), "data_sha256": file_hash(str(data))} if data else {}
        io.write_json(f"{out_file}.json", provenance(command="pfbench run", **data_in,
                                                     **{k: v for k, v in out.items() if k != "rmse"}))
    if as_json:
        from .io import to_json

        if not math.isfinite(res.loglik):
            why = (f"{int(res.degenerate.sum())} degenerate steps (every particle weight zero)"
                   if res.degenerate.any() else "the likelihood under/overflowed")
            out["loglik_nonfinite"] = f"{res.loglik}: {why}"
        click.echo(to_json(out, default=str))
        return
    for k, v in out.items():
        if k == "note" or (k == "params" and not v):
            continue
        if isinstance(v, float):
            v = f"{v:.6g}"
        click.echo(f"{k:>22}: {v}")
    if out.get("note"):
        click.echo(f"note: {out['note']}")


def _given(name: str) -> bool:
    """Whether the current command's option ``name`` (its parameter name) was given by the user."""
    from click.core import ParameterSource

    return click.get_current_context().get_parameter_source(name) not in (ParameterSource.DEFAULT, None)


#: the ``run`` options each method cannot use (the Kalman filter is exact: no particles, no random
#: numbers of its own, float64)
_UNUSED = {"kalman": ("particles", "resampling", "dtype", "threads"), "sis": ("resampling",)}


def _refuse_unused(method: str, data) -> None:
    """An option given for a run that cannot use it is a usage error naming it, as ``--ess-threshold``
    with ``bootstrap`` is, rather than a value printed beside results it did not shape."""
    unused = [f"--{n.replace('_', '-')}" for n in _UNUSED.get(method, ()) if _given(n)]
    if unused:
        why = "it never resamples" if method == "sis" else "it is exact: no particles, no draws, float64"
        raise click.UsageError(f"{', '.join(unused)} cannot apply to --method {method} ({why})")
    if data and _given("truth_seed"):
        raise click.UsageError("--truth-seed seeds the simulated truth, and with --data nothing is simulated")


def _first_rows(traj, steps: int, data):
    """The first ``steps`` rows of a log loaded up to that many rows (``--steps`` with ``--data``);
    fewer rows are refused."""
    import dataclasses

    if steps > traj.n_steps:
        raise click.BadParameter(f"{steps} steps, but {data} has {traj.n_steps} rows", param_hint="'--steps'")
    return dataclasses.replace(traj, x=traj.x[:steps], y=traj.y[:steps],
                               u=None if traj.u is None else traj.u[:steps])


# --------------------------------------------------------------------------- compile
@main.command("compile")
@click.option("--model", "model_names", default=None, metavar="MODEL[,MODEL...]", shell_complete=complete_models,
              help="Model specs as for `run`, comma-separated (default: every registered model).")
@click.option("--method", "methods", type=ChoiceList(METHODS), default="bootstrap", show_default=True,
              metavar="METHOD[,METHOD...]", help=f"Comma-separated methods: {', '.join(METHODS)}.")
@click.option("--resampling", "schemes", type=ChoiceList(SCHEMES), default="systematic", show_default=True,
              metavar="SCHEME[,SCHEME...]", help=f"Comma-separated schemes: {', '.join(SCHEMES)}.")
@click.option("--dtype", "dtypes", type=ChoiceList(DTYPES), default="float64", show_default=True,
              metavar="DTYPE[,DTYPE...]", help=f"Comma-separated particle dtypes: {', '.join(DTYPES)}.")
@click.option("--all-threads", is_flag=True,
              help="Also the all-threads kernel of one particle filter (used above 8192 particles "
                   "unless --threads 1).")
@click.option("--jobs", type=int, default=None, callback=positive_int("jobs"),
              help="Processes compiling side by side (default: all cores).")
@click.option("--json", "as_json", is_flag=True, help="Print the rows as JSON.")
def compile_cmd(model_names, methods, schemes, dtypes, all_threads, jobs, as_json):
    """Compile kernels ahead of the first run, so later runs load them from the cache.

    Each configuration runs once on a tiny problem; `make all` does this for every model's
    default `pfbench run`. Exit code 2 if a configuration failed, not if it is not applicable.
    """
    from . import models
    from .backends.cache import check_cache_dir
    from .precompile import compile_all, targets, text

    from .options import comma_list

    specs = comma_list(model_names, "--model") if model_names is not None else models.names()
    for spec in specs:  # one-line errors for bad names before any process starts
        name, kw = models.parse_spec(spec)
        models.get(name, **kw)
    todo = targets(specs, comma_list(methods, "--method", METHODS), comma_list(schemes, "--resampling", SCHEMES),
                   comma_list(dtypes, "--dtype", DTYPES), all_threads)
    cache = check_cache_dir()  # an unusable cache is one line before any process starts
    rows = compile_all(todo, jobs=jobs, progress=not as_json)
    if as_json:
        from .io import to_json

        click.echo(to_json(rows))
    else:
        for line in text(rows, str(cache)):
            click.echo(line)
    failed = [r for r in rows if r["status"] == "failed"]
    if failed:
        raise PfbenchError(f"compile: {len(failed)} configuration(s) failed, the first: {failed[0]['model']} "
                           f"{failed[0]['method']}: {failed[0]['detail']}")


# --------------------------------------------------------------------------- recipes
@main.command("list")
@click.option("--json", "as_json", is_flag=True,
              help="Print the recipes as JSON (costs also in seconds: quick_cost_s, full_cost_s).")
def list_cmd(as_json):
    """List the registered recipes (ID, quick/full cost, title, --option keys, --data)."""
    from .recipes import cost_seconds, discover

    reg = discover()
    if as_json:
        from .io import to_json

        click.echo(to_json([{"id": r.id, "aliases": list(r.aliases), "paper": r.paper, "title": r.title,
                                "quick_cost": r.quick_cost, "full_cost": r.full_cost,
                                "quick_cost_s": cost_seconds(r.quick_cost), "full_cost_s": cost_seconds(r.full_cost),
                                "needs": list(r.needs), "reads_data": r.reads_data,
                                "options": {o.key: o.as_dict() for o in r.options}}
                               for r in reg.values()]))
        return
    if not reg:
        click.echo("no recipes registered")
        return
    w = max(len(r.id) for r in reg.values())
    click.echo(f"{'ID'.ljust(w)}  {'quick':>10}  {'full':>10}  title")
    for r in reg.values():
        alias = f" (alias: {', '.join(r.aliases)})" if r.aliases else ""
        click.echo(f"{r.id.ljust(w)}  {r.quick_cost:>10}  {r.full_cost:>10}  {r.title}{alias}")
        extra = ([f"--option {', '.join(r.option_keys)}"] if r.options else []) + \
            (["--data FILE"] if r.reads_data else [])
        if extra:
            click.echo(f"{''.ljust(w)}  {'':>10}  {'':>10}    takes {'; '.join(extra)}")
    click.echo("`pfbench options ID` explains a recipe's options.")


@main.command("options")
@click.argument("recipe_id", shell_complete=complete_recipes)
@click.option("--json", "as_json", is_flag=True, help="Print the recipe's options as one JSON object.")
def options_cmd(recipe_id, as_json):
    """The --option keys a recipe takes (type, allowed values, help) and whether it reads --data."""
    from .recipes import resolve

    rec = resolve(recipe_id)
    if as_json:
        from .io import to_json

        click.echo(to_json({"id": rec.id, "title": rec.title, "options": {o.key: o.as_dict() for o in rec.options},
                            "reads_data": rec.reads_data}))
        return
    click.echo(f"{rec.id}: {rec.title}")
    if not rec.options:
        click.echo("  (no --option keys)")
    w = max((len(o.key) for o in rec.options), default=0)
    rw = max((len(o.range_text) for o in rec.options), default=0)
    for o in rec.options:
        click.echo(f"  {o.key.ljust(w)}  {o.type_name:<5}  {o.range_text.ljust(rw)}  {o.help}")
    click.echo("  --data FILE: " + ("a log to run on instead of a simulation" if rec.reads_data
                                    else "not accepted (the recipe reads no data)"))


@main.command()
@click.argument("recipe_ids", nargs=-1, shell_complete=complete_recipes)
@click.option("--all", "run_all", is_flag=True, help="Run every registered recipe.")
@click.option("--paper", default=None, shell_complete=complete_papers,
              help="Every recipe of this paper (alone or with --all).")
@click.option("--full", is_flag=True, help="Paper scale (slow; shows a progress bar).")
@click.option("--backend", type=click.Choice(BACKENDS), default="numba", show_default=True)
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option("--out", "out_root", **OUT_DIR, default="results", show_default=True,
              help="Results folder (results/<paper>/ per recipe).")
@click.option("--data", type=click.Path(dir_okay=False, exists=True), default=None,
              help="Run the recipe on a real log instead of a simulation (where supported).")
@click.option("--option", "options", multiple=True, metavar="KEY=VALUE",
              help="Recipe option (repeatable; `pfbench options ID` lists a recipe's keys).")
@click.option("--quiet", is_flag=True)
@click.option("--force", is_flag=True,
              help="With --all: rerun recipes whose verified result is already up to date.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object when done: per recipe its status, result folder, comparisons, "
                   "claims and notes (the progress lines go to stderr).")
def reproduce(recipe_ids, run_all, paper, full, backend, seed, out_root, data, options, quiet, force, as_json):
    """Run recipe(s): `pfbench reproduce fig5`, `pfbench reproduce multipdf:fig3 --full`.

    With --all, a recipe whose result set verifies and was made by the same code with the same
    mode, seed, backend, options and data is skipped as up to date, so an interrupted
    `reproduce --all --full` resumes where it stopped (--force reruns everything)."""
    from . import recipes

    def say(text):  # with --json, stdout holds only the JSON object
        click.echo(text, err=as_json)

    if run_all and recipe_ids:
        raise click.UsageError("give recipe IDs or --all, not both")
    if paper is not None and recipe_ids:
        raise click.UsageError("--paper runs every recipe of a paper (as --all --paper): give recipe IDs "
                               "or --paper, not both")
    run_all = run_all or paper is not None
    if run_all:
        recs = recipes.select(paper)
    elif recipe_ids:
        recs = [recipes.resolve(r) for r in recipe_ids]
        for name, rec in zip(recipe_ids, recs):
            if others := recipes.same_name(name, rec):
                click.echo(f"note: {name} is {rec.id}; {' and '.join(others)} also exist", err=True)
    else:
        raise click.UsageError("name a recipe (see `pfbench list`) or pass --all")
    opts = parse_key_values(options, "--option")
    # Validate every recipe's options (and --data) before running any of them. With several
    # recipes each gets the keys it declares; a key that none of them declares is an error.
    per_recipe = {}
    for rec in recs:
        mine = opts if len(recs) == 1 else {k: v for k, v in opts.items() if k in rec.option_keys}
        per_recipe[rec.id] = rec.check_options(mine)
    if len(recs) > 1:
        from .options import check_known

        check_known(opts, {k for r in recs for k in r.option_keys}, "an option of the selected recipes")
    recipes.check_data(recs, data)
    failed, done = [], []
    for k, rec in enumerate(recs, 1):
        step = f"[{k}/{len(recs)}] " if len(recs) > 1 else ""
        if run_all and rec.needs and not recipes.needs_met(rec.needs):
            say(f"-- {step}{rec.id}: skipped ({recipes.needs_hint(rec.needs)})")
            done.append({"id": rec.id, "status": "skipped", "reason": recipes.needs_hint(rec.needs)})
            continue
        rec_data = data if (rec.reads_data or len(recs) == 1) else None
        if run_all and not force and recipes.up_to_date(rec, out_root=out_root, full=full, seed=seed,
                                                        backend=backend, options=per_recipe[rec.id],
                                                        data=rec_data):
            say(f"-- {step}{rec.id}: up to date (verified result of this code and settings; --force reruns)")
            done.append({"id": rec.id, "status": "up to date"})
            continue
        say(f"== {step}{rec.id}: {rec.title} ({'full' if full else 'quick'}, {backend})")
        try:
            with compile_notice(show=not quiet):
                ctx = recipes.run(rec, full=full, backend=backend, seed=seed, out_root=out_root,
                                  data=rec_data, quiet=quiet, options=per_recipe[rec.id])
        except PfbenchError as exc:
            if not run_all:
                raise
            failed.append(rec.id)
            done.append({"id": rec.id, "status": "failed", "error": _one_line(exc)})
            click.echo(f"error: {rec.id}: {_one_line(exc)}", err=True)
            continue
        done.append({"id": rec.id, "status": "ran", "out_dir": str(ctx.out_dir), "files": list(ctx.outputs),
                     "elapsed_s": ctx.extra["elapsed_s"], "comparisons": [c.as_dict() for c in ctx.comparisons],
                     "claims": ctx.claims, "notes": ctx.notes})
        if as_json:
            continue
        click.echo(recipes.format_comparisons(ctx.comparisons))
        for c in ctx.claims:
            click.echo(f"claim: {c['verdict']:<16} {c['claim']} ({c['where']})")
        for n in ctx.notes:
            click.echo(f"note: {n}")
        click.echo(f"-> {ctx.out_dir} ({len(ctx.outputs)} files, {ctx.extra['elapsed_s']:.1f} s)")
    if as_json:
        from .io import to_json

        click.echo(to_json({"mode": "full" if full else "quick", "backend": backend, "seed": seed,
                            "out": str(out_root), "recipes": done}, default=str))
    if failed:
        raise PfbenchError(f"{len(failed)} recipe(s) failed: {', '.join(failed)}")


@main.command()
@click.option("--out", "out_root", **OUT_DIR, default="results", show_default=True,
              help="Results folder to report on (REPORT.md is written there).")
@click.option("--strict", is_flag=True,
              help="Exit 2 if a result is damaged: a record that is not valid JSON, or an "
                   "artefact that is missing or differs from its record's checksum.")
@click.option("--json", "as_json", is_flag=True, help="Print the scorecard, claims and problems as JSON.")
@click.option("--compare", "compare", type=click.Path(exists=True, file_okay=False), metavar="DIR", default=None,
              help="Another results folder (e.g. a quick run kept beside a --full one): list every "
                   "claim whose verdict differs from it.")
def report(out_root, strict, as_json, compare):
    """Regenerate results/REPORT.md (the scorecard, with a report per paper beside it) from the
    provenance records, each verified against the checksums of its files. Damaged results are
    printed as warnings; they and the recipes that have not been run are listed in the report's
    "Not reproduced / damaged" section. With --json the same data is printed and nothing is written."""
    from .report import Problem, check_results, compare_verdicts, report_data, write_report

    if not Path(out_root).is_dir():   # a mistyped folder was created, with every recipe "not run"
        raise InputError(f"cannot report on {out_root}: no such results folder (`pfbench reproduce --out "
                         f"{out_root}` writes one)")
    if as_json:
        from .io import to_json

        data = report_data(out_root, compare)
        click.echo(to_json(data))
        damaged = [Problem(**p) for p in data["problems"] if p["damaged"]]
        for p in damaged:
            click.echo(f"warning: {_one_line(p.line())}", err=True)
        if strict and damaged:
            raise PfbenchError(f"report --strict: {len(damaged)} result(s) damaged or incomplete")
        return
    path, problems = write_report(out_root, compare)
    damaged = [p for p in problems if p.damaged]
    for p in damaged:
        click.echo(f"warning: {_one_line(p.line())}", err=True)
    click.echo(f"wrote {path}")
    if compare is not None:
        cmp = compare_verdicts(check_results(out_root)[0], compare)
        click.echo(f"against {compare}: {cmp['matched']} claims matched, {len(cmp['changed'])} "
                   "changed verdict" + "".join(f"; {t}: {n}" for t, n in cmp["transitions"].items()))
    if len(problems) > len(damaged):
        click.echo(f"{len(problems) - len(damaged)} note(s): recipes not run, leftovers of an "
                   "interrupted run or a sentence scored twice (listed in the report)")
    if strict and damaged:
        raise PfbenchError(f"report --strict: {len(damaged)} result(s) damaged or incomplete "
                           f"(listed in {path})")


# --------------------------------------------------------------------------- models / info
@main.command("models")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object per model, in a list.")
def models_cmd(as_json):
    """The registered models: description, dimensions (n_x states, n_y measurements, n_u inputs)
    and which of the methods that need declared structure (mpf, guided, kalman) each supports, at
    its default parameters."""
    from . import models
    from .models.catalog import describe

    rows = [describe(name) for name in models.names()]
    if as_json:
        from .io import to_json

        click.echo(to_json(rows))
        return
    w = max((len(r["name"]) for r in rows), default=4)
    click.echo(f"{'model'.ljust(w)}  n_x  n_y  n_u  {'supports':<18}  description")
    for r in rows:
        also = ", ".join(m for m, ok in r["supports"].items() if ok) or "-"
        click.echo(f"{r['name'].ljust(w)}  {r['n_x']:>3}  {r['n_y']:>3}  {r['n_u']:>3}  {also:<18}  {r['description']}")


@main.command()
@click.option("--json", "as_json", is_flag=True)
def info(as_json):
    """CPU, core count, numba threading layer, package versions, GPU and CuPy, registered models."""
    from . import models
    from .provenance import host_info, numba_threading_layer, package_versions

    from .backends.cupy_backend import gpu_info

    data = {"host": host_info(), "numba_threading_layer": numba_threading_layer(),
            "packages": package_versions(), "gpu": gpu_info(), "models": models.names()}
    if as_json:
        from .io import to_json

        click.echo(to_json(data))
        return
    for k, v in data["host"].items():
        click.echo(f"{k:>22}: {v}")
    click.echo(f"{'numba threading layer':>22}: {data['numba_threading_layer']}")
    for k, v in data["packages"].items():
        click.echo(f"{k:>22}: {v}")
    g = data["gpu"]
    click.echo(f"{'cupy':>22}: {g.get('cupy') or 'not installed'}")
    click.echo(f"{'gpu':>22}: {g.get('gpu')}" + (f" ({g['gpu_memory_bytes'] / 2**30:.0f} GiB, CUDA runtime "
                                                 f"{g['cuda_runtime']})" if g.get("gpu_memory_bytes") else ""))
    click.echo(f"{'models':>22}: {', '.join(data['models'])} (`pfbench models` describes them)")


#: subcommand groups that live next to their subsystem: name -> (module, attribute), imported on use
SUBSYSTEMS = {"bench": ("pfbench.bench", "bench"), "mcu": ("pfbench.mcu.cli", "mcu"),
              "sweep": ("pfbench.sweep.cli", "sweep"), "compare": ("pfbench.compare.cli", "compare"),
              "tasks": ("pfbench.tasks", "tasks_cmd")}


def _add_subsystem_command(name: str) -> None:
    """Import subsystem ``name`` and add its group to :func:`main` (nothing if it is not installed)."""
    modname, attr = SUBSYSTEMS[name]
    try:
        mod = importlib.import_module(modname)
    except ModuleNotFoundError as exc:
        if exc.name == modname or (exc.name and modname.startswith(exc.name + ".")):
            return
        raise
    main.add_command(getattr(mod, attr), name)

if __name__ == "__main__":
    main()
