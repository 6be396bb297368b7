"""The inlined PCG64 + ziggurat gives NumPy's numbers and leaves the generator where NumPy would."""
import numba
import numpy as np
import pytest

import pfbench
from pfbench.backends import pcg64
from pfbench.errors import UnsupportedError


@numba.njit
def _fill(rng, out):
    pcg64.normals_into(rng, out)


def test_layout_is_read_correctly_here():
    """On this platform NumPy's PCG64 struct is the layout the kernels read (else they fall back to
    numba's own draws and the speed-up is lost). Catches a wrong word order of the 128-bit state."""
    assert pcg64.layout_ok()


@pytest.mark.parametrize("seed", [0, 1, 12345])
def test_normals_are_numpys_and_the_stream_continues(seed):
    """2 x 10^5 draws (about 50 from the ziggurat's tail beyond r = 3.654, and ~2 % wedge rejections)
    equal ``standard_normal`` bit for bit, for a 1-D and a 2-D array, and the next uniform, normal
    and 64-bit integer after them are NumPy's too. Catches a wrong multiplier or increment, an
    output rotation off by one bit, the sign or index taken from the wrong bits, a tail or wedge
    branch that consumes a different number of words, and a state not stored back."""
    a, b = np.random.default_rng(seed), np.random.default_rng(seed)
    out = np.empty(200_000)
    _fill(a, out)
    ref = b.standard_normal(200_000)
    assert np.array_equal(out, ref)
    assert (np.abs(ref) > pcg64.ziggurat_nor_r).sum() > 10  # the tail branch was exercised
    out2 = np.empty((301, 3))
    _fill(a, out2)
    assert np.array_equal(out2, b.standard_normal((301, 3)))
    assert a.random() == b.random()
    assert a.standard_normal() == b.standard_normal()
    assert a.integers(0, 2 ** 63) == b.integers(0, 2 ** 63)


def test_other_bit_generators_are_refused():
    """The kernels read PCG64's state struct; any other bit generator's struct would be misread
    (wrong numbers or a crash). Catches a missing check before the kernel runs."""
    pcg64.check_generators([np.random.default_rng(0)])
    with pytest.raises(UnsupportedError, match="PCG64"):
        pcg64.check_generators([np.random.default_rng(0), np.random.Generator(np.random.Philox(0))])
    m = pfbench.models.get("ob1")
    with pytest.raises(UnsupportedError, match="PCG64"):
        from pfbench.backends import numba_backend
        from pfbench.backends.particle_work import outputs
        numba_backend.run_group(m, m.params(), np.random.Generator(np.random.MT19937(0)), np.zeros((2, 1)),
                                np.zeros((2, 0)), outputs(1, 2, 4, 1), 0, 0, 1.0)


@numba.njit
def _fill32(rng, out):
    pcg64.normals_into_f32(rng, out)


@pytest.mark.parametrize("seed", [0, 3])
def test_float32_normals_are_numpys_and_the_half_word_buffer_carries_over(seed):
    """float32 draws take 32-bit halves of PCG64 words and buffer the spare half in the state
    struct. An odd count leaves a half buffered: the next float32 draw by NumPy must use it, and a
    64-bit draw must skip it, as NumPy does. Catches the halves swapped, a buffer not stored back
    (or stored where NumPy does not read it), and a wrong sign bit or index mask."""
    a, b = np.random.default_rng(seed), np.random.default_rng(seed)
    out = np.empty(200_001, np.float32)
    _fill32(a, out)
    assert np.array_equal(out, b.standard_normal(200_001, dtype=np.float32))
    assert a.standard_normal(3, dtype=np.float32).tolist() == b.standard_normal(3, dtype=np.float32).tolist()
    out2 = np.empty((11, 2), np.float32)
    _fill32(a, out2)
    assert np.array_equal(out2, b.standard_normal((11, 2), dtype=np.float32))
    assert a.standard_normal() == b.standard_normal()


@pytest.mark.parametrize("name, dtype, draw", [("fill_normals", np.float64, np.float64),
                                               ("fill_normals", np.float32, np.float32),
                                               ("fill_normals_f32", np.float32, np.float32),
                                               ("fill_normals_f32", np.float64, np.float32)])
