/*
 * imf_fixed_quat.h -- steps shared by the fixed-point quaternion filters
 * (mahony_q.c, madgwick_q.c).  Mirrored by python/imufuse/reference/fixed_quat.py.
 *
 * Longer than 500 lines because: each shared step is here in its 32-bit and
 * 8-bit profile forms side by side (and their AVR paths), one header for the
 * two filters that include it.
 *
 * Formats:
 *   q[4]   quaternion, q30 (int32; 1.0 = 2^30, headroom to +-2)
 *   qs[4]  snapshot of q in symmetric q15 (int16, +-32767), the multiplier
 *          operand of every product with q
 *   a[3]   normalised accelerometer, symmetric q15
 *   h[3]   half rotation angle per sample, 0.5 * w * dt, q30 (int32) in the
 *          32-bit profile; in the 8-bit profile it is narrowed to int16 in
 *          q(15+hs), hs chosen at init from the gyro range
 */
#ifndef IMF_FIXED_QUAT_H
#define IMF_FIXED_QUAT_H

#include "imf_fixed.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Profiles compiled into the dispatching imf_<filter>_update: both, or only
 * the one IMF_FIXED_PROFILE (32 or 8) names -- then the other profile's code
 * is not linked (on AVR the 32-bit profile is about half the flash of these
 * filters) and init_consts rejects that profile. */
#if defined(IMF_FIXED_PROFILE) && (IMF_FIXED_PROFILE == 8)
#define IMF_Q_HAS_P32 0
#define IMF_Q_HAS_P8 1
#elif defined(IMF_FIXED_PROFILE) && (IMF_FIXED_PROFILE == 32)
#define IMF_Q_HAS_P32 1
#define IMF_Q_HAS_P8 0
#else
#define IMF_Q_HAS_P32 1
#define IMF_Q_HAS_P8 1
#endif

/* The profile default_settings gives: 32, or 8 in a build of the 8-bit profile only (a
 * default the build compiles: init of the defaults never returns -1 for the profile). */
#define IMF_Q_DEFAULT_PROFILE (IMF_Q_HAS_P32 ? 32 : 8)

/* 1 if the profile given to init (32 or 8; any other value: 0) is compiled in. */
static inline int imf_q_profile_ok(const int32_t profile)
{
    return profile == 8 ? IMF_Q_HAS_P8 : (profile == 32 && IMF_Q_HAS_P32);
}

/* On AVR, keep the rarely taken or self-contained steps out of line: the
 * inlined copies cost more in register spills than the call. */
#if defined(__AVR__)
#define IMF_Q_OUTLINE static __attribute__((noinline, unused))
#else
#define IMF_Q_OUTLINE static inline
#endif

/* Out of line on every target: a rarely taken step (its inlined copy
 * costs the usual path registers). */
#if defined(__GNUC__)
#define IMF_Q_NOINLINE __attribute__((noinline, unused))
#else
#define IMF_Q_NOINLINE
#endif

/* q30 quaternion -> symmetric q15 snapshot. */
static inline void imf_q_snapshot(const int32_t q[4], int16_t qs[4])
{
    int i;
    for (i = 0; i < 4; ++i) {
        qs[i] = imf_qn_to_q15s(q[i], 30);
    }
}

/* Normalise raw accelerometer counts to symmetric q15.  Returns 0 for the
 * zero vector (no direction: the caller skips the correction). */
static inline int imf_q_normalise_acc(const int16_t acc[3], int16_t a[3])
{
    /* each square <= 2^30, three of them < 2^32: no uint32 wrap */
    const uint32_t n2 = (uint32_t)imf_mul16(acc[0], acc[0]) + (uint32_t)imf_mul16(acc[1], acc[1])
                        + (uint32_t)imf_mul16(acc[2], acc[2]);
    int sh, i;
    uint16_t y;
    if (n2 == 0u) {
        return 0;
    }
    y = imf_invsqrt_u32(n2, &sh); /* 1/|acc| = y 2^-sh, sh >= 16 */
    for (i = 0; i < 3; ++i) {
        /* |acc| <= 2^15, y < 2^16: the product fits int32 (> -2^31) */
        a[i] = imf_sat_q15s(imf_rshr32(imf_mul16su(acc[i], y), sh - 15));
    }
    return 1;
}

