"""The helpers of the fixed-point RobustIMU and RobustAHRS shared by both profiles, and the
32-bit profile's: pure-Python twin of csrc/fixed/robust_q_ops.h, line for line.
"""
from __future__ import annotations

from . import _cint as ci
from . import fixed_quat as fq
from .fixed_robust_p8 import angle_p8, qexp_p8, recip_p8


def recip(x, N):
    """robust_q_recip: 2^N / x as a q-scale for x > 0 (imf_invsqrt_u32 squared)."""
    y, sh = ci.invsqrt_u32(x)
    p = y * y
    if p >= 2147483648:
        m = (p + 65536) >> 17
        s = 2 * sh - N - 17
    else:
        m = (p + 32768) >> 16
        s = 2 * sh - N - 16
    if m >= 32768:
        # the rounding reached 2^15
        m = 16384
        s -= 1
    return ci.QScale(m, s)


def scale_of(x, N):
    """robust_q_scale_of: |x| 2^-N as a q-scale (15 leading bits, rounded) and its sign."""
    u = -x if x < 0 else x
    t = u
    e = 0
    sign = -1 if x < 0 else 1
    while t >= 8388608:                  # e: the shift that brings u below 2^15 (at most 17),
        t >>= 8                          # a byte at a time first (the C on AVR only)
        e += 8
    while t >= 32768:
        t >>= 1
        e += 1
    if e > 0:
        u = (u + (1 << (e - 1))) >> e
        if u >= 32768:
            u >>= 1
            e += 1
    while u != 0 and u < 16384:
        u <<= 1
        e -= 1
    return ci.QScale(u, N - e), sign


def mul_signed(x, c, sign, K, N):
    """robust_q_mul_signed: x times the signed q-scale (sign, c), qK -> qN."""
    p = ci.scale32_s(x, c, K, N)
    return ci.sub_sat32(0, p) if sign < 0 else p


def matrix(qs):
    """robust_q_matrix: the rotation matrix of a q15 snapshot, q15, by rows (the C computes
    the first two rows only where only those are used)."""
    ww = qs[0] * qs[0]
    r = [0] * 9
    r[0] = ci.qn_to_q15s(ww + qs[1] * qs[1] - 536870912, 29)
    r[4] = ci.qn_to_q15s(ww + qs[2] * qs[2] - 536870912, 29)
    r[8] = ci.qn_to_q15s(ww + qs[3] * qs[3] - 536870912, 29)
    r[1] = ci.qn_to_q15s(qs[1] * qs[2] - qs[0] * qs[3], 29)
    r[3] = ci.qn_to_q15s(qs[1] * qs[2] + qs[0] * qs[3], 29)
    r[2] = ci.qn_to_q15s(qs[1] * qs[3] + qs[0] * qs[2], 29)
    r[6] = ci.qn_to_q15s(qs[1] * qs[3] - qs[0] * qs[2], 29)
    r[5] = ci.qn_to_q15s(qs[2] * qs[3] - qs[0] * qs[1], 29)
    r[7] = ci.qn_to_q15s(qs[2] * qs[3] + qs[0] * qs[1], 29)
    return r


def rotate(r, t, v):
    """robust_q_rotate: R v (t = 0) or R^T v (t = 1), products rounded, sums saturated."""
    out = []
    for i in range(3):
        a = 0
        for j in range(3):
            a = ci.add_sat32(a, fq.mul_hq_p32(v[j], r[3 * j + i if t else 3 * i + j]))
        out.append(a)
    return out


def rotate16(r, t, v):
    """robust_q_rotate16: R v or R^T v for an int16 v, one 16x16 product per term."""
    out = []
    for i in range(3):
        a = 0
        for j in range(3):
            a = ci.add_sat32(a, v[j] * r[3 * j + i if t else 3 * i + j])
        out.append(a)
    return out


def renorm(q):
    """robust_q_renorm: q (1 - d / 2) while |d| = ||q|^2 - 1| < 2^-10, else the full
    normalisation; returns the new q."""
    qs = fq.snapshot(q)
    n2 = fq.norm2(q, qs)
    if 1072693248 < n2 < 1074790400:
        # |d| < 2^-10 (q30: 2^20)
        d = n2 - 1073741824
        return [ci.sub_sat32(q[i], fq.mul_hq_p32(ci.rshr32(d, 1), qs[i])) for i in range(4)]
    return fq.normalise(q)


#: robust_q_mul's tables: out_i = sum_j +-a_j b_{BI[i][j]}, minus where bit j of NEG[i]
BI = ((0, 1, 2, 3), (1, 0, 3, 2), (2, 3, 0, 1), (3, 2, 1, 0))
NEG = (14, 8, 2, 4)


def qmul(a, b):
    """robust_q_mul: a (x) b, a a q15 snapshot, b q30, sums saturated in j's order."""
    out = []
    for i in range(4):
        t = 0
        for j in range(4):
            if a[j] == 0:
                continue                         # a zero term (r's last component): the same sum
            p = fq.mul_hq_p32(b[BI[i][j]], a[j])
            t = ci.sub_sat32(t, p) if (NEG[i] >> j) & 1 else ci.add_sat32(t, p)
        out.append(t)
    return out


