"""Resampling schemes, NumPy reference implementations ([Thesis] §2.5; [MultiPDF] ref. [35]).

Every scheme takes (possibly unnormalised) non-negative ``weights`` of length N and a
``numpy.random.Generator`` and returns N ancestor indices (int64, sorted ascending), except
:func:`regularized`, which returns new particles. The numba backend has loop versions of
every scheme but :func:`regularized` in :mod:`pfbench.backends.numba_resampling`; both consume the generator in the
same documented amounts, so under the same generator state they return identical indices:

=====================  ======================================  =========================
scheme                 draws from the generator                 offspring variance
=====================  ======================================  =========================
systematic             1 uniform                               lowest (not always)
stratified             N uniforms                              <= multinomial
multinomial            N uniforms (inverse CDF, unsorted)       N w (1 - w)
residual               R uniforms, R = N - sum floor(N w)       <= multinomial
residual_deterministic none                                    deterministic
=====================  ======================================  =========================

All comparisons are made against the running sum of the *unnormalised* weights (computed
sequentially, ``np.cumsum``) scaled by its last element, so both backends do the same
floating-point operations.
"""
from __future__ import annotations

import math

import numpy as np

from .errors import InputError
from .options import Choice


class Scheme(Choice):
    """The one table of resampling schemes; the value is the code the compiled kernels branch on."""

    SYSTEMATIC = 0
    STRATIFIED = 1
    MULTINOMIAL = 2
    RESIDUAL = 3
    RESIDUAL_DETERMINISTIC = 4


Scheme._what = "resampling scheme"
SCHEMES = Scheme.labels()
#: the schemes whose positions (u_i + i) / N increase with i: the particle kernels resample them
#: by a merge over the running sum, per stream block (pass C of
#: :mod:`pfbench.backends.numba_particle`); every other scheme draws all N indices on the filter's
#: stream, then the particles are gathered
MERGED = frozenset({Scheme.SYSTEMATIC, Scheme.STRATIFIED})


def _cdf(weights: np.ndarray) -> np.ndarray:
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.size == 0:
        raise InputError("weights must be a non-empty 1-D array")
    cdf = np.cumsum(w)
    if not (np.isfinite(cdf[-1]) and cdf[-1] > 0.0) or np.any(w < 0):
        raise InputError("weights must be finite, non-negative and not all zero")
    return cdf


