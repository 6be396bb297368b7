"""The numba backend's host side: :func:`run_group` (particle), :func:`run_mpf` and :func:`run_guided`
build their family's kernel (:func:`pfbench.backends.kernels.build`), allocate its argument groups and
call its driver with the entry addresses of what it calls by address (:func:`native_addresses`).
"""
from __future__ import annotations

import threading
import warnings

import numba
import numpy as np
from numba.core.errors import NumbaPendingDeprecationWarning

from ..errors import InputError
from ..methods import Estimate
from ..models.contract import compiled_model_code
from ..procs import free_cores
from ..resampling import MERGED
from . import compile_helper, mpf_work, native_call, pcg64
from .interrupts import held
from .kernels import build, column_major_tiles
from .numpy_backend import BLOCK, block_bounds, draw_initial
from .particle_work import Settings, Step, outputs, pass_types, work_arrays

_LOCK = threading.RLock()
_WARM: set = set()
#: numba's ``workqueue`` threading layer aborts when two Python threads launch parallel regions at
#: once: every ``run_group_parallel`` call holds this lock
_PARALLEL_LOCK = threading.Lock()


def warm_up(model, p, y, u, dtype, scheme=0, parallel: bool = False) -> None:
    """Compile (or load) the particle kernel for these argument types outside any timed region:
    one call on one step with a throwaway generator (``parallel``: two blocks on two threads)."""
    key = (type(model), column_major_tiles(model), np.dtype(dtype).str, int(scheme),
           tuple(type(v).__name__ for v in p), parallel)
    if key in _WARM:
        return
    rng = np.random.default_rng(0)
    run_group(model, p, rng, y[:1], u[:1], outputs(1, 1, 1 + parallel, model.n_x, dtype), 0, int(scheme), 1.0,
              brngs=[rng, np.random.default_rng(1)] if parallel else None, n_threads=1 + parallel,
              block=1 if parallel else None)
    _WARM.add(key)


def run_group(model, p, rng, y, u, out, method, scheme, ess_threshold, *, brngs=None,
              n_threads: int | None = 1, block: int | None = None, estimate: str = "pre") -> None:
    """Numba twin of :func:`pfbench.backends.numpy_backend.run_group` (releases the GIL); ``block``: the
    largest stream block. Above one block and with ``n_threads`` != 1 (None: all) the block loops run on
    numba threads, with results independent of the thread count."""
    y, u = np.ascontiguousarray(y), np.ascontiguousarray(u)  # C arrays, as pass A's types say
    x = out.x
    bounds = block_bounds(x.shape[1], int(block or BLOCK))
    brngs = [rng] if brngs is None else list(brngs)
    if len(brngs) != bounds.shape[0] - 1:
        raise ValueError(f"{len(brngs)} block streams for {x.shape[1]} particles in {bounds.shape[0] - 1} blocks")
    pcg64.check_generators([rng, *brngs])  # the kernel reads PCG64's state struct directly
    mod = build("particle", model, scheme)
    work = work_arrays(x, bounds.shape[0] - 1, bounds, int(method))
    # the NumPy backend's draw, into the kernel's first particle buffer
    draw_initial(model.kernel_functions()["initial"], p, rng, work.xs[0], brngs)
    settings = Settings(int(model.n_noise), int(method), int(scheme), float(ess_threshold),
                        Estimate.parse(estimate) == Estimate.POST, 0, 0, 0)
    parallel = len(brngs) > 1 and n_threads != 1
    if parallel:  # numba starts its threading layer on first use, in a compile too: one line if it cannot
        try:
            numba.get_num_threads()
        except ValueError as exc:
            raise InputError(f"numba's threads cannot start here ({' '.join(str(exc).split())}); unset "
                             "NUMBA_THREADING_LAYER for the default") from None
    driver = mod.run_group_parallel if parallel else mod.run_group
    with warnings.catch_warnings():  # the block generators travel as a (reflected) list
        warnings.simplefilter("ignore", NumbaPendingDeprecationWarning)
        args = (p, rng, brngs, y, u, out, work, settings)

        def find():
            step = Step()
            calls = [("_pass_a", pass_types(p, rng, y, u, work, settings, step), numba.types.float64),
                     ("_pass_b", pass_types(work, step), numba.types.none)]
            if mod._SCHEME == -1 or mod._SCHEME in MERGED:  # the merge branch (-1: any scheme)
                calls.append(("_merge_gather", pass_types(work, settings, step), numba.types.none))
            # a cold start: the driver and pass B here, pass A and the merge in the helper (balanced)
            found = native_addresses(model, "particle", mod, driver, args, calls, here=("_pass_b",),
                                     f_tiles=column_major_tiles(model))
            return found + [0] * (3 - len(found))  # an index scheme's kernel never calls the merge

        a, b, c = (int(v) for v in _call_addresses(driver, args, find))
        args = args[:-1] + (settings._replace(pass_a=a, pass_b=b, merge=c),)
        with held(), compiled_model_code(model):  # held: the generators' unboxing (interrupts.held)
            if not parallel:
                driver(*args)
                return
            k = min(int(n_threads or free_cores()), numba.config.NUMBA_NUM_THREADS)
            with _PARALLEL_LOCK:
                numba.set_num_threads(k)
                try:
                    driver(*args)
                except SystemError as exc:  # a parallel region's exception is its cause: raised as serially
                    c = exc.__cause__
                    raise c if isinstance(c, Exception) and not isinstance(c, SystemError) else exc from None


