/*
 * imf_fixed_scale.h -- the arithmetic of the single-axis and gravity-vector
 * fixed-point filters (filters_1d_q.c, gravity_q.c), shaped for 8-bit
 * cores.  Mirrored by python/imufuse/reference/fixed_scale.py (same names
 * without the imf_ prefix).  docs/history/fixed-point.md, "Single-axis and
 * gravity-vector filters on AVR", gives the cost and accuracy of each.
 *
 * Same values as imf_fixed.h: imf_mulk16, imf_mulk32, imf_mul32x16k,
 * imf_rshrk, imf_shl_satk return exactly what imf_scale16, imf_scale32,
 * imf_mul_32x16, imf_rshr32, imf_shl_sat32 return (rounded to nearest,
 * ties up, saturated to int32); off AVR they are those functions.  On AVR
 * they get there in small code, because imf_fixed.h's general shifts,
 * inlined, made these filters' updates several KB:
 *   - the common shift (a rounding right shift by 1..31 after the product)
 *     is one out-of-line function, imf_rshr32_avr: byte moves, then at
 *     most 7 single-bit steps;
 *   - every 16x16 partial product is the inline MUL sequence of
 *     imf_mul16 / imf_mulu16 / imf_mul16su (no __mulsi3);
 *   - the rare shifts (saturating left shifts, a 32x16 product whose shift
 *     is below 16) take a short out-of-line path.
 * Defining IMF_SCALE_SHORT selects the AVR code on any target: the host
 * test tests/test_fixed_scale.py compares it with the imf_fixed.h helpers
 * over every shift; the emulated ATmega328P runs of
 * tests/test_mcu_filters.py compare the filters bit for bit.
 *
 * Own values: imf_gain16 / imf_gain16_mul (a gain rounded at init to 16
 * bits with a byte-aligned shift), imf_cross16 (a cross-product component
 * rounded once), imf_invsqrt16_u32 / imf_unit_xy_k (the accelerometer
 * direction), imf_shl_exact32 (a left shift known not to saturate).
 */
#ifndef IMF_FIXED_SCALE_H
#define IMF_FIXED_SCALE_H

#include "imf_fixed.h"

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__)
#define IMF_SCALE_OUTLINE static __attribute__((noinline, unused))
#else
#define IMF_SCALE_OUTLINE static
#endif

#if defined(__AVR__) || defined(IMF_SCALE_SHORT)

/* imf_rshr32's value for n in [1, 31]: floor(floor(x / 2^(n-1)) / 2 + 1/2)
 * = (y + 1) >> 1 = (y >> 1) + (y & 1) for y = floor(x / 2^(n-1)) (the
 * second form without the overflow of y + 1 for y = INT32_MAX). */
IMF_SCALE_OUTLINE int32_t imf_rshr32_avr(int32_t x, int n)
{
    n -= 1;
    while (n >= 8) {
        x >>= 8; /* byte moves */
        n -= 8;
    }
    x >>= n; /* at most 7 bit steps */
    return (x >> 1) + (x & 1);
}

/* imf_shl_sat32's value, k in [0, 31], by k doublings (the rare left
 * shifts: small code): x > (2^31 - 1) / 2 or x < -2^30 before a doubling
 * is exactly the case in which it leaves int32. */
IMF_SCALE_OUTLINE int32_t imf_shl_sat32_avr(int32_t x, int k)
{
    for (; k > 0; --k) {
        if (x > IMF_INT32_MAX / 2) {
            return IMF_INT32_MAX;
        }
        if (x < IMF_INT32_MIN / 2) {
            return IMF_INT32_MIN;
        }
        x += x;
    }
    return x;
}

/* imf_mul_32x16's tail for n in [0, 15]: (m 2^16 + lol) / 2^n rounded,
 * saturated (m the high part, lol in [0, 2^16) the low 16 bits). */
