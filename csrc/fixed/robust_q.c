/* Fixed-point RobustIMU and RobustAHRS (B4; not B6); see robust_q.h for the Q formats and
 * ranges.
 * Mirrored line for line by python/imufuse/reference/fixed_robust.py; the blocks and
 * their order are those of csrc/robust.c. */
#include <stddef.h>
#include <string.h>
#include "robust_q.h"
#include "imf_fixed_init.h"
#include "imf_fixed_quat.h"

/* ---- helpers ------------------------------------------------------------------- */
/* The helpers called more than once are out of line on every target (IMF_Q_NOINLINE):
 * their inlined copies made the Cortex-M0 build larger than the float filter's. */

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

/* ---- the 8-bit profile's helpers ------------------------------------------------
 * The same blocks with int16 operands: every quaternion product and rotation one 16x16
 * product a term (no 32x16 product), a value that is not int16 narrowed first with one
 * exponent for the whole vector (its 15 leading bits), the normalisation first order in
 * 16-bit products. */

#if IMF_Q_HAS_P8
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

/* ---- init ----------------------------------------------------------------------- */

/* a q-scale constant: 0, or its shift within [smin, smax] */
static int robust_q_ok(const imf_qscale_t c, const int smin, const int smax)
{
    return c.m == 0 || imf_qscale_ok(c, smin, smax);
}

void imf_robust_imu_q_default_settings(imf_robust_imu_q_settings_t *const s)
{
    s->dt = 0.01;
    s->tau_acc = 2.5;
    s->rate_ref = 1.7453292519943295; /* 100 deg/s */
    s->tau_bias = 100.0;
    s->tau_bias_rest = 3.0;
    s->rest_gyr = 0.03490658503988659; /* 2 deg/s */
    s->rest_acc = 0.05;
    s->rest_time = 1.5;
    s->tau_rest = 0.5;
    s->latency = 0.0;
    s->gyr_scale = 1.0642e-3;
    s->profile = 32;
}

/* the IMU constants in range (shifts of imf_scale32_s: kg (gyr_scale dt < 2^-15), klat,
 * eps (e in [1/8192, 1/200]), kq, the low-pass gains, kbias, kacc2) */
static int robust_q_consts_ok(const imf_robust_imu_q_consts_t *const k)
{
    return !(k->kg.m == 0 || !imf_qscale_ok(k->kg, 31, 62) || !robust_q_ok(k->klat, 15, 62)
             || k->eps.m == 0 || !imf_qscale_ok(k->eps, 22, 27) || !robust_q_ok(k->kq, 30, 62)
             || k->k_rest.m == 0 || !imf_qscale_ok(k->k_rest, 0, 47) || k->kb_rest.m == 0
             || !imf_qscale_ok(k->kb_rest, 0, 47) || !robust_q_ok(k->kbias, -15, 32)
             || !imf_qscale_ok(k->kacc2, 14, 47) || k->qg0 < 16 || k->qcap < k->qg0 || k->pg0 <= 0
             || k->n_tau < 0 || k->n_acc < 0 || k->n_rest < 0 || k->n_max < k->n_tau
             || k->n_max < k->n_acc || k->n_max > 1073741824L || !imf_q_profile_ok(k->profile));
}

/* the IMU state at power-up: zero, but the three quaternions the identity (one memset:
 * the stores one by one were 250 bytes of AVR flash) */
static void robust_q_clear(imf_robust_imu_q_state_t *const x)
{
    memset(x, 0, sizeof *x);
    x->q[0] = x->s[0] = x->c[0] = IMF_Q30_ONE;
}

int imf_robust_imu_q_init_consts(imf_robust_imu_q_t *const self,
                                 const imf_robust_imu_q_consts_t *const k)
{
    if (!robust_q_consts_ok(k)) {
        return -1;
    }
    self->k = *k;
    robust_q_clear(&self->x);
    return 0;
}

/* ceil(v) for v in [0, 2^30] (else -1: refused) */
static int32_t robust_q_ceil(const double v)
{
    const double c = ceil(v);
    return (c >= 0.0 && c <= 1073741824.0) ? (int32_t)c : -1;
}

