"""Operation counting (pfbench.mcu.counting): derived from the NumPy engine, exact and linear."""
import numpy as np
import pytest

from pfbench import models
from pfbench.backends import numpy_backend
from pfbench.errors import PfbenchError
from pfbench.mcu import counting
from pfbench.models.ob1 import Ob1


def _exact(model, m, n, **kw):
    return counting.count_run(model, m, n, exact=True, **kw)


def _diff(a, b):
    return {k: b.get(k, 0) - a.get(k, 0) for k in set(a) | set(b)}


@pytest.mark.parametrize("method,nf", [("bootstrap", 1), ("sis", 1), ("asir", 1), ("multipdf", 2)])
def test_counts_affine_in_particles(method, nf):
    # bootstrap work does not depend on the data: counts(N) = a + b N exactly
    c = [_exact("ob1", 5, n, method=method, n_filters=nf) for n in (20, 40, 60)]
    d1, d2 = _diff(c[0], c[1]), _diff(c[1], c[2])
    assert d1 == d2
    assert d1["normal"] == 5 * 20  # one transition draw per particle-step (Ob1 n_noise = 1)


def test_counts_affine_in_steps_and_extrapolation_exact():
    c = [_exact("ob1", m, 30) for m in (3, 6, 9)]
    assert _diff(c[0], c[1]) == _diff(c[1], c[2])
    # the fast path (probe steps + affine extrapolation) equals counting every step
    assert counting.count_run("ob1", 25, 30) == _exact("ob1", 25, 30)


def test_scalar_step_work_counted_once_per_step():
    # Ob1's 8 cos(1.2 t) is loop-invariant: one cos per step, whatever N_p
    for n in (10, 50):
        assert _exact("ob1", 7, n)["cos"] == 7


def test_transition_draws_are_steps_times_particles_times_noise_dim():
    # each extra step draws exactly N_p * n_noise standard normals (initial draws cancel)
    for model in ("ob1", "ob3", "thermal_inertial"):
        mdl = models.get(model)
        for n in (8, 16):
            d = _exact(mdl, 4, n)["normal"] - _exact(mdl, 2, n)["normal"]
            assert d == 2 * n * mdl.n_noise


class _ExtraCos(Ob1):
    """Ob1 plus one cos per particle whose result is discarded (a register temporary)."""

    @staticmethod
    def transition(x, u, t, noise, p):
        out = Ob1.transition(x, u, t, noise, p)
        np.cos(out)
        return out


def test_one_extra_cos_per_particle_costs_exactly_one_cos():
    m, n = 6, 25
    base, extra = _exact(Ob1(), m, n), _exact(_ExtraCos(), m, n)
    d = {k: v for k, v in _diff(base, extra).items() if v}
    assert d == {"cos": m * n}


def test_ob1_counts_are_pinned():
    """The NumPy engine's operations on Ob1 (bootstrap, 2 steps, 10 particles), pinned: they feed
    every MCU prediction (the cost model's efficiency is fitted on Ob1), so a change must be
    deliberate. Catches host-only bookkeeping counted as firmware work (the count of the model's NaN
    log-likelihoods, done in NumPy's own arithmetic, added 10 compares and 10 integer operations)."""
    assert _exact("ob1", 2, 10) == {"add": 314, "mul": 246, "div": 26, "div_scalar": 60, "cmp": 142, "exp": 20,
                                    "log": 2, "cos": 2, "int": 80, "load": 470, "store": 230, "uniform": 2,
                                    "normal": 20}


def test_box_muller_normals_counted_as_draws():
    c = _exact("ob1", 2, 10)
    assert c["uniform"] == 2  # one systematic-resampling uniform per step
    assert c["normal"] == 20


def test_engine_restored_after_counting_and_error():
    orig = numpy_backend.np
    _exact("ob1", 2, 5)
    assert numpy_backend.np is orig
    with pytest.raises(PfbenchError):
        counting.count_run("ob1", 2, 5, method="nope")
    assert numpy_backend.np is orig


