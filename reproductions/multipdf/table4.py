"""multipdf Table 4: marginalized PF aRMSE for Ob2 and Ob3 v1-v5 ([MultiPDF] §5, §7)."""
from __future__ import annotations

import pandas as pd

from pfbench.recipes import recipe

from pfbench.verdicts import all_cases, direction

from ._common import OPTIONS, interval_text, per_run, sweep

OBJECTS = [("Ob2", "ob2", {}), ("Ob3 v1", "ob3", {"version": 1}), ("Ob3 v2", "ob3", {"version": 2}),
           ("Ob3 v3", "ob3", {"version": 3}), ("Ob3 v4", "ob3", {"version": 4}),
           ("Ob3 v5", "ob3", {"version": 5})]


@recipe("multipdf:table4", aliases=("mpf-table",), title="MPF aRMSE, Ob2 and Ob3 v1-v5 (Table 4)",
        quick_cost="~30 s", full_cost="~10 min", options=OPTIONS)
def table4(ctx):
    rows, wides = [], {}
    for label, model, params in OBJECTS:
        name = "table4_" + label.replace(" ", "").lower()
        # MPF (all states linear in the transition: an EKF, independent of N_p) next to the
        # MultiPDF/BF reference grid N_p in {100, 1000}, N_f in {1, 3}.
        summ, spec, wall, st = sweep(ctx, name, model, params=params, particles=(100, 1000),
                                     filters=(1, 3), runs_quick=60, runs_full=1000,
                                     extra_configs=[("mpf", 100, 1)])
        s = summ.set_index(["method", "n_particles", "n_filters"])
        mpf = float(s.loc[("mpf", 100, 1), "armse_mean"])
        pf = s.loc["multipdf"]["armse_mean"]
        wides[label] = per_run(st)
        rows.append({"object": label, "mpf_armse": mpf,
                     "mpf_lo": float(s.loc[("mpf", 100, 1), "armse_lo"]),
                     "mpf_hi": float(s.loc[("mpf", 100, 1), "armse_hi"]),
                     "multipdf_worst": float(pf.max()), "multipdf_best": float(pf.min()),
                     "bf_np100": float(pf[(100, 1)]), "bf_np1000": float(pf[(1000, 1)]),
                     "runs": spec["runs"]})
    df = pd.DataFrame(rows)
    ctx.write_table("table4", df)
    worse = []
    for r in rows:
        ctx.compare(f"table4: {r['object']} MPF aRMSE", ours=r["mpf_armse"],
                    note=f"MultiPDF/BF range {r['multipdf_best']:.3f}-{r['multipdf_worst']:.3f}")
        wide = wides[r["object"]]
        pf_cols = sorted((c for c in wide.columns if c[0] == "multipdf"), key=lambda c: wide[c].mean())
        mpf = wide[("mpf", 100, 1)]
        if r["object"] == "Ob3 v1":
            # "smaller than most of the values": below more than half of the MultiPDF/BF configurations,
            # so below the one ranked (n - 1) // 2 by mean aRMSE (with n = 4: the second best, beating 3 of 4;
            # the third best beat 2 of 4, half)
            ref = pf_cols[(len(pf_cols) - 1) // 2]
            ctx.claim("the estimation quality was improved only for Ob3 in version (v1) ... Only for this "
                      "plant, the quality index in Table 4 is smaller than most of the values presented in "
                      "the corresponding Fig. 5", "[MultiPDF] §7, Table 4", f"Ob3 v1: aRMSE(MPF) - "
                      f"aRMSE(MultiPDF N_p={ref[1]}, N_f={ref[2]}, ranked {(len(pf_cols) - 1) // 2 + 1} of "
                      f"{len(pf_cols)}: beating it beats more than half)", direction((mpf - wide[ref]).to_numpy(), -1, "aRMSE difference"),
                      paper="< 0")
        else:
            ref = pf_cols[-1]  # the worst MultiPDF/BF configuration by mean aRMSE
            o = direction((mpf - wide[ref]).to_numpy(), +1, "aRMSE difference")
            q = f"{r['object']}: aRMSE(MPF) - aRMSE(worst MultiPDF/BF: N_p={ref[1]}, N_f={ref[2]})"
            worse.append((o, q))
            ctx.compare(f"table4: {q}", ours=o.ours,
                        note=f"one case of the 'other objects' sentence: {interval_text(o)}")
    ctx.claim("For other objects, the MPF result is worse than the worst results from MultiPDF PF (higher "
              "aRMSE values than all values visible in the graphs)", "[MultiPDF] §7, Table 4",
              "per object (Ob2, Ob3 v2-v5): aRMSE(MPF) - aRMSE(worst MultiPDF/BF configuration), paired "
              "per run", all_cases([o for o, _ in worse], 1.0, "MPF worse than the worst MultiPDF/BF",
                                    "every other object of Table 4"),
              paper="> 0 for each other object",
              note="our worst configuration is at N_p = 100, the smallest of our reference grid; the "
                   "paper's graphs may reach smaller N_p (larger aRMSE), which would make the sentence "
                   "harder to meet")
    ctx.note("table4: the numeric Table 4 values were lost in the text extraction; only the claim "
             "'MPF improves only on Ob3 v1, elsewhere worse than the worst MultiPDF result' is "
             "tested (as claims). With every state linear in the transition the MPF is an EKF (one copy, "
             "independent of N_p, as the paper says); the reference grid is N_p in {100, 1000}, "
             "N_f in {1, 3}, M = 100.")
    ctx.note("table4: for Ob3 v2 and v4 the measurement Jacobian vanishes at the prior mean "
             "x = 0 (products x_i x_j), so the EKF never moves off 0 and its aRMSE equals the RMS "
             "of the state itself (same value for both); for v5 the EKF diverges (log/min "
             "singularities).")