/* 32-bit profile, appendix step 7 (Mahony) / 3 (Madgwick):
 * dq = q (x) (0, h), h = 0.5 w dt in q30; products q15 x q30 -> q30 by
 * imf_mul_32x16 (rounded), sums saturate. */
/* h q15 -> q30: imf_mul_32x16(h, qs, 15)'s value without its range tests.
 * qs is a symmetric q15 snapshot (|qs| <= 32767), so for any int32 h,
 * |h qs| < 2^46, the high part m = floor(h qs / 2^16) is in
 * [-2^30, 2^30 - 2^15] and 2 m + (lol + 2^14) / 2^15 (lol the low 16 bits,
 * the rounded term in [0, 2]) never leaves int32: no saturation.  (Each
 * inlined copy of imf_mul_32x16's saturating path cost ~200 bytes on the
 * Cortex-M0; on AVR its general path cost ~250 cycles a product.)  One
 * out-of-line copy on AVR: twelve inlined copies are most of the 32-bit
 * profile's flash. */
IMF_Q_OUTLINE int32_t imf_q_mul_hq_p32(const int32_t h, const int16_t qs)
{
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
    /* The same value as below, (P + 2^14) >> 15 for the 48-bit P = h qs, in one block of
     * eight 8x8 products (AVR201's signed steps: MULSU sets the carry to the product's sign,
     * SBC extends it over the higher bytes), then 2 P rounded at bit 16: bytes 2..5. No
     * call-saved register is needed (the C form pushed ten: 40 of its ~110 cycles). */
    int32_t r;  /* bytes 2..5 of P, then the result */
    uint16_t l; /* bytes 0..1 of P */
    uint8_t z;
    __asm__("clr %[z]\n\t"
            "muls %D[h], %B[q]\n\t" /* h3 q1: bytes 4, 5 */
            "movw %C[r], r0\n\t"
            "mul %C[h], %A[q]\n\t" /* h2 q0: bytes 2, 3 */
            "movw %A[r], r0\n\t"
            "mulsu %D[h], %A[q]\n\t" /* h3 q0: bytes 3, 4 (signed) */
            "sbc %D[r], %[z]\n\t"
            "add %B[r], r0\n\t"
            "adc %C[r], r1\n\t"
            "adc %D[r], %[z]\n\t"
            "mulsu %B[q], %C[h]\n\t" /* q1 h2: bytes 3, 4 (signed) */
            "sbc %D[r], %[z]\n\t"
            "add %B[r], r0\n\t"
            "adc %C[r], r1\n\t"
            "adc %D[r], %[z]\n\t"
            "mul %A[h], %A[q]\n\t" /* h0 q0: bytes 0, 1 */
            "movw %A[l], r0\n\t"
            "mul %B[h], %A[q]\n\t" /* h1 q0: bytes 1, 2 */
            "add %B[l], r0\n\t"
            "adc %A[r], r1\n\t"
            "adc %B[r], %[z]\n\t"
            "adc %C[r], %[z]\n\t"
            "adc %D[r], %[z]\n\t"
            "mulsu %B[q], %A[h]\n\t" /* q1 h0: bytes 1, 2 (signed) */
            "sbc %B[r], %[z]\n\t"
            "sbc %C[r], %[z]\n\t"
            "sbc %D[r], %[z]\n\t"
            "add %B[l], r0\n\t"
            "adc %A[r], r1\n\t"
            "adc %B[r], %[z]\n\t"
            "adc %C[r], %[z]\n\t"
            "adc %D[r], %[z]\n\t"
            "mulsu %B[q], %B[h]\n\t" /* q1 h1: bytes 2, 3 (signed) */
            "sbc %C[r], %[z]\n\t"
            "sbc %D[r], %[z]\n\t"
            "add %A[r], r0\n\t"
            "adc %B[r], r1\n\t"
            "adc %C[r], %[z]\n\t"
            "adc %D[r], %[z]\n\t"
            "lsl %A[l]\n\t" /* 2 P (|P| < 2^46) */
            "rol %B[l]\n\t"
            "rol %A[r]\n\t"
            "rol %B[r]\n\t"
            "rol %C[r]\n\t"
            "rol %D[r]\n\t"
            "lsl %B[l]\n\t" /* carry: bit 15 of 2 P, the rounding */
            "adc %A[r], %[z]\n\t"
            "adc %B[r], %[z]\n\t"
            "adc %C[r], %[z]\n\t"
            "adc %D[r], %[z]\n\t"
            "clr __zero_reg__"
            : [r] "=&r"(r), [l] "=&r"(l), [z] "=&r"(z)
            : [h] "a"(h), [q] "a"(qs));
    return r;
#else
    const int32_t lo = imf_mul16su(qs, (uint16_t)((uint32_t)h & 0xFFFFu)); /* |.| < 2^31 */
    const int32_t m = imf_mul16((int16_t)(h >> 16), qs) + (lo >> 16);
    /* (lol + 2^14) >> 15 = ((lol >> 14) + 1) >> 1, lol = lo mod 2^16 */
    return m * 2 + (int32_t)((uint16_t)(((uint16_t)((uint32_t)lo & 0xFFFFu) >> 14) + 1u) >> 1);
#endif
}

