/*
 * imufuse's recommended AHRS (docs/recommended-ahrs.md): the article's
 * chapter 3 (the gyro bias as a state, PI tuning by Eq. 3.12) and chapter 4
 * (correction on SO(3)) built for real sensors.
 *
 *   q = c (x) s      s: strapdown quaternion, sensor -> inertial frame, from
 *                       the bias-corrected gyro only;
 *                    c: correction, inertial -> earth frame (NWU, z up), set so
 *                       that the gravity estimated in the inertial frame points
 *                       up, and turned about z towards magnetic north.
 *
 * Blocks:
 *   B1 gyro bias at rest: rest when the low-passed and the current gyro are
 *      below rest_gyr and the accelerometer stays within rest_acc (g) of its
 *      low-pass for rest_time; then the bias is the low-passed gyro.
 *   B2 gravity in the inertial frame: a Kalman filter of (v, g) per axis with
 *      v' = a - g (v: velocity, stays bounded: pseudo-measurement v = 0) and a
 *      random walk of g whose rate grows with (|w| / rate_ref)^2 (gyro scale
 *      and misalignment errors turn the inertial frame). At rest it is a
 *      second-order low-pass with omega_0 = 1 / tau_acc, damping 1/sqrt(2).
 *      Linear accelerations integrate to a bounded velocity and cancel.
 *   B3 gyro bias in motion: the inclination correction, seen in the sensor
 *      frame, integrated with gain 1 / tau_bias (Eq. 3.6).
 *   B4 magnetometer, heading only (a rotation of c about earth z), rejected
 *      while the field's norm or dip differ from a learned reference, and until
 *      they have matched it again for mag_hold; a new field that stays the
 *      same for mag_new_time becomes the reference.
 *   B5 start from the first samples: every low-pass is a running mean until
 *      its time constant has passed.
 *   B6 magnetometer offset (hard iron) learnt while the sensor turns: a Kalman
 *      filter of the field h in the inertial frame and the offset b in the
 *      sensor frame, m = R(s)^T h + b (relative to the first field's norm). An
 *      offset is constant in the sensor frame, a field (also a disturbance near
 *      the path) is fixed in the earth frame: turning tells them apart; a sensor
 *      that never turns leaves b unobservable (its variance stays at the prior).
 *      B4 reads m - u; u, the offset in use, is the stored offset until the
 *      estimate is trusted and differs from it by more than mag_offset_min, or
 *      until the reading's norm shows the stored offset wrong (it moves the norm
 *      as the sensor turns, the estimate does not); a new offset in use starts
 *      B4's reference again.
 *   Output: q = c (x) s, predicted forward by the sensor chain's latency (the
 *      group delay of the gyroscope's internal filter) with the current rate.
 *
 * No transcendental function in the update (sqrt and division only); the
 * strapdown step uses the series of exp(1/2 w dt) to fourth order.
 * Valid-attitude policy (imf_math.h): a sample with a non-finite input, a
 * normalisation that fails or a non-finite new state is rejected and counted.
 */
#ifndef IMF_ROBUST_H
#define IMF_ROBUST_H

