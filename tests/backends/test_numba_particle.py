"""The particle kernel's branch-free systematic/stratified resampling gives the ancestors of the
sequential merge (and of the NumPy reference's searchsorted) for any weights and block split. Each
call gets a marks scratch of one estimate tile (what the kernel gives a block), so a merge that
indexed it by particle would write past it."""
import numpy as np
import pytest

import pfbench
from pfbench.backends.kernels import build
from pfbench.backends.particle_work import Settings, Step, work_arrays
from pfbench.methods import Method
from pfbench.resampling import Scheme


@pytest.fixture(scope="module")
def kernel():
    return build("particle", pfbench.models.get("ob1"), "systematic")


def _merge(kernel, cdf, u, ub, strat, bounds, lam_src, with_lam, pos=None):
    """Pass C over every block of ``bounds`` on particles 0..n-1 (one state): the resampled states
    (the ancestors) and the carried ``lam`` row. Each block gets its own estimate tile of marks."""
    n = cdf.size
    work = work_arrays(np.arange(n, dtype=np.float64).reshape(1, n, 1), len(bounds) - 1, bounds, int(Method.ASIR))
    work.xs[0, 0, :, 0] = np.arange(n)
    work.xs[1] = -1.0
    work.gstate[:, 0] = (0, 1)
    work.fwork[0], work.fwork[1], work.fwork[3], work.fwork[4] = ub, cdf, 0.0, lam_src
    work.fwork[2] = np.nan if pos is None else pos
    settings = Settings(1, int(Method.ASIR), int(Scheme.STRATIFIED if strat else Scheme.SYSTEMATIC), 0.0, False,
                        0, 0, 0)
    for b in range(len(bounds) - 1):
        kernel._merge_gather(work, settings, Step(0, 0, b, with_lam, False, 0.0, u))
    return work.xs[1, 0, :, 0], work.fwork[3]


@pytest.mark.parametrize("strat", [False, True])
def test_merge_gather_picks_the_searchsorted_ancestors(kernel, strat):
    """Uneven, sparse (70 % zeros), one-hot and flat weights, split into 1-3 output blocks. Catches
    an off-by-one in the count K_j (>= vs > against the positions), a zero-weight particle that keeps
    its mark instead of handing it on, a block that starts from the wrong ancestor, ties between
    a position and a cdf value (flat weights put positions exactly on the cdf), and ``lam`` written
    (or left alone, odd trials) against ``with_lam``."""
    rng = np.random.default_rng(11)
    for trial in range(600):
        n = int(rng.integers(1, 50))
        kind = trial % 5
        w = rng.random(n)
        if kind == 1:
            w[rng.random(n) < 0.7] = 0.0
        elif kind == 2:
            w = np.exp(-rng.exponential(30, n))
        elif kind == 3:
            w[:] = 0.0
            w[rng.integers(n)] = 1.0
        elif kind == 4:
            w[:] = 1.0
        if w.sum() == 0:
            w[0] = 1.0
        cdf = np.cumsum(w)
        u = 0.0 if kind == 4 else rng.random()
        ub = rng.random(n)
        pos = ((ub if strat else u) + np.arange(n)) / n * cdf[-1]
        expect = np.minimum(np.searchsorted(cdf, pos, side="right"), n - 1)
        with_lam = trial % 2 == 0
        bounds = np.unique(np.r_[0, np.sort(rng.integers(1, n + 1, int(rng.integers(0, 3)))), n])
        dst, lam_dst = _merge(kernel, cdf, u, ub, strat, bounds, np.arange(n) * 10.0, with_lam)
        np.testing.assert_array_equal(dst, expect, err_msg=f"trial {trial}")
        np.testing.assert_array_equal(lam_dst, expect * 10.0 if with_lam else 0.0)