IMF_Q_OUTLINE void imf_q_rate_p32(const int16_t qs[4], const int32_t h[3], int32_t dq[4])
{
    /* p[j][i] = h[j] qs[i] (q30): x = p[0], y = p[1], z = p[2]; a loop on
     * AVR (flash), unrolled elsewhere */
    int32_t p[3][4];
#if defined(__AVR__)
    int i, j;
    for (j = 0; j < 3; ++j) {
        for (i = 0; i < 4; ++i) {
            p[j][i] = imf_q_mul_hq_p32(h[j], qs[i]);
        }
    }
#else
    p[0][0] = imf_q_mul_hq_p32(h[0], qs[0]), p[0][1] = imf_q_mul_hq_p32(h[0], qs[1]);
    p[0][2] = imf_q_mul_hq_p32(h[0], qs[2]), p[0][3] = imf_q_mul_hq_p32(h[0], qs[3]);
    p[1][0] = imf_q_mul_hq_p32(h[1], qs[0]), p[1][1] = imf_q_mul_hq_p32(h[1], qs[1]);
    p[1][2] = imf_q_mul_hq_p32(h[1], qs[2]), p[1][3] = imf_q_mul_hq_p32(h[1], qs[3]);
    p[2][0] = imf_q_mul_hq_p32(h[2], qs[0]), p[2][1] = imf_q_mul_hq_p32(h[2], qs[1]);
    p[2][2] = imf_q_mul_hq_p32(h[2], qs[2]), p[2][3] = imf_q_mul_hq_p32(h[2], qs[3]);
#endif
    /* |each product| <= |h| < 2^30 for |h| < 1: the sums of three stay in int32
     * only while |h| < 2/3; saturate anyway */
    dq[0] = imf_sub_sat32(imf_sub_sat32(imf_sub_sat32(0, p[0][1]), p[1][2]), p[2][3]);
    dq[1] = imf_sub_sat32(imf_add_sat32(p[0][0], p[2][2]), p[1][3]);
    dq[2] = imf_add_sat32(imf_sub_sat32(p[1][0], p[2][1]), p[0][3]);
    dq[3] = imf_sub_sat32(imf_add_sat32(p[2][0], p[1][1]), p[0][2]);
}

/* 8-bit profile: unit vector of an int16 3-vector in symmetric q15, or 0
 * for the zero vector.  The vector is first block-scaled by 2^k (k >= 0,
 * -32768 clamped to -32767) until its largest component is in [2^14, 2^15),
 * so its squared norm is in [2^28, 2^32) for imf_invsqrt8_u32 and the
 * final product needs a constant shift only. */
