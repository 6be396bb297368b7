"""``pfbench mcu ...``: Cortex-M cost model commands (estimate, fit, calibrate)."""
from __future__ import annotations


import click

from ..clitypes import NonEmptyPath, complete_models, positive_float, positive_int
from ..methods import PARTICLE_METHODS
from ..io import to_json
from ..options import parse_key_values
from ..resampling import SCHEMES


@click.group()
def mcu():
    """Cortex-M time, energy and memory predictions (M0+, M3, M4F, M7, M33)."""



@mcu.command()
@click.option("--model", "model_name", default="ob1", show_default=True, shell_complete=complete_models,
              help="Registered model, optionally with a variant (ob3:v4).")
@click.option("--steps", type=int, default=1000, show_default=True, callback=positive_int("steps"))
@click.option("--particles", type=int, default=1000, show_default=True, callback=positive_int("particles"))
@click.option("--precision", type=click.Choice(["float", "double"]), default="float", show_default=True,
              help="float: FPU build (paper D(O)); double: soft-float build (paper D(S)).")
@click.option("--method", type=click.Choice(PARTICLE_METHODS), default="bootstrap", show_default=True,
              help="A particle method (the operation counts cover the bootstrap-family kernel).")
@click.option("--filters", type=int, default=1, show_default=True, callback=positive_int("filters"),
              help="MultiPDF sub-filters N_f.")
@click.option("--resampling", type=click.Choice(SCHEMES), default="systematic", show_default=True)
@click.option("--core", "core_name", default="m4", show_default=True,
              help="Core: m0plus, m3, m4 (the paper's STM32F407), m7, m33.")
@click.option("--clock-mhz", type=float, default=None, callback=positive_float("clock-mhz"),
              help="Core clock [default: the core's typical chip, 168 MHz for the M4].")
@click.option("--cycles", "cycles_file", type=NonEmptyPath(dir_okay=False), default=None,
              help="Cycle table JSON (default: the core's built-in table).")
@click.option("--board-power-w", type=float, default=None,
              callback=positive_float("board-power-w", allow_zero=True),
              help="Board power for the board energy figure [default: 1.39 W on the M4 (Table 3), none else].")
@click.option("--no-calibration", is_flag=True, help="Raw instruction-table cycles, no Table-2 efficiency "
              "(= --basis table).")
@click.option("--basis", type=click.Choice(["board", "code", "table"]), default=None,
              help="What the predicted time is: board = the paper's board running hand-written C "
                   "([Embedded] Table-2 efficiency; default); code = the code pfbench compiles for "
                   "the MCU (harness + your model's own code, zero wait states: what "
                   "`mcu emulate --model` checks); table = instruction-table cycles only.")
@click.option("--no-history", is_flag=True, help="Memory check without the per-step history arrays.")
@click.option("--param", "params", multiple=True, metavar="KEY=VALUE",
              help="Model parameter (repeatable; JSON-typed, as `pfbench run --param`).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def estimate(model_name, steps, particles, precision, method, filters, resampling, core_name, clock_mhz,
             cycles_file, board_power_w, no_calibration, basis, no_history, params, as_json):
    """Predict Cortex-M run time, energy and RAM of a particle filter."""
    from .. import models
    from .costmodel import predict

    name, model_params = models.parse_spec(model_name, parse_key_values(params, "--param"))
    if method != "multipdf" and filters != 1:
        raise click.BadParameter(f"--filters {filters} needs --method multipdf", param_hint="'--filters'")
    if filters > particles:
        raise click.BadParameter(f"{filters} sub-filters for {particles} particles: need --filters <= --particles",
                                 param_hint="'--filters'")
    if no_calibration and basis not in (None, "table"):
        raise click.BadParameter(f"--no-calibration is --basis table, not {basis}", param_hint="'--basis'")
    r = predict(name, steps, particles, precision, method=method, n_filters=filters,
                clock_mhz=clock_mhz, core=core_name, cycles=cycles_file, board_power_w=board_power_w,
                calibrated=not no_calibration, resampling=resampling, history=not no_history,
                model_params=model_params, basis=basis)
    if as_json:
        click.echo(to_json(r, indent=2, default=float))
        return
    click.echo(_format(r, model_name, paper_board=board_power_w is None))
    if cycles_file and r["calibrated"]:
        click.echo(f"note: the board layer re-fits its efficiency to [Embedded] Table 2 with {cycles_file}'s cycles "
                   f"({r['efficiency']:.3f}), so it keeps the paper's times; --basis table prices the file's "
                   "cycles alone")


