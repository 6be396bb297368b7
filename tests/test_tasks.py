"""pfbench.tasks: the registry (at least 10 tasks, `pfbench tasks --json`), deterministic datasets,
the shipped real data, the exact reference, the three classic models on both backends; sweeps
keep each run's seed and log-likelihood."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

import pfbench
from pfbench import tasks
from pfbench.cli import main


def test_tasks_json_lists_at_least_ten_with_the_fields():
    res = CliRunner().invoke(main, ["tasks", "--json"])
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)
    assert len(rows) >= 10
    for r in rows:
        assert {"name", "model", "steps", "datasets", "data", "reference"} <= set(r)
        assert r["data"] in ("simulated", "real")
    by = {r["name"]: r for r in rows}
    assert by["lg-d2"]["reference"] == "exact-loglik" and by["ob1"]["reference"] is None
    assert by["sv-gbpusd"]["data"] == "real"
    assert {"ob1", "ob2", "ob3-v1", "ob3-v5", "ob4", "ob5", "thermal", "pmsm", "bearings-only",
            "lorenz96-d20"} <= set(by)
    text = CliRunner().invoke(main, ["tasks"])
    assert text.exit_code == 0 and "sv-gbpusd" in text.stdout


def test_unknown_task_is_an_input_error():
    with pytest.raises(pfbench.InputError, match="did you mean ob1"):
        tasks.get("ob11")


def test_datasets_are_fixed_and_equal_to_the_sweep_trajectories():
    from pfbench.sweep.core import trajectory_seed

    t = tasks.get("ob1")
    a, b = tasks.dataset(t, 3), tasks.dataset(t, 3)
    assert np.array_equal(a.y, b.y) and not np.array_equal(a.y, tasks.dataset(t, 4).y)
    sw = t.get_model().simulate(t.steps, seed=np.random.default_rng(trajectory_seed({"seed": 0}, 3)))
    assert np.array_equal(a.y, sw.y)
    assert tasks.filter_seed(t, 3) == tasks.filter_seed(t, 3) != tasks.filter_seed(t, 4)


def test_real_data_is_the_750_gbp_usd_returns():
    t = tasks.get("sv-gbpusd")
    tr = tasks.dataset(t, 0)
    assert tr.y.shape == (750, 1) and np.all(np.isnan(tr.x))
    # first return: 100 log(0.59154 / 0.59296), the file's first two rates
    assert tr.y[0, 0] == pytest.approx(100 * np.log(0.59154 / 0.59296), rel=1e-12)
    assert 0.3 < tr.y.std() < 1.0  # daily % moves of a major currency pair


def test_exact_reference_is_the_kalman_filter():
    t = tasks.get("lg-d2")
    m = t.get_model()
    tr = tasks.dataset(t, 0, m)
    ll, means = tasks.exact_reference(t, tr, m)
    kf = pfbench.run_filter(m, tr.y, method="kalman", backend="numpy")
    assert abs(kf.loglik - ll) < 1e-9 and np.allclose(kf.estimates, means, atol=1e-12)
    assert tasks.exact_reference(tasks.get("ob1"), tasks.dataset(tasks.get("ob1"), 0)) is None


@pytest.mark.parametrize("name,kw,steps", [("stochastic_volatility", {}, 30), ("bearings_only", {}, 12),
                                           ("lorenz96", {"d": 6}, 10)])
def test_classic_models_agree_on_both_backends(name, kw, steps):
    m = pfbench.models.get(name, **kw)
    tr = m.simulate(steps, seed=1)
    lls = [pfbench.run_filter(m, tr.y, method="bootstrap", n_particles=64, backend=b, seed=2).loglik
           for b in ("numpy", "numba")]
    assert np.isfinite(lls[0]) and abs(lls[0] - lls[1]) <= 1e-9 * abs(lls[0])


def test_stochastic_volatility_prior_is_stationary():
    m = pfbench.models.get("stochastic_volatility")
    x = m.initial(np.random.default_rng(0), 200000, m.params())
    assert x.mean() == pytest.approx(m.mu, abs=0.01)
    assert x.std() == pytest.approx(m.sigma / np.sqrt(1 - m.rho ** 2), rel=0.01)


def test_sweep_rows_keep_seed_and_loglik(tmp_path):
    from pfbench.sweep import load_frame, make_spec, run_sweep

    spec = make_spec("ob1", methods=("bootstrap",), particles=(50,), runs=2, steps=20, backend="numpy")
    out = tmp_path / "s.jsonl"
    run_sweep(spec, out, workers=1, progress=False)
    frame, _, _ = load_frame(out)
    assert {"loglik", "seed", "seed_key"} <= set(frame.columns)
    row = frame.iloc[1]
    model = pfbench.models.get("ob1")
    from pfbench.sweep.core import trajectory_seed

    tr = model.simulate(20, seed=np.random.default_rng(trajectory_seed(spec, int(row["run"]))))
    key = tuple(int(k) for k in row["seed_key"].split("."))
    res = pfbench.run_filter(model, tr.y, method="bootstrap", n_particles=50, backend="numpy",
                             seed=np.random.SeedSequence(int(row["seed"]), spawn_key=key))
    assert res.loglik == pytest.approx(row["loglik"], rel=1e-12)
