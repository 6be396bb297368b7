"""``pfbench mcu emulate``: cross-compile a C filter, count executed Cortex-M4 instructions.

Without ``--model``: the hand-written Ob1 port ``pf_ob1.c`` ([Embedded] Table 2 benchmark).
With ``--model NAME``: the model's own code (the functions the numba backend compiles),
compiled for Cortex-M4 and linked into the generic harness ``pf_model.c``.
Needs the optional toolchain (``make mcu-tools``); without it the command says so in one line.
"""
from __future__ import annotations


import click

from ..clitypes import complete_models, positive_float, positive_int
from ..errors import InputError, PfbenchError


def _parse_configs(text: str | None):
    if not text:
        return None
    out = []
    for part in text.split(","):
        try:
            m, n = part.lower().split("x")
            out.append((int(m), int(n)))
        except ValueError as exc:
            raise InputError(f"--configs: expected MxN[,MxN...] (e.g. 10x50,20x50,10x100), "
                             f"got {part!r}") from exc
    return out


def _check_fits(spec: str, params: dict, precision: str, steps: int, particles: int, core: str) -> None:
    """The filter asked for must fit the core's chip, as `mcu estimate` checks: a time predicted for
    N particles the chip cannot hold answers no question (an InputError with the largest N that fits)."""
    from .. import models
    from .costmodel import check_memory

    name, kw = models.parse_spec(spec, params)
    check_memory(models.get(name, **kw), particles, steps, precision, core=core, history_flag=None)


@click.command()
@click.option("--model", "model_name", default=None, metavar="NAME", shell_complete=complete_models,
              help="Run this registered model's OWN compiled code (e.g. ob1, ob3:v4, pmsm) in the "
                   "generic C harness. Without --model: the hand-written Ob1 port pf_ob1.c "
                   "(the [Embedded] Table 2 benchmark, object simulated on the MCU).")
@click.option("--param", "params", multiple=True, metavar="KEY=VALUE",
              help="Model parameter for --model (repeatable; JSON-typed as `pfbench run --param`).")
@click.option("--precision", type=click.Choice(["float", "double"]), default="float",
              show_default=True, help="float = FPU single precision (-Ofast); double = soft-float "
                                      "double (-O0; hand port: D(S), --model: M4F hard-float ABI).")
@click.option("--steps", "-M", type=int, default=None, callback=positive_int("steps"),
              help="M iterations to predict for [default: 1000; with --model 100].")
@click.option("--particles", "-N", type=int, default=None, callback=positive_int("particles"),
              help="N particles to predict for [default: 1000; with --model 500].")
@click.option("--configs", default=None,
              help="Small MxN configurations to emulate and fit (default depends on precision).")
@click.option("--opt", default=None, help="Override the -O level of the build (e.g. -O2).")
@click.option("--clock-mhz", type=float, default=None, callback=positive_float("clock-mhz"),
              help="Core clock (default: the core's typical chip, 168 MHz for the M4).")
@click.option("--core", default="m4", show_default=True,
              help="Cortex-M core (m0plus, m3, m4, m7, m33): with --model the code is compiled "
                   "for it and timed with its table data/cortex_<core>_timing.json (m7 code with "
                   "double-precision FPU instructions cannot run in unicorn, and the harness has "
                   "such instructions at either precision); the hand port is "
                   "always the M4F build.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=1, show_default=True,
              help="srand() seed in the C code (and the host simulation seed with --model).")
@click.option("--tile", type=click.IntRange(1, 1024), default=32, show_default=True,
              help="With --model: particles per model call (PF_TILE); numba's per-call array "
                   "allocations are spread over a tile, its temporaries are a tile large.")