def native_addresses(model, family: str, mod, driver, args, calls, *, here=(), f_tiles: bool = False) -> list:
    """The native entry addresses of ``calls``, ``(name, argument types, return type)`` of scheme-free
    functions of the kernel module ``mod`` (:attr:`pfbench.backends.kernels.Family.shared`, the model's,
    step math), which ``driver`` (called with ``args``) calls by address; return type None: known once
    compiled (only later entries call it). On a cold cache a helper compiles those not in ``here``
    while this process compiles the driver and ``here`` (:mod:`pfbench.backends.compile_helper`)."""
    funcs = [(name, getattr(mod, name), argtypes, restype) for name, argtypes, restype in calls]
    away = [(name, f, a) for name, f, a, _ in funcs if name not in here]
    with _LOCK:  # threads of one process start one helper, not one each
        for _, func, argtypes, restype in funcs:
            if restype is not None:
                native_call.declare(func, argtypes, restype)
        if compile_helper.enabled() and any(compile_helper.cold(f, a) for _, f, a in away):
            sig = tuple(driver.typeof_pyval(a) for a in args)
            if compile_helper.cold(driver, sig):
                helper = compile_helper.start(type(model), family, f_tiles, [(name, a) for name, _, a in away])
                if helper is not None:
                    try:
                        driver.compile(sig)
                        for name, f, a, _ in funcs:
                            if name in here:
                                native_call.entry_address(f, a)
                        helper.wait()
                    finally:  # after Ctrl-C (delivered when the compile ends) or an error: not wanted
                        compile_helper.stop(helper)
        return [native_call.entry_address(f, a) for _, f, a, _ in funcs]


# --------------------------------------------------------------------------- the MPF family
def run_mpf(model, p, rng, xn, s, u, scheme, out) -> None:
    """The numba MPF recursion ([Schon2005] Alg. 1; :func:`pfbench.filters.marginalized.run_mpf`) from
    the prior draws ``xn`` of x^n (None: every state linear, one Kalman/EKF recursion); ``s``:
    :func:`pfbench.filters.marginalized.structure`; fills ``out``
    (:class:`pfbench.backends.mpf_work.Outputs`) in place."""
    u = np.ascontiguousarray(u)  # its rows are then the C arrays _run_calls types
    st = mpf_work.structure_group(s)
    work = mpf_work.work_arrays(xn, int(s["d_l"]), st.meas.yw.shape[1])
    if s["d_n"] == 0:
        mod = build("mpf", model, None)
        args = (p, u, st, out, work, np.zeros(len(mod.LINEAR_CALLS), np.int64))
        addresses = _call_addresses(mod.run_linear, args, lambda: native_addresses(
            model, "mpf", mod, mod.run_linear, args,
            [(name, *_step_calls(st, out, work)[name]) for name in mod.LINEAR_CALLS]))
        with compiled_model_code(model):
            mod.run_linear(*args[:-1], addresses)
        return
    mod = build("mpf", model, scheme)
    args = (p, rng, u, st, out, work, int(scheme), np.zeros(len(mod.RUN_CALLS), np.int64))

    def find():
        calls = {**_run_calls(p, rng, u, st, work), **_step_calls(st, out, work)}
        return native_addresses(model, "mpf", mod, mod.run, args, [(name, *calls[name]) for name in mod.RUN_CALLS],
                                here=_RUN_HERE)

    addresses = _call_addresses(mod.run, args, find)
    with held(), compiled_model_code(model):  # held: the generator's unboxing (interrupts.held)
        mod.run(*args[:-1], addresses)


#: (driver, its arguments' type fingerprints: numba's dispatcher key, far cheaper than ``numba.typeof``) ->
#: the int64 entry addresses of its calls by address, found once per process (compiled code keeps its address)
_CALL_ADDRESSES: dict = {}