static inline int imf_q_unit3_p8(const int16_t v[3], int16_t a[3])
{
    int16_t b[3];
    uint16_t m = 0u;
    uint32_t n2;
    int i, e;
    uint16_t y;
    for (i = 0; i < 3; ++i) {
        b[i] = (v[i] < -32767) ? (int16_t)-32767 : v[i];
        m |= (uint16_t)(b[i] < 0 ? -b[i] : b[i]); /* same top bit as the max */
    }
    if (m == 0u) {
        return 0;
    }
#if defined(__AVR__)
    while (m < 16384u) {
        m = (uint16_t)(m << 1);
        for (i = 0; i < 3; ++i) {
            b[i] = (int16_t)(b[i] + b[i]); /* |b| < 2^14: no overflow */
        }
    }
#else
    if (m < 16384u) { /* the same scaling with one multiply per component */
        unsigned int mm = m, k = 1u;
        while (mm < 16384u) {
            mm <<= 1;
            k <<= 1;
        }
        for (i = 0; i < 3; ++i) {
            b[i] = (int16_t)(b[i] * (int)k); /* |b k| < 2^15 */
        }
    }
#endif
    n2 = (uint32_t)imf_mul16(b[0], b[0]) + (uint32_t)imf_mul16(b[1], b[1])
         + (uint32_t)imf_mul16(b[2], b[2]); /* [2^28, 3 2^30] */
    y = imf_invsqrt8_u32(n2, &e);           /* 1/|b| ~= y 2^(e-31) */
    for (i = 0; i < 3; ++i) {
        /* |b| < 2^15, y < 2^16: the product fits int32 */
        const int32_t p = imf_mul16su(b[i], y);
        a[i] = e ? imf_qn_to_q15s(p, 30) : imf_qn_to_q15s(p, 31);
    }
    return 1;
}

/* imf_rshr32 for n in [0, 15] (the 8-bit profile's hs): the same value
 * with fewer range checks.  On AVR it is imf_rshr32_v, whose compact copy
 * (byte moves, at most 7 bit steps, the last one's carry added back) is
 * linked anyway: one copy instead of two (flash). */
#if defined(__AVR__)
static inline int32_t imf_q_rshr_hs_p8(const int32_t x, const int n)
{
    return imf_rshr32_v(x, n);
}
#else
IMF_Q_OUTLINE int32_t imf_q_rshr_hs_p8(const int32_t x, const int n)
{
    if (n >= 2) {
        return (imf_asr32(x, n - 1) + 1) >> 1; /* <= 2^30 + 1: no overflow */
    }
    if (n == 1) {
        return (x >> 1) + (x & 1);
    }
    return x;
}
#endif

/* 8-bit profile, step 1 with the remainder carried: h = floor((t + c) / 2^16)
 * in q(15+hs) for a rate t in q(31+hs), keeping c = (t + c) mod 2^16 for the
 * next sample.  The sum of the h applied so far is then the exact sum of the
 * t to within one LSB of q(15+hs), however long a rate is held: rounding
 * each sample on its own leaves up to half an LSB per sample (0.002 rad/s for
 * a +-2000 deg/s gyro at 512 Hz), which the accelerometer corrects in tilt
 * but which accumulates in the unobserved yaw.  In 16-bit operations (no
 * overflow for any t and c): the low words add, their carry goes to the high
 * word. */
static inline int32_t imf_q_carry_p8(const int32_t t, int32_t *const c)
{
#if defined(__AVR__)
    /* the same in one 16-bit add whose carry goes straight to the result */
    int32_t r;
    uint16_t s;
    __asm__("movw %A[r], %C[t]\n\t"
            "mov %C[r], %D[t]\n\t"
            "lsl %C[r]\n\t"
            "sbc %C[r], %C[r]\n\t" /* sign of t */
            "mov %D[r], %C[r]\n\t"
            "add %A[s], %A[t]\n\t"
            "adc %B[s], %B[t]\n\t" /* C = carry of the low words */
            "adc %A[r], __zero_reg__\n\t"
            "adc %B[r], __zero_reg__\n\t"
            "adc %C[r], __zero_reg__\n\t"
            "adc %D[r], __zero_reg__"
            : [r] "=&r"(r), [s] "=&r"(s)
            : [t] "r"(t), "1"((uint16_t)((uint32_t)*c & 0xFFFFu)));
    *c = (int32_t)s;
    return r;
#else
    const uint16_t lo = (uint16_t)((uint32_t)t & 0xFFFFu);
    const uint16_t s = (uint16_t)(lo + (uint16_t)((uint32_t)*c & 0xFFFFu));
    *c = (int32_t)s;
    return (int32_t)(int16_t)(t >> 16) + (s < lo ? 1 : 0); /* floor(t / 2^16) + carry */
#endif
}