#include <stdint.h>
#include "imf_config.h"
#include "imf_math.h"
#include "imf_attitude.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    imf_real q[4];           /* estimate, sensor -> earth (NWU), w first */
    imf_real s[4];           /* strapdown: sensor -> inertial frame */
    imf_real c[4];           /* correction: inertial -> earth frame */
    imf_real f[3];           /* B2: gravity (specific force) in the inertial frame, acc unit */
    imf_real v[3];           /* B2: velocity-like state, acc unit * s */
    imf_real pvv, pvg, pgg;  /* B2: covariance, shared by the three axes */
    imf_real b[3];           /* gyro bias, rad/s */
    imf_real lw[3];          /* B1: low-passed gyro, rad/s */
    imf_real la[3];          /* B1: low-passed accelerometer, acc unit */
    imf_real t, t_rest;      /* time since start (saturating), time at rest, s */
    imf_real bu;             /* B1/B3: how unknown the bias still is: 1 at the start (any
                                bias up to gyr_bias_max), 0 once learnt (at rest for
                                3 tau_bias_rest or in motion for tau_bias) */
    imf_real ref[3];         /* B4: magnetic reference: norm, cos(dip), vertical part (rn rh rz) */
    imf_real cand[3];        /* B4: candidate reference, a changed field (cn ch cz) */
    imf_real t_cand, t_dist; /* B4: candidate stable for, field disturbed for, s */
    imf_real t_ok;           /* B4: field matching the reference for (saturating), s */
    imf_real lm[3];          /* B1: low-passed magnetometer, field unit (0: no reading yet) */
    imf_real l0[3];          /* B1: lm where the rest window began, field unit */
    imf_real w0[3];          /* B1: lw where the rest window began, rad/s */
    imf_real db[3];          /* B3: the strapdown's turn by the bias, R(s) b dt summed, less
                                B2's low-pass of it (B2's model of the bias), rad */
    imf_real vb[3];          /* B3: its velocity-like state, rad s */
    imf_real dr[9];          /* B3: the same for R(s) (columns: the sensor axes in I), s */
    imf_real vr[9];          /* B3: its velocity-like state, s^2 */
    imf_real bp[6];          /* B3: covariance of b, upper triangle (p00 p01 p02 p11 p12 p22),
                                relative to the measurement noise (1/s) */
    imf_real an;             /* B3: its rows' noise, relative to its bound (rest_acc): the
                                linear acceleration B2 sees, low-passed; 1 from the first sample */
    /* B6 (relative: field unit / m_n0) */
    imf_real hi[6];  /* field in the inertial frame h (hx hy hz), then the offset (hard iron)
                        estimate in the sensor frame (ix iy iz), relative */
    imf_real P[21];  /* covariance of hi, upper triangle by rows: p00 p01 .. p05 p11 .. p55,
                        p<i><j> = P[i][j] */
    imf_real u[3];   /* offset in use, field unit (B4 reads m - u; ux uy uz) */
    imf_real so[3];  /* stored offset (set_mag_offset), field unit (sx sy sz) */
    imf_real m_n0;   /* field unit of the estimator (0: starts at the next reading) */
    imf_real m_ew;   /* mean normalised innovation (about 1 when consistent) */
    imf_real m_d2;   /* last normalised innovation */
    imf_real m_std;  /* standard deviation of the offset estimate, relative */
    imf_real mn[4];  /* the norm of the reading less the offset in use, low-passed over
                        tau_mag (relative, 1 at the start), and its squared deviation from
                        that low-pass, low-passed; then the same two with the estimate
                        (m_nu m_vu m_ne m_ve) */
    imf_real m_axis; /* the axis the next reading updates: 0, 1, 2 */
    imf_real m_bad;  /* absurd readings for (s): the estimator restarts after 1 s */
} imf_robust_state_t;

/* The settings of imf_robust_init. Start from imf_robust_default_settings(), then set dt.
   Units are those of the C (rad/s, sines); imufuse.reference.RobustAHRS takes deg/s and
   converts. Blocks B1-B6: docs/recommended-ahrs.md. imf_robust_update_imu reads the first
   ten and the last (B1-B3, B5); imufuse.reference.RobustIMU is the filter initialised with
   tau_mag = tau_mag_ref = tau_rest and mag_learn = 0 (its start-up horizon that of the
   blocks it runs), the other magnetic settings at their defaults. */