def _call_addresses(driver, args, find) -> np.ndarray:
    """``find()`` (:func:`native_addresses`) for ``driver`` and ``args``, kept in :data:`_CALL_ADDRESSES`."""
    from numba._dispatcher import compute_fingerprint

    key = [driver]
    for a in args:
        try:
            key.append(compute_fingerprint(a))
        except NotImplementedError:  # no fingerprint (a generator): its numba type
            key.append(numba.typeof(a))
    key = tuple(key)
    addresses = _CALL_ADDRESSES.get(key)
    if addresses is None:
        addresses = _CALL_ADDRESSES.setdefault(key, np.array(find(), np.int64))
    return addresses


def _step_calls(st, out, work) -> dict:
    """Name -> (argument types, return type) of the step math both MPF drivers call by address
    (:mod:`pfbench.backends.numba_mpf_steps`), typed from the groups the host passes."""
    none, w = numba.types.none, work
    return {"_time_update": (pass_types(w.lin, w.cond, st.noise.Ql, w.APl, w.pred), none),
            "_kalman_update": (pass_types(w.obs, w.pred, st.meas, 0, w.upd, w.wts.ll, w.cond), none),
            "_mixture_moments": (pass_types(w.wts.wu, 0.0, w.mom, w.xs, w.cond, st.split, out.est[0], out.cov[0]),
                                 none)}


#: the :data:`~pfbench.backends.numba_mpf.RUN_CALLS` a cold start compiles here after the driver
#: while a helper compiles the rest: the split that balances two cores on Ob5
_RUN_HERE = ("_normals_into", "_sandwich", "_condition", "_time_update", "_weigh", "_moments", "_mixture_moments")


def _run_calls(p, rng, u, st, work) -> dict:
    """Name -> (argument types, return type) of the rest of :data:`pfbench.backends.numba_mpf.RUN_CALLS`:
    the model's ``cl_*`` functions (return type None: known once compiled), their wrappers, the x^n
    noise, steps 1-2, weights and moments, typed from the objects the driver passes."""
    t = numba.types
    none, ut, w = t.none, u[0], work
    return {"_cl_transition": (pass_types(w.xn, ut, 0, p), None),
            "_cl_observation": (pass_types(w.xs, w.pred.m, ut, 0, p), None),
            "_cl_constrain": (pass_types(w.xnew, p), None),
            "_transition_into": (pass_types(w.xn, ut, 0, p, w.tn, w.tl, 0), none),
            "_observation_into": (pass_types(w.xs, w.pred.m, ut, 0, p, w.obs, 0), none),
            "_constrain_into": (pass_types(w.xnew, p, w.xs, 0), none),
            "_normals_into": (pass_types(rng, w.fac.z), none),
            "_sandwich": (pass_types(w.tn.A, w.prior.P, st.noise.Qn, w.fac.APn, w.fac.N), none),
            "_condition": (pass_types(w.tn, w.tl, w.prior, w.fac, st.noise, w.xnew, w.cond, w.lin), none),
            "_weigh": (pass_types(w.wts.lw, w.wts.ll, w.wts.wu, w.wts.cdf), t.Tuple((t.float64, t.float64, t.boolean))),
            "_moments": (pass_types(w.xs, w.wts.wu, 0.0, w.mom.mean_n, w.mom.var_n), t.float64)}


# --------------------------------------------------------------------------- the guided family
def run_guided(model, kind, p, rng, y, u, particles, out, settings):
    """The numba guided filter (:func:`pfbench.filters.guided.run_guided`) from the initial ``particles``;
    ``kind``: ``proposal`` or ``optimal``; fills ``out`` in place (groups of :mod:`pfbench.backends.guided_work`;
    the addresses in ``settings`` are found here)."""
    y, u = np.ascontiguousarray(y), np.ascontiguousarray(u)  # the row types _model_calls gives
    mod = build("guided", model, settings.scheme)
    driver = getattr(mod, f"run_{kind}")
    args = (p, rng, y, u, particles, out, settings)
    propose, weight = _call_addresses(driver, args, lambda: native_addresses(
        model, "guided", mod, driver, args, _model_calls(kind, p, y, u, particles.x, settings.n_noise)))
    with held(), compiled_model_code(model):  # held: the generator's unboxing (interrupts.held)
        driver(*args[:-1], settings._replace(propose=int(propose), weight=int(weight)))


def _model_calls(kind, p, y, u, x, n_noise) -> list:
    """``(name, argument types, return type)`` of a guided run's two model calls by address: the
    proposal, then its weight (``kind`` "proposal") or the predictive likelihood ("optimal")."""
    none = numba.types.none
    noise, xn, ll = np.empty((1, n_noise)), np.empty_like(x), np.empty(1)
    calls = [("_propose_into", pass_types(x, y[0], u[0], 0, noise, p, xn), none)]
    if kind == "proposal":
        return calls + [("_weight_into", pass_types(xn, x, y[0], u[0], 0, p, ll), none)]
    return calls + [("_predictive_into", pass_types(y[0], x, u[0], 0, p, ll), none)]
