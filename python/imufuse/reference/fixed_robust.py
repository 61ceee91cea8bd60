"""Fixed-point RobustIMU and RobustAHRS (without B6): pure-Python twin of
csrc/fixed/robust_q.c, line for line (Q formats and ranges in robust_q.h).

Longer than 500 lines because: it is the twin of robust_q.c (also one file, the AHRS's B4
sharing the IMU's helpers and update), read side by side with it, block by block.
"""
from __future__ import annotations

import math

from . import _cint as ci
from . import fixed_quat as fq
from .fixed_base import FixedFilter, check_profile, check_scale, qconst
from .robust import RobustAHRS, RobustIMU

Q29_ONE = 1 << 29


# ---- helpers -------------------------------------------------------------------------

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


def recip_p8(x, N):
    """robust_q_recip_p8: 2^N / x as a q-scale for x > 0 in the 8-bit profile: a, x's 16
    leading bits (x 2^sh in [2^31, 2^32)), z ~= 2^31 / a from a chord and two Newton steps
    z <- z (2 - a z 2^-31) in 16x16 products, z <= 65535; 2^N / x = z 2^(N + sh - 47)."""
    sh = 0
    while x < 8388608:                 # below 2^23: a byte at a time (the C on AVR only)
        x <<= 8
        sh += 8
    while x < 2147483648:
        x <<= 1
        sh += 1
    a = x >> 16
    z = 92521 - ((a * 61681) >> 16)                      # 2^15 (48 - 32 a 2^-16) / 17
    for _ in range(2):
        w = ci.checku32((1 << 32) - ci.checku32(a * z))  # 2^32 - a z, a z in (0, 2^32)
        p = z * (w >> 16)                                # z w 2^-16
        z = 65535 if p >= 2147483648 else p >> 15
    m = (z >> 1) + (z & 1)                               # z / 2 rounded, in [2^14, 2^15]
    s = 46 - N - sh
    if m >= 32768:
        m = 16384
        s -= 1
    return ci.QScale(m, s)


def one_plus(c, a, b):
    """robust_q_one_plus: 1 + c in q15 for a unit (c, a, b) with c < 0, as
    (a^2 + b^2) / (1 - c), saturated to 32767."""
    rd = recip(32768 - c, 15)                              # 1 / (1 - c)
    return min((ci.sat_q15s((a * a + b * b) >> 15) * rd.m) >> rd.s, 32767)


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


# ---- the 8-bit profile's helpers -------------------------------------------------------
# The same blocks with int16 operands: every quaternion product and rotation one 16x16
# product a term, a value that is not int16 narrowed first with one exponent for the whole
# vector (its 15 leading bits), the normalisation first order in 16-bit products.

NORM_STEPS = 40


def normalise_p8(q):
    """robust_q_normalise_p8: beyond the first-order band, q halved above it, steps
    q - qs d / 2 with d = |q|^2 - 1 in [-1, 0) (q15, Newton's for 1 / |q|) below it, until
    |d| < 2^-8, at most NORM_STEPS; the identity for a q whose snapshot is zero. The new q."""
    q = list(q)
    qs = fq.snapshot(q)
    n2 = fq.norm2(q, qs)
    j = 0
    while j < NORM_STEPS and (n2 <= 1069547520 or n2 >= 1077936128):   # 2^30 -+ 2^22
        # below: d in q15, saturated to -1
        d = ci.sat_q15(((n2 >> 1) - 536870912) >> 14)
        if n2 == 0:
            q = [fq.Q30_ONE, 0, 0, 0]
        for i in range(4):
            q[i] = ci.rshr32(q[i], 1) if n2 >= 1077936128 else q[i] - ci.rshr32(qs[i] * d, 1)
            qs[i] = ci.qn_to_q15s(q[i], 30)
        n2 = fq.norm2(q, qs)
        j += 1
    return q


def renorm_p8(q):
    """robust_q_renorm_p8: q - q d / 2 with d = |q|^2 - 1 in q22 while |d| < 2^-8, else
    normalise_p8; the new q."""
    qs = fq.snapshot(q)
    n2 = fq.norm2(q, qs)
    if n2 <= 1069547520 or n2 >= 1077936128:             # 2^30 -+ 2^22
        return normalise_p8(q)
    d16 = ci.rshr32(n2 - fq.Q30_ONE, 8)                  # q22, |d| < 2^14
    # q d / 2 in q30 = qs (q15) d16 (q22) / 2^8
    return [ci.sub_sat32(q[i], ci.rshr32(qs[i] * d16, 8)) for i in range(4)]


def exponent_p8(v):
    """robust_q_exponent_p8: the smallest e >= 0 with |v_i| 2^-e < 2^15 for every i."""
    m = 0
    for a in v:
        m |= abs(a)                                      # the top bit of the largest
    e = 0
    while m >= 8388608:                # 2^23: a byte at a time (the C on AVR only)
        m >>= 8
        e += 8
    while m >= 32768:
        m >>= 1
        e += 1
    return e


def narrow_p8(v, e):
    """robust_q_narrow_p8: v 2^-e rounded, symmetric int16."""
    return [ci.sat_q15s(ci.rshr32(a, e)) for a in v]


