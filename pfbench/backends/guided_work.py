"""The numba guided kernel's arguments as named groups (:mod:`pfbench.backends.numba_guided`).

A whole run takes the parameters, the generator, ``y``, ``u``, the particles and log-weights,
:class:`Outputs` and :class:`Settings`; as in :mod:`pfbench.backends.particle_work`, the argument
types are ``numba.typeof`` of the objects the host passes.
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
    """A run's constants: normals per particle for the proposal; the :class:`~pfbench.resampling.Scheme`
    code; the resampling threshold (a particle count); the entry addresses of the model's proposal and
    of its weight or predictive likelihood (0 until the host has them)."""

    n_noise: int
    scheme: int
    threshold: float
    propose: int = 0
    weight: int = 0

