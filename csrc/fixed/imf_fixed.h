/*
 * imf_fixed.h -- Q-format core of imufuse's fixed-point filters.
 *
 * Plain C99, header-only static inline, no malloc, no globals, no I/O.
 * Every function is mirrored operation for operation by
 * python/imufuse/reference/_cint.py; tests/test_fixed_core.py compares
 * the two over random and extreme inputs in a UBSan build.
 *
 * Longer than 500 lines because: it is the one header every fixed-point
 * filter includes, each helper beside its AVR form and the compile-time
 * checks it relies on; split, a helper and its AVR form would part.
 *
 * Formats (CMSIS style, the format is in the name):
 *   q15   int16_t, value = x / 2^15, range [-1, 1 - 2^-15]
 *   q30   int32_t, value = x / 2^30, range [-2, 2 - 2^-30]
 *   qN    int32_t, value = x / 2^N (state variables name their N)
 *   imf_qscale_t  a positive constant m * 2^-s with m in [2^14, 2^15)
 *                 (or m = 0): a gain or a unit conversion with 15
 *                 significant bits, whatever its magnitude.
 *
 * Rounding: every multiply that drops bits rounds to nearest, ties towards
 * +infinity (floor(x / 2^n + 1/2)).  The error is within +-1/2 LSB and its
 * mean is 2^-(n+1) LSB, so there is no accumulating truncation bias.
 *
 * Undefined behaviour and how it is avoided:
 *   - signed overflow: products are formed in a type wide enough to hold
 *     them exactly (16x16 in 32 bits; 32x16 as two 16x16 partial products);
 *     sums that can leave the range saturate (imf_add_sat32 ...);
 *   - left shift of a negative value: never done; multiplication by 2^k of
 *     a signed value goes through the unsigned magnitude (imf_shl_sat32);
 *   - right shift of a negative value: implementation-defined in C99; it is
 *     used only after the compile-time checks below prove it arithmetic.
 *   - conversion of an out-of-range value to a signed type: never done;
 *     values are saturated first.
 * No 64-bit integer is used anywhere in this header: the 8-bit profile
 * (AVR) has no fast int64, and on Cortex-M0 a 64-bit product is a library
 * call.  A 32x16 product with exact rounding costs two 16x16->32 multiplies.
 */
#ifndef IMF_FIXED_H
#define IMF_FIXED_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Right shift of a negative value must be arithmetic (sign-extending). */
#if ((-1) >> 1) != -1
#error "imf_fixed.h needs an arithmetic right shift of negative integers"
#endif
/* The preprocessor computes in intmax_t; check the run-time types too. */
typedef char imf_fixed_asr32_is_arithmetic[(((int32_t)-1) >> 1) == -1 ? 1 : -1];
typedef char imf_fixed_asr16_is_arithmetic[(((int16_t)-32768) >> 15) == -1 ? 1 : -1];

#define IMF_Q15_MAX ((int16_t)32767)
#define IMF_Q15_MIN ((int16_t)(-32767 - 1))
#define IMF_Q15_ONE ((int16_t)32767) /* 1.0 saturated to q15 */
#define IMF_Q30_ONE ((int32_t)1073741824L)
#define IMF_INT32_MAX ((int32_t)2147483647L)
#define IMF_INT32_MIN ((int32_t)(-2147483647L - 1))

/* A positive constant with 15 significant bits: value = m * 2^-s. */
typedef struct {
    int16_t m; /* mantissa, 0 or in [2^14, 2^15) */
    int16_t s; /* binary exponent (shift), any value in [-16, 62] */
} imf_qscale_t;

/* 1 if c is a well-formed q-scale (m = 0 or m in [2^14, 2^15)) with its
 * shift s in [smin, smax]: the check every _init_consts makes of the
 * constants it is given. */
static inline int imf_qscale_ok(const imf_qscale_t c, const int smin, const int smax)
{
    return (c.m == 0 || c.m >= 16384) && c.s >= smin && c.s <= smax;
}

/* On AVR, helpers marked IMF_AVR_NOINLINE stay out of line: their inlined
 * copies cost more in code size and register spills than the call. */
#if defined(__AVR__)
#define IMF_AVR_NOINLINE __attribute__((noinline, unused))
#define IMF_AVR_OUTLINE static __attribute__((noinline, unused))
#else
#define IMF_AVR_NOINLINE
#define IMF_AVR_OUTLINE static inline
#endif

/* On AVR, a helper called with a shift count known only at run time goes
 * to one out-of-line copy (its inlined copies, each a loop over the count,
 * are most of a filter's flash); with a constant count it stays inline
 * and folds to byte moves and a few bit steps. */
#if defined(__AVR__)
#define IMF_AVR_VARIABLE(n) (!__builtin_constant_p(n))
#else
#define IMF_AVR_VARIABLE(n) 0
#endif

/* ---- shifts -------------------------------------------------------- */

/* 32-bit shifts by n in [0, 31].  The 8-bit target has no barrel shifter:
 * avr-gcc shifts by 8, 16 and 24 with byte moves but by any other count,
 * constant or not, with a loop of single-bit steps over four bytes.  On AVR
 * the shift is therefore split into byte moves and at most 7 bit steps
 * (the same value: shifts compose); elsewhere it is one shift. */
#if defined(__AVR__)
#define IMF_SPLIT_SHIFT(x, n, op) \
    do { \
        if ((n) >= 16) { \
            (x) op 16; \
            (n) -= 16; \
        } \
        if ((n) >= 8) { \
            (x) op 8; \
            (n) -= 8; \
        } \
    } while (0)
#else
#define IMF_SPLIT_SHIFT(x, n, op) \
    do { \
    } while (0)
#endif