IMF_SCALE_OUTLINE int32_t imf_mulk_low_avr(const int32_t m, const uint16_t lol, const int n)
{
    /* (lol + 2^(n-1)) >> n = ((lol >> (n-1)) + 1) >> 1 for n >= 1, 16-bit */
    const int32_t r =
        (n == 0) ? (int32_t)lol
                 : (int32_t)(((uint16_t)(lol >> (n - 1)) >> 1) + ((uint16_t)(lol >> (n - 1)) & 1u));
    /* m < -2^(15+n), i.e. (m + 1) 2^(16-n) <= -2^31: below INT32_MIN whatever
     * the non-negative low part adds */
    if (imf_shl_sat32_avr(m + 1, 16 - n) == IMF_INT32_MIN) {
        return IMF_INT32_MIN;
    }
    return imf_add_sat32(imf_shl_sat32_avr(m, 16 - n), r);
}

/* imf_rshr32, n in [0, 31] */
static inline int32_t imf_rshrk(const int32_t x, const int n)
{
    return (n >= 1) ? imf_rshr32_avr(x, n) : x;
}

/* imf_shl_sat32, k in [0, 31] */
static inline int32_t imf_shl_satk(const int32_t x, const int k)
{
    return imf_shl_sat32_avr(x, k);
}

/* imf_mul_32x16, n in [0, 47]: the two partial products signed x unsigned
 * (imf_mul16su) and signed x signed, then the shift. */
static inline int32_t imf_mul32x16k(const int32_t a, const int16_t b, const int n)
{
    const int32_t lo = imf_mul16su(b, (uint16_t)((uint32_t)a & 0xFFFFu));
    const int32_t m = imf_mul16((int16_t)(a >> 16), b) + (lo >> 16);
    if (n >= 17) {
        return imf_rshr32_avr(m, n - 16);
    }
    if (n == 16) {
        return m + (int32_t)((uint16_t)lo >> 15);
    }
    return imf_mulk_low_avr(m, (uint16_t)lo, n);
}

static inline int32_t imf_mulk16(const int16_t x, const imf_qscale_t c, const int N)
{
    const int n = c.s - N;
    const int32_t p = imf_mul16(x, c.m);
    if (n >= 1) {
        return imf_rshr32_avr(p, n); /* n <= 31: the callers' init checks */
    }
    return imf_shl_sat32_avr(p, -n);
}

static inline int32_t imf_mulk32(const int32_t x, const imf_qscale_t c, const int K, const int N)
{
    return imf_mul32x16k(x, c.m, c.s + K - N);
}

#else

/* rounding right shift by n in [0, 31]: imf_rshr32 */
static inline int32_t imf_rshrk(const int32_t x, const int n)
{
    return imf_rshr32(x, n);
}

/* x 2^k saturated, k in [0, 31]: imf_shl_sat32 */
static inline int32_t imf_shl_satk(const int32_t x, const int k)
{
    return imf_shl_sat32(x, k);
}

/* a b 2^-n rounded, saturated, n in [0, 47]: imf_mul_32x16 */
static inline int32_t imf_mul32x16k(const int32_t a, const int16_t b, const int n)
{
    return imf_mul_32x16(a, b, n);
}

/* x c 2^N for int16 x: imf_scale16 (shift c.s - N in [-31, 31]). */
static inline int32_t imf_mulk16(const int16_t x, const imf_qscale_t c, const int N)
{
    return imf_scale16(x, c, N);
}

/* x c 2^(N-K) for int32 x in qK: imf_scale32 (shift c.s + K - N in [0, 47]). */
static inline int32_t imf_mulk32(const int32_t x, const imf_qscale_t c, const int K, const int N)
{
    return imf_scale32(x, c, K, N);
}

#endif

/* ---- 16-bit gains (Complementary1DQ) ----------------------------------- */

/* A constant factor g = c 2^(N-K) of the products x (qK) c -> qN of an
 * update, rounded at init to 16 bits with a byte-aligned shift so that the
 * product needs no bit shifts: g ~= m 2^-(16 + 8 j).  With the product's
 * shift n = c.s + K - N >= 15 (g < 1 or c = 1 exactly), j = (n - 15) / 8
 * in [0, 4], d = n - 15 - 8 j in [0, 7] and m = round(2 c.m / 2^d) in
 * [2^8, 2^16): exact for d <= 1, otherwise a relative error below
 * 2^(d - 16), at most 2^-9 (0.2 %).  A shift below 15 (g >= 1) marks
 * j = -2 for g = 1 exactly, else j = -1: the caller takes another path
 * (imf_gain16_mul needs j >= 0). */
