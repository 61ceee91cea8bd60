/* The helpers of the fixed-point RobustIMU and RobustAHRS (robust_q.h) shared by both
 * profiles, and the 32-bit profile's: private to csrc/fixed/robust_q.c, which includes this
 * file once (static functions, one translation unit: the filter is one source for the
 * harnesses). Mirrored line for line by python/imufuse/reference/fixed_robust_ops.py.
 *
 * The helpers called more than once are out of line on every target (IMF_Q_NOINLINE):
 * their inlined copies made the Cortex-M0 build larger than the float filter's. */
#ifndef IMF_ROBUST_Q_OPS_H
#define IMF_ROBUST_Q_OPS_H

#include "imf_fixed_quat.h"
#include "robust_q8.h"

/* 2^N / x as a q-scale for x > 0: 1 / x = y^2 2^-2sh (imf_invsqrt_u32, relative error
 * below 2e-4), the square rounded to 15 bits. */
static IMF_Q_NOINLINE imf_qscale_t robust_q_recip(const uint32_t x, const int N)
{
    imf_qscale_t r;
    int sh, s;
    const uint16_t y = imf_invsqrt_u32(x, &sh);
    const uint32_t p = imf_mulu16(y, y); /* in [2^30, 2^32) */
    uint32_t m;
    if (p >= 2147483648u) {
        m = (uint32_t)((uint16_t)((p + 65536u) >> 16) >> 1); /* no carry out: p < 2^32 - 2^17 */
        s = 2 * sh - N - 17;
    } else {
        m = (p + 32768u) >> 16;
        s = 2 * sh - N - 16;
    }
    if (m >= 32768u) {
        /* the rounding reached 2^15 */
        m = 16384u;
        s--;
    }
    r.m = (int16_t)m;
    r.s = (int16_t)s;
    return r;
}

#if IMF_Q_HAS_P8
#define ROBUST_Q_RECIP(p8, x, N) ((p8) ? robust_q_recip_p8((x), (N)) : robust_q_recip((x), (N)))
#else
#define ROBUST_Q_RECIP(p8, x, N) robust_q_recip((x), (N))
#endif

/* |x| 2^-N (x in qN) as a q-scale and its sign (1, or -1): the 15 leading bits of |x|,
 * rounded. x = 0 gives m 0 (its s is N). */
static IMF_Q_NOINLINE imf_qscale_t robust_q_scale_of(const int32_t x, const int N, int *const sign)
{
    imf_qscale_t r;
    uint32_t u = x < 0 ? 0u - (uint32_t)x : (uint32_t)x, t = u;
    uint16_t v;
    int e = 0;
    *sign = x < 0 ? -1 : 1;
    /* e: the shift that brings u below 2^15 (at most 17); on AVR a byte at a time first
       (byte moves; the same e) */
#if defined(__AVR__)
    while (t >= 8388608u) {
        t >>= 8;
        e += 8;
    }
#endif
    while (t >= 32768u) {
        t >>= 1;
        e++;
    }
    if (e > 0) {
        u = imf_lsr32(u + imf_lsl32(1u, e - 1), e); /* u + 2^(e-1) <= 2^31 + 2^16 */
        if (u >= 32768u) {
            u >>= 1;
            e++;
        }
    }
    v = (uint16_t)u; /* < 2^15 */
    while (v != 0u && v < 16384u) {
        v = (uint16_t)(v << 1);
        e--;
    }
    r.m = (int16_t)v;
    r.s = (int16_t)(N - e);
    return r;
}

/* x times a signed q-scale (sign, c) from qK to qN: x c 2^(N-K), rounded, saturated */
static inline int32_t robust_q_mul_signed(const int32_t x, const imf_qscale_t c, const int sign,
                                          const int K, const int N)
{
    const int32_t p = imf_scale32_s(x, c, K, N);
    return sign < 0 ? imf_sub_sat32(0, p) : p;
}

/* The rotation matrix of a q15 snapshot qs (sensor -> earth), q15, by rows:
 * diagonal 2 (w^2 + a^2) - 1, the others 2 (a b -+ w c), in q29 -> q15; for rows = 2 its
 * first two rows only, the third 0 (B3's R^T (x, y, 0): the same values) */