/* Arithmetic shift right, n in [0, 31]: floor(x / 2^n) (checked above). */
static inline int32_t imf_asr32(const int32_t x, const int n)
{
    int32_t y = x;
    int k = n;
    IMF_SPLIT_SHIFT(y, k, >>=);
    return y >> k;
}

/* Logical shift right of a uint32, n in [0, 31]. */
static inline uint32_t imf_lsr32(const uint32_t x, const int n)
{
    uint32_t y = x;
    int k = n;
    IMF_SPLIT_SHIFT(y, k, >>=);
    return y >> k;
}

/* Shift left of a uint32 (modulo 2^32, defined), n in [0, 31]. */
static inline uint32_t imf_lsl32(const uint32_t x, const int n)
{
    uint32_t y = x;
    int k = n;
    IMF_SPLIT_SHIFT(y, k, <<=);
    return y << k;
}

/* Rounding shift right, n in [0, 31]: floor(x / 2^n + 1/2)
 * = floor((floor(x / 2^(n-1)) + 1) / 2): one shift by n - 1, then one by 1;
 * floor(x / 2^(n-1)) + 1 <= 2^30 + 1 for n >= 2 cannot overflow, and
 * n = 1 adds the low bit instead (x = INT32_MAX). */
static inline int32_t imf_rshr32_k(const int32_t x, const int n)
{
    if (n <= 0) {
        return x;
    }
    if (n > 31) {
        return 0; /* |x| / 2^n < 1/2 */
    }
    if (n == 1) {
        return (x >> 1) + (x & 1);
    }
#if defined(__AVR__)
    /* The same value from the high word (byte moves) and 16-bit shifts:
     * floor(x / 2^(n-1)) = floor(floor(x / 2^16) / 2^(n-17)) for n >= 17;
     * for n = 16, 15 the dropped bits 15 (and 14) round. */
    if (n == 8 && x <= IMF_INT32_MAX - 128) {
        return (x + 128) >> 8; /* byte moves */
    }
    if (n >= 15) {
        const int16_t t = (int16_t)(x >> 16);
        const uint16_t lo = (uint16_t)((uint32_t)x & 0xFFFFu);
        if (n == 15) {
            return (int32_t)t * 2 + (int32_t)(lo >> 15) + (int32_t)((lo >> 14) & 1u);
        }
        if (n == 16) {
            return (int32_t)t + (int32_t)(lo >> 15);
        }
        return ((int32_t)(int16_t)(t >> (n - 17)) + 1) >> 1;
    }
#endif
    return (imf_asr32(x, n - 1) + 1) >> 1;
}

IMF_AVR_OUTLINE int32_t imf_rshr32_v(const int32_t x, const int n)
{
#if defined(__AVR__)
    /* the same value in one compact copy: y = x / 2^(n-1) (floor; byte
     * moves, <= 7 bit steps), then (y >> 1) + (y & 1) = (y + 1) >> 1
     * without its overflow at y = INT32_MAX: the bit shifted out is the
     * carry added back */
    if ((unsigned int)n - 1u <= 30u) {
        int32_t y = imf_asr32(x, n - 1);
        __asm__("asr %D0\n\t"
                "ror %C0\n\t"
                "ror %B0\n\t"
                "ror %A0\n\t"
                "adc %A0, __zero_reg__\n\t"
                "adc %B0, __zero_reg__\n\t"
                "adc %C0, __zero_reg__\n\t"
                "adc %D0, __zero_reg__"
                : "+r"(y));
        return y;
    }
    return n <= 0 ? x : 0;
#else
    return imf_rshr32_k(x, n);
#endif
}

static inline int32_t imf_rshr32(const int32_t x, const int n)
{
    if (IMF_AVR_VARIABLE(n)) {
        return imf_rshr32_v(x, n);
    }
    return imf_rshr32_k(x, n);
}

/* x * 2^k, k in [0, 31], saturated to int32.  Uses the unsigned magnitude:
 * a left shift of a negative value is undefined in C99. */
static inline int32_t imf_shl_sat32_k(const int32_t x, const int k)
{
    uint32_t mag;
    if (k <= 0) {
        return x;
    }
    if (x >= 0) {
        mag = (uint32_t)x;
        if (mag > imf_lsr32((uint32_t)IMF_INT32_MAX, k)) {
            return IMF_INT32_MAX;
        }
        return (int32_t)imf_lsl32(mag, k);
    }
    mag = 0u - (uint32_t)x; /* |x|, 2^31 for INT32_MIN */
    if (mag > imf_lsr32((uint32_t)1 << 31, k)) {
        return IMF_INT32_MIN;
    }
    mag = imf_lsl32(mag, k); /* <= 2^31 */
    if (mag == ((uint32_t)1 << 31)) {
        return IMF_INT32_MIN;
    }
    return -(int32_t)mag;
}

IMF_AVR_OUTLINE int32_t imf_shl_sat32_v(const int32_t x, const int k)
{
#if defined(__AVR__)
    /* the same value with one shift each way (one compact copy) */
    const int neg = x < 0;
    uint32_t mag = neg ? 0u - (uint32_t)x : (uint32_t)x; /* 2^31 for INT32_MIN */
    if (k <= 0) {
        return x;
    }
    if (mag > imf_lsr32(neg ? (uint32_t)1 << 31 : (uint32_t)IMF_INT32_MAX, k)) {
        return neg ? IMF_INT32_MIN : IMF_INT32_MAX;
    }
    mag = imf_lsl32(mag, k); /* <= 2^31 */
    if (!neg) {
        return (int32_t)mag;
    }
    return (mag == ((uint32_t)1 << 31)) ? IMF_INT32_MIN : -(int32_t)mag;
#else
    return imf_shl_sat32_k(x, k);
#endif
}

static inline int32_t imf_shl_sat32(const int32_t x, const int k)
{
    if (IMF_AVR_VARIABLE(k)) {
        return imf_shl_sat32_v(x, k);
    }
    return imf_shl_sat32_k(x, k);
}