def _format(r: dict, label: str, paper_board: bool) -> str:
    """The text of ``mcu estimate``: ``label`` names the model as the user gave it (``ob3:v4``);
    ``paper_board``: the board power is the default one (on the M4, [Embedded] Table 3's)."""
    mem = r["memory"]
    lines = [
        f"{label} {r['method']}" + (f" (N_f={r['n_filters']})" if r["method"] == "multipdf" else "")
        + f", M={r['n_steps']} steps, N_p={r['n_particles']} particles"
        + (f" ({r['n_particles_requested']} asked: {r['n_filters']} sub-filters of "
           f"{r['n_particles'] // r['n_filters']})" if r["n_particles_requested"] != r["n_particles"] else "")
        + f", {r['precision']} on "
        f"{r['core_name']} ({r['chip']}) @ {r['clock_mhz']:g} MHz",
        f"predicted time : {r['predicted_ms']:,.1f} ms ({r['step_us']:,.1f} us per step)"
        + (f"  (instruction-table {r['raw_ms']:,.1f} ms x efficiency {r['efficiency']:.3f}: {r['efficiency_basis']})"
           if r["calibrated"] else f"  ({r['efficiency_basis']})" if r.get("basis") == "code"
           else "  (uncalibrated)"),
        f"cycles/particle-step: {r['cycles_per_particle_step']:,.0f}",
        f"layers         : board {r['board_ms']:,.1f} ms (hand-written C at the [Embedded] Table-2 "
        f"efficiency of the paper's board) | code {r['code_ms']:,.1f} ms (pfbench's compiled harness + model, "
        f"zero wait states; what `pfbench mcu emulate --model` runs: bootstrap, systematic)",
        f"energy (MCU)   : {r['energy_mcu_wh']:.3g} Wh, {r['energy_per_step_uj']:.3g} uJ per step "
        f"({r['mcu_current_ma']:.3g} mA x {r['mcu_voltage_v']:g} V"
        + (", an assumed run current: see cores.json)" if r["mcu_current_assumed"] else ")"),
    ]
    if r["energy_board_wh"] is not None:
        lines.append(f"energy (board) : {r['energy_board_wh']:.3g} Wh at {r['board_power_w']:g} W board power"
                     + (" (the figure [Embedded] Table 3 reports, of its board)" if r["core"] == "m4" and paper_board
                        else ""))
    lines += [
        f"RAM            : {mem['bytes'] / 1024:.1f} kB of {mem['usable_bytes'] / 1024:.0f} kB usable "
        f"({mem['ram_bytes'] / 1024:.0f} kB {mem['chip']}); largest N_p that fits: {mem['max_particles']}",
        "operation breakdown (cycles share; normals expanded into their generator's operations):",
    ]
    ps = r["n_steps"] * r["n_particles"]
    lines.append(f"  {'op':<11}{'per particle-step':>18}{'cycles each':>12}{'share':>8}")
    per_ps = r["primitive_ops_per_particle_step"]
    for op, share in sorted(r["share"].items(), key=lambda kv: -kv[1]):
        lines.append(f"  {op:<11}{per_ps.get(op, 0.0):>18.3f}{r['cycles_each'][op]:>12g}{share:>8.1%}")
    lines.append("counted ops: " + ", ".join(f"{k}={v:,}" for k, v in r["ops"].items()) + f"  (for {ps:,} particle-steps)")
    return "\n".join(lines)


@mcu.command()
@click.option("--model", "model_name", default="ob1", show_default=True, shell_complete=complete_models,
              help="Registered model, optionally with a variant (ob3:v4).")
@click.option("--steps", type=int, default=1000, show_default=True, callback=positive_int("steps"),
              help="Run length M (per-step cost is averaged over min(M, 100) steps; RAM with --history).")
@click.option("--period-us", type=float, required=True, callback=positive_float("period-us"),
              help="Sampling period T in microseconds (1000 = 1 kHz).")
@click.option("--method", type=click.Choice(PARTICLE_METHODS), default="bootstrap", show_default=True)
@click.option("--filters", type=int, default=1, show_default=True, callback=positive_int("filters"),
              help="MultiPDF sub-filters N_f.")
@click.option("--resampling", type=click.Choice(SCHEMES), default="systematic", show_default=True)
@click.option("--core", "core_names", multiple=True, help="Restrict to these cores (repeatable; default all five).")
@click.option("--precision", "precisions", multiple=True, type=click.Choice(["float", "double"]),
              help="Restrict to a precision (repeatable; default both).")
