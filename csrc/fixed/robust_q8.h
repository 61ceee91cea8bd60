/* The 8-bit profile's helpers of the fixed-point RobustIMU and RobustAHRS (robust_q.h): private
 * to csrc/fixed/robust_q.c, which includes this file once (static functions, one translation
 * unit: the filter is one source for the harnesses). Mirrored line for line by
 * python/imufuse/reference/fixed_robust_p8.py.
 *
 * The same blocks with int16 operands: every quaternion product and rotation one 16x16
 * product a term (no 32x16 product), a value that is not int16 narrowed first with one
 * exponent for the whole vector (its 15 leading bits), the normalisation first order in
 * 16-bit products. */
#ifndef IMF_ROBUST_Q8_H
#define IMF_ROBUST_Q8_H

#include "imf_fixed_quat.h"

#if IMF_Q_HAS_P8
/* robust_q_recip in the 8-bit profile: a, x's 16 leading bits (x 2^sh in [2^31, 2^32),
 * truncated), z ~= 2^31 / a from a chord (relative error below 1/17) and two Newton steps
 * z <- z (2 - a z 2^-31) in unsigned 16x16 products, z <= 65535 (relative error below
 * 7.1e-5 with the truncations, robust_q_recip's 1.2e-4: tests/test_robust_q.py runs every
 * a); 2^N / x = z 2^(N + sh - 47) */
static IMF_Q_NOINLINE imf_qscale_t robust_q_recip_p8(uint32_t x, const int N)
{
    imf_qscale_t r;
    uint16_t a, z, m;
    int sh = 0, i;
#if defined(__AVR__)
    while (x < 8388608u) { /* below 2^23: a byte at a time (byte moves; the same sh) */
        x <<= 8;
        sh += 8;
    }
#endif
    while (x < 2147483648u) {
        x <<= 1;
        sh++;
    }
    a = (uint16_t)(x >> 16);
    z = (uint16_t)(92521u - (imf_mulu16(a, 61681u) >> 16)); /* 2^15 (48 - 32 a 2^-16) / 17 */
    for (i = 0; i < 2; ++i) {
        const uint32_t w = 0u - imf_mulu16(a, z);              /* 2^32 - a z, a z in (0, 2^32) */
        const uint32_t p = imf_mulu16(z, (uint16_t)(w >> 16)); /* z w 2^-16 */
        if (p >= 2147483648u) {
            z = 65535u;
        } else {
            z = (uint16_t)((uint16_t)((uint16_t)(p >> 16) << 1) | (uint16_t)((uint16_t)p >> 15));
        }
    }
    m = (uint16_t)((uint16_t)(z >> 1) + (z & 1u)); /* z / 2 rounded, in [2^14, 2^15] */
    r.s = (int16_t)(46 - N - sh);
    if (m >= 32768u) {
        m = 16384u;
        r.s--;
    }
    r.m = (int16_t)m;
    return r;
}

/* the exponent that narrows v to int16: the smallest e >= 0 with |v_i| 2^-e < 2^15 for
 * every i (n components) */
static IMF_Q_NOINLINE int robust_q_exponent_p8(const int32_t *const v, const int n)
{
    uint32_t m = 0u;
    int e = 0, i;
    for (i = 0; i < n; ++i) {
        m |= v[i] < 0 ? 0u - (uint32_t)v[i] : (uint32_t)v[i]; /* the top bit of the largest */
    }
#if defined(__AVR__)
    while (m >= 8388608u) { /* 2^23: a byte at a time (byte moves; the same e) */
        m >>= 8;
        e += 8;
    }
#endif
    while (m >= 32768u) {
        m >>= 1;
        e++;
    }
    return e;
}

/* v 2^-e rounded, symmetric int16 (the rounding can reach 2^15: saturated) */
static IMF_Q_NOINLINE void robust_q_narrow_p8(const int32_t *const v, const int n, const int e,
                                              int16_t *const out)
{
    int i;
    for (i = 0; i < n; ++i) {
        out[i] = imf_sat_q15s(imf_rshr32(v[i], e));
    }
}

/* x 2^k saturated, k >= 0 (imf_shl_sat32's value) as k saturating doublings: one compact
 * copy for the 8-bit profile's rare left shifts (the start-up's gains, the latency's
 * large angles, extreme parameters) */
