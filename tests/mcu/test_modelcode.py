"""A model's own code compiled for Cortex-M4 (pfbench.mcu.modelcode), called in the emulator.

Every compile is cached on disk (keyed on the package source), so a rerun costs the emulation only.
Tests that need the cross toolchain skip with the reason when it is missing (`make mcu-tools`).
"""
from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from pfbench import models as M
from pfbench.errors import UnsupportedError
from pfbench.mcu import modelcode as mc
from pfbench.mcu import toolchain

pytestmark = pytest.mark.mcu_tools

DOCS = Path(__file__).resolve().parents[2] / "docs" / "MCU_MODELS.md"
EPS32 = float(np.finfo(np.float32).eps)


@pytest.fixture(scope="module", autouse=True)
def tools():
    why = toolchain.missing()
    if why:
        pytest.skip("Cortex-M4 toolchain/emulator missing: " + "; ".join(why))


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def _inputs(model, n, seed=0):
    rng = np.random.default_rng(seed)
    p = model.params()
    x = np.asarray(model.initial(rng, n, p), float) + rng.standard_normal((n, model.n_x)) * \
        np.abs(np.asarray(model.initial(rng, 1, p), float)).reshape(1, -1) * 0.01
    u = np.asarray(model.inputs(rng, 4)[2], float) if model.n_u else np.zeros(0)
    z = rng.standard_normal((n, model.n_noise))
    t = 3
    x1 = np.asarray(type(model).transition(x, u, t, z, p), float).reshape(n, model.n_x)
    y = np.asarray(type(model).observe(x1[:1], u, t, rng.standard_normal((1, model.obs_noise_dim)),
                                       p), float).reshape(model.n_y)
    return dict(x=x, u=u, t=t, noise=z), dict(y=y, x=x1, u=u, t=t)


def _host(model, tr, ll, real):
    """The model's NumPy functions on the inputs rounded to ``real`` (what the target receives)."""
    c = lambda a: np.asarray(a, real).astype(float)  # noqa: E731
    p = model.params()
    xt = np.asarray(type(model).transition(c(tr["x"]), c(tr["u"]), tr["t"], c(tr["noise"]), p), float)
    lt = np.asarray(type(model).log_likelihood(c(ll["y"]), c(ll["x"]), c(ll["u"]), ll["t"], p), float)
    return xt.reshape(tr["x"].shape), lt


@pytest.mark.parametrize("name", ["ob1", pytest.param("ob5", marks=pytest.mark.slow)])
def test_double_build_is_bit_exact(name):
    """Double: the target's numbers are the host's (newlib libm vs glibc may differ by 1 ulp; Ob5
    calls exp). Catches: a wrong ABI (soft-float triple: doubles read from r0-r3 instead of d0-d7),
    x86 struct offsets baked into the IR, wrong parameter freezing, a wrong stack argument."""
    model = M.get(name)
    mo = mc.compile_model(name, "double")
    assert (mo.n_x, mo.n_y, mo.n_u, mo.n_noise) == (model.n_x, model.n_y, model.n_u, model.n_noise)
    assert "-DPF_FLOAT" not in mo.defines and f"-DPFM_NX={model.n_x}" in mo.defines
    tr, ll = _inputs(model, 7)
    xt, lt = _host(model, tr, ll, np.float64)
    np.testing.assert_array_max_ulp(mc.call_on_target(mo, "transition", tr), xt, maxulp=2)
    np.testing.assert_array_max_ulp(mc.call_on_target(mo, "log_likelihood", ll), lt, maxulp=2)


#: a 2-state linear-Gaussian model with an input: matrix products (the BLAS shim), n_u > 0
LG2 = dict(A=((0.9, 0.1), (-0.2, 0.8)), C=((1.0, 0.5), (0.0, 1.0)), Q=((1.0, 0.2), (0.2, 0.5)),
           R=((1.0, 0.0), (0.0, 2.0)), B=((1.0,), (0.5,)))


@pytest.mark.parametrize("name,params", [("ob1", {}), ("linear_gaussian", LG2),
                                         pytest.param("ob5", {}, marks=pytest.mark.slow)])
def test_float_build_matches_to_float32_rounding(name, params):
    """Float: each output is a short chain of float32 operations on float32 inputs, so it agrees
    with the float64 evaluation of the same inputs to a few float32 roundings of the largest term:
    |err| <= 64 eps32 (|ref| + max|term|); we take the terms' scale as |ref| + |x| + 10 (Ob1's
    25x/(1+x^2) <= 12.5 and 8 cos <= 8; the other models' states are O(1)). Catches a float build
    that reads or writes the wrong type/stride, loses a term, or a wrong BLAS shim (gemm/gemv
    transposes: the 2x2 matrices are not symmetric)."""
    model = M.get(name, **params)
    mo = mc.compile_model(name, "float", params=params)
    assert (mo.n_x, mo.n_u) == (model.n_x, model.n_u)
    assert "-DPF_FLOAT" in mo.defines
    tr, ll = _inputs(model, 7)
    xt, lt = _host(model, tr, ll, np.float32)
    gx = mc.call_on_target(mo, "transition", tr)
    gl = mc.call_on_target(mo, "log_likelihood", ll)
    scale_x = np.abs(xt) + np.abs(np.asarray(tr["x"], float)) + 10.0
    assert np.all(np.abs(gx - xt) <= 64 * EPS32 * scale_x)
    # log-likelihood: squared residuals / variance; scale by the largest term |lt| + 10
    assert np.all(np.abs(gl - lt) <= 64 * EPS32 * (np.abs(lt) + 10.0) * max(1.0, np.max(np.abs(lt))))


