/*
 * Sensor models of Longbin's walkthrough (x-io Fusion, imufusion 1.2.3), applied to N
 * samples at once (rows of 3, C order):
 *   inertial (gyroscope, accelerometer)  i_c = M s (i_u - b)
 *     M misalignment (3x3, row-major), s sensitivity (3), b offset (3),
 *     evaluated as M ((i_u - b) .* s), each row of M summed left to right;
 *   magnetic                            m_c = S (m_u - h)
 *     S soft-iron matrix (3x3), h hard-iron offset (3).
 * Axis alignment: a signed permutation of the axes, out_i = sign_i in_{perm_i}
 * (negation, never a product with -1). The 24 rotations are Fusion's
 * FusionAxesSwap alignments; the other 24 are reflections.
 */
#ifndef IMF_FUSION_CALIBRATION_H
#define IMF_FUSION_CALIBRATION_H

#include <stddef.h>
#include "fusion_math.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Fusion's inertial model, n samples of 3: out = m (s * (in - b)) with the
 * misalignment m (3x3, row major), sensitivity s (3) and offset b (3), in the
 * sensor's units (deg/s, g). */
void imf_fusion_calibrate_inertial(const imf_real *m, const imf_real *s, const imf_real *b,
                                   const imf_real *in, imf_real *out, size_t n);
/* Fusion's magnetic model, n samples of 3: out = soft_iron (in - hard_iron), soft
 * iron 3x3 row major, hard iron in the magnetometer's unit (uT). */
void imf_fusion_calibrate_magnetic(const imf_real *soft_iron, const imf_real *hard_iron,
                                   const imf_real *in, imf_real *out, size_t n);
/* perm: source axis (0..2) of each output axis; negate: nonzero to negate */
void imf_fusion_axes_apply(const int *perm, const int *negate, const imf_real *in, imf_real *out,
                           size_t n);
/* heading (degrees) for N accelerometer/magnetometer rows, per convention */
void imf_fusion_compass_headings(int convention, const imf_real *acc, const imf_real *mag,
                                 imf_real *out, size_t n, int invsqrt);

#ifdef __cplusplus
}
#endif

#endif /* IMF_FUSION_CALIBRATION_H */