static IMF_Q_NOINLINE int32_t robust_q_shl_p8(int32_t x, int k)
{
    while (k-- > 0) {
        x = imf_add_sat32(x, x);
    }
    return x;
}

/* imf_rshift_sat32 (x 2^-n rounded, saturated) with robust_q_shl_p8's left shifts */
static inline int32_t robust_q_shift_p8(const int32_t x, const int n)
{
    return n >= 0 ? imf_rshr32(x, n) : robust_q_shl_p8(x, -n);
}

/* the 8-bit profile's full normalisation, for |q|^2 - 1 beyond the first-order band (a
 * state set by hand, hostile rates): above it q is halved (rounded: its direction kept);
 * below it, steps q - qs d / 2 with d = |q|^2 - 1 in [-1, 0) in q15 (Newton's for 1 / |q|:
 * 1 + d goes to 1 + d^3 / 4 - 3 d^2 / 4, below 1 and growing by up to 3/2 a step), every
 * component below 1 (its snapshot q's rounding); until |d| < 2^-8: at most 29 steps from
 * any q (the smallest nonzero snapshot), bounded by ROBUST_Q_NORM_STEPS. qs: the new
 * snapshot. A q whose snapshot is zero (set by hand) becomes the identity. The blocks' own
 * operations: no second normalisation (imf_q_normalise_p8) linked. */
#define ROBUST_Q_NORM_STEPS 40
static IMF_Q_NOINLINE void robust_q_normalise_p8(int32_t q[4], int16_t qs[4])
{
    uint32_t n2 = imf_q_norm2(q, qs);
    int i, j;
    for (j = 0; j < ROBUST_Q_NORM_STEPS && (n2 <= 1069547520u || n2 >= 1077936128u); ++j) {
        /* 2^30 -+ 2^22; below: d in q15, saturated to -1 */
        const int16_t d = imf_sat_q15(((int32_t)(n2 >> 1) - (int32_t)536870912) >> 14);
        if (n2 == 0u) {
            q[0] = IMF_Q30_ONE;
            q[1] = q[2] = q[3] = 0;
        }
        for (i = 0; i < 4; ++i) {
            /* |qs d / 2| <= 2^29 (the identity: qs 0 but for its q0, from which d is 0) */
            q[i] =
                n2 >= 1077936128u ? imf_rshr32(q[i], 1) : q[i] - imf_rshr32(imf_mul16(qs[i], d), 1);
            qs[i] = imf_qn_to_q15s(q[i], 30);
        }
        n2 = imf_q_norm2(q, qs);
    }
}

/* q /= |q| as robust_q_renorm, in 16-bit products; qs: q's snapshot, then the new q's: while |d| = ||q|^2 - 1| < 2^-8,
 * q - q d / 2 with d in q22 (int16) times q's q15 snapshot (imf_q_add_step_p8's
 * step); else robust_q_normalise_p8 */
static IMF_Q_NOINLINE void robust_q_renorm_p8(int32_t q[4], int16_t qs[4])
{
    int16_t d16;
    uint32_t n2;
    int i;
    n2 = imf_q_norm2(q, qs);
    if (n2 <= 1069547520u || n2 >= 1077936128u) { /* 2^30 -+ 2^22 */
        robust_q_normalise_p8(q, qs);
        return;
    }
    d16 = (int16_t)imf_rshr32((int32_t)n2 - IMF_Q30_ONE, 8); /* q22, |d| < 2^14 */
    for (i = 0; i < 4; ++i) {
        /* q d / 2 in q30 = qs (q15) d16 (q22) / 2^8 */
        q[i] = imf_sub_sat32(q[i], imf_rshr32(imf_mul16(qs[i], d16), 8));
        qs[i] = imf_qn_to_q15s(q[i], 30);
    }
}

/* the unit vector of an int16 vector w as robust_q_unit: imf_q_unit3_p8 (|u| within
 * 1.2e-3 of 1), then one Newton step on the norm, u + u (1 - |u|^2) / 2 (1 - |u|^2 in
 * q23); 0 for the zero vector */
