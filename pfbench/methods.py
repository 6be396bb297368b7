"""The tables of filtering methods, point estimates, backends and particle dtypes. Every layer
(``run_filter``, the kernels, the CLI, sweeps, the operation counter) takes its names and codes
from here; it sits below both :mod:`pfbench.filters` and :mod:`pfbench.backends`.

The integer value of a :class:`Method` is the code the compiled particle kernels branch on; numba
compiles ``IntEnum`` members as integer constants.
"""
from __future__ import annotations

from .errors import InputError
from .options import Choice


class Method(Choice):
    """Filtering methods of :func:`pfbench.run_filter`.

    ========== ============================================================================
    bootstrap  resample every step ([Embedded] Alg. 1; [MultiPDF] Alg. 1)
    sir        resample when N_eff < threshold ([MultiPDF] eq. 8; [Thesis] Alg. 3)
    sis        never resample ([Thesis] Alg. 2)
    asir       auxiliary SIR, first-stage weights p(y_t | f(x_{t-1})) ([Thesis] Alg. 6)
    multipdf   N_f bootstrap sub-filters, estimates averaged ([MultiPDF] Alg. 2, eq. 9)
    mpf        marginalized PF on the model's linear-Gaussian substructure ([Schon2005] Alg. 1)
    guided     the model's own proposal, or the locally optimal one ([Doucet2000]; [Thesis] §4.2.1)
    kalman     (extended) Kalman filter on a model whose every state is linear-Gaussian
    ========== ============================================================================
    """

    BOOTSTRAP = 0
    SIR = 1
    SIS = 2
    ASIR = 3
    MULTIPDF = 4
    MPF = 5
    GUIDED = 6
    KALMAN = 7

    @property
    def family(self) -> str:
        """``particle`` (the bootstrap kernel), ``mpf``, ``guided`` or ``kalman``."""
        return _FAMILY.get(self, "particle")


Method._what = "method"


_FAMILY = {Method.MPF: "mpf", Method.GUIDED: "guided", Method.KALMAN: "kalman"}

#: method names in table order
METHODS = Method.labels()
#: the methods the bootstrap-family particle kernel runs
PARTICLE_METHODS = tuple(m.label for m in Method if m.family == "particle")


class Estimate(Choice):
    """Where the particle filters take the point estimate (mean and variance) of a step.

    ===== ==========================================================================================
    pre   the weighted mean/variance of the weighted particles, before the step's resampling
    post  the unweighted mean/variance of the resampled particles, after it ([MultiPDF] Alg. 1
          step 6, Alg. 2 step 2e); the same as ``pre`` at a step that does not resample
    ===== ==========================================================================================
    """

    PRE = 0
    POST = 1


Estimate._what = "estimate"

#: estimate names in table order
ESTIMATES = Estimate.labels()


BACKENDS = ("numpy", "numba", "cupy")
#: the backends that run :mod:`pfbench.backends.array_backend`, with their array namespace;
#: ``xp-numpy`` is the ``cupy`` backend's code on NumPy (how the CPU tests cover it)
ARRAY_BACKENDS = {"cupy": "cupy", "xp-numpy": "numpy"}
DTYPES = ("float64", "float32")


def check_backend(backend: str) -> str:
    if backend not in BACKENDS and backend not in ARRAY_BACKENDS:
        raise InputError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    return backend


def check_dtype(dtype) -> str:
    """The name of a particle dtype; a NumPy dtype or type (``np.float32``) is taken by its name."""
    if not isinstance(dtype, str) and getattr(dtype, "__name__", None) in DTYPES:
        dtype = dtype.__name__
    elif not isinstance(dtype, str) and str(getattr(dtype, "name", "")) in DTYPES:  # np.dtype("float32")
        dtype = dtype.name
    if dtype not in DTYPES:
        raise InputError(f"unknown dtype {dtype!r}; choose one of {', '.join(DTYPES)}")
    return dtype
