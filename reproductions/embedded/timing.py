"""[Embedded] §5.1: platform timing (Fig. 5), D(S) vs D(O) (Table 2), energy per task (Table 3).

Host: this machine, single-threaded, ``pfbench.run_filter`` on Ob1 ([Embedded] eq. 6), bootstrap
filter with systematic resampling (Alg. 1), both backends (numba, numpy) and both particle
precisions (float64, float32); median of repeated runs (quick: numba 5 / numpy 3 repeats; full:
21 / 7). STM32F4: the Cortex-M4 cost model (:mod:`pfbench.mcu.costmodel`): operation counts
derived from the NumPy engine x cycle tables, one efficiency factor per precision fitted on
Table 2; the D(S)/D(O) bars and table columns are *leave-one-out* predictions (the cell being
predicted is not in the fit), the in-sample fit is shown beside them.

Options (``--option KEY=VALUE``): ``host_power_w`` (W, power model for the host when RAPL is
not readable; default :data:`DEFAULT_HOST_POWER_W`), ``repeats`` (override both repeat counts),
``board_power_w`` (default 1.39 W, Table 3).
"""
from __future__ import annotations


import numpy as np
import pandas as pd

from . import _host as bench_host
from pfbench.mcu import costmodel as cm
from pfbench.models import get as get_model
from pfbench.ranges import COUNT, POSITIVE
from pfbench.recipes import recipe
from pfbench import plotting
from pfbench.verdicts import CONSTRUCTION, close_to, holds, not_reproducible

#: accuracy target of the cost model's leave-one-out predictions (one fitted efficiency per precision,
#: the cell predicted is not in the fit), shown beside every Table 2 / Table 3 number
LOO_TOL = 0.15
#: why every Table 2 / Table 3 comparison of the cost model is "by construction" (shown, never scored)
CALIBRATED = ("the cost model's time scale is one efficiency per precision fitted on Table 2 itself (leave-one-out: "
              "fitted on the other two cells of the same build), so its prediction of a Table 2 cell is the paper's "
              "neighbouring cells rescaled by M x N_p; it tests only that Table 2 scales linearly, not the board")

CONFIGS = [(500, 500), (500, 1000), (1000, 1000)]     # (M iterations, N_p particles), Table 2
VARIANTS = [("numba", "float64"), ("numba", "float32"), ("numpy", "float64"), ("numpy", "float32")]
#: Host power model when RAPL is unreadable: ~10 W, an estimate of what one busy core adds to a
#: server Xeon package (TDP 150-205 W over 20-28 cores = 7-10 W per core, upper end taken).
#: It is NOT a measurement; the paper's PCs measured whole-system power (Table 3: A 98 W,
#: B 42 W, C 32 W = energy / time).
DEFAULT_HOST_POWER_W = 10.0
PAPER_PLATFORMS = {"A": "AMD Ryzen 7 2700 (3.2 GHz), C#", "B": "Intel Core i5 4210M (2.6 GHz), C#",
                   "C": "Intel Atom D525 (1.8 GHz), C#", "D(O)": "STM32F407 @ 168 MHz, float -Ofast",
                   "D(S)": "STM32F407 @ 168 MHz, double standard C"}


REPEATS = (int, "timed runs per configuration (quick numba 5 / numpy 3, full 21 / 7)", COUNT)


def _opt_float(ctx, key, default):
    return cm.checked_number(ctx.option(key, default, float), f"option {key}")


def _repeats(ctx, backend):
    if "repeats" in ctx.options:
        return ctx.option("repeats", 1, int)
    if ctx.full:
        return 21 if backend == "numba" else 7
    return 5 if backend == "numba" else 3


def _mcu(m, n):
    """Model D(S)/D(O) for one Table 2 cell: calibrated (in-sample), leave-one-out and raw."""
    cal = cm.calibrate()
    out = {}
    for prec, build in (("double", "D(S)"), ("float", "D(O)")):
        r = cm.predict("ob1", m, n, prec)
        cell = next((c for c in cal["cells"] if (c["M"], c["N_p"], c["precision"]) == (m, n, prec)), None)
        out[build] = {"fitted_ms": r["predicted_ms"], "raw_ms": r["raw_ms"],
                      "loo_ms": cell["loo_ms"] if cell else r["predicted_ms"],
                      "cycles_per_ps": r["cycles_per_particle_step"], "energy_wh": r["energy_wh"]}
    return out


