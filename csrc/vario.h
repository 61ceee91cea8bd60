/*
 * Variometer of Hari Nair ("IMU modules, AHRS and a Kalman filter
 * for sensor fusion", 2016): gravity-compensated vertical acceleration from
 * an attitude quaternion, and the three-state Kalman filter that fuses it
 * with barometric altitude.
 *
 * Kalman filter states (Nair's units): z altitude (cm), v climb rate (cm/s),
 * b accelerometer bias (cm/s^2); the true vertical acceleration is the
 * measured one minus b. Per barometer sample, with dt the interval since the
 * previous one (s):
 *
 *   F = [[1, dt, -dt^2/2], [0, 1, -dt], [0, 0, 1]]
 *   Q = [[dt^4/4 sa, dt^3/2 sa, 0], [dt^3/2 sa, dt^2 sa, 0], [0, 0, sb]]
 *   H = [1 0 0],  R = sz
 *
 * sa = var_acc ((cm/s^2)^2), sb = var_bias ((cm/s^2)^2, added once per step
 * as in Nair (2016)), sz = var_z (cm^2). The covariance is symmetric and stored
 * as its upper triangle.
 *
 * State prediction (step 2 of Nair's lists):
 *   IMF_VARIO_PREDICT_SEED   as Nair writes it: v += (a - b) dt, then
 *                            z += v dt with the new v;
 *   IMF_VARIO_PREDICT_MODEL  consistent with F: z += v dt + (a - b) dt^2/2,
 *                            then v += (a - b) dt.
 *
 * Start: with z0_from_baro the first accepted sample only sets z to its
 * altitude (z0 = first barometer altitude); otherwise z starts at z0.
 * Non-finite policy (imf_math.h): a sample with a non-finite input or a dt
 * that is not > 0, or whose update would leave the state non-finite, is
 * rejected and counted in `skipped`.
 */
#ifndef IMF_VARIO_H
#define IMF_VARIO_H

#include <stdint.h>
#include "imf_config.h"
#include "imf_math.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { IMF_VARIO_PREDICT_SEED = 0, IMF_VARIO_PREDICT_MODEL = 1 };

typedef struct {
    imf_real z;   /* altitude, cm */
    imf_real v;   /* climb rate, cm/s */
    imf_real b;   /* accelerometer bias, cm/s^2 */
    imf_real pzz; /* covariance P, upper triangle */
    imf_real pzv; /* cm^2/s */
    imf_real pzb; /* cm^2/s^2 */
    imf_real pvv; /* (cm/s)^2 */
    imf_real pvb; /* cm^2/s^3 */
    imf_real pbb; /* (cm/s^2)^2 */
} imf_vario_state_t;

/* Internal: the settings as init keeps them (read by the update). */
typedef struct {
    imf_real var_z;    /* R: barometer altitude variance, cm^2 */
    imf_real var_acc;  /* acceleration variance, (cm/s^2)^2 */
    imf_real var_bias; /* bias variance added per step, (cm/s^2)^2 */
    int predict;       /* IMF_VARIO_PREDICT_SEED or IMF_VARIO_PREDICT_MODEL */
} imf_vario_consts_t;

typedef struct {
    imf_vario_consts_t set; /* internal: the settings as init converted them */
    uint32_t skipped;       /* samples rejected by the non-finite policy */
    int started;            /* 0 until the first sample has set z (z0_from_baro) */
    imf_vario_state_t x;    /* the state (above): the estimate; write it only through the API */
} imf_vario_t;

/* The settings of imf_vario_init. Start from imf_vario_default_settings() (Nair's
   values) and change what differs. */
typedef struct {
    imf_real var_z;    /* R: barometer altitude variance, cm^2; > 0 (default 300) */
    imf_real var_acc;  /* acceleration variance, (cm/s^2)^2; >= 0 (default 200) */
    imf_real var_bias; /* bias variance added per step, (cm/s^2)^2; >= 0 (default 1) */
    imf_real p_z;      /* initial variance of z, cm^2; >= 0 (default 1); P0 is diagonal */
    imf_real p_v;      /* initial variance of v, (cm/s)^2; >= 0 (default 1) */
    imf_real p_b;      /* initial variance of b, (cm/s^2)^2; >= 0 (default 1e5) */
    imf_real z0;       /* initial altitude, cm, used when z0_from_baro is 0 (default 0) */
    imf_real v0;       /* initial climb rate, cm/s (default 0) */
    imf_real b0;       /* initial accelerometer bias, cm/s^2 (default 0) */
    int z0_from_baro;  /* nonzero: z starts at the first barometer sample (default 1) */
    int predict;       /* IMF_VARIO_PREDICT_SEED (default, as published) or
                          IMF_VARIO_PREDICT_MODEL (stable for every setting; SEED diverges
                          when var_z is small against the process noise: docs/vario.md) */
} imf_vario_settings_t;

/* The defaults listed with each member (those of imufuse.reference.VarioKF()). */
void imf_vario_default_settings(imf_vario_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them). */
void imf_vario_init(imf_vario_t *self, const imf_vario_settings_t *settings);
/* accel: net vertical acceleration, up positive, cm/s^2 (bias included);
   baro_alt: barometer altitude, cm; dt: time since the previous sample, s. */
void imf_vario_update(imf_vario_t *self, imf_real accel, imf_real baro_alt, imf_real dt);

/*
 * Gravity-compensated vertical acceleration (Nair 2016): the z component of
 * the accelerometer rotated into the earth frame by q (sensor -> earth),
 *
 *   az_earth = (2q1q3 - 2q0q2) ax + (2q2q3 + 2q0q1) ay + (q0^2 - q1^2 - q2^2 + q3^2) az,
 *
 * returned as (sign az_earth - one_g) scale: the net acceleration along the
 * vertical, up positive. sign = +1 when the accelerometer reads +1 g along
 * earth z at rest (imufuse's NWU and ENU, and Nair's NED board, whose
 * D axis reads +1 g); sign = -1 for a NED frame with a specific-force
 * accelerometer (-1 g on D at rest). one_g: 1 g in the accelerometer's unit;
 * scale: output unit per accelerometer unit (Nair: 1 g, scale 980 for cm/s^2).
 */
imf_real imf_vertical_accel(imf_real q0, imf_real q1, imf_real q2, imf_real q3, imf_real ax,
                            imf_real ay, imf_real az, imf_real sign, imf_real one_g,
                            imf_real scale);

#ifdef __cplusplus
}
#endif

#endif /* IMF_VARIO_H */
