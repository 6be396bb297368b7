"""The numba backend: the particle family's run entry point and the calls by address that every
family's driver makes.

Kernels are built by :func:`pfbench.backends.kernels.build` (one module per model, scheme and tile
layout, from the family's template module); this module runs them: :func:`run_group` (the
particle kernel), :func:`run_mpf`/:func:`run_kalman` and :func:`run_guided`, and
:func:`native_addresses`, which compiles the functions a driver calls by address (on a cold cache
in a helper process, :mod:`pfbench.backends.compile_helper`) and returns their entry points.
"""
from __future__ import annotations

import threading

import numpy as np

from ..methods import Estimate
from ..procs import free_cores
from ..resampling import Scheme
from . import compile_helper, guided_work, mpf_work, native_call, pcg64
from .kernels import build, column_major_tiles
from .particle_work import Outputs, Settings, Step, pass_types, work_arrays

_LOCK = threading.RLock()


_WARM: set = set()
#: numba's default ``workqueue`` threading layer aborts when two Python threads launch parallel
#: regions at once: every ``run_group_parallel`` call holds this lock (tbb/omp would not need it)
_PARALLEL_LOCK = threading.Lock()


def warm_up(model, p, y, u, dtype, scheme=0, parallel: bool = False) -> None:
    """Compile (or load) the particle kernel for these argument types outside any timed region.

    numba compiles on the first call, so one call on a single step and particle with a
    throwaway generator; the caller's random streams are not touched. ``parallel`` warms the
    all-threads compilation instead of the serial one: a call compiles only the variant it runs.
    """
    key = (type(model), column_major_tiles(model), np.dtype(dtype).str, int(scheme),
           tuple(type(v).__name__ for v in p), parallel)
    if key in _WARM:
        return
    n_x = model.n_x
    for par in ((True,) if parallel else (False,)):
        x = np.empty((1, 2 if par else 1, n_x), dtype=dtype)
        G, n = 1, x.shape[1]
        rng = np.random.default_rng(0)
        run_group(model, p, rng, y[:1], u[:1], x, 0, int(scheme), 1.0, np.empty((G, 1, n_x)),
                  np.empty((G, 1, n_x)), np.empty((G, 1)), np.empty((G, 1)), np.zeros((G, 1), np.bool_),
                  np.zeros((G, 1), np.bool_), np.empty((G, 0, n, n_x), dtype), np.empty((G, 0, n)),
                  brngs=[rng, np.random.default_rng(1)] if par else None, n_threads=2 if par else 1,
                  block=1 if par else None)
    _WARM.add(key)


