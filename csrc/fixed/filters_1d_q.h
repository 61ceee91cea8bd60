/*
 * Fixed-point single-axis filters (article chapters 2 and 3) for MCUs
 * without an FPU.  Inputs are raw int16 counts: rate in counts of
 * gyr_scale rad/s, angle in counts of angle_scale rad.  The update uses
 * only 16x16->32 multiplies, shifts and saturating int32 adds, no int64
 * and no division, so one update serves both profiles ("32" and "8" give
 * identical results).  The products are those of imf_fixed_scale.h.
 *
 * Formats:
 *   theta   q15 angle counts (int32): theta [rad] = theta * 2^-15 * angle_scale
 *   j       (Mahony1DBiasQ) the I term as an angle step per sample,
 *           I dt, in q23 angle counts: I [rad/s] = j 2^-23 angle_scale / dt
 * Constants (q-scale m 2^-s):
 *   kr  = gyr_scale dt / angle_scale   rate counts -> angle counts per sample
 *   ka  = 1 - alpha                    (Complementary1DQ; the update uses
 *                                       ka16, ka rounded to 16 bits with a
 *                                       byte-aligned shift: imf_gain16)
 *   kp  = Kp dt, ki = Ki dt^2          (Mahony1DBiasQ; the update uses
 *                                       them as 16-bit gains likewise, kp16
 *                                       and ki16 2^8: Kp dt < 1, Ki dt^2 < 2^-8)
 */
#ifndef IMF_FILTERS_1D_Q_H
#define IMF_FILTERS_1D_Q_H

#include <stdint.h>
#include "imf_fixed.h"
#include "imf_fixed_scale.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- Eq. 2.2: complementary filter --------------------------------- */
typedef struct {
    int32_t theta; /* q15 angle counts */
} imf_complementary1d_q_state_t;

typedef struct {
    imf_qscale_t kr;   /* gyr_scale dt / angle_scale: rate counts -> angle counts per sample */
    imf_gain16_t ka16; /* ka rounded to 16 bits, byte-aligned shift (imf_gain16) */
    imf_complementary1d_q_state_t
        x; /* the state (above): the estimate; write it only through the API */
} imf_complementary1d_q_t;

/* The settings of imf_complementary1d_q_init. Start from
 * imf_complementary1d_q_default_settings(), then set dt and the scales of your sensors.
 * The constants are computed in double: on a target whose double is 32 bits (avr-gcc)
 * they can differ from a host's; use _init_consts there. */
typedef struct {
    double dt;          /* sample period, s; > 0 (default 0.01: 100 Hz) */
    double alpha;       /* weight of the gyro path, dimensionless; 0..1: alpha = (T/dt) /
                           (1 + T/dt) for a time constant T (default 50/51: T = 0.5 s at
                           100 Hz) */
    double gyr_scale;   /* rad/s per gyro count; > 0 (default 1.0642e-3: 2000 deg/s on
                           16 bits) */
    double angle_scale; /* rad per angle count; > 0 (default 1e-4) */
} imf_complementary1d_q_settings_t;

/* The defaults listed with each member (imufuse's catalogue: a 16-bit MEMS gyro). */
void imf_complementary1d_q_default_settings(imf_complementary1d_q_settings_t *settings);
/* Returns 0, or -1 for a parameter or a constant out of the fixed-point range (then the
 * filter is not usable). */
int imf_complementary1d_q_init(imf_complementary1d_q_t *self,
                               const imf_complementary1d_q_settings_t *settings);
/* The same from the precomputed constants kr (q-scale as above) and ka16
 * (m, j: imf_gain16(ka, 15, 15), the 16-bit gain the update uses), computed
 * once on a host: imufuse.reference.Complementary1DQ(...).c_init_args().
 * Integer only, identical on every target, and it only stores them (no
 * init arithmetic linked).  Returns 0, or -1 if a constant is out of range. */
int imf_complementary1d_q_init_consts(imf_complementary1d_q_t *self, imf_qscale_t kr,
                                      uint16_t ka16_m, int ka16_j);
/* rate, angle: counts */
void imf_complementary1d_q_update(imf_complementary1d_q_t *self, int16_t rate, int16_t angle);

