"""The particle-family front end: MultiPDF's combined variance and likelihood increments, the
reported particle split, the ESS-threshold convention, the method table."""
import numpy as np
import pytest

import pfbench
from pfbench import models
from pfbench.errors import InputError
from pfbench.methods import METHODS, PARTICLE_METHODS, Method


@pytest.fixture(scope="module")
def ob4():
    model = models.get("ob4")
    return model, model.simulate(40, seed=2)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_multipdf_variance_is_the_law_of_total_variance(ob4, backend):
    """Var = mean of the sub-filter variances + variance of the sub-filter means (equal weights,
    [MultiPDF] eq. 9). Catches the old within-only variance (it misses the between term, which is
    of the order of the sub-filter spread and is not small here: checked below)."""
    model, traj = ob4
    r = pfbench.run_filter(model, traj.y, traj.u, method="multipdf", n_particles=60, n_filters=4,
                           backend=backend, seed=3)
    within = r.sub_variances.mean(axis=0)
    between = ((r.sub_estimates - r.estimates) ** 2).mean(axis=0)
    np.testing.assert_allclose(r.variances, within + between, rtol=1e-12)
    assert between.mean() > 1e-3 * within.mean()


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_multipdf_increments_sum_to_loglik_of_the_mean_likelihood(ob4, backend):
    """loglik = log mean_l p_hat_l(y_1:M) and its increments telescope to it. Catches increments
    taken from sub-filter 0 only (they sum to log p_hat_0, not to loglik)."""
    model, traj = ob4
    r = pfbench.run_filter(model, traj.y, traj.u, method="multipdf", n_particles=60, n_filters=4,
                           backend=backend, seed=3)
    sub_totals = np.array([np.sum(v) for v in _sub_increments(model, traj, backend)])
    expected = np.log(np.mean(np.exp(sub_totals - sub_totals.max()))) + sub_totals.max()
    assert r.loglik == pytest.approx(expected, rel=1e-12)
    assert r.loglik_increments.sum() == pytest.approx(r.loglik, rel=1e-12)
    assert not np.allclose(r.loglik, sub_totals[0])


def _sub_increments(model, traj, backend):
    """Each sub-filter run alone as a bootstrap filter on its own stream (MultiPDF's streams are
    SeedSequence(seed).spawn(N_f), one per sub-filter)."""
    out = []
    for ss in np.random.SeedSequence(3).spawn(4):
        r = pfbench.run_filter(model, traj.y, traj.u, method="bootstrap", n_particles=15,
                               backend=backend, seed=ss)
        out.append(r.loglik_increments)
    return out


def test_single_filter_increments_sum_to_loglik(ob4):
    model, traj = ob4
    for method in PARTICLE_METHODS:
        r = pfbench.run_filter(model, traj.y, traj.u, method=method, n_particles=50, backend="numpy",
                               seed=1, n_filters=2 if method == "multipdf" else 1)
        assert r.loglik_increments.sum() == pytest.approx(r.loglik, rel=1e-12), method


def test_uneven_multipdf_split_reports_the_particles_used(ob4):
    """N_p = 250, N_f = 100: round(2.5) = 2 per sub-filter, so 200 particles run; the result says so."""
    model, traj = ob4
    r = pfbench.run_filter(model, traj.y[:5], traj.u[:5], method="multipdf", n_particles=250,
                           n_filters=100, backend="numpy", seed=0)
    assert r.n_particles == 200 and r.info["n_per_filter"] == 2
    assert r.info["n_particles_requested"] == 250 and "200 particles" in r.info["note"]
    even = pfbench.run_filter(model, traj.y[:5], traj.u[:5], method="multipdf", n_particles=200,
                              n_filters=100, backend="numpy", seed=0)
    assert "n_particles_requested" not in even.info


@pytest.mark.parametrize("bad", [0.0, -0.1, 1.5, 12, "half"])
def test_ess_threshold_is_a_fraction(ob4, bad):
    """A count such as 12 (the old convention) used to be taken as a fraction > 1 or silently never
    trigger; now anything outside (0, 1] is refused with a message that names the convention."""
    model, traj = ob4
    with pytest.raises(InputError, match="ess_threshold"):
        pfbench.run_filter(model, traj.y, traj.u, method="sir", n_particles=50, ess_threshold=bad,
                           backend="numpy")


def test_ess_threshold_fraction_controls_resampling(ob4):
    """SIR with threshold 1 resamples whenever N_eff < N_p (every step with unequal weights), so it
    equals the bootstrap filter; a tiny threshold resamples less often."""
    model, traj = ob4
    kw = dict(n_particles=50, backend="numpy", seed=5, common_random_numbers=True)
    full = pfbench.run_filter(model, traj.y, traj.u, method="sir", ess_threshold=1.0, **kw)
    boot = pfbench.run_filter(model, traj.y, traj.u, method="bootstrap", **kw)
    rare = pfbench.run_filter(model, traj.y, traj.u, method="sir", ess_threshold=0.05, **kw)
    assert full.n_resampled == boot.n_resampled == traj.y.shape[0]
    np.testing.assert_array_equal(full.estimates, boot.estimates)
    assert rare.n_resampled < full.n_resampled


def test_ess_threshold_only_for_sir(ob4):
    model, traj = ob4
    with pytest.raises(InputError, match="sir"):
        pfbench.run_filter(model, traj.y, traj.u, method="bootstrap", n_particles=10, ess_threshold=0.5)


def test_one_method_table():
    """Every method name parses to its Method and back; unknown names list the choices."""
    assert METHODS == tuple(m.label for m in Method)
    for name in METHODS:
        assert Method.parse(name).label == name
    with pytest.raises(InputError, match="bootstrap, sir"):
        Method.parse("nope")


def test_one_group_does_not_ask_how_many_cores_are_free(ob4, monkeypatch):
    """One filter of one stream block, or any filter on NumPy, has nothing to spread over threads,
    so it does not read /proc for the free cores (about 0.1 ms a call, more than the filter itself
    at small N_p); catches the count taken for every run."""
    import pfbench.filters.particle as particle

    def refuse():
        raise AssertionError("free_cores read for a single group")

    monkeypatch.setattr(particle, "free_cores", refuse)
    model, traj = ob4
    res = pfbench.run_filter(model, traj.y, traj.u, method="bootstrap", n_particles=50, backend="numpy")
    assert res.n_particles == 50
    res = pfbench.run_filter(model, traj.y, traj.u, method="multipdf", n_particles=50, n_filters=2, backend="numpy")
    assert res.info["threads"] == 1
    with pytest.raises(AssertionError, match="single group"):  # several sub-filters on numba do need it
        pfbench.run_filter(model, traj.y, traj.u, method="multipdf", n_particles=50, n_filters=2,
                           backend="numba")
