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
    imf_qscale_t kw;    /* gyr_scale dt: rate counts -> rad per sample */
    imf_gain16_t kp16;  /* kp in 16 bits (imf_gain16) */
    imf_kk_q_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_kk_q_t;

/* The settings of imf_kk_q_init. Start from imf_kk_q_default_settings(), then set dt
 * and the gyro's scale. The constants are computed in double: on a target whose double
 * is 32 bits (avr-gcc) they can differ from a host's; use _init_consts there. */
typedef struct {
    double dt;        /* sample period, s; > 0 (default 0.01: 100 Hz) */
    double kp;        /* gain of the P controller, per sample (dimensionless); 0..1 (default
                         0.01) */
    double gyr_scale; /* rad/s per gyro count; > 0, gyr_scale dt < 2^-13 (default 1.0642e-3:
                         2000 deg/s on 16 bits) */
} imf_kk_q_settings_t;

/* The defaults listed with each member (imufuse's catalogue: a 16-bit MEMS gyro). */
void imf_kk_q_default_settings(imf_kk_q_settings_t *settings);
/* Returns 0, or -1 for a parameter or a constant out of the fixed-point range (then the
 * filter is not usable). */
int imf_kk_q_init(imf_kk_q_t *self, const imf_kk_q_settings_t *settings);
/* From the precomputed constants kw = gyr_scale dt and kp16 = (m, j) =
 * imf_gain16(kp, 15, 15), stored as given (integer only, identical on every
 * target; imufuse.reference.KKQ(...).c_init_args()). */
int imf_kk_q_init_consts(imf_kk_q_t *self, imf_qscale_t kw, uint16_t kp16_m, int kp16_j);
/* One sample: gyr and acc in sensor counts (int16; every input is accepted, sums
 * saturate; a zero accelerometer gives no correction). */
void imf_kk_q_update_v(imf_kk_q_t *self, const int16_t gyr[3], const int16_t acc[3]);
/* The same sample in the float update's form (imf_kk_update): gx, gy, gz, ax, ay, az in counts,
 * put into arrays for imf_kk_q_update_v. Where the sample is in arrays, call that (on AVR two
 * pointers take fewer instructions than six values). */
static inline void imf_kk_q_update(imf_kk_q_t *self, int16_t gx, int16_t gy, int16_t gz, int16_t ax,
                                   int16_t ay, int16_t az);
static inline void imf_kk_q_update(imf_kk_q_t *self, int16_t gx, int16_t gy, int16_t gz, int16_t ax,
                                   int16_t ay, int16_t az)
{
    const int16_t gyr[3] = { gx, gy, gz }, acc[3] = { ax, ay, az };
    imf_kk_q_update_v(self, gyr, acc);
}

typedef struct {
    int32_t d[3]; /* q15 acc counts */
    int32_t l[3]; /* accSmooth (accLPF32 / 2^k): q15 acc counts */
} imf_multiwii_q_state_t;

typedef struct {
    imf_qscale_t kw, kc;      /* gyr_scale dt (rad per sample per count), 1 / (F + 1) */
    imf_gain16_t kw16, kc16;  /* kw (rotation), kc as 16-bit gains (imf_gain16) */
    uint32_t lo2, hi2;        /* window on |accSmooth|^2, counts^2 */
    int16_t k;                /* ACC_LPF_FACTOR, 0..15 */
    imf_multiwii_q_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_multiwii_q_t;

/* The settings of imf_multiwii_q_init (double: see above). Start from
 * imf_multiwii_q_default_settings(), then set dt and the scales of your sensors. */
typedef struct {
    double dt;         /* sample period, s; > 0 (default 0.01: 100 Hz) */
    double cmpf;       /* GYR_CMPF_FACTOR F, dimensionless; 0 .. 1e9 (default 600) */
    int acc_lpf_shift; /* ACC_LPF_FACTOR: accelerometer LPF of 2^shift samples, 0..15
                          (default 4) */
    double acc_1g;     /* accelerometer counts of 1 g, in (0, 32767] (default 4096: 8 g on
                          16 bits) */
    double window;     /* |a| window around 1 g for the correction, g; 0 < window <= 1
                          (default 0.15) */
    double gyr_scale;  /* rad/s per gyro count; > 0 (default 1.0642e-3: 2000 deg/s on
                          16 bits) */
} imf_multiwii_q_settings_t;

/* The integer constants of imf_multiwii_q_init_consts, identical on every target
 * (imufuse.reference.MultiWiiQ(...).c_init_args()). */
typedef struct {
    imf_qscale_t kw;    /* gyr_scale dt */
    imf_qscale_t kc;    /* 1 / (F + 1) */
    int acc_lpf_shift;  /* as in the settings */
    uint32_t lo2, hi2;  /* the window lo2 < |accSmooth|^2 < hi2, counts^2 */
    int32_t acc_1g_q15; /* acc_1g in q15 counts, in (0, 32767 * 2^15] */
} imf_multiwii_q_consts_t;

/* The defaults listed with each member (imufuse's catalogue: a 16-bit MEMS IMU). */
void imf_multiwii_q_default_settings(imf_multiwii_q_settings_t *settings);
/* Returns 0, or -1 for a parameter out of range (then the filter is not usable). */
int imf_multiwii_q_init(imf_multiwii_q_t *self, const imf_multiwii_q_settings_t *settings);
/* From the precomputed constants (integer only). Returns 0, or -1 if a constant is out
 * of range. */
int imf_multiwii_q_init_consts(imf_multiwii_q_t *self, const imf_multiwii_q_consts_t *consts);
/* One sample: gyr and acc in sensor counts (int16; every input is accepted, sums
 * saturate; outside the |acc| window the accelerometer gives no correction). */
void imf_multiwii_q_update_v(imf_multiwii_q_t *self, const int16_t gyr[3], const int16_t acc[3]);
/* The same sample in the float update's form (imf_multiwii_update): gx, gy, gz, ax, ay, az in
 * counts, put into arrays for imf_multiwii_q_update_v. Where the sample is in arrays, call that
 * (on AVR two pointers take fewer instructions than six values). */
static inline void imf_multiwii_q_update(imf_multiwii_q_t *self, int16_t gx, int16_t gy, int16_t gz,
                                         int16_t ax, int16_t ay, int16_t az);
static inline void imf_multiwii_q_update(imf_multiwii_q_t *self, int16_t gx, int16_t gy, int16_t gz,
                                         int16_t ax, int16_t ay, int16_t az)
{
    const int16_t gyr[3] = { gx, gy, gz }, acc[3] = { ax, ay, az };
    imf_multiwii_q_update_v(self, gyr, acc);
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_GRAVITY_Q_H */