def _host_times(ctx, configs):
    model = get_model("ob1")
    rows = []
    jobs = [(m, n, be, dt) for (m, n) in configs for be, dt in VARIANTS]
    trajs = {m: model.simulate(m, seed=ctx.seed) for m in {c[0] for c in configs}}
    for m, n, be, dt in ctx.progress(jobs, total=len(jobs), desc="host timing"):
        t = bench_host.time_filter(model, trajs[m].y, backend=be, dtype=dt, n_particles=n,
                                   repeats=_repeats(ctx, be), seed=ctx.seed)
        rows.append({"M": m, "N_p": n, "backend": be, "dtype": dt, "median_ms": 1e3 * t["median_s"],
                     "min_ms": 1e3 * t["min_s"], "max_ms": 1e3 * t["max_s"], "repeats": t["repeats"],
                     "ns_per_particle_step": 1e9 * t["median_s"] / (m * n),
                     "rapl_energy_j": t["energy_j"]})
    return pd.DataFrame(rows)


@recipe("embedded:fig5", aliases=("fig5",), title="Platform timing: host vs STM32F4 model (Fig. 5)",
        quick_cost="~30 s", full_cost="~2 min",
        options={"repeats": REPEATS})
def fig5(ctx):
    host = _host_times(ctx, CONFIGS)
    rows = []
    for _, h in host.iterrows():
        rows.append({"M": h.M, "N_p": h.N_p, "platform": f"host {h['backend']} {h['dtype']}", "source": "ours (measured)",
                     "time_ms": h.median_ms})
    for m, n in CONFIGS:
        pred = _mcu(m, n)
        pub = cm.TABLE2[(m, n)]
        for build, col in (("D(S)", 0), ("D(O)", 1)):
            rows.append({"M": m, "N_p": n, "platform": f"model {build}", "source": "ours (cost model, LOO)",
                         "time_ms": pred[build]["loo_ms"], "fitted_ms": pred[build]["fitted_ms"],
                         "raw_ms": pred[build]["raw_ms"]})
            rows.append({"M": m, "N_p": n, "platform": f"paper {build}", "source": "paper Table 2",
                         "time_ms": pub[col]})
            ctx.compare(f"{build} M={m} N_p={n} (leave-one-out)", ours=round(pred[build]["loo_ms"], 1),
                        paper=pub[col], unit="ms")
        if (m, n) == (1000, 1000):
            for p in ("A", "B", "C"):
                rows.append({"M": m, "N_p": n, "platform": f"paper {p}", "source": "paper Table 3",
                             "time_ms": 1e3 * cm.TABLE3[p][0]})
    df = pd.DataFrame(rows)
    ctx.write_table("fig5", df)

    # grouped log-scale bars, one group per (M, N_p)
    order = ([f"host {b} {d}" for b, d in VARIANTS] + ["model D(O)", "model D(S)", "paper D(O)", "paper D(S)",
                                                        "paper A", "paper B", "paper C"])
    colors = {"host numba float64": "#1f77b4", "host numba float32": "#6baed6", "host numpy float64": "#2ca02c",
              "host numpy float32": "#98df8a", "model D(O)": "#ff7f0e", "model D(S)": "#d62728",
              "paper D(O)": "#fdae6b", "paper D(S)": "#ff9896", "paper A": "#9467bd", "paper B": "#c5b0d5",
              "paper C": "#8c564b"}
    fig, ax = plotting.subplots(figsize=(11, 5.2))
    width = 0.8 / len(order)
    for i, plat in enumerate(order):
        xs, ys = [], []
        for g, (m, n) in enumerate(CONFIGS):
            sel = df[(df.M == m) & (df.N_p == n) & (df.platform == plat)]
            if len(sel):
                xs.append(g - 0.4 + (i + 0.5) * width)
                ys.append(float(sel.time_ms.iloc[0]))
        if xs:
            hatch = "//" if plat.startswith("paper") else None
            ax.bar(xs, ys, width=width, color=colors[plat], label=plat, hatch=hatch, edgecolor="k", linewidth=0.3)
    ax.set_yscale("log")
    ax.set_ylim(top=float(df.time_ms.max()) * 60)  # head-room for the legend
    ax.set_xticks(range(len(CONFIGS)))
    ax.set_xticklabels([f"M={m}, N_p={n}" for m, n in CONFIGS])
    plotting.label(ax, "configuration (M iterations, N_p particles)", "execution time [ms] (log scale)",
                   "Ob1 bootstrap PF, single thread: this host (measured), STM32F4 cost model (LOO), "
                   "paper (hatched: Table 2, Table 3)")
    ax.grid(axis="y", which="both", alpha=0.3)
    ax.legend(ncol=3, loc="upper left")
    ctx.write_figure("fig5", fig)

    # host float32 vs float64, next to the MCU's ~30x
    h = host.set_index(["M", "N_p", "backend", "dtype"]).median_ms
    for be in ("numba", "numpy"):
        r = h[(1000, 1000, be, "float64")] / h[(1000, 1000, be, "float32")]
        ctx.compare(f"host {be} float64/float32 time ratio, M=N_p=1000", ours=round(float(r), 3),
                    paper="D(S)/D(O) on the MCU: 29.9", note="host has hardware double")
    r_mcu = cm.TABLE2[(1000, 1000)][0] / cm.TABLE2[(1000, 1000)][1]
    ctx.note(f"Host float64/float32 ratio ~{float(h[(1000, 1000, 'numba', 'float64')] / h[(1000, 1000, 'numba', 'float32')]):.2f} "
             f"(numba) vs {r_mcu:.1f} on the STM32F4: the x86 core executes double in hardware at (nearly) "
             "the speed of float and our engine keeps weights/likelihoods in float64 whatever the particle dtype, "
             "whereas the Cortex-M4F's FPU is single-precision only, so every double operation there is a "
             "soft-float libgcc/newlib call costing 50-600x a VADD/VMUL (transcendentals ~15-20x).")
    hn = h[(1000, 1000, "numba", "float64")]
    ctx.compare("host numba float64, M=N_p=1000 vs paper platform A (C#)", ours=round(float(hn), 2),
                paper=1e3 * cm.TABLE3["A"][0], unit="ms",
                note=f"different hardware: {bench_host.cpu_name()} vs Ryzen 7 2700")
    ctx.claim("The STM32F4 standard build D(S) is 57 to 360 times slower than platforms A-C", "[Embedded] §5.1, Fig. 5",
              "time of D(S) / time of A, B, C",
              not_reproducible("platforms A-C (C# on three PCs) are not available and Fig. 5's bar heights are not "
                               f"legible; our host ({bench_host.cpu_name()}) is different hardware, so its absolute "
                               "times test nothing the paper measured"), paper="57-360x")
    ratios = {(m, n): _mcu(m, n) for m, n in CONFIGS}
    worst = min(v["D(S)"]["loo_ms"] / v["D(O)"]["loo_ms"] for v in ratios.values())
    ctx.claim("The highly optimized version D(O) is much more efficient than the standard D(S)", "[Embedded] §5.1, Fig. 5",
              "smallest D(S)/D(O) time ratio over the three Fig. 5 configurations (cost model, leave-one-out)",
              holds(worst > 10, f"smallest leave-one-out ratio {worst:.1f}; above 10 (our reading of "
                                "'much': an order of magnitude)"), paper="much faster", kind=CONSTRUCTION,
              note=CALIBRATED + "; the ratio is the paper's own (29.9-36.3 in Table 2). The emulated builds "
                   "(embedded:mcu) exceed it by construction too")
    ctx.note("Fig. 5's bar heights for platforms A-C are not legible in the text extraction; only their "
             "M=N_p=1000 times (Table 3) are shown. 'model D(S)/D(O)' bars are leave-one-out predictions of "
             "the cost model (see table2 for the fit); the host bars are measured on this machine "
             f"({bench_host.cpu_name()}), single thread, median of {_repeats(ctx, 'numba')} (numba) / "
             f"{_repeats(ctx, 'numpy')} (numpy) runs, other jobs sharing the 2 cores may inflate them.")
    ctx.extra["host_cpu"] = bench_host.cpu_name()