typedef struct {
    imf_real dt;             /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real tau_acc;        /* B2: tilt correction time constant, s; > 0 (default 2.5) */
    imf_real rate_ref;       /* B2: the turn rate at which gravity's process noise doubles,
                               rad/s; >= 0, 0: constant (default 100 deg/s = 1.745 rad/s) */
    imf_real tau_bias;       /* B3: gyro-bias time constant in motion at the bound of its
                               noise (its random walk 1 / tau_bias^2; smooth motion learns
                               faster), s; 0 (off) or >= 4 tau_acc (default 100) */
    imf_real tau_bias_rest;  /* B3: gyro-bias time constant at rest, s; > 0 (default 3) */
    imf_real rest_gyr;       /* B1: rest threshold on the low-passed rate, rad/s; >= 0
                               (default 2 deg/s = 0.0349 rad/s) */
    imf_real rest_acc;       /* B1: rest threshold on |a| - 1 g, relative to 1 g; >= 0
                               (default 0.05); B3: the motion its noise is scaled by */
    imf_real rest_time;      /* B1: time below both thresholds before rest, s; >= 0
                               (default 1.5) */
    imf_real tau_rest;       /* B1: low-pass time constant of the rest detector, s; > 0
                               (default 0.5) */
    imf_real latency;        /* B5: the sensor chain's delay, compensated in the output q by
                               predicting it forward with the current rate, s;
                               0 .. 0.1, 0: none (default 0) */
    imf_real tau_mag;        /* B4: heading correction time constant, s; > 0 (default 10) */
    imf_real mag_norm;       /* B4: disturbance threshold on |m| against the reference's,
                               relative; >= 0 (default 0.1) */
    imf_real mag_dip;        /* B4: disturbance threshold on the dip angle, as its sine;
                               > 1: no dip test (default sin(10 deg) = 0.1736) */
    imf_real tau_mag_ref;    /* B4: time constant of the learned reference field, s; > 0
                               (default 20) */
    imf_real mag_new_time;   /* B4: a changed field steady this long becomes the reference,
                               s; >= 0 (default 20) */
    imf_real mag_hold;       /* B4: after a disturbance the field must match the reference
                               this long before it is used, s; >= 0 (default 0.5) */
    int mag_learn;           /* B6: learn the magnetometer's offset while turning; 0: use
                               the stored offset only (default 1) */
    imf_real mag_noise;      /* B6: magnetometer noise, relative to the field; > 0
                               (default 0.02) */
    imf_real mag_lag;        /* B6: magnetometer-to-gyro timing mismatch, s: the noise grows
                               by |w| mag_lag; >= 0 (default 0.003) */
    imf_real mag_offset_min; /* B6: a trusted estimate replaces the stored offset when they
                                differ by more than this, relative; >= 0 (default 0.1) */
    imf_real gyr_bias_max;   /* B1/B3: the largest gyro bias (zero-rate offset) per axis the
                               part may have, rad/s; 0 .. 1000 deg/s (default 6 deg/s = 0.1047 rad/s);
                               0: a calibrated gyro, the bias learnt as the fixed-point
                               filters do (rest on the raw rate, B3 from the levelling
                               with 1 / tau_bias) */
} imf_robust_settings_t;

/* Internal: the settings as init keeps them (s: the IMU filter's own, and for the
   magnetometer the AHRS defaults, never read without a field) and the constants init
   derives from them once (the dt-dependent ones again by set_dt). */