/* imf_sat_q15 of the rates: on AVR the same value in a few byte operations
 * (x is in range iff its high word is the sign extension of its low word;
 * otherwise 0x7FFF, plus 1 = 0x8000 if negative). */
static inline int16_t imf_q_sat_q15_p8(const int32_t x)
{
#if defined(__AVR__)
    int32_t r = x;
    uint8_t t;
    __asm__("mov %[t], %B[r]\n\t"
            "lsl %[t]\n\t"
            "sbc %[t], %[t]\n\t" /* sign of the low word: 0 or 0xFF */
            "cp %C[r], %[t]\n\t"
            "cpc %D[r], %[t]\n\t"
            "breq 1f\n\t"   /* in range */
            "lsl %D[r]\n\t" /* C = sign of x */
            "ldi %A[r], 0xFF\n\t"
            "ldi %B[r], 0x7F\n\t"
            "adc %A[r], __zero_reg__\n\t"
            "adc %B[r], __zero_reg__\n"
            "1:"
            : [r] "+d"(r), [t] "=&r"(t));
    return (int16_t)r;
#else
    return imf_sat_q15(x);
#endif
}

/* 8-bit profile, appendix step 7 / 3: dq = q (x) (0, h), h in q(15+hs)
 * saturated to int16; each component's three q15 x q(15+hs) products are
 * summed (saturating) and rounded to q30 once. */
static inline void imf_q_rate_p8(const int16_t qs[4], const int32_t h[3], const int hs,
                                 int32_t dq[4])
{
    const int16_t hx = imf_q_sat_q15_p8(h[0]);
    const int16_t hy = imf_q_sat_q15_p8(h[1]);
    const int16_t hz = imf_q_sat_q15_p8(h[2]);
#define IMF_P(a, b) imf_mul16((a), (b)) /* |.| <= 2^30 */
    dq[0] =
        imf_q_rshr_hs_p8(imf_sub_sat32(-IMF_P(qs[1], hx) - IMF_P(qs[2], hy), IMF_P(qs[3], hz)), hs);
    dq[1] =
        imf_q_rshr_hs_p8(imf_sub_sat32(IMF_P(qs[0], hx) + IMF_P(qs[2], hz), IMF_P(qs[3], hy)), hs);
    dq[2] =
        imf_q_rshr_hs_p8(imf_add_sat32(IMF_P(qs[0], hy) - IMF_P(qs[1], hz), IMF_P(qs[3], hx)), hs);
    dq[3] =
        imf_q_rshr_hs_p8(imf_sub_sat32(IMF_P(qs[0], hz) + IMF_P(qs[1], hy), IMF_P(qs[2], hx)), hs);
#undef IMF_P
}

/* |q|^2 in q30 (uint32, saturated to 2^32 - 1) for the normalisation
 * (appendix step 8), from the q15 snapshot qs of q -- except where it
 * saturates.  The symmetric q15 snapshot reads 1.0 as 32767, so a norm
 * taken from it alone sees the identity as |q|^2 = 1 - 2^-14, and a
 * normalisation driven by it scales q up at every sample, without bound
 * (q0 >= 1 never looks too long).  Where qs is +-32767 the component is
 * rounded to q15 again without saturation (|q_i| up to 2: magnitudes up to
 * 2^16, clamped to 65535; the sum saturates only for |q| >= 2); elsewhere qs
 * is that rounding already. */
