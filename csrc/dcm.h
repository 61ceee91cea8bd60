/*
 * Mahony's filter in DCM form with Premerlani & Bizard's re-orthogonalisation
 * (article 4.1 and 4.3).
 *
 *   e = a x d,  d = R^T e_z (the third row of R)                 4.1 step 3
 *   I_n = I_{n-1} + Ki dt e;  w' = w + Kp e + I_n                 4.1 steps 4-5
 *   R_n = R_{n-1} + R_{n-1} Omega'_x dt                           4.1 step 6
 *   then, with R^T = (r_x r_y r_z) (r_i: row i of R, earth axis i in body
 *   coordinates), 4.3 steps 1-5:
 *   dr = 1/2 r_x.r_y;  r_x' = r_x - dr r_y;  r_y' = r_y - dr r_x;
 *   r'' = 1/2 (3 - |r'|^2) r';  r_z'' = r_x'' x r_y''.
 *
 * R rotates body to earth (v_earth = R v_body), as imufuse's quaternions.
 * d = +R^T e_z and a is the specific force (level: acc = (0, 0, +1)); the
 * article's d = -R^T e_z with a the gravity direction gives the same e.
 * At equilibrium with a constant gyro bias b, I = -b for the components of b
 * made observable by the motion (always those perpendicular to gravity).
 */
#ifndef IMF_DCM_H
#define IMF_DCM_H

#include <stdint.h>
#include "imf_config.h"
#include "imf_attitude.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    imf_real r00, r01, r02; /* row 0 of R: r_x, earth x in body coordinates */
    imf_real r10, r11, r12; /* row 1 of R: r_y */
    imf_real r20, r21, r22; /* row 2 of R: r_z = d, earth up in body coordinates */
    imf_real ix, iy, iz;    /* integral term I, rad/s (converges to minus the gyro bias) */
} imf_dcm_state_t;

/* Valid attitude (imf_math.h policy): every row of R of squared length
   1 +- IMF_DCM_ORTHO_TOL and every pair of rows with a dot product within
   +-IMF_DCM_ORTHO_TOL. A sane update keeps R orthonormal to O(|w dt|^4);
   an update that does not (a rotation increment far beyond what the
   first-order step and the Taylor normalisation of 4.3 can represent) is
   rejected. */
#define IMF_DCM_ORTHO_TOL IMF_R(0.01)

typedef struct {
    imf_real dt;       /* sample period, s */
    imf_real kp;       /* proportional gain, 1/s */
    imf_real ki;       /* integral gain Ki, 1/s^2 (kept for set_dt) */
    imf_real ki_dt;    /* Ki dt, 1/s */
    uint32_t skipped;  /* samples rejected by the non-finite policy */
    imf_dcm_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_dcm_t;

/* The settings of imf_dcm_init. Start from imf_dcm_default_settings(), then set what
   differs. */
typedef struct {
    imf_real dt; /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real kp; /* proportional gain, 1/s, >= 0 (default 0.5) */
    imf_real ki; /* integral gain, 1/s^2, >= 0 (default 0) */
} imf_dcm_settings_t;

/* The defaults listed with each member. */
void imf_dcm_default_settings(imf_dcm_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them).
   State starts at R = identity, I = 0. */
void imf_dcm_init(imf_dcm_t *self, const imf_dcm_settings_t *settings);
/* gx, gy, gz: rad/s; ax, ay, az: any unit (normalised). A zero (or
   overflowing) acceleration means e = 0: w' = w + I. */
void imf_dcm_update(imf_dcm_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                    imf_real ay, imf_real az);
/* A new sample period dt (s): dt and Ki dt by the expressions of init (init
   calls it). For timestamps with jitter call it before each update. */
void imf_dcm_set_dt(imf_dcm_t *self, imf_real dt);
/* Start from a given attitude (imf_attitude.h): R = att->r; I is kept. */
void imf_dcm_set_attitude(imf_dcm_t *self, const imf_attitude_t *att);
/* Output, not state: roll and pitch (rad, ZYX) of r_z, in double via libm. */
void imf_dcm_angles(const imf_dcm_t *self, double *roll, double *pitch);

#ifdef __cplusplus
}
#endif

#endif /* IMF_DCM_H */
