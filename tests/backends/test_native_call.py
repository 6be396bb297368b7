"""Calls through a native entry point: the caller gets the callee's result and exceptions, does not
compile the callee into itself, and refuses argument types the host did not compile."""
import re

import numba
import numpy as np
import pytest
from numba.core.errors import TypingError

from pfbench.backends import native_call


@numba.njit(cache=False)
def _scaled(x, i, k):
    if k < 0:
        raise ValueError("negative k")
    return x[i] * k


_call3 = native_call.caller(3)


@numba.njit(cache=False)
def _through_address(address, x, k):
    s = 0.0
    for i in range(x.shape[0]):
        s += _call3(_scaled, address, x, i, k)
    return s


def _defines(dispatcher) -> str:
    return " ".join(re.findall(r"define [^@]*@(\S+)\(", dispatcher.inspect_llvm(dispatcher.signatures[0])))


def test_call_through_the_address_gives_the_result_and_the_exception():
    """Catches: a wrong argument order or return value, a swallowed exception (the status not
    propagated). That the caller does not compile the callee: the kernel test below."""
    x = np.arange(50.0)
    address = native_call.entry_address(_scaled, (numba.typeof(x), numba.int64, numba.float64))
    assert _through_address(address, x, 2.0) == 2.0 * x.sum()
    with pytest.raises(ValueError, match="negative k"):
        _through_address(address, x, -1.0)


def test_argument_types_the_host_did_not_compile_are_refused_at_compile_time():
    """A call site whose types differ from those registered by entry_address (here int64 k) does
    not compile. Catches: a call through an address compiled for other types."""
    x = np.arange(5.0)
    address = native_call.entry_address(_scaled, (numba.typeof(x), numba.int64, numba.float64))
    with pytest.raises(TypingError, match="did not compile"):
        _through_address(address, x, 2)


def _in_memory_models() -> dict:
    """Model classes defined in executed code, which the disk cache cannot hold: numba compiles
    them in memory, so the drivers' code can be inspected. ``Drift`` (a random walk with drift
    towards 0), ``DriftProposal`` and ``DriftOptimal`` (the same with the two kinds of proposal)."""
    ns = {}
    exec("import numpy as np\n"
         "from pfbench.models import StateSpaceModel\n"
         "class Drift(StateSpaceModel):\n"
         "    n_x, n_y, n_noise = 1, 1, 1\n"
         "    def params(self):\n"
         "        return (0.5,)\n"
         "    @staticmethod\n"
         "    def initial(rng, n, p):\n"
         "        return rng.normal(0.0, 1.0, (n, 1))\n"
         "    @staticmethod\n"
         "    def transition(x, u, t, noise, p):\n"
         "        return 0.9 * x + p[0] * noise\n"
         "    @staticmethod\n"
         "    def log_likelihood(y, x, u, t, p):\n"
         "        r = y[0] - x[:, 0]\n"
         "        return -0.5 * r * r\n"
         "    @staticmethod\n"
         "    def observe(x, u, t, noise, p):\n"
         "        return x + noise\n"
         "class DriftProposal(Drift):\n"
         "    proposal_kind = 'proposal'\n"
         "    @staticmethod\n"
         "    def proposal(x_prev, y, u, t, noise, p):\n"
         "        return 0.9 * x_prev + p[0] * noise\n"
         "    @staticmethod\n"
         "    def proposal_log_weight(x, x_prev, y, u, t, p):\n"
         "        r = y[0] - x[:, 0]\n"
         "        return -0.5 * r * r\n"
         "    @staticmethod\n"
         "    def predictive_log_likelihood(y, x_prev, u, t, p):\n"
         "        r = y[0] - 0.9 * x_prev[:, 0]\n"
         "        return -0.5 * r * r / (1.0 + p[0] * p[0])\n"
         "class DriftOptimal(DriftProposal):\n"
         "    proposal_kind = 'optimal'\n", ns)
    return ns


def test_the_particle_kernel_driver_does_not_compile_its_passes_again():
    """The driver calls pass A (the model inlined) and passes B and C through their addresses: none
    of the passes' or the model's functions is defined in the driver's code. A model the disk cache
    cannot hold (:func:`_in_memory_models`) is compiled in memory, so its code can be inspected.
    Catches: the driver calling ``_pass_a``, ``block_weights`` or ``merge_gather`` directly, which
    compiles it (and, for pass A, the model) into every driver again."""
    import pfbench
    from pfbench.backends.kernels import build

    model = _in_memory_models()["Drift"]()
    tr = model.simulate(4, seed=0)
    pfbench.run_filter(model, tr.y, tr.u, method="bootstrap", n_particles=8, backend="numba", seed=0)
    driver = build("particle", model, "systematic").run_group
    defined = _defines(driver)
    assert "run_group" in defined
    for name in ("_pass_a", "transition", "log_likelihood", "block_weights", "merge_gather"):
        assert name not in defined, name


def test_a_guided_run_calls_the_model_by_address():
    """A whole guided run (a scheme's module) calls the model's proposal and its weight (or the
    predictive likelihood) through the wrappers' addresses: none of the model's functions or the
    wrappers is defined in the driver's code, for either kind of proposal. Catches: a run calling
    the model directly (compiled into every scheme's driver again, and not in a compile helper)."""
    import pfbench
    from pfbench.backends.kernels import build

    ns = _in_memory_models()
    for cls, kind in ((ns["DriftProposal"], "proposal"), (ns["DriftOptimal"], "optimal")):
        model = cls()
        tr = model.simulate(4, seed=0)
        pfbench.run_filter(model, tr.y, tr.u, method="guided", n_particles=8, backend="numba", seed=0)
        defined = _defines(getattr(build("guided", model, "systematic"), f"run_{kind}"))
        assert f"run_{kind}" in defined
        # numba's symbols carry each name's length: "8proposal" is the model's ``proposal`` itself
        for name in ("8proposal", "proposal_log_weight", "predictive_log_likelihood", "_into"):
            assert name not in defined, (kind, name)


def test_a_declared_signature_lets_the_call_site_compile_before_the_callee():
    """The host may compile the call site before the callee (a compile helper builds the callee
    meanwhile); the call then works once the callee is compiled. Catches: typing a call site from
    the callee's compiled overloads (it would fail here), and a declared return type that the
    compiled one contradicts (it would misread the result)."""
    @numba.njit(cache=False)
    def later(x, i, k):
        return x[i] + k

    x = np.arange(4.0)
    argtypes = (numba.typeof(x), numba.int64, numba.float64)
    native_call.declare(later, argtypes, numba.float64)

    @numba.njit(cache=False)
    def site(address, x, k):
        return _call3(later, address, x, 1, k)

    site.compile((numba.int64, numba.typeof(x), numba.float64))
    assert not later.overloads  # the call site compiled without the callee
    assert site(native_call.entry_address(later, argtypes), x, 0.5) == 1.5

    @numba.njit(cache=False)
    def wrong(x, i, k):
        return i

    native_call.declare(wrong, argtypes, numba.float64)
    with pytest.raises(TypeError, match="returns int64, declared float64"):
        native_call.entry_address(wrong, argtypes)
