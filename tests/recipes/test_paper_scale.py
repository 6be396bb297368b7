"""Paper-scale runs (`make test-slow`; not run by CI)."""
import numpy as np
import pytest

import pfbench
from pfbench import kalman, recipes

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("recipe_id", ["thesis:fig4.9", "multipdf:fig3", "embedded:tableA1", "rtd:fig5"])
def test_full_recipe_runs_and_records_comparisons(recipe_id, tmp_path):
    ctx = recipes.run(recipes.resolve(recipe_id), full=True, out_root=tmp_path, quiet=True)
    assert ctx.outputs and all((tmp_path / ctx.recipe.paper).exists() for _ in ctx.outputs)
    assert ctx.comparisons
    assert (tmp_path / ctx.recipe.paper / f"{ctx.recipe.name}.json").exists()


def test_bootstrap_matches_kalman_at_large_n():
    """N_p = 200000: Monte Carlo error of the posterior mean ~ 0.62 * sqrt(c / N) << 0.01."""
    model = pfbench.models.get("linear_gaussian", A=[[0.9]], C=[[1.0]], Q=[[1.0]], R=[[1.0]])
    traj = model.simulate(200, seed=1)
    kf = kalman.filter_model(model, traj.y)
    r = pfbench.run_filter(model, traj.y, method="bootstrap", n_particles=200_000, backend="numba", seed=2)
    assert np.sqrt(np.mean((r.estimates[:, 0] - kf.means[:, 0]) ** 2)) < 0.01
    assert r.loglik == pytest.approx(kf.loglik, abs=0.1)
