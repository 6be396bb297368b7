"""Validation shared by every filter entry point: measurements, inputs, seeds, thresholds."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..models.base import StateSpaceModel

def check_inputs(model, y, u):
    """``y`` as a C-contiguous float64 (M, n_y) array and ``u`` as (M, n_u), or an InputError.

    NaN/inf measurements or inputs are rejected up front with the first bad step named.
    """
    if not isinstance(model, StateSpaceModel):
        raise InputError("model must be a pfbench StateSpaceModel (see pfbench.models.get)")
    y = np.asarray(y, dtype=np.float64)
    given = y.shape
    if y.ndim == 1 and model.n_y == 1:  # one measurement per step
        y = y.reshape(-1, 1)
    if y.ndim != 2 or y.shape[1] != model.n_y:  # a 1-D y for several outputs: steps or one step? refused
        raise InputError(f"y must have shape (n_steps, {model.n_y}), got {given}")
    if y.shape[0] < 1:
        raise InputError("y has no steps: at least one measurement is needed")
    bad = ~np.isfinite(y).all(axis=1)
    if bad.any():
        t = int(np.argmax(bad))
        raise InputError(f"measurement y at step {t} is not finite ({y[t].tolist()}); "
                         "remove or interpolate bad samples first")
    u = model.input_array(u, y.shape[0])
    if not np.isfinite(u).all():
        t = int(np.argmax(~np.isfinite(u).all(axis=1)))
        raise InputError(f"input u at step {t} is not finite")
    return np.ascontiguousarray(y), np.ascontiguousarray(u)


def seed_sequence(seed) -> np.random.SeedSequence:
    """``seed`` (int or SeedSequence) as a SeedSequence; a negative or non-integer seed is an InputError."""
    if isinstance(seed, np.random.SeedSequence):
        return seed
    try:
        return np.random.SeedSequence(seed)
    except (TypeError, ValueError) as exc:
        raise InputError(f"seed must be a non-negative integer, a sequence of them or a numpy.random.SeedSequence "
                         f"(None: fresh entropy, a run that cannot be repeated), got {seed!r}") from exc


def ess_count(ess_threshold, n_per: int) -> float:
    """The resampling threshold as a particle count from a *fraction* of N_p in (0, 1].

    ``ess_threshold`` is the fraction of the (sub-filter) particle count below which N_eff
    triggers resampling, as in the ``particles`` library (default 0.5). Anything outside (0, 1]
    is refused: a count such as 12 would silently never resample.
    """
    frac = 0.5 if ess_threshold is None else ess_threshold
    try:
        if isinstance(frac, (bool, np.bool_)):  # True was taken as 1.0
            raise TypeError
        frac = float(frac)
    except (TypeError, ValueError):
        raise InputError(f"ess_threshold must be a number in (0, 1], got {ess_threshold!r}") from None
    if not (0.0 < frac <= 1.0):
        raise InputError(f"ess_threshold is a fraction of N_p in (0, 1] (resample when N_eff < "
                         f"ess_threshold * N_p), got {ess_threshold!r}")
    return frac * n_per
