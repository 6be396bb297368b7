"""[Embedded] Table 2 from the executed instruction stream.

The bootstrap filter on Ob1 ([Embedded] Alg. 1, eq. 6, systematic resampling, object simulated
inside) is cross-compiled as D(S) (double, soft-float, -O0) and D(O) (float, FPv4-SP, -Ofast),
run in the unicorn Cortex-M4 emulator on small (M, N), converted to cycles with the Cortex-M4
timing table and extrapolated to Table 2's configurations; beside it the analytic cost model
(:mod:`pfbench.mcu.costmodel`) and the published times.  Needs ``make mcu-tools``.
"""
from __future__ import annotations

import pandas as pd

from pfbench.ranges import at_least
from pfbench.recipes import recipe
from pfbench import plotting
from pfbench.verdicts import CONSTRUCTION, close_to, holds, not_reproducible

FULL_CONFIGS = {"float": ((20, 100), (40, 100), (20, 200), (40, 200)),
                "double": ((8, 50), (16, 50), (8, 100), (16, 100))}

SRAND_SEED = at_least(0, 2 ** 32 - 1)   # an unsigned int of the C harness


@recipe("embedded:mcu", aliases=("mcu",), title="Table 2 from emulated Cortex-M4 instruction counts",
        quick_cost="~15 s", full_cost="~1 min", needs=("mcu-tools",),
        options={"seed": (int, "srand() seed of the emulated C filter (default 1)", SRAND_SEED)})
