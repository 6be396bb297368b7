"""Public name of the Kalman family: ``pfbench.kalman`` re-exports :mod:`pfbench.filters.kalman`
(KF, EKF, time-varying and steady-state KF) and :mod:`pfbench.filters.dare` (the DARE by the
generalized Schur method, [RTD] eqs. 41-42)."""
from .filters.kalman import *  # noqa: F401,F403
from .filters.kalman import __all__  # noqa: F401
