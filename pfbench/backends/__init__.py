"""How the filters execute: ``numpy`` (the readable reference) and ``numba`` (the fast path).

Both expose ``run_group(model, p, rng, y, u, out, method, scheme, ess_threshold)`` for the particle
family (``out``: :func:`pfbench.backends.particle_work.outputs`);
:func:`pfbench.run_filter` is the public entry point. The marginalized and guided filters have
their compiled kernels in ``numba_mpf.py`` / ``numba_guided.py``.
"""
from __future__ import annotations

from ..methods import check_backend


def get(name: str):
    """The backend module by name."""
    check_backend(name)
    if name == "numpy":
        from . import numpy_backend

        return numpy_backend
    from . import numba_backend

    return numba_backend
