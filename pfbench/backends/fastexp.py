"""A vectorisable exponential for the particle weights, the same bits on both backends.

Every particle-filter step evaluates ``w_i = exp(a_i - max a)`` once per particle ([Embedded]
Alg. 1 step 3; [Thesis] eq. 2.13). The math library's ``exp`` is a scalar call that LLVM cannot
vectorise. This module computes
the same function with arithmetic only (no call, no table, no branch), so a loop of it compiles to
SIMD instructions, and it does so with the same floating-point operations in NumPy
(:func:`exp_array`) and in numba (:func:`exp_scalar`): the two backends get bit-identical weights.

Method (the classic argument reduction of fdlibm's ``e_exp``, written branch-free):

* k = round(x / ln 2), by adding and subtracting 1.5 * 2^52 (round to nearest even);
* r = (x - k ln2_hi) - k ln2_lo with a two-part ln 2 (``k ln2_hi`` is exact for |k| < 2^11),
  |r| <= ln(2) / 2;
* exp(r) = 1 - ((lo - r c / (2 - c)) - hi), c = r - r^2 (P1 + r^2 (P2 + ... + r^2 P5)), the
  rational form of exp on [-ln 2 / 2, ln 2 / 2] with fdlibm's minimax coefficients (error < 1 ulp);
* exp(x) = exp(r) 2^(k // 2) 2^(k - k // 2): two exact power-of-two factors built from their bit
  patterns, so the result underflows gradually into the subnormals with a single rounding.

The argument is clamped to [-746, 710] first: below -746 the result is 0, above 710 it is +inf,
as for the library exp; NaN maps to 0 (the weighting has already turned NaN log-likelihoods into
-inf, whose weight is 0). Accuracy: within 1 ulp of ``np.exp`` (tested on a dense grid of
[-745, 709], subnormal results included).

In numba a loop that calls :func:`exp_scalar` vectorises only if nothing else in it carries a
dependence (a running sum does), so the kernels evaluate the exponentials in a loop of their own,
and only if the function is compiled with ``error_model="numpy"``: numba's default guards the
division with a zero check that raises, and the vectoriser gives up on it.
"""
from __future__ import annotations

import numpy as np
from numba import types
from numba.extending import intrinsic, register_jitable

#: 1 / ln 2
_LOG2E = 1.4426950408889634
#: 1.5 * 2^52: x + _SHIFT - _SHIFT rounds x to an integer (to nearest, ties to even) for |x| < 2^51
_SHIFT = 6755399441055744.0
#: the bit pattern of _SHIFT: bits(_SHIFT + k) - _SHIFT_BITS = k for |k| < 2^51
_SHIFT_BITS = int(np.float64(_SHIFT).view(np.int64))
#: ln 2 in two parts (fdlibm's ln2HI, ln2LO): the high part has 32 significant bits
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
#: fdlibm's minimax coefficients of the rational form of exp on [-ln 2 / 2, ln 2 / 2]
_P1 = 1.66666666666666019037e-01
_P2 = -2.77777777770155933842e-03
_P3 = 6.61375632143793436117e-05
_P4 = -1.65339022054652515390e-06
_P5 = 4.13813679705723846039e-08
#: the argument range outside which the result is 0 or +inf
_LOW = -746.0
_HIGH = 710.0


@intrinsic
def bitcast(typingctx, x):
    """The int64 bit pattern of a float64, or the float64 of an int64's bits (a register move,
    vectorisable)."""
    to = {types.float64: types.int64, types.int64: types.float64}.get(x)
    if to is None:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(to))
    return to(x), codegen


@register_jitable
def _reduced(x):
    """(exp(r), k + 1.5 * 2^52) for a clamped x = k ln 2 + r: the arithmetic shared by both twins
    (plain + - * /, so the same code runs on a numba float and on a NumPy array)."""
    ks = x * _LOG2E + _SHIFT
    kf = ks - _SHIFT
    hi = x - kf * _LN2_HI
    lo = kf * _LN2_LO
    r = hi - lo
    t = r * r
    c = r - t * (_P1 + t * (_P2 + t * (_P3 + t * (_P4 + t * _P5))))
    return 1.0 - ((lo - (r * c) / (2.0 - c)) - hi), ks


@register_jitable
def exp_scalar(x):
    """exp(x) for a float64 in numba code, bit-identical to :func:`exp_array` (see the module)."""
    x = x if x > _LOW else _LOW
    x = x if x < _HIGH else _HIGH
    e, ks = _reduced(x)
    k = bitcast(ks) - _SHIFT_BITS
    k1 = k >> 1
    return e * bitcast((k1 + 1023) << 52) * bitcast((k - k1 + 1023) << 52)


def exp_array(x) -> np.ndarray:
    """exp of a float64 array in NumPy, with the operations of :func:`exp_scalar` (the same bits)."""
    x = np.asarray(x, dtype=np.float64)
    x = np.where(x > _LOW, x, _LOW)
    x = np.where(x < _HIGH, x, _HIGH)
    e, ks = _reduced(x)
    k = ks.view(np.int64) - _SHIFT_BITS
    k1 = k >> 1
    return e * ((k1 + 1023) << 52).view(np.float64) * ((k - k1 + 1023) << 52).view(np.float64)
