/*
 * Madgwick's gradient-descent filter: article chapter 5 and the Appendix
 * "IMU Implementations" (Madgwick's 6DOF IMU filter, steps 1-9), and its
 * AHRS form with a magnetometer.
 *
 *   dq = 1/2 q (x) omega - beta ds / |ds|,   q_n = q_{n-1} + dq dt
 *
 * ds = J^T f is the gradient of the objective function f, the mismatch
 * between the measured directions (a, and m for AHRS) and those predicted
 * from q. q = (q0, q1, q2, q3) rotates sensor to earth frame (earth z up).
 * beta (rad/s) is the published "beta" (default 0.1).
 *
 * delta_s (imf_madgwick_update_imu only):
 *   IMF_MADGWICK_DS_FULL        appendix step 4 as published, valid for any q,
 *                               with the published intermediates 2q, 4q, 8q,
 *                               q0q0, ... in the published order;
 *   IMF_MADGWICK_DS_SIMPLIFIED  the article's simplified form for a unit q,
 *                               ds = 4 (q1^2 + q2^2) q + 2 (...).
 * imf_madgwick_update (with the magnetometer) always uses the full (published) form.
 *
 * Accelerometer gate (Nair 2016): with acc_gate_lo >= 0 the correction runs
 * only while the squared accelerometer magnitude is within
 * [(acc_gate_lo acc_1g)^2, (acc_gate_hi acc_1g)^2]; outside, the update
 * integrates the gyro only. acc_gate_lo < 0 (e.g. -1) turns it off: the
 * published behaviour.
 *
 * Guards (published behaviour): an all-zero accelerometer skips the
 * correction (gyro integration only); an all-zero magnetometer makes the
 * AHRS update the IMU update. Non-finite policy: see imf_math.h.
 */
#ifndef IMF_MADGWICK_H
#define IMF_MADGWICK_H

#include <stdint.h>
#include "imf_config.h"
#include "imf_math.h"
#include "imf_attitude.h"
#include "imf_gate.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { IMF_MADGWICK_DS_FULL = 0, IMF_MADGWICK_DS_SIMPLIFIED = 1 };

typedef struct {
    imf_real q0, q1, q2, q3; /* attitude quaternion, sensor -> earth, w first */
} imf_madgwick_state_t;

/* Internal: the settings as init converts them once (read by the update). */
typedef struct {
    imf_real dt;               /* sample period, s */
    imf_real beta;             /* gradient step gain, rad/s */
    int delta_s;               /* IMF_MADGWICK_DS_FULL or IMF_MADGWICK_DS_SIMPLIFIED */
    int invsqrt;               /* IMF_INVSQRT_EXACT or IMF_INVSQRT_FAST */
    int acc_gate;              /* nonzero: correct only when acc_lo2 <= |a|^2 <= acc_hi2 */
    imf_real acc_lo2, acc_hi2; /* squared gate bounds, accelerometer unit^2 */
} imf_madgwick_consts_t;

/* One filter for both forms (as the published code and x-io Fusion): imf_madgwick_update
   with a magnetometer, imf_madgwick_update_imu without. */
typedef struct {
    imf_madgwick_consts_t set; /* internal: the settings as init converted them */
    uint32_t skipped;          /* samples rejected by the non-finite policy */
    imf_madgwick_state_t x;    /* the state (above): the estimate; write it only through the API */
} imf_madgwick_t;

/* The settings of imf_madgwick_init. Start from imf_madgwick_default_settings(), then set
   dt (and what else differs). */
typedef struct {
    imf_real dt;          /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real beta;        /* gradient step gain, rad/s; >= 0, beta dt <= 0.1 (default 0.1,
                             the published value) */
    int delta_s;          /* imf_madgwick_update_imu's corrective step: IMF_MADGWICK_DS_FULL
                             (default, the appendix) or IMF_MADGWICK_DS_SIMPLIFIED (the
                             article's form, unit q); imf_madgwick_update always uses the full
                             form */
    int invsqrt;          /* IMF_INVSQRT_EXACT (default) or IMF_INVSQRT_FAST */
    imf_real acc_gate_lo; /* accelerometer gate, lower bound in units of acc_1g; < 0 turns
                             the gate off (default -1: off, the published behaviour) */
    imf_real acc_gate_hi; /* upper bound in units of acc_1g (Nair 2016: 1.4; default 0) */
    imf_real acc_1g;      /* 1 g in the accelerometer's unit, > 0 (default 1) */
} imf_madgwick_settings_t;

/* The defaults listed with each member (those of imufuse.reference.MadgwickIMU(0.01)). */
void imf_madgwick_default_settings(imf_madgwick_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them);
   q = (1, 0, 0, 0). */
void imf_madgwick_init(imf_madgwick_t *self, const imf_madgwick_settings_t *settings);

/* Accelerometer gate (Nair 2016: 0.6, 1.4), set as init sets it (init calls
   it): lo, hi in units of acc_1g (1 g in the accelerometer's unit); lo < 0
   turns it off. */
void imf_madgwick_set_acc_gate(imf_madgwick_t *self, imf_real acc_gate_lo, imf_real acc_gate_hi,
                               imf_real acc_1g);

/* A new sample period dt (s), set as init sets it (init calls it). For
   timestamps with jitter call it before each update. */
void imf_madgwick_set_dt(imf_madgwick_t *self, imf_real dt);

/* Start from a given attitude (imf_attitude.h): q = att->q. */
void imf_madgwick_set_attitude(imf_madgwick_t *self, const imf_attitude_t *att);

/* Gyroscope and accelerometer (the appendix's IMU filter, steps 1-9).
   gx, gy, gz: rad/s; ax, ay, az: any unit (normalised) */
void imf_madgwick_update_imu(imf_madgwick_t *self, imf_real gx, imf_real gy, imf_real gz,
                             imf_real ax, imf_real ay, imf_real az);
/* With the magnetometer (published AHRS form, always the full corrective step); an
   all-zero magnetometer runs imf_madgwick_update_imu.
   gx, gy, gz: rad/s; ax, ay, az and mx, my, mz: any unit (normalised) */
void imf_madgwick_update(imf_madgwick_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                         imf_real ay, imf_real az, imf_real mx, imf_real my, imf_real mz);

#ifdef __cplusplus
}
#endif

#endif /* IMF_MADGWICK_H */