/* Rounding shift by n (right if n > 0, saturating left if n < 0). */
static inline int32_t imf_rshift_sat32(const int32_t x, const int n)
{
    return (n >= 0) ? imf_rshr32(x, n) : imf_shl_sat32(x, -n);
}

/* ---- saturation, saturating add/sub ---------------------------------- */

/* int32 -> q15, results are saturated to [-32768, 32767]. */
static inline int16_t imf_sat_q15(const int32_t x)
{
    if (x > 32767) {
        return IMF_Q15_MAX;
    }
    if (x < -32768) {
        return IMF_Q15_MIN;
    }
    return (int16_t)x;
}

/* int32 -> symmetric q15 [-32767, 32767]: squares of it sum without
 * wrapping (4 * 32767^2 < 2^32). */
static inline int16_t imf_sat_q15s(const int32_t x)
{
    if (x > 32767) {
        return IMF_Q15_MAX;
    }
    if (x < -32767) {
        return (int16_t)-32767;
    }
    return (int16_t)x;
}

/* a + b, results are saturated to [INT32_MIN, INT32_MAX]. */
static inline int32_t imf_add_sat32(const int32_t a, const int32_t b)
{
#if defined(__AVR__)
    /* the same value: add, and on signed overflow (V) the bound of the
     * true sign, which is the opposite of the wrapped sum's */
    int32_t r = a;
    __asm__("add %A[r], %A[b]\n\t"
            "adc %B[r], %B[b]\n\t"
            "adc %C[r], %C[b]\n\t"
            "adc %D[r], %D[b]\n\t"
            "brvc 1f\n\t"
            "lsl %D[r]\n\t"
            "sbc %A[r], %A[r]\n\t"
            "mov %B[r], %A[r]\n\t"
            "mov %C[r], %A[r]\n\t"
            "mov %D[r], %A[r]\n\t"
            "subi %D[r], 0x80\n"
            "1:"
            : [r] "+d"(r)
            : [b] "r"(b));
    return r;
#else
    if (b > 0 && a > IMF_INT32_MAX - b) {
        return IMF_INT32_MAX;
    }
    if (b < 0 && a < IMF_INT32_MIN - b) {
        return IMF_INT32_MIN;
    }
    return a + b;
#endif
}

/* a - b, results are saturated to [INT32_MIN, INT32_MAX]. */
static inline int32_t imf_sub_sat32(const int32_t a, const int32_t b)
{
#if defined(__AVR__)
    int32_t r = a; /* as imf_add_sat32 */
    __asm__("sub %A[r], %A[b]\n\t"
            "sbc %B[r], %B[b]\n\t"
            "sbc %C[r], %C[b]\n\t"
            "sbc %D[r], %D[b]\n\t"
            "brvc 1f\n\t"
            "lsl %D[r]\n\t"
            "sbc %A[r], %A[r]\n\t"
            "mov %B[r], %A[r]\n\t"
            "mov %C[r], %A[r]\n\t"
            "mov %D[r], %A[r]\n\t"
            "subi %D[r], 0x80\n"
            "1:"
            : [r] "+d"(r)
            : [b] "r"(b));
    return r;
#else
    if (b < 0 && a > IMF_INT32_MAX + b) {
        return IMF_INT32_MAX;
    }
    if (b > 0 && a < IMF_INT32_MIN + b) {
        return IMF_INT32_MIN;
    }
    return a - b;
#endif
}

/* q15 + q15, saturated to q15 (the int32 sum is exact). */
static inline int16_t imf_add_sat_q15(const int16_t a, const int16_t b)
{
    return imf_sat_q15((int32_t)a + (int32_t)b);
}

/* q15 - q15, saturated to q15. */
static inline int16_t imf_sub_sat_q15(const int16_t a, const int16_t b)
{
    return imf_sat_q15((int32_t)a - (int32_t)b);
}

/* ---- multiplies ---------------------------------------------------- */

/* int16 x int16 -> int32, exact.  avr-gcc often keeps sign-extended 16-bit
 * operands in 32-bit registers and then calls the 32x32 __mulsi3; on AVR
 * this is the inline MULS/MULSU/MUL sequence of Atmel's AVR201 (four 8x8
 * multiplies), elsewhere the plain C product. */
static inline int32_t imf_mul16(const int16_t a, const int16_t b)
{
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
    int32_t r;
    uint8_t z;
    __asm__("clr %[z]\n\t"
            "muls %B[a], %B[b]\n\t"
            "movw %C[r], r0\n\t"
            "mul %A[a], %A[b]\n\t"
            "movw %A[r], r0\n\t"
            "mulsu %B[a], %A[b]\n\t"
            "sbc %D[r], %[z]\n\t"
            "add %B[r], r0\n\t"
            "adc %C[r], r1\n\t"
            "adc %D[r], %[z]\n\t"
            "mulsu %B[b], %A[a]\n\t"
            "sbc %D[r], %[z]\n\t"
            "add %B[r], r0\n\t"
            "adc %C[r], r1\n\t"
            "adc %D[r], %[z]\n\t"
            "clr __zero_reg__"
            : [r] "=&r"(r), [z] "=&r"(z)
            : [a] "a"(a), [b] "a"(b));
    return r;
#else
    return (int32_t)a * (int32_t)b;
#endif
}

/* uint16 x uint16 -> uint32, exact (AVR: four inline MULs, no library
 * call; elsewhere the plain C product). */
