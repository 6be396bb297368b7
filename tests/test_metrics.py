"""Estimation-quality metrics (pfbench.metrics, [MultiPDF] eqs. 11-14)."""
import numpy as np
import pytest

import pfbench
from pfbench import metrics
from pfbench.errors import InputError


def test_armse_is_the_mean_of_the_per_state_rmse():
    """[MultiPDF] eqs. 11-13 on numbers worked by hand: errors (3, 4) at one step and (0, 0) at the
    other give RMSE (sqrt(4.5), sqrt(8)) and their mean. Catches a mean over the wrong axis."""
    est, truth = np.array([[3.0, 4.0], [0.0, 0.0]]), np.zeros((2, 2))
    np.testing.assert_allclose(metrics.rmse(est, truth), [np.sqrt(4.5), np.sqrt(8.0)])
    assert metrics.armse(est, truth) == pytest.approx((np.sqrt(4.5) + np.sqrt(8.0)) / 2)
    np.testing.assert_allclose(metrics.distance(est, truth), [5.0, 0.0])


def test_a_result_and_a_trajectory_are_taken_as_they_are():
    """armse(res, traj) was "float() argument must be ... not 'FilterResult'"; scalars and empty
    arrays were NumPy's AxisError or a NaN with warnings. Catches either back."""
    model = pfbench.models.get("ob1")
    traj = model.simulate(10, seed=0)
    res = pfbench.run_filter(model, traj.y, n_particles=20, backend="numpy")
    assert metrics.armse(res, traj) == metrics.armse(res.estimates, traj.x)
    with pytest.raises(InputError, match=r"must both be \(n_steps, n_x\)"):
        metrics.armse(1.0, 2.0)
    with pytest.raises(InputError, match="no steps"):
        metrics.armse(np.zeros((0, 1)), np.zeros((0, 1)))
