"""NumPy's PCG64 generator and standard-normal ziggurat, inlined into numba code: the same numbers.

Every particle of a bootstrap step draws one standard normal ([Embedded] Alg. 1 step 2), and the
engine's random numbers are NumPy's (``numpy.random.default_rng``: PCG64 and the 256-layer
ziggurat of ``Generator.standard_normal``), so that the NumPy and numba backends run on common
random numbers. numba's own ``Generator.standard_normal`` reaches the bit generator through a
function pointer for every 64-bit word: an opaque call per draw, which keeps the 128-bit state in
memory and the ziggurat out of the kernel's optimiser. This module runs the same algorithm with
the state in registers:

* :func:`normals_into` loads the 128-bit PCG64 state from NumPy's own state struct, advances it
  inline (state * multiplier + increment, output XSL-RR: rotr64(high ^ low, state >> 122), as
  NumPy's ``pcg_setseq_128_xsl_rr_64_random_r``), runs NumPy's float64 ziggurat
  (``random_standard_normal``, numba's copy of NumPy's tables) and stores the state back, so any
  later draw, by numba or NumPy, continues the stream;
* :func:`normals_into_f32` does the same for ``standard_normal(dtype=np.float32)`` (the float32
  ziggurat on 32-bit words, two per PCG64 step, the spare half buffered in the state struct);
* :func:`fill_normals`, :func:`fill_normals_f32` and :func:`fill_uniforms` (``Generator.random``)
  are what compiled code calls: the inlined draws, or numba's own where :func:`layout_ok` says no;
* :func:`layout_ok` checks once per process that NumPy's state struct is laid out as this module
  reads it (a pointer to two little-endian 128-bit integers); if not, the kernels keep numba's
  own draws (the same numbers, slower).

Only PCG64 generators may be passed (:func:`check_generators`).
"""
from __future__ import annotations

import ctypes
import functools

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, overload, register_jitable
from pfbench.backends.fastexp import bitcast
from numba.np.random._constants import (fi_double, fi_float, ki_double, ki_float, wi_double, wi_float,
                                        ziggurat_nor_inv_r, ziggurat_nor_inv_r_f, ziggurat_nor_r,
                                        ziggurat_nor_r_f)

#: PCG64's 128-bit multiplier (PCG_DEFAULT_MULTIPLIER_128)
MULTIPLIER = 0x2360ED051FC65DA44385DF649FCCF645


def _struct_address(builder, context, gen_type, gen):
    """The address (uintp) of a Generator's ``pcg64_state`` struct, as numba holds it."""
    gproxy = cgutils.create_struct_proxy(gen_type)(context, builder, value=gen)
    bt = types.NumPyRandomBitGeneratorType("bit_generator")
    return cgutils.create_struct_proxy(bt)(context, builder, value=gproxy.bit_generator).state


def _state_pointer(builder, context, gen_type, gen):
    """The ``pcg64_random_t *`` (two 128-bit words: state, increment): the struct's first member."""
    i128p = ir.IntType(128).as_pointer()
    return builder.load(builder.inttoptr(_struct_address(builder, context, gen_type, gen), i128p.as_pointer()))


def _buffer_pointer(builder, context, gen_type, gen):
    """An ``i32 *`` at the ``pcg64_state`` struct: word 2 is ``has_uint32``, word 3 ``uinteger``."""
    return builder.inttoptr(_struct_address(builder, context, gen_type, gen), ir.IntType(32).as_pointer())


def _generator_intrinsic(doc, sig_of, body):
    """An intrinsic taking a Generator first: ``sig_of(gen, *rest)`` types it, ``body(context,
    builder, signature, args)`` lowers it (one place for the type check)."""
    def check(gen, *rest):
        return (sig_of(gen, *rest), body) if isinstance(gen, types.NumPyRandomGeneratorType) else None

    # numba reads the typer's arity from its signature: no *args
    if sig_of.__code__.co_argcount == 1:
        def typer(typingctx, gen):
            return check(gen)
    else:
        def typer(typingctx, gen, a, b):
            return check(gen, a, b)

    typer.__doc__ = doc
    return intrinsic(typer)


