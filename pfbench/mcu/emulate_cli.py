"""``pfbench mcu emulate``: cross-compile the C filter, count executed Cortex-M4 instructions.

Needs the optional toolchain (``make mcu-tools``); without it the command says so in one line.
"""
from __future__ import annotations


import click

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


@click.command()
@click.option("--precision", type=click.Choice(["float", "double"]), default="float",
              show_default=True, help="float = D(O) (FPU, -Ofast); double = D(S) (soft double, -O0).")
@click.option("--steps", "-M", type=int, default=1000, show_default=True,
              help="M iterations to predict for.")
@click.option("--particles", "-N", type=int, default=1000, show_default=True,
              help="N particles to predict for.")
@click.option("--configs", default=None,
              help="Small MxN configurations to emulate and fit (default depends on precision).")
@click.option("--opt", default=None, help="Override the -O level of the build (e.g. -O2).")
@click.option("--clock-mhz", type=float, default=None, help="Core clock (default 168 MHz).")
@click.option("--seed", type=int, default=1, show_default=True, help="srand() seed in the C code.")
@click.option("--json", "as_json", is_flag=True, help="Print the full result as JSON.")
def emulate(precision, steps, particles, configs, opt, clock_mhz, seed, as_json):
    """Emulate the C bootstrap filter (Ob1) on a Cortex-M4F and predict STM32F4 time.

    Builds D(S)/D(O) (cached), runs small (M, N) in the unicorn emulator, counts executed
    instructions by class and function, converts them to cycles with the Cortex-M4 timing
    table, fits cost = a + b*M + c*M*N and extrapolates to (--steps, --particles) and to
    Table 2 of [Embedded].
    """
    from . import emulate as E
    from . import toolchain

    why = toolchain.missing()
    if why:
        raise PfbenchError("mcu emulate needs the cross toolchain: " + "; ".join(why))
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
               + (f"{an:.0f} ms" if an is not None else "n/a (pfbench.mcu.costmodel missing)"))
    click.echo("\nTable 2 ([Embedded])      paper ms   emulated ms   (best-worst)      analytic ms")
    for row in res["table2"]:
        a = row["analytic_ms"]
        click.echo(f"  M={row['steps']:4d} N={row['particles']:4d}  {row['paper_ms']:10.0f}  "
                   f"{row['emulated_ms']:12.0f}   ({row['emulated_ms_best']:.0f}-"
                   f"{row['emulated_ms_worst']:.0f})  "
                   + (f"{a:12.0f}" if a is not None else "         n/a"))
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
