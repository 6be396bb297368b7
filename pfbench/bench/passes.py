"""Where the nanoseconds of a particle-filter step go: each part of the numba particle kernel timed
on its own, on Ob1 ([Embedded] eq. 6) with the weights of a real run.

Parts (ns per particle-step, single thread, median of repeats), in the kernel's order
(:mod:`pfbench.backends.numba_particle`):

* ``normals``: the transition noise, drawn tile by tile as the kernel draws it;
* ``model``: the model's vectorised transition + log-likelihood on the same tiles;
* ``transition_c`` / ``transition_f``: the model's transition alone on (tile, 1) arrays typed
  row-major ('C', as the tiles are stored) and typed column-major ('F', as the kernel hands them
  to a model with one state and one noise component). numba lowers an array expression over a C
  array as nested loops with the trailing axis (length 1) innermost, and LLVM vectorises inner
  loops only, so on C tiles the transition's division runs one particle at a time;
* ``pass_a``: the whole fused pass A (draw + propagate + log-likelihood + log-weight + max);
* ``exp``: one ``exp`` per particle alone (the kernel's vectorised exp, in its own loop);
* ``pass_b``: the whole fused pass B (exp + running sum + moments + sum of squared weights);
* ``resample``: systematic resampling + gather into the second buffer, on the cdf of the run's
  own weights at every step (Ob1's weights are very uneven, which is what makes a merge slow);
* ``filter``: the whole filter, for comparison (the parts sum to about this).

The harnesses compile with plain ``numba.njit`` (not cached): a few seconds per process.
"""
from __future__ import annotations

import statistics
import time

import numba.extending
import numpy as np


@numba.extending.register_jitable
def _as_is(a):
    return a


def _harnesses(mod):
    pass_a, pass_b, merge = mod._pass_a, mod._pass_b, mod._merge_gather
    transition, log_likelihood = mod._transition, mod._log_likelihood
    tile = mod._TILE
    draw = mod._normals
    tiles = mod._column_major if mod._F_TILES else _as_is

    @numba.njit
    def normals(rng, n, m):
        like = np.empty((1, 1))
        acc = 0.0
        for _ in range(m):
            for s in range(0, n, tile):
                acc += draw(rng, min(s + tile, n) - s, 1, like)[0, 0]
        return acc

    @numba.njit
    def model(p, y, x, noise, m):
        acc = 0.0
        n = x.shape[0]
        for t in range(m):
            for s in range(0, n, tile):
                e = min(s + tile, n)
                xn = transition(tiles(x[s:e]), y[t], t, tiles(noise[s:e]), p)  # as the kernel does
                acc += log_likelihood(y[t], xn, y[t], t, p)[0]
        return acc

    def transition_on(layout):
        @numba.njit
        def run(p, x, noise, m):
            acc = 0.0
            n = x.shape[0]
            for t in range(m):
                for s in range(0, n, tile):
                    e = min(s + tile, n)
                    acc += transition(layout(x[s:e]), x[s], t, layout(noise[s:e]), p)[0, 0]
            return acc
        return run

    transition_c, transition_f = transition_on(_as_is), transition_on(mod._column_major)

    @numba.njit
    def whole_a(p, rng, y, x, m, la, lam):
        n = x.shape[0]
        lw = np.full(n, -np.log(n))
        acc = 0.0
        for t in range(m):
            acc += pass_a(p, rng, y[t], y[t], t, x, 0, n, 1, lw, True, -np.log(n), False, lam, False, lam, la)
        return acc

    exp = mod._exp

    @numba.njit(error_model="numpy")
    def exps(a, m):
        e = np.empty(a.shape[0])
        acc = 0.0
        for _ in range(m):
            for i in range(a.shape[0]):  # as pass B runs it: a vectorised loop of its own
                e[i] = exp(a[i])
            acc += e[0]
        return acc

    @numba.njit
    def whole_b(la, x, m):
        n = x.shape[0]
        wu, cdf = np.empty(n), np.empty(n)
        bsum, bs2, bsx, bsxx = np.empty(1), np.empty(1), np.empty((1, 1)), np.empty((1, 1))
        for _ in range(m):
            pass_b(la, 0.0, wu, cdf, x, 0, n, True, 0, bsum, bs2, bsx, bsxx)
        return bsum[0]

    @numba.njit
    def resample(cdfs, x, rng):
        n = x.shape[0]
        dst, lam = np.empty_like(x), np.empty(n)
        ub, anc, pos, kk = np.empty(1), np.empty(n, np.int64), np.empty(n), np.empty(n, np.int64)
        for t in range(cdfs.shape[0]):
            merge(cdfs[t], n, rng.random(), ub, False, 0, n, x, dst, lam, lam, False, anc, pos, kk)
        return dst[0, 0]

    return normals, model, transition_c, transition_f, whole_a, exps, whole_b, resample