static inline uint32_t imf_mulu16(const uint16_t a, const uint16_t b)
{
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
    uint32_t r;
    uint8_t z;
    __asm__("clr %[z]\n\t"
            "mul %B[a], %B[b]\n\t"
            "movw %C[r], r0\n\t"
            "mul %A[a], %A[b]\n\t"
            "movw %A[r], r0\n\t"
            "mul %B[a], %A[b]\n\t"
            "add %B[r], r0\n\t"
            "adc %C[r], r1\n\t"
            "adc %D[r], %[z]\n\t"
            "mul %B[b], %A[a]\n\t"
            "add %B[r], r0\n\t"
            "adc %C[r], r1\n\t"
            "adc %D[r], %[z]\n\t"
            "clr __zero_reg__"
            : [r] "=&r"(r), [z] "=&r"(z)
            : [a] "r"(a), [b] "r"(b));
    return r;
#else
    return (uint32_t)a * (uint32_t)b;
#endif
}

/* int16 x uint16 -> int32, exact (|x m| < 2^31).  AVR: inline MULSU/MUL. */
static inline int32_t imf_mul16su(const int16_t a, const uint16_t b)
{
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
    int32_t r;
    uint8_t z;
    __asm__("clr %[z]\n\t"
            "mulsu %B[a], %B[b]\n\t"
            "movw %C[r], r0\n\t"
            "mul %A[a], %A[b]\n\t"
            "movw %A[r], r0\n\t"
            "mulsu %B[a], %A[b]\n\t"
            "sbc %D[r], %[z]\n\t"
            "add %B[r], r0\n\t"
            "adc %C[r], r1\n\t"
            "adc %D[r], %[z]\n\t"
            "mul %A[a], %B[b]\n\t"
            "add %B[r], r0\n\t"
            "adc %C[r], r1\n\t"
            "adc %D[r], %[z]\n\t"
            "clr __zero_reg__"
            : [r] "=&r"(r), [z] "=&r"(z)
            : [a] "a"(a), [b] "a"(b));
    return r;
#else
    return (int32_t)a * (int32_t)b;
#endif
}

/* q15 * q15 -> q15, rounded to nearest; the only overflow,
 * (-1) * (-1), saturates to 32767. One 16x16->32 multiply. */
static inline int16_t imf_mul_q15(const int16_t a, const int16_t b)
{
    return imf_sat_q15(imf_rshr32((int32_t)a * (int32_t)b, 15));
}

/* x 2^15 for an int16 x, exact (|x 2^15| <= 2^30); on AVR x 2^16 (byte moves), then one
 * shift right (avr-gcc compiles (int32_t)x * 32768 to a loop of fifteen one-bit shifts) */
static inline int32_t imf_x32768(const int16_t x)
{
#if defined(__AVR__)
    return imf_asr32((int32_t)x * 65536L, 1);
#else
    return (int32_t)x * 32768L;
#endif
}

/* q15 * q15 -> q30, exact (|a*b| <= 2^30 cannot overflow). */
static inline int32_t imf_mul_q15_q30(const int16_t a, const int16_t b)
{
    return imf_mul16(a, b);
}

/* (a * b) / 2^n for int32 a, int16 b, n in [0, 47], rounded to nearest,
 * saturated to int32.  Exact to the 48-bit product without any 64-bit
 * type: a = ah*2^16 + al with al in [0, 2^16), so
 * a*b = (ah*b + asr(al*b, 16))*2^16 + (al*b mod 2^16) = m*2^16 + lol.
 * ah*b <= 2^30 and |al*b| < 2^31 fit int32 (two 16x16->32 multiplies). */
static inline int32_t imf_mul_32x16_k(const int32_t a, const int16_t b, const int n)
{
    /* two 16x16->32 products, imf_mul16su and imf_mul16 (AVR: inline MULs; as plain
     * (int32_t) products avr-gcc called the 32x32 __mulsi3 twice, 130 of a call's 385
     * cycles) */
    const int16_t ah = (int16_t)(a >> 16);                 /* in [-2^15, 2^15) */
    const uint16_t al = (uint16_t)((uint32_t)a & 0xFFFFu); /* in [0, 2^16) */
    const int32_t lo = imf_mul16su(b, al);                 /* |lo| < 2^31 */
    const int32_t m = imf_mul16(ah, b) + (lo >> 16);       /* |m| <= 2^30 + 2^15 */
    const int32_t lol = (int32_t)((uint32_t)lo & 0xFFFFu);
    if (n > 16) {
        /* floor((m*2^16 + lol)/2^n + 1/2) = floor((m + 2^(n-17))/2^(n-16))
         * because lol/2^16 < 1 cannot carry past a multiple of 2^(n-16). */
        return imf_rshr32(m, n - 16);
    }
    if (n == 16) {
        return m + (lol >> 15); /* |m| + 1 < 2^31 */
    }
    /* n < 16: m*2^(16-n) may leave int32: saturate.  Below -2^(15+n) the
     * sum is below INT32_MIN whatever the (non-negative) low part adds. */
#if !defined(__AVR__) && defined(__GNUC__)
    if (__builtin_constant_p(n) && (uint32_t)(m >> (14 + n)) + 1u <= 1u) {
        /* a shift known at compile time (with a run-time shift the larger
         * body is no longer inlined and costs more than it saves):
         * m >> (14 + n) in {-1, 0}, so |m 2^(16-n)| <= 2^30 and the rounded
         * low part <= 2^(16-n), no saturation: the same value without the
         * range tests */
        return m * ((int32_t)1 << (16 - n)) + ((lol + ((int32_t)1 << n >> 1)) >> n);
    }
#endif
    if (m < -(int32_t)imf_lsl32(1u, 15 + n)) {
        return IMF_INT32_MIN;
    }
    return imf_add_sat32(imf_shl_sat32(m, 16 - n),
                         imf_asr32(lol + (int32_t)(imf_lsl32(1u, n) >> 1), n));
}

