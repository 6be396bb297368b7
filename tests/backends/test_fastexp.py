"""The engine's branch-free exp: accuracy against the math library, the same bits on both backends,
and the compile settings that let the kernels vectorise it."""
from __future__ import annotations

import platform

import numba
import numpy as np
import pytest

from pfbench.backends import fastexp, numba_weights
from pfbench.backends.fastexp import exp_array, exp_scalar
from pfbench.backends.kernels import build
from pfbench.backends.particle_work import Step, work_arrays
from pfbench.methods import Method


@numba.njit(error_model="numpy")
def _exp_loop(x, out):
    for i in range(x.shape[0]):
        out[i] = exp_scalar(x[i])


def _grid():
    rng = np.random.default_rng(3)
    return np.concatenate([np.linspace(-745.2, 709.78, 400_001),  # every binade of the result, subnormals included
                           rng.uniform(-50.0, 0.0, 100_000),  # where the filters' log-weights live
                           -rng.exponential(1e-3, 10_000), [0.0, -0.0, 1e-300, -1e-300]])


def test_within_one_ulp_of_the_math_library():
    """Catches a wrong coefficient, a one-part ln 2 (errors grow with |k|), a wrong rounding of k and
    a power-of-two scaling that flushes the subnormals: each puts many results more than 1 ulp away."""
    x = _grid()
    ours = exp_array(x)
    ref = np.exp(x)
    ulps = np.abs(ours.view(np.int64) - ref.view(np.int64))
    assert ulps.max() <= 1
    assert (ulps == 0).mean() > 0.8  # mostly the correctly rounded result
    sub = (ref > 0) & (ref < np.finfo(float).tiny)
    assert sub.sum() > 1000 and ulps[sub].max() <= 1  # gradual underflow, not a flush to zero


def test_special_values_and_clamping():
    """exp(0) = 1 exactly, -inf and anything below -746 give 0, +inf and overflow give +inf, NaN
    gives 0 (documented: the weighting maps NaN to -inf first). Catches a missing clamp, where
    -inf would go through an undefined float -> int conversion."""
    x = np.array([0.0, -0.0, -np.inf, -746.0, -1e308, 710.0, 1e308, np.inf, np.nan])
    with np.errstate(over="ignore"):
        ours = exp_array(x)
    np.testing.assert_array_equal(ours, [1.0, 1.0, 0.0, 0.0, 0.0, np.inf, np.inf, np.inf, 0.0])


def test_numba_and_numpy_give_the_same_bits():
    """The weights of the two backends are bit-identical. Catches a change of operation order (or
    a fused multiply-add) in one of the twins."""
    x = np.concatenate([_grid(), [-np.inf, np.nan, 710.0]])
    out = np.empty_like(x)
    _exp_loop(x, out)
    with np.errstate(over="ignore"):
        ref = exp_array(x)
    np.testing.assert_array_equal(out.view(np.int64), ref.view(np.int64))


def test_kernels_compile_their_exp_loops_without_the_zero_division_check():
    """numba's default error model guards every float division with a check that raises, which
    stops LLVM from vectorising the exp loop. Catches dropping ``error_model="numpy"`` from a kernel
    that calls the exp."""
    import pfbench.models

    mod = build("particle", pfbench.models.get("ob1"), "systematic")
    for disp in (mod._pass_b, numba_weights.weigh):
        assert disp.targetoptions.get("error_model") == "numpy", disp


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="checks x86 SIMD instructions")
def test_the_exp_loop_vectorises():
    """The compiled loop uses packed double divisions (the rational step of every lane at once).
    Catches a construct in exp_scalar that LLVM cannot vectorise (a call, a branch, a check)."""
    x = np.linspace(-5, 0, 64)
    out = np.empty_like(x)
    _exp_loop(x, out)
    asm = next(iter(_exp_loop.inspect_asm().values()))
    assert "divpd" in asm, "no packed division: the exp loop did not vectorise"
    assert fastexp._SHIFT_BITS == np.float64(fastexp._SHIFT).view(np.int64)


def _has_avx512() -> bool:
    try:
        with open("/proc/cpuinfo") as fh:
            return " avx512f" in fh.read()
    except OSError:
        return False


@pytest.mark.skipif(not _has_avx512(), reason="LLVM emits gathers for this mistake only with AVX-512")
def test_pass_b_exp_loop_uses_plain_loads_and_stores():
    """Pass B's exponentials (over one stream block [i0, i1) of the particles) compile to packed
    loads and stores. Indexed ``la[i]`` for i from the run-time ``i0``, numba keeps its
    negative-index wraparound on every access and the vectorised loop reads through gathers and
    writes through scatters (measured: about twice the time); over views that start at 0 it does
    not. Catches a block loop written back over ``range(i0, i1)``."""
    from pfbench.backends import numba_weights

    disp = numba_weights.block_weights
    opts = {k: v for k, v in disp.targetoptions.items() if k != "nopython"}
    fresh = numba.njit(**opts)(disp.py_func)  # compiled here: a cache load has no assembly
    n = 64
    work = work_arrays(np.zeros((1, n, 1)), 2, np.array([0, 8, n]), int(Method.SIR))
    work.xs[:] = 0.0
    work.gstate[:, 0] = (0, 1)
    la = work.fwork[2]
    la[:] = -np.linspace(0.0, 5.0, n)
    a = la.copy()
    fresh(work, Step(0, 0, 1, False, False, 0.0, 0.0))  # block 1: particles [8, n)
    np.testing.assert_array_equal(la[8:], exp_array(a[8:]))  # in place, from the block's start
    np.testing.assert_array_equal(la[:8], a[:8])
    asm = "\n".join(fresh.inspect_asm().values())
    assert "divpd" in asm, "the exp loop did not vectorise"
    assert "vgatherqpd" not in asm and "vscatterqpd" not in asm