def test_fill_normals_falls_back_to_numbas_draws_with_the_same_numbers(monkeypatch, name, dtype, draw):
    """Where NumPy's state struct is not laid out as read, ``fill_normals`` and ``fill_normals_f32``
    must not read it: they fall back to the Generator's own draws (the same numbers). The fallback
    is taken from the overload and run as plain Python (a float32 ``fill_normals`` goes through
    ``fill_normals_f32``, whose fallback is then taken the same way). Catches a fallback that
    still reads the struct, or one that draws another shape or dtype."""
    monkeypatch.setattr(pcg64, "layout_ok", lambda: False)
    out = np.empty((7, 3), dtype)
    gen_t = numba.typeof(np.random.default_rng(0))
    if name == "fill_normals" and dtype == np.float32:
        assert pcg64._fill_normals_impl(gen_t, numba.typeof(out)).__code__.co_names == ("fill_normals_f32",)
        name = "fill_normals_f32"
    impl = getattr(pcg64, f"_{name}_impl")(gen_t, numba.typeof(out))
    assert "normals_into" not in impl.__code__.co_names and "normals_into_f32" not in impl.__code__.co_names
    impl(np.random.default_rng(5), out)
    assert np.array_equal(out, np.random.default_rng(5).standard_normal((7, 3), dtype=draw))
    monkeypatch.undo()
    out2 = np.empty((7, 3), dtype)
    (_fill_via if draw == dtype else _fill_f32_via)(np.random.default_rng(5), out2)
    assert np.array_equal(out2, out)


@numba.njit
def _fill_f32_via(rng, out):
    pcg64.fill_normals_f32(rng, out)


def test_float32_draws_into_float64_are_the_float32_numbers_and_the_stream_continues():
    """``fill_normals_f32`` on a float64 array stores NumPy's float32 draws exactly, and leaves the
    generator (and its buffered 32-bit half) where NumPy's own draw would. Catches float64 draws
    (another ziggurat), a lost spare half, or a state not stored back."""
    a, b = np.random.default_rng(11), np.random.default_rng(11)
    out = np.empty((9, 1))
    _fill_f32_via(a, out)
    assert np.array_equal(out, b.standard_normal((9, 1), dtype=np.float32).astype(np.float64))
    assert a.standard_normal(dtype=np.float32) == b.standard_normal(dtype=np.float32)
    assert a.standard_normal() == b.standard_normal()


@numba.njit
def _fill_via(rng, out):
    pcg64.fill_normals(rng, out)


@numba.njit
def _uniforms(rng, out):
    pcg64.fill_uniforms(rng, out)


@pytest.mark.parametrize("seed", [0, 7])
def test_uniforms_are_numpys_and_the_stream_continues(seed):
    """``fill_uniforms`` (systematic's one uniform, stratified's one per particle) equals
    ``Generator.random`` bit for bit, on a whole array and on a slice, and the next normal, uniform
    and integer after them are NumPy's. Catches the wrong 53 bits kept, a wrong scale, a state not
    stored back and a slice written past its end."""
    a, b = np.random.default_rng(seed), np.random.default_rng(seed)
    out = np.empty(10_001)
    _uniforms(a, out)
    assert np.array_equal(out, b.random(10_001))
    buf = np.full(9, -1.0)
    _uniforms(a, buf[2:5])
    assert np.array_equal(buf[2:5], b.random(3)) and np.all(buf[:2] == -1.0) and np.all(buf[5:] == -1.0)
    assert a.standard_normal() == b.standard_normal()
    assert a.random() == b.random()
    assert a.integers(0, 2 ** 63) == b.integers(0, 2 ** 63)


def test_fill_uniforms_falls_back_to_numbas_draws_with_the_same_numbers(monkeypatch):
    """Without the struct layout, ``fill_uniforms`` draws through the Generator (same numbers).
    Catches a fallback that still reads the struct."""
    monkeypatch.setattr(pcg64, "layout_ok", lambda: False)
    out = np.empty(5)
    impl = pcg64._fill_uniforms_impl(numba.typeof(np.random.default_rng(0)), numba.typeof(out))
    assert "uniforms_into" not in impl.__code__.co_names
    impl(np.random.default_rng(2), out)
    assert np.array_equal(out, np.random.default_rng(2).random(5))