#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
/* AVR, n in [17, 47] (every q-scale product of a gain below 1/2): imf_mul_32x16_k's value,
 * floor((m + 2^(n-17)) / 2^(n-16)) with m = floor(a b / 2^16) = ah b + floor(al b / 2^16),
 * in one block of eight 8x8 products on call-clobbered registers (the C function saved ten
 * call-saved registers on every call): L = al b (its bytes 1 to 3), m = ah b + (L >> 16),
 * then m shifted right by n - 17 (bytes, then bits) and once more, the bit shifted out
 * added back (imf_rshr32_v's rounding). */
static __attribute__((noinline, unused)) int32_t imf_mul_32x16_hi(const int32_t a, const int16_t b,
                                                                  const int n)
{
    register int32_t x __asm__("r22") = a;
    register int16_t y __asm__("r20") = b;
    register uint8_t k __asm__("r30") = (uint8_t)(n - 17);
    __asm__("movw r18, r24\n\t" /* ah: r19:r18 (MULSU takes r16..r23) */
            "clr r24\n\t"       /* zero */
            "mul r22, r20\n\t"  /* L = al b: bytes 1..3 in r26, r27, r31 */
            "mov r26, r1\n\t"
            "clr r27\n\t"
            "clr r31\n\t"
            "mul r23, r20\n\t"
            "add r26, r0\n\t"
            "adc r27, r1\n\t"
            "adc r31, r24\n\t"
            "mulsu r21, r22\n\t"
            "sbc r31, r24\n\t"
            "add r26, r0\n\t"
            "adc r27, r1\n\t"
            "adc r31, r24\n\t"
            "mulsu r21, r23\n\t"
            "add r27, r0\n\t"
            "adc r31, r1\n\t"
            "muls r19, r21\n\t" /* m = ah b: r25..r22 */
            "movw r24, r0\n\t"
            "mul r18, r20\n\t"
            "movw r22, r0\n\t"
            "clr r26\n\t" /* zero */
            "mulsu r19, r20\n\t"
            "sbc r25, r26\n\t"
            "add r23, r0\n\t"
            "adc r24, r1\n\t"
            "adc r25, r26\n\t"
            "mulsu r21, r18\n\t"
            "sbc r25, r26\n\t"
            "add r23, r0\n\t"
            "adc r24, r1\n\t"
            "adc r25, r26\n\t"
            "mov r0, r31\n\t" /* m += L >> 16, sign-extended */
            "lsl r0\n\t"
            "sbc r0, r0\n\t"
            "add r22, r27\n\t"
            "adc r23, r31\n\t"
            "adc r24, r0\n\t"
            "adc r25, r0\n"
            "1:\n\t" /* m >>= n - 17: bytes */
            "cpi r30, 8\n\t"
            "brlo 2f\n\t"
            "mov r22, r23\n\t"
            "mov r23, r24\n\t"
            "mov r24, r25\n\t"
            "lsl r25\n\t"
            "sbc r25, r25\n\t"
            "subi r30, 8\n\t"
            "rjmp 1b\n"
            "2:\n\t" /* bits */
            "tst r30\n\t"
            "breq 4f\n"
            "3:\n\t"
            "asr r25\n\t"
            "ror r24\n\t"
            "ror r23\n\t"
            "ror r22\n\t"
            "dec r30\n\t"
            "brne 3b\n"
            "4:\n\t" /* once more, the bit shifted out added back */
            "asr r25\n\t"
            "ror r24\n\t"
            "ror r23\n\t"
            "ror r22\n\t"
            "adc r22, r26\n\t"
            "adc r23, r26\n\t"
            "adc r24, r26\n\t"
            "adc r25, r26\n\t"
            "clr r1"
            : "+r"(x), "+d"(k)
            : "r"(y)
            : "r0", "r18", "r19", "r26", "r27", "r31");
    return x;
}

/* AVR, n in [0, 16] (gains of 1/4 and more): imf_mul_32x16_k's value in one compact copy.
 * With m 2^16 + lol the product plus 2^(n-1) (the carry of lol into m), the result is
 * m 2^(16-n) + lol 2^-n, the low part below 2^(16-n): m doubled 16 - n times, saturated
 * where a doubling leaves int32, then the low part added (it cannot carry past int32). */
static __attribute__((noinline, unused)) int32_t imf_mul_32x16_lo(const int32_t a, const int16_t b,
                                                                  const int n)
{
    const int32_t lo = imf_mul16su(b, (uint16_t)((uint32_t)a & 0xFFFFu)); /* |lo| < 2^31 */
    int32_t m = imf_mul16((int16_t)(a >> 16), b) + (lo >> 16);            /* |m| <= 2^30 + 2^15 */
    uint16_t lol = (uint16_t)((uint32_t)lo & 0xFFFFu);
    int k;
    if (n > 0) {
        const uint16_t h = (uint16_t)(1u << (n - 1));
        lol = (uint16_t)(lol + h);
        if (lol < h) {
            m++; /* the carry: m < 2^30 + 2^15, no overflow */
        }
    }
    for (k = n; k < 16; ++k) {
        if (m >= 1073741824L) {
            return IMF_INT32_MAX;
        }
        if (m < -1073741824L) {
            return IMF_INT32_MIN;
        }
        m *= 2;
    }
    return m + (int32_t)(lol >> n);
}

IMF_AVR_OUTLINE int32_t imf_mul_32x16_v(const int32_t a, const int16_t b, const int n)
{
    if (n > 16 && n <= 47) {
        return imf_mul_32x16_hi(a, b, n);
    }
    return imf_mul_32x16_lo(a, b, n);
}
#else
IMF_AVR_OUTLINE int32_t imf_mul_32x16_v(const int32_t a, const int16_t b, const int n)
{
    return imf_mul_32x16_k(a, b, n);
}
#endif