/* the IMU constants from the settings: 0, or -1 for a parameter out of range */
static int robust_q_consts(const imf_robust_imu_q_settings_t *const s,
                           imf_robust_imu_q_consts_t *const kp)
{
    imf_robust_imu_q_consts_t k;
    const double dt = s->dt, gs = s->gyr_scale, e = s->dt / s->tau_acc;
    const double g2 = s->rest_gyr / gs;
    if (!(dt > 0.0) || !(gs > 0.0) || !(s->tau_acc >= 200.0 * dt && s->tau_acc <= 8192.0 * dt)
        || !(s->rate_ref >= 0.0) || !(s->tau_bias == 0.0 || s->tau_bias >= 4.0 * s->tau_acc)
        || !(s->tau_bias_rest > 0.0) || !imf_param_ok(s->rest_gyr, 0.0, 1e30)
        || !imf_param_ok(s->rest_acc, 0.0, 1.0) || !imf_param_ok(s->rest_time, 0.0, 1e30)
        || !(s->tau_rest > 0.0) || !imf_param_ok(s->latency, 0.0, 0.1)
        || !imf_q_profile_ok(s->profile)) {
        return -1;
    }
    k.kg = imf_qscale_from_double(0.5 * gs * dt);
    k.klat = imf_qscale_from_double(0.5 * gs * s->latency);
    k.eps = imf_qscale_from_double(e);
    k.kq = imf_qscale_from_double(
        s->rate_ref > 0.0 ? 4.0 * e * e * (gs / s->rate_ref) * (gs / s->rate_ref) : 0.0);
    k.k_rest = imf_qscale_from_double(dt / (s->tau_rest + dt));
    k.kb_rest = imf_qscale_from_double(dt / (s->tau_bias_rest + dt));
    k.kbias = imf_qscale_from_double(s->tau_bias > 0.0 ? 1.0 / (s->tau_bias * gs) : 0.0);
    k.kacc2 = imf_qscale_from_double(s->rest_acc * s->rest_acc);
    k.qg0 = (int32_t)floor(e * e * 1073741824.0 + 0.5);
    k.qcap = (int32_t)floor(1e4 * e * e * 1073741824.0 + 0.5);
    k.pg0 = (int32_t)floor(e * 1073741824.0 + 0.5);
    k.rest_g2 = g2 * g2 >= 4294967295.0 ? 4294967295u : (uint32_t)ceil(g2 * g2);
    k.n_tau = robust_q_ceil(s->tau_rest / dt);
    k.n_acc = robust_q_ceil(s->tau_acc / dt);
    k.n_rest = robust_q_ceil(s->rest_time / dt);
    k.n_max = k.n_tau > k.n_acc ? k.n_tau : k.n_acc;
    k.profile = s->profile;
    /* a constant of a block that is on must not underflow to 0 (off) */
    if ((s->rate_ref > 0.0 && k.kq.m == 0) || (s->tau_bias > 0.0 && k.kbias.m == 0)
        || (s->latency > 0.0 && k.klat.m == 0) || (s->rest_acc > 0.0 && k.kacc2.m == 0)) {
        return -1;
    }
    *kp = k;
    return 0;
}

int imf_robust_imu_q_init(imf_robust_imu_q_t *const self,
                          const imf_robust_imu_q_settings_t *const s)
{
    imf_robust_imu_q_consts_t k;
    if (robust_q_consts(s, &k) != 0) {
        return -1;
    }
    return imf_robust_imu_q_init_consts(self, &k);
}

/* ---- the update ----------------------------------------------------------------- */

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

/* B1, B2, B3 and B5 of one sample; returns 0 when the sample is not taken (no start
 * without an accelerometer reading), then nothing else runs. rq: NULL, or where the
 * rotation matrix of the new q is written (all three rows, for B4; B3 uses it too) */
