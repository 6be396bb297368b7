"""The MPF kernel's copy of what a model's structure functions return into its own arrays."""
import numba
import numpy as np
import pytest

from pfbench.backends.numba_mpf_steps import CONSTRAIN, OBSERVATION, TRANSITION, copy_into


@numba.njit(cache=False)
def _copy(src, dst, fn=TRANSITION):
    copy_into(src, dst, fn)


@pytest.mark.parametrize("src", [
    np.arange(12.0).reshape(3, 4),                       # C: read as it is
    np.arange(12.0).reshape(4, 3).T,                     # F: read through a C copy
    np.arange(24.0).reshape(3, 8)[:, ::2],               # strided: read through a C copy
    np.arange(12, dtype=np.int64).reshape(3, 4),         # another dtype, converted
    np.arange(24.0).reshape(2, 3, 4),                    # 3-D, C
    np.arange(24.0).reshape(4, 3, 2).transpose(2, 1, 0), # 3-D, F
])
def test_copy_into_gives_the_source_in_the_kernel_array(src):
    """Catches: a flat read of a non-contiguous source's memory (wrong order or wrong elements), a
    lost dtype conversion."""
    dst = np.full(src.shape, np.nan)
    _copy(src, dst)
    np.testing.assert_array_equal(dst, src.astype(np.float64))


@pytest.mark.parametrize("src", [np.zeros((3, 5)), np.zeros((4, 4)), np.zeros((4, 4)).T[:, :3]])
def test_copy_into_refuses_another_shape(src):
    """A model that returns another shape than the one it declared (same size or not) is an error,
    not memory read out of bounds. Catches: a missing shape check (the same-size (4, 3) source
    would then be copied in the wrong shape)."""
    with pytest.raises(ValueError, match=r"^cl_transition\(\) returned an array of another shape"):
        _copy(src, np.empty((3, 4)))


@pytest.mark.parametrize("fn, name", [(TRANSITION, "cl_transition"), (OBSERVATION, "cl_observation"),
                                      (CONSTRAIN, "cl_constrain")])
def test_copy_into_names_the_structure_function(fn, name):
    """The message names the function whose result changed shape. Catches the codes' messages
    swapped or one message for all three."""
    with pytest.raises(ValueError, match=rf"^{name}\(\) returned"):
        _copy(np.zeros((3, 5)), np.empty((3, 4)), fn)
