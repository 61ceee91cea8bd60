/*
 * Fixed-point gravity-vector filters of the appendix, in the integer
 * arithmetic 8-bit flight-controller firmware runs: only 16x16->32
 * multiplies (imf_mul_32x16 is two of them), shifts and saturating int32
 * adds; no int64, no division.  One update serves both profiles.
 *
 * Inputs: gyr in counts of gyr_scale rad/s, acc in counts with acc_1g
 * counts = 1 g (the magnitude matters here: MultiWii gates on it, KK reads
 * small angles from it).
 *
 * KKQ (appendix "KK", Eq. 4.5 with a P controller), small angles:
 *   theta_x[n] = theta_x + (w_y + theta_y w_z) dt + Kp (a_x - theta_x)
 *   theta_y[n] = theta_y + (w_x - theta_x w_z) dt + Kp (a_y - theta_y)
 *   with the accelerometer angles a_x = -acc_x / 1g, a_y = acc_y / 1g
 *   (Eq. 4.5: theta_x ~ d_x, theta_y ~ -d_y, d = -acc the gravity vector).
 *   State: tx, ty in q28 rad.  Constants: kw = gyr_scale dt, ka = 1/acc_1g,
 *   kp = Kp (per sample).
 *
 * MultiWiiQ (appendix "MultiWii 2.2"):
 *   d[n] = d + d x w dt; if |a| within 1 +- 0.15 g: d = (d F + a) / (F + 1)
 *   computed as d + (a - d) / (F + 1) with 1/(F+1) a q-scale constant.
 *   State: d[3] in q15 acc counts (d [g] = d 2^-15 / acc_1g); d follows the
 *   accelerometer reading (+1 g up when level), d x w is the same equation
 *   for d and -d.  Constants: kw = gyr_scale dt, kc = 1/(F+1), gate
 *   thresholds (0.85 acc_1g)^2 < |a|^2 < (1.15 acc_1g)^2 in counts^2.
 */
#ifndef IMF_GRAVITY_Q_H
#define IMF_GRAVITY_Q_H

#include <stdint.h>
#include "imf_fixed.h"

typedef struct {
    int32_t t[2]; /* tx, ty: q28 rad */
} imf_kk_q_state_t;

typedef struct {
    imf_qscale_t kw, ka, kp;
    imf_kk_q_state_t x;
} imf_kk_q_t;

/* dt: s; kp: per sample, [0, 1]; gyr_scale: rad/s per count; acc_1g: counts */
int imf_kk_q_init(imf_kk_q_t *self, double dt, double kp, double gyr_scale, double acc_1g);
void imf_kk_q_update(imf_kk_q_t *self, const int16_t gyr[3], const int16_t acc[3]);

typedef struct {
    int32_t d[3]; /* q15 acc counts */
} imf_multiwii_q_state_t;

typedef struct {
    imf_qscale_t kw, kc;
    uint32_t lo2, hi2; /* gate on |a|^2, counts^2 */
    int32_t one_g;     /* acc_1g in q15 counts, the initial d_z */
    imf_multiwii_q_state_t x;
} imf_multiwii_q_t;

/* dt: s; cmpf: the weight F (>= 0); gyr_scale: rad/s per count; acc_1g: counts */
int imf_multiwii_q_init(imf_multiwii_q_t *self, double dt, double cmpf, double gyr_scale,
                        double acc_1g);
void imf_multiwii_q_update(imf_multiwii_q_t *self, const int16_t gyr[3], const int16_t acc[3]);

#endif /* IMF_GRAVITY_Q_H */