static int robust_q_step(const imf_robust_imu_q_consts_t *const k,
                         imf_robust_imu_q_state_t *const x, const int16_t gyr[3],
                         const int16_t acc[3], int16_t *const rq)
{
    const int first = x->n == 0;
    /* an all-zero accelerometer is no reading: gyro only (and no start without one) */
    int has_acc = !(acc[0] == 0 && acc[1] == 0 && acc[2] == 0);
    int16_t ss[4], sn[4], rm[9], u[3], r[4];
    int32_t ai[3], ge[3], t[4], e[3];
    uint32_t w2;
    imf_qscale_t kk;
    int still, rest, b3, i;
    const int p8 = ROBUST_Q_IS_P8(k);
    if (first && !has_acc) {
        return 0;
    }
    if (has_acc && !first) {
        /* a reading beyond 100 times the gravity estimate (100 g) is a shock or a
           hostile value: no reading */
        const uint32_t f2 = robust_q_norm2_counts(x->f);
        const uint32_t an2 = robust_q_norm2(acc[0], acc[1], acc[2]);
        if (f2 < 429497u && an2 > f2 * 10000u) {
            has_acc = 0;
        }
    }
    /* B1: rest detection, low-passes of gyro and accelerometer in the sensor frame */
    kk = robust_q_gain(p8, x->n, k->n_tau, k->k_rest);
    robust_q_lowpass3(x->lw, gyr, kk);
    if (has_acc) {
        robust_q_lowpass3(x->la, acc, kk);
    }
    w2 = robust_q_norm2_counts(x->lw);
    /* at rest: the low-passed and the raw gyro below rest_gyr, the accelerometer within
       rest_acc of its low-pass (each test only where the ones before hold) */
    still = has_acc && w2 < k->rest_g2 && robust_q_norm2(gyr[0], gyr[1], gyr[2]) < k->rest_g2;
    if (still) {
        int16_t lc[3], de[3];
        for (i = 0; i < 3; ++i) {
            /* the accelerometer's difference from its low-pass, counts, within +-32767 */
            lc[i] = (int16_t)robust_q_counts(x->la[i]);
            de[i] = imf_sat_q15s((int32_t)acc[i] - lc[i]);
        }
        still = (int32_t)(robust_q_norm2(de[0], de[1], de[2]) >> 2) < imf_scale32_s(
                    (int32_t)(robust_q_norm2(lc[0], lc[1], lc[2]) >> 2), k->kacc2, 0, 0);
    }
    if (still) {
        if (x->n_rest < k->n_rest) {
            x->n_rest++;
        }
    } else {
        x->n_rest = 0;
    }
    rest = x->n_rest >= k->n_rest;
    if (rest) {
        /* Eq. 3.1: b_k = b_{k-1}, observed directly at rest */
        robust_q_lowpass3(x->b, gyr, k->kb_rest);
    }
    /* strapdown: s = s (x) exp(1/2 (w - b) dt), series as the float filter */
    robust_q_integrate(p8, x->s, gyr, x->b, k->kg, sn); /* and s's snapshot: s is not changed
                                                          again in the update */
    /* B2: the accelerometer in the inertial frame */
    robust_q_matrix(sn, rm, 3);
    robust_q_rotate16(rm, 0, acc, ai); /* q15 counts */
    if (first) {
        /* B5: gravity from the first sample */
        for (i = 0; i < 3; ++i) {
            x->f[i] = ai[i];
            x->v[i] = 0;
        }
        x->p[0] = x->p[1] = 0;
        x->p[2] = k->pg0;
    } else if (has_acc) {
        int32_t qg, pe, pvv, pvg, pgg, kv, kg;
        imf_qscale_t inv, kvs, kgs;
        int sv, sg;
        /* predict: v' = (a - g) / tau_acc, g' = 0 (+ process noise growing with the rate) */
        for (i = 0; i < 3; ++i) {
            x->v[i] = imf_add_sat32(x->v[i],
                                    imf_scale32_s(imf_sub_sat32(ai[i], x->f[i]), k->eps, 15, 15));
        }
        /* e^2 (1 + |w|^2 / rate_ref^2), the rate term capped at 1e4 e^2 */
        qg = k->kq.m != 0 ? imf_scale32_s((int32_t)(w2 >> 2), k->kq, 0, 30) : 0;
        if (qg > k->qcap) {
            qg = k->qcap;
        }
        qg = k->qg0 + qg;
        pe = imf_scale32_s(x->p[2], k->eps, 30, 30); /* e pgg */
        pvv = imf_add_sat32(imf_sub_sat32(x->p[0], imf_scale32_s(x->p[1], k->eps, 29, 30)),
                            imf_scale32_s(pe, k->eps, 30, 30));
        pvg = imf_sub_sat32(x->p[1], pe);
        pgg = imf_add_sat32(x->p[2], qg);
        /* update with the pseudo-measurement v = 0 (noise 1): gains P / (pvv + 1) */
        inv = ROBUST_Q_RECIP(p8, (uint32_t)(pvv < 0 ? 0 : pvv >> 1) + 536870912u, 29);
        {
            /* the 8-bit profile's in q27: a shift of inv.s + 3 >= 17 (imf_mul_32x16's
               fast path on AVR); kvs and kgs keep their 15 leading bits */
            const int ng = p8 ? 27 : 30;
            kv = imf_scale32_s(pvv, inv, 30, ng);
            kg = imf_scale32_s(pvg, inv, 30, ng);
            kvs = robust_q_scale_of(kv, ng, &sv);
            kgs = robust_q_scale_of(kg, ng, &sg);
        }
        for (i = 0; i < 3; ++i) {
            x->f[i] = imf_sub_sat32(x->f[i], robust_q_mul_signed(x->v[i], kgs, sg, 15, 15));
            x->v[i] = imf_sub_sat32(x->v[i], robust_q_mul_signed(x->v[i], kvs, sv, 15, 15));
        }
        x->p[2] = imf_sub_sat32(pgg, robust_q_mul_signed(pvg, kgs, sg, 30, 30));
        x->p[1] = imf_sub_sat32(pvg, robust_q_mul_signed(pvg, kvs, sv, 30, 30));
        x->p[0] = imf_sub_sat32(pvv, robust_q_mul_signed(pvv, kvs, sv, 30, 30));
    }
    /* inclination: the smallest rotation r that turns the gravity estimate onto earth z,
       (1 + u_z, u_y, -u_x, 0) normalised for the unit gravity u in the earth frame */
    imf_q_snapshot(x->c, ss);
#if IMF_Q_HAS_P8
    if (p8) {
        /* 8-bit profile: f narrowed to int16 (its largest at most 2^14), rotated by R(c)
           and rounded to f's format, the unit vector of its 15 leading bits
           (imf_q_unit3_p8); c += d (x) c with d = r - 1 in
           16-bit products. For u_z >= 0, r = (1 + u_z, u_y, -u_x) / 2, not normalised (the
           normalisation of c takes it: the same direction); below (turned over), r
           normalised with 1 + u_z from its product with 1 - u_z (below).
           B3 takes 2 (r1, r2): (u_y, -u_x) for the first, the doubled r for the second. */
        int16_t f16[3], g16[3], d[4];
        int half = 0;
        robust_q_narrow_p8(x->f, 3, robust_q_exponent_p8(x->f, 3) + 1, f16);
        robust_q_matrix(ss, rm, 3);
        robust_q_rotate16(rm, 0, f16, ge); /* |ge| < 2^30 */
        g16[0] = imf_sat_q15s(imf_rshr32(ge[0], 15));
        g16[1] = imf_sat_q15s(imf_rshr32(ge[1], 15));
        g16[2] = imf_sat_q15s(imf_rshr32(ge[2], 15));
        d[0] = d[1] = d[2] = d[3] = 0;
        r[1] = r[2] = 0;
        if (imf_q_unit3_p8(g16, u)) {
            if (u[2] >= 0) {
                d[0] = (int16_t)(u[2] - 32768L); /* [-32768, -1] */
                d[1] = r[1] = u[1];
                d[2] = r[2] = (int16_t)-u[0];
                half = 1; /* d is twice r - 1 */
            } else {
                /* turned over (the first samples only: c takes the whole r): r = (1 +
                   u_z, u_y, -u_x) normalised, as the direction of its product with 1 - u_z,
                   (u_x^2 + u_y^2, u_y (1 - u_z), -u_x (1 - u_z)) in q30 (no difference of
                   nearly equal numbers; u's norm error scales the first by 1.2e-3 at most),
                   narrowed to its 15 leading bits; (0, 1, 0) where it is 0 (exactly upside
                   down: the half turn about x, as robust_q_half) */
                const uint16_t w = (uint16_t)(32768L - u[2]);          /* 1 - u_z, (2^15, 2^16) */
                ge[0] = imf_mul16(u[0], u[0]) + imf_mul16(u[1], u[1]); /* < 2^31 */
                ge[1] = imf_mul16su(u[1], w);                          /* |.| < 2^31 */
                ge[2] = -imf_mul16su(u[0], w);
                robust_q_narrow_p8(ge, 3, robust_q_exponent_p8(ge, 3), r);
                if (!imf_q_unit3_p8(r, r)) {
                    r[0] = 0;
                    r[1] = 32767;
                    r[2] = 0;
                }
                d[0] = (int16_t)(r[0] - 32768L); /* [-32768, -1] */
                d[1] = r[1];
                d[2] = r[2];
                r[1] = imf_sat_q15s(2L * r[1]);
                r[2] = imf_sat_q15s(2L * r[2]);
            }
        }
        robust_q_mul_p8(d, ss, t);
        for (i = 0; i < 4; ++i) {
            x->c[i] = imf_add_sat32(x->c[i], imf_rshr32(t[i], half));
            ss[i] = imf_qn_to_q15s(x->c[i], 30);
        }
        robust_q_renorm_p8(x->c, ss);  /* c's snapshot, then its new one */
        robust_q_mul_p8(ss, sn, x->q); /* |q|^2 - 1: c's and the snapshots' rounding */
    }
#endif
#if IMF_Q_HAS_P32
    if (!p8) {
        robust_q_matrix(ss, rm, 3);
        robust_q_rotate(rm, 0, x->f, ge);
        if (robust_q_unit(ge, u)) {
            /* gravity straight down (upside down): the half turn about x */
            robust_q_half(u[2], u[1], (int16_t)-u[0], r);
        } else {
            /* no gravity estimate (a zero vector): no correction */
            r[0] = 32767;
            r[1] = r[2] = 0;
        }
        r[3] = 0;
        robust_q_mul(r, x->c, t);
        for (i = 0; i < 4; ++i) {
            x->c[i] = t[i];
        }
        robust_q_renorm(x->c);
        imf_q_snapshot(x->c, ss);
        robust_q_mul(ss, x->s, x->q);
        robust_q_renorm(x->q);
    }
#endif
    /* B3: the correction rate seen in the sensor frame is minus the bias error
       (Eq. 3.6, with Ki dt = 1 / tau_bias): b -= R(q)^T (2 r1, 2 r2, 0) / tau_bias */
    b3 = !rest && x->n >= k->n_acc && k->kbias.m != 0;
    if (b3 || rq != NULL) {
        imf_q_snapshot(x->q, ss);
        robust_q_matrix(ss, rq != NULL ? rq : rm, rq != NULL ? 3 : 2);
    }
    if (b3) {
        /* R^T (r1, r2, 0) in q30 (the error is twice that); the 8-bit profile's six products
           inline (the same sums: cycles), the 32-bit profile's by robust_q_rotate16 (flash) */
        const int16_t *const m = rq != NULL ? rq : rm;
        if (p8) {
            for (i = 0; i < 3; ++i) {
                e[i] = imf_mul16(m[i], r[1]) + imf_mul16(m[3 + i], r[2]); /* < 2^31 */
            }
        } else {
            u[0] = r[1];
            u[1] = r[2];
            u[2] = 0;
            robust_q_rotate16(m, 1, u, e);
        }
        for (i = 0; i < 3; ++i) {
#if IMF_Q_HAS_P8
            if (p8) {
                /* 8-bit profile: R^T 2 r in q15 (2 r is q15) times kbias, one 16x16 product */
                x->b[i] = imf_sub_sat32(
                    x->b[i],
                    robust_q_shift_p8(imf_mul16(imf_sat_q15s(imf_rshr32(e[i], 15)), k->kbias.m),
                                      k->kbias.s)); /* imf_scale16's value */
                continue;
            }
#endif
            x->b[i] =
                imf_sub_sat32(x->b[i], imf_scale32_s(imf_add_sat32(e[i], e[i]), k->kbias, 30, 15));
        }
    }
    return 1;
}