@recipe("embedded:table2", aliases=("table2",), title="STM32F4 D(S) vs D(O): cost model vs Table 2",
        quick_cost="~5 s", full_cost="~5 s")
def table2(ctx):
    cal = cm.calibrate()
    rows = []
    for (m, n), pub in cm.TABLE2.items():
        row = {"M": m, "N_p": n}
        for c in cal["cells"]:
            if (c["M"], c["N_p"]) != (m, n):
                continue
            b = c["build"]
            row.update({f"{b} published ms": c["published_ms"], f"{b} raw ms": round(c["raw_ms"], 1),
                        f"{b} fitted ms": round(c["fitted_ms"], 1), f"{b} fit err": round(c["fit_error"], 4),
                        f"{b} LOO ms": round(c["loo_ms"], 1), f"{b} LOO err": round(c["loo_error"], 4),
                        f"{b} cycles/particle-step published": round(c["published_ms"] * 168e3 / (m * n), 1),
                        f"{b} raw cycles/particle-step": round(c["raw_ms"] * 168e3 / (m * n), 1)})
            ctx.compare(f"{b} M={m} N_p={n}, leave-one-out", ours=round(c["loo_ms"], 1), paper=c["published_ms"],
                        unit="ms")
            ctx.claim(f"STM32F407 {b} execution time, M = {m}, N_p = {n}", "[Embedded] Table 2",
                      "cost-model time predicted without this cell (leave-one-out) [ms]",
                      close_to(c["loo_ms"], c["published_ms"], LOO_TOL,
                               why="the cost model's stated leave-one-out accuracy target"),
                      paper=c["published_ms"], kind=CONSTRUCTION, note=CALIBRATED)
        r = next(x for x in cal["ratios"] if (x["M"], x["N_p"]) == (m, n))
        row.update({"ratio published": round(r["published_ratio"], 2), "ratio raw": round(r["raw_ratio"], 2),
                    "ratio fitted": round(r["fitted_ratio"], 2), "ratio LOO": round(r["loo_ratio"], 2)})
        ctx.compare(f"D(S)/D(O) ratio M={m} N_p={n}, leave-one-out", ours=round(r["loo_ratio"], 2),
                    paper=round(r["published_ratio"], 1))
        ctx.claim(f"D(S)/D(O) time ratio, M = {m}, N_p = {n}", "[Embedded] §5.1, Table 2",
                  "ratio of the leave-one-out cost-model times",
                  close_to(r["loo_ratio"], r["published_ratio"], 2 * LOO_TOL,
                           why="a ratio of two predictions each within the 15 % leave-one-out target"),
                  paper=round(r["published_ratio"], 2), kind=CONSTRUCTION, note=CALIBRATED)
        rows.append(row)
    df = pd.DataFrame(rows)
    ctx.write_table("table2", df)
    for prec, eff in cal["efficiency"].items():
        ctx.compare(f"fitted efficiency ({prec})", ours=round(eff, 4), paper=None,
                    note="cycles actually spent / instruction-table cycles")
    f = cm.predict("ob1", 1000, 1000, "float")
    d = cm.predict("ob1", 1000, 1000, "double")
    top = lambda r: ", ".join(f"{k} {v:.0%}" for k, v in sorted(r["share"].items(), key=lambda kv: -kv[1])[:4])
    ctx.write_json("table2_calibration", cal)
    ctx.note(f"Fit: {cal['method']}; 2 parameters (float {cal['efficiency']['float']:.3f}, double "
             f"{cal['efficiency']['double']:.3f}); max |leave-one-out error| {cal['max_abs_loo_error']:.1%}.")
    cpps = {b: [c["published_ms"] * 168e3 / (c["M"] * c["N_p"]) for c in cal["cells"] if c["build"] == b]
            for b in ("D(S)", "D(O)")}
    loo_f = [c["loo_error"] for c in cal["cells"] if c["build"] == "D(O)"]
    loo_d = [abs(c["loo_error"]) for c in cal["cells"] if c["build"] == "D(S)"]
    drift = cpps["D(O)"][-1] / cpps["D(O)"][0] - 1.0
    ratio_fit = cal["ratios"][0]["fitted_ratio"]
    ctx.note("Published cycles per particle-step (ms x 168e3 / (M N_p)): D(S) "
             + " / ".join(f"{v:,.0f}" for v in cpps["D(S)"]) + ", D(O) " + " / ".join(f"{v:,.0f}" for v in cpps["D(O)"])
             + f". Double is linear in M*N_p, so one factor predicts every left-out D(S) cell within "
             f"{max(loo_d):.1%}. Float is not: a {drift:.0%} drift that no operation-count model can produce (the "
             "per-particle-step work of the algorithm is the same in all cells, and per-step/per-run overheads "
             "would make the smaller runs dearer per particle, not cheaper). With one factor the left-out float "
             "cells land at " + " / ".join(f"{e:+.1%}" for e in loo_f) + ", just inside the 15% target, and the "
             f"predicted float/double ratio is one constant ({ratio_fit:.1f} fitted) against the published "
             + " / ".join(f"{r['published_ratio']:.1f}" for r in cal["ratios"]) + "; a 2-parameter float model "
             "(per-run overhead + per-particle-step cost) would do worse when the smallest cell is left out "
             "because the fitted overhead turns negative.")
    ctx.note(f"Dominant costs at M=N_p=1000 - double: {top(d)}; float: {top(f)}. The Box-Muller normal "
             "(rand x2, log, sqrt, cos) and the weight exp dominate both builds; in double the "
             "divisions by a constant (x/20, w/sum) are true __divdf3 calls, which -Ofast's reciprocal-math "
             "turns into multiplications in the float build (table entry div_scalar).")
    eff = cal["efficiency"]
    ctx.note(f"Raw (uncalibrated) instruction-table cycles are {1 / eff['float']:.2f}x the paper's for float "
             f"and {1 / eff['double']:.2f}x for double (fitted efficiencies {eff['float']:.2f} / {eff['double']:.2f}). "
             "Our counted algorithm also validates weights (NaN/inf checks), which a hand-written C loop of "
             "Alg. 1 does not; the -Ofast build plausibly used fast-math logf/expf/cosf and hoisted the "
             "loop-invariant 8 cos(1.2k), which the fitted float factor absorbs.")