def _load_body(context, builder, signature, args):
    p = _state_pointer(builder, context, signature.args[0], args[0])
    i64, i128 = ir.IntType(64), ir.IntType(128)
    s = builder.load(p)
    c = builder.load(builder.gep(p, [ir.Constant(ir.IntType(32), 1)]))
    parts = [builder.trunc(v, i64) for w in (s, c) for v in (w, builder.lshr(w, ir.Constant(i128, 64)))]
    return context.make_tuple(builder, signature.return_type, parts)


def _store_body(context, builder, signature, args):
    p = _state_pointer(builder, context, signature.args[0], args[0])
    i128 = ir.IntType(128)
    builder.store(builder.or_(builder.zext(args[1], i128), builder.shl(builder.zext(args[2], i128),
                                                                        ir.Constant(i128, 64))), p)
    return context.get_dummy_value()


def _load32_body(context, builder, signature, args):
    p = _buffer_pointer(builder, context, signature.args[0], args[0])
    i64, i32 = ir.IntType(64), ir.IntType(32)
    words = [builder.zext(builder.load(builder.gep(p, [ir.Constant(i32, k)])), i64) for k in (2, 3)]
    return context.make_tuple(builder, signature.return_type, words)


def _store32_body(context, builder, signature, args):
    p = _buffer_pointer(builder, context, signature.args[0], args[0])
    i32 = ir.IntType(32)
    for k, v in ((2, args[1]), (3, args[2])):
        builder.store(builder.trunc(v, i32), builder.gep(p, [ir.Constant(i32, k)]))
    return context.get_dummy_value()


_U64 = types.uint64
_load = _generator_intrinsic("(state low, state high, increment low, increment high) of a Generator's PCG64 "
                             "state.", lambda g: types.UniTuple(_U64, 4)(g), _load_body)
_store = _generator_intrinsic("Write the 128-bit state (lo, hi) back into a Generator's PCG64 state.",
                              lambda g, lo, hi: types.void(g, _U64, _U64), _store_body)
_load32 = _generator_intrinsic("(has_uint32, uinteger): the buffered upper half of the last 64-bit word "
                               "that a 32-bit draw split.", lambda g: types.UniTuple(_U64, 2)(g), _load32_body)
_store32 = _generator_intrinsic("Write (has_uint32, uinteger) back.",
                                lambda g, has, buf: types.void(g, _U64, _U64), _store32_body)


@intrinsic
def _step(typingctx, lo, hi, inc_lo, inc_hi):
    """One PCG64 step: (new state low, new state high, 64-bit output) ([O'Neill] XSL-RR 128/64)."""
    u64 = types.uint64
    sig = types.UniTuple(u64, 3)(u64, u64, u64, u64)

    def codegen(context, builder, signature, args):
        i128 = ir.IntType(128)
        i64 = ir.IntType(64)
        sh = ir.Constant(i128, 64)

        def join(a, b):
            return builder.or_(builder.zext(a, i128), builder.shl(builder.zext(b, i128), sh))

        s = builder.add(builder.mul(join(args[0], args[1]), ir.Constant(i128, MULTIPLIER)), join(args[2], args[3]))
        slo = builder.trunc(s, i64)
        shi = builder.trunc(builder.lshr(s, sh), i64)
        rot = builder.trunc(builder.lshr(s, ir.Constant(i128, 122)), i64)
        v = builder.xor(shi, slo)
        left = builder.and_(builder.neg(rot), ir.Constant(i64, 63))
        out = builder.or_(builder.lshr(v, rot), builder.shl(v, left))  # rotate right (LLVM: one ror)
        return context.make_tuple(builder, signature.return_type, [slo, shi, out])

    return sig, codegen