static IMF_Q_NOINLINE int robust_q_unit16_p8(const int16_t w[3], int16_t u[3])
{
    int16_t d;
    int32_t n2 = 0;
    int i;
    if (!imf_q_unit3_p8(w, u)) {
        return 0;
    }
    for (i = 0; i < 3; ++i) {
        n2 += imf_mul16(u[i], u[i]); /* q30, < 3 2^30 / 2: no overflow */
    }
    d = imf_sat_q15s(imf_rshr32(IMF_Q30_ONE - n2, 7)); /* q23 */
    for (i = 0; i < 3; ++i) {
        u[i] = imf_sat_q15s(u[i] + imf_rshr32(imf_mul16(u[i], d), 24));
    }
    return 1;
}

/* out = a (x) b for q15 a and b, q30: 16x16 products, each component's four summed with
 * saturation in robust_q_mul's order */
static IMF_Q_NOINLINE void robust_q_mul_p8(const int16_t a[4], const int16_t b[4], int32_t out[4])
{
#define ROBUST_Q_P(x, y) imf_mul16(b[x], a[y]) /* |.| <= 2^30 */
    out[0] = imf_sub_sat32(imf_sub_sat32(ROBUST_Q_P(0, 0) - ROBUST_Q_P(1, 1), ROBUST_Q_P(2, 2)),
                           ROBUST_Q_P(3, 3));
    out[1] = imf_sub_sat32(imf_add_sat32(ROBUST_Q_P(1, 0) + ROBUST_Q_P(0, 1), ROBUST_Q_P(3, 2)),
                           ROBUST_Q_P(2, 3));
    out[2] = imf_add_sat32(imf_add_sat32(ROBUST_Q_P(2, 0) - ROBUST_Q_P(3, 1), ROBUST_Q_P(0, 2)),
                           ROBUST_Q_P(1, 3));
    out[3] = imf_add_sat32(imf_sub_sat32(ROBUST_Q_P(3, 0) + ROBUST_Q_P(2, 1), ROBUST_Q_P(1, 2)),
                           ROBUST_Q_P(0, 3));
#undef ROBUST_Q_P
}

/* The half angle h = k (g 2^15 - b) of robust_q_exp_p8 (q30; k the q-scale kg or klat,
 * g counts, b q15 counts) as int16 hn and its exponent e, h = hn 2^e: w = g 2^15 - b
 * narrowed to its 15 leading bits wn (exponent ew), hn = wn k.m 2^-15 rounded, e = ew + 30
 * - k.s. e > 15 (|h| >= 1 rad, the latency's step only) is saturated to 15; e < -16 (|h|
 * below a quarter of q30's LSB) gives h = 0 */
static IMF_Q_NOINLINE int robust_q_angle_p8(const int16_t g[3], const int32_t b[3],
                                            const imf_qscale_t k, int16_t hn[3])
{
    int32_t w[3];
    int e, i;
    for (i = 0; i < 3; ++i) {
        w[i] = imf_sub_sat32(imf_x32768(g[i]), b[i]);
    }
    e = robust_q_exponent_p8(w, 3);
    robust_q_narrow_p8(w, 3, e, hn);
    e += 30 - k.s;
    for (i = 0; i < 3; ++i) {
        /* |hn k.m| < 2^30: |hn| stays below 2^15 */
        hn[i] = (int16_t)imf_rshr32(imf_mul16(hn[i], k.m), 15);
    }
    if (e > 15) {
        for (i = 0; i < 3; ++i) {
            hn[i] = imf_sat_q15s(robust_q_shl_p8(hn[i], e - 15));
        }
        return 15;
    }
    if (e < -16) {
        hn[0] = hn[1] = hn[2] = 0;
        return 0;
    }
    return e;
}

/* q = q (x) exp(h) as robust_q_exp, in 16-bit products, its normalisation folded in
 * (one snapshot): d = |q|^2 - 1 from q's q15 snapshot at the start (robust_q_normalise_p8
 * first if |d| >= 2^-8); h = hn 2^e in q30 (robust_q_angle_p8, e in [-16, 15]); |h|^2 / 2
 * and |h|^2 / 6 in q15 (0 for e < 8: below their q15 LSB); then
 *     q += q (x) (0, h (1 - |h|^2 / 6)) - q (|h|^2 + d) / 2,
 * the product by robust_q_mul_p8 rounded by hs = 15 - e, so q is normalised to first
 * order from the update before (|q|^2 - 1 stays of the order of |h|^4 and the rounding);
 * qs_out: the new q's snapshot */