IMF_Q_OUTLINE uint32_t imf_q_norm2(const int32_t q[4], const int16_t qs[4])
{
    uint32_t n2 = 0u, p;
    int32_t r;
    uint16_t u;
    int i;
    /* the usual case, every component from qs: four squares < 2^30 each,
     * the sum < 2^32 needs no saturation (the same value as the loop below).
     * Not on AVR, where the loop below alone is the smaller code (flash) */
#if !defined(__AVR__)
    {
        /* the test for +-32767 on the squares: qs in [-32767, 32767], so qs
         * is +-32767 iff its square is 32767^2 = 2^30 - 2^16 + 1, the only
         * one that reaches 2^30 with 2^16 - 1 added */
        const uint32_t p0 = (uint32_t)imf_mul16(qs[0], qs[0]),
                       p1 = (uint32_t)imf_mul16(qs[1], qs[1]);
        const uint32_t p2 = (uint32_t)imf_mul16(qs[2], qs[2]),
                       p3 = (uint32_t)imf_mul16(qs[3], qs[3]);
        if ((((p0 + 65535u) | (p1 + 65535u) | (p2 + 65535u) | (p3 + 65535u)) >> 30) == 0u) {
            return p0 + p1 + p2 + p3;
        }
    }
#endif
    for (i = 0; i < 4; ++i) {
        if (qs[i] > -32767 && qs[i] < 32767) {
            u = (uint16_t)(qs[i] < 0 ? -qs[i] : qs[i]);
        } else {
            r = imf_rshr32(q[i], 15); /* [-2^16, 2^16] */
            if (r < 0) {
                r = -r;
            }
            u = (uint16_t)(r > 65535 ? 65535 : r);
        }
        p = imf_mulu16(u, u);
        n2 += p;
        if (n2 < p) { /* wrapped */
            n2 = 4294967295u;
        }
    }
    return n2;
}

/* q /= |q| with the division-free inverse square root (after q += dq). */
IMF_Q_OUTLINE void imf_q_normalise(int32_t q[4])
{
    int16_t qs[4];
    uint32_t n2;
    uint16_t y;
    int16_t y14;
    int sh, i;
    imf_q_snapshot(q, qs);
    n2 = imf_q_norm2(q, qs);
    if (n2 == 0u) {
        q[0] = IMF_Q30_ONE;
        q[1] = q[2] = q[3] = 0;
        return;
    }
    y = imf_invsqrt_u32(n2, &sh);                           /* 1/sqrt(n2) = y 2^-sh, n2 in q30 */
    y14 = (int16_t)((y >= 65535u) ? 32767 : (y + 1u) >> 1); /* y/2, q14 -> int16 */
    for (i = 0; i < 4; ++i) {
        /* q / sqrt(n2 / 2^30) = q * y14 * 2^(16 - sh); sh = 30 for |q| near 1
         * (the usual case): outside AVR, that shift as a constant (faster) */
#if !defined(__AVR__)
        if (sh == 30) {
            q[i] = imf_mul_32x16(q[i], y14, 14);
            continue;
        }
#endif
        q[i] = imf_mul_32x16(q[i], y14, sh - 16);
    }
}

/* 8-bit profile, the rare full normalisation of step 8 (imf_q_snapshot_norm_p8)
 * in 16-bit operations, to the precision the next updates need: q is
 * block-scaled by 2^-k (rounded, saturated to symmetric q15) so that its
 * largest component is in [2^14, 2^15], so |b|^2 is in [2^28, 2^32) for
 * the short inverse square root imf_invsqrt8_u32 (relative error < 1.2e-3);
 * then q30 = b y 2^(e-1), exact for e = 1, rounded for e = 0.  |q|^2 - 1
 * after it is below 2.5e-3, inside the band of the first-order step, which
 * removes it over the next updates; the direction is kept to b's 15 bits.
 * A zero quaternion (possible only from a state set by hand) resets to
 * the identity. */
