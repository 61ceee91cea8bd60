/*
 * Fixed-point Mahony filter in quaternion form (appendix: "Mahony's filter
 * in quaternion form as implemented by Madgwick"), for MCUs without an FPU.
 *
 * Inputs are raw int16 sensor counts: gyr in counts of gyr_scale rad/s,
 * acc in any unit (it is normalised).  Two profiles:
 *   imf_mahony_imu_q_update_p32  int32 state and vectors, 32x16 products
 *                              (two 16x16->32 multiplies), no int64
 *                              (Cortex-M0/M3)
 *   imf_mahony_imu_q_update_p8   error vector and rates narrowed to int16,
 *                              one 16x16->32 multiply per product, no int64,
 *                              no division (AVR)
 *
 * State x (int32, in this order):
 *   q0..q3   attitude quaternion [w x y z], q30 (1.0 = 2^30), sensor -> earth
 *   ix..iz   integral term I of step 5 as a half angle per sample,
 *            0.5 * I * dt in q38 (I [rad/s] = i * 2^-38 * 2 / dt)
 *   cx..cz   the remainder carried to the next sample: 32-bit profile
 *            (ki.s >= 31), the 8 bits of Ki dt e below q38, in [0, 2^8)
 *            (imf_mahony_imu_q_carry_i); 8-bit profile's short path, the low 16 bits of
 *            the rate 0.5 w' dt in q(31+hs), in [0, 2^16) (imf_q_carry_p8);
 *            0 otherwise
 * Settings (q-scale constants m 2^-s, imf_fixed.h):
 *   kg = 0.5 gyr_scale dt   gyro counts -> half angle per sample
 *   kp = 0.5 Kp dt          error (q30) -> half angle per sample (q30)
 *   ki = 0.5 Ki dt^2        error (q30) -> increment of i (q38)
 *   hs                      exponent of the 8-bit profile's int16 rates
 *   kg8, kp8, ki8           kg, kp, ki prepared at init for the 8-bit
 *                           profile's products (imf_gain8, imf_fixed.h)
 *   kpi, fast8              kp rounded to the integral's format q38 (for
 *                           kp.s >= 22) and whether the 8-bit profile's
 *                           short path (kpi, ki8 and kg8 with shift 16)
 *                           applies
 */
#ifndef IMF_MAHONY_Q_H
#define IMF_MAHONY_Q_H

#include <stdint.h>
#include "imf_fixed.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int32_t q[4]; /* q0..q3, q30 */
    int32_t i[3]; /* ix, iy, iz: q38, half angle per sample */
    int32_t c[3]; /* cx, cy, cz: remainder carried to the next sample (see above) */
} imf_mahony_imu_q_state_t;

typedef struct {
    imf_qscale_t kg, kp, ki;    /* 0.5 gyr_scale dt, 0.5 kp dt, 0.5 ki dt^2 (q-scales) */
    int16_t hs;                 /* 8-bit profile: rates in q(15+hs) */
    imf_gain8_t kg8, kp8, ki8;  /* 8-bit profile: kg, kp, ki for int16 products */
    uint16_t kpi;               /* 8-bit profile: kp for e (q15) -> q38, when fast8 */
    int16_t fast8;              /* 8-bit profile: kpi and ki8 (shift 16) usable */
    int16_t profile;            /* 32 or 8 */
    imf_mahony_imu_q_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_mahony_imu_q_t;

/* The settings of imf_mahony_imu_q_init. Start from imf_mahony_imu_q_default_settings(),
 * then set dt and the gyro's scale. */
typedef struct {
    double dt;        /* sample period, s; > 0 (default 0.01: 100 Hz) */
    double kp;        /* proportional gain, 1/s; >= 0, kp dt < 1 (default 1) */
    double ki;        /* integral gain, 1/s^2; >= 0 (default 0) */
    double gyr_scale; /* rad/s per gyro count; > 0 (default 1.0642e-3: 2000 deg/s on
                         16 bits) */
    int profile;      /* 32 or 8: the update imf_mahony_imu_q_update calls (default 32; 8 in
                         a build of the 8-bit profile only); any other value: init returns -1 */
} imf_mahony_imu_q_settings_t;

/* The defaults listed with each member. */
void imf_mahony_imu_q_default_settings(imf_mahony_imu_q_settings_t *settings);
/* Returns 0, or -1 if a constant is outside the fixed-point range (then the filter is
 * not usable). */
int imf_mahony_imu_q_init(imf_mahony_imu_q_t *self, const imf_mahony_imu_q_settings_t *settings);
/* The same from the precomputed constants kg, kp, ki above (integer only,
 * identical on every target; computed once on a host by
 * imufuse.reference.MahonyIMUQ(...).c_init_args()).  init computes them in
 * double, which is 32 bits wide on avr-gcc: there the constants can differ
 * from a host's, so firmware that must match a host bit for bit uses this. */
int imf_mahony_imu_q_init_consts(imf_mahony_imu_q_t *self, imf_qscale_t kg, imf_qscale_t kp,
                                 imf_qscale_t ki, int profile);
/* gyr: counts; acc: counts (any scale, zero vector = no correction) */
void imf_mahony_imu_q_update_p32(imf_mahony_imu_q_t *self, const int16_t gyr[3],
                                 const int16_t acc[3]);
void imf_mahony_imu_q_update_p8(imf_mahony_imu_q_t *self, const int16_t gyr[3],
                                const int16_t acc[3]);
/* calls the update of the profile given to init */
void imf_mahony_imu_q_update_v(imf_mahony_imu_q_t *self, const int16_t gyr[3],
                               const int16_t acc[3]);
/* The same sample in the float update's form (imf_mahony_update_imu): gx, gy, gz, ax, ay, az in
 * counts, put into arrays for imf_mahony_imu_q_update_v. Where the sample is in arrays, call that
 * (on AVR two pointers take fewer instructions than six values). */
static inline void imf_mahony_imu_q_update(imf_mahony_imu_q_t *self, int16_t gx, int16_t gy,
                                           int16_t gz, int16_t ax, int16_t ay, int16_t az);
static inline void imf_mahony_imu_q_update(imf_mahony_imu_q_t *self, int16_t gx, int16_t gy,
                                           int16_t gz, int16_t ax, int16_t ay, int16_t az)
{
    const int16_t gyr[3] = { gx, gy, gz }, acc[3] = { ax, ay, az };
    imf_mahony_imu_q_update_v(self, gyr, acc);
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_MAHONY_Q_H */