def run_group(model, p, rng, y, u, x, method, scheme, ess_threshold, est, var, ess, inc, resampled,
              degen, hist_x=None, hist_w=None, *, brngs=None, n_threads: int | None = 1,
              block: int | None = None, estimate: str = "pre") -> None:
    """Numba twin of :func:`pfbench.backends.numpy_backend.run_group` (releases the GIL).

    ``brngs``: the stream-block generators (:func:`pfbench.backends.numpy_backend.block_streams`;
    None: ``[rng]``, one block); ``block``: the largest stream block (default
    :data:`pfbench.backends.numpy_backend.BLOCK`; the layout is
    :func:`~pfbench.backends.numpy_backend.block_bounds`). With more than one block and
    ``n_threads`` != 1 the block loops run on ``n_threads`` numba threads (None: all); results do
    not depend on the thread count. ``estimate``: ``pre`` or ``post`` (the kernel's ``post`` flag).
    """
    import warnings

    from numba.core.errors import NumbaPendingDeprecationWarning

    from .numpy_backend import BLOCK, block_bounds, draw_initial

    y, u = np.ascontiguousarray(y), np.ascontiguousarray(u)  # C arrays, as pass A's types say
    bounds = block_bounds(x.shape[1], int(block or BLOCK))
    if hist_x is None:
        G, n, n_x = x.shape
        hist_x, hist_w = np.empty((G, 0, n, n_x), x.dtype), np.empty((G, 0, n))
    brngs = [rng] if brngs is None else list(brngs)
    if len(brngs) != bounds.shape[0] - 1:
        raise ValueError(f"{len(brngs)} block streams for {x.shape[1]} particles in {bounds.shape[0] - 1} blocks")
    pcg64.check_generators([rng, *brngs])  # the kernel reads PCG64's state struct directly
    mod = build("particle", model, scheme)
    work = work_arrays(x, bounds.shape[0] - 1, bounds, int(method))
    # in NumPy, as the NumPy backend, straight into the kernel's first particle buffer (block by
    # block on the run's threads above one block: the draw and its first touch of the buffer)
    draw_initial(model.kernel_functions()["initial"], p, rng, work.xs[0], brngs, n_threads)
    out = Outputs(x, est, var, ess, inc, resampled, degen, hist_x, hist_w)
    settings = Settings(int(model.n_noise), int(method), int(scheme), float(ess_threshold),
                        Estimate.parse(estimate) == Estimate.POST, 0, 0, 0)
    parallel = len(brngs) > 1 and n_threads != 1
    driver = mod.run_group_parallel if parallel else mod.run_group
    with warnings.catch_warnings():  # the block generators travel as a (reflected) list
        warnings.simplefilter("ignore", NumbaPendingDeprecationWarning)
        import numba

        key = (driver, numba.typeof(p), numba.typeof(work), y.dtype, u.dtype)
        addresses = _PASS_ADDRESSES.get(key)
        if addresses is None:
            step = Step()
            calls = [("_pass_a", pass_types(p, rng, y, u, work, settings, step), numba.types.float64),
                     ("_pass_b", pass_types(work, step), numba.types.none)]
            if mod._SCHEME in (-1, Scheme.SYSTEMATIC, Scheme.STRATIFIED):  # the merge branch (-1: any)
                calls.append(("_merge_gather", pass_types(work, settings, step), numba.types.none))
            addresses = native_addresses(model, "particle", mod, driver, (p, rng, brngs, y, u, out, work, settings),
                                         calls, here=("_pass_b", "_merge_gather"), f_tiles=column_major_tiles(model))
            addresses = _PASS_ADDRESSES.setdefault(key, addresses + [0] * (3 - len(addresses)))
        # an index scheme's kernel never calls the merge: its address is 0
        args = (p, rng, brngs, y, u, out, work, settings._replace(pass_a=addresses[0], pass_b=addresses[1],
                                                                   merge=addresses[2]))
        if parallel:
            k = min(int(n_threads or free_cores()), numba.config.NUMBA_NUM_THREADS)
            with _PARALLEL_LOCK:
                numba.set_num_threads(k)
                try:
                    driver(*args)
                except SystemError as exc:
                    raise _raised_in_parallel(exc) from None
        else:
            driver(*args)


#: (driver, parameter type, particle, y and u dtypes) -> the addresses of passes A, B and C for
#: that driver: found once per process (:func:`native_addresses` types every pass's arguments and
#: looks its entry point up; measured, Ob1, N_p = 1000: a run's time beyond its steps 0.35 ms when
#: done on every run, 0.19 ms with this table, 0.8 ns per particle-step less at M = 200); compiled
#: code stays at its address for the life of the process
_PASS_ADDRESSES: dict = {}


def native_addresses(model, family: str, mod, driver, args, calls, *, here=(), f_tiles: bool = False) -> list:
    """The native entry addresses of the functions ``driver`` calls by address
    (:mod:`pfbench.backends.native_call`), in the order of ``calls``: ``(name, argument types, return
    type)`` of functions of the kernel module ``mod`` that do not depend on the scheme: the ones that
    inline or call the model (:data:`SCHEME_FREE`, the model's own functions), or model-free ones
    it imports (step math). A return type of None means "known once compiled": such a function is
    only called by functions listed after it, which are compiled after it. When the driver (called
    with ``args``, the addresses' places holding ints) and any of the functions not named in
    ``here`` are cold, a helper process compiles those functions while this one compiles the driver
    and then the ones in ``here`` (:mod:`pfbench.backends.compile_helper`)."""
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
                    except BaseException:  # Ctrl-C (delivered when the compile ends) or an error
                        helper.kill()
                        raise
                    helper.finish()
        return [native_call.entry_address(f, a) for _, f, a, _ in funcs]