static IMF_Q_NOINLINE void imf_q_normalise_p8(int32_t q[4])
{
    int16_t b[4];
    uint32_t m = 0u, n2 = 0u;
    uint16_t y;
    int k = 0, e, i;
    for (i = 0; i < 4; ++i) {
        m |= (q[i] < 0) ? 0u - (uint32_t)q[i] : (uint32_t)q[i]; /* top bit of the max */
    }
    if (m == 0u) {
        q[0] = IMF_Q30_ONE;
        q[1] = q[2] = q[3] = 0;
        return;
    }
    while (m >= 32768u) {
        m >>= 1;
        ++k;
    }
    while (m < 16384u) {
        m <<= 1;
        --k;
    }
    for (i = 0; i < 4; ++i) {
        /* q 2^-k rounded (the largest in [2^14, 2^15], saturated to 32767);
         * k < 0: exact, |q 2^-k| < 2^15 (imf_rshift_sat32's value) */
        b[i] = imf_sat_q15s(k >= 0 ? imf_rshr32(q[i], k) : (int32_t)((uint32_t)q[i] << -k));
        n2 += (uint32_t)imf_mul16(b[i], b[i]); /* each < 2^30: no wrap */
    }
    y = imf_invsqrt8_u32(n2, &e); /* 1/|b| ~= y 2^(e-31) */
    for (i = 0; i < 4; ++i) {
        /* |b| < 2^15, y < 2^16: the product fits int32 */
        const int32_t p = imf_mul16su(b[i], y);
        q[i] = imf_rshr32(p, 1 - e); /* e in {0, 1} */
    }
}

/* 8-bit profile, step 8 folded into the next update (no second snapshot):
 * at the start of an update, the q15 snapshot qs of q and d = |q|^2 - 1 in
 * q22 (int16, imf_q_norm2); while |d| < 2^-8 (every ordinary update: a step leaves
 * |q|^2 - 1 ~ |h|^2) the update's own step is q += dq - q d / 2
 * (imf_q_add_step_p8), a first-order normalisation one sample late (|q|^2 - 1
 * stays of the order of |h|^2 + rounding).  Otherwise (a state set by hand,
 * a rotation above 0.06 rad per sample) q is first normalised
 * (imf_q_normalise_p8) and d = 0. */
static inline int16_t imf_q_snapshot_norm_p8(int32_t q[4], int16_t qs[4])
{
    uint32_t n2;
    imf_q_snapshot(q, qs);
    n2 = imf_q_norm2(q, qs);
    if (n2 <= 1069547520u || n2 >= 1077936128u) { /* 2^30 -+ 2^22 */
        imf_q_normalise_p8(q);
        imf_q_snapshot(q, qs);
        return 0;
    }
    return (int16_t)imf_rshr32((int32_t)n2 - IMF_Q30_ONE, 8); /* q22, |d| <= 2^14 */
}

/* q += dq - q d / 2: q d / 2 in q30 = qs (q15) d16 (q22) / 2^8, |.| < 2^29. */
static inline void imf_q_add_step_p8(int32_t q[4], const int32_t dq[4], const int16_t qs[4],
                                     const int16_t d16)
{
    int i;
    for (i = 0; i < 4; ++i) {
#if defined(__AVR__)
        /* imf_rshr32(., 8) without its overflow test: |.| < 2^29 */
        q[i] = imf_add_sat32(q[i], imf_sub_sat32(dq[i], (imf_mul16(qs[i], d16) + 128) >> 8));
#else
        q[i] = imf_add_sat32(q[i], imf_sub_sat32(dq[i], imf_rshr32(imf_mul16(qs[i], d16), 8)));
#endif
    }
}

/* q += dq (saturating), then q /= |q| (appendix step 8).  The norm comes
 * from imf_q_norm2 (q rounded to q15, unsaturated) and the division-free
 * inverse square root; the scale factor is applied to the full q30 values.
 * A zero quaternion (possible only from a state set by hand) resets to
 * the identity. */
static inline void imf_q_add_normalise(int32_t q[4], const int32_t dq[4])
{
    int i;
    for (i = 0; i < 4; ++i) {
        q[i] = imf_add_sat32(q[i], dq[i]);
    }
    imf_q_normalise(q);
}

/* Exponent hs of the 8-bit profile's narrowed rate: the gyro full scale
 * times 2 (room for the feedback) fits int16 in q(15+hs).  kg = 0.5 gyr_scale
 * dt = m 2^-s, 32768 kg < 2^(30-s), so hs = s - 31 clamped to [0, 15]. */
static inline int16_t imf_q_rate_exponent(const imf_qscale_t kg)
{
    int hs = kg.s - 31;
    if (hs < 0) {
        hs = 0;
    }
    if (hs > 15) {
        hs = 15;
    }
    return (int16_t)hs;
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_FIXED_QUAT_H */