def unit16_p8(w):
    """robust_q_unit16_p8: unit3_p8, then one Newton step on the norm,
    u + u (1 - |u|^2) / 2; None for the zero vector."""
    u = fq.unit3_p8(w)
    if u is None:
        return None
    n2 = sum(a * a for a in u)                           # q30
    d = ci.sat_q15s(ci.rshr32(fq.Q30_ONE - n2, 7))       # q23
    return [ci.sat_q15s(a + ci.rshr32(a * d, 24)) for a in u]


def qmul_p8(a, b):
    """robust_q_mul_p8: a (x) b for q15 a and b, q30, sums saturated in qmul's order."""
    def p(x, y):
        return b[x] * a[y]
    sub, add = ci.sub_sat32, ci.add_sat32
    return [sub(sub(p(0, 0) - p(1, 1), p(2, 2)), p(3, 3)),
            sub(add(p(1, 0) + p(0, 1), p(3, 2)), p(2, 3)),
            add(add(p(2, 0) - p(3, 1), p(0, 2)), p(1, 3)),
            add(sub(p(3, 0) + p(2, 1), p(1, 2)), p(0, 3))]


def shl_p8(x, k):
    """robust_q_shl_p8: x 2^k saturated, k >= 0, as k saturating doublings (ci.shl_sat32's
    value)."""
    for _ in range(k):
        x = ci.add_sat32(x, x)
    return x


def shift_p8(x, n):
    """robust_q_shift_p8: x 2^-n rounded, saturated (ci.rshift_sat32's value), its left
    shifts by shl_p8."""
    return ci.rshr32(x, n) if n >= 0 else shl_p8(x, -n)


def angle_p8(g, b, k):
    """robust_q_angle_p8: the half angle h = k (g 2^15 - b) (q30) as int16 hn and its
    exponent e, h = hn 2^e: w's 15 leading bits (exponent ew) times k.m 2^-15, e = ew + 30
    - k.s; e > 15 saturated to 15, e < -16 gives h = 0."""
    w = [ci.sub_sat32(g[i] * 32768, b[i]) for i in range(3)]
    e = exponent_p8(w)
    hn = narrow_p8(w, e)
    e += 30 - k.s
    hn = [ci.rshr32(v * k.m, 15) for v in hn]            # |hn k.m| < 2^30
    if e > 15:
        return [ci.sat_q15s(shl_p8(v, e - 15)) for v in hn], 15
    if e < -16:
        return [0, 0, 0], 0
    return hn, e


def qexp_p8(q, hn, e):
    """robust_q_exp_p8: qexp in 16-bit products, its normalisation folded in (in place):
    d = |q|^2 - 1 from q's snapshot at the start (normalise_p8 first if |d| >= 2^-8), h =
    hn 2^e in q30 (angle_p8), |h|^2 / 2 and / 6 in q15 (0 for e < 8), then
    q += q (x) (0, h (1 - |h|^2 / 6)) - q (|h|^2 + d) / 2."""
    qs = fq.snapshot(q)
    n2 = fq.norm2(q, qs)
    d16 = 0
    if n2 <= 1069547520 or n2 >= 1077936128:             # 2^30 -+ 2^22
        q[:] = normalise_p8(q)
        qs = fq.snapshot(q)
    else:
        d16 = ci.rshr32(n2 - fq.Q30_ONE, 8)              # q22, |d| < 2^14
    n2h = n6 = 0
    if e >= 8:
        # |h|^2 / 2 in q15: the squares (q(60 - 2e)) halved, shifted by 45 - 2e
        sq = sum(v * v for v in hn)
        n2h = min(ci.rshr32(sq >> 1, 45 - 2 * e), 16384)
        n6 = ci.rshr32(n2h * 10923, 15)                  # |h|^2 / 6
    # q(30 - e), |.| < 2^15 (the correction 0 for n6 = 0)
    hv = [0] + ([v - ci.rshr32(v * n6, 15) for v in hn] if n6 != 0 else list(hn))
    # q (x) (0, h) by qmul_p8, rounded to q30: fq.rate_p8's value
    dq = [fq.rshr_hs_p8(v, 15 - e) for v in qmul_p8(qs, hv)]
    sub = ci.sub_sat32
    if n2h != 0:
        # q (|h|^2 / 2) in q30 (0 for n2h = 0: the same sum without the product)
        dq = [sub(dq[i], n2h * qs[i]) for i in range(4)]
    q[:] = [ci.add_sat32(q[i], sub(dq[i], ci.rshr32(qs[i] * d16, 8))) for i in range(4)]


def integrate(p8, q, g, b, k):
    """robust_q_integrate: q = q (x) exp(k (g 2^15 - b)) in place (the strapdown, the
    latency's prediction), each profile's."""
    if p8:
        qexp_p8(q, *angle_p8(g, b, k))
    else:
        qexp(q, [ci.scale32_s(ci.sub_sat32(g[i] * 32768, b[i]), k, 15, 30) for i in range(3)])


def turn_z_p8(q, z, n):
    """robust_q_turn_z_p8: turn_z in 16-bit products, (dw, dz) = z 2^-n, not normalised (the
    next update normalises c); the new q."""
    qs = fq.snapshot(q)
    out = []
    for i in range(4):
        o = qs[3 - i]
        p = qs[i] * z[0]
        out.append(ci.add_sat32(q[i], shift_p8(p - o * z[1] if i < 2 else p + o * z[1], n)))
    return out


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


