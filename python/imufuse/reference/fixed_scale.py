"""Products with a q-scale constant of the single-axis and gravity-vector
fixed-point filters: pure-Python twins of csrc/fixed/imf_fixed_scale.h.

Each returns the value of the imf_fixed.h helper it names (the C computes
the same value on AVR in smaller code: byte moves and at most 7 bit steps
per shift, inline 16x16 multiplies, the rare left shifts out of line)."""
from __future__ import annotations

from . import _cint as ci


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



def invsqrt16_u32(x: int) -> int:
    """imf_invsqrt16_u32, x in [2^30, 2^32): y, 1/sqrt(x) ~= y 2^-31."""
    u = x >> 16
    y = ci.invsqrt_chord16(u)
    for _ in range(2):
        y = ci.invsqrt_newton16(u, y)  # raises where a bound fails (tested for every u)
    return y


def unit_xy_k(v):
    """imf_unit_xy_k: x, y of the symmetric q15 unit vector of int16 counts, or None."""
    n2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    if n2 == 0:
        return None
    k = 16
    while n2 < (1 << 30):
        n2 <<= 2
        k -= 1
    y = invsqrt16_u32(n2)
    return [ci.sat_q15s(rshrk(ci.check32(x * y), k)) for x in v[:2]]


def cross16(a1: int, b1: int, a2: int, b2: int) -> int:
    """imf_cross16: round((a1 b1 - a2 b2) / 2^16) saturated to int32, from
    h = floor(a b / 2^16) and the low 16 bits of each product."""
    p1, p2 = ci.check32((a1 & 0xFFFF) * b1), ci.check32((a2 & 0xFFFF) * b2)
    h1 = (a1 >> 16) * b1 + (p1 >> 16)
    h2 = (a2 >> 16) * b2 + (p2 >> 16)
    r = ((p1 & 0xFFFF) - (p2 & 0xFFFF) + 32768) >> 16
    return ci.sub_sat32(h1 + r, h2)


def cross3_16(a, b) -> list:
    """imf_cross3_16: the cross product a x b, each component cross16."""
    return [cross16(a[(i + 1) % 3], b[(i + 2) % 3], a[(i + 2) % 3], b[(i + 1) % 3])
            for i in range(3)]


def shl_exact32(x: int, k: int) -> int:
    """imf_shl_exact32: x 2^k for |x| 2^k < 2^31."""
    return ci.check32(x * (1 << k))


def gain16(c: ci.QScale, K: int, N: int) -> tuple[int, int]:
    """imf_gain16: (m, j), c 2^(N-K) ~= m 2^-(16 + 8 j); j = -2: exactly 1, -1: above."""
    d = c.s + K - N - 15
    if d < 0:
        return 0, (-2 if d == -1 and c.m == 16384 else -1)  # -2: exactly 1
    # j = (n - 15) / 8, r = d - 8 j = n - 15 - 8 j; m = 2 c.m 2^-r rounded
    # (rshrk's value, in unsigned 16-bit steps: 2 c.m < 2^16)
    r = d % 8
    j = d // 8
    u = (c.m & 0xFFFF) * 2
    if r != 0:
        u = ((u >> (r - 1)) + 1) >> 1
    return u & 0xFFFF, j


def gain16_mul(x: int, g: tuple[int, int]) -> int:
    """imf_gain16_mul: round(x m / 2^(16 + 8 j)) for int32 x, j >= 0."""
    m, j = g
    p = (x & 0xFFFF) * m
    h = (x >> 16) * m + (p >> 16)
    if j == 0:
        return h + ((p & 0xFFFF) >> 15)
    for _ in range(1, j):
        h >>= 8
    return (h >> 8) + ((h & 0xFF) >> 7)


def gain16_above(x: int, g: tuple[int, int], c: ci.QScale, K: int, N: int) -> int:
    """imf_gain16_above: x for a gain of exactly 1 (j = -2), else mulk32."""
    return x if g[1] == -2 else mulk32(x, c, K, N)


def gain16_or_mulk32(x: int, g: tuple[int, int], c: ci.QScale, K: int, N: int) -> int:
    """imf_gain16_or_mulk32: by the 16-bit gain when it has one, else gain16_above."""
    if g[1] >= 0:
        return gain16_mul(x, g)
    return gain16_above(x, g, c, K, N)
