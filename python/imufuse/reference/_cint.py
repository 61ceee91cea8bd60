"""C integer semantics for the fixed-point references.

Each function mirrors one static inline function of csrc/fixed/imf_fixed.h,
operation for operation, on Python ints.  Python's ``>>`` on ints is an
arithmetic (floor) shift, which is what the C header proves at compile time
for its targets; everything else (wrap-around, truncating division,
saturation) is spelled out here.  tests/test_fixed_core.py checks every
function against the compiled C over random and extreme inputs.
"""
from __future__ import annotations

import math

INT16_MIN, INT16_MAX = -32768, 32767
INT32_MIN, INT32_MAX = -(1 << 31), (1 << 31) - 1
Q15_ONE = 32767
Q30_ONE = 1 << 30


# ---- C semantics -----------------------------------------------------------

def wrap32(x: int) -> int:
    """Two's-complement wrap to int32 (what a cast from uint32 does on gcc)."""
    x &= 0xFFFFFFFF
    return x - (1 << 32) if x & 0x80000000 else x


def wrap16(x: int) -> int:
    """Two's-complement wrap to int16."""
    x &= 0xFFFF
    return x - (1 << 16) if x & 0x8000 else x


def u32(x: int) -> int:
    """Conversion to uint32 (modulo 2^32, defined in C)."""
    return x & 0xFFFFFFFF


def asr(x: int, n: int) -> int:
    """Arithmetic shift right (C >> on a negative value, checked in C)."""
    return x >> n


def c_div(a: int, b: int) -> int:
    """C99 integer division: truncates towards zero."""
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b > 0) else -q


def sat(x: int, lo: int, hi: int) -> int:
    return lo if x < lo else hi if x > hi else x


def check32(x: int) -> int:
    """Assert that an int32 C expression did not overflow (it would be UB)."""
    if not INT32_MIN <= x <= INT32_MAX:
        raise OverflowError(f"int32 overflow in C expression: {x}")
    return x


def checku32(x: int) -> int:
    if not 0 <= x <= 0xFFFFFFFF:
        raise OverflowError(f"uint32 out of range: {x}")
    return x


# ---- imf_fixed.h mirrors ---------------------------------------------------

def asr32(x: int, n: int) -> int:
    return x >> n


def rshr32(x: int, n: int) -> int:
    """imf_rshr32: floor(x / 2^n + 1/2), n in [0, 31]."""
    if n <= 0:
        return x
    if n > 31:
        return 0
    return (x >> n) + ((x >> (n - 1)) & 1)


def shl_sat32(x: int, k: int) -> int:
    """imf_shl_sat32: x * 2^k saturated to int32."""
    if k <= 0:
        return x
    return sat(x * (1 << k), INT32_MIN, INT32_MAX)


def rshift_sat32(x: int, n: int) -> int:
    return rshr32(x, n) if n >= 0 else shl_sat32(x, -n)


def sat_q15(x: int) -> int:
    return sat(x, INT16_MIN, INT16_MAX)


def sat_q15s(x: int) -> int:
    return sat(x, -32767, INT16_MAX)


def add_sat32(a: int, b: int) -> int:
    return sat(a + b, INT32_MIN, INT32_MAX)


def sub_sat32(a: int, b: int) -> int:
    return sat(a - b, INT32_MIN, INT32_MAX)


def add_sat_q15(a: int, b: int) -> int:
    return sat_q15(a + b)


def sub_sat_q15(a: int, b: int) -> int:
    return sat_q15(a - b)


def mul_q15(a: int, b: int) -> int:
    return sat_q15(rshr32(a * b, 15))


def mul_q15_q30(a: int, b: int) -> int:
    return a * b


def mul_32x16(a: int, b: int, n: int) -> int:
    """imf_mul_32x16: round(a*b / 2^n) saturated, via two 16x16 products."""
    ah = a >> 16
    al = a & 0xFFFF
    lo = check32(al * b)
    m = check32(ah * b + (lo >> 16))
    lol = lo & 0xFFFF
    if n > 16:
        return rshr32(m, n - 16)
    if n == 16:
        return m + (lol >> 15)
    if m < -(1 << (15 + n)):
        return INT32_MIN
    return add_sat32(shl_sat32(m, 16 - n), (lol + ((1 << n) >> 1)) >> n)


def mul_32x16_exact(a: int, b: int, n: int) -> int:
    """The value imf_mul_32x16 must produce (used by the tests only)."""
    p = a * b
    r = (p + ((1 << n) >> 1)) >> n
    return sat(r, INT32_MIN, INT32_MAX)


class QScale:
    """imf_qscale_t: a positive constant m * 2^-s, m in [2^14, 2^15) or 0."""

    __slots__ = ("m", "s")

    def __init__(self, m: int, s: int):
        self.m, self.s = m, s

    def __iter__(self):
        return iter((self.m, self.s))

    def __repr__(self):
        return f"QScale(m={self.m}, s={self.s})"

    @property
    def value(self) -> float:
        return math.ldexp(self.m, -self.s)


