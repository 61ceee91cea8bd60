/* csvfmt.h: rows of doubles as CSV text, each value printed as C's "%.17g"
 * (float64 columns) or "%.9g" (float32 columns widened to double): enough
 * digits that every value reads back to the same bits.
 *
 * Part of the compiled package's output path (imufuse_c/_csvout.pyx), not of
 * the embeddable filter library in csrc/ (which does no I/O).
 *
 * The text is the one of Python's "%.17g" % x / "%.9g" % x: the significand
 * correctly rounded (ties to even) to P significant digits; exponent style
 * when the decimal exponent X < -4 or X >= P, else fixed; trailing zeros
 * and a bare decimal point removed; an exponent of at least two digits.
 * Non-finite values are "nan", "inf", "-inf" (NaN sign never shown, as in
 * Python). "-0" keeps its sign.
 *
 * The digits are computed exactly with 128-bit integers when the value's
 * magnitude allows (about 1e-6 <= |x| < 1.7e38 for P = 17, 1e-14 <= |x| < 1.7e38
 * for P = 9);
 * otherwise (tiny values, or a compiler without unsigned __int128) by
 * snprintf, whose "%.*g" is correctly rounded in glibc, musl and the BSD and
 * macOS C libraries. No allocation, no global state: callable without the GIL.
 */
#ifndef IMUFUSE_CSVFMT_H
#define IMUFUSE_CSVFMT_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

/* the longest value text: "-" + 17 digits + "." + "e-308" = 25 chars */
#define CSVFMT_MAX_VALUE 32

#if defined(__SIZEOF_INT128__)
#define CSVFMT_HAVE_U128 1
typedef unsigned __int128 csvfmt_u128;
#else
#define CSVFMT_HAVE_U128 0
#endif

/* Lay out `ndig` significant digits (no trailing zeros beyond those given)
 * with decimal exponent X in %g style for precision P; returns the length. */
static int csvfmt_layout(char *out, int neg, const char *dig, int ndig, int X, int P)
{
    int n = 0, i;
    while (ndig > 1 && dig[ndig - 1] == '0')      /* %g drops trailing zeros */
        ndig--;
    if (neg)
        out[n++] = '-';
    if (X < -4 || X >= P) {                       /* d.ddde+XX */
        unsigned ax;
        out[n++] = dig[0];
        if (ndig > 1) {
            out[n++] = '.';
            for (i = 1; i < ndig; i++)
                out[n++] = dig[i];
        }
        out[n++] = 'e';
        out[n++] = X < 0 ? '-' : '+';
        ax = (unsigned)(X < 0 ? -X : X);
        if (ax >= 100)
            out[n++] = (char)('0' + ax / 100);
        out[n++] = (char)('0' + (ax / 10) % 10);
        out[n++] = (char)('0' + ax % 10);
    } else if (X < 0) {                           /* 0.000ddd */
        out[n++] = '0';
        out[n++] = '.';
        for (i = -1; i > X; i--)
            out[n++] = '0';
        for (i = 0; i < ndig; i++)
            out[n++] = dig[i];
    } else {                                      /* ddd[.ddd] */
        for (i = 0; i <= X; i++)
            out[n++] = i < ndig ? dig[i] : '0';
        if (ndig > X + 1) {
            out[n++] = '.';
            for (i = X + 1; i < ndig; i++)
                out[n++] = dig[i];
        }
    }
    return n;
}

/* Fallback: the C library's "%.*g" (correctly rounded), with a '.' radix
 * whatever LC_NUMERIC says. */
static int csvfmt_libc(char *out, double x, int P)
{
    int n = snprintf(out, CSVFMT_MAX_VALUE, "%.*g", P, x), i;
    if (n < 0 || n >= CSVFMT_MAX_VALUE)
        return -1;
    for (i = 0; i < n; i++)
        if (out[i] == ',')
            out[i] = '.';
    return n;
}

#if CSVFMT_HAVE_U128
/* Exact: D = round_half_even(|x| * 10^(P-1-X)) with 10^(P-1) <= D < 10^P.
 * Returns 0 when the magnitude is outside what 128 bits hold. */