@pytest.mark.parametrize("n", [7, 1000, 1024, 4099])
def test_merge_gather_is_exact_where_counts_sit_next_to_positions(kernel, n):
    """Systematic resampling takes each count K_j from cdf[j] n / total - u without the positions
    unless that lies within a rounding bound of an integer. Here every cdf value sits a few ulps
    from a position (and the last at the total), so the computed estimate is wrong in the last
    place for many j: the exact path must take over. Catches a bound that is too small (0 or one
    rounding), positions not computed before the corrections that need them, and an estimate
    trusted after the flag is set. 1-3 output blocks."""
    rng = np.random.default_rng(n)
    for trial in range(40):
        u = [0.0, 0.5, rng.random(), 1e-13, 1 - 1e-13][trial % 5]
        total = float(n) if trial % 2 else rng.uniform(1.0, 1e6)
        pos = (u + np.arange(n)) / n * total
        at = np.sort(rng.integers(0, n, n - 1))
        cdf = np.empty(n)
        cdf[:-1] = pos[at] * (1.0 + rng.integers(-4, 5, n - 1) * 2.0 ** -52)
        cdf[:-1] = np.minimum(np.maximum.accumulate(cdf[:-1]), total)
        cdf[-1] = total
        expect = np.minimum(np.searchsorted(cdf, pos, side="right"), n - 1)
        bounds = np.unique(np.r_[0, np.sort(rng.integers(1, n + 1, trial % 3)), n])
        dst, _ = _merge(kernel, cdf, u, np.zeros(n), False, bounds, np.zeros(n), False)
        np.testing.assert_array_equal(dst, expect, err_msg=f"trial {trial}")


def test_column_major_tiles_follow_the_instance_dimensions():
    """Tiles are typed column-major only for an instance with one state and one noise component.
    ``linear_gaussian`` takes its dimensions from its matrices while its class keeps the defaults
    n_x = n_noise = 1: deciding on the class would hand a (tile, 2) C array to the model typed 'F'
    (columns read as rows, silently wrong estimates). Catches a layout decided from the class, and
    a module cache that serves the 1-state module to a 2-state instance of the same class."""
    lg1 = pfbench.models.get("linear_gaussian")
    lg2 = pfbench.models.get("linear_gaussian", A=np.eye(2) * 0.9, C=[[1.0, 0.5]], Q=np.eye(2), R=[[0.5]])
    assert type(lg1) is type(lg2) and type(lg2).n_x == 1 and lg2.n_x == 2
    m1 = build("particle", lg1, "systematic")
    m2 = build("particle", lg2, "systematic")
    assert m1._F_TILES is True and m2._F_TILES is False
    assert build("particle", type(lg1), "systematic")._F_TILES is False


def test_float32_two_state_model_agrees_with_numpy():
    """float32 particles of a 2-state model (row-major tiles, the per-component conversion and
    store loops) give NumPy's numbers: both backends store the same float32 states from the same
    float64 model evaluation, so only the float64 moment sums differ in order (<= 1e-9, as for
    float64). Catches a component stored at the wrong offset, the likelihood fed the unrounded
    states, or float64 draws where float32 ones are due (the trajectories would part)."""
    model = pfbench.models.get("linear_gaussian", A=[[0.9, 0.1], [0.0, 0.8]], C=[[1.0, 0.5]],
                               Q=[[0.5, 0.1], [0.1, 0.3]], R=[[0.4]])
    traj = model.simulate(25, seed=2)
    kw = dict(method="bootstrap", n_particles=300, dtype="float32", seed=4)
    a = pfbench.run_filter(model, traj.y, traj.u, backend="numpy", **kw)
    b = pfbench.run_filter(model, traj.y, traj.u, backend="numba", **kw)
    np.testing.assert_allclose(b.estimates, a.estimates, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.loglik_increments, a.loglik_increments, rtol=1e-9, atol=1e-9)
    c = pfbench.run_filter(model, traj.y, traj.u, backend="numba", **{**kw, "dtype": "float64"})
    assert np.max(np.abs(c.estimates - b.estimates)) > 0  # float32 really is another run