def mcu(ctx):
    from pfbench.mcu import emulate as E

    res = {}
    for prec in ctx.progress(("double", "float"), total=2):
        res[prec] = E.emulate(prec, 1000, 1000, configs=FULL_CONFIGS[prec] if ctx.full else None,
                              seed=ctx.option("seed", 1, int))
    rows = []
    for prec, r in res.items():
        for row in r["table2"]:
            rows.append({"build": r["build"], "precision": prec, "steps": row["steps"],
                         "particles": row["particles"], "paper_ms": row["paper_ms"],
                         "analytic_ms": row["analytic_ms"], "emulated_ms": row["emulated_ms"],
                         "emulated_ms_best": row["emulated_ms_best"],
                         "emulated_ms_worst": row["emulated_ms_worst"],
                         "emulated_cycles_per_particle_step": r["cycles_per_particle_step"],
                         "emulated_instructions_per_particle_step":
                             r["instructions_per_particle_step"]})
    df = pd.DataFrame(rows)
    ratio = []
    for (m, n), g in df.groupby(["steps", "particles"], sort=False):
        d, f = g[g.precision == "double"].iloc[0], g[g.precision == "float"].iloc[0]
        row = {"build": "D(S)/D(O)", "precision": "ratio", "steps": m, "particles": n}
        for col in ("paper_ms", "analytic_ms", "emulated_ms"):
            row[col] = (d[col] / f[col]) if d[col] and f[col] else None
        ratio.append(row)
    df = pd.concat([df, pd.DataFrame(ratio)], ignore_index=True)
    ctx.write_table("mcu", df)
    ctx.write_json("mcu", res)

    import numpy as np

    fig, axes = plotting.subplots(1, 3, figsize=(13, 4.4))
    for ax, prec in zip(axes[:2], ("double", "float")):
        g = df[df.precision == prec]
        x = np.arange(len(g))
        for i, (col, lab) in enumerate((("paper_ms", "Table 2 (published)"),
                                        ("analytic_ms", "analytic cost model"),
                                        ("emulated_ms", "emulated count"))):
            vals = g[col].astype(float).fillna(0).to_numpy()
            yerr = None
            if col == "emulated_ms":
                yerr = np.array([vals - g.emulated_ms_best.to_numpy(),
                                 g.emulated_ms_worst.to_numpy() - vals]) / 1e3
            ax.bar(x + (i - 1) * 0.27, vals / 1e3, 0.27, label=lab, yerr=yerr, capsize=3)
        ax.set_xticks(x, [f"M={m}\nN={n}" for m, n in zip(g.steps, g.particles)])
        plotting.label(ax, "configuration (M iterations, N_p particles)", "execution time [s]",
                       f"{res[prec]['build']} ({prec})")
    axes[0].legend()
    g = df[df.precision == "ratio"]
    x = np.arange(len(g))
    for i, (col, lab) in enumerate((("paper_ms", "Table 2"), ("analytic_ms", "analytic"),
                                    ("emulated_ms", "emulated"))):
        axes[2].bar(x + (i - 1) * 0.27, g[col].astype(float).fillna(0), 0.27, label=lab)
    axes[2].set_xticks(x, [f"M={m}\nN={n}" for m, n in zip(g.steps, g.particles)])
    plotting.label(axes[2], "configuration (M iterations, N_p particles)", "D(S) / D(O) time ratio [-]",
                   "D(S) / D(O) time ratio")
    axes[2].legend()
    fig.suptitle("STM32F4 @ 168 MHz: bootstrap PF on Ob1 (error bars: best/worst pipeline timing)")
    ctx.write_figure("mcu", fig)

    for prec, r in res.items():
        lab = r["build"]
        for row in r["table2"]:
            m, n = row["steps"], row["particles"]
            ctx.compare(f"{lab} time, M={m} N={n} (emulated)", ours=round(row["emulated_ms"], 1),
                        paper=row["paper_ms"], unit="ms",
                        note=f"best-worst {row['emulated_ms_best']:.0f}-"
                             f"{row['emulated_ms_worst']:.0f} ms; analytic model "
                             + (f"{row['analytic_ms']:.0f} ms" if row["analytic_ms"] else "n/a"))
        ctx.compare(f"{lab} cycles per particle-step (emulated)",
                    ours=round(r["cycles_per_particle_step"], 1),
                    paper=round(r["table2"][-1]["paper_ms"] * 168e3 / 1e6, 0), unit="cycles",
                    note=f"{r['instructions_per_particle_step']:.0f} instructions per "
                         f"particle-step, CPI {r['cpi']:.2f}; paper value = Table 2 M=N=1000 "
                         f"time x 168 MHz / 1e6 (includes per-step costs)")
    for prec, r in res.items():
        for row in r["table2"]:
            lo, hi = row["emulated_ms_best"], row["emulated_ms_worst"]
            ctx.claim(f"STM32F407 {r['build']} execution time, M = {row['steps']}, N_p = {row['particles']}",
                      "[Embedded] Table 2", "emulated Cortex-M4 time (best-worst pipeline timing) [ms]",
                      not_reproducible(
                          "the authors' C is not published: the emulated time is of our re-implementation, whose "
                          "unstated choices (normal generator, cos(1.2k) per particle, -O0 for D(S)) move it more than "
                          f"the timing table does (see the notes); emulated {lo:.0f}-{hi:.0f} ms is shown as a "
                          "comparison"), paper=row["paper_ms"])
    d, f = res["double"]["table2"][-1], res["float"]["table2"][-1]
    lo, hi = d["emulated_ms_best"] / f["emulated_ms_worst"], d["emulated_ms_worst"] / f["emulated_ms_best"]
    ratios = [d_["paper_ms"] / f_["paper_ms"] for d_, f_ in zip(res["double"]["table2"], res["float"]["table2"])]
    paper_ratio = d["paper_ms"] / f["paper_ms"]
    tol = max(abs(x / paper_ratio - 1.0) for x in ratios)
    ctx.claim("D(S)/D(O) time ratio at M = N_p = 1000", "[Embedded] §5.1, Table 2",
              "emulated D(S) time / emulated D(O) time (interval: best/worst pipeline timing of both builds)",
              close_to(d["emulated_ms"] / f["emulated_ms"], paper_ratio, tol, interval=(lo, hi),
                       interval_is="the best-worst range of the pipeline timing",
                       why="the paper's own ratio of the same two programs spans "
                           + "-".join(f"{x:.1f}" for x in sorted(ratios)) + " across Table 2's cells"),
              paper=round(paper_ratio, 2),
              note=f"a ratio of the two builds of one re-implementation; against Table 2 the emulated D(O) is "
                   f"{f['emulated_ms'] / f['paper_ms'] - 1:+.0%} and D(S) {d['emulated_ms'] / d['paper_ms'] - 1:+.0%} at "
                   "this cell, so our port's choices (normal generator, libm calls per particle) do not cancel in it")
    ctx.claim("The highly optimized version D(O) is much more efficient than the standard D(S)", "[Embedded] §5.1, Fig. 5",
              "smallest emulated D(S)/D(O) time ratio over Table 2's configurations (worst case of the pipeline timing)",
              holds(min(d_["emulated_ms_best"] / f_["emulated_ms_worst"]
                        for d_, f_ in zip(res["double"]["table2"], res["float"]["table2"])) > 10,
                    "deterministic emulation: agree if the worst-case ratio exceeds 10 (our reading of 'much': an "
                    "order of magnitude; the paper's own ratios are 29.9-36.3)"), paper="much faster",
              kind=CONSTRUCTION,
              note="the same C built as soft-float double at -O0 and as hardware float at -Ofast: the timing "
                   "table's per-operation costs of the two are 50-600x apart, so the ratio exceeds 10 whatever "
                   "the port's other choices (embedded:fig5 labels this sentence so too)")
    ctx.compare("D(S)/D(O) ratio at M=N=1000 (emulated)", ours=round(d["emulated_ms"] /
                f["emulated_ms"], 2), paper=round(d["paper_ms"] / f["paper_ms"], 2))
    top_d = res["double"]["breakdown"]["by_c_function_inclusive"]
    tot_d = res["double"]["cycles_per_particle_step"]
    lib_d = res["double"]["breakdown"]["by_library_call_inclusive"]
    ctx.note("D(S) per particle-step: normal draws (randn: Box-Muller with rand, log, sqrt, cos) "
             f"{100 * top_d.get('randn', 0) / tot_d:.0f}%, transition "
             f"(incl. cos(1.2k) per particle) {100 * top_d.get('transition', 0) / tot_d:.0f}%, "
             f"weights (exp) {100 * top_d.get('pf_weights', 0) / tot_d:.0f}%; by library call: "
             + ", ".join(f"{k} {100 * v / tot_d:.0f}%" for k, v in list(lib_d.items())[:6]) + ".")
    ctx.note("Our C is a re-implementation (the authors' C is not published): Box-Muller normals "
             "(one per call, 2 rand()), cos(1.2k) evaluated per particle inside the transition, "
             "weights exp(-e^2/2R) without the constant, D(S) at -O0 with -mfloat-abi=soft. "
             "Differences in these choices move the result more than the timing table does.")
    ctx.note("D(O) is over-predicted: Table 2 implies fewer cycles per particle-step than our "
             "-Ofast newlib build executes (cosf/logf/expf from Debian's newlib cost ~120-155 "
             "cycles each); the authors' code probably saved some libm calls (e.g. caching "
             "the second Box-Muller value or cos(1.2k) per step).")
    ctx.note(E.UNSEEN)