static int csvfmt_exact(double ax, int P, uint64_t *D_out, int *X_out)
{
    static const uint64_t p10[20] = {
        1ull, 10ull, 100ull, 1000ull, 10000ull, 100000ull, 1000000ull, 10000000ull,
        100000000ull, 1000000000ull, 10000000000ull, 100000000000ull,
        1000000000000ull, 10000000000000ull, 100000000000000ull,
        1000000000000000ull, 10000000000000000ull, 100000000000000000ull,
        1000000000000000000ull, 10000000000000000000ull};
    int e2, X, tries;
    double f = frexp(ax, &e2);                    /* ax = f * 2^e2, f in [0.5, 1) */
    uint64_t m = (uint64_t)ldexp(f, 53);          /* exact: ax = m * 2^(e2 - 53) */
    int e = e2 - 53;
    const uint64_t lo = p10[P - 1], hi = p10[P];
    /* decimal exponent estimate: floor(log10(ax)) is X or X - 1 */
    X = (int)floor((e2 - 1) * 0.30102999566398120);
    for (tries = 0; tries < 3; tries++) {
        int s = P - 1 - X;                        /* scale by 10^s */
        csvfmt_u128 num, den, q, r, half;
        (void)den;
        if (s >= 0) {
            csvfmt_u128 scale;
            if (s > 38)
                return 0;
            /* 10^38 < 2^128 */
            scale = s > 19 ? (csvfmt_u128)p10[19] * p10[s - 19] : (csvfmt_u128)p10[s];
            if (scale > ((csvfmt_u128)-1) / m)   /* m * 10^s must fit */
                return 0;
            num = (csvfmt_u128)m * scale;
            if (e >= 0) {
                if (e > 60 || (num >> (127 - e)) != 0)
                    return 0;
                q = num << e;
                r = 0;                            /* exact: no rounding */
                half = 1;
            } else {
                if (-e > 127)
                    return 0;
                den = (csvfmt_u128)1 << (-e);
                q = num >> (-e);
                r = num & (den - 1);
                half = den >> 1;
            }
        } else {                                  /* divide by 10^-s */
            if (-s > 38 || e > 74 || e < 0)
                return 0;
            num = (csvfmt_u128)m << e;
            den = -s > 19 ? (csvfmt_u128)p10[19] * p10[-s - 19] : (csvfmt_u128)p10[-s];
            q = num / den;
            r = num % den;
            half = den >> 1;                      /* den even: exact half */
        }
        if (q >= hi) {
            X++;
            continue;
        }
        if (q < lo) {
            X--;
            continue;
        }
        {
            uint64_t d = (uint64_t)q;
            if (r > half || (r == half && r != 0 && (d & 1u)))
                d++;
            if (d == hi) {                        /* 99.99 rounded up to 100.0 */
                d = lo;
                X++;
            }
            *D_out = d;
            *X_out = X;
            return 1;
        }
    }
    return 0;
}
#endif

/* One value as %.{P}g text (P = 9 or 17) into out (CSVFMT_MAX_VALUE bytes);
 * returns the length, or -1 (never for a finite or non-finite double). */
static int csvfmt_value(char *out, double x, int P)
{
    if (isnan(x)) {
        memcpy(out, "nan", 3);
        return 3;
    }
    if (isinf(x)) {
        if (x < 0) {
            memcpy(out, "-inf", 4);
            return 4;
        }
        memcpy(out, "inf", 3);
        return 3;
    }
    if (x == 0.0) {
        if (signbit(x)) {
            memcpy(out, "-0", 2);
            return 2;
        }
        out[0] = '0';
        return 1;
    }
#if CSVFMT_HAVE_U128
    {
        uint64_t D;
        int X, i;
        char dig[20];
        if (csvfmt_exact(fabs(x), P, &D, &X)) {
            for (i = P - 1; i >= 0; i--) {
                dig[i] = (char)('0' + (int)(D % 10u));
                D /= 10u;
            }
            return csvfmt_layout(out, x < 0, dig, P, X, P);
        }
    }
#endif
    return csvfmt_libc(out, x, P);
}

/* Rows [r0, r1) of ncol columns as CSV lines ("," between values, "\n"
 * after each row) into out, which holds at least
 * (r1 - r0) * ncol * (CSVFMT_MAX_VALUE + 1) bytes. Column j's value of row r
 * is the double at (const char *)cols[j] + r * stride[j] (bytes), printed
 * with precision prec[j]. Returns the bytes written, or -1 when a value could
 * not be formatted. */
static long csvfmt_rows(char *out, const char *const *cols, const long *stride,
                        const int *prec, int ncol, long r0, long r1)
{
    long r, n = 0;
    int j, k;
    double x;
    for (r = r0; r < r1; r++) {
        for (j = 0; j < ncol; j++) {
            memcpy(&x, cols[j] + r * stride[j], sizeof x);
            k = csvfmt_value(out + n, x, prec[j]);
            if (k < 0)
                return -1;
            n += k;
            out[n++] = j + 1 < ncol ? ',' : '\n';
        }
    }
    return n;
}

#endif /* IMUFUSE_CSVFMT_H */