def _median_ns(fn, args, n: int, m: int, repeats: int) -> float:
    fn(*args)  # compile
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(*args)
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e9 / (n * m)


def passes_ns(n: int = 1000, m: int = 1000, repeats: int = 5) -> dict:
    """ns per particle-step of each part of the Ob1 bootstrap step (see the module docstring)."""
    from .. import models
    from ..backends import numba_backend
    from ..filters import run_filter

    model = models.get("ob1")
    traj = model.simulate(m, seed=1)
    p = model.params()
    mod = numba_backend.kernel_module(model, "particle", "systematic")
    normals, model_fn, transition_c, transition_f, whole_a, exps, whole_b, resample = _harnesses(mod)
    run = run_filter(model, traj.y, None, method="bootstrap", n_particles=n, seed=0, n_threads=1,
                     store_particles=True)
    weights = run.extras["weights"][0]
    cdfs = np.cumsum(weights, axis=1)
    x = np.ascontiguousarray(run.extras["particles"][0, m // 2])
    la = np.log(np.maximum(weights[m // 2], 1e-300)) - np.log(weights[m // 2].max())
    rng = np.random.default_rng(0)
    noise = rng.standard_normal((n, 1))
    out = {"steps": m, "particles": n,
           "normals": _median_ns(normals, (rng, n, m), n, m, repeats),
           "model": _median_ns(model_fn, (p, traj.y, x, noise, m), n, m, repeats),
           "transition_c": _median_ns(transition_c, (p, x, noise, m), n, m, repeats),
           "transition_f": _median_ns(transition_f, (p, x, noise, m), n, m, repeats),
           "pass_a": _median_ns(whole_a, (p, rng, traj.y, x.copy(), m, np.empty(n), np.zeros(n)), n, m, repeats),
           "exp": _median_ns(exps, (la, m), n, m, repeats),
           "pass_b": _median_ns(whole_b, (la, x, m), n, m, repeats),
           "resample": _median_ns(resample, (cdfs, x, rng), n, m, repeats)}
    times = [run_filter(model, traj.y, None, method="bootstrap", n_particles=n, seed=s, n_threads=1).elapsed_s
             for s in range(repeats)]
    out["filter"] = statistics.median(times) * 1e9 / (n * m)
    out["rest"] = out["filter"] - out["pass_a"] - out["pass_b"] - out["resample"]
    return out


def passes_text(d: dict) -> str:
    return (f"kernel parts (numba 1 thread, M={d['steps']}, N_p={d['particles']}; ns per particle-step, each "
            f"timed alone): pass A {d['pass_a']:.1f} (normal draws {d['normals']:.1f} + model transition and "
            f"likelihood {d['model']:.1f} + the rest), pass B {d['pass_b']:.1f} (exp alone {d['exp']:.1f}), "
            f"resampling + gather {d['resample']:.1f}; whole filter {d['filter']:.1f} (unaccounted "
            f"{d['rest']:.1f}); the model's transition alone on (tile, 1) arrays: {d['transition_c']:.1f} "
            f"typed row-major, {d['transition_f']:.1f} typed column-major as the kernel passes them (numba "
            f"vectorises no array expression over a trailing axis of length 1)")
