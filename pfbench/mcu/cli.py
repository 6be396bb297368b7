"""``pfbench mcu ...``: Cortex-M4 cost model commands."""
from __future__ import annotations

import math

import click

from ..filters.methods import PARTICLE_METHODS
from ..io import to_json
from ..options import parse_key_values
from ..resampling import SCHEMES


@click.group()
def mcu():
    """Cortex-M4 (STM32F4) time, energy and memory predictions."""


def _positive_int(name):
    def cb(ctx, param, value):
        if value is not None and value < 1:
            raise click.BadParameter(f"must be >= 1, got {value}", param_hint=f"'--{name}'")
        return value
    return cb


def _positive_float(name, allow_zero=False):
    def cb(ctx, param, value):
        if value is None:
            return value
        ok = (value >= 0 if allow_zero else value > 0) and math.isfinite(value)
        if not ok:
            raise click.BadParameter(f"must be {'>= 0' if allow_zero else '> 0'}, got {value}",
                                     param_hint=f"'--{name}'")
        return value
    return cb


@mcu.command()
@click.option("--model", "model_name", default="ob1", show_default=True,
              help="Registered model, optionally with a variant (ob3:v4).")
@click.option("--steps", type=int, default=1000, show_default=True, callback=_positive_int("steps"))
@click.option("--particles", type=int, default=1000, show_default=True, callback=_positive_int("particles"))
@click.option("--precision", type=click.Choice(["float", "double"]), default="float", show_default=True,
              help="float: FPU build (paper D(O)); double: soft-float build (paper D(S)).")
@click.option("--method", type=click.Choice(PARTICLE_METHODS), default="bootstrap", show_default=True,
              help="A particle method (the operation counts cover the bootstrap-family kernel).")
@click.option("--filters", type=int, default=1, show_default=True, callback=_positive_int("filters"),
              help="MultiPDF sub-filters N_f.")
@click.option("--resampling", type=click.Choice(SCHEMES), default="systematic", show_default=True)
@click.option("--clock-mhz", type=float, default=168.0, show_default=True, callback=_positive_float("clock-mhz"))
@click.option("--cycles", "cycles_file", type=click.Path(dir_okay=False), default=None,
              help="Cycle table JSON (default: built-in Cortex-M4F table).")
@click.option("--board-power-w", type=float, default=1.39, show_default=True,
              callback=_positive_float("board-power-w", allow_zero=True), help="Board power (Table 3).")
@click.option("--no-calibration", is_flag=True, help="Raw instruction-table cycles, no Table-2 efficiency.")
@click.option("--no-history", is_flag=True, help="Memory check without the per-step history arrays.")
@click.option("--param", "params", multiple=True, metavar="KEY=VALUE",
              help="Model parameter (repeatable; JSON-typed, as `pfbench run --param`).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def estimate(model_name, steps, particles, precision, method, filters, resampling, clock_mhz, cycles_file,
             board_power_w, no_calibration, no_history, params, as_json):
    """Predict STM32F4 run time, energy and RAM of a particle filter."""
    from .. import models
    from .costmodel import predict

    name, model_params = models.parse_spec(model_name, parse_key_values(params, "--param"))
    if method != "multipdf" and filters != 1:
        raise click.BadParameter(f"--filters {filters} needs --method multipdf", param_hint="'--filters'")
    if filters > particles:
        raise click.BadParameter(f"{filters} sub-filters for {particles} particles: need --filters <= --particles",
                                 param_hint="'--filters'")
    r = predict(name, steps, particles, precision, method=method, n_filters=filters,
                clock_mhz=clock_mhz, cycles=cycles_file, board_power_w=board_power_w,
                calibrated=not no_calibration, resampling=resampling, history=not no_history,
                model_params=model_params)
    if as_json:
        click.echo(to_json(r, indent=2, default=float))
        return
    click.echo(_format(r))


def _format(r: dict) -> str:
    mem = r["memory"]
    lines = [
        f"{r['model']} {r['method']}" + (f" (N_f={r['n_filters']})" if r["method"] == "multipdf" else "")
        + f", M={r['n_steps']} steps, N_p={r['n_particles']} particles, {r['precision']} @ {r['clock_mhz']:g} MHz",
        f"predicted time : {r['predicted_ms']:,.1f} ms"
        + (f"  (instruction-table {r['raw_ms']:,.1f} ms x efficiency {r['efficiency']:.3f} fitted on [Embedded] Table 2)"
           if r["calibrated"] else "  (uncalibrated)"),
        f"cycles/particle-step: {r['cycles_per_particle_step']:,.0f}",
        f"energy         : {r['energy_wh']:.3g} Wh at {r['board_power_w']:g} W board power",
        f"RAM            : {mem['bytes'] / 1024:.1f} kB of {mem['usable_bytes'] / 1024:.0f} kB usable "
        f"(192 kB STM32F407); largest N_p that fits: {mem['max_particles']}",
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
@click.option("--cycles", "cycles_file", type=click.Path(dir_okay=False), default=None)
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