@recipe("embedded:table3", aliases=("table3",), title="Energy per task, host vs STM32F4 (Table 3)",
        quick_cost="~20 s", full_cost="~1 min",
        options={"repeats": REPEATS,
                 "host_power_w": (float, "host power model in W when RAPL is unreadable (default 10)",
                                  POSITIVE),
                 "board_power_w": (float, "STM32F4 board power in W (default 1.39, Table 3)", POSITIVE)})
def table3(ctx):
    m, n = 1000, 1000
    host_power = _opt_float(ctx, "host_power_w", DEFAULT_HOST_POWER_W)
    board_power = _opt_float(ctx, "board_power_w", cm.BOARD_POWER_W)
    host = _host_times(ctx, [(m, n)])
    rapl = bench_host.rapl_domains()
    rows = []
    for p, (t, e) in cm.TABLE3.items():
        rows.append({"platform": p, "source": "paper Table 3", "description": PAPER_PLATFORMS[p], "time_s": t,
                     "energy_wh": e, "power_w": round(e * 3600 / t, 2), "energy_method": "measured (clamp meter)"})
    host_rows = {}
    for _, h in host.iterrows():
        t = h.median_ms / 1e3
        if rapl and h.rapl_energy_j is not None and np.isfinite(h.rapl_energy_j):
            e_wh, how = h.rapl_energy_j / 3600.0, "RAPL package energy (whole package, incl. other load)"
        else:
            e_wh, how = host_power * t / 3600.0, f"ESTIMATE: power model {host_power:g} W x time (RAPL not readable)"
        name = f"host {h['backend']} {h['dtype']}"
        host_rows[name] = (t, e_wh)
        rows.append({"platform": name, "source": "ours (measured time)", "description": bench_host.cpu_name(),
                     "time_s": t, "energy_wh": e_wh, "power_w": e_wh * 3600 / t if t > 0 else float("nan"),
                     "energy_method": how})
    pred = _mcu(m, n)
    for build, prec in (("D(O)", "float"), ("D(S)", "double")):
        t = pred[build]["loo_ms"] / 1e3
        e = board_power * t / 3600.0
        rows.append({"platform": f"model {build}", "source": "ours (cost model, LOO)", "description":
                     PAPER_PLATFORMS[build], "time_s": t, "energy_wh": e, "power_w": board_power,
                     "energy_method": f"board power {board_power:g} W x predicted time"})
        ctx.compare(f"{build} energy per task (LOO time x {board_power:g} W)", ours=round(e, 5),
                    paper=cm.TABLE3[build][1], unit="Wh")
        ctx.compare(f"{build} time (LOO)", ours=round(t, 3), paper=cm.TABLE3[build][0], unit="s")
    # break-even: host power at which the host spends the same energy per task as D(O)
    e_do_model = board_power * pred["D(O)"]["loo_ms"] / 1e3
    e_do_paper = cm.TABLE3["D(O)"][1] * 3600.0
    for name, (t, e_wh) in host_rows.items():
        be_model, be_paper = e_do_model / t, e_do_paper / t
        for r in rows:
            if r["platform"] == name:
                r["break_even_power_w_vs_model_DO"] = round(be_model, 2)
                r["break_even_power_w_vs_paper_DO"] = round(be_paper, 2)
    e_model = {b: board_power * pred[b]["loo_ms"] / 1e3 / 3600.0 for b in ("D(O)", "D(S)")}
    board_note = (f"energy = board power x time, where the power ({board_power:g} W) is Table 3's own energy / time and "
             "the time is the cost model calibrated on Table 2 (whose times Table 3 repeats): " + CALIBRATED)
    for b in ("D(O)", "D(S)"):
        ctx.claim(f"Energy per task of the STM32F4 {b} build (M = N_p = 1000)", "[Embedded] Table 3",
                  "board power x leave-one-out time [Wh]",
                  close_to(e_model[b], cm.TABLE3[b][1], LOO_TOL,
                           why=f"the 15 % leave-one-out time target; power {board_power:g} W as Table 3"),
                  paper=cm.TABLE3[b][1], kind=CONSTRUCTION, note=board_note)
    e_c = cm.TABLE3["C"][1]
    ctx.claim("Platform C consumes about 2.3 times less energy per task than D(S)", "[Embedded] §5.1, Table 3",
              "our D(S) energy / the paper's platform C energy",
              close_to(e_model["D(S)"] / e_c, 2.3, LOO_TOL, why="the 15 % leave-one-out time target"), paper=2.3,
              kind=CONSTRUCTION, note=board_note + f"; the paper's own ratio is {cm.TABLE3['D(S)'][1] / e_c:.2f}")
    ctx.claim("D(O) consumes over 10 times less energy per task than platform C", "[Embedded] §5.1, Table 3",
              "the paper's platform C energy / our D(O) energy",
              holds(e_c / e_model["D(O)"] > 10, f"{e_c / e_model['D(O)']:.1f}x; above 10"), paper="> 10",
              kind=CONSTRUCTION, note=board_note + f"; the paper's own ratio is {e_c / cm.TABLE3['D(O)'][1]:.1f}")
    ctx.claim("The PCs (A-C) calculate much faster and during this time can consume less energy than the board's "
              "standard build", "[Embedded] §5.1, Table 3", "host energy per task",
              not_reproducible("needs the paper's PCs and a clamp meter; " + (
                  "RAPL is not readable here, so our host energy is only a power-model estimate" if not rapl else
                  "RAPL measures our package, not a whole system like the paper's meters")), paper="A-C < D(S)")
    t_host = host_rows["host numba float64"][0]
    ctx.compare("break-even host power vs D(O) (numba float64)", ours=round(e_do_paper / t_host, 1),
                paper=round(cm.TABLE3["D(O)"][1] * 3600 / cm.TABLE3["A"][0], 1), unit="W",
                note="paper column: same for platform A; host must draw less than this to beat the board")
    df = pd.DataFrame(rows)
    ctx.write_table("table3", df)
    if not rapl:
        ctx.note(f"RAPL (/sys/class/powercap) is not readable on this host, so host energies are an ESTIMATE: "
                 f"{host_power:g} W x measured time ({DEFAULT_HOST_POWER_W:g} W default = one busy core's share of "
                 "a server Xeon package, TDP 150-205 W over 20-28 cores; override with --option host_power_w=...). "
                 "The paper's PC energies are whole-system clamp-meter readings (98 / 42 / 32 W).")
    ctx.note(f"Break-even: this host spends less energy per task than the STM32F4 D(O) build as long as its power "
             f"stays below {e_do_paper / t_host:.0f} W (published D(O) energy) or {e_do_model / t_host:.0f} W (model "
             f"D(O)) for the numba float64 run of {t_host * 1e3:.0f} ms, {cm.TABLE3['A'][0] / t_host:.1f}x faster than "
             "the paper's platform A (C#). The paper's PCs drew 32-98 W, above their own break-even "
             f"({e_do_paper / cm.TABLE3['A'][0]:.0f} W for A), which is why D(O) won there.")
