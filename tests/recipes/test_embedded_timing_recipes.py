"""Claims of the [Embedded] timing recipes (fig5, table2, table3, mcu) and the report's embedded section.

Every recipe records its claims with a verdict computed by a rule of pfbench.verdicts; hardware-bound
absolute times (our host is not the paper's PCs) are "not reproducible" with the reason.
"""
import pytest

from pfbench import recipes, report
from pfbench.mcu import costmodel as cm
from pfbench.verdicts import VERDICTS


def _run(name, tmp_path, **options):
    return recipes.run(recipes.resolve(name), out_root=tmp_path, quiet=True, options=options, seed=0)


def _claims(ctx):
    assert ctx.claims, "recipe records no claims"
    for c in ctx.claims:
        assert c["verdict"] in VERDICTS and c["rule"] and c["where"].startswith("[Embedded]"), c
    return ctx.claims


def test_table2_claims_are_leave_one_out_within_tolerance(tmp_path):
    claims = _claims(_run("table2", tmp_path))
    times = [c for c in claims if "execution time" in c["claim"]]
    assert len(times) == 6 and len([c for c in claims if "ratio" in c["claim"]]) == 3
    cal = {(c["M"], c["N_p"], c["build"]): c for c in cm.calibrate()["cells"]}
    for c in times:
        # the verdict follows from the recorded numbers: agree iff |LOO - published| <= 15 % published
        # (catches a claim fed the in-sample fit, or a hand-typed verdict)
        cell = next(v for (m, n, b), v in cal.items() if f"{b} execution time, M = {m}, N_p = {n}" in c["claim"])
        assert c["ours"] == pytest.approx(cell["loo_ms"]) and c["paper"] == cell["published_ms"]
        assert (c["verdict"] == "agree") == (abs(cell["loo_error"]) <= 0.15)


def test_fig5_and_table3_claims(tmp_path):
    claims = _claims(_run("fig5", tmp_path, repeats="1"))
    verdicts = {c["claim"]: c["verdict"] for c in claims}
    assert verdicts["The STM32F4 standard build D(S) is 57 to 360 times slower than platforms A-C"] == "not reproducible"
    assert verdicts["The highly optimized version D(O) is much more efficient than the standard D(S)"] == "agree"
    claims = {c["claim"]: c for c in _claims(_run("table3", tmp_path, repeats="1"))}
    c = claims["Platform C consumes about 2.3 times less energy per task than D(S)"]
    # ours = (board power x LOO D(S) time) / published platform C energy
    d_s = cm.BOARD_POWER_W * [x for x in cm.calibrate()["cells"]
                              if (x["M"], x["N_p"], x["build"]) == (1000, 1000, "D(S)")][0]["loo_ms"] / 3.6e6
    assert c["ours"] == pytest.approx(d_s / cm.TABLE3["C"][1])
    assert claims["D(O) consumes over 10 times less energy per task than platform C"]["verdict"] in ("agree", "disagree")
    assert any(v["verdict"] == "not reproducible" for v in claims.values())


def test_mcu_claims(tmp_path):
    if not recipes.needs_met(("mcu-tools",)):
        pytest.skip("needs `make mcu-tools`")
    claims = _claims(_run("mcu", tmp_path))
    assert len(claims) == 7          # 3 Table 2 cells x 2 builds + the ratio
    for c in claims:
        assert c["verdict"] in ("agree", "disagree")


def test_report_says_mcu_not_run_in_the_embedded_section(tmp_path, monkeypatch):
    # without the Cortex-M4 tools the embedded section itself (not only the problems list) says so
    monkeypatch.setattr(recipes, "needs_met", lambda needs: False)
    path, problems = report.write_report(tmp_path)
    text = path.read_text()
    section = text.split("## embedded:", 1)[1].split("\n## ", 1)[0]
    assert "`embedded:mcu`: not run: needs `make mcu-tools`" in section
    assert any(p.recipe == "embedded:mcu" and p.what.startswith("not run") for p in problems)
