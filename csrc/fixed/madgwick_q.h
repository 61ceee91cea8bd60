/*
 * Fixed-point Madgwick IMU filter (appendix: "Madgwick's 6DOF IMU filter",
 * simplified corrective step delta-s), for MCUs without an FPU.
 *
 * Inputs are raw int16 counts: gyr in counts of gyr_scale rad/s, acc in
 * any unit (it is normalised).  Profiles as in mahony_q.h:
 *   imf_madgwick_imu_q_update_p32  rates in q30, 32x16 products, no int64
 *   imf_madgwick_imu_q_update_p8   rates narrowed to int16, 16x16->32 only
 * Both are division-free.
 *
 * State x (int32): q[4] = q0..q3 [w x y z], q30, sensor -> earth;
 * c[3] = cx..cz, 8-bit profile: the low 16 bits of the rate 0.5 w dt in
 * q(31+hs) not yet applied, in [0, 2^16) (imf_q_carry_p8; 0 otherwise).
 * Settings (q-scale constants):
 *   kg = 0.5 gyr_scale dt   gyro counts -> half angle per sample
 *   kb = beta dt            normalised delta-s (q15) -> quaternion step (q30)
 *   hs                      exponent of the 8-bit profile's int16 rates
 *   kg8, kbf                8-bit profile: kg prepared for shift 16
 *                           (imf_gain8); the final shift (0, 8, 16, 24) of
 *                           the step kb * unit delta-s
 * Intermediates: s = delta-s / 2 in q28 (8-bit profile: q29), |s| < 4 for
 * unit q and a, scaled by a power of two into q15 before it is normalised.
 */
#ifndef IMF_MADGWICK_Q_H
#define IMF_MADGWICK_Q_H

#include <stdint.h>
#include "imf_fixed.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int32_t q[4]; /* q0..q3, q30 */
    int32_t c[3]; /* cx, cy, cz: 8-bit profile, remainder of h carried to the next sample */
} imf_madgwick_imu_q_state_t;

typedef struct {
    imf_qscale_t kg, kb; /* 0.5 gyr_scale dt, beta dt (q-scales) */
    int16_t hs;          /* 8-bit profile: rates in q(15+hs) */
    imf_gain8_t kg8;     /* 8-bit profile: kg for int16 products */
    int16_t kbf;         /* 8-bit profile: beta dt in q15 */
    int16_t profile;     /* 32 or 8 */
    imf_madgwick_imu_q_state_t
        x; /* the state (above): the estimate; write it only through the API */
} imf_madgwick_imu_q_t;

/* The settings of imf_madgwick_imu_q_init. Start from imf_madgwick_imu_q_default_settings(),
 * then set dt and the gyro's scale. */
typedef struct {
    double dt;        /* sample period, s; > 0 (default 0.01: 100 Hz) */
    double beta;      /* gain of the corrective step, rad/s; >= 0, beta dt < 0.5 (default 0.1) */
    double gyr_scale; /* rad/s per gyro count; > 0 (default 1.0642e-3: 2000 deg/s on
                         16 bits) */
    int profile;      /* 32 or 8: the update imf_madgwick_imu_q_update calls (default 32; 8 in
                         a build of the 8-bit profile only); any other value: init returns -1 */
} imf_madgwick_imu_q_settings_t;

/* The defaults listed with each member. */
void imf_madgwick_imu_q_default_settings(imf_madgwick_imu_q_settings_t *settings);
/* Returns 0, or -1 if a constant is outside the fixed-point range (then the filter is
 * not usable). */
int imf_madgwick_imu_q_init(imf_madgwick_imu_q_t *self,
                            const imf_madgwick_imu_q_settings_t *settings);
/* The same from the precomputed constants kg, kb (integer only, identical on
 * every target; imufuse.reference.MadgwickIMUQ(...).c_init_args()); see
 * imf_mahony_imu_q_init_consts for why firmware uses it. */
int imf_madgwick_imu_q_init_consts(imf_madgwick_imu_q_t *self, imf_qscale_t kg, imf_qscale_t kb,
                                   int profile);
/* One sample, 32-bit and 8-bit profile: gyr and acc in sensor counts (int16;
 * every input is accepted; a zero accelerometer vector gives no correction). */
void imf_madgwick_imu_q_update_p32(imf_madgwick_imu_q_t *self, const int16_t gyr[3],
                                   const int16_t acc[3]);
void imf_madgwick_imu_q_update_p8(imf_madgwick_imu_q_t *self, const int16_t gyr[3],
                                  const int16_t acc[3]);
/* One sample with the update of the profile given to init. */
void imf_madgwick_imu_q_update_v(imf_madgwick_imu_q_t *self, const int16_t gyr[3],
                                 const int16_t acc[3]);
/* The same sample in the float update's form (imf_madgwick_update_imu): gx, gy, gz, ax, ay, az in
 * counts, put into arrays for imf_madgwick_imu_q_update_v. Where the sample is in arrays, call
 * that (on AVR two pointers take fewer instructions than six values). */
static inline void imf_madgwick_imu_q_update(imf_madgwick_imu_q_t *self, int16_t gx, int16_t gy,
                                             int16_t gz, int16_t ax, int16_t ay, int16_t az);
static inline void imf_madgwick_imu_q_update(imf_madgwick_imu_q_t *self, int16_t gx, int16_t gy,
                                             int16_t gz, int16_t ax, int16_t ay, int16_t az)
{
    const int16_t gyr[3] = { gx, gy, gz }, acc[3] = { ax, ay, az };
    imf_madgwick_imu_q_update_v(self, gyr, acc);
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_MADGWICK_Q_H */
