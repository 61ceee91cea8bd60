"""Twin of csrc/imf_math.h: inverse square root, normalisation and quaternion helpers.

R is the arithmetic type of the filter (float or numpy.float32). Functions
return new values instead of writing through pointers.
"""
import math
import struct

import numpy as np

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


NORM_OK, NORM_TINY, NORM_HUGE = 0, 1, 2


def real_limits(R):
    """(IMF_REAL_MIN, IMF_REAL_MAX): smallest normal and largest finite value of
    R; for exact arithmetic (fractions.Fraction, used by tests) every non-zero
    value is normal: (None, None)."""
    if R is float or R is np.float32:
        fi = np.finfo(np.float64 if R is float else np.float32)
        return R(fi.tiny), R(fi.max)
    return None, None


_LIMITS: dict = {}


def _limits(R):
    lim = _LIMITS.get(R)
    if lim is None:
        lim = _LIMITS[R] = real_limits(R)
    return lim


def inverse_norm(R, n2, mode):
    """imf_inverse_norm: (NORM_OK, r) with r = 1/|v| when n2 is a normal
    number and r finite and non-zero; (NORM_TINY, None) for n2 zero or
    subnormal; (NORM_HUGE, None) for n2 overflowed or NaN."""
    lo, hi = _limits(R)
    if lo is None:
        return (NORM_TINY, None) if n2 == 0 else (NORM_OK, invsqrt(R, n2, mode))
    if not n2 <= hi:
        return NORM_HUGE, None
    if n2 < lo:
        return NORM_TINY, None
    r = invsqrt(R, n2, mode)
    return (NORM_OK, r) if R(0.0) < r <= hi else (NORM_HUGE, None)


def normalise3(R, x, y, z, mode):
    """imf_normalise3: (rc, (x, y, z)); unchanged unless rc is NORM_OK."""
    rc, r = inverse_norm(R, x * x + y * y + z * z, mode)
    if rc != NORM_OK:
        return rc, (x, y, z)
    return NORM_OK, (x * r, y * r, z * r)


def normalise4(R, w, x, y, z, mode):
    """imf_normalise4: (rc, (w, x, y, z)); unchanged unless rc is NORM_OK."""
    rc, r = inverse_norm(R, w * w + x * x + y * y + z * z, mode)
    if rc != NORM_OK:
        return rc, (w, x, y, z)
    return NORM_OK, (w * r, x * r, y * r, z * r)


def gravity_ok(R, dx, dy, dz, d2_max):
    """imf_gravity_ok: |d|^2 a normal number and at most d2_max."""
    lo = _limits(R)[0]
    n2 = dx * dx + dy * dy + dz * dz
    return (n2 != 0 if lo is None else lo <= n2) and n2 <= d2_max


def is_zero3(R, x, y, z):
    return x == R(0.0) and y == R(0.0) and z == R(0.0)


def sqrt(R, x):
    # imf_sqrt: sqrt / sqrtf; x >= 0 here (a sum of squares) or NaN / inf
    return R(math.sqrt(x)) if x >= 0 else R(math.nan)


def qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    # imf_qmul: the Hamilton product a (x) b
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


def qrotate(R, w, x, y, z, vx, vy, vz):
    # imf_qrotate: R(q) v = v + w t + q_v x t, t = 2 q_v x v
    tx = R(2.0) * (y * vz - z * vy)
    ty = R(2.0) * (z * vx - x * vz)
    tz = R(2.0) * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))
