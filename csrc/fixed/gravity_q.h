/*
 * Fixed-point gravity-vector filters of the appendix, in the integer
 * arithmetic 8-bit flight-controller firmware runs: only 16x16->32
 * multiplies, shifts and saturating int32 adds; no int64, no division.
 * One update serves both profiles.  The products are those of
 * imf_fixed_scale.h (short code on AVR).
 *
 * Inputs: gyr in counts of gyr_scale rad/s, acc in counts.
 *
 * KKQ (appendix "KK", Eq. 4.5 with a P controller; twin of KK, csrc/kk.h):
 *   pitch_n = pitch + (w_y - roll w_z) dt + Kp (a_pitch - pitch)
 *   roll_n  = roll  + (w_x + pitch w_z) dt + Kp (a_roll - roll)
 *   a_pitch = -a_x/|a|, a_roll = a_y/|a| (small angles; |a|^2 scaled by 4^k
 *   into [2^30, 2^32) and 1/|a| by a 16-bit inverse square root with two
 *   Newton steps, imf_unit_xy_k; a zero vector skips the P term).
 *   State: pitch, roll in q28 rad.  Constants: kw = gyr_scale dt (< 2^-13
 *   rad per count and sample), kp (per sample, in [0, 1]: kp > 1 would
 *   correct more than the whole error in one sample) as the 16-bit gain
 *   kp16 = imf_gain16(kp, 15, 15) (byte-aligned shift, docs/fixed-point.md;
 *   kp = 1 exactly: j = -2).  w dt in q28 (gyro path); the yaw cross terms
 *   multiply the state rounded to q15 by w_z dt (q28), rounded once.
 *
 * MultiWiiQ (appendix "MultiWii 2.2"; twin of MultiWii, csrc/multiwii.h):
 *   accelerometer LPF  MultiWii's L = L - L/2^k + a (accLPF32), divided by
 *                      2^k: accSmooth += (a - accSmooth)/2^k (rounded
 *                      shift: no truncation bias), in q15 counts
 *   rotation           d_n = d + d x w dt (d from before the step; each
 *                      component of d x w rounded once, imf_cross16)
 *   complementary      d = (d F + s) / (F + 1) = d + (s - d)/(F + 1) while
 *                      (1 - window) acc_1g < |accSmooth| < (1 + window) acc_1g
 *   State: d[3] in q15 acc counts, l[3] = accSmooth in q15 acc counts
 *   (MultiWii's accLPF32 / 2^k).  Constants: kw = gyr_scale dt,
 *   kc = 1/(F+1) (in the update as a 16-bit gain, imf_gain16), the window
 *   on |accSmooth|^2 in counts^2, k <= 15.
 */
#ifndef IMF_GRAVITY_Q_H
#define IMF_GRAVITY_Q_H

#include <stdint.h>
#include "imf_fixed.h"
#include "imf_fixed_scale.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int32_t t[2]; /* pitch, roll: q28 rad */
} imf_kk_q_state_t;

typedef struct {
    imf_qscale_t kw;
    imf_gain16_t kp16; /* kp in 16 bits (imf_gain16) */
    imf_kk_q_state_t x;
} imf_kk_q_t;

/* dt: s; kp: per sample, [0, 1]; gyr_scale: rad/s per count.  Constants
 * computed in double: on a target whose double is 32 bits (avr-gcc) they
 * can differ from a host's; use _init_consts there. */
int imf_kk_q_init(imf_kk_q_t *self, double dt, double kp, double gyr_scale);
/* From the precomputed constants kw = gyr_scale dt and kp16 = (m, j) =
 * imf_gain16(kp, 15, 15), stored as given (integer only, identical on every
 * target; imufuse.reference.KKQ(...).c_init_args()). */
int imf_kk_q_init_consts(imf_kk_q_t *self, imf_qscale_t kw, uint16_t kp16_m, int kp16_j);
/* One sample: gyr and acc in sensor counts (int16; every input is accepted, sums
 * saturate; a zero accelerometer gives no correction). */
void imf_kk_q_update(imf_kk_q_t *self, const int16_t gyr[3], const int16_t acc[3]);

typedef struct {
    int32_t d[3]; /* q15 acc counts */
    int32_t l[3]; /* accSmooth (accLPF32 / 2^k): q15 acc counts */
} imf_multiwii_q_state_t;

typedef struct {
    imf_qscale_t kw, kc;
    imf_gain16_t kw16, kc16; /* kw (rotation), kc as 16-bit gains (imf_gain16) */
    uint32_t lo2, hi2; /* window on |accSmooth|^2, counts^2 */
    int16_t k;         /* ACC_LPF_FACTOR, 0..15 */
    imf_multiwii_q_state_t x;
} imf_multiwii_q_t;

/* dt: s; cmpf: F >= 0; acc_lpf_shift: 0..15; acc_1g: counts of 1 g in
 * (0, 32767]; window: [0, 1]; gyr_scale: rad/s per count */
int imf_multiwii_q_init(imf_multiwii_q_t *self, double dt, double cmpf, int acc_lpf_shift,
                        double acc_1g, double window, double gyr_scale);
/* From the precomputed constants (integer only, identical on every target;
 * imufuse.reference.MultiWiiQ(...).c_init_args()): kw = gyr_scale dt,
 * kc = 1/(F+1), the window lo2 < |accSmooth|^2 < hi2 in counts^2 and
 * acc_1g_q15 = acc_1g in q15 counts, in (0, 32767 * 2^15]. */
int imf_multiwii_q_init_consts(imf_multiwii_q_t *self, imf_qscale_t kw, imf_qscale_t kc,
                               int acc_lpf_shift, uint32_t lo2, uint32_t hi2, int32_t acc_1g_q15);
/* One sample: gyr and acc in sensor counts (int16; every input is accepted, sums
 * saturate; outside the |acc| window the accelerometer gives no correction). */
void imf_multiwii_q_update(imf_multiwii_q_t *self, const int16_t gyr[3], const int16_t acc[3]);

#ifdef __cplusplus
}
#endif

#endif /* IMF_GRAVITY_Q_H */