static inline int32_t imf_mul_32x16(const int32_t a, const int16_t b, const int n)
{
    if (IMF_AVR_VARIABLE(n)) {
        return imf_mul_32x16_v(a, b, n);
    }
    return imf_mul_32x16_k(a, b, n);
}

/* int16 x (an integer count, or qK: then pass N - K) times a q-scale
 * constant, result x * c * 2^N, rounded, saturated.  One 16x16->32 multiply
 * and a shift by c.s - N, which must lie in [-31, 31]. */
static inline int32_t imf_scale16(const int16_t x, const imf_qscale_t c, const int N)
{
    return imf_rshift_sat32(imf_mul16(x, c.m), c.s - N);
}

/* int32 x (in qK) times a q-scale constant, result in qN, rounded,
 * saturated (x * c * 2^(N-K)).  Needs c.s - N + K in [0, 47]; callers
 * check this at init. */
static inline int32_t imf_scale32(const int32_t x, const imf_qscale_t c, const int K, const int N)
{
    return imf_mul_32x16(x, c.m, c.s + K - N);
}

/* 8-bit profile: a q-scale constant prepared at init for the products
 * x * c * 2^N (x int16) of one update, so that the update has no run-time
 * shift count: n = c.s - N; for n >= 15 the mantissa is rounded to a shift
 * of exactly 16 (high word, byte moves): m = c.m 2^(16 - n) in [0, 2^16)
 * (unsigned; exact for n = 15, 16; the product's extra error is <= 1/4
 * LSB); other n keep c.m with its shift (general path, out of line). */
typedef struct {
    uint16_t m; /* mantissa */
    int16_t n;  /* 16, or the general shift c.s - N */
} imf_gain8_t;

IMF_AVR_OUTLINE int32_t imf_rshift_sat32_ool(const int32_t x, const int n)
{
    return imf_rshift_sat32(x, n);
}

IMF_AVR_OUTLINE imf_gain8_t imf_gain8(const imf_qscale_t c, const int N)
{
    imf_gain8_t g;
    const int n = c.s - N;
    if (n == 15) {
        g.m = (uint16_t)((uint16_t)c.m * 2u);
        g.n = 16;
    } else if (n >= 16) {
        g.m = (uint16_t)imf_rshr32(c.m, n - 16);
        g.n = 16;
    } else {
        g.m = (uint16_t)c.m;
        g.n = (int16_t)n;
    }
    return g;
}

/* x * g, rounded to nearest, saturated: one 16x16->32 multiply and (on the
 * fast path) a shift by 16 taken from the high word. */
IMF_AVR_OUTLINE int32_t imf_gain8_mul(const int16_t x, const imf_gain8_t g)
{
    const int32_t p = imf_mul16su(x, g.m);
#if defined(__AVR__)
    /* the same value in one compact copy (only the slow gain paths call
     * it): imf_rshr32_v for n >= 0 (16 included); the rare left shift by
     * doublings, saturated where a doubling leaves int32 (bits 31 and 30
     * differ) */
    uint32_t u = (uint32_t)p;
    int n = g.n;
    if (n >= 0) {
        return imf_rshr32_v(p, n);
    }
    for (; n < 0; ++n) {
        if (((u ^ (u << 1)) & 0x80000000u) != 0u) {
            return p < 0 ? IMF_INT32_MIN : IMF_INT32_MAX;
        }
        u <<= 1;
    }
    return (int32_t)u;
#else
    if (g.n == 16) {
        return imf_rshr32(p, 16);
    }
    return imf_rshift_sat32_ool(p, g.n);
#endif
}

/* ---- square roots -------------------------------------------------- */

/* Integer square root: floor(sqrt(x)) for any uint32 x.  Bit by bit,
 * shifts and subtractions only (no multiply, no division). */
static inline uint16_t imf_isqrt_u32(uint32_t x)
{
    uint32_t res = 0u;
    uint32_t bit = (uint32_t)1 << 30;
    while (bit > x) {
        bit >>= 2;
    }
    while (bit != 0u) {
        if (x >= res + bit) {
            x -= res + bit;
            res = (res >> 1) + bit;
        } else {
            res >>= 1;
        }
        bit >>= 2;
    }
    return (uint16_t)res;
}

/* The operand and result type of imf_invsqrt_chord16 / imf_invsqrt_newton16
 * (values below 2^16): 16 bits on AVR, 32 elsewhere (no conversions). */
#if defined(__AVR__)
typedef uint16_t imf_invsqrt16_t;
#else
typedef uint32_t imf_invsqrt16_t;
#endif

/* The chord of the short inverse square roots (imf_invsqrt8_u32,
 * imf_invsqrt16_u32): y ~= 2^31 / sqrt(u 2^16) (< 2^16) for u = x / 2^16
 * in [2^14, 2^16), lowered to balance the error of the Newton step after
 * it: 64635 - floor(38 d / 32) below 2^15, 45691 - floor(27 d / 64) above,
 * as floor(38 d / 32) = d + floor(3 d / 16) for d < 2^14 and
 * floor(27 d / 64) = 27 floor(d / 64) + floor(27 (d mod 64) / 64): 16-bit
 * operations on AVR, 32-bit elsewhere (the same values). */
static inline imf_invsqrt16_t imf_invsqrt_chord16(const imf_invsqrt16_t u)
{
#if defined(__AVR__)
    uint16_t d, y;
    if (u < 32768u) {
        d = (uint16_t)(u - 16384u);
        y = (uint16_t)(64635u - (uint16_t)(d + (uint16_t)((uint16_t)(d * 3u) >> 4)));
    } else {
        d = (uint16_t)(u - 32768u);
        y = (uint16_t)(45691u
                       - (uint16_t)((uint16_t)((d >> 6) * 27u)
                                    + (uint16_t)((uint16_t)((d & 63u) * 27u) >> 6)));
    }
    return y;
#else
    uint32_t d, y;
    if (u < 32768u) {
        d = u - 16384u;
        y = 64635u - (d + ((d * 3u) >> 4));
    } else {
        d = u - 32768u;
        y = 45691u - ((d >> 6) * 27u + (((d & 63u) * 27u) >> 6));
    }
    return y;
#endif
}