/* ---- Eq. 3.6 (and Eq. 3.9): Mahony&Madgwick PI filter ---------------- */
typedef struct {
    int32_t theta; /* q15 angle counts */
    int32_t j;     /* I dt, q23 angle counts per sample */
} imf_mahony1d_bias_q_state_t;

typedef struct {
    imf_qscale_t kr; /* gyr_scale dt / angle_scale: rate counts -> angle counts per sample */
    imf_gain16_t kp16, ki16; /* kp, ki 2^8 as 16-bit gains (imf_gain16) */
    int16_t integrate_first; /* 1: Eq. 3.9 order (Corollary #1) */
    imf_mahony1d_bias_q_state_t
        x; /* the state (above): the estimate; write it only through the API */
} imf_mahony1d_bias_q_t;

/* The settings of imf_mahony1d_bias_q_init (double: see above). Start from
 * imf_mahony1d_bias_q_default_settings(), then set dt and the scales of your sensors.
 * Kp dt must be below 1 (a correction faster than one sample overshoots the measured
 * angle) and Ki dt^2 below 2^-8 (the I loop's natural frequency sqrt(Ki) below 1/16 rad
 * per sample): the gains the 16-bit products cover. */
typedef struct {
    double dt;           /* sample period, s; > 0 (default 0.01: 100 Hz) */
    double kp;           /* proportional gain, 1/s; >= 0, Kp dt < 1 (default 2) */
    double ki;           /* integral gain, 1/s^2; >= 0, Ki dt^2 < 2^-8 (default 0.3) */
    int integrate_first; /* nonzero: Eq. 3.9's order (Corollary #1); 0: Eq. 3.6 (default) */
    double gyr_scale;    /* rad/s per gyro count; > 0 (default 1.0642e-3: 2000 deg/s
                            on 16 bits) */
    double angle_scale;  /* rad per angle count; > 0 (default 1e-4) */
} imf_mahony1d_bias_q_settings_t;

/* The integer constants of imf_mahony1d_bias_q_init_consts: kr (q-scale of
 * gyr_scale dt / angle_scale), kp16 (m, j: imf_gain16(Kp dt, 15, 15)) and ki16
 * (imf_gain16(Ki dt^2, 15, 23); m = j = 0 for Ki = 0), computed once on a host:
 * imufuse.reference.Mahony1DBiasQ(...).c_init_args(). */
typedef struct {
    imf_qscale_t kr; /* gyr_scale dt / angle_scale: rate counts -> angle counts per sample */
    uint16_t kp16_m; /* Kp dt as a 16-bit gain (imf_gain16(Kp dt, 15, 15)): mantissa */
    int kp16_j;      /* and byte shift */
    uint16_t
        ki16_m; /* Ki dt^2 as a 16-bit gain (imf_gain16(Ki dt^2, 15, 23)): mantissa (0: Ki = 0) */
    int ki16_j; /* and byte shift (0 for Ki = 0) */
    int integrate_first; /* as in the settings */
} imf_mahony1d_bias_q_consts_t;

/* The defaults listed with each member (imufuse's catalogue: a 16-bit MEMS gyro). */
void imf_mahony1d_bias_q_default_settings(imf_mahony1d_bias_q_settings_t *settings);
/* Returns 0, or -1 for a parameter out of range (then the filter is not usable). */
int imf_mahony1d_bias_q_init(imf_mahony1d_bias_q_t *self,
                             const imf_mahony1d_bias_q_settings_t *settings);
/* The same from the precomputed constants. Integer only, and it only stores them.
 * Returns 0, or -1 if a constant is out of range. */
int imf_mahony1d_bias_q_init_consts(imf_mahony1d_bias_q_t *self,
                                    const imf_mahony1d_bias_q_consts_t *consts);
/* One sample: rate in gyro counts, angle in angle counts (int16: every input is a
 * number; sums saturate, so no input is rejected). */
void imf_mahony1d_bias_q_update(imf_mahony1d_bias_q_t *self, int16_t rate, int16_t angle);

#ifdef __cplusplus
}
#endif

#endif /* IMF_FILTERS_1D_Q_H */
