"""Twin of csrc/imf_math.h: inverse square root and normalisation helpers.

R is the arithmetic type of the filter (float or numpy.float32). Functions
return new values instead of writing through pointers.
"""
import math
import struct

INVSQRT = {"exact": 0, "fast": 1}
INVSQRT_EXACT, INVSQRT_FAST = 0, 1

_F32 = struct.Struct("<f")
_U32 = struct.Struct("<I")
_F64 = struct.Struct("<d")
_U64 = struct.Struct("<Q")


def invsqrt_exact(R, x):
    # 1/sqrt(x): sqrt in double is correctly rounded, so R(sqrt) equals sqrtf
    return R(1.0) / R(math.sqrt(x)) if x >= 0 else R(math.nan)


def invsqrt_fast(R, x):
    """0x5f3759df (float32) / 0x5fe6eb50c7b537a9 (float64) and one Newton step,
    on the unsigned integer image of x (C: memcpy into uint32_t/uint64_t)."""
    halfx = R(0.5) * x
    if R is float:
        i = _U64.unpack(_F64.pack(x))[0]
        i = (0x5FE6EB50C7B537A9 - (i >> 1)) & 0xFFFFFFFFFFFFFFFF
        y = _F64.unpack(_U64.pack(i))[0]
    else:
        i = _U32.unpack(_F32.pack(x))[0]
        i = (0x5F3759DF - (i >> 1)) & 0xFFFFFFFF
        y = R(_F32.unpack(_U32.pack(i))[0])
    return y * (R(1.5) - halfx * y * y)


def invsqrt(R, x, mode):
    return invsqrt_fast(R, x) if mode == INVSQRT_FAST else invsqrt_exact(R, x)


def normalise3(R, x, y, z, mode):
    n2 = x * x + y * y + z * z
    if mode != INVSQRT_FAST and n2 == R(0.0):
        return x, y, z
    r = invsqrt(R, n2, mode)
    return x * r, y * r, z * r


def normalise4(R, w, x, y, z, mode):
    n2 = w * w + x * x + y * y + z * z
    if mode != INVSQRT_FAST and n2 == R(0.0):
        return w, x, y, z
    r = invsqrt(R, n2, mode)
    return w * r, x * r, y * r, z * r


def is_zero3(R, x, y, z):
    return x == R(0.0) and y == R(0.0) and z == R(0.0)


def sqrt(R, x):
    # imf_sqrt: sqrt / sqrtf; x >= 0 here (a sum of squares) or NaN / inf
    return R(math.sqrt(x)) if x >= 0 else R(math.nan)