@click.option("--history", is_flag=True, help="Count the M-step history arrays in the RAM check.")
@click.option("--basis", type=click.Choice(["board", "code", "table"]), default="board", show_default=True,
              help="Time layer, as for `mcu estimate`: board = hand-written C on the paper's board "
                   "(Table-2 efficiency); code = the code pfbench compiles (what `mcu emulate --model` runs).")
@click.option("--param", "params", multiple=True, metavar="KEY=VALUE", help="Model parameter (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def fit(model_name, steps, period_us, method, filters, resampling, core_names, precisions, history, basis,
        params, as_json):
    """Largest N_p per core and precision that meets the sampling period and fits in RAM."""
    from .. import models
    from . import cores as _cores
    from .costmodel import fit as _fit

    name, model_params = models.parse_spec(model_name, parse_key_values(params, "--param"))
    if method != "multipdf" and filters != 1:
        raise click.BadParameter(f"--filters {filters} needs --method multipdf", param_hint="'--filters'")
    keys = list(dict.fromkeys(_cores.get(c).key for c in core_names)) or None
    r = _fit(name, steps, period_us, method=method, n_filters=filters, resampling=resampling, cores=keys,
             precisions=tuple(precisions) or ("float", "double"), history=history, model_params=model_params,
             basis=basis)
    if as_json:
        click.echo(to_json(r, indent=2, default=float))
        return
    click.echo(f"{model_name} {r['method']}" + (f" (N_f={filters})" if method == "multipdf" else "")
               + f": largest N_p per step period {r['period_us']:g} us "
               f"({r['rate_hz']:g} Hz){' with M-step history in RAM' if r['history'] else ''}; "
               f"time basis: {r['basis']}")
    click.echo(f"{'core':<11}{'chip':<13}{'MHz':>5}{'RAM kB':>8} {'prec':<7}{'N_p':>8} {'limit':<6}"
               f"{'step us':>9}{'uJ/step':>9}")
    for x in r["rows"]:
        step = f"{x['step_us']:.1f}" if x["step_us"] is not None else "-"
        e = f"{x['energy_per_step_uj']:.3g}" if x["energy_per_step_uj"] is not None else "-"
        click.echo(f"{x['core_name']:<11}{x['chip']:<13}{x['clock_mhz']:>5g}{x['ram_kb']:>8g} {x['precision']:<7}"
                   f"{x['max_particles']:>8} {x['binding']:<6}{step:>9}{e:>9}")
    for n in r["notes"]:
        click.echo("note: " + n)


@mcu.command()
@click.option("--cycles", "cycles_file", type=NonEmptyPath(dir_okay=False), default=None)
@click.option("--json", "as_json", is_flag=True)
def calibrate(cycles_file, as_json):
    """Fit the per-precision efficiency on [Embedded] Table 2; leave-one-out errors and ratios."""
    from .costmodel import calibrate as _cal

    c = _cal(cycles_file)
    if as_json:
        click.echo(to_json(c, indent=2, default=float))
        return
    click.echo(f"fit: {c['method']}")
    click.echo("efficiency: " + ", ".join(f"{k} {v:.4f}" for k, v in c["efficiency"].items()))
    click.echo(f"{'M':>5}{'N_p':>6} {'build':<6}{'published':>11}{'raw':>11}{'fitted':>11}{'LOO':>11}{'LOO err':>9}")
    for x in c["cells"]:
        click.echo(f"{x['M']:>5}{x['N_p']:>6} {x['build']:<6}{x['published_ms']:>11,.0f}{x['raw_ms']:>11,.0f}"
                   f"{x['fitted_ms']:>11,.0f}{x['loo_ms']:>11,.0f}{x['loo_error']:>+9.1%}")
    for r in c["ratios"]:
        click.echo(f"ratio D(S)/D(O) M={r['M']} N_p={r['N_p']}: published {r['published_ratio']:.1f}, "
                   f"raw {r['raw_ratio']:.1f}, fitted {r['fitted_ratio']:.1f} ({r['fitted_ratio_error']:+.1%}), "
                   f"LOO {r['loo_ratio']:.1f} ({r['loo_ratio_error']:+.1%})")
    click.echo(f"max |LOO error|: {c['max_abs_loo_error']:.1%}")


try:  # the emulator commands live beside the emulator (optional toolchain)
    from .emulate_cli import emulate as _emulate
except ModuleNotFoundError as _exc:  # pragma: no cover - until the emulator lands
    if _exc.name != f"{__package__}.emulate_cli":
        raise
else:
    mcu.add_command(_emulate)
