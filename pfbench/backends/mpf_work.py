"""The numba MPF kernel's arguments as named groups (:mod:`pfbench.backends.numba_mpf`).

The drivers take the parameters, the generator, ``u``, :class:`Structure`, :class:`Outputs` and
:class:`Work` (allocated by the host), each made of small groups; a function called by address takes
only the groups it uses, as every array argument costs compile time whether read or not. Argument
types are ``numba.typeof`` of the objects passed (:func:`pfbench.backends.particle_work.pass_types`).
Both drivers fill one :class:`Work` type, so the step math they share is compiled once.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Affine(NamedTuple):
    """An affine map ``f + A x`` per particle: f (n, d), A (n, d, d_l); the model's x^n and x^l
    transitions, the measurement h + C x^l, the x^l transition after conditioning."""

    f: np.ndarray
    A: np.ndarray


class Gaussians(NamedTuple):
    """Means and covariances: (n, d_l), (n, d_l, d_l) per particle, or the prior's (d_l,), (d_l, d_l)."""

    m: np.ndarray
    P: np.ndarray


class Split(NamedTuple):
    """The state indices (int64) of x^n and of x^l."""

    n: np.ndarray
    l: np.ndarray  # noqa: E741 - x^l


class Noise(NamedTuple):
    """The process noise: Q^n, the decorrelated Q^l, T = Q^ln (Q^n)^-1, ``corr``: whether Q^ln != 0."""

    Qn: np.ndarray
    Ql: np.ndarray
    T: np.ndarray
    corr: bool


class Measurement(NamedTuple):
    """The measurements ``yw`` (M, n_y), whitened with ``W`` when ``whiten`` (``logdet`` the log
    determinant taken out), and the per-output variances ``rvar``."""

    yw: np.ndarray
    W: np.ndarray
    rvar: np.ndarray
    whiten: bool
    logdet: float


class Structure(NamedTuple):
    """The model's conditionally linear-Gaussian split, as
    :func:`pfbench.filters.marginalized.structure` returns it (:func:`structure_group`)."""

    split: Split
    noise: Noise
    meas: Measurement
    prior: Gaussians


def structure_group(s: dict) -> Structure:
    """The :class:`Structure` of the dict ``s`` of :func:`pfbench.filters.marginalized.structure`."""
    return Structure(Split(s["idx_n"], s["idx_l"]), Noise(s["Qn"], s["Ql"], s["T"], s["corr"]),
                     Measurement(s["yw"], s["W"], s["rvar"], s["whiten"], s["logdet"]), Gaussians(s["m0"], s["P0"]))


class Outputs(NamedTuple):
    """What a run fills: ``est`` (M, n_x), ``cov`` (M, n_x, n_x), ``ess``, ``inc``, ``degen`` (M,)."""

    est: np.ndarray
    cov: np.ndarray
    ess: np.ndarray
    inc: np.ndarray
    degen: np.ndarray


def outputs(n_steps: int, n_x: int) -> Outputs:
    """Zeroed :class:`Outputs` of a run of ``n_steps`` (M) steps."""
    M = n_steps
    return Outputs(np.zeros((M, n_x)), np.zeros((M, n_x, n_x)), np.zeros(M), np.zeros(M), np.zeros(M, np.bool_))


class Conditioning(NamedTuple):
    """The x^n sampling and conditioning: noise z (n, d_n); A^n P (n, d_n, d_l), N = A^n P A^n' + Q^n
    and its Cholesky factor L (n, d_n, d_n); scratch w (d_n,), V (d_n, d_l)."""

    z: np.ndarray
    APn: np.ndarray
    N: np.ndarray
    L: np.ndarray
    w: np.ndarray
    V: np.ndarray


class UpdateScratch(NamedTuple):
    """Scratch of the measurement update: h0 (n_y,), H (n_y, d_l), PH (d_l,)."""

    h0: np.ndarray
    H: np.ndarray
    PH: np.ndarray


class Weights(NamedTuple):
    """(n,) log-likelihoods, log-weights, weights, their running sum; (n,) int64 ancestors."""

    ll: np.ndarray
    lw: np.ndarray
    wu: np.ndarray
    cdf: np.ndarray
    idx: np.ndarray


class Moments(NamedTuple):
    """Weighted means and variances of x^n and of the x^l means; deviations from the mixture's mean."""

    mean_n: np.ndarray
    var_n: np.ndarray
    mean_l: np.ndarray
    var_l: np.ndarray
    dev: np.ndarray


class Work(NamedTuple):
    """The kernel's arrays (:func:`work_arrays`), float64 C but the ancestors, for n particles; the Kalman
    driver fills it with n = 1, d_n = 0 and keeps its x^l state in ``cond``."""

    #: (n, d_n) the x^n particles: the prior draw (the host's), then the resampled ones
    xn: np.ndarray
    #: the x^l of the particles
    prior: Gaussians
    #: the model's ``cl_transition``: f^n, A^n and f^l, A^l
    tn: Affine
    tl: Affine
    fac: Conditioning
    #: (n, d_n) the new x^n sample, and constrained (``cl_constrain``)
    xnew: np.ndarray
    xs: np.ndarray
    #: the x^l transition after conditioning
    lin: Affine
    #: x^l conditioned on x^n, then measurement-updated
    cond: Gaussians
    #: (n, d_l, d_l) scratch of the time update, and the predicted x^l
    APl: np.ndarray
    pred: Gaussians
    #: the model's ``cl_observation``: h (n, n_y), C (n, n_y, d_l)
    obs: Affine
    upd: UpdateScratch
    wts: Weights
    mom: Moments


def work_arrays(xn, d_l: int, n_y: int) -> Work:
    """The kernel's arrays for the x^n particles ``xn`` (n, d_n), float64 C, kept as :attr:`Work.xn`
    (None: the Kalman driver's one copy), d_l linear states and n_y outputs; allocated by the host, as
    building them in the driver compiled no faster than unboxing them."""
    if xn is None:
        xn = np.empty((1, 0))
    n, d_n = xn.shape
    return Work(xn,
                Gaussians(np.empty((n, d_l)), np.empty((n, d_l, d_l))),  # prior
                Affine(np.empty((n, d_n)), np.empty((n, d_n, d_l))),  # tn
                Affine(np.empty((n, d_l)), np.empty((n, d_l, d_l))),  # tl
                Conditioning(np.empty((n, d_n)), np.empty((n, d_n, d_l)), np.empty((n, d_n, d_n)),
                             np.empty((n, d_n, d_n)), np.empty(d_n), np.empty((d_n, d_l))),
                np.empty((n, d_n)), np.empty((n, d_n)),  # xnew, xs
                Affine(np.empty((n, d_l)), np.empty((n, d_l, d_l))),  # lin
                Gaussians(np.empty((n, d_l)), np.empty((n, d_l, d_l))),  # cond
                np.empty((n, d_l, d_l)),  # APl
                Gaussians(np.empty((n, d_l)), np.empty((n, d_l, d_l))),  # pred
                Affine(np.empty((n, n_y)), np.empty((n, n_y, d_l))),  # obs
                UpdateScratch(np.empty(n_y), np.empty((n_y, d_l)), np.empty(d_l)),
                Weights(np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n, np.int64)),
                Moments(np.empty(d_n), np.empty(d_n), np.empty(d_l), np.empty(d_l), np.empty((n, d_n + d_l))))