def test_float_rewrite_keeps_particles_in_single_precision():
    """Ob1 in float: nothing double inside the particle loops, at most the per-call step term
    (1.2 * t: int->double, multiply, ->float); the double build has double ops in its loops.
    Catches: float literals left double; the float64-scalar narrowing removed (then
    8 cos(1.2 t) makes every particle's update double: ~20 loop ops); a counter that always
    returns 0 (the double assertion)."""
    f = mc.compile_model("ob1", "float")
    d = mc.compile_model("ob1", "double")
    assert f.double_loop_ops == {"pfm_transition": 0, "pfm_log_likelihood": 0}
    assert f.double_ops["pfm_log_likelihood"] == 0
    assert f.double_ops["pfm_transition"] <= 4
    assert d.double_loop_ops["pfm_transition"] > 0 and d.double_loop_ops["pfm_log_likelihood"] > 0


def test_float_cbrt_calls_cbrtf():
    """np.cbrt in a float build calls C's cbrtf on the target (as a C port would and as the cost
    model counts it), not a float or double pow. Catches: the rewrite dropped (numba's np.cbrt
    is a double pow), or replaced by sign(v) |v|**(1/3) (a powf)."""
    mo = mc.compile_model("ob4", "float")
    assert "cbrtf" in mo.undefined
    assert not {"pow", "powf", "cbrt"} & set(mo.undefined)


def test_float32_rewrite_of_source():
    """The rewrite itself (host side): float and int literals in arithmetic become float32
    constants, indices/exponents/shapes stay integers, constructors get dtype=float32.
    Catches a rewrite that converts an index (x[:, 0] -> x[:, 0.0] fails to compile) or misses
    a literal."""
    import numba

    src = mc.float32_source(M.model_class("ob1").transition, "")[0]
    ns = src.__globals__
    consts = sorted(float(v) for k, v in ns.items() if k.startswith("_pfm_f32_"))
    for c in (0.5, 25.0, 1.0, 8.0, np.float32(1.2)):
        assert any(abs(v - float(c)) < 1e-6 for v in consts)
    x = np.linspace(-3, 3, 6, dtype=np.float32).reshape(6, 1)
    z = np.ones((6, 1), np.float32)
    p = (np.float32(np.sqrt(10.0)), np.float32(1.0), np.float32(0.1))
    out = numba.njit(src)(x, np.zeros(0, np.float32), 2, z, p)
    assert out.dtype == np.float32

    def helper(n):
        a = np.zeros((n, 2))
        return a[:, 1] + 2 ** 2 + 3

    h = mc.float32_source(helper, "")[0]
    assert numba.njit(h)(3).dtype == np.float32


def _docs_example(tmp_path: Path):
    text = DOCS.read_text()
    code = re.findall(r"```python\n(.*?)```", text, flags=re.S)[0]
    path = tmp_path / "growth_mcu_doc.py"
    path.write_text(code.replace('@register("growth")', '@register("growth_doc_test")'))
    return path


def test_user_model_from_docs_compiles_and_runs(tmp_path):
    """The user model of docs/MCU_MODELS.md compiles (float) and its target transition agrees with
    its NumPy one (same bound as above). Catches docs drifting from what compiles."""
    mod = _load(_docs_example(tmp_path), "growth_mcu_doc")
    try:
        model = mod.Growth()
        mo = mc.compile_model(model, "float")
        assert mo.double_loop_ops["pfm_transition"] == 0
        tr, _ = _inputs(model, 5)
        xt, _ = _host(model, tr, _inputs(model, 5)[1], np.float32)
        gx = mc.call_on_target(mo, "transition", tr)
        assert np.all(np.abs(gx - xt) <= 64 * EPS32 * (np.abs(xt) + np.abs(tr["x"]) + 10.0))
    finally:
        M._REGISTRY.pop("growth_doc_test", None)
        sys.modules.pop("growth_mcu_doc", None)


BAD = '''
import numpy as np
from pfbench.models.base import StateSpaceModel

class RandomInside(StateSpaceModel):
    n_x, n_y, n_u, n_noise = 1, 1, 0, 1
    def params(self):
        return (1.0,)
    @staticmethod
    def transition(x, u, t, noise, p):
        return x + np.random.standard_normal(x.shape)
    @staticmethod
    def log_likelihood(y, x, u, t, p):
        return -0.5 * (y[0] - x[:, 0]) ** 2

class TypoInside(RandomInside):
    @staticmethod
    def transition(x, u, t, noise, p):
        return x.no_such_attribute + noise
'''