static IMF_Q_NOINLINE void robust_q_matrix(const int16_t qs[4], int16_t r[9], const int rows)
{
    /* each product once (avr-gcc does not merge the repeated inline ones) */
    const int32_t ww = imf_mul16(qs[0], qs[0]), ab = imf_mul16(qs[1], qs[2]);
    const int32_t wc = imf_mul16(qs[0], qs[3]), ac = imf_mul16(qs[1], qs[3]);
    const int32_t wb = imf_mul16(qs[0], qs[2]), bc = imf_mul16(qs[2], qs[3]);
    const int32_t wa = imf_mul16(qs[0], qs[1]);
    r[0] = imf_qn_to_q15s(ww + imf_mul16(qs[1], qs[1]) - 536870912L, 29);
    r[4] = imf_qn_to_q15s(ww + imf_mul16(qs[2], qs[2]) - 536870912L, 29);
    r[1] = imf_qn_to_q15s(ab - wc, 29);
    r[3] = imf_qn_to_q15s(ab + wc, 29);
    r[2] = imf_qn_to_q15s(ac + wb, 29);
    r[5] = imf_qn_to_q15s(bc - wa, 29);
    if (rows == 3) {
        r[6] = imf_qn_to_q15s(ac - wb, 29);
        r[7] = imf_qn_to_q15s(bc + wa, 29);
        r[8] = imf_qn_to_q15s(ww + imf_mul16(qs[3], qs[3]) - 536870912L, 29);
    } else {
        r[6] = r[7] = r[8] = 0;
    }
}

/* out = R v (t = 0) or R^T v (t = 1) for int32 v in any format (the same format out),
 * products rounded, sums saturated */
static IMF_Q_NOINLINE void robust_q_rotate(const int16_t r[9], const int t, const int32_t v[3],
                                           int32_t out[3])
{
#if defined(__AVR__)
    /* AVR: the same sums unrolled over the rows of R or R^T */
    const int d = t ? 3 : 1; /* R^T's row i is R's column i */
    int i;
    for (i = 0; i < 3; ++i) {
        const int16_t *const m = r + (t ? i : 3 * i);
        out[i] =
            imf_add_sat32(imf_add_sat32(imf_q_mul_hq_p32(v[0], m[0]), imf_q_mul_hq_p32(v[1], m[d])),
                          imf_q_mul_hq_p32(v[2], m[2 * d]));
    }
#else
    int i, j;
    for (i = 0; i < 3; ++i) {
        int32_t a = 0;
        for (j = 0; j < 3; ++j) {
            a = imf_add_sat32(a, imf_q_mul_hq_p32(v[j], r[t ? 3 * j + i : 3 * i + j]));
        }
        out[i] = a;
    }
#endif
}

/* out = R v (t = 0) or R^T v (t = 1) for an int16 v: one 16x16 product per term (q15 R
 * times v, in v's format times 2^15), sums saturated */
static IMF_Q_NOINLINE void robust_q_rotate16(const int16_t r[9], const int t, const int16_t v[3],
                                             int32_t out[3])
{
#if defined(__AVR__)
    /* AVR: the same sums unrolled over the rows of R or R^T */
    const int d = t ? 3 : 1; /* R^T's row i is R's column i */
    int i;
    for (i = 0; i < 3; ++i) {
        const int16_t *const m = r + (t ? i : 3 * i);
        out[i] = imf_add_sat32(imf_add_sat32(imf_mul16(v[0], m[0]), imf_mul16(v[1], m[d])),
                               imf_mul16(v[2], m[2 * d]));
    }
#else
    int i, j;
    for (i = 0; i < 3; ++i) {
        int32_t a = 0;
        for (j = 0; j < 3; ++j) {
            a = imf_add_sat32(a, imf_mul16(v[j], r[t ? 3 * j + i : 3 * i + j]));
        }
        out[i] = a;
    }
#endif
}

/* q /= |q|: while |q|^2 - 1 is small (every ordinary update: q is a product or a series
 * step of unit quaternions), the first-order q (1 - d / 2), d = |q|^2 - 1 from
 * imf_q_norm2, one product per component; else the full imf_q_normalise */
