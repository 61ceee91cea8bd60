/*
 * Mahony's filter in quaternion form as implemented by Madgwick: article
 * chapter 4.1, Eq. 4.1, and the Appendix "IMU Implementations" steps 1-9.
 *
 *   omega' = omega + (Kp + Ki/s) e,   e = a x d,   dq/dt = 1/2 q (x) omega'
 *
 * q = (q0, q1, q2, q3) rotates sensor to earth frame (earth z up); d is the
 * earth's up axis seen in the sensor frame, i.e. what a level accelerometer
 * at rest reads. With a magnetometer (AHRS) the error gains m x w, where w is
 * the earth field direction, reduced to its horizontal and vertical parts
 * (bx, 0, bz) in the earth frame, seen in the sensor frame.
 *
 * Gains. kp (1/s) and ki (1/s^2) are the Kp and Ki of Eq. 4.1 with e = a x d
 * for unit a and unit d. The published code stores twoKp = 2 Kp and
 * twoKi = 2 Ki and multiplies them with half the error vector, so
 *     kp = twoKp / 2,   ki = twoKi / 2;
 * its defaults twoKp = 2 * 0.5 and twoKi = 2 * 0 are kp = 0.5, ki = 0. The
 * code here keeps the same factorisation (2 Kp times e/2) so that, with
 * invsqrt = IMF_INVSQRT_FAST in float32, it reproduces the published code
 * bit for bit.
 *
 * Integral term. I accumulates Ki dt e (step 5) and is state. As in the
 * published code it is only updated and applied while the accelerometer
 * reads something (not all zero), and it is held at zero while Ki = 0.
 *
 * Accelerometer gate (Nair 2016): with acc_gate_lo >= 0 the correction runs
 * only while the squared accelerometer magnitude is within
 * [(acc_gate_lo acc_1g)^2, (acc_gate_hi acc_1g)^2]; outside, the update
 * integrates the gyro only. acc_gate_lo < 0 (e.g. -1) turns it off: the
 * published behaviour.
 *
 * Guards (published behaviour): an all-zero accelerometer skips the
 * correction (gyro integration only); an all-zero magnetometer makes
 * imf_mahony_update imf_mahony_update_imu. Non-finite policy: see imf_math.h.
 */
#ifndef IMF_MAHONY_H
#define IMF_MAHONY_H

#include <stdint.h>
#include "imf_config.h"
#include "imf_math.h"
#include "imf_attitude.h"
#include "imf_gate.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    imf_real q0, q1, q2, q3; /* attitude quaternion, sensor -> earth, w first */
    imf_real ix, iy, iz;     /* integral term I of step 5, rad/s */
} imf_mahony_state_t;

/* Internal: the settings as init converts them once (read by the update). */
typedef struct {
    imf_real dt;               /* sample period, s */
    imf_real half_dt;          /* dt / 2, the factor of dq = 1/2 q (x) omega' dt */
    imf_real two_kp;           /* 2 Kp, multiplies the half error vector, 1/s */
    imf_real two_ki;           /* 2 Ki, 1/s^2 */
    int invsqrt;               /* IMF_INVSQRT_EXACT or IMF_INVSQRT_FAST */
    int acc_gate;              /* nonzero: correct only when acc_lo2 <= |a|^2 <= acc_hi2 */
    imf_real acc_lo2, acc_hi2; /* squared gate bounds, accelerometer unit^2 */
} imf_mahony_consts_t;

/* One filter for both forms (as the published code and x-io Fusion): imf_mahony_update
   with a magnetometer, imf_mahony_update_imu without. */
typedef struct {
    imf_mahony_consts_t set; /* internal: the settings as init converted them */
    uint32_t skipped;        /* samples rejected by the non-finite policy */
    imf_mahony_state_t x;    /* the state (above): the estimate; write it only through the API */
} imf_mahony_t;

/* The settings of imf_mahony_init. Start from imf_mahony_default_settings(), then set dt
   and the gains. */
typedef struct {
    imf_real dt;          /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real kp;          /* proportional gain, 1/s, >= 0: the published twoKp / 2
                             (default 0.5, the published twoKp = 2 * 0.5) */
    imf_real ki;          /* integral gain, 1/s^2, >= 0: the published twoKi / 2; 0 turns the
                             gyro-bias integral off (default 0, published) */
    int invsqrt;          /* IMF_INVSQRT_EXACT (default) or IMF_INVSQRT_FAST */
    imf_real acc_gate_lo; /* accelerometer gate lower bound, units of acc_1g; < 0 turns the
                             gate off (default -1: off, the published behaviour) */
    imf_real acc_gate_hi; /* upper bound, units of acc_1g (Nair 2016: 1.4; default 0) */
    imf_real acc_1g;      /* 1 g in the accelerometer's unit, > 0 (default 1) */
} imf_mahony_settings_t;

/* The defaults listed with each member (those of imufuse.reference.MahonyIMU(0.01)). */
void imf_mahony_default_settings(imf_mahony_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them);
   q = (1, 0, 0, 0), I = 0. */
void imf_mahony_init(imf_mahony_t *self, const imf_mahony_settings_t *settings);

/* Accelerometer gate (Nair 2016: 0.6, 1.4), set as init sets it (init calls
   it): lo, hi in units of acc_1g (1 g in the accelerometer's unit); lo < 0
   turns it off. Outside the gate: no proportional or integral feedback. */
void imf_mahony_set_acc_gate(imf_mahony_t *self, imf_real acc_gate_lo, imf_real acc_gate_hi,
                             imf_real acc_1g);

/* A new sample period dt (s): dt and dt / 2 by the expressions of init (init
   calls it), so the filter equals one initialised with this dt bit for bit.
   For timestamps with jitter call it before each update. */
void imf_mahony_set_dt(imf_mahony_t *self, imf_real dt);

/* Start from a given attitude (imf_attitude.h): q = att->q; I is kept. */
void imf_mahony_set_attitude(imf_mahony_t *self, const imf_attitude_t *att);

/* Gyroscope and accelerometer. gx, gy, gz: rad/s; ax, ay, az: any unit (normalised) */
void imf_mahony_update_imu(imf_mahony_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                           imf_real ay, imf_real az);
/* With the magnetometer; an all-zero magnetometer runs imf_mahony_update_imu.
   gx, gy, gz: rad/s; ax, ay, az and mx, my, mz: any unit (normalised) */
void imf_mahony_update(imf_mahony_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                       imf_real ay, imf_real az, imf_real mx, imf_real my, imf_real mz);

#ifdef __cplusplus
}
#endif

#endif /* IMF_MAHONY_H */