@pytest.mark.parametrize("cls,needle", [
    ("RandomInside", "runtime helper numba_get_np_random_state"),
    ("TypoInside", "Unknown attribute 'no_such_attribute'")])
def test_unsupported_user_model_is_one_line(tmp_path, cls, needle):
    """A construct the MCU cannot run is ONE UnsupportedError line naming the model function and
    the construct. Catches a traceback/worker crash instead, or an object that silently links
    against a symbol that does not exist on the MCU."""
    path = tmp_path / "bad_mcu_models.py"
    path.write_text(BAD)
    mod = _load(path, "bad_mcu_models")
    try:
        with pytest.raises(UnsupportedError) as exc:
            mc.compile_model(getattr(mod, cls)(), "float")
        msg = str(exc.value)
        assert "\n" not in msg and "function transition" in msg and needle in msg
    finally:
        sys.modules.pop("bad_mcu_models", None)


def test_bad_arguments():
    from pfbench.errors import InputError

    with pytest.raises(InputError):
        mc.compile_model("ob1", "half")
    with pytest.raises(InputError):
        mc.compile_model("ob1", "float", cpu="z80")
    with pytest.raises(InputError):
        mc.compile_model("no_such_model")


@pytest.mark.parametrize("cpu", ["cortex-m0plus", "cortex-m33",
                                 pytest.param("cortex-m3", marks=pytest.mark.slow)])
def test_other_cores_run_ob1(cpu):
    """Ob1 (float) for a core without FPU (M0+: ARMv6-M, soft-float ABI) and the M33 (ARMv8-M,
    FPv5-SP), run on unicorn's model of that core: same bound as the M4 float test. Catches a wrong
    triple/ABI per core (e.g. hard-float calls into a soft-float newlib). (The M7 object compiles,
    but unicorn's Cortex-M7 model rejects its double-precision FPU instructions.)"""
    model = M.get("ob1")
    mo = mc.compile_model("ob1", "float", cpu=cpu)
    assert mo.cpu == cpu and mo.gcc_flags[0] == f"-mcpu={cpu}"
    tr, _ = _inputs(model, 5)
    xt, _ = _host(model, tr, _inputs(model, 5)[1], np.float32)
    gx = mc.call_on_target(mo, "transition", tr)
    assert np.all(np.abs(gx - xt) <= 64 * EPS32 * (np.abs(xt) + np.abs(tr["x"]) + 10.0))


def test_matrix_products_are_compiled_into_the_model():
    """Double LG2 (x @ A', noise @ LQ', u @ B', x @ C', resid @ R^-1: gemm and gemv with
    non-symmetric 2x2 matrices): numba's BLAS entry points are compiled into the object (inlined
    and specialised, not calls into the C shim) and the results are the host's: two-term dot
    products, so at most a couple of ulps (the host BLAS may fuse a multiply-add). Catches: the
    in-module BLAS dropped (the symbols reappear as calls), a swapped transpose or leading
    dimension in it (wrong numbers), the float32/float64 dispatch on the kind inverted."""
    model = M.get("linear_gaussian", **LG2)
    mo = mc.compile_model("linear_gaussian", "double", params=LG2)
    assert not {"numba_xxgemm", "numba_xxgemv", "numba_xxdot"} & set(mo.undefined)
    tr, ll = _inputs(model, 6)
    xt, lt = _host(model, tr, ll, np.float64)
    np.testing.assert_array_max_ulp(mc.call_on_target(mo, "transition", tr), xt, maxulp=4)
    np.testing.assert_allclose(mc.call_on_target(mo, "log_likelihood", ll), lt,
                               rtol=0, atol=64 * np.finfo(float).eps * (np.max(np.abs(lt)) + 10))


def test_reused_temporaries_keep_their_values():
    """Ob2's functions allocate and free dozens of same-size temporaries per call (one per array
    expression in a 5-iteration and a 15-iteration column loop), so the NRT shim's free list hands
    the same blocks out again and again within one call of 40 particles; the results must still
    match the host to float32 rounding (bound as in the float test above: terms O(10)). Catches a
    free list that returns a block still in use, the wrong data pointer or a too-small block."""
    model = M.get("ob2")
    mo = mc.compile_model("ob2", "float")
    assert mo.needs_nrt
    tr, ll = _inputs(model, 40, seed=3)
    xt, lt = _host(model, tr, ll, np.float32)
    gx = mc.call_on_target(mo, "transition", tr)
    gl = mc.call_on_target(mo, "log_likelihood", ll)
    assert np.all(np.abs(gx - xt) <= 64 * EPS32 * (np.abs(xt) + np.abs(np.asarray(tr["x"])) + 10.0))
    assert np.all(np.abs(gl - lt) <= 64 * EPS32 * (np.abs(lt) + 10.0) * max(1.0, np.max(np.abs(lt))))
