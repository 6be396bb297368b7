"""Which MCU does a particle filter need? ``pfbench mcu fit`` across five Cortex-M cores.

For Ob1 ([Embedded] eq. 6, bootstrap, systematic resampling) at 1 kHz and for the PMSM model
([Thesis] ch. 4) at its own 125 us sampling period (8 kHz), the largest particle count per
core (M0+, M3, M4F, M7, M33) and precision (float, double) that meets the sampling period
and fits in the typical chip's RAM, the limit that binds, and the MCU energy per filter step
(:func:`pfbench.mcu.costmodel.fit`). Cost model only (operation counts x per-core cycle
tables, [Embedded] Table 2 efficiency fitted on the M4 and applied to every core); no paper
publishes these numbers, so there is nothing to compare against.
"""
from __future__ import annotations

import pandas as pd

from pfbench.ranges import COUNT
from pfbench.recipes import recipe

CASES = (("ob1", 1000.0, "Ob1, 1 kHz"), ("pmsm", 125.0, "PMSM, 8 kHz (dt = 125 us)"))


@recipe("embedded:mcu-fit", title="Largest N_p per Cortex-M core at a sampling period (float/double)",
        quick_cost="~5 s", full_cost="~5 s",
        options={"steps": (int, "run length M for the per-step cost average (default 1000)", COUNT)})
def mcu_fit(ctx):
    from pfbench.mcu import cores
    from pfbench.mcu.costmodel import fit

    steps = ctx.option("steps", 1000, int)
    res, rows = {}, []
    for model, period, label in ctx.progress(CASES, total=len(CASES)):
        r = fit(model, steps, period)
        res[model] = r
        for x in r["rows"]:
            rows.append({"model": model, "period_us": period, **{k: x[k] for k in (
                "core", "core_name", "chip", "clock_mhz", "ram_kb", "precision", "max_particles", "binding",
                "n_time", "n_ram", "step_us", "energy_per_step_uj", "fixed_us", "per_particle_us")}})
    df = pd.DataFrame(rows)
    ctx.write_table("mcu_fit", df)
    ctx.write_json("mcu_fit", {"fits": res, "cores": [c.as_dict() for c in cores.all_cores()]})

    import numpy as np

    from pfbench import plotting

    order = list(cores.names())
    fig, axes = plotting.subplots(1, len(CASES), figsize=(6.2 * len(CASES), 4.8), sharey=True)
    for ax, (model, period, label) in zip(np.atleast_1d(axes), CASES):
        g = df[df.model == model]
        x = np.arange(len(order))
        for j, (prec, colour) in enumerate((("float", "tab:blue"), ("double", "tab:orange"))):
            h = g[g.precision == prec].set_index("core").loc[order]
            vals = h.max_particles.to_numpy(float)
            pos = x + (j - 0.5) * 0.38
            ax.bar(pos, np.maximum(vals, 0.8), 0.38, color=colour, label=prec,
                   hatch=None, edgecolor="k", linewidth=0.4)
            for p, v, b in zip(pos, vals, h.binding):
                txt = f"{int(v)}" + ("\nRAM" if b == "ram" else "")
                ax.text(p, max(v, 0.8) * 1.15, txt, ha="center", va="bottom", fontsize=7)
        names = [f"{cores.get(k).name}\n{cores.get(k).chip}\n{cores.get(k).clock_mhz:g} MHz" for k in order]
        ax.set_xticks(x, names, fontsize=7)
        ax.set_yscale("log")
        plotting.label(ax, "Cortex-M core (typical chip, clock)", "largest N_p meeting the period and RAM [particles]",
                       label)
        ax.grid(axis="y", which="both", alpha=0.3)
    np.atleast_1d(axes)[0].legend(title="precision")
    fig.suptitle("Bootstrap PF: particles per Cortex-M core (cost model; 'RAM' = RAM binds, else time; "
                 "no paper publishes these numbers)")
    ctx.write_figure("mcu_fit", fig)

    for model, period, label in CASES:
        for x in res[model]["rows"]:
            ctx.compare(f"{label}: largest N_p on {x['core_name']} ({x['chip']}), {x['precision']}",
                        ours=x["max_particles"], unit="particles",
                        note=(f"{x['binding']} binds; step {x['step_us']:.0f} us; "
                              f"{x['energy_per_step_uj']:.3g} uJ/step (MCU)") if x["max_particles"] else
                        f"does not fit: the fixed per-step work alone takes {x['fixed_us']:.0f} us "
                        f"(+{x['per_particle_us']:.2f} us per particle)")
    for n in res["ob1"]["notes"]:
        ctx.note(n)
    ctx.note("Cycle tables: M4 = the original [Recovered] table; M0+, M3, M7, M33 derived by "
             "pfbench.mcu.libcost (micro-benchmark x each core's timing table); the M7 double column and "
             "the M7/M33 timing tables rest on stated assumptions (see the JSON sources).")
