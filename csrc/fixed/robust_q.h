/*
 * Fixed-point RobustIMU (csrc/robust.h, docs/recommended-ahrs.md) for MCUs without an
 * FPU: the blocks B1 (rest), B2 (gravity in the inertial frame, a Kalman filter), B3
 * (gyro bias in motion), B5 (start from the first samples) and the output latency, and
 * RobustAHRS (RobustAHRSQ: B4, the magnetometer confined to heading, and B6, its offset
 * learnt while turning; below), in
 * int32 with 16x16->32 multiplies only (no int64, no division: reciprocals and
 * square roots by imf_invsqrt_u32).  Mirrored line for line by
 * python/imufuse/reference/fixed_robust.py (robust_q.c: one function per block, the
 * blocks and their helpers in the private headers robust_q_blocks.h, robust_q_mag.h,
 * robust_q_b6.h, robust_q_ops.h and robust_q8.h, each with its twin module).
 *
 * Two profiles (the constants' profile, given to init; IMF_FIXED_PROFILE 32 or 8 compiles
 * one only), the same state, constants and blocks:
 *   32  q30 quaternions, products of a q30 value and a q15 snapshot (imf_q_mul_hq_p32)
 *   8   the same q30 state; every quaternion product and rotation one 16x16 product a
 *       term (q15 snapshots, or a snapshot and a vector narrowed to int16 with one
 *       exponent); normalisation first order in 16-bit products, the strapdown's folded
 *       into its step; unit vectors from 15 leading bits (imf_q_unit3_p8; B4's field
 *       and horizontal directions with one Newton step); the output q the product of c's
 *       and s's q15 snapshots (|q|^2 - 1 < 2e-4, up to 2.5e-3 after a full normalisation:
 *       the first sample, a turned-over start); reciprocals by Newton's z (2 - a z) in
 *       16x16 products, B2's gains in q27; B1, B3's matrix and the rest of B2 as the 32-bit
 *       profile (robust_q8.h, the 8-bit profile's helpers)
 * Both run on every target.
 *
 * Inputs are int16 counts: gyr in counts of gyr_scale rad/s, acc in any unit (the
 * filter is relative to its own low-passed magnitude, as the float filter).
 *
 * State x (int32, in this order):
 *   q[4]    estimate, sensor -> earth (NWU), q30
 *   s[4]    strapdown quaternion, sensor -> inertial frame, q30
 *   c[4]    correction, inertial -> earth frame, q30
 *   f[3]    gravity (specific force) in the inertial frame, q15 acc counts
 *   v[3]    B2's velocity-like state divided by tau_acc, q15 acc counts
 *   p[3]    B2's covariance (pvv, pvg, pgg) times dt, tau_acc dt, tau_acc^2 dt, q30 (the
 *           same filter as the float's with the measurement noise 1 and
 *           e = dt / tau_acc: P' = P - e (2 pvg, pgg, 0) + e^2 (pgg, 0, 0) + (0, 0, Q),
 *           Q = e^2 (1 + |w|^2 / rate_ref^2))
 *   b[3]    gyro bias, q15 gyro counts
 *   lw[3]   low-passed gyro (B1), q15 gyro counts
 *   la[3]   low-passed accelerometer (B1), q15 acc counts
 *   n       samples since the start (saturating at the longest start-up horizon)
 *   n_rest  samples at rest (saturating at rest_time)
 * Times are sample counts: t < tau is n < ceil(tau / dt).
 *
 * Ranges (refused at init otherwise, in the filter's own arithmetic):
 *   rate      |w| dt / 2 < 1/2 rad at the gyro's full scale (gyr_scale dt < 2^-15:
 *             2000 deg/s on 16 bits up to dt = 28 ms)
 *   dt        tau_acc / dt in [200, 8192]: e = dt / tau_acc in q30 keeps B2's
 *             covariance below 2 at 1e4 (rate_ref)^2 and its process noise above 16 LSB
 *   tau       tau_rest, tau_bias_rest, rest_time: up to 2^30 samples; tau_bias 0 or
 *             >= 4 tau_acc with 1 / (tau_bias gyr_scale) below 2^15;
 *             latency 0 .. 0.1 s; rest_acc 0 or in [1.1e-5, 1]
 */
#ifndef IMF_ROBUST_Q_H
#define IMF_ROBUST_Q_H