/* the end of every update: the output predicted by the latency with the bias-corrected
 * rate, then the clock of the start-up (saturating) */
static void robust_q_finish(const imf_robust_imu_q_consts_t *const k,
                            imf_robust_imu_q_state_t *const x, const int16_t gyr[3])
{
    if (k->klat.m != 0) {
        int16_t qs[4];
        robust_q_integrate(ROBUST_Q_IS_P8(k), x->q, gyr, x->b, k->klat, qs);
    }
    if (x->n < k->n_max) {
        x->n++;
    }
}

void imf_robust_imu_q_update(imf_robust_imu_q_t *const self, const int16_t gyr[3],
                             const int16_t acc[3])
{
    if (robust_q_step(&self->k, &self->x, gyr, acc, NULL)) {
        robust_q_finish(&self->k, &self->x, gyr);
    }
}

/* ---- RobustAHRSQ: B4, the magnetometer confined to heading ------------------------ */

void imf_robust_ahrs_q_default_settings(imf_robust_ahrs_q_settings_t *const s)
{
    imf_robust_imu_q_settings_t m;
    imf_robust_imu_q_default_settings(&m);
    s->dt = m.dt;
    s->tau_acc = m.tau_acc;
    s->rate_ref = m.rate_ref;
    s->tau_bias = m.tau_bias;
    s->tau_bias_rest = m.tau_bias_rest;
    s->rest_gyr = m.rest_gyr;
    s->rest_acc = m.rest_acc;
    s->rest_time = m.rest_time;
    s->tau_rest = m.tau_rest;
    s->latency = m.latency;
    s->tau_mag = 10.0;
    s->mag_norm = 0.1;
    s->mag_dip = 0.17364817766693033; /* sin 10 deg */
    s->tau_mag_ref = 20.0;
    s->mag_new_time = 20.0;
    s->mag_hold = 0.5;
    s->mag_learn = 0;
    s->gyr_scale = m.gyr_scale;
    s->profile = m.profile;
}

