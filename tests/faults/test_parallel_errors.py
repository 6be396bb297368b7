"""An exception raised by compiled code inside the all-threads kernel reaches the caller as itself
(numba's parallel region hands it back as a SystemError caused by it)."""
import pytest

import pfbench
from pfbench.errors import UnsupportedError


def test_model_error_in_the_all_threads_kernel_is_the_models_error():
    """pmsm_reduced's log-likelihood raises UnsupportedError (it has no p(y_t | x_t)); run on more
    than one stream block and two threads, the filter raises that error, as the serial kernel
    does, so the CLI prints one line instead of a SystemError traceback. Catches: the
    all-threads call without the unwrapping."""
    m = pfbench.models.get("pmsm_reduced")
    tr = m.simulate(2, seed=0)
    with pytest.raises(UnsupportedError, match="no p\\(y_t"):
        pfbench.run_filter(m, tr.y, tr.u, method="bootstrap", n_particles=4, backend="numba", seed=0,
                           n_threads=2, _block=2)