typedef struct {
    uint16_t m; /* mantissa, 0 or in [2^8, 2^16) */
    int16_t j;  /* byte shift in [0, 4]; -1, -2: see above */
} imf_gain16_t;

/* A 16-bit gain (m, j) that imf_gain16 gives for g < 1 (j in [0, 4] with
 * m = 0 or m in [2^8, 2^16)) or, if one_ok, for g = 1 exactly (j = -2,
 * m = 0): the check of init_consts, which stores such gains as given. */
static inline int imf_gain16_ok(const uint16_t m, const int j, const int one_ok)
{
    return (j >= 0 && j <= 4 && (m == 0u || m >= 256u)) || (one_ok && j == -2 && m == 0u);
}

/* The gain c as a 16-bit multiplier m and a shift j for products with q(K) values
 * giving q(N) (init only). */
#if defined(__AVR__) || defined(IMF_SCALE_SHORT)
IMF_SCALE_OUTLINE /* init only: one small copy */
#else
static inline
#endif
    imf_gain16_t
    imf_gain16(const imf_qscale_t c, const int K, const int N)
{
    imf_gain16_t g;
    const int d = c.s + K - N - 15;
    unsigned int r, u;
    g.m = 0u;
    if (d < 0) {
        g.j = (int16_t)((d == -1 && c.m == 16384) ? -2 : -1); /* -2: exactly 1 */
        return g;
    }
    /* j = (n - 15) / 8, r = d - 8 j = n - 15 - 8 j; m = 2 c.m 2^-r rounded
     * (imf_rshrk's value, in unsigned 16-bit steps: 2 c.m < 2^16) */
    r = (unsigned int)d % 8u;
    g.j = (int16_t)((unsigned int)d / 8u);
    u = (unsigned int)(uint16_t)c.m * 2u;
    if (r != 0u) {
        u = ((u >> (r - 1u)) + 1u) >> 1;
    }
    g.m = (uint16_t)u;
    return g;
}

/* round(x g) for int32 x, g.j >= 0: h = floor(x m / 2^16) from two 16x16
 * products (|h| < 2^31 - 2^15), then the rounding shift by 8 j from whole
 * bytes: floor(h / 2^(8j)) plus the last dropped bit, bit 7 of the low byte
 * (on AVR no 32-bit shift by 7) (|x g| < |x|: no saturation). */
static inline int32_t imf_gain16_mul(const int32_t x, const imf_gain16_t g)
{
    uint32_t lo;
    int32_t h;
    int i;
    lo = imf_mulu16((uint16_t)((uint32_t)x & 0xFFFFu), g.m);
    h = imf_mul16su((int16_t)(x >> 16), g.m) + (int32_t)(uint16_t)(lo >> 16);
    if (g.j == 0) {
        return h + (int32_t)((uint16_t)lo >> 15);
    }
    for (i = 1; i < g.j; ++i) {
        h >>= 8;
    }
    return (h >> 8) + (int32_t)((uint8_t)h >> 7);
}

/* The gains without a 16-bit form (>= 1): x for a gain of exactly 1,
 * else imf_mulk32; out of line on AVR (rare). */
#if defined(__AVR__) || defined(IMF_SCALE_SHORT)
IMF_SCALE_OUTLINE
#else
static inline
#endif
int32_t imf_gain16_above(const int32_t x, const imf_gain16_t g, const imf_qscale_t c, const int K,
                         const int N)
{
#if defined(__AVR__) || defined(IMF_SCALE_SHORT)
    /* imf_mulk32's value; its shift c.s + K - N is below 15 here (g.j < 0)
     * and not negative (the callers' init checks): imf_mul32x16k's tail for
     * n < 16 only */
    int32_t lo;
    if (g.j == -2) {
        return x;
    }
    lo = imf_mul16su(c.m, (uint16_t)((uint32_t)x & 0xFFFFu));
    return imf_mulk_low_avr(imf_mul16((int16_t)(x >> 16), c.m) + (lo >> 16), (uint16_t)lo,
                            c.s + K - N);
#else
    return (g.j == -2) ? x : imf_mulk32(x, c, K, N);
#endif
}