int imf_robust_ahrs_q_init_consts(imf_robust_ahrs_q_t *const self,
                                  const imf_robust_ahrs_q_consts_t *const k)
{
    imf_robust_ahrs_q_state_t *const x = &self->x;
    /* the IMU's; mag_norm <= 1; B4's horizons within n_max */
    if (!robust_q_consts_ok(&k->imu) || k->k_mag.m == 0 || !imf_qscale_ok(k->k_mag, 0, 47)
        || k->k_ref.m == 0 || !imf_qscale_ok(k->k_ref, 0, 47) || !robust_q_ok(k->knorm, 14, 47)
        || k->kdip < 0 || k->n_mag < 0 || k->n_ref < 0 || k->n_hold < 0 || k->n_new < 0
        || k->imu.n_max < k->n_mag || k->imu.n_max < k->n_ref) {
        return -1;
    }
    self->k = *k;
    memset(x, 0, sizeof *x);
    robust_q_clear(&x->imu);
    return 0;
}

int imf_robust_ahrs_q_init(imf_robust_ahrs_q_t *const self,
                           const imf_robust_ahrs_q_settings_t *const s)
{
    imf_robust_ahrs_q_consts_t k;
    imf_robust_imu_q_settings_t m;
    const double dt = s->dt;
    m.dt = dt;
    m.tau_acc = s->tau_acc;
    m.rate_ref = s->rate_ref;
    m.tau_bias = s->tau_bias;
    m.tau_bias_rest = s->tau_bias_rest;
    m.rest_gyr = s->rest_gyr;
    m.rest_acc = s->rest_acc;
    m.rest_time = s->rest_time;
    m.tau_rest = s->tau_rest;
    m.latency = s->latency;
    m.gyr_scale = s->gyr_scale;
    m.profile = s->profile;
    if (robust_q_consts(&m, &k.imu) != 0 || !(s->tau_mag > 0.0) || !(s->tau_mag_ref > 0.0)
        || !imf_param_ok(s->mag_norm, 0.0, 1.0) || !imf_param_ok(s->mag_dip, 0.0, 1e30)
        || !imf_param_ok(s->mag_new_time, 0.0, 1e30) || !imf_param_ok(s->mag_hold, 0.0, 1e30)
        || s->mag_learn != 0) {
        return -1;
    }
    k.k_mag = imf_qscale_from_double(dt / (s->tau_mag + dt));
    k.k_ref = imf_qscale_from_double(dt / (s->tau_mag_ref + dt));
    k.knorm = imf_qscale_from_double(s->mag_norm);
    k.kdip = s->mag_dip >= 2.0 ? 2147483647L : (int32_t)floor(s->mag_dip * 1073741824.0 + 0.5);
    k.n_mag = robust_q_ceil(s->tau_mag / dt);
    k.n_ref = robust_q_ceil(s->tau_mag_ref / dt);
    k.n_hold = robust_q_ceil(s->mag_hold / dt);
    k.n_new = robust_q_ceil(s->mag_new_time / dt);
    k.imu.n_max = k.imu.n_max > k.n_mag ? k.imu.n_max : k.n_mag;
    k.imu.n_max = k.imu.n_max > k.n_ref ? k.imu.n_max : k.n_ref;
    if (s->mag_norm > 0.0 && k.knorm.m == 0) {
        return -1;
    }
    return imf_robust_ahrs_q_init_consts(self, &k);
}

