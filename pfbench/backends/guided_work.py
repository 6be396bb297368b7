"""The numba guided kernel's arguments as named groups (:mod:`pfbench.backends.numba_guided`).

A whole run (``run_proposal``/``run_optimal``) takes the parameters, the generator, ``y``, ``u``,
the particles and log-weights and two groups, :class:`Outputs` and :class:`Settings`; the field
order is written once, here. numba types a named tuple by its fields, so the driver's argument
types are ``numba.typeof`` of the objects the host passes. The model's calls by address keep the
model's own argument order (``_model_calls`` of :mod:`pfbench.backends.numba_backend`).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Outputs(NamedTuple):
    """What a run fills: ``est``, ``var`` (M, n_x); ``ess``, ``inc``, ``resampled``, ``degen`` (M,)."""

    est: np.ndarray
    var: np.ndarray
    ess: np.ndarray
    inc: np.ndarray
    resampled: np.ndarray
    degen: np.ndarray


class Settings(NamedTuple):
    """A run's constants: standard normals per particle for the proposal; the
    :class:`~pfbench.resampling.Scheme` code; the resampling threshold (a particle count); the
    native entry addresses of the model's proposal and of its weight (the proposal's weight or the
    predictive likelihood) (:mod:`pfbench.backends.native_call`; 0 until the host has them)."""

    n_noise: int
    scheme: int
    threshold: float
    propose: int = 0
    weight: int = 0

