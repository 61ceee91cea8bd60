"""Products with a q-scale constant of the single-axis and gravity-vector
fixed-point filters: pure-Python twins of csrc/fixed/imf_fixed_scale.h.

Each returns the value of the imf_fixed.h helper it names (the C computes
the same value on AVR in smaller code: byte moves and at most 7 bit steps
per shift, inline 16x16 multiplies, the rare left shifts out of line)."""
from __future__ import annotations

from . import _cint as ci
from . import fixed_quat as fq


def rshrk(x: int, n: int) -> int:
    """imf_rshrk: rounding right shift by n in [0, 31] (imf_rshr32)."""
    return ci.rshr32(x, n)


def shl_satk(x: int, k: int) -> int:
    """imf_shl_satk: x 2^k saturated to int32, k in [0, 31] (imf_shl_sat32)."""
    return ci.shl_sat32(x, k)


def mul32x16k(a: int, b: int, n: int) -> int:
    """imf_mul32x16k: a b 2^-n rounded, saturated, n in [0, 47] (imf_mul_32x16)."""
    return ci.mul_32x16(a, b, n)


def mulk16(x: int, c: ci.QScale, N: int) -> int:
    """imf_mulk16: x c 2^N for int16 x (imf_scale16)."""
    return ci.scale16(x, c, N)


def mulk32(x: int, c: ci.QScale, K: int, N: int) -> int:
    """imf_mulk32: x c 2^(N-K) for int32 x in qK (imf_scale32)."""
    return ci.scale32(x, c, K, N)


def i16_to_q15(a: int) -> int:
    """imf_i16_to_q15: a 2^15 exactly (imf_q15_to_q30)."""
    return (a * 65536) >> 1


def normalise_acc_k(acc):
    """imf_normalise_acc_k: symmetric q15 unit vector of raw counts, or None
    for the zero vector (imf_q_normalise_acc)."""
    return fq.normalise_acc(acc)