/* x c 2^(N-K) by the 16-bit gain g = imf_gain16(c, K, N) when it has one
 * (g.j >= 0), else exactly (imf_gain16_above). */
static inline int32_t imf_gain16_or_mulk32(const int32_t x, const imf_gain16_t g,
                                           const imf_qscale_t c, const int K, const int N)
{
    if (g.j >= 0) {
        return imf_gain16_mul(x, g);
    }
    return imf_gain16_above(x, g, c, K, N);
}

/* y0 = imf_gain16_or_mulk32(x0, g, c, K, N); y1 = the same of x1 (KKQ's pitch
 * and roll), and the same added to a0, a1 (imf_add_sat32): on AVR one copy
 * of the code in a loop, elsewhere the two statements as written out (the
 * Cortex-M0 pays for a loop and for holding x0 and x1 at once).  Same values
 * either way. */
#if defined(__AVR__) || defined(IMF_SCALE_SHORT)
#define IMF_GAIN16_OR_MULK32_2(y0, x0, y1, x1, g, c, K, N) \
    do { \
        int32_t imf_x_[2]; \
        int imf_i_; \
        imf_x_[0] = (x0); \
        imf_x_[1] = (x1); \
        for (imf_i_ = 0; imf_i_ < 2; ++imf_i_) { \
            imf_x_[imf_i_] = imf_gain16_or_mulk32(imf_x_[imf_i_], g, c, K, N); \
        } \
        (y0) = imf_x_[0]; \
        (y1) = imf_x_[1]; \
    } while (0)
#define IMF_ADD_GAIN16_OR_MULK32_2(a0, x0, a1, x1, g, c, K, N) \
    do { \
        int32_t imf_y0_, imf_y1_; \
        IMF_GAIN16_OR_MULK32_2(imf_y0_, x0, imf_y1_, x1, g, c, K, N); \
        (a0) = imf_add_sat32((a0), imf_y0_); \
        (a1) = imf_add_sat32((a1), imf_y1_); \
    } while (0)
#else
#define IMF_GAIN16_OR_MULK32_2(y0, x0, y1, x1, g, c, K, N) \
    do { \
        (y0) = imf_gain16_or_mulk32((x0), g, c, K, N); \
        (y1) = imf_gain16_or_mulk32((x1), g, c, K, N); \
    } while (0)
#define IMF_ADD_GAIN16_OR_MULK32_2(a0, x0, a1, x1, g, c, K, N) \
    do { \
        (a0) = imf_add_sat32((a0), imf_gain16_or_mulk32((x0), g, c, K, N)); \
        (a1) = imf_add_sat32((a1), imf_gain16_or_mulk32((x1), g, c, K, N)); \
    } while (0)
#endif

/* ---- unit vector of raw accelerometer counts (KKQ) -------------------- */

/* 1/sqrt(x) for x in [2^30, 2^32): y (unsigned q15) with 1/sqrt(x) ~= y 2^-31.
 * The chord of imf_invsqrt8_u32 on u = x / 2^16 (imf_invsqrt_chord16) and
 * two Newton steps y <- y (3 - u y^2) / 2 (imf_invsqrt_newton16), each three
 * unsigned 16x16->32 products: relative error below 6e-5.  y depends on u alone, and every u
 * is tested (tests/test_fixed_scale.py: the twin raises where a bound below
 * fails): u y^2 stays below 3 2^30 and the new y below 2^16 (no clamp, no
 * saturation needed). */
static inline uint16_t imf_invsqrt16_u32(const uint32_t x)
{
    const imf_invsqrt16_t u = (imf_invsqrt16_t)(x >> 16); /* q16 in [2^14, 2^16) */
    imf_invsqrt16_t y = imf_invsqrt_chord16(u);
    int i;
    for (i = 0; i < 2; ++i) {
        y = imf_invsqrt_newton16(u, y);
    }
    return (uint16_t)y;
}

/* x and y components of the unit vector of int16 counts v (KKQ needs no
 * more) in symmetric q15; returns 0 for the zero vector.  |v|^2 < 2^32
 * scaled by 4^k into [2^30, 2^32) (two bits per step) for
 * imf_invsqrt16_u32: 1/|v| ~= y 2^(k - 31), v / |v| in q15 = v y 2^(k - 16)
 * (imf_rshrk, k in [0, 15]). */
