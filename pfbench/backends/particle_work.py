"""The particle kernel's arguments as named groups (:mod:`pfbench.backends.numba_particle`).

The driver takes the parameters, the generators, ``y``, ``u``, :class:`Outputs`, :class:`Work` and
:class:`Settings`; each pass it calls by address takes these groups and a :class:`Step`. numba types a
named tuple by its fields, so a call's argument types are ``numba.typeof`` of the objects the host
passes (:func:`pass_types`), the field order written once, here.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..methods import Method

#: the rows of :attr:`Work.fwork`: stratified uniforms, running sum (cdf), log-weights (weights after
#: pass B; the merge's positions after that); ASIR only: the first-stage log-likelihoods of the
#: particles now in the buffer, and those of every particle before the first-stage resampling
F_UNIFORMS, F_CDF, F_WEIGHTS, F_LAM, F_LAM_ALL = range(5)
#: rows of :attr:`Work.bwork`, per block: max log-weight, weight sum, sum of squares, cdf offset, NaN/+inf count
B_MAX, B_SUM, B_SUM_SQ, B_OFFSET, B_INVALID = range(5)
#: particles per tile of the merge's count estimates
#: (:func:`pfbench.backends.numba_resampling.merge_gather`); :attr:`Work.iwork` holds one tile per block
ESTIMATE_TILE = 512


class Outputs(NamedTuple):
    """What a run of G filters fills: final particles ``x`` (G, N_p, n_x); ``est``, ``var`` (G, M, n_x);
    ``ess``, ``inc``, ``resampled``, ``degen`` (G, M); ``invalid`` (G, M): the log-likelihoods the model
    returned as NaN or +inf (weight zero); ``hist_x`` (G, M, N_p, n_x), ``hist_w`` (G, M, N_p): every
    step's weighted particles (second dimension 0: none)."""

    x: np.ndarray
    est: np.ndarray
    var: np.ndarray
    ess: np.ndarray
    inc: np.ndarray
    resampled: np.ndarray
    degen: np.ndarray
    invalid: np.ndarray
    hist_x: np.ndarray
    hist_w: np.ndarray

    def rows(self, sl: slice) -> "Outputs":
        """The outputs of the filters ``sl`` (views)."""
        return Outputs(*(a[sl] for a in self))


def outputs(n_filters: int, n_steps: int, n_particles: int, n_x: int, dtype=np.float64,
            store: bool = False) -> Outputs:
    """Fresh :class:`Outputs` of G = ``n_filters`` (N_f) filters of ``n_particles`` (N_p) particles
    over ``n_steps`` (M) steps, particles in ``dtype``; ``store``: room for every step's weighted
    particles."""
    G, M, n, k = n_filters, n_steps, n_particles, n_steps if store else 0
    return Outputs(x=np.empty((G, n, n_x), dtype), est=np.empty((G, M, n_x)), var=np.empty((G, M, n_x)),
                   ess=np.empty((G, M)), inc=np.empty((G, M)), resampled=np.zeros((G, M), np.bool_),
                   degen=np.zeros((G, M), np.bool_), invalid=np.zeros((G, M), np.int64),
                   hist_x=np.empty((G, k, n, n_x), dtype),
                   hist_w=np.empty((G, k, n)))


class Work(NamedTuple):
    """The kernel's work arrays (:func:`work_arrays`), allocated by the host: every array
    constructor compiled into a kernel adds to a cold start."""

    #: (2, G, N_p, n_x) in the particle dtype: the two particle buffers (resampling writes the
    #: other one, and they swap)
    xs: np.ndarray
    #: (G, N_p) log-weights kept between steps; (G, 0) for the bootstrap filter, which never keeps them
    lw: np.ndarray
    #: (3, N_p) float rows ``F_*`` (5 for ASIR)
    fwork: np.ndarray
    #: (N_p + B * ESTIMATE_TILE,) int64: ancestor indices, then one estimate tile of merge marks per block
    iwork: np.ndarray
    #: (5, B) per block, rows ``B_*``
    bwork: np.ndarray
    #: (2, B, n_x) per block: sums of w x and of w (x - x_0)^2
    bmom: np.ndarray
    #: (2, G) int64 per filter: the current particle buffer, and 1 while every log-weight is -log N_p
    gstate: np.ndarray
    #: (B + 1,) int64: the start of every stream block, then N_p
    bounds: np.ndarray


class Settings(NamedTuple):
    """A run's constants: the noise count; :class:`~pfbench.methods.Method` and :class:`~pfbench.resampling.Scheme`
    codes; the SIR threshold (particles); ``post`` (``estimate="post"``); the entry addresses of passes
    A, B and C (0 for a pass never called)."""

    n_noise: int
    method: int
    scheme: int
    ess_threshold: float
    post: bool
    pass_a: int
    pass_b: int
    merge: int


class Step(NamedTuple):
    """The scalars of one pass call: step ``t``, filter ``g``, stream block ``b``; ``first``: ASIR's
    first stage; ``asir``: ASIR's second stage; ``m``: the largest log-weight (pass B); ``u``: the
    systematic uniform (pass C). The defaults type the calls (:func:`pass_types`)."""

    t: int = 0
    g: int = 0
    b: int = 0
    first: bool = False
    asir: bool = False
    m: float = 0.0
    u: float = 0.0


def work_arrays(x, n_blocks: int, bounds, method: int) -> Work:
    """The work arrays for particles ``x`` (G, N_p, n_x) in ``n_blocks`` stream blocks and a
    :class:`~pfbench.methods.Method` code, only as large as the method uses: a fresh page is
    zero-filled by the operating system on first touch, so a row no pass reads costs nothing."""
    keeps_weights = method != int(Method.BOOTSTRAP)
    asir = method == int(Method.ASIR)
    G, n, n_x = x.shape
    return Work(xs=np.empty((2, G, n, n_x), x.dtype), lw=np.empty((G, n) if keeps_weights else (G, 0)),
                fwork=np.empty((F_LAM_ALL + 1 if asir else F_WEIGHTS + 1, n)),
                iwork=np.empty(n + n_blocks * ESTIMATE_TILE, np.int64), bwork=np.empty((B_INVALID + 1, n_blocks)),
                bmom=np.empty((2, n_blocks, n_x)), gstate=np.empty((2, G), np.int64),
                bounds=np.ascontiguousarray(bounds, dtype=np.int64))


def pass_types(*values) -> tuple:
    """The numba types of a pass's arguments from the objects the host hands the driver (a pass
    that takes a :class:`Step` gets ``Step()``)."""
    import numba

    return tuple(numba.typeof(v) for v in values)