#include <stdint.h>
#include "imf_fixed.h"

/* B6 compiled in (1, the default) or left out (0: its code is not linked, saving 4 to 6 KB
 * of flash on an ATmega328P, and init refuses mag_learn 1; the state keeps B6's words) */
#ifndef IMF_ROBUST_Q_B6
#define IMF_ROBUST_Q_B6 1
#endif

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int32_t q[4];   /* estimate, sensor -> earth, q30 */
    int32_t s[4];   /* strapdown, sensor -> inertial frame, q30 */
    int32_t c[4];   /* correction, inertial -> earth frame, q30 */
    int32_t f[3];   /* gravity in the inertial frame, q15 acc counts */
    int32_t v[3];   /* B2 velocity-like state / tau_acc, q15 acc counts */
    int32_t p[3];   /* B2 covariance pvv, pvg, pgg (scaled, see above), q30 */
    int32_t b[3];   /* gyro bias, q15 gyro counts */
    int32_t lw[3];  /* low-passed gyro, q15 gyro counts */
    int32_t la[3];  /* low-passed accelerometer, q15 acc counts */
    int32_t n;      /* samples since the start (saturating) */
    int32_t n_rest; /* samples at rest (saturating) */
} imf_robust_imu_q_state_t;

/* The integer constants of imf_robust_imu_q_init_consts, identical on every target
 * (imufuse.reference.RobustIMUQ(...).c_init_args()). */
typedef struct {
    imf_qscale_t kg;      /* 0.5 gyr_scale dt: gyro counts -> half angle per sample */
    imf_qscale_t klat;    /* 0.5 gyr_scale latency (m 0: no prediction) */
    imf_qscale_t eps;     /* dt / tau_acc */
    imf_qscale_t kq;      /* 4 e^2 gyr_scale^2 / rate_ref^2 (m 0: rate_ref 0) */
    imf_qscale_t k_rest;  /* dt / (tau_rest + dt) */
    imf_qscale_t kb_rest; /* dt / (tau_bias_rest + dt) */
    imf_qscale_t kbias;   /* 1 / (tau_bias gyr_scale) (m 0: no bias in motion) */
    imf_qscale_t kacc2;   /* rest_acc^2 */
    int32_t qg0;          /* e^2, q30 */
    int32_t qcap;         /* 1e4 e^2, q30: the largest rate term */
    int32_t pg0;          /* e, q30: pgg at the first sample */
    uint32_t rest_g2;     /* ceil((rest_gyr / gyr_scale)^2), counts^2 */
    int32_t n_tau;        /* ceil(tau_rest / dt): B1's start-up */
    int32_t n_acc;        /* ceil(tau_acc / dt): B3 from then on */
    int32_t n_rest;       /* ceil(rest_time / dt) */
    int32_t n_max;        /* max(n_tau, n_acc): n saturates there */
    int32_t profile;      /* 32 or 8: the update's arithmetic (a profile compiled in) */
} imf_robust_imu_q_consts_t;

