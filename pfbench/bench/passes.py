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
* ``convert``: pass A's tile traffic around the model: the states handed to the model (float32
  particles: converted to float64 into a buffer; float64: a view) and the new states stored
  (float32: rounded, and the rounded values kept in float64 for the likelihood);
* ``filter``: the whole filter, for comparison (the parts sum to about this).

With ``dtype="float32"`` every part runs as the float32 kernel runs it (float32 draws and particle
buffers, the model in float64 on converted tiles), so the two dtypes' parts side by side say where
float32 gains and where it pays (:func:`dtype_text`).

The harnesses compile with plain ``numba.njit`` (not cached): a few seconds per process.
"""
from __future__ import annotations

import functools
import statistics
import time

import numba.extending
import numpy as np

from ..backends.fastexp import exp_scalar
from ..backends.interrupts import held
from ..backends.particle_work import B_SUM, F_WEIGHTS, Settings, Step, Work, work_arrays
from ..methods import Method
from ..resampling import Scheme
from .timing import filter_ns, interleaved, paired_ratio


@numba.extending.register_jitable
def _as_is(a):
    return a


@functools.lru_cache(maxsize=None)
def _harnesses(mod):
    """The timing harnesses around kernel module ``mod``'s parts (one set per module, so every
    configuration and dtype of a process reuses their compilations)."""
    pass_a, pass_b, merge = mod._pass_a, mod._pass_b, mod._merge_gather
    transition, log_likelihood = mod._transition, mod._log_likelihood
    tile = mod._TILE
    draw = mod._normals
    tiles = mod._column_major if mod._F_TILES else _as_is
    tile64, store, tile_buffer = mod._tile64, mod._store, mod._tile_buffer

    @numba.njit
    def normals(rng, n, m, like):
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
    def convert(xs, m):
        acc = 0.0
        n = xs.shape[0]
        bin_, bout = tile_buffer(xs, n), tile_buffer(xs, n)
        for _ in range(m):
            for s in range(0, n, tile):
                e = min(s + tile, n)
                a = tile64(xs, s, e, bin_)  # as pass A does (storing back the values it read)
                c = store(xs[s:e], a, bout)
                acc += c[0, 0]
        return acc

    @numba.njit
    def whole_a(p, rng, y, work, settings, m):
        acc = 0.0
        for t in range(m):
            acc += pass_a(p, rng, y, y, work, settings, Step(t, 0, 0, False, False, 0.0, 0.0))
        return acc

    exp = exp_scalar  # pass B's exponential

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
    def whole_b(work, m):
        for _ in range(m):  # in place: the weights are in (0, 1], so with max 1 the next call's stay there
            pass_b(work, Step(0, 0, 0, False, False, 1.0, 0.0))
        return work.bwork[B_SUM, 0]

    @numba.njit
    def resample(cdfs, work, settings, rng):
        for t in range(cdfs.shape[0]):  # cdfs[t, 1]: the cdf of step t (rows 0 and 2: the merge's)
            merge(Work(work.xs, work.lw, cdfs[t], work.iwork, work.bwork, work.bmom, work.gstate, work.bounds),
                  settings, Step(t, 0, 0, False, False, 0.0, rng.random()))
        return work.xs[1, 0, 0, 0]

    return normals, model, transition_c, transition_f, convert, whole_a, exps, whole_b, resample


def _timer(fn, args, n: int, m: int):
    """A callable timing one run of ``fn(*args)`` in ns per particle-step (``fn`` compiled first);
    the interrupts are held back during each call (:func:`pfbench.backends.interrupts.held`: the
    arguments may include a generator)."""
    def once():
        with held():
            t0 = time.perf_counter()
            fn(*args)
            return (time.perf_counter() - t0) * 1e9 / (n * m)
    once()  # compile
    return once


def _part_timers(n: int, m: int, dtype: str) -> tuple[dict, str]:
    """(part name -> timer of one run, the particle dtype the filter stored) for the Ob1 bootstrap
    step with ``dtype`` particles: the parts run on that filter's own particles and weights."""
    from .. import models
    from ..backends.kernels import build
    from ..filters import run_filter

    model = models.get("ob1")
    traj = model.simulate(m, seed=1)
    p = model.params()
    mod = build("particle", model, "systematic")
    normals, model_fn, transition_c, transition_f, convert, whole_a, exps, whole_b, resample = _harnesses(mod)
    run = run_filter(model, traj.y, None, method="bootstrap", n_particles=n, seed=0, n_threads=1,
                     store_particles=True, dtype=dtype)
    weights = run.extras["weights"][0]
    cdfs = np.cumsum(weights, axis=1)
    x = np.ascontiguousarray(run.extras["particles"][0, m // 2])  # in the dtype the filter stored
    x64 = x.astype(np.float64)  # what the model sees
    la = np.log(np.maximum(weights[m // 2], 1e-300)) - np.log(weights[m // 2].max())
    rng = np.random.default_rng(0)

    def work(la_row=None):
        """The kernel's work arrays for one filter of the stored particles (flat weights)."""
        w = work_arrays(x[None], 1, np.array([0, n]), int(Method.BOOTSTRAP))
        w.xs[0, 0] = x
        w.gstate[:, 0] = (0, 1)
        if la_row is not None:
            w.fwork[F_WEIGHTS] = la_row
        return w

    settings = Settings(1, int(Method.BOOTSTRAP), int(Scheme.SYSTEMATIC), 0.0, False, 0, 0, 0)
    cdfs3 = np.zeros((m, 3, n))
    cdfs3[:, 1] = cdfs
    noise64 = rng.standard_normal((n, 1), dtype=x.dtype).astype(np.float64)  # as the model gets it
    return {"normals": _timer(normals, (rng, n, m, x[:1]), n, m),
            "model": _timer(model_fn, (p, traj.y, x64, noise64, m), n, m),
            "transition_c": _timer(transition_c, (p, x64, noise64, m), n, m),
            "transition_f": _timer(transition_f, (p, x64, noise64, m), n, m),
            "convert": _timer(convert, (x.copy(), m), n, m),
            "pass_a": _timer(whole_a, (p, rng, traj.y, work(), settings, m), n, m),
            "exp": _timer(exps, (la, m), n, m),
            "pass_b": _timer(whole_b, (work(la), m), n, m),  # in place
            "resample": _timer(resample, (cdfs3, work(), settings, rng), n, m),
            "filter": lambda: filter_ns(model, traj, n, "numba", dtype, 1, n_threads=1)}, str(x.dtype)


def _parts(timings: dict, n: int, m: int, dtype: str) -> dict:
    """Medians of the per-round timings; ``dtype``: the particle dtype the parts ran on (as the filter
    stored it, not as asked: a harness that ran another dtype says so)."""
    out = {"steps": m, "particles": n, "dtype": dtype, **{k: statistics.median(v) for k, v in timings.items()}}
    out["rest"] = out["filter"] - out["pass_a"] - out["pass_b"] - out["resample"]
    return out


def passes_ns(n: int = 1000, m: int = 1000, repeats: int = 5, dtype: str = "float64") -> dict:
    """ns per particle-step of each part of the Ob1 bootstrap step with ``dtype`` particles (see
    the module docstring): medians of ``repeats`` rounds, each timing every part once."""
    timers, stored = _part_timers(n, m, dtype)
    return _parts(interleaved(timers, repeats), n, m, stored)


def dtype_parts(n: int, m: int, repeats: int = 5) -> dict:
    """The parts in float64 and in float32, timed in the same interleaved rounds (every part of both
    dtypes once per round), and each part's float32 speed-up as the median of its per-round
    float64 / float32 ratios (a change of the machine's speed between rounds cancels)."""
    made = {dt: _part_timers(n, m, dt) for dt in ("float64", "float32")}
    timers = {(dt, k): f for dt, (parts, _) in made.items() for k, f in parts.items()}
    rounds = interleaved(timers, repeats)
    by_dtype = {dt: {k: v for (d, k), v in rounds.items() if d == dt} for dt in made}
    out = {dt: _parts(by_dtype[dt], n, m, made[dt][1]) for dt in made}
    out["speedup"] = {k: paired_ratio(rounds[("float64", k)], rounds[("float32", k)]) for k in by_dtype["float64"]}
    out["rounds"] = by_dtype
    return out


def passes_text(d: dict) -> str:
    return (f"kernel parts (numba 1 thread, M={d['steps']}, N_p={d['particles']}; ns per particle-step, each "
            f"timed alone): pass A {d['pass_a']:.1f} (normal draws {d['normals']:.1f} + model transition and "
            f"likelihood {d['model']:.1f} + the rest), pass B {d['pass_b']:.1f} (exp alone {d['exp']:.1f}), "
            f"resampling + gather {d['resample']:.1f}; whole filter {d['filter']:.1f} (unaccounted "
            f"{d['rest']:.1f}); the model's transition alone on (tile, 1) arrays: {d['transition_c']:.1f} "
            f"typed row-major, {d['transition_f']:.1f} typed column-major as the kernel passes them (numba "
            f"vectorises no array expression over a trailing axis of length 1)")


#: the parts :func:`dtype_text` compares, with their printed names
_COMPARED = (("normals", "normal draws"), ("convert", "tile in/out (float32: conversions)"), ("model", "model"),
             ("pass_a", "pass A"), ("pass_b", "pass B"), ("resample", "resampling + gather"),
             ("filter", "whole filter"))


def dtype_text(parts: dict) -> str:
    """The float32 and float64 kernel parts side by side (``parts``: :func:`dtype_parts`), with the
    float32 speed-up of each (paired per round): where float32 gains and where it pays."""
    a, b, r = parts["float64"], parts["float32"], parts["speedup"]
    cells = ", ".join(f"{name} {a[k]:.1f} vs {b[k]:.1f} ({r[k]:.2f}x)" for k, name in _COMPARED)
    return (f"float32 vs float64 kernel parts (numba 1 thread, M={a['steps']}, N_p={a['particles']}; median ns "
            f"per particle-step float64 vs float32, float32 speed-up paired per round): {cells}. "
            "The models compute in float64 "
            "(Python float literals and float64 parameters): float32 changes the storage, the draws and the "
            "tile conversions, not the arithmetic")