def _ceil(v):
    c = math.ceil(v)
    return int(c) if 0.0 <= c <= 1073741824.0 else -1


class RobustIMUQ(FixedFilter):
    """imufuse's recommended attitude filter (RobustIMU, docs/recommended-ahrs.md) in
    fixed point: B1, B2, B3, B5 and the output latency, int32 with 16x16 multiplies.

    RobustIMUQ(dt, <RobustIMU's keywords, the same units>, gyr_scale=rad/s per count,
    profile="32"). Two profiles: "32" (q30 times q15 products) and "8" (the same state
    and blocks, every quaternion product and rotation in 16x16 products: for 8-bit MCUs).
    State: q, s, c (q30), gravity f and B2's v (q15 acc counts), B2's scaled covariance
    (q30), bias b, low-passes lw, la (q15 counts), the sample counters n, n_rest;
    state_float gives the quaternions, f and la in counts, b and lw in rad/s.
    """
    kind = "imu"
    c_name = "imf_robust_imu_q"
    state_names: tuple = ("q0", "q1", "q2", "q3", "s0", "s1", "s2", "s3", "c0", "c1", "c2", "c3",
                   "fx", "fy", "fz", "vx", "vy", "vz", "pvv", "pvg", "pgg",
                   "bx", "by", "bz", "lwx", "lwy", "lwz", "lax", "lay", "laz", "n", "n_rest")

    @staticmethod
    def _params(dt, tau_acc=2.5, rate_ref=100.0, tau_bias=100.0, tau_bias_rest=3.0,
                rest_gyr=2.0, rest_acc=0.05, rest_time=1.5, tau_rest=0.5, latency=0.0, *,
                gyr_scale, profile="32"):
        args = RobustIMU._params(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr,
                                 rest_acc, rest_time, tau_rest, latency)
        dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc, rest_time, \
            tau_rest, latency = args
        profile = check_profile(profile)
        gyr_scale = check_scale("gyr_scale", gyr_scale)
        if not 200.0 * dt <= tau_acc <= 8192.0 * dt:
            hint = (f"; dt is in seconds (dt={dt!r} looks like milliseconds)" if dt >= 1.0
                    else "")
            raise ValueError(f"tau_acc: must be within [200 dt, 8192 dt] = [{200.0 * dt:.4g}, "
                             f"{8192.0 * dt:.4g}] s in fixed point (B2's covariance in q30), "
                             f"got {tau_acc!r}{hint}; give tau_acc in that range, or sample "
                             f"{'faster' if tau_acc < 200.0 * dt else 'slower'}")
        if not gyr_scale * dt < 2.0 ** -15:
            raise ValueError(f"gyr_scale: {gyr_scale!r} rad/s per count turns the gyro's full "
                             f"scale by more than half a radian per sample at dt={dt!r} s "
                             f"(gyr_scale dt must be below 2^-15 = {2.0 ** -15:.4g}); gyr_scale "
                             "is in rad/s per count (2000 deg/s on 16 bits: 1.0642e-3; a deg/s "
                             "scale is 57 times larger)")
        if rest_acc > 1.0:
            raise ValueError(f"rest_acc: must be <= 1 in fixed point, got {rest_acc!r}")
        if rest_acc > 0.0:
            qconst("rest_acc^2", rest_acc * rest_acc, 14, 47, nonzero=True)
        qconst("gyr_scale*dt", 0.5 * gyr_scale * dt, 31, 62, nonzero=True)
        if latency > 0.0:
            qconst("gyr_scale*latency", 0.5 * gyr_scale * latency, 15, 62, nonzero=True)
        if rate_ref > 0.0:
            e = dt / tau_acc
            qconst("(dt/tau_acc)^2 (gyr_scale/rate_ref)^2",
                   4.0 * e * e * (gyr_scale / rate_ref) * (gyr_scale / rate_ref), 30, 62,
                   nonzero=True)
        if tau_bias > 0.0:
            qconst("1/(tau_bias*gyr_scale)", 1.0 / (tau_bias * gyr_scale), -15, 32, nonzero=True)
        for name, v in (("rest_time", rest_time), ("tau_rest", tau_rest)):
            if _ceil(v / dt) < 0:
                raise ValueError(f"{name}: must be at most 2^30 samples, got {v!r}")
        qconst("dt/(tau_rest+dt)", dt / (tau_rest + dt), 0, 47, nonzero=True)
        qconst("dt/(tau_bias_rest+dt)", dt / (tau_bias_rest + dt), 0, 47, nonzero=True)
        return args + (gyr_scale, profile)

    @staticmethod
    def _consts(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc, rest_time,
                tau_rest, latency, gyr_scale, profile):
        # imf_robust_imu_q_init: the constants from the double parameters
        gs = gyr_scale
        e = dt / tau_acc
        g2 = rest_gyr / gs
        n_tau, n_acc = _ceil(tau_rest / dt), _ceil(tau_acc / dt)
        return dict(kg=ci.qscale(0.5 * gs * dt), klat=ci.qscale(0.5 * gs * latency),
                    eps=ci.qscale(e),
                    kq=ci.qscale(4.0 * e * e * (gs / rate_ref) * (gs / rate_ref)
                                 if rate_ref > 0.0 else 0.0),
                    k_rest=ci.qscale(dt / (tau_rest + dt)),
                    kb_rest=ci.qscale(dt / (tau_bias_rest + dt)),
                    kbias=ci.qscale(1.0 / (tau_bias * gs) if tau_bias > 0.0 else 0.0),
                    kacc2=ci.qscale(rest_acc * rest_acc),
                    qg0=math.floor(e * e * 1073741824.0 + 0.5),
                    qcap=math.floor(1e4 * e * e * 1073741824.0 + 0.5),
                    pg0=math.floor(e * 1073741824.0 + 0.5),
                    rest_g2=0xFFFFFFFF if g2 * g2 >= 4294967295.0 else math.ceil(g2 * g2),
                    n_tau=n_tau, n_acc=n_acc, n_rest=_ceil(rest_time / dt),
                    n_max=max(n_tau, n_acc), profile=int(profile))

    def _init(self, dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc,
              rest_time, tau_rest, latency, gyr_scale, profile):
        self.dt = dt
        self.gyr_scale = gyr_scale
        self.tau_acc = tau_acc
        self._init_consts(**self._consts(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest,
                                         rest_gyr, rest_acc, rest_time, tau_rest, latency,
                                         gyr_scale, profile))

    def _init_consts(self, **k):
        # imf_robust_imu_q_init_consts (the ranges were checked by _params)
        self.k = k
        self.kg = k["kg"]                                  # the rate scale integrated
        self.q = [fq.Q30_ONE, 0, 0, 0]
        self.s = [fq.Q30_ONE, 0, 0, 0]
        self.c = [fq.Q30_ONE, 0, 0, 0]
        self.f, self.v, self.p = [0, 0, 0], [0, 0, 0], [0, 0, 0]
        self.b, self.lw, self.la = [0, 0, 0], [0, 0, 0], [0, 0, 0]
        self.n = self.n_rest = 0

    def _get_state(self):
        return (self.q + self.s + self.c + self.f + self.v + self.p + self.b + self.lw
                + self.la + [self.n, self.n_rest])

    def _set_state(self, v):
        v = list(v)
        self.q, self.s, self.c = v[0:4], v[4:8], v[8:12]
        self.f, self.v, self.p = v[12:15], v[15:18], v[18:21]
        self.b, self.lw, self.la = v[21:24], v[24:27], v[27:30]
        self.n, self.n_rest = v[30], v[31]

    def _state_float(self, s):
        q30, q15 = 2.0 ** -30, 2.0 ** -15
        w = self.gyr_scale * q15
        return ([v * q30 for v in s[:12]] + [v * q15 for v in s[12:15]]
                + [v * q15 * self.tau_acc for v in s[15:18]] + [v * q30 for v in s[18:21]]
                + [v * w for v in s[21:27]] + [v * q15 for v in s[27:30]] + list(s[30:]))

    def _update(self, gyr, acc):
        if self._step(gyr, acc):
            self._finish(gyr)

    def _step(self, gyr, acc):
        # robust_q_step: B1, B2, B3 and B5 of one sample; False when the sample is not
        # taken (no start without an accelerometer reading), then nothing else runs
        k = self.k
        p8 = k["profile"] == 8
        first = self.n == 0
        # an all-zero accelerometer is no reading: gyro only (and no start without one)
        has_acc = not (acc[0] == 0 and acc[1] == 0 and acc[2] == 0)
        if first and not has_acc:
            return False
        if has_acc and not first:
            # a reading beyond 100 times the gravity estimate (100 g): no reading
            f2 = norm2_counts(self.f)
            an2 = norm2(acc[0], acc[1], acc[2])
            if f2 < 429497 and an2 > f2 * 10000:
                has_acc = False
        # B1: rest detection, low-passes of gyro and accelerometer in the sensor frame
        kk = gain(p8, self.n, k["n_tau"], k["k_rest"])
        lowpass3(self.lw, gyr, kk)
        if has_acc:
            lowpass3(self.la, acc, kk)
        w2 = norm2_counts(self.lw)
        # at rest: the low-passed and the raw gyro below rest_gyr, the accelerometer within
        # rest_acc of its low-pass (each test only where the ones before hold)
        still = has_acc and w2 < k["rest_g2"] and norm2(gyr[0], gyr[1], gyr[2]) < k["rest_g2"]
        if still:
            # the accelerometer's difference from its low-pass, counts, within +-32767
            lc = [counts(v) for v in self.la]
            de = [ci.sat_q15s(acc[i] - lc[i]) for i in range(3)]
            still = ((norm2(de[0], de[1], de[2]) >> 2)
                     < ci.scale32_s(norm2(lc[0], lc[1], lc[2]) >> 2, k["kacc2"], 0, 0))
        if still:
            if self.n_rest < k["n_rest"]:
                self.n_rest += 1
        else:
            self.n_rest = 0
        rest = self.n_rest >= k["n_rest"]
        if rest:
            # Eq. 3.1: b_k = b_{k-1}, observed directly at rest
            lowpass3(self.b, gyr, k["kb_rest"])
        # strapdown: s = s (x) exp(1/2 (w - b) dt), series as the float filter
        integrate(p8, self.s, gyr, self.b, k["kg"])
        # B2: the accelerometer in the inertial frame
        sn = fq.snapshot(self.s)            # s is not changed again in the update
        rm = matrix(sn)
        ai = rotate16(rm, 0, acc)                         # q15 counts
        if first:
            # B5: gravity from the first sample
            self.f = list(ai)
            self.v = [0, 0, 0]
            self.p = [0, 0, k["pg0"]]
        elif has_acc:
            eps = k["eps"]
            # predict: v' = (a - g) / tau_acc, g' = 0 (+ process noise growing with the rate)
            self.v = [ci.add_sat32(self.v[i], ci.scale32_s(ci.sub_sat32(ai[i], self.f[i]),
                                                           eps, 15, 15)) for i in range(3)]
            # e^2 (1 + |w|^2 / rate_ref^2), the rate term capped at 1e4 e^2
            qg = ci.scale32_s(w2 >> 2, k["kq"], 0, 30) if k["kq"].m != 0 else 0
            if qg > k["qcap"]:
                qg = k["qcap"]
            qg = k["qg0"] + qg
            p = self.p
            pe = ci.scale32_s(p[2], eps, 30, 30)                # e pgg
            pvv = ci.add_sat32(ci.sub_sat32(p[0], ci.scale32_s(p[1], eps, 29, 30)),
                               ci.scale32_s(pe, eps, 30, 30))
            pvg = ci.sub_sat32(p[1], pe)
            pgg = ci.add_sat32(p[2], qg)
            # update with the pseudo-measurement v = 0 (noise 1): gains P / (pvv + 1)
            inv = (recip_p8 if p8 else recip)((0 if pvv < 0 else pvv >> 1) + Q29_ONE, 29)
            # the 8-bit profile's in q27: a shift of inv.s + 3 >= 17 (imf_mul_32x16's fast
            # path on AVR); kvs and kgs keep their 15 leading bits
            ng = 27 if p8 else 30
            kv = ci.scale32_s(pvv, inv, 30, ng)
            kg = ci.scale32_s(pvg, inv, 30, ng)
            kvs, sv = scale_of(kv, ng)
            kgs, sg = scale_of(kg, ng)
            for i in range(3):
                self.f[i] = ci.sub_sat32(self.f[i], mul_signed(self.v[i], kgs, sg, 15, 15))
                self.v[i] = ci.sub_sat32(self.v[i], mul_signed(self.v[i], kvs, sv, 15, 15))
            self.p = [ci.sub_sat32(pvv, mul_signed(pvv, kvs, sv, 30, 30)),
                      ci.sub_sat32(pvg, mul_signed(pvg, kvs, sv, 30, 30)),
                      ci.sub_sat32(pgg, mul_signed(pvg, kgs, sg, 30, 30))]
        # inclination: the smallest rotation r that turns the gravity estimate onto earth
        # z, (1 + u_z, u_y, -u_x, 0) normalised for the unit gravity u in the earth frame
        ss = fq.snapshot(self.c)
        if p8:
            # 8-bit profile: f narrowed to int16 (its largest at most 2^14), rotated by R(c)
            # and rounded to f's format, the unit vector of its 15 leading bits (unit3_p8);
            # c += d (x) c with d = r - 1 in 16-bit
            # products. For u_z >= 0, r = (1 + u_z, u_y, -u_x) / 2, not normalised (the
            # normalisation of c takes it: the same direction); below (turned over), r
            # normalised with 1 + u_z from its product with 1 - u_z (below). B3 takes 2 (r1,
            # r2): (u_y, -u_x) for the first, the doubled r for the second.
            f16 = narrow_p8(self.f, exponent_p8(self.f) + 1)
            g16 = [ci.sat_q15s(ci.rshr32(v, 15)) for v in rotate16(matrix(ss), 0, f16)]
            u = fq.unit3_p8(g16)
            d = [0, 0, 0, 0]
            r = [0, 0, 0]
            hs = 0
            if u is not None:
                if u[2] >= 0:
                    d = [u[2] - 32768, u[1], -u[0], 0]   # [-32768, -1] first
                    r = [0, u[1], -u[0]]
                    hs = 1                               # d is twice r - 1
                else:
                    # turned over (the first samples only: c takes the whole r): r = (1 + u_z,
                    # u_y, -u_x) normalised, as the direction of its product with 1 - u_z,
                    # (u_x^2 + u_y^2, u_y (1 - u_z), -u_x (1 - u_z)) in q30, narrowed to its
                    # 15 leading bits; (0, 1, 0) where it is 0 (exactly upside down)
                    w = 32768 - u[2]                     # 1 - u_z, (2^15, 2^16)
                    ge = [u[0] * u[0] + u[1] * u[1], u[1] * w, -(u[0] * w)]
                    r = fq.unit3_p8(narrow_p8(ge, exponent_p8(ge))) or [0, 32767, 0]
                    d = [r[0] - 32768, r[1], r[2], 0]
                    r = [r[0], ci.sat_q15s(2 * r[1]), ci.sat_q15s(2 * r[2])]
            t = qmul_p8(d, ss)
            self.c = renorm_p8([ci.add_sat32(self.c[i], ci.rshr32(t[i], hs)) for i in range(4)])
            # |q|^2 - 1: c's and the snapshots' rounding
            self.q = qmul_p8(fq.snapshot(self.c), sn)
        else:
            ge = rotate(matrix(ss), 0, self.f)
            u = unit(ge)
            if u is not None:
                # gravity straight down (upside down): the half turn about x
                r = half(u[2], u[1], -u[0])
            else:
                # no gravity estimate (a zero vector): no correction
                r = [32767, 0, 0]
            r.append(0)
            self.c = renorm(qmul(r, self.c))
            self.q = renorm(qmul(fq.snapshot(self.c), self.s))
        # B3: the correction rate seen in the sensor frame is minus the bias error
        # (Eq. 3.6, with Ki dt = 1 / tau_bias): b -= R(q)^T (2 r1, 2 r2, 0) / tau_bias
        if not rest and self.n >= k["n_acc"] and k["kbias"].m != 0:
            rm = matrix(fq.snapshot(self.q))   # its first two rows (the C computes only those)
            e = rotate16(rm, 1, [r[1], r[2], 0])   # R^T r in q30; the error is twice that
            if p8:
                # 8-bit profile: R^T 2 r in q15 (2 r is q15) times kbias, one 16x16 product
                kb = k["kbias"]
                self.b = [ci.sub_sat32(self.b[i],
                                       shift_p8(ci.sat_q15s(ci.rshr32(e[i], 15)) * kb.m, kb.s))
                          for i in range(3)]          # ci.scale16's value
            else:
                self.b = [ci.sub_sat32(self.b[i], ci.scale32_s(ci.add_sat32(e[i], e[i]),
                                                               k["kbias"], 30, 15))
                          for i in range(3)]
        return True

    def _finish(self, gyr):
        # robust_q_finish: the end of every update, the output predicted by the latency
        # with the bias-corrected rate, then the clock of the start-up (saturating)
        k = self.k
        if k["klat"].m != 0:
            integrate(k["profile"] == 8, self.q, gyr, self.b, k["klat"])
        if self.n < k["n_max"]:
            self.n += 1


