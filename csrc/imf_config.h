/*
 * imufuse build configuration: the one switch between float32 and float64.
 *
 * Every float filter is written once in terms of imf_real and IMF_R().
 *   default        imf_real is float; literals get the f suffix, so a float32
 *                  build never promotes to double (-Wdouble-promotion clean).
 *   -DIMF_DOUBLE   imf_real is double.
 *
 * Build every source with -std=c99 -O2 -ffp-contract=off. Without
 * -ffp-contract=off, GCC fuses a*b+c into one FMA on targets that have it
 * (x86 with FMA, Cortex-M4F) and the results no longer match the reference
 * bit for bit. Never build with -ffast-math.
 */
#ifndef IMF_CONFIG_H
#define IMF_CONFIG_H

#include <float.h>
#include <math.h>

#ifdef IMF_DOUBLE
typedef double imf_real;
#define IMF_R(x) (x)
#define imf_sqrt(x) sqrt(x)
#define IMF_REAL_MIN DBL_MIN /* smallest normal imf_real */
#define IMF_REAL_MAX DBL_MAX /* largest finite imf_real */
#else
typedef float imf_real;
#define IMF_R(x) (x##f)
#define imf_sqrt(x) sqrtf(x)
#define IMF_REAL_MIN FLT_MIN
#define IMF_REAL_MAX FLT_MAX
#endif

#endif /* IMF_CONFIG_H */
