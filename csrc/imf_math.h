/*
 * imufuse math helpers: header-only, static inline, no state.
 */
#ifndef IMF_MATH_H
#define IMF_MATH_H

#include <stdint.h>
#include <string.h>

#include "imf_config.h"

#ifdef __cplusplus
extern "C" {
#endif

/*
 * Valid-attitude policy shared by every filter (docs/robustness.md): a sample
 * with a NaN or +-Inf input, or whose update would leave the state
 * non-finite or no longer a valid attitude -- a normalisation that fails
 * (squared norm zero, subnormal or overflowed: imf_normalise3/4), a DCM that
 * is no longer orthonormal, a gravity vector of implausible length -- is
 * rejected. The state keeps its previous value and the filter's `skipped`
 * counter is incremented. The state therefore is always a valid attitude.
 */
static inline int imf_finite2(const imf_real a, const imf_real b)
{
    return isfinite(a) && isfinite(b);
}

static inline int imf_finite3(const imf_real a, const imf_real b, const imf_real c)
{
    return isfinite(a) && isfinite(b) && isfinite(c);
}

static inline int imf_finite4(const imf_real a, const imf_real b, const imf_real c,
                              const imf_real d)
{
    return imf_finite2(a, b) && imf_finite2(c, d);
}

/* ---- inverse square root and normalisation ------------------------------
 *
 * Filters that normalise vectors take an `invsqrt` option:
 *   IMF_INVSQRT_EXACT  1/sqrt(x): two correctly rounded operations.
 *   IMF_INVSQRT_FAST   the 0x5f3759df estimate refined by one Newton step,
 *                      as in Madgwick's published C (x-io, 2010-2012):
 *                      relative error up to about 1.8e-3.
 * Either way a normalisation is only done when it can succeed: the squared
 * norm must be a normal number (not zero, not subnormal, not overflowed, not
 * NaN) and its inverse square root finite and non-zero. Otherwise the vector
 * is left unchanged and the caller is told why (IMF_NORM_TINY: zero or
 * subnormal, no direction to keep; IMF_NORM_HUGE: overflowed), so that it can
 * reject the sample (valid-attitude policy above).
 */
enum { IMF_INVSQRT_EXACT = 0, IMF_INVSQRT_FAST = 1 };
enum { IMF_NORM_OK = 0, IMF_NORM_TINY = 1, IMF_NORM_HUGE = 2 };

static inline imf_real imf_invsqrt_exact(const imf_real x)
{
    return IMF_R(1.0) / imf_sqrt(x);
}

/*
 * Fast inverse square root. The float is reinterpreted as an unsigned
 * integer through memcpy (no pointer cast: no strict-aliasing violation, and
 * the width is exact, unlike `long`, which is 64-bit on LP64 hosts and would
 * read four bytes beyond the float). Unsigned arithmetic cannot overflow;
 * for x >= 0 (every caller passes a sum of squares) it equals the classic
 * 32-bit signed version bit for bit.
 * float32: 0x5f3759df; float64: the 64-bit constant 0x5fe6eb50c7b537a9
 * (Lomont), followed by the same Newton step y (1.5 - (x/2) y y).
 */
static inline imf_real imf_invsqrt_fast(const imf_real x)
{
    const imf_real halfx = IMF_R(0.5) * x;
    imf_real y;
#ifdef IMF_DOUBLE
    uint64_t i;
    memcpy(&i, &x, sizeof i);
    i = UINT64_C(0x5fe6eb50c7b537a9) - (i >> 1);
#else
    uint32_t i;
    memcpy(&i, &x, sizeof i);
    i = UINT32_C(0x5f3759df) - (i >> 1);
#endif
    memcpy(&y, &i, sizeof y);
    return y * (IMF_R(1.5) - halfx * y * y);
}

static inline imf_real imf_invsqrt(const imf_real x, const int mode)
{
    return mode == IMF_INVSQRT_FAST ? imf_invsqrt_fast(x) : imf_invsqrt_exact(x);
}

/* The inverse norm r of a squared norm n2 (IMF_NORM_OK), or why there is
   none: n2 zero or subnormal (IMF_NORM_TINY), overflowed or NaN, or an
   inverse that is 0 or Inf (IMF_NORM_HUGE). */
static inline int imf_inverse_norm(const imf_real n2, const int mode, imf_real *const r)
{
    if (!(n2 <= IMF_REAL_MAX)) {
        return IMF_NORM_HUGE;
    }
    if (n2 < IMF_REAL_MIN) {
        return IMF_NORM_TINY;
    }
    *r = imf_invsqrt(n2, mode);
    return *r > IMF_R(0.0) && *r <= IMF_REAL_MAX ? IMF_NORM_OK : IMF_NORM_HUGE;
}

/* Scale (x, y, z) to unit length (squared norm summed left to right); on
   failure leave it unchanged and return IMF_NORM_TINY or IMF_NORM_HUGE. */
static inline int imf_normalise3(imf_real *const x, imf_real *const y, imf_real *const z,
                                 const int mode)
{
    imf_real r = IMF_R(0.0);
    const int rc = imf_inverse_norm(*x * *x + *y * *y + *z * *z, mode, &r);
    if (rc != IMF_NORM_OK) {
        return rc;
    }
    *x *= r;
    *y *= r;
    *z *= r;
    return IMF_NORM_OK;
}

/* Scale the quaternion (or any 4-vector) (w, x, y, z) to unit length; on
   failure leave it unchanged and return IMF_NORM_TINY or IMF_NORM_HUGE. */
static inline int imf_normalise4(imf_real *const w, imf_real *const x, imf_real *const y,
                                 imf_real *const z, const int mode)
{
    imf_real r = IMF_R(0.0);
    const int rc = imf_inverse_norm(*w * *w + *x * *x + *y * *y + *z * *z, mode, &r);
    if (rc != IMF_NORM_OK) {
        return rc;
    }
    *w *= r;
    *x *= r;
    *y *= r;
    *z *= r;
    return IMF_NORM_OK;
}

/* A gravity-vector estimate (multiwii, mahony2d) is a valid attitude while
   its squared length is a normal number (a direction to read angles from)
   and at most d2_max (never NaN). */
static inline int imf_gravity_ok(const imf_real dx, const imf_real dy, const imf_real dz,
                                 const imf_real d2_max)
{
    const imf_real n2 = dx * dx + dy * dy + dz * dz;
    return n2 >= IMF_REAL_MIN && n2 <= d2_max;
}

/* All three components exactly zero (+0 or -0): a sensor that reports no
   measurement. Madgwick's published code skips the correction then. */
static inline int imf_is_zero3(const imf_real x, const imf_real y, const imf_real z)
{
    return x == IMF_R(0.0) && y == IMF_R(0.0) && z == IMF_R(0.0);
}

/* ---- quaternions ----------------------------------------------------------
 * Twins in imufuse.reference._math (qmul, qrotate), the same operations in the same order. */

/* The Hamilton product a (x) b into o[4]. */
static inline void imf_qmul(imf_real *const o, const imf_real a0, const imf_real a1,
                            const imf_real a2, const imf_real a3, const imf_real b0,
                            const imf_real b1, const imf_real b2, const imf_real b3)
{
    o[0] = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3;
    o[1] = a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2;
    o[2] = a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1;
    o[3] = a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0;
}

/* The vector v rotated by the unit quaternion q = (w, x, y, z), into o[3]:
   R(q) v = v + w t + q_v x t, t = 2 q_v x v. */
static inline void imf_qrotate(imf_real *const o, const imf_real w, const imf_real x,
                               const imf_real y, const imf_real z, const imf_real vx,
                               const imf_real vy, const imf_real vz)
{
    const imf_real tx = IMF_R(2.0) * (y * vz - z * vy);
    const imf_real ty = IMF_R(2.0) * (z * vx - x * vz);
    const imf_real tz = IMF_R(2.0) * (x * vy - y * vx);
    o[0] = vx + w * tx + (y * tz - z * ty);
    o[1] = vy + w * ty + (z * tx - x * tz);
    o[2] = vz + w * tz + (x * ty - y * tx);
}

/* ---- gravity-vector filters (multiwii, kk, mahony2d, dcm) ---------------
 * Outputs only, never part of a state update (docs/internals.md, numerical contract 5): roll
 * and pitch (rad, ZYX aerospace sequence as in imufuse.rotations) of the
 * attitude whose body-frame "up" vector R^T e_z is (dx, dy, dz) (any length
 * > 0). Evaluated in double with libm; Python's math.atan2/math.sqrt are the
 * same functions, so both backends return the same bits. */
static inline void imf_tilt_angles(const double dx, const double dy, const double dz,
                                   double *const roll, double *const pitch)
{
    *roll = atan2(dy, dz);
    *pitch = atan2(-dx, sqrt(dy * dy + dz * dz));
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_MATH_H */