def _mag_test(k, mn, hn, zn, n, h, z):
    """robust_q_mag_test: the field matches the reference (n, h, z): norm within mag_norm
    n and dip within mag_dip (the sine of the dip difference: zn h - hn z, q30)."""
    dn = ci.sub_sat32(mn, n)
    tn = ci.scale32_s(n, k["knorm"], 15, 15)
    dd = zn * ci.qn_to_q15s(h, 30) - hn * ci.qn_to_q15s(z, 30)
    return dn < tn and ci.sub_sat32(0, dn) < tn and dd < k["kdip"] and -dd < k["kdip"]


class RobustAHRSQ(RobustIMUQ):
    """imufuse's recommended attitude filter with a magnetometer (RobustAHRS,
    docs/recommended-ahrs.md) in fixed point: RobustIMUQ's blocks and B4, the magnetometer
    confined to heading with its disturbance detector.

    RobustAHRSQ(dt, <RobustAHRS's keywords up to mag_hold, the same units>,
    mag_learn=False, gyr_scale=rad/s per count, profile="32"). The magnetometer in counts,
    any unit (B4 is relative to its learned reference). B6, the offset learnt while
    turning, is not built: mag_learn=True is refused; the stored offset (counts) is given
    with set_mag_offset. State: RobustIMUQ's, then the offset in use u, the reference
    (rn q15 counts, rh, rz q30) and the candidate (cn, ch, cz), the sample counters n_ok,
    n_dist, n_cand.
    """
    kind = "ahrs"
    c_name = "imf_robust_ahrs_q"
    state_names = RobustIMUQ.state_names + ("ux", "uy", "uz", "rn", "rh", "rz", "cn", "ch",
                                            "cz", "n_ok", "n_dist", "n_cand")

    @staticmethod
    def _params(dt, tau_acc=2.5, rate_ref=100.0, tau_bias=100.0, tau_bias_rest=3.0,
                rest_gyr=2.0, rest_acc=0.05, rest_time=1.5, tau_rest=0.5, latency=0.0,
                tau_mag=10.0, mag_norm=0.1, mag_dip=10.0, tau_mag_ref=20.0, mag_new_time=20.0,
                mag_hold=0.5, mag_learn=False, *, gyr_scale, profile="32"):
        if mag_learn is not False and mag_learn != 0:
            raise ValueError("mag_learn: B6 (the magnetometer offset learnt while turning) is "
                             "not built in fixed point; give the stored offset in counts with "
                             "set_mag_offset (e.g. from RobustAHRS's get_mag_offset on the "
                             "host), and leave mag_learn False")
        imu = RobustIMUQ._params(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr,
                                 rest_acc, rest_time, tau_rest, latency, gyr_scale=gyr_scale,
                                 profile=profile)
        mag = RobustAHRS._params(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr,
                                 rest_acc, rest_time, tau_rest, latency, tau_mag, mag_norm,
                                 mag_dip, tau_mag_ref, mag_new_time, mag_hold, False)[10:16]
        dt = imu[0]
        tau_mag, mag_norm, dip, tau_mag_ref, mag_new_time, mag_hold = mag
        if mag_norm > 1.0:
            raise ValueError(f"mag_norm: must be <= 1 in fixed point, got {mag_norm!r}")
        if mag_norm > 0.0:
            qconst("mag_norm", mag_norm, 14, 47, nonzero=True)
        for name, v in (("tau_mag", tau_mag), ("tau_mag_ref", tau_mag_ref),
                        ("mag_new_time", mag_new_time), ("mag_hold", mag_hold)):
            if _ceil(v / dt) < 0:
                raise ValueError(f"{name}: must be at most 2^30 samples, got {v!r}")
        qconst("dt/(tau_mag+dt)", dt / (tau_mag + dt), 0, 47, nonzero=True)
        qconst("dt/(tau_mag_ref+dt)", dt / (tau_mag_ref + dt), 0, 47, nonzero=True)
        return imu[:10] + mag + (0,) + imu[10:]

    @staticmethod
    def _consts(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc, rest_time,
                tau_rest, latency, tau_mag, mag_norm, mag_dip, tau_mag_ref, mag_new_time,
                mag_hold, mag_learn, gyr_scale, profile):
        # imf_robust_ahrs_q_init: RobustIMUQ's constants and B4's
        imu = RobustIMUQ._consts(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr,
                                 rest_acc, rest_time, tau_rest, latency, gyr_scale, profile)
        n_mag, n_ref = _ceil(tau_mag / dt), _ceil(tau_mag_ref / dt)
        imu["n_max"] = max(imu["n_max"], n_mag, n_ref)
        return dict(imu=imu, k_mag=ci.qscale(dt / (tau_mag + dt)),
                    k_ref=ci.qscale(dt / (tau_mag_ref + dt)), knorm=ci.qscale(mag_norm),
                    kdip=0x7FFFFFFF if mag_dip >= 2.0 else math.floor(mag_dip * 1073741824.0
                                                                       + 0.5),
                    n_mag=n_mag, n_ref=n_ref, n_hold=_ceil(mag_hold / dt),
                    n_new=_ceil(mag_new_time / dt))

    def _init(self, dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc,
              rest_time, tau_rest, latency, tau_mag, mag_norm, mag_dip, tau_mag_ref,
              mag_new_time, mag_hold, mag_learn, gyr_scale, profile):
        self.dt = dt
        self.gyr_scale = gyr_scale
        self.tau_acc = tau_acc
        self._init_consts(**self._consts(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest,
                                         rest_gyr, rest_acc, rest_time, tau_rest, latency,
                                         tau_mag, mag_norm, mag_dip, tau_mag_ref,
                                         mag_new_time, mag_hold, mag_learn, gyr_scale,
                                         profile))

    def _init_consts(self, imu, **k):
        # imf_robust_ahrs_q_init_consts (the ranges were checked by _params)
        RobustIMUQ._init_consts(self, **imu)
        self.km = k
        self.u = [0, 0, 0]
        self.rn = self.rh = self.rz = self.cn = self.ch = self.cz = 0
        self.n_ok = self.n_dist = self.n_cand = 0

    @staticmethod
    def _offset_counts(offset):
        # (x, y, z) int16 counts, or ValueError naming the component
        try:
            values = tuple(offset)
        except TypeError:
            raise ValueError(f"mag offset: expected (x, y, z) in counts, got {offset!r}") from None
        if len(values) != 3:
            raise ValueError(f"mag offset: expected 3 values (x, y, z), got {len(values)}")
        out = []
        for n, v in zip("xyz", values):
            try:
                ok = (not isinstance(v, (bool, str)) and float(v).is_integer()
                      and -32768 <= v <= 32767)
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(f"mag offset {n}: expected an int16 count (the offset in the "
                                 f"magnetometer's counts, as its readings), got {v!r}")
            out.append(int(v))
        return tuple(out)

    def set_mag_offset(self, offset):
        """imf_robust_ahrs_q_set_mag_offset: the stored offset (hard iron), magnetometer
        counts (x, y, z) in the sensor frame, used from the next sample. reset() clears it
        (as the C init does): set it again after a reset."""
        self.u = list(self._offset_counts(offset))

    def _get_state(self):
        return (super()._get_state() + self.u
                + [self.rn, self.rh, self.rz, self.cn, self.ch, self.cz,
                   self.n_ok, self.n_dist, self.n_cand])

    def _set_state(self, v):
        v = list(v)
        super()._set_state(v[:32])
        self.u = v[32:35]
        self.rn, self.rh, self.rz, self.cn, self.ch, self.cz = v[35:41]
        self.n_ok, self.n_dist, self.n_cand = v[41:44]

    def _state_float(self, s):
        q30, q15 = 2.0 ** -30, 2.0 ** -15
        return (super()._state_float(s[:32]) + list(s[32:35])
                + [s[35] * q15, s[36] * q30, s[37] * q30, s[38] * q15, s[39] * q30,
                   s[40] * q30] + list(s[41:]))

    def _update(self, gyr, acc, mag):
        if self._step(gyr, acc):
            self._mag(mag)
            self._finish(gyr)

    def _mag(self, mag):
        # robust_q_mag: B4, heading from the magnetometer (counts, less the stored offset)
        k = self.km
        if mag[0] == 0 and mag[1] == 0 and mag[2] == 0:
            return                           # no reading: gyro and accelerometer only
        # the reading less the offset in use, counts within +-32767, in the earth frame
        m = [ci.sat_q15s(ci.sub_sat32(mag[i], self.u[i])) for i in range(3)]
        me = rotate16(matrix(fq.snapshot(self.q)), 0, m)    # q15 counts
        p8 = self.k["profile"] == 8
        # the unit vector u; the norm |m| = m . u (q15 counts); the horizontal direction ch;
        # the dip's cosine hn = u . ch and sine u[2]
        if p8:
            # 8-bit profile: u from me's 15 leading bits w (exponent e; unit16_p8),
            # |m| = w . u 2^(e - 15); the horizontal direction from u's (unit16_p8: the half
            # angle of the heading below needs the norm of the 32-bit profile's too)
            e = exponent_p8(me)
            w = narrow_p8(me, e)
            u = unit16_p8(w)
            if u is None:
                return                       # no usable reading: gyro and accelerometer only
            mn = shift_p8(ci.check32(w[0] * u[0] + w[1] * u[1] + w[2] * u[2]), 15 - e)
            ch = unit16_p8([u[0], u[1], 0])
        else:
            u = unit(me)
            if u is None:
                return                       # no usable reading: gyro and accelerometer only
            mn = 0
            for i in range(3):
                mn = ci.add_sat32(mn, fq.mul_hq_p32(me[i], u[i]))
            ch = unit([me[0], me[1], 0])
        hn = ci.qn_to_q15s(u[0] * ch[0] + u[1] * ch[1], 30) if ch is not None else 0
        zn = u[2]
        if self.rn == 0:
            # first reading: it is the reference
            self.rn = self.cn = mn
            self.rh = self.ch = hn * 32768
            self.rz = self.cz = zn * 32768
            self.n_ok = k["n_hold"]
        match = _mag_test(k, mn, hn, zn, self.rn, self.rh, self.rz)
        if not match:
            self.n_ok = 0
        elif self.n_ok < k["n_hold"]:
            self.n_ok += 1
        if match and self.n_ok >= k["n_hold"]:
            self.n_dist = 0
            self.n_cand = 0
            kk = gain(p8, self.n, k["n_ref"], k["k_ref"])
            self.rn = ci.add_sat32(self.rn, ci.scale32_s(ci.sub_sat32(mn, self.rn), kk, 15, 15))
            self.rh = lowpass(self.rh, hn, kk)
            self.rz = lowpass(self.rz, zn, kk)
            self.cn = mn
            self.ch = hn * 32768
            self.cz = zn * 32768
            if ch is None:
                return                       # field vertical: no heading information
            # heading: the rotation about earth z that turns the horizontal field onto
            # north (+x), (1 + cos, 0, 0, -sin) normalised, taken by the fraction k:
            # (1 + k (f_w - 1), k f_z), normalised with c and q
            kk = gain(p8, self.n, k["n_mag"], k["k_mag"])
            if p8:
                # 8-bit profile: (1 + cos, -sin) / 2 normalised by unit3_p8 (within 1.2e-3:
                # the turn's gain); (0, 1) where it is 0, as half()
                f = fq.unit3_p8([(32768 + ch[0]) >> 1, -ch[1] >> 1, 0]) or [0, 32767]
            else:
                f = half(ch[0], -ch[1], 0)
            if p8:
                # 8-bit profile: (dw, dz) = z 2^(15 - kk.s) in q30, z = kk.m (f_w - 1, f_z)
                # 2^-15 rounded; c and q turned, neither normalised here (the next update
                # normalises c and takes q = c (x) s again)
                z16 = [ci.rshr32((f[0] - 32768) * kk.m, 15), ci.rshr32(f[1] * kk.m, 15)]
                self.c = turn_z_p8(self.c, z16, kk.s - 15)
                self.q = turn_z_p8(self.q, z16, kk.s - 15)
            else:
                dz = [ci.scale32_s(f[0] - 32768, kk, 15, 30), ci.scale32_s(f[1], kk, 15, 30)]
                self.c = turn_z(self.c, dz[0], dz[1])
                self.q = turn_z(self.q, dz[0], dz[1])
        else:
            # disturbed (or not yet matching for mag_hold): no heading correction; a new
            # field that stays the same for mag_new_time of motion becomes the reference
            if self.n_dist < 1073741824:
                self.n_dist += 1
            if _mag_test(k, mn, hn, zn, self.cn, self.ch, self.cz):
                kr = self.k["k_rest"]
                self.cn = ci.add_sat32(self.cn, ci.scale32_s(ci.sub_sat32(mn, self.cn), kr,
                                                             15, 15))
                self.ch = lowpass(self.ch, hn, kr)
                self.cz = lowpass(self.cz, zn, kr)
                if self.n_rest < self.k["n_rest"] and self.n_cand < k["n_new"]:
                    # only motion counts: at rest an attached magnet's field is steady too
                    self.n_cand += 1
                if self.n_cand >= k["n_new"]:
                    self.rn, self.rh, self.rz = self.cn, self.ch, self.cz
                    self.n_cand = 0
            else:
                self.cn = mn
                self.ch = hn * 32768
                self.cz = zn * 32768
                self.n_cand = 0
