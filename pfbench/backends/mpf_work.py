"""The numba MPF kernel's arguments as named groups (:mod:`pfbench.backends.numba_mpf`).

The drivers take the parameters, the generator, ``u`` and three groups: :class:`Structure` (the
model's linear-Gaussian split), :class:`Outputs` and :class:`Work` (the kernel's per-particle
arrays, allocated by the host); the step math of :mod:`pfbench.backends.numba_mpf_steps` and the
model's wrappers, called by address, take these groups too. numba types a named tuple by its
fields, so the argument types of every call by address are ``numba.typeof`` of the very objects
the host passes (:func:`pfbench.backends.particle_work.pass_types`): the order of the fields is
written once, here. Both drivers fill one :class:`Work` type (the Kalman driver with one copy and
no x^n), so the step math they share is compiled once for both.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Structure(NamedTuple):
    """The model's conditionally linear-Gaussian split, as
    :func:`pfbench.filters.marginalized.structure` returns it (:func:`structure_group`): the
    indices of x^n and x^l; the noise blocks Q^n, the decorrelated Q^l, T = Q^ln (Q^n)^-1 and
    whether there is a cross-covariance (``corr``); the measurement whitening ``W``, the
    per-output variances ``rvar``, ``whiten``, ``logdet``; the x^l prior ``m0``, ``P0``; the
    (whitened) measurements ``yw`` (M, n_y)."""

    idx_n: np.ndarray
    idx_l: np.ndarray
    Qn: np.ndarray
    Ql: np.ndarray
    T: np.ndarray
    corr: bool
    W: np.ndarray
    rvar: np.ndarray
    whiten: bool
    logdet: float
    m0: np.ndarray
    P0: np.ndarray
    yw: np.ndarray


def structure_group(s: dict) -> Structure:
    """The :class:`Structure` of the dict ``s`` of :func:`pfbench.filters.marginalized.structure`."""
    return Structure(**{name: s[name] for name in Structure._fields})


class Outputs(NamedTuple):
    """What a run fills: ``est`` (M, n_x), ``cov`` (M, n_x, n_x), ``ess``, ``inc``, ``degen`` (M,)."""

    est: np.ndarray
    cov: np.ndarray
    ess: np.ndarray
    inc: np.ndarray
    degen: np.ndarray


class Work(NamedTuple):
    """The kernel's arrays (:func:`work_arrays`), float64 C arrays but ``idx``; n particles, d_n
    and d_l the sizes of x^n and x^l, n_y outputs. The Kalman driver fills it with n = 1, d_n = 0
    and keeps its x^l state in ``mm``, ``Pm``."""

    #: (n, d_n) the x^n particles: the prior draw (the host's), then the resampled ones
    xn: np.ndarray
    #: (n, d_l), (n, d_l, d_l) the x^l means and covariances of the particles
    m: np.ndarray
    P: np.ndarray
    #: (n, d_n) the x^n noise of a step; (n, d_n) the new x^n sample
    z: np.ndarray
    xnew: np.ndarray
    #: the model's ``cl_transition``: f^n (n, d_n), A^n (n, d_n, d_l), f^l (n, d_l), A^l (n, d_l, d_l)
    fn: np.ndarray
    An: np.ndarray
    fl: np.ndarray
    Al: np.ndarray
    #: A^n P (n, d_n, d_l), N = A^n P A^n' + Q^n (n, d_n, d_n) and its Cholesky factor L
    APn: np.ndarray
    N: np.ndarray
    L: np.ndarray
    #: (d_n,), (d_n, d_l) scratch of the conditioning
    w: np.ndarray
    V: np.ndarray
    #: the x^l transition after conditioning (n, d_l), (n, d_l, d_l)
    f: np.ndarray
    A: np.ndarray
    #: x^l conditioned on x^n, then measurement-updated (n, d_l), (n, d_l, d_l)
    mm: np.ndarray
    Pm: np.ndarray
    #: A P (n, d_l, d_l) scratch of the time update; the predicted x^l (n, d_l), (n, d_l, d_l)
    APl: np.ndarray
    m_pred: np.ndarray
    P_pred: np.ndarray
    #: (n, d_n) the constrained x^n; the model's ``cl_observation``: h (n, n_y), C (n, n_y, d_l)
    xs: np.ndarray
    h: np.ndarray
    C: np.ndarray
    #: (n_y,), (n_y, d_l), (d_l,) scratch of the measurement update
    h0: np.ndarray
    H: np.ndarray
    PH: np.ndarray
    #: (n,) log-likelihoods, log-weights, weights, their running sum; (n,) int64 ancestors
    ll: np.ndarray
    lw: np.ndarray
    wu: np.ndarray
    cdf: np.ndarray
    idx: np.ndarray
    #: the weighted means and variances of x^n (d_n,) and of the x^l means (d_l,)
    mean_n: np.ndarray
    var_n: np.ndarray
    mean_l: np.ndarray
    var_l: np.ndarray
    #: (n, d_n + d_l) the deviations from the mean of the mixture moments
    dev: np.ndarray


def work_arrays(xn, d_l: int, n_y: int) -> Work:
    """The kernel's arrays for the initial x^n particles ``xn`` (n, d_n), float64 C (kept as
    :attr:`Work.xn`; None: the Kalman driver, one copy, no x^n), d_l linear states and n_y
    outputs. Allocated here, not in the kernel: an array constructor compiled into a kernel is
    compile time on every cold start."""
    if xn is None:
        xn = np.empty((1, 0))
    n, d_n = xn.shape
    shapes = dict(m=(n, d_l), P=(n, d_l, d_l), z=(n, d_n), xnew=(n, d_n), fn=(n, d_n), An=(n, d_n, d_l),
                  fl=(n, d_l), Al=(n, d_l, d_l), APn=(n, d_n, d_l), N=(n, d_n, d_n), L=(n, d_n, d_n), w=d_n,
                  V=(d_n, d_l), f=(n, d_l), A=(n, d_l, d_l), mm=(n, d_l), Pm=(n, d_l, d_l), APl=(n, d_l, d_l),
                  m_pred=(n, d_l), P_pred=(n, d_l, d_l), xs=(n, d_n), h=(n, n_y), C=(n, n_y, d_l), h0=n_y,
                  H=(n_y, d_l), PH=d_l, ll=n, lw=n, wu=n, cdf=n, mean_n=d_n, var_n=d_n, mean_l=d_l, var_l=d_l,
                  dev=(n, d_n + d_l))
    return Work(xn=xn, idx=np.empty(n, np.int64), **{name: np.empty(shape) for name, shape in shapes.items()})
