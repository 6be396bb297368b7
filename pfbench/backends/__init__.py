"""Execution backends: ``numpy`` (reference) and ``numba`` (fast path).

Both expose ``run_group(model, p, rng, y, u, x, method, scheme, ess_threshold, est, var, ess,
inc, resampled, degen)``; :func:`pfbench.run_filter` is the public entry point.
"""
from __future__ import annotations

from ..errors import PfbenchError

NAMES = ("numpy", "numba")


def get(name: str):
    """The backend module by name."""
    if name == "numpy":
        from . import numpy_backend

        return numpy_backend
    if name == "numba":
        from . import numba_backend

        return numba_backend
    raise PfbenchError(f"unknown backend {name!r}; choose one of {', '.join(NAMES)}")
