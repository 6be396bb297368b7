"""multipdf Table 4: marginalized PF aRMSE for Ob2 and Ob3 v1-v5 ([MultiPDF] §5, §7)."""
from __future__ import annotations

import pandas as pd

from pfbench.recipes import recipe

from ._common import OPTIONS, sweep

OBJECTS = [("Ob2", "ob2", {}), ("Ob3 v1", "ob3", {"version": 1}), ("Ob3 v2", "ob3", {"version": 2}),
           ("Ob3 v3", "ob3", {"version": 3}), ("Ob3 v4", "ob3", {"version": 4}),
           ("Ob3 v5", "ob3", {"version": 5})]


@recipe("multipdf:table4", aliases=("mpf-table",), title="MPF aRMSE, Ob2 and Ob3 v1-v5 (Table 4)",
        quick_cost="~30 s", full_cost="~10 min", options=OPTIONS)
def table4(ctx):
    rows = []
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
        rows.append({"object": label, "mpf_armse": mpf,
                     "mpf_lo": float(s.loc[("mpf", 100, 1), "armse_lo"]),
                     "mpf_hi": float(s.loc[("mpf", 100, 1), "armse_hi"]),
                     "multipdf_worst": float(pf.max()), "multipdf_best": float(pf.min()),
                     "bf_np100": float(pf[(100, 1)]), "bf_np1000": float(pf[(1000, 1)]),
                     "runs": spec["runs"]})
    df = pd.DataFrame(rows)
    ctx.write_table("table4", df)
    for r in rows:
        wins = r["mpf_armse"] < r["multipdf_worst"]
        ctx.compare(f"table4: {r['object']} MPF aRMSE", ours=r["mpf_armse"],
                    note=f"MultiPDF/BF range {r['multipdf_best']:.3f}-{r['multipdf_worst']:.3f}")
        ctx.compare(f"table4: {r['object']} MPF better than the worst MultiPDF/BF value",
                    ours="yes" if wins else "no",
                    paper="yes" if r["object"] == "Ob3 v1" else "no")
    ctx.note("table4: the numeric Table 4 values were lost in the text extraction; only the claim "
             "'MPF improves only on Ob3 v1, elsewhere worse than the worst MultiPDF result' is "
             "compared. With every state linear in the transition the MPF is an EKF (one copy, "
             "independent of N_p, as the paper says); the reference grid is N_p in {100, 1000}, "
             "N_f in {1, 3}, M = 100.")
    ctx.note("table4: for Ob3 v2 and v4 the measurement Jacobian vanishes at the prior mean "
             "x = 0 (products x_i x_j), so the EKF never moves off 0 and its aRMSE equals the RMS "
             "of the state itself (same value for both); for v5 the EKF diverges (log/min "
             "singularities). Ob2's and Ob3 v4's EKF beat the worst PF value here, unlike the "
             "paper's statement.")