static IMF_Q_NOINLINE void robust_q_exp_p8(int32_t q[4], const int16_t hn[3], const int e,
                                           int16_t qs_out[4])
{
    int16_t qs[4], hv[4], n2h = 0, n6 = 0, d16 = 0;
    int32_t dq[4];
    uint32_t n2;
    int i;
    imf_q_snapshot(q, qs);
    n2 = imf_q_norm2(q, qs);
    if (n2 <= 1069547520u || n2 >= 1077936128u) { /* 2^30 -+ 2^22 */
        robust_q_normalise_p8(q, qs);
    } else {
        d16 = (int16_t)imf_rshr32((int32_t)n2 - IMF_Q30_ONE, 8); /* q22, |d| < 2^14 */
    }
    if (e >= 8) {
        /* |h|^2 / 2 in q15: the three squares (q(60 - 2e), < 2^32) halved, then
           shifted by 45 - 2e in [15, 29]; capped at 1/2 (|h| <= 1) */
        uint32_t sq = 0u;
        int32_t h2;
        for (i = 0; i < 3; ++i) {
            sq += (uint32_t)imf_mul16(hn[i], hn[i]);
        }
        h2 = imf_rshr32((int32_t)(sq >> 1), 45 - 2 * e);
        n2h = (int16_t)(h2 > 16384 ? 16384 : h2);
        n6 = (int16_t)imf_rshr32(imf_mul16(n2h, 10923), 15); /* |h|^2 / 6 = (|h|^2 / 2) / 3 */
    }
    hv[0] = 0;
    for (i = 0; i < 3; ++i) {
        /* q(30 - e), |.| < 2^15 (the correction 0 for n6 = 0) */
        hv[i + 1] = hn[i];
        if (n6 != 0) {
            hv[i + 1] = (int16_t)(hn[i] - imf_rshr32(imf_mul16(hn[i], n6), 15));
        }
    }
    /* q (x) (0, h) by robust_q_mul_p8, rounded to q30: imf_q_rate_p8's value (the h_0 = 0
       terms add 0 to sums that cannot saturate before them) without its twelve inlined
       products (1 KB of AVR flash, for 60 cycles) */
    robust_q_mul_p8(qs, hv, dq);
    for (i = 0; i < 4; ++i) {
        dq[i] = imf_q_rshr_hs_p8(dq[i], 15 - e);
        /* q (|h|^2 / 2) in q30 from q15 x q15 (0 for n2h = 0: the same sum without the
           product); q d / 2 = qs (q15) d16 (q22) / 2^8 */
        if (n2h != 0) {
            dq[i] = imf_sub_sat32(dq[i], imf_mul16(n2h, qs[i]));
        }
        q[i] = imf_add_sat32(q[i], imf_sub_sat32(dq[i], imf_rshr32(imf_mul16(qs[i], d16), 8)));
        qs_out[i] = imf_qn_to_q15s(q[i], 30);
    }
}

/* robust_q_turn_z in 16-bit products and not normalised (the next update normalises c):
 * (dw, dz) = z 2^-n in q30 (int16 z, n in [-1, 32]), q_i + (qs_i dw + (-q3, -q2, q1,
 * q0)_i dz) from q's q15 snapshot */
static IMF_Q_NOINLINE void robust_q_turn_z_p8(int32_t q[4], const int16_t z[2], const int n)
{
    int16_t qs[4];
    int i;
    imf_q_snapshot(q, qs);
    for (i = 0; i < 4; ++i) {
        const int16_t o = qs[3 - i];
        const int32_t p = imf_mul16(qs[i], z[0]); /* |.| < 2^30: the sum fits */
        q[i] = imf_add_sat32(
            q[i], robust_q_shift_p8(i < 2 ? p - imf_mul16(o, z[1]) : p + imf_mul16(o, z[1]), n));
    }
}
#endif

#endif /* IMF_ROBUST_Q8_H */