static inline int imf_unit_xy_k(const int16_t v[3], int16_t a[2])
{
    uint32_t n2 = 0u;
    uint16_t y;
    int i, k = 16;
    for (i = 0; i < 3; ++i) {
        n2 += (uint32_t)imf_mul16(v[i], v[i]); /* <= 3 2^30 */
    }
    if (n2 == 0u) {
        return 0;
    }
    while (n2 < ((uint32_t)1 << 30)) {
        n2 <<= 2;
        --k;
    }
    y = imf_invsqrt16_u32(n2);
    for (i = 0; i < 2; ++i) {
        /* |v| <= 2^15, y < 2^16: > -2^31 */
        a[i] = imf_sat_q15s(imf_rshrk(imf_mul16su(v[i], y), k));
    }
    return 1;
}

/* ---- MultiWiiQ --------------------------------------------------------- */

/* round((a1 b1 - a2 b2) / 2^16), saturated, for int32 a, int16 b: each
 * product as h = floor(a b / 2^16) and its low 16 bits (two 16x16
 * products), the two low words rounded together:
 * lo1 - lo2 + 2^15 lies in (-2^15, 3 2^15), its floor / 2^16 in {-1, 0, 1};
 * |h| <= 2^30 + 2^15, so only the final difference can leave int32. */
static inline int32_t imf_cross16(const int32_t a1, const int16_t b1, const int32_t a2,
                                  const int16_t b2)
{
    const int32_t lo1 = imf_mul16su(b1, (uint16_t)((uint32_t)a1 & 0xFFFFu));
    const int32_t lo2 = imf_mul16su(b2, (uint16_t)((uint32_t)a2 & 0xFFFFu));
    const int32_t h1 = imf_mul16((int16_t)(a1 >> 16), b1) + (lo1 >> 16);
    const int32_t h2 = imf_mul16((int16_t)(a2 >> 16), b2) + (lo2 >> 16);
    const int32_t r = ((int32_t)(uint16_t)lo1 - (int32_t)(uint16_t)lo2 + 32768) >> 16;
    return imf_sub_sat32(h1 + r, h2);
}

/* The cross product c = a x b of an int32 vector a and an int16 vector b,
 * each component imf_cross16 (round((a1 b1 - a2 b2) / 2^16), saturated).
 * On AVR one copy of the code in a loop (the three inline copies were
 * 540 bytes); elsewhere straight-line (a loop costs the Cortex-M0 ~50
 * instructions).  Same values either way. */
static inline void imf_cross3_16(const int32_t a[3], const int16_t b[3], int32_t c[3])
{
#if defined(__AVR__) || defined(IMF_SCALE_SHORT)
    int i, i1 = 1, i2 = 2;
    for (i = 0; i < 3; ++i) { /* (i1, i2) = (i + 1, i + 2) mod 3 */
        c[i] = imf_cross16(a[i1], b[i2], a[i2], b[i1]);
        i1 = i2;
        i2 = i;
    }
#else
    c[0] = imf_cross16(a[1], b[2], a[2], b[1]);
    c[1] = imf_cross16(a[2], b[0], a[0], b[2]);
    c[2] = imf_cross16(a[0], b[1], a[1], b[0]);
#endif
}

/* x 2^k for |x| 2^k < 2^31, k in [0, 31] (no saturation needed): the shift
 * of the magnitude (imf_lsl32: bytes, then bits). */
static inline int32_t imf_shl_exact32(const int32_t x, const int k)
{
    if (x >= 0) {
        return (int32_t)imf_lsl32((uint32_t)x, k);
    }
    return -(int32_t)imf_lsl32(0u - (uint32_t)x, k);
}

/* a 2^15 for int16 a (q15 -> q30 exactly, the value of imf_q15_to_q30):
 * a 2^16 is byte moves, the halving one step (exact: even). */
static inline int32_t imf_i16_to_q15(const int16_t a)
{
    return ((int32_t)a * 65536) >> 1;
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_FIXED_SCALE_H */