def test_counting_does_not_change_the_numbers():
    # arrays computed under counting are the same as plain NumPy
    with counting.counting() as cnt:
        a = counting._wrap(np.linspace(0.1, 2.0, 11), mem=True)
        r = np.exp(a) * 2.0 + np.cos(a) / 3.0
    np.testing.assert_array_equal(np.asarray(r), np.exp(np.linspace(0.1, 2.0, 11)) * 2.0
                                  + np.cos(np.linspace(0.1, 2.0, 11)) / 3.0)
    assert cnt.as_dict() == {"add": 11, "mul": 11, "div_scalar": 11, "exp": 11, "cos": 11, "load": 22}


@pytest.mark.parametrize("bad", [dict(method="x"), dict(n_filters=2), dict(resampling="zzz")])
def test_bad_configuration(bad):
    with pytest.raises(PfbenchError):
        counting.count_run("ob1", 3, 10, **bad)


def test_counts_beyond_one_stream_block():
    # N_p above numpy_backend.BLOCK: counting runs the population as one block (it gives the engine
    # no per-block streams); before that was handled the draws of the first block were broadcast
    # against the whole population and counting failed for N_p > BLOCK
    n = numpy_backend.BLOCK + 100
    c = _exact("ob1", 2, n)
    assert c["normal"] == 2 * n


# ---------------------------------------------------------------- compiled-code conventions
class _ToyMatmul:
    """x_t = x_{t-1} @ A + noise (2 states), log-likelihood of y = x[:, 0]."""
    n_noise = 2
    A = np.array([[0.9, 0.1], [0.0, 0.8]])

    def kernel_functions(self):
        def transition(x, u, t, noise, p):
            return x @ self.A + noise

        def log_likelihood(y, x, u, t, p):
            xx = x[:, 0]                 # a view: no temporary
            return -0.5 * (y[0] - xx) ** 2

        return {"initial": None, "transition": transition, "log_likelihood": log_likelihood,
                "observe": None}


@pytest.mark.parametrize("n", [32, 33, 64])
def test_code_ops_on_toy_model(n):
    # tmp: every array result is materialised (transition: x @ A and + noise, 2 N each;
    # log-likelihood: y - xx, **2, * -0.5, N each; the view x[:, 0] none) -> 7 N elements;
    # alloc: 5 arrays, each once per 32-particle tile; mm_load: 2 k loads per output element.
    # Catches: views counted as arrays, allocations per call instead of per tile, a matrix
    # product without its operand loads, code ops leaking outside the model functions.
    toy = counting._CountingModel(_ToyMatmul(), True).kernel_functions()
    x = counting._wrap(np.ones((n, 2)), mem=True)
    with counting.counting() as c:
        xp = toy["transition"](x, np.zeros(0), 3, counting._wrap(np.zeros((n, 2)), mem=True), ())
        toy["log_likelihood"](np.array([0.5]), xp, np.zeros(0), 3, ())
        _ = counting._wrap(np.ones(n), mem=False) * 2.0     # outside the model: no code ops
    ops = c.as_dict()
    tiles = -(-n // 32)
    assert ops["tmp"] == 7 * n
    assert ops["alloc"] == 5 * tiles
    assert ops["mm_load"] == 2 * (n * 2) * 2
    assert ops["mul"] == n * 2 * 2 + n + n + n   # matmul k=2, square, * -0.5, outside * 2


def test_code_counts_leave_engine_counts_alone_and_follow_ob1_source():
    # Ob1's source has 9 array results in transition and 7 in log_likelihood: 16 per particle
    # per step, allocated once per tile of 32; every other count is the same with code=True
    m, n = 5, 65
    plain = counting.count_run("ob1", m, n, exact=True)
    code = counting.count_run("ob1", m, n, exact=True, code=True)
    assert {k: v for k, v in code.items() if k not in counting.CODE_OPS} == plain
    assert code["tmp"] == 16 * m * n
    assert code["alloc"] == 16 * m * 3          # ceil(65 / 32) = 3 tiles
    assert "mm_load" not in code


def test_cbrt_is_its_own_operation():
    # ob4's transition takes one np.cbrt per particle: counted as cbrt (newlib cbrt costs about
    # half a pow), never as pow. Catches cbrt mapped back to pow.
    c = _exact("ob4", 3, 20)
    assert c.get("cbrt", 0) > 0 and c["cbrt"] % 20 == 0
    assert c.get("pow", 0) == 0