typedef struct {
    imf_robust_imu_q_consts_t k; /* the constants (above) */
    imf_robust_imu_q_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_robust_imu_q_t;

/* The settings of imf_robust_imu_q_init (those of imf_robust_imu_settings_t in double,
 * rad/s, and the gyro's scale). Start from imf_robust_imu_q_default_settings(), then set
 * dt and gyr_scale. */
typedef struct {
    double dt;            /* sample period, s; tau_acc / dt in [200, 8192] (default 0.01) */
    double tau_acc;       /* B2: tilt correction time constant, s (default 2.5) */
    double rate_ref;      /* B2: rate at which gravity's process noise doubles, rad/s;
                             >= 0, 0: constant (default 1.745: 100 deg/s) */
    double tau_bias;      /* B3: 0 (off) or >= 4 tau_acc, s (default 100) */
    double tau_bias_rest; /* B3 at rest, s; > 0 (default 3) */
    double rest_gyr;      /* B1: rest threshold, rad/s; >= 0 (default 0.0349: 2 deg/s) */
    double rest_acc;      /* B1: rest threshold on |a| - |a|_lowpass, relative; 0 .. 1
                             (default 0.05) */
    double rest_time;     /* B1: s; >= 0 (default 1.5) */
    double tau_rest;      /* B1: low-pass time constant, s; > 0 (default 0.5) */
    double latency;       /* output prediction, s; 0 .. 0.1 (default 0) */
    double gyr_scale;     /* rad/s per gyro count; > 0 (default 1.0642e-3: 2000 deg/s on
                             16 bits) */
    int profile;          /* 32 or 8, a profile compiled in (default 32; 8 in a build of the
                             8-bit profile only); any other value: init returns -1 */
} imf_robust_imu_q_settings_t;

/* The defaults listed with each member. */
void imf_robust_imu_q_default_settings(imf_robust_imu_q_settings_t *settings);
/* Returns 0, or -1 for a parameter out of range (then the filter is not usable). */
int imf_robust_imu_q_init(imf_robust_imu_q_t *self, const imf_robust_imu_q_settings_t *settings);
/* From the precomputed constants (integer only, identical on every target: init computes
 * them in double, which is 32 bits wide on avr-gcc). Returns 0, or -1 if a constant is
 * out of range. */
int imf_robust_imu_q_init_consts(imf_robust_imu_q_t *self, const imf_robust_imu_q_consts_t *consts);
/* One sample: gyr and acc in counts (every int16 is accepted; sums saturate; a zero
 * accelerometer is no reading, and no start without one). */
void imf_robust_imu_q_update_v(imf_robust_imu_q_t *self, const int16_t gyr[3],
                               const int16_t acc[3]);
/* The same sample in the float update's form (imf_robust_update_imu): gx, gy, gz, ax, ay, az in
 * counts, put into arrays for imf_robust_imu_q_update_v. Where the sample is in arrays, call that
 * (on AVR two pointers take fewer instructions than six values). */
static inline void imf_robust_imu_q_update(imf_robust_imu_q_t *self, int16_t gx, int16_t gy,
                                           int16_t gz, int16_t ax, int16_t ay, int16_t az);
static inline void imf_robust_imu_q_update(imf_robust_imu_q_t *self, int16_t gx, int16_t gy,
                                           int16_t gz, int16_t ax, int16_t ay, int16_t az)
{
    const int16_t gyr[3] = { gx, gy, gz }, acc[3] = { ax, ay, az };
    imf_robust_imu_q_update_v(self, gyr, acc);
}

/* ---- RobustAHRSQ: RobustIMUQ and B4, the magnetometer confined to heading --------
 *
 * The magnetometer in counts, any unit (B4 is relative to its own learned reference).
 * The offset in use is the stored one (imf_robust_ahrs_q_set_mag_offset, counts) until B6
 * (mag_learn 1; off by default) has a trusted estimate that differs from it by more than
 * mag_offset_min (csrc/robust.h's B6, in robust_q_b6.h; the same code in both profiles).
 *
 * State x: RobustIMUQ's, then
 *   u[3]     the offset in use, counts
 *   rn       reference field norm, q15 counts; rh, rz its horizontal and vertical
 *            parts relative to the norm (cos and sin of the dip), q30
 *   cn, ch, cz  the candidate reference, the same formats
 *   n_ok     samples the field has matched the reference (saturating at mag_hold)
 *   n_dist   samples since the field was last used (saturating at 2^30)
 *   n_cand   samples of motion the candidate has stayed the same
 * then B6's (constant while mag_learn is 0), relative to the field unit n0 = |m - u| at
 * the estimator's start:
 *   hi[6]    the field h in the inertial frame, then the offset o in the sensor frame, q26
 *   P[21]    their covariance, upper triangle by rows, q30
 *   so[3]    the stored offset, counts
 *   m_n2     n0^2, counts^2 (saturated to 2^31 - 1; 0: the estimator starts at the next
 *            reading); m_im, m_is: 1 / n0 and m_nm, m_ns: n0 as q-scales (mantissa, shift)
 *   m_ew, m_d2  mean and last normalised innovation, q16
 *   m_var    the offset's largest variance, q30 (1 before the estimator starts)
 *   mn[4]    the norm of the reading less u, relative to n0, low-passed, and its squared
 *            deviation from that low-pass, low-passed; then the same with the estimate
 *            (m_nu m_vu m_ne m_ve), q26
 *   m_qo     the offset's random walk not yet added to P, q46 (below 2^16)
 *   m_axis   the axis the next reading updates (0, 1, 2); m_bad: samples of absurd readings
 *
 * Ranges: RobustIMUQ's; tau_mag, tau_mag_ref, mag_new_time, mag_hold up to 2^30
 * samples; mag_norm 0 .. 1; mag_dip (a sine) >= 0; B6: mag_noise 0.01 .. 1 (its gains in
 * q24), mag_lag 0 .. 0.1 with (gyr_scale mag_lag)^2 a q-scale of shift 29 .. 62,
 * mag_offset_min 0 .. 1.
 */
typedef struct {
    imf_robust_imu_q_state_t imu; /* RobustIMUQ's state (above) */
    int32_t u[3];                 /* offset in use, counts */
    int32_t rn, rh, rz;           /* reference: norm q15 counts; cos, sin of the dip q30 */
    int32_t cn, ch, cz;           /* candidate reference, the same */
    int32_t n_ok, n_dist, n_cand; /* sample counters */
    /* B6 (all constant while mag_learn is 0) */
    int32_t hi[6];      /* field in the inertial frame h, then the offset o, q26 of n0 */
    int32_t P[21];      /* covariance of hi, upper triangle by rows, q30 */
    int32_t so[3];      /* stored offset, counts */
    int32_t m_n2;       /* n0^2, counts^2 (0: the estimator starts at the next reading) */
    int32_t m_im, m_is; /* 1 / n0 as a q-scale (mantissa, shift) */
    int32_t m_nm, m_ns; /* n0 (counts) as a q-scale */
    int32_t m_ew, m_d2; /* mean and last normalised innovation, q16 */
    int32_t m_var;      /* the offset's largest variance, q30 (1 until estimated) */
    int32_t mn[4];      /* the reading's norm through u and through the estimate: low-pass
                           and squared deviation, relative, q26 */
    int32_t m_qo;       /* the offset's walk not yet added to P, q46 */
    int32_t m_axis;     /* the axis the next reading updates: 0, 1, 2 */
    int32_t m_bad;      /* samples of absurd readings (saturating at n_bad) */
} imf_robust_ahrs_q_state_t;

typedef struct {
    imf_robust_imu_q_consts_t imu; /* RobustIMUQ's constants (n_max covers B4's horizons) */
    imf_qscale_t k_mag;            /* dt / (tau_mag + dt) */
    imf_qscale_t k_ref;            /* dt / (tau_mag_ref + dt) */
    imf_qscale_t knorm;            /* mag_norm (m 0: the field never matches) */
    int32_t kdip;                  /* mag_dip (a sine), q30, 2^31 - 1 for >= 2 (no test) */
    int32_t n_mag;                 /* ceil(tau_mag / dt): the heading's start-up */
    int32_t n_ref;                 /* ceil(tau_mag_ref / dt): the reference's */
    int32_t n_hold;                /* ceil(mag_hold / dt) */
    int32_t n_new;                 /* ceil(mag_new_time / dt) */
    int32_t learn;                 /* B6 on (1) or off (0) */
    int32_t kqh;                   /* B6: the field's walk per sample, 1e-3 dt, q30 */
    int32_t kqo;                   /* B6: the offset's walk per sample, 1e-7 dt, q46 */
    int32_t knoise2;               /* B6: mag_noise^2, q28 */
    imf_qscale_t klag2;            /* B6: (gyr_scale mag_lag)^2 (m 0: no lag) */
    int32_t kmin2;                 /* B6: mag_offset_min^2, q30 */
    int32_t n_bad;                 /* B6: ceil(1 s / dt): absurd readings before a restart */
} imf_robust_ahrs_q_consts_t;

typedef struct {
    imf_robust_ahrs_q_consts_t k; /* the constants (above) */
    imf_robust_ahrs_q_state_t x;  /* the state (above); write it only through the API */
} imf_robust_ahrs_q_t;

/* The settings of imf_robust_ahrs_q_init: RobustIMUQ's and B4's (those of
 * imf_robust_ahrs_settings_t, in double). */
typedef struct {
    double dt;             /* sample period, s; tau_acc / dt in [200, 8192] (default 0.01) */
    double tau_acc;        /* B2: tilt correction time constant, s (default 2.5) */
    double rate_ref;       /* B2: rate at which gravity's process noise doubles, rad/s;
                             >= 0, 0: constant (default 1.745: 100 deg/s) */
    double tau_bias;       /* B3: 0 (off) or >= 4 tau_acc, s (default 100) */
    double tau_bias_rest;  /* B3 at rest, s; > 0 (default 3) */
    double rest_gyr;       /* B1: rest threshold, rad/s; >= 0 (default 0.0349: 2 deg/s) */
    double rest_acc;       /* B1: rest threshold on |a| - |a|_lowpass, relative; 0 .. 1
                             (default 0.05) */
    double rest_time;      /* B1: s; >= 0 (default 1.5) */
    double tau_rest;       /* B1: low-pass time constant, s; > 0 (default 0.5) */
    double latency;        /* output prediction, s; 0 .. 0.1 (default 0) */
    double tau_mag;        /* B4: heading correction time constant, s; > 0 (default 10) */
    double mag_norm;       /* B4: disturbance threshold on |m|, relative; 0 .. 1 (default 0.1) */
    double mag_dip;        /* B4: disturbance threshold on the dip, its sine; >= 0, 2: none
                            (default 0.1736: 10 deg) */
    double tau_mag_ref;    /* B4: the learned reference's time constant, s; > 0 (default 20) */
    double mag_new_time;   /* B4: a changed field steady this long in motion becomes the
                            reference, s; >= 0 (default 20) */
    double mag_hold;       /* B4: the field must match this long after a disturbance, s;
                            >= 0 (default 0.5) */
    int mag_learn;         /* B6: learn the magnetometer's offset while turning (1); 0 (default):
                             the stored offset only */
    double mag_noise;      /* B6: magnetometer noise, relative to the field; 0.01 .. 1
                             (default 0.02) */
    double mag_lag;        /* B6: magnetometer-to-gyro timing mismatch, s; 0 .. 0.1 (default
                             0.003) */
    double mag_offset_min; /* B6: a trusted estimate replaces the stored offset when they
                              differ by more than this, relative; 0 .. 1 (default 0.1) */
    double gyr_scale;      /* rad/s per gyro count; > 0 (default 1.0642e-3) */
    int profile;           /* 32 or 8, a profile compiled in (default 32; 8 in a build of the
                              8-bit profile only); any other value: init returns -1 */
} imf_robust_ahrs_q_settings_t;

/* The defaults listed with each member. */
void imf_robust_ahrs_q_default_settings(imf_robust_ahrs_q_settings_t *settings);
/* Returns 0, or -1 for a parameter out of range (then the filter is not usable). */
int imf_robust_ahrs_q_init(imf_robust_ahrs_q_t *self, const imf_robust_ahrs_q_settings_t *settings);
/* From the precomputed constants; 0, or -1 if a constant is out of range. */
int imf_robust_ahrs_q_init_consts(imf_robust_ahrs_q_t *self,
                                  const imf_robust_ahrs_q_consts_t *consts);
/* The stored offset (hard iron), magnetometer counts in the sensor frame, used from the
 * next sample; B6 starts again from it. init and init_consts clear it: set it after them. */
void imf_robust_ahrs_q_set_mag_offset(imf_robust_ahrs_q_t *self, const int16_t offset[3]);
/* One sample: gyr, acc and mag in counts (an all-zero mag is no reading). */
void imf_robust_ahrs_q_update_v(imf_robust_ahrs_q_t *self, const int16_t gyr[3],
                                const int16_t acc[3], const int16_t mag[3]);
/* The same sample in the float update's form (imf_robust_update): gx, gy, gz, ax, ay, az, mx, my,
 * mz in counts, put into arrays for imf_robust_ahrs_q_update_v. Where the sample is in arrays,
 * call that (on AVR three pointers take fewer instructions than nine values). */
static inline void imf_robust_ahrs_q_update(imf_robust_ahrs_q_t *self, int16_t gx, int16_t gy,
                                            int16_t gz, int16_t ax, int16_t ay, int16_t az,
                                            int16_t mx, int16_t my, int16_t mz);
static inline void imf_robust_ahrs_q_update(imf_robust_ahrs_q_t *self, int16_t gx, int16_t gy,
                                            int16_t gz, int16_t ax, int16_t ay, int16_t az,
                                            int16_t mx, int16_t my, int16_t mz)
{
    const int16_t gyr[3] = { gx, gy, gz }, acc[3] = { ax, ay, az }, mag[3] = { mx, my, mz };
    imf_robust_ahrs_q_update_v(self, gyr, acc, mag);
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_ROBUST_Q_H */