def _search(cdf: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Smallest j with cdf[j] > position (clamped to N-1 against rounding)."""
    idx = np.searchsorted(cdf, positions, side="right")
    return np.minimum(idx, cdf.size - 1).astype(np.int64)


def systematic(weights, rng: np.random.Generator) -> np.ndarray:
    """Systematic resampling: positions (U + i) / N, one U ~ U[0, 1) ([Embedded] Alg. 1 step 5)."""
    cdf = _cdf(weights)
    n = cdf.size
    u = rng.random()
    positions = (u + np.arange(n)) / n * cdf[-1]
    return _search(cdf, positions)


def stratified(weights, rng: np.random.Generator) -> np.ndarray:
    """Stratified resampling: positions (U_i + i) / N, U_i ~ U[0, 1) independent."""
    cdf = _cdf(weights)
    n = cdf.size
    positions = (rng.random(n) + np.arange(n)) / n * cdf[-1]
    return _search(cdf, positions)


def multinomial(weights, rng: np.random.Generator) -> np.ndarray:
    """Multinomial resampling ([Thesis] §2.5.1): N i.i.d. draws by inverse CDF."""
    cdf = _cdf(weights)
    n = cdf.size
    return np.sort(_search(cdf, rng.random(n) * cdf[-1]))


def residual_counts(weights) -> tuple[np.ndarray, np.ndarray]:
    """floor(N w_i) offspring and the residuals N w_i - floor(N w_i) ([Thesis] §2.5.2)."""
    cdf = _cdf(weights)
    n = cdf.size
    w = np.asarray(weights, dtype=np.float64)
    nw = (w / cdf[-1]) * n  # normalise first: n / total overflows when total is subnormal
    counts = np.floor(nw).astype(np.int64)
    return counts, nw - counts


def residual(weights, rng: np.random.Generator) -> np.ndarray:
    """Residual resampling with a random (multinomial) remainder ([Thesis] §2.5.2)."""
    counts, res = residual_counts(weights)
    n = counts.size
    r = n - int(counts.sum())
    if r > 0:
        rcdf = np.cumsum(res)
        extra = _search(rcdf, rng.random(r) * rcdf[-1])
        counts = counts + np.bincount(extra, minlength=n)
    return np.repeat(np.arange(n, dtype=np.int64), counts)


def residual_deterministic(weights, rng: np.random.Generator | None = None) -> np.ndarray:
    """Residual resampling with a deterministic remainder: the R largest residuals get one more.

    Ties are broken by the lower index (stable sort). Draws nothing from ``rng``.
    """
    counts, res = residual_counts(weights)
    n = counts.size
    r = n - int(counts.sum())
    if r > 0:
        order = np.argsort(-res, kind="mergesort")[:r]
        counts = counts.copy()
        counts[order] += 1
    return np.repeat(np.arange(n, dtype=np.int64), counts)


_FUNCS = {Scheme.SYSTEMATIC: systematic, Scheme.STRATIFIED: stratified, Scheme.MULTINOMIAL: multinomial,
          Scheme.RESIDUAL: residual, Scheme.RESIDUAL_DETERMINISTIC: residual_deterministic}


def get(name):
    """The scheme function by name or :class:`Scheme`."""
    return _FUNCS[Scheme.parse(name)]


def resample(name: str, weights, rng: np.random.Generator) -> np.ndarray:
    """Ancestor indices from scheme ``name``."""
    return get(name)(weights, rng)


def effective_sample_size(weights) -> float:
    """N_eff = 1 / sum w_i^2 for normalised weights ([MultiPDF] eq. 8; [Thesis] eq. 2.14)."""
    w = np.asarray(weights, dtype=np.float64)
    total = np.cumsum(w)[-1]
    wn = w / total
    return float(1.0 / np.cumsum(wn * wn)[-1])


# --------------------------------------------------------------------------- regularized
def unit_ball_volume(n_x: int) -> float:
    """c_nx, volume of the unit hypersphere in R^n_x."""
    return math.pi ** (n_x / 2) / math.gamma(n_x / 2 + 1)


def h_opt(n_particles: int, n_x: int) -> float:
    """Optimal Epanechnikov bandwidth h_opt = A N^(-1/(n_x+4)) ([Thesis] eq. 2.17),
    A = [8 c_nx^-1 (n_x + 4) (2 sqrt(pi))^n_x]^(1/(n_x+4))."""
    a = (8.0 / unit_ball_volume(n_x) * (n_x + 4) * (2.0 * math.sqrt(math.pi)) ** n_x) ** (1.0 / (n_x + 4))
    return a * n_particles ** (-1.0 / (n_x + 4))


def epanechnikov(rng: np.random.Generator, n: int, n_x: int) -> np.ndarray:
    """n draws from the n_x-dimensional Epanechnikov kernel (density ~ 1 - ||e||^2 on the unit ball).

    Draw order: a direction from n x n_x standard normals, then the squared radius
    r^2 ~ Beta(n_x / 2, 2) from n beta draws.
    """
    z = rng.standard_normal((n, n_x))
    norm = np.sqrt(np.sum(z * z, axis=1))
    r = np.sqrt(rng.beta(n_x / 2.0, 2.0, n))
    return z * (r / norm)[:, None]


def regularized(particles, weights, rng: np.random.Generator, scheme: str = "systematic",
                bandwidth: float | None = None) -> np.ndarray:
    """Regularized resampling ([Thesis] Alg. 4): resample, then jitter with the Epanechnikov kernel.

    x_i* = x_{a_i} + h_opt D eps_i, with D D^T the weighted empirical covariance and
    eps_i ~ Epanechnikov. Draw order: the scheme's draws, then :func:`epanechnikov`'s.
    Returns the new (N, n_x) particles.
    """
    x, w, d, h = regularization_setup(particles, weights, bandwidth)
    idx = get(scheme)(w, rng)
    eps = epanechnikov(rng, x.shape[0], x.shape[1])
    return x[idx] + h * eps @ d.T


def regularization_setup(particles, weights, bandwidth=None):
    """(x, w, D, h) for regularized resampling: particles as (N, n_x) float64, the weights,
    a factor D with D D^T = weighted empirical covariance, and the bandwidth (default h_opt)."""
    x = np.ascontiguousarray(particles, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    n, n_x = x.shape
    w = np.asarray(weights, dtype=np.float64)
    wn = w / np.cumsum(w)[-1]
    mean = wn @ x
    cov = ((x - mean) * wn[:, None]).T @ (x - mean)
    ev, v = np.linalg.eigh(0.5 * (cov + cov.T))
    d = np.ascontiguousarray(v * np.sqrt(np.clip(ev, 0.0, None)))
    h = h_opt(n, n_x) if bandwidth is None else float(bandwidth)
    return x, w, d, h
