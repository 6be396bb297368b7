"""Tests of pfbench.plants.rtd ([RTD]): models, RC fit, boundary layer, data logs and the rtd recipes."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pfbench import kalman
from pfbench.plants import rtd
from pfbench.errors import DataError, InputError


def test_identified_model_poles_and_gain():
    p = rtd.tf_poles()
    np.testing.assert_allclose(p, rtd.PAPER_POLES, atol=5e-5)      # chapter rounds to 4 decimals
    m = rtd.identified_model()
    np.testing.assert_allclose(np.sort(m.poles_z.real), np.exp(np.sort(p) * rtd.TS), rtol=1e-12)
    assert m.dc_gain == pytest.approx(0.1711 / 0.1695, rel=1e-10)
    # ZOH step response at the samples equals the continuous step response of eq. 52
    from scipy.signal import step
    tt = np.arange(50) * rtd.TS
    _, yc = step((rtd.TF_NUM, rtd.TF_DEN), T=tt)
    np.testing.assert_allclose(m.simulate(np.ones(50)), yc, atol=1e-6)


def test_eq54_sign_choice_is_the_stable_one():
    assert np.abs(rtd.eq54_model().poles_z).max() < 1.0
    assert np.abs(rtd.eq54_model({"A21": 1.0}).poles_z).max() > 1.0


def test_fit_exponential_exact_on_noise_free_data():
    t = np.linspace(0, 10, 40)
    f = rtd.fit_exponential(t, 3.0 * np.exp(-0.25 * t))
    assert f.amp == pytest.approx(3.0, rel=1e-12) and f.rate == pytest.approx(-0.25, rel=1e-12)
    assert f.tau == pytest.approx(4.0, rel=1e-12)
    with pytest.raises(InputError):
        rtd.fit_exponential(t, -np.exp(-t))


@pytest.mark.parametrize("seed", range(5))
def test_rc_fit_recovers_time_constant_from_noisy_step(seed):
    """tau = 5 s, step 25 -> 38 degC, noise sd 0.1 degC at Ts = 0.1 s. Tolerance: 4 sd of the
    delta-method standard error of the log-linear slope plus its second-order bias."""
    tau, Ts, sd, lo, hi = 5.0, 0.1, 0.1, 25.0, 38.0
    t = np.arange(0, 40, Ts)
    truth = hi - (hi - lo) * np.exp(-t / tau)
    y = truth + sd * np.random.default_rng(seed).standard_normal(t.size)
    fit = rtd.fit_rc_step(t, y, y_final=hi, y_start=lo, frac=(0.1, 0.9))
    # theory on the (approximately the same) window of the noise-free response
    prog = (truth - lo) / (hi - lo)
    sel = (prog >= 0.1) & (prog <= 0.9)
    d = hi - truth[sel]
    tw = t[sel] - t[sel].mean()
    w = tw / np.sum(tw ** 2)                        # slope = sum w_i ln|d_i + e_i|
    sd_rate = np.sqrt(np.sum(w ** 2 * sd ** 2 / d ** 2))
    bias_rate = abs(np.sum(w * (-sd ** 2 / (2 * d ** 2))))
    tol_tau = tau ** 2 * (4 * sd_rate + bias_rate)  # d tau = tau^2 d rate
    assert tol_tau < 0.05 * tau                     # the test is informative
    assert abs(fit.tau - tau) < tol_tau


def test_rc_model_discretisation():
    rc = rtd.rc_model(2.0, Ts=0.1, gain=260.0)
    assert rc.A[0, 0] == pytest.approx(np.exp(-0.05)) and rc.B[0, 0] == pytest.approx(1 - np.exp(-0.05))
    assert rc.C[0, 0] == 260.0
    assert rc.dc_gain == pytest.approx(260.0)
    with pytest.raises(InputError):
        rtd.rc_model(-1.0)


def test_predictors_exact_on_noise_free_first_order_data():
    """If the readings follow the RC model exactly, every innovation is zero, so both predictors
    reproduce the readings exactly whatever Q and R."""
    rc = rtd.rc_model(1.5, gain=1.0)
    t, u = rtd.bath_profile(25.0, 38.0, 20.0)
    y = rc.simulate(u, x0=np.array([25.0]))
    bl = rtd.boundary_layer(y, u, rc, qr_a=(10.0, 0.1), qr_b=(0.01, 0.1))
    np.testing.assert_allclose(bl.pred_a, y, atol=1e-9)
    np.testing.assert_allclose(bl.pred_b, y, atol=1e-9)
    assert bl.gains[0] > bl.gains[1] > 0
    assert rtd.envelope_fraction(y, bl.pred_a, bl.pred_b) == 1.0


def test_envelope_fraction():
    ref = np.array([0.0, 1.0, 2.0, 3.0])
    assert rtd.envelope_fraction(ref, ref - 1, ref + 1) == 1.0
    assert rtd.envelope_fraction(ref, ref + 1, ref + 2) == 0.0
    assert rtd.envelope_fraction(ref, np.array([1, 0, 3, 4.0]), np.array([2, 2, 2, 5.0]),
                                 mask=[True, True, True, False]) == pytest.approx(2 / 3)


def test_fig5_filter_is_consistent():
    """The error variance of the time-varying KF over many noise realisations equals its own C P C^T
    (chi-square tolerance: 4 sd of a sample variance of N draws is 4 sqrt(2/(N-1)) relative)."""
    N, n = 400, 60
    errs = np.empty(N)
    for s in range(N):
        d = rtd.simulate_fig5(n=n, seed=s)
        errs[s] = d["y_true"][-1] - d["yest"][-1]
    d = rtd.simulate_fig5(n=n, seed=0)
    v = d["errcov"][-1]
    m = d["model"]
    _, P_post, _ = kalman.steady_state_gain(m.A, m.C, d["Qx"], [[1.0]])
    # after 6 s the slow mode (pole 0.993) still moves C P C^T in the 6th digit
    assert v == pytest.approx((m.C @ P_post @ m.C.T)[0, 0], rel=1e-4)
    assert abs(errs.var(ddof=1) / v - 1.0) < 4 * np.sqrt(2.0 / (N - 1))
    assert abs(errs.mean()) < 4 * np.sqrt(v / N)


# ----------------------------------------------------------------------------- logs

def _write(path, text):
    path.write_text(text)
    return path


def test_load_log_errors(tmp_path):
    with pytest.raises(DataError, match="not found"):
        rtd.load_log(tmp_path / "nope.csv")
    with pytest.raises(DataError, match="missing column 'y'"):
        rtd.load_log(_write(tmp_path / "a.csv", "t,z\n" + "".join(f"{i},{i}\n" for i in range(30))))
    with pytest.raises(DataError, match="non-numeric"):
        rtd.load_log(_write(tmp_path / "b.csv", "t,y\n" + "".join(f"{i},x{i}\n" for i in range(30))))
    with pytest.raises(DataError, match="at least 20"):
        rtd.load_log(_write(tmp_path / "c.csv", "t,y\n0,1\n1,2\n"))
    with pytest.raises(DataError, match="strictly increasing"):
        rtd.load_log(_write(tmp_path / "d.csv", "t,y\n" + "".join(f"{i % 10},{i}\n" for i in range(30))))
    with pytest.raises(DataError, match="uniformly"):
        rtd.load_log(_write(tmp_path / "e.csv", "t,y\n" + "".join(f"{i * i},{i}\n" for i in range(30))))
    with pytest.raises(DataError, match="NaN"):
        rtd.load_log(_write(tmp_path / "f.csv", "t,y\n" + "".join(f"{i},{'nan' if i == 3 else i}\n" for i in range(30))))
    with pytest.raises(DataError, match="cannot parse"):
        rtd.load_log(_write(tmp_path / "g.csv", 't,y\n"0,1\n'))


def test_load_log_reconstructs_setpoint(tmp_path):
    t, u, y_true, y = rtd.simulate_bath(R=0.01, seed=1)
    p = tmp_path / "log.csv"
    pd.DataFrame({"t": t, "y": y}).to_csv(p, index=False)
    log = rtd.load_log(p)
    assert log["u_reconstructed"] and log["Ts"] == pytest.approx(rtd.TS)
    levels = sorted(set(np.round(log["u"], 0)))
    assert levels == [25.0, 38.0]
    # steps found within 1 s of the true ones
    ch_true = np.nonzero(np.diff(u))[0]
    ch = np.nonzero(np.diff(log["u"]))[0]
    assert ch.size == 2 and np.all(np.abs(ch - ch_true) <= 10)


# ----------------------------------------------------------------------------- recipes

def _run(name, tmp_path, **kw):
    from pfbench import recipes

    return recipes.run(recipes.resolve(name), out_root=tmp_path, quiet=True, **kw)


def test_recipes_quick(tmp_path):
    ctx = _run("rtd:poles", tmp_path)
    comp = {c.quantity: c for c in ctx.comparisons}
    c1 = comp["eq. 52 pole 1 (roots of s^2 + 2.488 s + 0.1695)"]
    assert abs(c1.ours - c1.paper) < 1e-4
    assert comp["DARE max |ours - scipy solve_discrete_are|"].ours < 1e-10
    assert (comp["RC (C = 260): scalar DARE closed form"].ours
            == pytest.approx(comp["RC (C = 260): general generalized-Schur DARE"].ours, rel=1e-9))
    ctx = _run("rtd:fig5", tmp_path)
    df = pd.read_csv(tmp_path / "rtd" / "fig5.csv")
    assert len(df) == 600 and (tmp_path / "rtd" / "fig5.png").stat().st_size > 10_000
    for name in ("rtd:fig6", "rtd:fig7"):
        ctx = _run(name, tmp_path)
        assert (tmp_path / "rtd" / f"{name.split(':')[1]}.png").exists()
    f7 = pd.read_csv(tmp_path / "rtd" / "fig7.csv")
    assert set(f7["direction"]) == {"up", "down"} and f7["fraction_inside"].between(0, 1).all()


def test_bath_recipe_on_data(tmp_path):
    t, u, _, y = rtd.simulate_bath(R=0.02, seed=4)
    good = tmp_path / "bath.csv"
    pd.DataFrame({"t": t, "y": y, "u": u}).to_csv(good, index=False)
    ctx = _run("rtd:fig6", tmp_path, data=good)
    assert any("log bath.csv" in n for n in ctx.notes)
    bad = _write(tmp_path / "bad.csv", "time,reading\n1,2\n")
    with pytest.raises(DataError, match="missing column"):
        _run("rtd:fig7", tmp_path, data=bad)
    flat = tmp_path / "flat.csv"
    pd.DataFrame({"t": t, "y": y, "u": np.full(t.size, 25.0)}).to_csv(flat, index=False)
    with pytest.raises(DataError, match="step up"):
        _run("rtd:fig6", tmp_path, data=flat)
    # on one log the fig6 claims are decided on its single run (no interval over runs)
    assert ctx.claims and all(c["verdict"] in ("agree", "disagree") and "on the one log" in c["rule"]
                              for c in ctx.claims)


# ----------------------------------------------------------------------------- Figs. 2-4 model curves

def test_tf_bode_is_eq52_evaluated_on_the_imaginary_axis():
    """Catches a Hz/rad-s mix-up or a wrong numerator/denominator: the Bode data must equal
    20 log10 |G(jw)| and arg G(jw) computed directly from the eq. 52 polynomials."""
    w = np.logspace(-3, 2, 50)
    w_out, mag, phase = rtd.tf_bode(w)
    g = np.polyval(rtd.TF_NUM, 1j * w) / np.polyval(rtd.TF_DEN, 1j * w)
    np.testing.assert_allclose(w_out, w)
    np.testing.assert_allclose(mag, 20 * np.log10(np.abs(g)), atol=1e-9)
    np.testing.assert_allclose(phase, np.degrees(np.angle(g)), atol=1e-7)
    # relative degree 1: -20 dB/decade far above the fast pole (2.42 rad/s); within 0.5 dB at 100 rad/s
    _, m2, _ = rtd.tf_bode([100.0, 1000.0])
    assert m2[1] - m2[0] == pytest.approx(-20.0, abs=0.5)
    with pytest.raises(InputError):
        rtd.tf_bode([0.0, 1.0])


def test_tf_step_is_the_zoh_model_at_the_samples():
    """ZOH discretisation is exact for a step input, so the continuous step response of eq. 52 at
    t = k Ts equals the discrete model's response (catches a wrong amplitude or a time shift)."""
    t = np.arange(200) * rtd.TS
    y = rtd.tf_step(t, 38.0)
    np.testing.assert_allclose(y, rtd.identified_model().simulate(np.full(200, 38.0)), atol=1e-6)
    # final value 38 x DC gain (slow pole 0.0701: e^-0.0701*300 ~ 7e-10)
    assert rtd.tf_step(np.linspace(0, 300, 3001))[-1] == pytest.approx(38.0 * 0.1711 / 0.1695, rel=1e-6)
    with pytest.raises(InputError):
        rtd.tf_step([1.0, 0.5])