void imf_robust_ahrs_q_set_mag_offset(imf_robust_ahrs_q_t *const self, const int16_t offset[3])
{
    int i;
    for (i = 0; i < 3; ++i) {
        self->x.u[i] = offset[i];
    }
}

/* the field matches the reference (n, h, z): norm within mag_norm n and dip within
 * mag_dip (the sine of the dip difference: zn h - hn z, q30) */
static IMF_Q_NOINLINE int robust_q_mag_test(const imf_robust_ahrs_q_consts_t *const k,
                                            const int32_t mn, const int16_t hn, const int16_t zn,
                                            const int32_t n, const int32_t h, const int32_t z)
{
    const int32_t dn = imf_sub_sat32(mn, n);
    const int32_t tn = imf_scale32_s(n, k->knorm, 15, 15);
    const int32_t dd = imf_mul16(zn, imf_qn_to_q15s(h, 30)) - imf_mul16(hn, imf_qn_to_q15s(z, 30));
    return dn < tn && imf_sub_sat32(0, dn) < tn && dd < k->kdip && -dd < k->kdip;
}

/* B4: heading from the magnetometer (counts, less the stored offset); rm: R(q), q15 */
static void robust_q_mag(const imf_robust_ahrs_q_consts_t *const k,
                         imf_robust_ahrs_q_state_t *const xm, const int16_t mag[3],
                         const int16_t rm[9])
{
    imf_robust_imu_q_state_t *const x = &xm->imu;
    int16_t m[3], u[3], ch[3], f[3], hn;
    int32_t me[3], mn = 0;
    imf_qscale_t kk;
    int horiz = 0, match, i;
    const int p8 = ROBUST_Q_IS_P8(&k->imu);
    if (mag[0] == 0 && mag[1] == 0 && mag[2] == 0) {
        return; /* no reading: gyro and accelerometer only */
    }
    /* the reading less the offset in use, counts within +-32767, in the earth frame */
    for (i = 0; i < 3; ++i) {
        m[i] = imf_sat_q15s(imf_sub_sat32(mag[i], xm->u[i]));
    }
    robust_q_rotate16(rm, 0, m, me); /* q15 counts, rm: R(q) from robust_q_step */
    /* the unit vector u; the norm |m| = m . u (q15 counts); the horizontal direction ch; the
       dip's cosine hn = u . ch and sine u[2] */
#if IMF_Q_HAS_P8
    if (p8) {
        /* 8-bit profile: u from me's 15 leading bits w (exponent e; robust_q_unit16_p8),
           |m| = w . u 2^(e - 15) (|w . u| <= |w| < 2^31); the horizontal direction from
           u's (robust_q_unit16_p8: the half angle of the heading below needs the norm of
           the 32-bit profile's too) */
        int16_t w[3];
        const int e = robust_q_exponent_p8(me, 3);
        robust_q_narrow_p8(me, 3, e, w);
        if (!robust_q_unit16_p8(w, u)) {
            return; /* no usable reading: gyro and accelerometer only */
        }
        mn = robust_q_shift_p8(
            imf_mul16(w[0], u[0]) + imf_mul16(w[1], u[1]) + imf_mul16(w[2], u[2]), 15 - e);
        w[0] = u[0];
        w[1] = u[1];
        w[2] = 0;
        horiz = robust_q_unit16_p8(w, ch);
    }
#endif
#if IMF_Q_HAS_P32
    if (!p8) {
        if (!robust_q_unit(me, u)) {
            return; /* no usable reading: gyro and accelerometer only */
        }
        for (i = 0; i < 3; ++i) {
            mn = imf_add_sat32(mn, imf_q_mul_hq_p32(me[i], u[i]));
        }
        me[2] = 0;
        horiz = robust_q_unit(me, ch);
    }
#endif
    hn = horiz ? imf_qn_to_q15s(imf_mul16(u[0], ch[0]) + imf_mul16(u[1], ch[1]), 30) : 0;
    if (xm->rn == 0) {
        /* first reading: it is the reference */
        xm->rn = xm->cn = mn;
        xm->rh = xm->ch = imf_x32768(hn);
        xm->rz = xm->cz = imf_x32768(u[2]);
        xm->n_ok = k->n_hold;
    }
    match = robust_q_mag_test(k, mn, hn, u[2], xm->rn, xm->rh, xm->rz);
    if (!match) {
        xm->n_ok = 0;
    } else if (xm->n_ok < k->n_hold) {
        xm->n_ok++;
    }
    if (match && xm->n_ok >= k->n_hold) {
        xm->n_dist = 0;
        xm->n_cand = 0;
        kk = robust_q_gain(p8, x->n, k->n_ref, k->k_ref);
        xm->rn = imf_add_sat32(xm->rn, imf_scale32_s(imf_sub_sat32(mn, xm->rn), kk, 15, 15));
        xm->rh = robust_q_lowpass(xm->rh, hn, kk);
        xm->rz = robust_q_lowpass(xm->rz, u[2], kk);
        xm->cn = mn;
        xm->ch = imf_x32768(hn);
        xm->cz = imf_x32768(u[2]);
        if (!horiz) {
            return; /* field vertical: no heading information */
        }
        /* heading: the rotation about earth z that turns the horizontal field onto north
           (+x), (1 + cos, 0, 0, -sin) normalised, taken by the fraction k:
           (1 + k (f_w - 1), k f_z), normalised with c and q */
        kk = robust_q_gain(p8, x->n, k->n_mag, k->k_mag);
        {
#if IMF_Q_HAS_P8
            if (p8) {
                /* 8-bit profile: (1 + cos, -sin) / 2 normalised by imf_q_unit3_p8 (within
                   1.2e-3: the turn's gain); (0, 1) where it is 0, as robust_q_half */
                int16_t w[3];
                w[0] = (int16_t)((32768L + ch[0]) >> 1);
                w[1] = (int16_t)(-(int32_t)ch[1] >> 1);
                w[2] = 0;
                if (!imf_q_unit3_p8(w, f)) {
                    f[0] = 0;
                    f[1] = 32767;
                }
            }
#endif
#if IMF_Q_HAS_P32
            if (!p8) {
                robust_q_half(ch[0], (int16_t)-ch[1], 0, f);
            }
#endif
#if IMF_Q_HAS_P8
            if (p8) {
                /* 8-bit profile: (dw, dz) = z 2^(15 - kk.s) in q30, z = kk.m (f_w - 1, f_z)
                   2^-15 rounded (|z| < 2^15); c and q turned, neither normalised here (the
                   next update normalises c and takes q = c (x) s again) */
                int16_t z16[2];
                z16[0] = (int16_t)imf_rshr32(imf_mul16((int16_t)(f[0] - 32768L), kk.m), 15);
                z16[1] = (int16_t)imf_rshr32(imf_mul16(f[1], kk.m), 15);
                robust_q_turn_z_p8(x->c, z16, kk.s - 15);
                robust_q_turn_z_p8(x->q, z16, kk.s - 15);
            }
#endif
#if IMF_Q_HAS_P32
            if (!p8) {
                int32_t dz[2];
                dz[0] = imf_scale32_s((int32_t)f[0] - 32768L, kk, 15, 30);
                dz[1] = imf_scale32_s(f[1], kk, 15, 30);
                robust_q_turn_z(x->c, dz[0], dz[1]);
                robust_q_turn_z(x->q, dz[0], dz[1]);
            }
#endif
        }
    } else {
        /* disturbed (or not yet matching for mag_hold): no heading correction; a new field
           that stays the same for mag_new_time of motion becomes the reference */
        if (xm->n_dist < 1073741824L) {
            xm->n_dist++;
        }
        if (robust_q_mag_test(k, mn, hn, u[2], xm->cn, xm->ch, xm->cz)) {
            const imf_qscale_t kr = k->imu.k_rest;
            xm->cn = imf_add_sat32(xm->cn, imf_scale32_s(imf_sub_sat32(mn, xm->cn), kr, 15, 15));
            xm->ch = robust_q_lowpass(xm->ch, hn, kr);
            xm->cz = robust_q_lowpass(xm->cz, u[2], kr);
            if (x->n_rest < k->imu.n_rest && xm->n_cand < k->n_new) {
                /* only motion counts: at rest an attached magnet's field is steady too */
                xm->n_cand++;
            }
            if (xm->n_cand >= k->n_new) {
                xm->rn = xm->cn;
                xm->rh = xm->ch;
                xm->rz = xm->cz;
                xm->n_cand = 0;
            }
        } else {
            xm->cn = mn;
            xm->ch = imf_x32768(hn);
            xm->cz = imf_x32768(u[2]);
            xm->n_cand = 0;
        }
    }
}

void imf_robust_ahrs_q_update(imf_robust_ahrs_q_t *const self, const int16_t gyr[3],
                              const int16_t acc[3], const int16_t mag[3])
{
    int16_t rq[9];
    if (robust_q_step(&self->k.imu, &self->x.imu, gyr, acc, rq)) {
        robust_q_mag(&self->k, &self->x, mag, rq);
        robust_q_finish(&self->k.imu, &self->x.imu, gyr);
    }
}
