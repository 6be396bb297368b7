"""Public name of the Kalman family: ``pfbench.kalman`` re-exports :mod:`pfbench.filters.kalman`
(KF, EKF, time-varying and steady-state KF) and :mod:`pfbench.filters.dare` (the DARE by the
generalized Schur method, [RTD] eqs. 41-42)."""
from .filters import dare as _dare_module
from .filters import kalman as _kalman_module
from .filters.dare import *  # noqa: F401,F403
from .filters.kalman import *  # noqa: F401,F403

__all__ = list(_kalman_module.__all__) + list(_dare_module.__all__)
