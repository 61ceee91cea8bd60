"""Steps shared by the fixed-point quaternion filters: twin of
csrc/fixed/imf_fixed_quat.h, function for function."""
from __future__ import annotations

from . import _cint as ci

Q30_ONE = 1 << 30


def snapshot(q):
    return [ci.qn_to_q15s(v, 30) for v in q]


def normalise_acc(acc):
    """Returns the symmetric q15 unit vector, or None for the zero vector."""
    n2 = acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2]
    if n2 == 0:
        return None
    y, sh = ci.invsqrt_u32(n2)
    return [ci.sat_q15s(ci.rshr32(ci.check32(a * y), sh - 15)) for a in acc]


def mul_hq_p32(h, qs):
    """imf_q_mul_hq_p32: h (q30) times a symmetric q15 snapshot component, q30:
    imf_mul_32x16(h, qs, 15)'s value as 2 m + the rounded low part, which never
    saturates for |qs| <= 32767."""
    lo = ci.check32(qs * (h & 0xFFFF))                 # |.| < 2^31
    m = ci.check32((h >> 16) * qs + (lo >> 16))
    # (lol + 2^14) >> 15 = ((lol >> 14) + 1) >> 1, lol = lo mod 2^16
    return ci.check32(m * 2 + ((((lo & 0xFFFF) >> 14) + 1) >> 1))


def rate_p32(qs, h):
    m = mul_hq_p32
    x0, x1, x2, x3 = (m(h[0], v) for v in qs)
    y0, y1, y2, y3 = (m(h[1], v) for v in qs)
    z0, z1, z2, z3 = (m(h[2], v) for v in qs)
    sub, add = ci.sub_sat32, ci.add_sat32
    return [sub(sub(sub(0, x1), y2), z3),
            sub(add(x0, z2), y3),
            add(sub(y0, z1), x3),
            sub(add(z0, y1), x2)]


def unit3_p8(v):
    """imf_q_unit3_p8: symmetric q15 unit vector of an int16 3-vector, or None."""
    b = [max(x, -32767) for x in v]
    m = 0
    for x in b:
        m |= abs(x)
    if m == 0:
        return None
    while m < 16384:
        m <<= 1
        b = [x + x for x in b]
    n2 = sum(x * x for x in b)
    y, e = ci.invsqrt8_u32(n2)
    return [ci.sat_q15s(ci.rshr32(check(x * y), 15 if e else 16)) for x in b]


def check(x):
    return ci.check32(x)


def rshr_hs_p8(x, n):
    """imf_q_rshr_hs_p8: ci.rshr32 for n in [0, 15] (the same value)."""
    if n >= 2:
        return ((x >> (n - 1)) + 1) >> 1
    if n == 1:
        return (x >> 1) + (x & 1)
    return x


def carry_p8(t, c, i):
    """imf_q_carry_p8: floor((t + c[i]) / 2^16), c[i] = the remainder, in 16-bit
    operations: the low words add, their carry goes to the high word."""
    lo = t & 0xFFFF
    s = (lo + (c[i] & 0xFFFF)) & 0xFFFF
    c[i] = s
    return (t >> 16) + (1 if s < lo else 0)


def rate_p8(qs, h, hs):
    """imf_q_rate_p8"""
    hx, hy, hz = (ci.sat_q15(v) for v in h)
    sub, add, r = ci.sub_sat32, ci.add_sat32, rshr_hs_p8
    return [r(sub(-qs[1] * hx - qs[2] * hy, qs[3] * hz), hs),
            r(sub(qs[0] * hx + qs[2] * hz, qs[3] * hy), hs),
            r(add(qs[0] * hy - qs[1] * hz, qs[3] * hx), hs),
            r(sub(qs[0] * hz + qs[1] * hy, qs[2] * hx), hs)]


def norm2(q, qs):
    """imf_q_norm2: |q|^2 in q30 from the snapshot qs, except where it saturates
    (+-32767): there q rounded to q15 again without saturation."""
    if all(-32767 < s < 32767 for s in qs):
        # the usual case, every component from qs: four squares < 2^30 each,
        # the sum < 2^32 needs no saturation
        return sum(s * s for s in qs)
    n2 = 0
    for v, s in zip(q, qs):
        if -32767 < s < 32767:
            u = abs(s)
        else:
            u = min(abs(ci.rshr32(v, 15)), 65535)
        n2 = min(n2 + u * u, 0xFFFFFFFF)
    return n2


def normalise_p8(q):
    """imf_q_normalise_p8: the rare full normalisation of the 8-bit profile, in
    16-bit operations: q block-scaled to [2^14, 2^15], the short inverse square
    root, q30 = b y 2^(e-1)."""
    m = 0
    for v in q:
        m |= abs(v)  # top bit of the max
    if m == 0:
        return [Q30_ONE, 0, 0, 0]
    k = 0
    while m >= 32768:
        m >>= 1
        k += 1
    while m < 16384:
        m <<= 1
        k -= 1
    b = [ci.sat_q15s(ci.rshift_sat32(v, k)) for v in q]
    n2 = sum(v * v for v in b)
    y, e = ci.invsqrt8_u32(n2)  # 1/|b| ~= y 2^(e-31)
    return [ci.rshr32(check(v * y), 1 - e) for v in b]  # e in {0, 1}


def snapshot_norm_p8(q):
    """imf_q_snapshot_norm_p8: (q, qs, d16); q normalised (normalise_p8) when far
    from 1."""
    qs = snapshot(q)
    n2 = norm2(q, qs)
    if n2 <= 1069547520 or n2 >= 1077936128:
        q = normalise_p8(q)
        return q, snapshot(q), 0
    return q, qs, ci.rshr32(n2 - Q30_ONE, 8)


def add_step_p8(q, dq, qs, d16):
    """imf_q_add_step_p8: q += dq - q d / 2."""
    return [ci.add_sat32(a, ci.sub_sat32(b, ci.rshr32(s * d16, 8)))
            for a, b, s in zip(q, dq, qs)]


def add_normalise(q, dq):
    """q += dq (saturating), then q /= |q|; returns the new q."""
    return normalise([ci.add_sat32(a, b) for a, b in zip(q, dq)])


def normalise(q):
    """imf_q_normalise: q /= |q| (full inverse square root)."""
    n2 = norm2(q, snapshot(q))
    if n2 == 0:
        return [Q30_ONE, 0, 0, 0]
    y, sh = ci.invsqrt_u32(n2)
    y14 = 32767 if y >= 65535 else (y + 1) >> 1
    return [ci.mul_32x16(v, y14, sh - 16) for v in q]


def rate_exponent(kg):
    return min(max(kg.s - 31, 0), 15)
