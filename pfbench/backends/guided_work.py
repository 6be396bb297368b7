"""The guided filter's arguments as named groups (:mod:`pfbench.backends.numba_guided`, its NumPy twin
:mod:`pfbench.filters.guided`): a step takes :class:`Particles`, :class:`Settings` and :class:`Moments`, a
whole run :class:`Particles`, :class:`Outputs` and :class:`Settings`. numba types a named tuple by its
fields (:mod:`pfbench.backends.particle_work`): the host passes instances, compiled code may build them.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Particles(NamedTuple):
    """The particles ``x`` (N_p, n_x) and their normalised log-weights ``lw`` (N_p,), updated in place."""

    x: np.ndarray
    lw: np.ndarray


class Moments(NamedTuple):
    """Where a step writes the weighted ``mean`` and ``var`` (n_x,) of its particles."""

    mean: np.ndarray
    var: np.ndarray


class Outputs(NamedTuple):
    """What a run fills: ``est``, ``var`` (M, n_x); ``ess``, ``inc``, ``resampled``, ``degen`` (M,)."""

    est: np.ndarray
    var: np.ndarray
    ess: np.ndarray
    inc: np.ndarray
    resampled: np.ndarray
    degen: np.ndarray


class Settings(NamedTuple):
    """A run's constants: ``n_noise`` normals per particle for the proposal, the :class:`~pfbench.resampling.Scheme`
    code, the ``threshold`` (a particle count: resample when N_eff < threshold) and the model's two calls, its
    proposal and its weight or predictive likelihood: entry addresses in a scheme's compiled module (0 until the
    host has them; the any-scheme module ignores them), the model's functions in the NumPy reference."""

    n_noise: int
    scheme: int
    threshold: float
    propose: int = 0
    weight: int = 0