def _raised_in_parallel(exc: SystemError) -> BaseException:
    """The exception compiled code raised inside a parallel region (the model's own ``raise``,
    e.g. an :class:`~pfbench.errors.UnsupportedError`): numba's parallel kernel returns with it
    set, which Python reports as a SystemError caused by it. The serial kernel raises it as it
    is, so the all-threads one does too; a SystemError without such a cause stays one."""
    cause = exc.__cause__
    return cause if isinstance(cause, Exception) and not isinstance(cause, SystemError) else exc


# --------------------------------------------------------------------------- the MPF family
def run_mpf(model, p, rng, xn, s, u, scheme, est, cov, ess, inc, degen) -> None:
    """The numba MPF recursion ([Schon2005] Alg. 1; :func:`pfbench.filters.marginalized.run_mpf`)
    from the prior draws ``xn`` of x^n (None when every state is linear: then one Kalman/EKF
    recursion, no random numbers and no scheme); ``s``: the model's structure
    (:func:`pfbench.filters.marginalized.structure`); fills the outputs in place."""
    u = np.ascontiguousarray(u)  # its rows are then the C arrays _run_calls types
    st = mpf_work.structure_group(s)
    out = mpf_work.Outputs(est, cov, ess, inc, degen)
    work = mpf_work.work_arrays(xn, int(s["d_l"]), st.meas.yw.shape[1])
    if s["d_n"] == 0:
        mod = build("mpf", model, None)
        args = (p, u, st, out, work, np.zeros(len(mod.LINEAR_CALLS), np.int64))
        addresses = _call_addresses(mod.run_linear, args, lambda: native_addresses(
            model, "mpf", mod, mod.run_linear, args,
            [(name, *_step_calls(st, out, work)[name]) for name in mod.LINEAR_CALLS]))
        mod.run_linear(*args[:-1], addresses)
        return
    mod = build("mpf", model, scheme)
    args = (p, rng, u, st, out, work, int(scheme), np.zeros(len(mod.RUN_CALLS), np.int64))

    def find():
        calls = {**_run_calls(p, rng, u, st, work), **_step_calls(st, out, work)}
        return native_addresses(model, "mpf", mod, mod.run, args, [(name, *calls[name]) for name in mod.RUN_CALLS],
                                here=_RUN_HERE)

    mod.run(*args[:-1], _call_addresses(mod.run, args, find))


#: (driver, the type fingerprints of its arguments) -> the int64 array of the entry addresses of
#: the functions it calls by address (MPF and guided drivers): found once per process, as the
#: particle kernel's passes are (:data:`_PASS_ADDRESSES`). The argument types of those calls are
#: ``numba.typeof`` of the groups passed, which costs milliseconds for the MPF's (numba types its
#: 37 work arrays one by one); the fingerprints, what numba's dispatcher keys its compiled code on,
#: take 10 us
_CALL_ADDRESSES: dict = {}


