"""The 8-bit profile's helpers of the fixed-point RobustIMU and RobustAHRS: pure-Python twin
of csrc/fixed/robust_q8.h, line for line.

The same blocks with int16 operands: every quaternion product and rotation one 16x16
product a term, a value that is not int16 narrowed first with one exponent for the whole
vector (its 15 leading bits), the normalisation first order in 16-bit products.
"""
from __future__ import annotations

from . import _cint as ci
from . import fixed_quat as fq


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


#: robust_q_normalise_p8's bound on its steps (ROBUST_Q_NORM_STEPS)
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