static IMF_Q_NOINLINE void robust_q_renorm(int32_t q[4])
{
    int16_t qs[4];
    uint32_t n2;
    int i;
    imf_q_snapshot(q, qs);
    n2 = imf_q_norm2(q, qs);
    if (n2 > 1072693248u && n2 < 1074790400u) {
        /* |d| < 2^-10 (q30: 2^20) */
        const int32_t d = (int32_t)n2 - 1073741824L;
        for (i = 0; i < 4; ++i) {
            q[i] = imf_sub_sat32(q[i], imf_q_mul_hq_p32(imf_rshr32(d, 1), qs[i]));
        }
        return;
    }
    imf_q_normalise(q);
}

/* out = a (x) b, a a q15 snapshot, b q30: out_i = sum_j +-a_j b_{robust_q_bi[i][j]}, the
 * minus signs in robust_q_neg[i] (bit j); products rounded, sums saturated in j's order. A
 * loop: one inlined product (flash on the Cortex-M0) */
#if !defined(__AVR__)
static const unsigned char robust_q_bi[4][4] = {
    { 0, 1, 2, 3 }, { 1, 0, 3, 2 }, { 2, 3, 0, 1 }, { 3, 2, 1, 0 }
};
static const unsigned char robust_q_neg[4] = { 14u, 8u, 2u, 4u };
#endif

static IMF_Q_NOINLINE void robust_q_mul(const int16_t a[4], const int32_t b[4], int32_t out[4])
{
#if defined(__AVR__)
/* AVR: the same sums unrolled (the loop's indexing and tests cost a third of its cycles);
 * a zero term of a is skipped as in the loop (its product is 0: the same value) */
#define ROBUST_Q_P(x, y) (a[y] != 0 ? imf_q_mul_hq_p32(b[x], a[y]) : 0)
    out[0] = imf_sub_sat32(
        imf_sub_sat32(imf_sub_sat32(ROBUST_Q_P(0, 0), ROBUST_Q_P(1, 1)), ROBUST_Q_P(2, 2)),
        ROBUST_Q_P(3, 3));
    out[1] = imf_sub_sat32(
        imf_add_sat32(imf_add_sat32(ROBUST_Q_P(1, 0), ROBUST_Q_P(0, 1)), ROBUST_Q_P(3, 2)),
        ROBUST_Q_P(2, 3));
    out[2] = imf_add_sat32(
        imf_add_sat32(imf_sub_sat32(ROBUST_Q_P(2, 0), ROBUST_Q_P(3, 1)), ROBUST_Q_P(0, 2)),
        ROBUST_Q_P(1, 3));
    out[3] = imf_add_sat32(
        imf_sub_sat32(imf_add_sat32(ROBUST_Q_P(3, 0), ROBUST_Q_P(2, 1)), ROBUST_Q_P(1, 2)),
        ROBUST_Q_P(0, 3));
#undef ROBUST_Q_P
#else
    int i, j;
    for (i = 0; i < 4; ++i) {
        int32_t t = 0;
        for (j = 0; j < 4; ++j) {
            int32_t p;
            if (a[j] == 0) {
                continue; /* a zero term (r's last component): the same sum */
            }
            p = imf_q_mul_hq_p32(b[robust_q_bi[i][j]], a[j]);
            t = (robust_q_neg[i] >> j) & 1u ? imf_sub_sat32(t, p) : imf_add_sat32(t, p);
        }
        out[i] = t;
    }
#endif
}

/* q = q (x) exp(h), h the half angle (q30): the series of csrc/robust.c,
 * (1 - |h|^2 / 2, h (1 - |h|^2 / 6)), then normalised */
static IMF_Q_NOINLINE void robust_q_exp(int32_t q[4], const int32_t h[3])
{
    int16_t qs[4], hs[3];
    int32_t hv[4], dq[4], n6;
    uint32_t n2 = 0u;
    int i;
    for (i = 0; i < 3; ++i) {
        hs[i] = imf_qn_to_q15s(h[i], 30);
        n2 += (uint32_t)imf_mul16(hs[i], hs[i]); /* three squares < 2^32 */
    }
    if (n2 > 1073741824u) {
        n2 = 1073741824u; /* |h|^2 <= 1, q30 */
    }
    n6 = imf_q_mul_hq_p32((int32_t)n2, 5461); /* |h|^2 / 6 */
    hv[0] = 0;
    for (i = 0; i < 3; ++i) {
        hv[i + 1] = imf_sub_sat32(h[i], imf_q_mul_hq_p32(n6, hs[i]));
    }
    imf_q_snapshot(q, qs);
    /* q (x) (0, h (1 - |h|^2 / 6)): the same values either way; on AVR without the four
       products by zero (cycles), elsewhere through robust_q_mul's loop (flash) */
#if defined(__AVR__)
    imf_q_rate_p32(qs, hv + 1, dq);
#else
    robust_q_mul(qs, hv, dq);
#endif
    for (i = 0; i < 4; ++i) {
        dq[i] = imf_sub_sat32(dq[i], imf_q_mul_hq_p32((int32_t)(n2 >> 1), qs[i]));
    }
    for (i = 0; i < 4; ++i) {
        q[i] = imf_add_sat32(q[i], dq[i]);
    }
    robust_q_renorm(q);
}

