/*
 * 2D Mahony filter (article 4.2): only the gravity direction d is estimated.
 *
 *   d' = d x w + (Kp + Ki/s) E                                   Eq. 4.3
 *   E = d x (a x d)   (error="exact", Eq. 4.3)
 *   E = a - d         (error="approx", Eq. 4.4: a.d ~ 1, |d| ~ 1)
 *
 * discretised like the single-axis filter of Eq. 3.6, per axis:
 *   I_n = I_{n-1} + Ki dt E_n;   d_n = d_{n-1} + (Kp E_n + I_n + d_{n-1} x w_n) dt
 * with E_n from d_{n-1} and the normalised accelerometer.
 *
 * Eq. 4.4 (E = a - d): d is never renormalised (the article: "the MultiWii
 * approach suggests itself"); the controller itself pulls |d| to 1.
 *
 * Eq. 4.3 (E = d x (a x d)): d is scaled back to unit length after every
 * update (task T2). E and d x w are perpendicular to d, so nothing in Eq. 4.3
 * controls |d|: d.d' = d.I, and the integral, applied outside the cross
 * product ("thanks to linearity", exact only while d does not move), keeps
 * any component along d that it gathered while d moved; the forward step
 * adds |d|^2 dt^2 |E, d x w|^2 on top. Left alone |d| grew without bound
 * (1 -> 2.33 in 60 s after a 25 deg initial error, 10 after 270 s at a static
 * 30 deg), the loop gain Kp |d|^2 with it, and once |d| reached the length
 * where that loop turns unstable every later sample had to be rejected. Only
 * the direction of d carries attitude, and E = a |d|^2 - d (a.d) is the
 * article's E with "both d and a normalized". From a unit d each step turns
 * d exactly as the unnormalised Eq. 4.3 step does (the scaling does not change
 * its direction); keeping |d| = 1 keeps the loop the single-axis filter of
 * Eq. 3.6 with gains Kp, Ki per axis, so its stable range is that of Eq. 4.4.
 *
 * Sign: d is the body-frame up vector R^T e_z (a level sensor at rest reads
 * acc = (0, 0, +1) = d), minus the article's d = -R^T e_z; E and d flip
 * together, so Eq. 4.3/4.4 hold unchanged. At equilibrium with a constant
 * gyro bias b, I = -d x b: the bias seen by the filter is b_perp = d x I
 * (its component along gravity is unobservable).
 */
#ifndef IMF_MAHONY2D_H
#define IMF_MAHONY2D_H

#include <stdint.h>
#include "imf_config.h"
#include "imf_attitude.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Valid attitude (imf_math.h policy): |d|^2 normal and at most d2_max = 4
   (|d| <= 2). Eq. 4.4 pulls |d| to 1; Eq. 4.3 renormalises d every update
   (|d| = 1 to rounding), and a normalisation that fails rejects the sample. */

typedef struct {
    imf_real dx, dy, dz; /* gravity direction estimate (body up), unit-less */
    imf_real ix, iy, iz; /* integral term I, 1/s (I = -d x b at equilibrium) */
} imf_mahony2d_state_t;

typedef struct {
    imf_real dt;            /* sample period, s */
    imf_real kp;            /* proportional gain, 1/s */
    imf_real ki;            /* integral gain Ki, 1/s^2 (kept for set_dt) */
    imf_real ki_dt;         /* Ki dt, 1/s */
    int exact;              /* 0: E = a - d (Eq. 4.4); 1: E = d x (a x d) (Eq. 4.3) */
    imf_real d2_max;        /* longest valid d, squared: 4 (see above) */
    uint32_t skipped;       /* samples rejected by the non-finite policy */
    imf_mahony2d_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_mahony2d_t;

/* The settings of imf_mahony2d_init. Start from imf_mahony2d_default_settings(), then set what
   differs. */
typedef struct {
    imf_real dt; /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real kp; /* proportional gain, 1/s, >= 0 (default 0.5) */
    imf_real ki; /* integral gain, 1/s^2, >= 0 (default 0) */
    int exact;   /* 0: the article's small-angle error, 1: the exact one (default 0) */
} imf_mahony2d_settings_t;

/* The defaults listed with each member. */
void imf_mahony2d_default_settings(imf_mahony2d_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them).
   State starts level, I = 0. */
void imf_mahony2d_init(imf_mahony2d_t *self, const imf_mahony2d_settings_t *settings);
/* gx, gy, gz: rad/s; ax, ay, az: any unit (normalised). A zero (or
   overflowing) acceleration means E = 0: the gyro path and I only. */
void imf_mahony2d_update(imf_mahony2d_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                         imf_real ay, imf_real az);
/* A new sample period dt (s): dt and Ki dt by the expressions of init (init
   calls it). For timestamps with jitter call it before each update. */
void imf_mahony2d_set_dt(imf_mahony2d_t *self, imf_real dt);
/* Start from a given attitude (imf_attitude.h): d = the up vector
   att->r[6..8]; I is kept. */
void imf_mahony2d_set_attitude(imf_mahony2d_t *self, const imf_attitude_t *att);
/* Output, not state: roll and pitch (rad, ZYX) of d, in double via libm. */
void imf_mahony2d_angles(const imf_mahony2d_t *self, double *roll, double *pitch);

#ifdef __cplusplus
}
#endif

#endif /* IMF_MAHONY2D_H */
