/*
 * imufuse math helpers: header-only, static inline, no state.
 */
#ifndef IMF_MATH_H
#define IMF_MATH_H

#include "imf_config.h"

/*
 * Non-finite policy shared by every filter: a sample with a NaN or +-Inf
 * input, or whose update would leave a non-finite state, is rejected. The
 * state keeps its previous value and the filter's `skipped` counter is
 * incremented. The state therefore never becomes non-finite.
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

/* ---- gravity-vector filters (multiwii, kk, mahony2d, dcm) ---------------
 * Outputs only, never part of a state update (DESIGN.md, contract 5): roll
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

#endif /* IMF_MATH_H */