@click.option("--json", "as_json", is_flag=True, help="Print the full result as JSON.")
def emulate(model_name, params, precision, steps, particles, configs, opt, clock_mhz, core, seed,
            tile, as_json):
    """Emulate a C bootstrap filter on a Cortex-M core and predict its chip's time.

    Builds the image (cached), runs small (M, N) in the unicorn emulator, counts executed
    instructions by class and function, converts them to cycles with the Cortex-M4 timing
    table, fits cost = a + b*M + c*M*N and extrapolates to (--steps, --particles).  Without
    --model it runs the hand-written Ob1 port and compares with Table 2 of [Embedded]; with
    --model it runs the model's own compiled code and reports the share of double-precision
    work, RAM, the tracking error and the analytic cost model's prediction beside it.
    """
    from ..options import parse_key_values
    from . import emulate as E
    from . import toolchain

    if model_name is None and params:
        raise InputError("--param needs --model")
    if model_name is None and core != "m4":
        raise InputError("--core applies to --model runs; the Ob1 port is timed on the M4")
    steps, particles = steps or (100 if model_name else 1000), particles or (500 if model_name else 1000)
    kw = parse_key_values(params, "--param")
    _check_fits(model_name or "ob1", kw, precision, steps, particles, core)
    why = toolchain.missing()
    if why:
        raise PfbenchError("mcu emulate needs the cross toolchain: " + "; ".join(why))
    if model_name is not None:
        res = E.emulate_model(model_name, precision, steps, particles, configs=_parse_configs(configs), seed=seed,
                              core=core, params=kw, clock_mhz=clock_mhz, opt=opt, tile=tile)
        _print_model(res, as_json)
        return
    res = E.emulate(precision, steps, particles, configs=_parse_configs(configs),
                    clock_mhz=clock_mhz, seed=seed, opt=opt)
    if as_json:
        from ..io import to_json

        click.echo(to_json(res, indent=2, default=float))
        return
    click.echo(f"{res['build']} ({precision}) {' '.join(res['cflags'][-4:])}  [{res['compiler']}]")
    click.echo(f"per particle-step: {res['instructions_per_particle_step']:.0f} instructions, "
               f"{res['cycles_per_particle_step']:.0f} cycles (best-worst "
               f"{res['cycles_per_particle_step_range'][0]:.0f}-"
               f"{res['cycles_per_particle_step_range'][1]:.0f}), CPI {res['cpi']:.2f}")
    click.echo(f"per step: {res['instructions_per_step']:.0f} instructions, "
               f"{res['cycles_per_step']:.0f} cycles; fit residual "
               f"{100 * res['fit_residual_rel']:.2f}%")
    an = res["analytic_ms"]
    click.echo(f"M={steps} N={particles} @ {res['clock_mhz']:.0f} MHz: emulated "
               f"{res['predicted_ms']:.0f} ms (best-worst {res['predicted_ms_range'][0]:.0f}-"
               f"{res['predicted_ms_range'][1]:.0f}); analytic model "
               + (f"{an:.0f} ms" if an is not None else f"n/a ({res['analytic'].get('error')})"))
    click.echo(f"\nTable 2 ([Embedded], 168 MHz; ours at {res['clock_mhz']:g} MHz)"
               + "\n                          paper ms   emulated ms   (best-worst)      analytic ms (its efficiency "
                 "is fitted to these cells)")
    for row in res["table2"]:
        a = row["analytic_ms"]
        click.echo(f"  M={row['steps']:4d} N={row['particles']:4d}  {row['paper_ms']:10.0f}  "
                   f"{row['emulated_ms']:12.0f}   ({row['emulated_ms_best']:.0f}-"
                   f"{row['emulated_ms_worst']:.0f})  "
                   + (f"{a:12.0f}" if a is not None else "         n/a"))
    over = min(row["emulated_ms_best"] / row["paper_ms"] for row in res["table2"]) - 1.0
    if res["clock_mhz"] == 168 and over > 0:  # at the paper's clock: zero wait states can only be faster
        click.echo(f"our C at zero wait states, best case, is {over:.0%} or more above every paper cell, where a "
                   "board with flash wait states runs slower still: our port does more work than the "
                   "authors' (unpublished) C")
    click.echo("\ninstruction classes per particle-step: " + ", ".join(
        f"{k} {v:.1f}" for k, v in res["classes_per_particle_step"].items() if v > 0.05))
    for title, key in (("cycles per particle-step by library call (inclusive)",
                        "by_library_call_inclusive"),
                       ("by C function (inclusive of its library calls)",
                        "by_c_function_inclusive"),
                       ("by function (self)", "by_function_self"), ("by phase", "by_phase")):
        d = res["breakdown"][key]
        tot = res["cycles_per_particle_step"]
        click.echo(f"\n{title}:")
        for name, v in list(d.items())[:10]:
            click.echo(f"  {name:28s} {v:10.1f}  {100 * v / tot:5.1f}%")
    click.echo("\nNot seen by the emulator: " + res["unseen"])