def qscale(v: float, name: str = "value", smin: int = -16, smax: int = 62) -> QScale:
    """imf_qscale_from_double: mantissa rounded to nearest (ties up).

    Mirrors the C: frexp (exact), m = floor(f * 2^15 + 0.5), renormalised if
    the rounding reached 2^15.  Raises ValueError naming the parameter when v
    is negative, not finite, or outside the representable exponents.
    """
    if not math.isfinite(v) or v < 0.0:
        raise ValueError(f"{name} must be finite and >= 0, got {v!r}")
    if v == 0.0:
        return QScale(0, 16)
    f, e = math.frexp(v)          # v = f * 2^e, f in [0.5, 1)
    m = math.floor(f * 32768.0 + 0.5)
    s = 15 - e
    if m == 32768:
        m, s = 16384, s - 1
    if not smin <= s <= smax:
        raise ValueError(f"{name}={v!r} is out of the fixed-point range")
    return QScale(m, s)


def scale16(x: int, c: QScale, N: int) -> int:
    return rshift_sat32(x * c.m, c.s - N)


def scale32(x: int, c: QScale, K: int, N: int) -> int:
    return mul_32x16(x, c.m, c.s + K - N)


def mul_32x16_s(a: int, b: int, n: int) -> int:
    """imf_mul_32x16_s: imf_mul_32x16's value (the C keeps the n = 16 and saturating
    paths out of line outside AVR: flash)."""
    return mul_32x16(a, b, n)


def scale32_s(x: int, c: QScale, K: int, N: int) -> int:
    """imf_scale32_s: imf_scale32 through imf_mul_32x16_s."""
    return mul_32x16_s(x, c.m, c.s + K - N)


def gain8(c: QScale, N: int) -> tuple[int, int]:
    """imf_gain8: (m, n) with the product x * c * 2^N = rshift(x * m, n)."""
    n = c.s - N
    if n == 15:
        return c.m * 2, 16
    if n >= 16:
        return rshr32(c.m, n - 16), 16
    return c.m, n


def gain8_mul(x: int, g: tuple[int, int]) -> int:
    return rshift_sat32(x * g[0], g[1])


def isqrt_u32(x: int) -> int:
    res = 0
    bit = 1 << 30
    while bit > x:
        bit >>= 2
    while bit:
        if x >= res + bit:
            x -= res + bit
            res = (res >> 1) + bit
        else:
            res >>= 1
        bit >>= 2
    return res


def invsqrt_u32(x: int) -> tuple[int, int]:
    """imf_invsqrt_u32: returns (y, shift), 1/sqrt(x) ~= y * 2^-shift."""
    if x == 0:
        return 0, 0
    e = 0
    while x < (1 << 30):
        x = (x << 2) & 0xFFFFFFFF
        e += 2
    u = x >> 16
    if u < 32768:
        y = 65535 - (((u - 16384) * 38) >> 5)
    else:
        y = 46341 - (((u - 32768) * 27) >> 6)
    for _ in range(3):
        y = invsqrt_newton16(u, y)  # raises where a bound fails (tested for every u)
    return y, 31 - e // 2


def invsqrt_chord16(u: int) -> int:
    """imf_invsqrt_chord16: the chord y ~= 2^31 / sqrt(u 2^16), u in [2^14, 2^16), of
    invsqrt8_u32 and invsqrt16_u32 (64635 - floor(38 d / 32), 45691 - floor(27 d / 64))."""
    if u < 32768:
        d = u - 16384
        return 64635 - (d + ((d * 3) >> 4))
    d = u - 32768
    return 45691 - ((d >> 6) * 27 + (((d & 63) * 27) >> 6))


def invsqrt_newton16(u: int, y: int) -> int:
    """imf_invsqrt_newton16: one Newton step y <- y (3 - u y^2) / 2 (q15 y, u in
    [2^14, 2^16)); raises OverflowError where u y^2 would reach 3 2^30 or the new y
    leave uint16 (the C has neither a clamp nor a saturation)."""
    y2 = (y * y + 32768) >> 16
    t = checku32(u * y2)
    w = checku32(3221225472 - t) >> 16
    t = y * w + 16384
    y = ((t >> 16) << 1) | ((t & 0xFFFF) >> 15)
    if y > 0xFFFF:
        raise OverflowError(f"imf_invsqrt_newton16: y = {y} leaves uint16 (u = {u})")
    return y


def invsqrt8_u32(x: int) -> tuple[int, int]:
    """imf_invsqrt8_u32, x in [2^28, 2^32): (y, e), 1/sqrt(x) ~= y * 2^(e - 31)."""
    e = 0
    if x < (1 << 30):
        x <<= 2
        e = 1
    u = x >> 16
    return invsqrt_newton16(u, invsqrt_chord16(u)), e


def q15_to_q30(x: int) -> int:
    return x * 32768


def q30_to_q15(x: int) -> int:
    return sat_q15(rshr32(x, 15))


def qn_to_q15s(x: int, N: int) -> int:
    return sat_q15s(rshr32(x, N - 15))
