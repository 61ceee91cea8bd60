/*
 * "KK": the linear small-angle filter of the article's appendix, Eq. 4.5 with
 * a P controller acting per sample (Kp dimensionless):
 *
 *   theta_pitch,n = theta_pitch + (w_pitch + theta_roll w_yaw) dt + Kp (a_pitch - theta_pitch)
 *   theta_roll,n  = theta_roll  + (w_roll - theta_pitch w_yaw) dt + Kp (a_roll - theta_roll)
 *
 * valid within about +-30 deg of level. Angles are the ZYX roll and pitch of
 * imufuse.rotations in a right-handed body frame; to first order the body up
 * vector R^T e_z is (-pitch, roll, 1), so the accelerometer angles are
 * a_pitch = -a_x / |a|, a_roll = a_y / |a| (sin of the angle = the angle to
 * first order), and w_pitch = w_y, w_roll = w_x.
 *
 * The yaw coupling follows the kinematics, d' = d x w of Eq. 4.2:
 * pitch' = w_y - roll w_z, roll' = w_x + pitch w_z. That is the appendix's
 * formula with w_yaw = -w_z; read with w_yaw = +w_z it would contradict Eq.
 * 4.2 under the article's own mapping theta_x = d_x, theta_y = -d_y (a sign
 * slip in Eq. 4.5; tests/test_gravity.py shows the literal sign is worse).
 */
#ifndef IMF_KK_H
#define IMF_KK_H

#include <stdint.h>
#include "imf_config.h"
#include "imf_attitude.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    imf_real pitch; /* theta_pitch, rad (ZYX pitch, small-angle) */
    imf_real roll;  /* theta_roll, rad (ZYX roll, small-angle) */
} imf_kk_state_t;

typedef struct {
    imf_real dt;      /* sample period, s */
    imf_real kp;      /* P gain per sample, dimensionless, 0 <= kp < 2 */
    uint32_t skipped; /* samples rejected by the non-finite policy */
    imf_kk_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_kk_t;

/* The settings of imf_kk_init. Start from imf_kk_default_settings(), then set what
   differs. */
typedef struct {
    imf_real dt; /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real kp; /* P gain per sample, dimensionless, 0 <= kp < 2 (default 0.01) */
} imf_kk_settings_t;

/* The defaults listed with each member. */
void imf_kk_default_settings(imf_kk_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them).
   State starts level (0, 0). */
void imf_kk_init(imf_kk_t *self, const imf_kk_settings_t *settings);
/* gx, gy, gz: rad/s; ax, ay, az: any unit (normalised). A zero (or
   overflowing) acceleration skips the P correction: gyro only. */
void imf_kk_update(imf_kk_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax, imf_real ay,
                   imf_real az);

/* A new sample period dt (s), set as init sets it; kp stays a gain per
   sample. */
void imf_kk_set_dt(imf_kk_t *self, imf_real dt);
/* Start from a given attitude (imf_attitude.h), in the filter's own small-
   angle terms: pitch = -up_x, roll = up_y (up = att->r[6..8]), the angles
   its accelerometer path measures at rest. */
void imf_kk_set_attitude(imf_kk_t *self, const imf_attitude_t *att);
/* (roll, pitch) in rad, in double: the state itself (an output, as the other filters'
   imf_<filter>_angles). */
void imf_kk_angles(const imf_kk_t *self, double *roll, double *pitch);

#ifdef __cplusplus
}
#endif

#endif /* IMF_KK_H */