typedef struct {
    imf_robust_settings_t s;                 /* the settings (above: units, ranges) */
    imf_real two_dt, dt2, r_d;               /* 2 dt, dt^2, 1 / dt */
    imf_real qg0, qg_dt, pgg0;               /* 1 / tau_acc^4, qg0 dt, 1 / dt^3 (1 /
                                                tau_acc^3 if gyr_bias_max is 0) */
    imf_real inv_rate_ref2;                  /* 1 / rate_ref^2, (rad/s)^-2; 0: constant */
    imf_real inv_tau_bias;                   /* 1 / tau_bias, 1/s; 0: no bias in motion */
    imf_real inv_tau_p, qb;                  /* B3: 1 / tau_p, the bias's prior variance;
                                                1 / tau_bias^2, its random walk per s */
    imf_real tau_b0, tau_h0;                 /* B3's shortest time constants from the
                                                levelling and the heading: 4 tau_acc,
                                                4 tau_mag, s */
    imf_real bias_var0;                      /* 3 gyr_bias_max^2, (rad/s)^2 (0 if rest_gyr is) */
    imf_real bias_w2;                        /* B2: (60 gyr_bias_max)^2, (rad/s)^2 */
    imf_real ku_motion;                      /* bu's fall per sample in motion, dt / tau_bias */
    imf_real rest_gyr2, rest_acc2;           /* (rad/s)^2, g^2 (relative) */
    imf_real k_rest, kb_rest, k_mag, k_ref;  /* dt / (tau + dt) */
    imf_real k_acc;                          /* dt / (tau_acc + dt) */
    imf_real c48;                            /* 1 / 48 */
    imf_real mag_noise2, mag_lag2, mag_min2; /* B6: squares */
    imf_real t_max;                          /* longest start-up horizon, s */
} imf_robust_consts_t;

/* One filter for both forms (as the published code and x-io Fusion): imf_robust_update with
   a magnetometer, imf_robust_update_imu without. */
typedef struct {
    uint32_t skipped;        /* samples rejected by the valid-attitude policy */
    imf_robust_state_t x;    /* the state (above): the estimate; write it only through the API */
    imf_robust_consts_t set; /* internal: the settings and what init derived from them */
} imf_robust_t;

/* The defaults listed with each member (those of imufuse.reference.RobustAHRS(0.01)). */
void imf_robust_default_settings(imf_robust_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them). */
void imf_robust_init(imf_robust_t *self, const imf_robust_settings_t *settings);
/* Gyroscope and accelerometer (B1-B3, B5). gx, gy, gz: rad/s; ax, ay, az: any unit */
void imf_robust_update_imu(imf_robust_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                           imf_real ay, imf_real az);
/* With the magnetometer (B4, B6 too). gx, gy, gz: rad/s; ax, ay, az and mx, my, mz: any
   unit (mag all zero: none) */
void imf_robust_update(imf_robust_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                       imf_real ay, imf_real az, imf_real mx, imf_real my, imf_real mz);

/* A new sample period dt (s): every dt-dependent constant by the expressions
   of init, so the filter equals one initialised with this dt bit for bit. */
void imf_robust_set_dt(imf_robust_t *self, imf_real dt);

/* Start again from att: q = s = att->q, c = 1; the next sample is the first
   (gravity, tilt and magnetic reference from it; the bias is kept). */
void imf_robust_set_attitude(imf_robust_t *self, const imf_attitude_t *att);

/* B6: the offset in use (field unit, sensor frame) into offset[3]; returns the standard
   deviation of the learnt estimate relative to the field (about 1 until the sensor has
   turned: the offset is not observable without turning). Store it at power-down ... */
imf_real imf_robust_get_mag_offset(const imf_robust_t *self, imf_real offset[3]);
/* ... and give it back at power-up: the stored offset, used until a trusted estimate
   differs from it by more than mag_offset_min; the estimator starts from it. */
void imf_robust_set_mag_offset(imf_robust_t *self, const imf_real offset[3]);

/* B1/B3: the gyro bias in use (rad/s, sensor frame) into bias[3]; returns how unknown it
   still is (bu: 1 until it has been learnt, at rest for a few tau_bias_rest or in motion
   for tau_bias; 0 once learnt). Store it at power-down ... */
imf_real imf_robust_get_gyr_bias(const imf_robust_t *self, imf_real bias[3]);
/* ... and give it back at power-up (or a calibrated zero-rate offset): the bias starts from
   it as known (bu = 0: the rest test uses rest_gyr around it, B3 learns with tau_bias).
   Each component within +-gyr_bias_max (not checked here: imufuse.reference checks it). */
void imf_robust_set_gyr_bias(imf_robust_t *self, const imf_real bias[3]);

#ifdef __cplusplus
}
#endif

#endif /* IMF_ROBUST_H */
