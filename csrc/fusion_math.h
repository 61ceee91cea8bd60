/*
 * Vector and quaternion helpers of the Fusion suite (Longbin's walkthrough of x-io Fusion as
 * shipped in imufusion 1.2.3). Header-only, static inline, no state.
 *
 * Small value types passed by value, as Fusion does. Each helper evaluates
 * its expression in the order Fusion's inline functions do (left to right,
 * the same grouping), so that a float32 build reproduces imufusion 1.2.3 bit
 * for bit. Units: angles in degrees at the interface, radians inside.
 */
#ifndef IMF_FUSION_MATH_H
#define IMF_FUSION_MATH_H

#include <float.h>
#include <stdint.h>
#include <string.h>

#include "imf_config.h"
#include "imf_math.h" /* imf_finite3, imf_finite4 */

#ifdef __cplusplus
extern "C" {
#endif

/* Transcendentals in the precision of the build: Fusion calls the float
   functions (sinf, cosf, atan2f, asinf) in its state update (set heading,
   external heading, settings) and in its outputs; a float32 build calls the
   same functions, so the results are the same bits. */
#ifdef IMF_DOUBLE
#define imf_fusion_sin(x) sin(x)
#define imf_fusion_cos(x) cos(x)
#define imf_fusion_atan2(y, x) atan2(y, x)
#define imf_fusion_asin(x) asin(x)
#define IMF_FUSION_REAL_MAX DBL_MAX
#define IMF_FUSION_PI (3.14159265358979323846)
#else
/* the casts: avr-libc defines sinf etc. as its 32-bit double functions */
#define imf_fusion_sin(x) ((imf_real)sinf(x))
#define imf_fusion_cos(x) ((imf_real)cosf(x))
#define imf_fusion_atan2(y, x) ((imf_real)atan2f(y, x))
#define imf_fusion_asin(x) ((imf_real)asinf(x))
#define IMF_FUSION_REAL_MAX FLT_MAX
#define IMF_FUSION_PI (3.14159265358979323846f) /* pi rounded to float, as (float) M_PI */
#endif

/* Earth frame conventions, numbered as FusionConvention. */
enum { IMF_FUSION_NWU = 0, IMF_FUSION_ENU = 1, IMF_FUSION_NED = 2 };

/* Inverse square root used by every normalisation of the suite. */
enum { IMF_FUSION_INVSQRT_EXACT = 0, IMF_FUSION_INVSQRT_FAST = 1 };

typedef struct {
    imf_real x, y, z; /* components */
} imf_fusion_vec_t;

typedef struct {
    imf_real w, x, y, z; /* w first */
} imf_fusion_quat_t;

/* Row-major 3x3 matrix: m[0..2] first row (xx, xy, xz), as FusionMatrix. */
typedef struct {
    imf_real m[9]; /* row major */
} imf_fusion_mat_t;

/* |x| for the threshold comparisons (gyroscope range, rest detection): the
   comparisons give the results of fabs/fabsf for every input (-0 and NaN
   included); a function of the build type, unlike avr-libc's fabsf macro,
   which returns double. */
static inline imf_real imf_fusion_fabs(const imf_real x)
{
    return x < IMF_R(0.0) ? -x : x;
}

/* degrees * (pi / 180): the factor is rounded once, in the build precision */
static inline imf_real imf_fusion_deg2rad(const imf_real degrees)
{
    return degrees * (IMF_FUSION_PI / IMF_R(180.0));
}

static inline imf_real imf_fusion_rad2deg(const imf_real radians)
{
    return radians * (IMF_R(180.0) / IMF_FUSION_PI);
}

/* asin clamped to +-pi/2 outside [-1, 1] (a rounded argument may leave it) */
static inline imf_real imf_fusion_safe_asin(const imf_real value)
{
    if (value <= IMF_R(-1.0)) {
        return IMF_FUSION_PI / IMF_R(-2.0);
    }
    if (value >= IMF_R(1.0)) {
        return IMF_FUSION_PI / IMF_R(2.0);
    }
    return imf_fusion_asin(value);
}

/*
 * Fusion's fast inverse square root: the initial guess 0x5F1F1412 - (i >> 1)
 * on the float's bit image, then one modified Newton step
 * y (1.69000231 - 0.714158168 x y y) (constants of Fusion's FusionMath.h).
 * The bit image is read with memcpy into an unsigned integer (no aliasing
 * violation, no shift of a negative value); for x >= 0 it equals Fusion's
 * int32_t union version. float64: the same piecewise-linear guess lifted to
 * the double exponent range, 1.5 * 2^52 * 896 + 0x5F1F1412 * 2^29
 * = 0x5FE3E28240000000, and the same step with the constants in double.
 */
static inline imf_real imf_fusion_invsqrt_fast(const imf_real x)
{
    imf_real y;
#ifdef IMF_DOUBLE
    uint64_t i;
    memcpy(&i, &x, sizeof i);
    i = UINT64_C(0x5FE3E28240000000) - (i >> 1);
#else
    uint32_t i;
    memcpy(&i, &x, sizeof i);
    i = UINT32_C(0x5F1F1412) - (i >> 1);
#endif
    memcpy(&y, &i, sizeof y);
    return y * (IMF_R(1.69000231) - IMF_R(0.714158168) * x * y * y);
}

static inline int imf_fusion_vec_is_zero(const imf_fusion_vec_t v)
{
    return v.x == IMF_R(0.0) && v.y == IMF_R(0.0) && v.z == IMF_R(0.0);
}

static inline imf_fusion_vec_t imf_fusion_vec_add(const imf_fusion_vec_t a,
                                                  const imf_fusion_vec_t b)
{
    const imf_fusion_vec_t r = { a.x + b.x, a.y + b.y, a.z + b.z };
    return r;
}

static inline imf_fusion_vec_t imf_fusion_vec_sub(const imf_fusion_vec_t a,
                                                  const imf_fusion_vec_t b)
{
    const imf_fusion_vec_t r = { a.x - b.x, a.y - b.y, a.z - b.z };
    return r;
}

static inline imf_fusion_vec_t imf_fusion_vec_scale(const imf_fusion_vec_t v, const imf_real s)
{
    const imf_fusion_vec_t r = { v.x * s, v.y * s, v.z * s };
    return r;
}

static inline imf_fusion_vec_t imf_fusion_vec_hadamard(const imf_fusion_vec_t a,
                                                       const imf_fusion_vec_t b)
{
    const imf_fusion_vec_t r = { a.x * b.x, a.y * b.y, a.z * b.z };
    return r;
}

static inline imf_fusion_vec_t imf_fusion_vec_cross(const imf_fusion_vec_t a,
                                                    const imf_fusion_vec_t b)
{
    const imf_fusion_vec_t r = { a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z,
                                 a.x * b.y - a.y * b.x };
    return r;
}

/* dot product: the element products summed left to right */
static inline imf_real imf_fusion_vec_dot(const imf_fusion_vec_t a, const imf_fusion_vec_t b)
{
    const imf_fusion_vec_t h = imf_fusion_vec_hadamard(a, b);
    return h.x + h.y + h.z;
}

static inline imf_real imf_fusion_vec_norm2(const imf_fusion_vec_t v)
{
    return imf_fusion_vec_dot(v, v);
}

/*
 * v / |v|. Exact mode: 1 / sqrt(|v|^2), as Fusion built with
 * FUSION_USE_NORMAL_SQRT (imufusion's build). Zero-vector guard: a vector
 * whose squared norm is zero is returned unchanged, where Fusion computes
 * 0 * (1/0) = NaN and never recovers. Every other vector gives Fusion's bits.
 */
static inline imf_fusion_vec_t imf_fusion_vec_normalise(const imf_fusion_vec_t v, const int invsqrt)
{
    const imf_real n2 = imf_fusion_vec_norm2(v);
    imf_real r;
    if (invsqrt == IMF_FUSION_INVSQRT_FAST) {
        r = imf_fusion_invsqrt_fast(n2);
    } else {
        if (n2 == IMF_R(0.0)) {
            return v;
        }
        r = IMF_R(1.0) / imf_sqrt(n2);
    }
    return imf_fusion_vec_scale(v, r);
}

/*
 * The error angle (degrees) an output reports for a halved feedback or residual (fx, fy, fz):
 * asin(2 |v|), as FusionAhrsGetInternalStates computes it in 1.2.3 and 1.3.
 */
static inline imf_real imf_fusion_error_degrees(const imf_real fx, const imf_real fy,
                                                const imf_real fz)
{
    const imf_fusion_vec_t v = { fx, fy, fz };
    return imf_fusion_rad2deg(imf_fusion_safe_asin(IMF_R(2.0) * imf_sqrt(imf_fusion_vec_norm2(v))));
}

/* A recovery trigger as the fraction of its period (1.2.3) or timeout (1.3); 0 without one. */
static inline imf_real imf_fusion_trigger_ratio(const int32_t trigger, const int32_t period)
{
    return period == 0 ? IMF_R(0.0) : (imf_real)trigger / (imf_real)period;
}

static inline imf_fusion_quat_t imf_fusion_quat_add(const imf_fusion_quat_t a,
                                                    const imf_fusion_quat_t b)
{
    const imf_fusion_quat_t r = { a.w + b.w, a.x + b.x, a.y + b.y, a.z + b.z };
    return r;
}

/* Hamilton product a (x) b */
static inline imf_fusion_quat_t imf_fusion_quat_mul(const imf_fusion_quat_t a,
                                                    const imf_fusion_quat_t b)
{
    const imf_fusion_quat_t r = {
        a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
        a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
        a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
        a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
    };
    return r;
}

/* q (x) (0, v) */
static inline imf_fusion_quat_t imf_fusion_quat_mul_vec(const imf_fusion_quat_t q,
                                                        const imf_fusion_vec_t v)
{
    const imf_fusion_quat_t r = {
        -q.x * v.x - q.y * v.y - q.z * v.z,
        q.w * v.x + q.y * v.z - q.z * v.y,
        q.w * v.y - q.x * v.z + q.z * v.x,
        q.w * v.z + q.x * v.y - q.y * v.x,
    };
    return r;
}

/* q / |q|; exact mode leaves a zero quaternion unchanged (the update then
   rejects it, see fusion_ahrs.h) */
static inline imf_fusion_quat_t imf_fusion_quat_normalise(const imf_fusion_quat_t q,
                                                          const int invsqrt)
{
    const imf_real n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
    imf_real r;
    if (invsqrt == IMF_FUSION_INVSQRT_FAST) {
        r = imf_fusion_invsqrt_fast(n2);
    } else {
        if (n2 == IMF_R(0.0)) {
            return q;
        }
        r = IMF_R(1.0) / imf_sqrt(n2);
    }
    {
        const imf_fusion_quat_t out = { q.w * r, q.x * r, q.y * r, q.z * r };
        return out;
    }
}

/* M v, each row summed left to right */
static inline imf_fusion_vec_t imf_fusion_mat_mul_vec(const imf_fusion_mat_t *const m,
                                                      const imf_fusion_vec_t v)
{
    const imf_fusion_vec_t r = {
        m->m[0] * v.x + m->m[1] * v.y + m->m[2] * v.z,
        m->m[3] * v.x + m->m[4] * v.y + m->m[5] * v.z,
        m->m[6] * v.x + m->m[7] * v.y + m->m[8] * v.z,
    };
    return r;
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_FUSION_MATH_H */