def qexp(q, h):
    """robust_q_exp: q (x) exp(h), the series of the float filter, normalised (in place)."""
    hs = [ci.qn_to_q15s(v, 30) for v in h]
    n2 = sum(v * v for v in hs)
    if n2 > 1073741824:
        n2 = 1073741824                                    # |h|^2 <= 1, q30
    n6 = fq.mul_hq_p32(n2, 5461)                           # |h|^2 / 6
    hv = [0] + [ci.sub_sat32(h[i], fq.mul_hq_p32(n6, hs[i])) for i in range(3)]
    qs = fq.snapshot(q)
    dq = qmul(qs, hv)                                      # q (x) (0, h (1 - |h|^2 / 6))
    dq = [ci.sub_sat32(dq[i], fq.mul_hq_p32(n2 >> 1, qs[i])) for i in range(4)]
    q[:] = renorm([ci.add_sat32(q[i], dq[i]) for i in range(4)])


def gain(p8, n, n_tau, k):
    """robust_q_gain: B5, a running mean until n reaches n_tau, then k (a negative n,
    possible only from a state written by hand, counts as 0); recip_p8 in the 8-bit
    profile."""
    if n < n_tau:
        return (recip_p8 if p8 else recip)(max(n, 0) + 1, 0)
    return k


def lowpass(x, u, k):
    """robust_q_lowpass: x += k (u 2^15 - x), counts u, q15 counts x."""
    return ci.add_sat32(x, ci.scale32_s(ci.sub_sat32(u * 32768, x), k, 15, 15))


def lowpass3(x, u, k):
    """robust_q_lowpass3: lowpass for the three components of x and u (in place)."""
    for i in range(3):
        x[i] = lowpass(x[i], u[i], k)


def counts(x):
    """robust_q_counts: q15 counts -> counts, rounded, saturated to +-32767."""
    return ci.qn_to_q15s(x, 30)


def norm2(a, b, c):
    return a * a + b * b + c * c


def norm2_counts(v):
    """robust_q_norm2_counts: |v|^2 in counts^2, each q15-counts component rounded first."""
    return norm2(counts(v[0]), counts(v[1]), counts(v[2]))


def unit(v):
    """robust_q_unit: the unit vector of v, symmetric q15, or None for the zero vector."""
    m = max(abs(a) for a in v)
    k = 0
    while m > 32767:                     # k: the shift that brings the largest below 2^15
        m >>= 1
        k += 1
    w = [ci.sat_q15s(ci.rshr32(a, k)) for a in v]
    return fq.normalise_acc(w)


def one_plus(c, a, b):
    """robust_q_one_plus: 1 + c in q15 for a unit (c, a, b) with c < 0, as
    (a^2 + b^2) / (1 - c), saturated to 32767."""
    rd = recip(32768 - c, 15)                              # 1 / (1 - c)
    return min((ci.sat_q15s((a * a + b * b) >> 15) * rd.m) >> rd.s, 32767)


def half(c, a, b):
    """robust_q_half: (1 + c, a, b) normalised, symmetric q15, for a unit (c, a, b) in
    q15; (0, 1, 0) where it is 0 (c = -1: any half turn is a smallest rotation)."""
    rw = one_plus(c, a, b) if c < 0 else 32768 + c  # [0, 65535]
    n2 = ((rw * rw) >> 2) + ((a * a) >> 2) + ((b * b) >> 2)   # q28
    if n2 != 0:
        y, sh = ci.invsqrt_u32(n2)                         # 1/|r| = y 2^(14 - sh)
        r0 = (rw * y + (1 << (sh - 15))) >> (sh - 14)
        return [min(r0, 32767), ci.sat_q15s(ci.rshr32(ci.check32(a * y), sh - 14)),
                ci.sat_q15s(ci.rshr32(ci.check32(b * y), sh - 14))]
    return [0, 32767, 0]


def turn_z(q, dw, dz):
    """robust_q_turn_z: (1 + dw, 0, 0, dz) (x) q (dw, dz q30), normalised; the new q."""
    qs = fq.snapshot(q)
    out = []
    for i in range(4):
        o = qs[3 - i]
        out.append(ci.add_sat32(ci.add_sat32(q[i], fq.mul_hq_p32(dw, qs[i])),
                                fq.mul_hq_p32(dz, -o if i < 2 else o)))
    return renorm(out)


def integrate(p8, q, g, b, k):
    """robust_q_integrate: q = q (x) exp(k (g 2^15 - b)) in place (the strapdown, the
    latency's prediction), each profile's; returns the new q's q15 snapshot."""
    if p8:
        qexp_p8(q, *angle_p8(g, b, k))
    else:
        qexp(q, [ci.scale32_s(ci.sub_sat32(g[i] * 32768, b[i]), k, 15, 30) for i in range(3)])
    return fq.snapshot(q)
