/*
 * imf_fixed_init.h -- init-time conversions from double parameters to
 * fixed-point constants.  Used by the filters' _init functions only (never
 * in an update), so the update code needs neither libm nor floating point.
 * Mirrored by qscale() in python/imufuse/reference/_cint.py.
 *
 * Note for AVR: avr-gcc's double may be 32 bits wide; constants computed
 * there can differ in the last mantissa bit from a host computation.
 */
#ifndef IMF_FIXED_INIT_H
#define IMF_FIXED_INIT_H

#include <math.h>
#include "imf_fixed.h"

#ifdef __cplusplus
extern "C" {
#endif

/* v >= 0 -> m * 2^-s with m = floor(f * 2^15 + 1/2), v = f * 2^e,
 * f in [1/2, 1) (frexp is exact); 0 -> {0, 16}.  Returns {0, 16} for
 * negative or non-finite v; callers validate v first. */
static inline imf_qscale_t imf_qscale_from_double(const double v)
{
    imf_qscale_t c;
    int e = 0;
    double f, m;
    c.m = 0;
    c.s = 16;
    if (!(v > 0.0) || !(v - v == 0.0)) { /* negative, zero, NaN or +inf */
        return c;
    }
    f = frexp(v, &e);
    m = floor(f * 32768.0 + 0.5);
    if (m >= 32768.0) {
        m = 16384.0;
        e += 1;
    }
    if (15 - e < -16 || 15 - e > 62) {
        return c;
    }
    c.m = (int16_t)m;
    c.s = (int16_t)(15 - e);
    return c;
}

/* 1 if v is finite and in [lo, hi]. */
static inline int imf_param_ok(const double v, const double lo, const double hi)
{
    return (v >= lo) && (v <= hi);
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_FIXED_INIT_H */