def _call_addresses(driver, args, find) -> np.ndarray:
    """The addresses ``find()`` returns (:func:`native_addresses`) for ``driver`` called with
    ``args``, looked up in :data:`_CALL_ADDRESSES` first."""
    import numba
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
    (``_time_update``, ``_kalman_update``, ``_mixture_moments`` of
    :mod:`pfbench.backends.numba_mpf_steps`): the types of the groups the host hands the driver
    (:mod:`pfbench.backends.mpf_work`) and of the step ``t`` and weight sum. The driver's compile
    refuses other types (:func:`pfbench.backends.native_call.caller`)."""
    import numba

    none, w = numba.types.none, work
    return {"_time_update": (pass_types(w.lin, w.cond, st.noise.Ql, w.APl, w.pred), none),
            "_kalman_update": (pass_types(w.obs, w.pred, st.meas, 0, w.upd, w.wts.ll, w.cond), none),
            "_mixture_moments": (pass_types(w.wts.wu, 0.0, w.mom, w.xs, w.cond, st.split, out.est[0], out.cov[0]),
                                 none)}


#: the functions of :data:`pfbench.backends.numba_mpf.RUN_CALLS` that a cold start compiles in
#: this process after the driver, while a helper compiles the others: the model's, the wrappers
#: that call them and ``_kalman_update``, the split that balances the two cores on Ob5 (measured,
#: cold ``pfbench run --model ob5 --method mpf``: here the driver 1.9 s and these 2.8 s, in the
#: helper the rest 4.3 s; both done about 5.1 s after the start)
_RUN_HERE = ("_normals_into", "_sandwich", "_condition", "_time_update", "_weigh", "_moments", "_mixture_moments")


def _run_calls(p, rng, u, st, work) -> dict:
    """Name -> (argument types, return type) of the other functions the numba MPF driver ``run``
    calls by address (:data:`pfbench.backends.numba_mpf.RUN_CALLS`): the model's
    ``cl_transition``, ``cl_observation`` and ``cl_constrain`` on the :class:`~pfbench.backends.mpf_work.Work`
    arrays they get (return type None: whatever the model returns, known once they are compiled,
    which is done before their callers), the three wrappers that call them
    (``_transition_into``, ``_observation_into``, ``_constrain_into``), the x^n noise, the
    ``sandwich`` and ``condition`` of steps 1-2 and the weights and moments: each the types of the
    objects the driver passes (``u[t]`` a row of the C-contiguous ``u``, ``t`` and the model's
    address int64, the weight sum float64). The driver's compile refuses other types
    (:func:`pfbench.backends.native_call.caller`)."""
    import numba

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
def run_guided(model, p, rng, y, u, x, lw, kind, n_noise, scheme, threshold, est, var, ess, inc, res, degen):
    """The numba guided filter (:func:`pfbench.filters.guided.run_guided`) from the initial particles
    ``x`` and log-weights ``lw``; ``kind``: ``proposal`` or ``optimal``; fills the outputs in place."""
    y, u = np.ascontiguousarray(y), np.ascontiguousarray(u)  # the row types _model_calls gives
    mod = build("guided", model, scheme)
    driver = getattr(mod, f"run_{kind}")
    out = guided_work.Outputs(est, var, ess, inc, res, degen)
    settings = guided_work.Settings(int(n_noise), int(scheme), float(threshold))
    args = (p, rng, y, u, x, lw, out, settings)
    propose, weight = _call_addresses(driver, args, lambda: native_addresses(
        model, "guided", mod, driver, args, _model_calls(kind, p, y, u, x, n_noise)))
    driver(*args[:-1], settings._replace(propose=int(propose), weight=int(weight)))


def _model_calls(kind, p, y, u, x, n_noise) -> list:
    """``(name, argument types, return type)`` of the two model calls a whole run makes by address
    (:mod:`pfbench.backends.numba_guided`, "the model's calls"): the proposal, then the proposal's
    weight (``kind`` "proposal") or the predictive likelihood ("optimal"), each ``numba.typeof``
    of what the kernel passes: rows of the C-contiguous ``y``, ``u``, the particles ``x``, the step
    (int64) and arrays like the ones the kernel allocates for the noise, the new particles and the
    log-likelihoods (float64, C order)."""
    import numba

    none = numba.types.none
    noise, xn, ll = np.empty((1, n_noise)), np.empty_like(x), np.empty(1)
    calls = [("_propose_into", pass_types(x, y[0], u[0], 0, noise, p, xn), none)]
    if kind == "proposal":
        return calls + [("_weight_into", pass_types(xn, x, y[0], u[0], 0, p, ll), none)]
    return calls + [("_predictive_into", pass_types(y[0], x, u[0], 0, p, ll), none)]