@register_jitable
def _double(r):
    """NumPy's next_double: the top 53 bits of a 64-bit word, in [0, 1)."""
    return np.float64(r >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@register_jitable
def normals_into(gen, out):
    """Fill the float64 array ``out`` (any shape, C order) with standard normals: the numbers
    ``gen.standard_normal(out.shape)`` gives, and ``gen`` advanced as far (see the module)."""
    lo, hi, clo, chi = _load(gen)
    flat = out.reshape(out.size)
    for i in range(flat.size):
        while True:
            lo, hi, r = _step(lo, hi, clo, chi)
            idx = np.int64(r & np.uint64(0xFF))
            r = r >> np.uint64(8)
            rabs = (r >> np.uint64(1)) & np.uint64(0x000FFFFFFFFFFFFF)
            # rabs < 2^52: the signed conversion is exact and cheap; the sign is flipped by bits, not
            # by a branch (a random sign mispredicts half the time)
            x = bitcast(bitcast(np.float64(np.int64(rabs)) * wi_double[idx]) ^ (np.int64(r & np.uint64(1)) << 63))
            if rabs < ki_double[idx]:
                break
            if idx == 0:  # the tail beyond r (rare: about 1 draw in 4000)
                while True:
                    lo, hi, r1 = _step(lo, hi, clo, chi)
                    xx = -ziggurat_nor_inv_r * np.log1p(-_double(r1))
                    lo, hi, r2 = _step(lo, hi, clo, chi)
                    yy = -np.log1p(-_double(r2))
                    if yy + yy > xx * xx:
                        break
                x = -(ziggurat_nor_r + xx) if (rabs >> np.uint64(8)) & np.uint64(1) else ziggurat_nor_r + xx
                break
            lo, hi, r1 = _step(lo, hi, clo, chi)
            if (fi_double[idx - 1] - fi_double[idx]) * _double(r1) + fi_double[idx] < np.exp(-0.5 * x * x):
                break
        flat[i] = x
    _store(gen, lo, hi)


@register_jitable
def _next32(lo, hi, clo, chi, has, buf):
    """NumPy's ``pcg64_next32``: the buffered upper half if there is one, else the lower half of a
    new 64-bit word (whose upper half is buffered). Returns (lo, hi, has, buf, 32-bit word)."""
    if has:
        return lo, hi, np.uint64(0), buf, buf
    lo, hi, r = _step(lo, hi, clo, chi)
    return lo, hi, np.uint64(1), r >> np.uint64(32), r & np.uint64(0xFFFFFFFF)


@register_jitable
def _float(r):
    """NumPy's next_float: the top 24 of 32 bits, in [0, 1)."""
    return np.float32(np.float32(np.int64(r >> np.uint64(8))) * np.float32(1.0 / 16777216.0))


@register_jitable
def normals_into_f32(gen, out):
    """Fill the float32 array ``out`` (C order) with ``gen.standard_normal(out.shape,
    dtype=np.float32)``: NumPy's float32 ziggurat on 32-bit words (two per PCG64 step, the upper
    half buffered in the generator's state as NumPy does), the branches of numba's copy of it."""
    lo, hi, clo, chi = _load(gen)
    has, buf = _load32(gen)
    flat = out.reshape(out.size)
    for i in range(flat.size):
        while True:
            lo, hi, has, buf, r = _next32(lo, hi, clo, chi, has, buf)
            idx = np.int64(r & np.uint64(0xFF))
            rabs = (r >> np.uint64(9)) & np.uint64(0x0007FFFFF)
            sign = np.float32(1 - 2 * np.int64((r >> np.uint64(8)) & np.uint64(1)))  # branch-free
            x = np.float32(np.float32(np.float32(np.int64(rabs)) * wi_float[idx]) * sign)
            if rabs < ki_float[idx]:
                break
            if idx == 0:
                while True:
                    lo, hi, has, buf, r1 = _next32(lo, hi, clo, chi, has, buf)
                    xx = np.float32(-ziggurat_nor_inv_r_f * np.log1p(np.float32(-_float(r1))))
                    lo, hi, has, buf, r2 = _next32(lo, hi, clo, chi, has, buf)
                    yy = np.float32(-np.log1p(np.float32(-_float(r2))))
                    if np.float32(yy + yy) > np.float32(xx * xx):
                        break
                if (rabs >> np.uint64(8)) & np.uint64(1):
                    x = -np.float32(ziggurat_nor_r_f + xx)
                else:
                    x = np.float32(ziggurat_nor_r_f + xx)
                break
            lo, hi, has, buf, r1 = _next32(lo, hi, clo, chi, has, buf)
            if ((fi_float[idx - 1] - fi_float[idx]) * _float(r1) + fi_float[idx]
                    < np.float32(np.exp(-np.float32(0.5) * x * x))):
                break
        flat[i] = x
    _store(gen, lo, hi)
    _store32(gen, has, buf)


def fill_normals(gen, out):  # pragma: no cover - compiled through the overload below
    """Fill ``out`` (float64 or float32, C order) with ``gen.standard_normal(out.shape, out.dtype)``:
    the one way compiled code draws normals."""
    out[...] = gen.standard_normal(out.shape, dtype=out.dtype)


def fill_normals_f32(gen, out):  # pragma: no cover - compiled through the overload below
    """Fill ``out`` (float32 or float64, C order) with ``gen.standard_normal(out.shape,
    dtype=np.float32)``: float32 draws, stored exactly in a float64 ``out`` too (a kernel that
    computes in float64 gets its float32 noise without a float32 array and a conversion)."""
    out[...] = gen.standard_normal(out.shape, dtype=np.float32)


@overload(fill_normals_f32)
def _fill_normals_f32_impl(gen, out):
    """The inlined float32 draws where :func:`layout_ok`, else numba's own (same numbers)."""
    if layout_ok():
        return lambda gen, out: normals_into_f32(gen, out)

    def library(gen, out):
        flat = out.reshape(out.size)
        flat[:] = gen.standard_normal(out.size, np.float32)
    return library


@overload(fill_normals)
def _fill_normals_impl(gen, out):
    """The inlined draws where NumPy's state struct is laid out as this module reads it
    (:func:`layout_ok`, checked here at compile time), else numba's own draws (same numbers)."""
    if out.dtype == types.float32:
        return lambda gen, out: fill_normals_f32(gen, out)
    if layout_ok():
        return lambda gen, out: normals_into(gen, out)

    def library(gen, out):
        flat = out.reshape(out.size)
        flat[:] = gen.standard_normal(out.size)
    return library


@register_jitable
def uniforms_into(gen, out):
    """Fill the 1-D float64 array ``out`` with ``gen.random(out.size)``: NumPy's ``next_double``
    (the top 53 bits of each 64-bit PCG64 output), the generator advanced as far."""
    lo, hi, clo, chi = _load(gen)
    for i in range(out.shape[0]):
        lo, hi, r = _step(lo, hi, clo, chi)
        out[i] = _double(r)
    _store(gen, lo, hi)


def fill_uniforms(gen, out):  # pragma: no cover - compiled through the overload below
    """Fill the 1-D float64 array ``out`` with ``gen.random(out.size)``: the one way compiled code
    draws uniforms."""
    out[:] = gen.random(out.size)


@overload(fill_uniforms)
def _fill_uniforms_impl(gen, out):
    """The inlined draws where :func:`layout_ok`, else numba's own (same numbers)."""
    if layout_ok():
        return lambda gen, out: uniforms_into(gen, out)

    def library(gen, out):
        for i in range(out.shape[0]):
            out[i] = gen.random()
    return library


def check_generators(gens) -> None:
    """Raise UnsupportedError unless every generator runs on PCG64 (the bit generator whose state
    :func:`normals_into` reads; another one's struct would be misread)."""
    from ..errors import UnsupportedError

    for g in gens:
        if type(g.bit_generator) is not np.random.PCG64:
            raise UnsupportedError(f"the numba kernels draw from PCG64 generators, got {type(g.bit_generator).__name__}")


@functools.lru_cache(maxsize=None)
def layout_ok() -> bool:
    """Whether NumPy's PCG64 state struct is laid out as :func:`_load` reads it (checked against
    ``bit_generator.state`` on a fresh generator)."""
    try:
        bg = np.random.PCG64(12345)
        inner = ctypes.c_void_p.from_address(bg.ctypes.state_address).value
        words = (ctypes.c_uint64 * 4).from_address(inner)
        st = bg.state["state"]
        ok = (words[0] | (words[1] << 64)) == st["state"] and (words[2] | (words[3] << 64)) == st["inc"]
        state = bg.state
        state.update(has_uint32=1, uinteger=0xDEADBEEF)
        bg.state = state
        buf = (ctypes.c_uint32 * 4).from_address(bg.ctypes.state_address)
        return ok and buf[2] == 1 and buf[3] == 0xDEADBEEF
    except Exception:  # noqa: BLE001 - any surprise means: do not read the struct
        return False