RTD_RECIPES = ("rtd:poles", "rtd:fig2", "rtd:fig3", "rtd:fig4", "rtd:fig5", "rtd:fig6", "rtd:fig7")


def test_every_rtd_recipe_records_computed_claims(tmp_path):
    from pfbench import recipes
    from pfbench.verdicts import VERDICTS

    ids = {r.id for r in recipes.select("rtd")}
    assert set(RTD_RECIPES) <= ids
    claims = {}
    for name in sorted(ids):
        opts = {"seeds": "2"} if name in ("rtd:fig6", "rtd:fig7") else {}
        ctx = _run(name, tmp_path, options=opts)
        assert ctx.claims, f"{name} records no claim"
        for c in ctx.claims:
            assert c["verdict"] in VERDICTS and c["rule"] and c["where"].startswith("[RTD]"), (name, c)
        claims[name] = {c["quantity"]: c for c in ctx.claims}
    # the measured curves of Figs. 2 and 4 are lost: claimed not reproducible, and the figures exist
    for name in ("rtd:fig2", "rtd:fig4"):
        assert "not reproducible" in {c["verdict"] for c in claims[name].values()}
        assert (tmp_path / "rtd" / f"{name.split(':')[1]}.png").stat().st_size > 10_000
    assert (tmp_path / "rtd" / "fig3.png").exists()
    # pinned findings (a change of behaviour is noticed): poles agree to the printed decimals; the
    # microcontroller formula is the continuous-time ARE root, not the DARE of its discrete loop;
    # the Bode diagram of eq. 52 has a -20 dB/decade roll-off (near pole-zero cancellation)
    po = claims["rtd:poles"]
    assert po["eq. 52 pole 1"]["verdict"] == po["eq. 52 pole 2"]["verdict"] == "agree"
    cont = [c for q, c in po.items() if "continuous-time ARE" in q]
    disc = [c for q, c in po.items() if "discrete-time ARE" in q]
    assert [c["verdict"] for c in cont] == ["agree"] and [c["verdict"] for c in disc] == ["disagree"]
    assert claims["rtd:fig3"]["high-frequency slope of the Bode magnitude"]["verdict"] == "disagree"
    # the fig6/fig7 claims are decided from per-run paired differences over the 2 runs
    for c in list(claims["rtd:fig6"].values()) + list(claims["rtd:fig7"].values()):
        assert c["n"] == 2 and "t-interval" in c["rule"]


def test_fig5_bound_claim_counts_runs(tmp_path):
    """The '< 1 degC after 45 s' claim is a rate over the Monte Carlo runs of fig5_mc.csv."""
    ctx = _run("rtd:fig5", tmp_path)
    mc = pd.read_csv(tmp_path / "rtd" / "fig5_mc.csv")
    c = {c["quantity"]: c for c in ctx.claims}
    every = c["runs whose max |error| over t >= 45 s is < 1 degC"]
    assert every["n"] == len(mc) and every["ours"] == pytest.approx(np.mean(mc["max_abs_err_after_45s"] < 1.0))
    at45 = c["runs with |error at t = 45 s| < 1 degC"]
    assert at45["ours"] == pytest.approx(np.mean(np.abs(mc["err_at_45s"]) < 1.0))


def test_bath_seeds_option_checked(tmp_path):
    with pytest.raises(InputError, match="seeds"):
        _run("rtd:fig6", tmp_path, options={"seeds": "1"})