/* One Newton step y <- y (3 - u y^2) / 2 of the short inverse square roots
 * (y in q15, u as in imf_invsqrt_chord16), after the chord or a previous
 * step: three unsigned 16x16->32 products.  From imf_invsqrt_chord16, u y^2
 * stays below 3 2^30 and the new y below 2^16 after each of two steps for
 * every u, and from imf_invsqrt_u32's chords after each of three
 * (tests/test_fixed_scale.py, tests/test_fixed_core.py run every u; the
 * twin raises otherwise): no clamp, no saturation.  16-bit operations on AVR (the rounding from the
 * high word: y w + 2^14 < 2^31), 32-bit elsewhere (the same values). */
static inline imf_invsqrt16_t imf_invsqrt_newton16(const imf_invsqrt16_t u, const imf_invsqrt16_t y)
{
#if defined(__AVR__)
    const uint16_t y2 = (uint16_t)((imf_mulu16(y, y) + 32768u) >> 16); /* q14 */
    const uint32_t t = imf_mulu16(u, y2);                              /* q30, < 3 2^30 */
    const uint16_t w = (uint16_t)((3221225472u - t) >> 16);
    const uint32_t r = imf_mulu16(y, w) + 16384u; /* (y w + 2^14) / 2^15 */
    return (uint16_t)((uint16_t)((uint16_t)(r >> 16) << 1) | (uint16_t)(((uint16_t)r) >> 15));
#else
    return (y * ((3221225472u - u * ((y * y + 32768u) >> 16)) >> 16) + 16384u) >> 15;
#endif
}

/* Inverse square root without division: for x > 0 returns y (unsigned
 * q15, in [2^15, 2^16)) and *shift so that
 *     1/sqrt(x) ~= y * 2^-(*shift),  *shift in [16, 31].
 * Relative error below 1e-4 (tested exhaustively over the mantissa).
 * x = 0 returns 0 with *shift = 0 (callers test for it).
 * Method: x' = x * 4^k in [2^30, 2^32), u = x'/2^32 in [1/4, 1),
 * a chord on [1/4,1/2) or [1/2,1) as first guess, then three Newton
 * steps y <- y (3 - u y^2) / 2 in unsigned 16x16->32 products. */
IMF_AVR_OUTLINE uint16_t imf_invsqrt_u32(uint32_t x, int *const shift)
{
    int e = 0;
    imf_invsqrt16_t u, y;
    int i;
    if (x == 0u) {
        *shift = 0;
        return 0u;
    }
    while (x < ((uint32_t)1 << 22)) {
        x <<= 8; /* unsigned: no UB; byte moves on 8-bit targets */
        e += 8;
    }
    while (x < ((uint32_t)1 << 30)) {
        x <<= 2;
        e += 2;
    }
    u = (imf_invsqrt16_t)(x >> 16); /* q16 in [2^14, 2^16) */
    /* chords through (1/4, 2), (1/2, sqrt 2) and (1/2, sqrt 2), (1, 1), q15 */
#if defined(__AVR__)
    /* the same values in 16-bit operations (imf_invsqrt_chord16's identities; the 32-bit
       shifts were loops of one-bit steps) */
    if (u < 32768u) {
        const uint16_t d = (uint16_t)(u - 16384u);
        y = (imf_invsqrt16_t)(65535u - (uint16_t)(d + (uint16_t)((uint16_t)(d * 3u) >> 4)));
    } else {
        const uint16_t d = (uint16_t)(u - 32768u);
        y = (imf_invsqrt16_t)(46341u
                              - (uint16_t)((uint16_t)((d >> 6) * 27u)
                                           + (uint16_t)((uint16_t)((d & 63u) * 27u) >> 6)));
    }
#else
    if (u < 32768u) {
        y = (imf_invsqrt16_t)(65535u
                              - (((uint32_t)(u - 16384u) * 38u) >> 5)); /* slope ~ 2(2-sqrt2)4 */
    } else {
        y = (imf_invsqrt16_t)(46341u
                              - (((uint32_t)(u - 32768u) * 27u) >> 6)); /* slope ~ (sqrt2-1)2 */
    }
#endif
    for (i = 0; i < 3; ++i) {
        /* from these chords too, u y^2 < 3 2^30 and y < 2^16 after every
         * step for every u (tests/test_fixed_core.py: the twin raises) */
        y = imf_invsqrt_newton16(u, y);
    }
    *shift = 31 - e / 2;
    return (uint16_t)y;
}

/* Short inverse square root of the 8-bit profile, for x in [2^28, 2^32)
 * (callers block-scale their vector first): returns y (unsigned q15) and
 * *e in {0, 1} so that 1/sqrt(x) ~= y * 2^(*e - 31).  Relative error below
 * 1.2e-3 (tested exhaustively over the mantissa): one chord (lowered to
 * balance the error) and one Newton step (imf_invsqrt_chord16,
 * imf_invsqrt_newton16), three unsigned 16x16->32 products, no loop.  Used
 * where only a direction matters (accelerometer, Madgwick's delta-s), so
 * the error scales a gain by at most 0.12 %. */
IMF_AVR_OUTLINE uint16_t imf_invsqrt8_u32(uint32_t x, int *const e)
{
    imf_invsqrt16_t u;
    *e = 0;
    if (x < ((uint32_t)1 << 30)) {
        x <<= 2;
        *e = 1;
    }
    u = (imf_invsqrt16_t)(x >> 16); /* q16 in [2^14, 2^16) */
    return (uint16_t)imf_invsqrt_newton16(u, imf_invsqrt_chord16(u));
}