/* B5: a running mean until n reaches n_tau, then the low-pass gain k (a negative n,
 * possible only from a state written by hand, counts as 0) */
static inline imf_qscale_t robust_q_gain(const int p8, const int32_t n, const int32_t n_tau,
                                         const imf_qscale_t k)
{
    if (n < n_tau) {
        return ROBUST_Q_RECIP(p8, (uint32_t)(n < 0 ? 0 : n) + 1u, 0);
    }
    (void)p8;
    return k;
}

/* x += k (u 2^15 - x) for a counts u and x in q15 counts */
static IMF_Q_NOINLINE int32_t robust_q_lowpass(const int32_t x, const int16_t u,
                                               const imf_qscale_t k)
{
    return imf_add_sat32(x, imf_scale32_s(imf_sub_sat32(imf_x32768(u), x), k, 15, 15));
}

/* robust_q_lowpass for the three components of x and u */
static IMF_Q_NOINLINE void robust_q_lowpass3(int32_t x[3], const int16_t u[3], const imf_qscale_t k)
{
    int i;
    for (i = 0; i < 3; ++i) {
        x[i] = imf_add_sat32(x[i], imf_scale32_s(imf_sub_sat32(imf_x32768(u[i]), x[i]), k, 15, 15));
    }
}

/* q15 counts -> counts, rounded, saturated symmetric to +-32767 */
static inline int32_t robust_q_counts(const int32_t x)
{
    return imf_qn_to_q15s(x, 30);
}

/* sum of the squares of three int32 values each within +-32767 (< 2^32) */
static IMF_Q_NOINLINE uint32_t robust_q_norm2(const int16_t a, const int16_t b, const int16_t c)
{
    return (uint32_t)imf_mul16(a, a) + (uint32_t)imf_mul16(b, b) + (uint32_t)imf_mul16(c, c);
}

/* |v|^2 in counts^2 of a vector in q15 counts, each component rounded to counts first */
static IMF_Q_NOINLINE uint32_t robust_q_norm2_counts(const int32_t v[3])
{
    return robust_q_norm2((int16_t)robust_q_counts(v[0]), (int16_t)robust_q_counts(v[1]),
                          (int16_t)robust_q_counts(v[2]));
}

#if IMF_Q_HAS_P32
/* the unit vector of v (any format), symmetric q15; 0 for the zero vector */
static IMF_Q_NOINLINE int robust_q_unit(const int32_t v[3], int16_t u[3])
{
    uint32_t m = 0u;
    int16_t w[3];
    int k = 0, i;
    for (i = 0; i < 3; ++i) {
        const uint32_t a = v[i] < 0 ? 0u - (uint32_t)v[i] : (uint32_t)v[i];
        m = a > m ? a : m;
    }
    while (m > 32767u) { /* k: the shift that brings the largest below 2^15 */
        m >>= 1;
        k++;
    }
    for (i = 0; i < 3; ++i) {
        w[i] = imf_sat_q15s(imf_rshr32(v[i], k));
    }
    return imf_q_normalise_acc(w, u);
}

/* 1 + c in q15 for a unit (c, a, b) in q15 with c < 0, as (a^2 + b^2) / (1 - c) (no
 * difference of nearly equal numbers near c = -1; (a, b)'s norm error scales it by at most
 * half of it), saturated to 32767 */
