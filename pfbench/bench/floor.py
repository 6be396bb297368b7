"""The irreducible-work floor of a particle-filter step, and where its nanoseconds go.

A bootstrap step cannot do less than draw one standard normal per particle (the transition noise)
and evaluate one exponential per particle (the likelihood weight, [Embedded] Alg. 1 steps 2-3):
:func:`floor_ns` times exactly that, as a numba loop and as vectorised NumPy, so a filter's
ns per particle-step reads as a multiple of what the machine needs at the least.

:func:`breakdown_ns` splits the numba floor into its parts, timed separately in the same run:

* ``normal``: the standard-normal draws alone (numba's ``Generator.standard_normal``, a ziggurat
  on PCG64 as in NumPy), summed so the draws cannot be optimised away;
* ``normal_engine``: the same draws (the same numbers) from the engine's inlined PCG64 + ziggurat
  (:func:`pfbench.backends.pcg64.fill_normals`), as the kernels draw them;
* ``exp``: ``exp(-z^2/2)`` over a fixed array alone (the math library's exp, in a reduction);
* ``exp_engine``: the same exponentials with the engine's own branch-free exp
  (:func:`pfbench.backends.fastexp.exp_scalar`) in a loop of its own, as the kernels run it
  (vectorised);
* ``memory_pass``: one read and one write of a float64 particle array of N_p elements
  (``x = 0.5 x + 1``), the cost of touching the particles once more -- in cache for small N_p,
  memory bandwidth for large N_p.

:func:`floor_ns` with ``backend="numba"`` is the floor with the library primitives (numba's
ziggurat normal and the math library's scalar exp), as the engine's targets are stated;
``backend="engine"`` is the same work with the engine's own primitives (inlined normals and the
vectorised exp), the floor the engine could reach with them.

All results are ns per particle-step, medians of ``repeats`` timings, compilation excluded.
"""
from __future__ import annotations

import statistics
import time

import numpy as np

from ..backends.cache import njit
from ..backends.fastexp import exp_scalar
from ..backends.interrupts import held
from ..backends.pcg64 import fill_normals


@njit(nogil=True)
def _floor(rng, n, m):
    acc = 0.0
    for _ in range(m):
        z = rng.standard_normal(n)
        for i in range(n):
            acc += np.exp(-0.5 * z[i] * z[i])
    return acc


@njit(nogil=True, error_model="numpy")
def _floor_engine(rng, n, m, e):
    acc = 0.0
    z = np.empty(n)
    for _ in range(m):
        fill_normals(rng, z)
        for i in range(n):
            e[i] = exp_scalar(-0.5 * z[i] * z[i])
        for i in range(n):
            acc += e[i]
    return acc


@njit(nogil=True, error_model="numpy")
def _exps_engine(z, m, e):
    acc = 0.0
    for _ in range(m):
        for i in range(z.size):
            e[i] = exp_scalar(-0.5 * z[i] * z[i])
        for i in range(z.size):
            acc += e[i]
    return acc


@njit(nogil=True)
def _normals(rng, n, m):
    acc = 0.0
    for _ in range(m):
        z = rng.standard_normal(n)
        for i in range(n):
            acc += z[i]
    return acc


@njit(nogil=True)
def _normals_engine(rng, n, m):
    acc = 0.0
    z = np.empty(n)
    for _ in range(m):
        fill_normals(rng, z)
        for i in range(n):
            acc += z[i]
    return acc


@njit(nogil=True)
def _exps(z, m):
    acc = 0.0
    for _ in range(m):
        for i in range(z.size):
            acc += np.exp(-0.5 * z[i] * z[i])
    return acc


@njit(nogil=True)
def _memory_pass(x, m):
    for _ in range(m):
        for i in range(x.size):
            x[i] = 0.5 * x[i] + 1.0
    return x[0]


def _median_ns(run, n: int, m: int, repeats: int) -> float:
    """Median ns per particle-step of ``repeats`` calls of ``run``, each with the interrupts held
    back (:func:`pfbench.backends.interrupts.held`: ``run`` may hand numba a generator)."""
    times = []
    for _ in range(max(int(repeats), 1)):
        with held():
            t0 = time.perf_counter()
            run()
            times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e9 / (n * m)


def floor_ns(n: int, m: int, repeats: int, backend: str) -> float:
    """ns per particle-step of one normal draw + one exp (the irreducible work of a PF step)."""
    rng = np.random.default_rng(0)
    if backend == "numba":
        with held():
            _floor(rng, 8, 2)  # compile
        return _median_ns(lambda: _floor(rng, n, m), n, m, repeats)
    if backend == "engine":
        e = np.empty(n)
        with held():
            _floor_engine(rng, 8, 2, e)  # compile
        return _median_ns(lambda: _floor_engine(rng, n, m, e), n, m, repeats)

    def run():
        acc = 0.0
        for _ in range(m):
            z = rng.standard_normal(n)
            acc += np.exp(-0.5 * z * z).sum()
        return acc

    return _median_ns(run, n, m, repeats)


def breakdown_ns(n: int, m: int, repeats: int) -> dict:
    """The numba floor's parts (ns per particle-step): ``normal``, ``normal_engine``, ``exp``,
    ``exp_engine``, ``memory_pass``."""
    rng = np.random.default_rng(0)
    z = np.random.default_rng(1).standard_normal(n)
    x = np.ones(n)
    e = np.empty(n)
    with held():  # compile
        _normals(rng, 8, 2), _normals_engine(rng, 8, 2), _exps(z[:8], 2), _exps_engine(z[:8], 2, e)
        _memory_pass(x[:8].copy(), 2)
    return {"normal": _median_ns(lambda: _normals(rng, n, m), n, m, repeats),
            "normal_engine": _median_ns(lambda: _normals_engine(rng, n, m), n, m, repeats),
            "exp": _median_ns(lambda: _exps(z, m), n, m, repeats),
            "exp_engine": _median_ns(lambda: _exps_engine(z, m, e), n, m, repeats),
            "memory_pass": _median_ns(lambda: _memory_pass(x, m), n, m, repeats)}
