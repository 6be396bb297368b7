"""Every filtering algorithm of pfbench.

* :func:`run_filter` (:mod:`.run`): the one entry point, dispatching on :class:`Method`;
* :mod:`.particle`: bootstrap / SIR / SIS / ASIR / MultiPDF (the bootstrap-family kernel);
* :mod:`.marginalized`: the marginalized PF on a model's linear-Gaussian substructure;
* :mod:`.guided`: the guided filter with a model's proposal or the locally optimal one;
* :mod:`.kalman` (public name ``pfbench.kalman``): KF, EKF, time-varying and steady-state KF;
  :mod:`.dare`: the discrete algebraic Riccati equation;
* :mod:`.result`: :class:`FilterResult`, what every filter returns; :mod:`.methods`: the table
  of methods.

How the algorithms execute (NumPy reference, numba kernels) lives in :mod:`pfbench.backends`.
"""
from ..methods import METHODS, Method
from .result import FilterResult
from .run import run_filter

__all__ = ["run_filter", "FilterResult", "Method", "METHODS"]