static IMF_Q_NOINLINE uint16_t robust_q_one_plus(const int16_t c, const int16_t a, const int16_t b)
{
    const uint32_t n2 = (uint32_t)imf_mul16(a, a) + (uint32_t)imf_mul16(b, b); /* q30 */
    const imf_qscale_t rd = robust_q_recip((uint32_t)(32768L - c), 15);        /* 1 / (1 - c) */
    const uint32_t w =
        imf_lsr32(imf_mulu16((uint16_t)imf_sat_q15s((int32_t)(n2 >> 15)), (uint16_t)rd.m), rd.s);
    return (uint16_t)(w > 32767u ? 32767u : w);
}

/* (1 + c, a, b) normalised, symmetric q15, for a unit (c, a, b) in q15: the rotation
 * half way to the one that turns the direction (c, .) onto the axis. Where it is 0
 * (c = -1: turned over), (0, 1, 0): any half turn is a smallest rotation; this one. */
static IMF_Q_NOINLINE void robust_q_half(const int16_t c, const int16_t a, const int16_t b,
                                         int16_t r[3])
{
    /* 1 + c in [0, 65535]; below c = 0 from (a^2 + b^2) / (1 - c) (robust_q_one_plus) */
    const uint32_t rw = c < 0 ? robust_q_one_plus(c, a, b) : (uint32_t)(32768L + c);
    const uint32_t n2 = (imf_mulu16((uint16_t)rw, (uint16_t)rw) >> 2)
                        + ((uint32_t)imf_mul16(a, a) >> 2)
                        + ((uint32_t)imf_mul16(b, b) >> 2); /* q28 */
    if (n2 != 0u) {
        int sh;
        const uint16_t y = imf_invsqrt_u32(n2, &sh); /* 1/|r| = y 2^(14 - sh) */
        const uint32_t r0 = (imf_mulu16((uint16_t)rw, y) + ((uint32_t)1 << (sh - 15))) >> (sh - 14);
        r[0] = (int16_t)(r0 > 32767u ? 32767u : r0);
        r[1] = imf_sat_q15s(imf_rshr32(imf_mul16su(a, y), sh - 14));
        r[2] = imf_sat_q15s(imf_rshr32(imf_mul16su(b, y), sh - 14));
    } else {
        r[0] = 0;
        r[1] = 32767;
        r[2] = 0;
    }
}
#endif

/* q = (1 + dw, 0, 0, dz) (x) q, a turn about earth z (dw, dz q30, small but any), then
 * normalised: q_i + dw q_i + dz (-q3, -q2, q1, q0)_i, products of q's q15 snapshot */
static IMF_Q_NOINLINE void robust_q_turn_z(int32_t q[4], const int32_t dw, const int32_t dz)
{
    int16_t qs[4];
    int i;
    imf_q_snapshot(q, qs);
    for (i = 0; i < 4; ++i) {
        const int16_t o = qs[3 - i];
        q[i] = imf_add_sat32(imf_add_sat32(q[i], imf_q_mul_hq_p32(dw, qs[i])),
                             imf_q_mul_hq_p32(dz, i < 2 ? (int16_t)-o : o));
    }
    robust_q_renorm(q);
}

/* the profile given to init: 1 for the 8-bit profile (a constant when one profile is
 * compiled, IMF_FIXED_PROFILE) */
#define ROBUST_Q_IS_P8(k) (IMF_Q_HAS_P8 && (!IMF_Q_HAS_P32 || (k)->profile == 8))

/* q = q (x) exp(h), h = k (g 2^15 - b) in q30 (k the q-scale kg or klat, g counts, b q15
 * counts): the strapdown and the latency's prediction, each profile's; qs: the new q's
 * snapshot */
static void robust_q_integrate(const int p8, int32_t q[4], const int16_t g[3], const int32_t b[3],
                               const imf_qscale_t k, int16_t qs[4])
{
#if IMF_Q_HAS_P8
    if (p8) {
        int16_t hn[3];
        const int e = robust_q_angle_p8(g, b, k, hn);
        robust_q_exp_p8(q, hn, e, qs);
        return;
    }
#endif
#if IMF_Q_HAS_P32
    {
        int32_t h[3];
        int i;
        for (i = 0; i < 3; ++i) {
            h[i] = imf_scale32_s(imf_sub_sat32(imf_x32768(g[i]), b[i]), k, 15, 30);
        }
        robust_q_exp(q, h);
        imf_q_snapshot(q, qs);
    }
#endif
    (void)p8;
}

#endif /* IMF_ROBUST_Q_OPS_H */