def _print_model(res: dict, as_json: bool) -> None:
    if as_json:
        from ..io import to_json

        click.echo(to_json(res, indent=2, default=float))
        return
    m, n = res["steps"], res["particles"]
    click.echo(f"{res['model']} ({res['precision']}, own compiled code in pf_model.c, tile "
               f"{res['tile']}) "
               f"{' '.join(f for f in res['cflags'] if f.startswith(('-mf', '-O')))}  "
               f"[{res['compiler']}]")
    click.echo(f"per particle-step: {res['instructions_per_particle_step']:.0f} instructions, "
               f"{res['cycles_per_particle_step']:.0f} cycles (best-worst "
               f"{res['cycles_per_particle_step_range'][0]:.0f}-"
               f"{res['cycles_per_particle_step_range'][1]:.0f}), CPI {res['cpi']:.2f}; model "
               f"functions {res['model_cycles_per_particle_step']:.0f} cycles")
    click.echo(f"double-precision work: {100 * res['double_share']:.1f}% of particle-step cycles")
    click.echo(f"per step: {res['cycles_per_step']:.0f} cycles; fit residual "
               f"{100 * res['fit_residual_rel']:.2f}%")
    cm = res.get("costmodel") or {}
    an = (f"cost model {cm['predicted_ms']:.1f} ms (error {100 * cm['error']:+.0f}%; paper's "
          f"board layer {cm['board_ms']:.1f} ms)"
          if "predicted_ms" in cm else f"cost model n/a ({cm.get('error', 'not run')})")
    click.echo(f"M={m} N={n} @ {res['clock_mhz']:.0f} MHz ({res['core']}): emulated "
               f"{res['predicted_ms']:.1f} ms (best-worst {res['predicted_ms_range'][0]:.1f}-"
               f"{res['predicted_ms_range'][1]:.1f}); {an}")
    runs = res["emulated_configs"]
    ns, big = sorted({r["particles"] for r in runs}), max(runs, key=lambda r: r["steps"] * r["particles"])
    if n < ns[0] or res["cycles_per_step"] < 0:
        click.echo(f"note: N={n} is below the emulated runs' N = {ns[0]}..{ns[-1]}: the prediction extrapolates "
                   "the fitted line a + b M + c M N" + (
                       f", whose fixed cost per step is negative ({res['cycles_per_step']:.0f} cycles), so it "
                       "underestimates small N" if res["cycles_per_step"] < 0 else "")
                   + "; emulate that size (--configs) to measure it")
    ram = res["ram"]
    click.echo(f"RAM of the largest emulated run (M={big['steps']}, N={big['particles']}; `mcu estimate` "
               f"sizes M={m}, N={n}): {ram['total_bytes']} bytes (.data {ram['data_bytes']}, "
               f".bss {ram['bss_bytes']}, stack {ram['stack_bytes']}, heap {ram['heap_bytes']}; "
               f"host-written y/u/x logs {ram['input_bytes']})")
    tr = res["tracking"]
    click.echo(f"tracking (M={tr['steps']}, N={tr['particles']}): RMSE emulated / host NumPy "
               "bootstrap: " + ", ".join(f"{s} {a:.3g}/{b:.3g}" for s, a, b in zip(
                   tr["state_names"], tr["emulated_rmse"], tr["host_rmse"])))
    click.echo(f"same filter in float64 NumPy with the target's random numbers: SSE relative "
               f"difference {tr['crn_rel_diff']:.2g}")
    tot = res["cycles_per_particle_step"]
    for title, key in (("cycles per particle-step by library call (inclusive)",
                        "by_library_call_inclusive"),
                       ("by C function (inclusive of its library calls)",
                        "by_c_function_inclusive")):
        click.echo(f"\n{title}:")
        for name, v in list(res["breakdown"][key].items())[:10]:
            click.echo(f"  {name:28s} {v:10.1f}  {100 * v / tot:5.1f}%")
    click.echo("\nNot seen by the emulator: " + res["unseen"])