/* ---- conversions --------------------------------------------------- */

/* q15 -> q30 exactly (multiply by 2^15; for negative values through the
 * product, not a left shift). */
static inline int32_t imf_q15_to_q30(const int16_t x)
{
    return (int32_t)x * 32768;
}

/* q30 -> q15, rounded to nearest, saturated to q15. */
static inline int16_t imf_q30_to_q15(const int32_t x)
{
    return imf_sat_q15(imf_rshr32(x, 15));
}

/* qN -> q15 (N in [15, 46]), rounded, saturated symmetric to +-32767.
 * On AVR, N = 29, 30, 31 (constants) take the same value in a few byte
 * operations: add the rounding bit 2^(N-16), shift left by 31 - N bit
 * steps (an overflow flag V on the add or on a step means the value is out
 * of range: saturate by its sign), and the high word is the result. */
#if defined(__AVR__)
#define IMF_QN_SAT_AVR \
    "brvc 3f\n\t" /* out of range: carry = sign */ \
    "2:\n\t" \
    "sbc %C[r], %C[r]\n\t" \
    "com %C[r]\n\t" \
    "mov %D[r], %C[r]\n\t" \
    "subi %D[r], 0x80\n" /* 0x7FFF, or 0x8000 if negative */ \
    "3:"
#endif
static inline int16_t imf_qn_to_q15s(const int32_t x, const int N)
{
#if defined(__AVR__)
    if (N == 29 || N == 30 || N == 31) {
        int32_t r = x;
        int16_t v;
        if (N == 31) {
            __asm__("lsl %B[r]\n\t" /* C = bit 15: the rounding */
                    "adc %C[r], __zero_reg__\n\t"
                    "adc %D[r], __zero_reg__\n\t"
                    "clc\n\t" /* overflow: positive */
                    IMF_QN_SAT_AVR
                    : [r] "+d"(r));
        } else if (N == 30) {
            __asm__("subi %B[r], 0xC0\n\t" /* + 2^14 */
                    "sbci %C[r], 0xFF\n\t"
                    "sbci %D[r], 0xFF\n\t"
                    "clc\n\t"
                    "brvs 2f\n\t" /* overflow: positive */
                    "lsl %B[r]\n\t"
                    "rol %C[r]\n\t"
                    "rol %D[r]\n\t" /* V = bit 31 ^ bit 30 */
                    IMF_QN_SAT_AVR
                    : [r] "+d"(r));
        } else {
            __asm__("subi %B[r], 0xE0\n\t" /* + 2^13 */
                    "sbci %C[r], 0xFF\n\t"
                    "sbci %D[r], 0xFF\n\t"
                    "clc\n\t"
                    "brvs 2f\n\t"
                    "lsl %B[r]\n\t"
                    "rol %C[r]\n\t"
                    "rol %D[r]\n\t"
                    "brvs 2f\n\t" /* carry = bit 31 */
                    "lsl %B[r]\n\t"
                    "rol %C[r]\n\t"
                    "rol %D[r]\n\t" IMF_QN_SAT_AVR
                    : [r] "+d"(r));
        }
        v = (int16_t)(r >> 16);
        return (v < -32767) ? (int16_t)-32767 : v;
    }
#endif
    return imf_sat_q15s(imf_rshr32(x, N - 15));
}

/* ---- 32x16 products in compact code outside AVR --------------------- */

/* imf_mul_32x16 (the same value, n in [0, 47]) for callers with a run-time
 * shift whose usual value is n > 16 (MahonyIMUQ's gains): outside AVR that
 * case stays inline (two products, then a rounding shift) and the rest
 * (n = 16, n < 16 with its saturation) is one out-of-line copy,
 * imf_mul_32x16_rest: each inlined copy of it cost a caller ~150 bytes on
 * the Cortex-M0.  On AVR, imf_mul_32x16 (out of line for a run-time
 * shift). */
#if !defined(__AVR__) && defined(__GNUC__)
/* (m 2^16 + lol) / 2^n rounded, saturated, n in [0, 16]: imf_mul_32x16_k's
 * tail (m its high part, lol in [0, 2^16) the low 16 bits) */
static __attribute__((noinline, unused)) int32_t imf_mul_32x16_rest(const int32_t m,
                                                                    const int32_t lol, const int n)
{
    if (n == 16) {
        return m + (lol >> 15);
    }
    if (m < -(int32_t)imf_lsl32(1u, 15 + n)) {
        return IMF_INT32_MIN;
    }
    return imf_add_sat32(imf_shl_sat32(m, 16 - n),
                         imf_asr32(lol + (int32_t)(imf_lsl32(1u, n) >> 1), n));
}
#endif

static inline int32_t imf_mul_32x16_s(const int32_t a, const int16_t b, const int n)
{
#if !defined(__AVR__) && defined(__GNUC__)
    const int16_t ah = (int16_t)(a >> 16);
    const uint16_t al = (uint16_t)((uint32_t)a & 0xFFFFu);
    const int32_t lo = (int32_t)al * (int32_t)b;
    const int32_t m = (int32_t)ah * (int32_t)b + (lo >> 16);
    const int32_t lol = (int32_t)((uint32_t)lo & 0xFFFFu);
    if (n > 16) {
        return imf_rshr32(m, n - 16);
    }
    return imf_mul_32x16_rest(m, lol, n);
#else
    return imf_mul_32x16(a, b, n);
#endif
}

/* imf_scale32 through imf_mul_32x16_s (shift c.s + K - N in [0, 47]). */
static inline int32_t imf_scale32_s(const int32_t x, const imf_qscale_t c, const int K, const int N)
{
    return imf_mul_32x16_s(x, c.m, c.s + K - N);
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_FIXED_H */
