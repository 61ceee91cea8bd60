/*
 * MultiWii 2.2 attitude estimate (article, Appendix "IMU Implementations").
 *
 * A gravity vector d, kept in accelerometer units, is rotated with the gyro
 * increment as the firmware's rotateV does (d += d x w dt, first order, never
 * renormalised: the article's point that task T2 is left entirely to the
 * complementary filter), then pulled towards the low-passed accelerometer,
 * d = (d F + a) / (F + 1), while |a| is within 1 +- window g.
 *
 * Frames and signs: d is the body-frame "up" vector R^T e_z in the units of
 * acc (a level sensor at rest: d = (0, 0, acc_1g)), i.e. minus the article's
 * d = -R^T e_z; the update is linear in (d, a), so every equation holds
 * unchanged. The firmware's sensor axes are not right-handed with respect to
 * its gyro channels ("d_x defined negative"); its rotateV is exactly
 * d + d x delta once the gyro is expressed in the accelerometer's axes, which
 * is what imufuse takes (right-handed body frame, rad/s).
 *
 * Deviations from the firmware (all listed in python/imufuse/reference/multiwii.py).
 */
#ifndef IMF_MULTIWII_H
#define IMF_MULTIWII_H

#include <stdint.h>
#include "imf_config.h"
#include "imf_attitude.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    imf_real dx, dy, dz; /* EstG: estimated gravity vector (body up), acc units */
    imf_real ax, ay, az; /* accSmooth: low-passed accelerometer, acc units */
} imf_multiwii_state_t;

typedef struct {
    imf_real dt;            /* sample period, s */
    imf_real cmpf;          /* GYR_CMPF_FACTOR F: weight of the gyro path */
    imf_real inv_cmpf1;     /* INV_GYR_CMPF_FACTOR = 1 / (F + 1) */
    imf_real lpf_n;         /* 2^ACC_LPF_FACTOR (the firmware's LPF length) */
    imf_real lpf_inv;       /* 2^-ACC_LPF_FACTOR */
    imf_real mag2_lo;       /* ((1 - window) acc_1g)^2: window on |a|^2 */
    imf_real mag2_hi;       /* ((1 + window) acc_1g)^2 */
    imf_real d2_max;        /* (4 acc_1g)^2: longest valid d (imf_gravity_ok), squared */
    imf_real acc_1g;        /* accelerometer reading of 1 g */
    uint32_t skipped;       /* samples rejected by the non-finite policy */
    imf_multiwii_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_multiwii_t;

/* The settings of imf_multiwii_init. Start from imf_multiwii_default_settings(), then
   set dt and acc_1g (the accelerometer's reading of 1 g). */
typedef struct {
    imf_real dt;       /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real cmpf;     /* GYR_CMPF_FACTOR, dimensionless, >= 0 (default 600, the firmware's) */
    int acc_lpf_shift; /* ACC_LPF_FACTOR: accelerometer LPF of 2^shift samples, 0..16
                          (default 4, the firmware's) */
    imf_real acc_1g;   /* accelerometer units per g, > 0 (default 1) */
    imf_real window;   /* |a| window around 1 g for the correction, g, 0 < window <= 1
                          (default 0.15, the firmware's 0.85 g .. 1.15 g) */
} imf_multiwii_settings_t;

/* The defaults listed with each member (those of imufuse.reference.MultiWii(0.01)). */
void imf_multiwii_default_settings(imf_multiwii_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them).
   State starts level. */
void imf_multiwii_init(imf_multiwii_t *self, const imf_multiwii_settings_t *settings);
/* gx, gy, gz: rad/s; ax, ay, az: accelerometer units (acc_1g per g) */
void imf_multiwii_update(imf_multiwii_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                         imf_real ay, imf_real az);
/* A new sample period dt (s), set as init sets it (init calls it); cmpf and
   the LPF stay per sample, as in the firmware. */
void imf_multiwii_set_dt(imf_multiwii_t *self, imf_real dt);
/* Start from a given attitude (imf_attitude.h): d and the smoothed
   accelerometer both acc_1g times the up vector att->r[6..8]. */
void imf_multiwii_set_attitude(imf_multiwii_t *self, const imf_attitude_t *att);
/* Output, not state: roll and pitch (rad, ZYX) of d, in double via libm. */
void imf_multiwii_angles(const imf_multiwii_t *self, double *roll, double *pitch);

#ifdef __cplusplus
}
#endif

#endif /* IMF_MULTIWII_H */
