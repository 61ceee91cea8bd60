/*
 * Single-axis filters of the article, chapters 2 and 3.
 *
 * Per sample each filter takes the gyro rate (rad/s) and the angle computed
 * from the accelerometer (rad) and updates its angle estimate theta (rad).
 * dt is the fixed sample period in seconds.
 *
 * Pattern shared by every imufuse filter:
 *   imf_<filter>_t       settings (converted once by init) and the state x;
 *                        all members private to the filter's functions.
 *   imf_<filter>_init()  sets the settings and the initial state (all zero).
 *   imf_<filter>_update() one fixed step. Non-finite inputs, or an update that
 *                        would make the state non-finite, leave the state
 *                        unchanged and increment `skipped` (imf_math.h).
 *   imf_<filter>_set_dt() a new sample period: dt and every constant derived
 *                        from it, by the expressions init uses (init calls
 *                        it where dt has derived constants), so a filter
 *                        whose dt was set equals one initialised with that
 *                        dt bit for bit. For timestamps with jitter call it
 *                        before each update.
 * The state struct x holds only imf_real members: it is the `state` seen from
 * Python, in declaration order.
 */
#ifndef IMF_FILTERS_1D_H
#define IMF_FILTERS_1D_H

#include <stdint.h>
#include "imf_config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- Eq. 2.2: complementary filter, 1st order ------------------------- */
typedef struct {
    imf_real theta; /* angle estimate, rad */
} imf_complementary1d_state_t;

typedef struct {
    imf_real dt;              /* sample period, s */
    imf_real alpha;           /* weight of the gyro path, 0..1 */
    imf_real one_minus_alpha; /* 1 - alpha, weight of the accelerometer */
    uint32_t skipped;         /* samples rejected by the non-finite policy */
    imf_complementary1d_state_t
        x; /* the state (above): the estimate; write it only through the API */
} imf_complementary1d_t;

/* The settings of imf_complementary1d_init. Start from imf_complementary1d_default_settings(), then set what
   differs. */
typedef struct {
    imf_real dt; /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real
        alpha; /* weight of the gyro path, 0..1: alpha = (T/dt) / (1 + T/dt) for a time constant T (default 50/51: T = 0.5 s at 100 Hz) */
} imf_complementary1d_settings_t;

/* The defaults listed with each member. */
void imf_complementary1d_default_settings(imf_complementary1d_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them).
   State starts at 0. */
void imf_complementary1d_init(imf_complementary1d_t *self,
                              const imf_complementary1d_settings_t *settings);
/* rate: rad/s; angle: rad */
void imf_complementary1d_update(imf_complementary1d_t *self, imf_real rate, imf_real angle);
/* dt: s (alpha, K0 and the gains stay as given) */
void imf_complementary1d_set_dt(imf_complementary1d_t *self, imf_real dt);

/* ---- Eq. 2.5: Kalman filter with constant gain, 1st order -------------- */
typedef struct {
    imf_real theta; /* angle estimate, rad */
} imf_kalman1d_state_t;

typedef struct {
    imf_real dt;            /* sample period, s */
    imf_real k0;            /* Kalman gain K0, 0..1 */
    imf_real one_minus_k0;  /* 1 - K0 */
    uint32_t skipped;       /* samples rejected by the non-finite policy (state kept) */
    imf_kalman1d_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_kalman1d_t;

/* The settings of imf_kalman1d_init. Start from imf_kalman1d_default_settings(), then set what
   differs. */
typedef struct {
    imf_real dt; /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real k0; /* gain K0 of the angle, 0..1 (default 0.01) */
} imf_kalman1d_settings_t;

/* The defaults listed with each member. */
void imf_kalman1d_default_settings(imf_kalman1d_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them).
   State starts at 0. */
void imf_kalman1d_init(imf_kalman1d_t *self, const imf_kalman1d_settings_t *settings);
/* One sample: rate rad/s (gyro), angle rad (accelerometer). A non-finite input, or an update whose result is not finite, is rejected: the state keeps its value and skipped counts it. */
void imf_kalman1d_update(imf_kalman1d_t *self, imf_real rate, imf_real angle);
/* dt: s (alpha, K0 and the gains stay as given) */
void imf_kalman1d_set_dt(imf_kalman1d_t *self, imf_real dt);

/* ---- Eq. 2.8: Mahony&Madgwick filter (P controller), 1st order -------- */
typedef struct {
    imf_real theta; /* angle estimate, rad */
} imf_mahony1d_state_t;

typedef struct {
    imf_real dt;            /* sample period, s */
    imf_real kp;            /* proportional gain, 1/s */
    uint32_t skipped;       /* samples rejected by the non-finite policy (state kept) */
    imf_mahony1d_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_mahony1d_t;

/* The settings of imf_mahony1d_init. Start from imf_mahony1d_default_settings(), then set what
   differs. */
typedef struct {
    imf_real dt; /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real kp; /* proportional gain, 1/s, >= 0, kp dt < 2 (default 2) */
} imf_mahony1d_settings_t;

/* The defaults listed with each member. */
void imf_mahony1d_default_settings(imf_mahony1d_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them).
   State starts at 0. */
void imf_mahony1d_init(imf_mahony1d_t *self, const imf_mahony1d_settings_t *settings);
/* One sample: rate rad/s (gyro), angle rad (accelerometer). A non-finite input, or an update whose result is not finite, is rejected: the state keeps its value and skipped counts it. */
void imf_mahony1d_update(imf_mahony1d_t *self, imf_real rate, imf_real angle);
/* dt: s (alpha, K0 and the gains stay as given) */
void imf_mahony1d_set_dt(imf_mahony1d_t *self, imf_real dt);

/* ---- Eq. 3.3: Kalman filter with bias state, 2nd order ---------------- */
typedef struct {
    imf_real theta; /* angle estimate, rad */
    imf_real b;     /* gyro bias estimate, rad/s */
} imf_kalman1d_bias_state_t;

typedef struct {
    imf_real dt;           /* sample period, s */
    imf_real k0;           /* gain K0 of the angle, 0..1 */
    imf_real one_minus_k0; /* 1 - K0 */
    imf_real k1;           /* gain K1 of the bias, 1/s */
    imf_real bias_sign;    /* -1: rate - b (natural sign); +1: rate + b (Corollary #2) */
    uint32_t skipped;      /* samples rejected by the non-finite policy (state kept) */
    imf_kalman1d_bias_state_t
        x; /* the state (above): the estimate; write it only through the API */
} imf_kalman1d_bias_t;

/* The settings of imf_kalman1d_bias_init. Start from imf_kalman1d_bias_default_settings(), then set what
   differs. */
typedef struct {
    imf_real dt;   /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real k0;   /* gain K0 of the angle, 0 < k0 <= 1 (default 0.01) */
    imf_real k1;   /* gain K1 of the bias, 1/s (default -0.02) */
    int bias_sign; /* -1: rate - b (natural sign); +1: rate + b (Corollary #2) (default -1) */
} imf_kalman1d_bias_settings_t;

/* The defaults listed with each member. */
void imf_kalman1d_bias_default_settings(imf_kalman1d_bias_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them).
   State starts at 0. */
void imf_kalman1d_bias_init(imf_kalman1d_bias_t *self,
                            const imf_kalman1d_bias_settings_t *settings);
/* One sample: rate rad/s (gyro), angle rad (accelerometer). A non-finite input, or an update whose result is not finite, is rejected: the state keeps its value and skipped counts it. */
void imf_kalman1d_bias_update(imf_kalman1d_bias_t *self, imf_real rate, imf_real angle);
/* dt: s (alpha, K0 and the gains stay as given) */
void imf_kalman1d_bias_set_dt(imf_kalman1d_bias_t *self, imf_real dt);

/* ---- Eq. 3.6 / 3.9: Mahony&Madgwick filter (PI controller) ------------ */
typedef struct {
    imf_real theta; /* angle estimate, rad */
    imf_real i;     /* integral term I, rad/s (converges to minus the gyro bias) */
} imf_mahony1d_bias_state_t;

typedef struct {
    imf_real dt;         /* sample period, s */
    imf_real kp;         /* proportional gain, 1/s (K_p' of Eq. 3.9 if integrate_first) */
    imf_real ki;         /* integral gain Ki, 1/s^2 (kept for set_dt) */
    imf_real ki_dt;      /* Ki * dt, 1/s */
    int integrate_first; /* 0: Eq. 3.6; 1: reversed order, Eq. 3.9 */
    uint32_t skipped;    /* samples rejected by the non-finite policy (state kept) */
    imf_mahony1d_bias_state_t
        x; /* the state (above): the estimate; write it only through the API */
} imf_mahony1d_bias_t;

/* The settings of imf_mahony1d_bias_init. Start from imf_mahony1d_bias_default_settings(), then set what
   differs. */
typedef struct {
    imf_real dt; /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real kp; /* proportional gain, 1/s, >= 0 (K_p' of Eq. 3.9 if integrate_first; default 2) */
    imf_real ki; /* integral gain, 1/s^2, >= 0 (default 0.3) */
    int integrate_first; /* 0: Eq. 3.6; 1: reversed order, Eq. 3.9 (default 0) */
} imf_mahony1d_bias_settings_t;

/* The defaults listed with each member. */
void imf_mahony1d_bias_default_settings(imf_mahony1d_bias_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them).
   State starts at 0. */
void imf_mahony1d_bias_init(imf_mahony1d_bias_t *self,
                            const imf_mahony1d_bias_settings_t *settings);
/* One sample: rate rad/s (gyro), angle rad (accelerometer). A non-finite input, or an update whose result is not finite, is rejected: the state keeps its value and skipped counts it. */
void imf_mahony1d_bias_update(imf_mahony1d_bias_t *self, imf_real rate, imf_real angle);
/* dt: s; recomputes the constants derived from dt */
void imf_mahony1d_bias_set_dt(imf_mahony1d_bias_t *self, imf_real dt);

/* ---- Eq. 3.10: complementary filter, 2nd order ------------------------ */
/*
 * theta = [(Ki + Kp s) a + s w] / (s^2 + Kp s + Ki)     (Eq. 3.10 times Ki)
 * discretised by backward difference s = (1 - z^-1)/dt (Eq. 1.2). Run in its
 * PI form (theta' = w + Kp e + I, I' = Ki e, e = a - theta: the same transfer
 * function), solved for theta_k since e_k depends on it:
 *   theta_k = theta_{k-1} + (dt (w_k + I_{k-1}) + (Kp dt + Ki dt^2) e'_k) / a0,
 *   e'_k = a_k - theta_{k-1},  a0 = 1 + Kp dt + Ki dt^2,
 *   I_k = I_{k-1} + Ki dt (a_k - theta_k).
 * Not as a direct-form section: its poles sit near z = 1, where a direct form
 * amplifies the rounding of its coefficients and operations by about
 * a0 / (Ki dt^2), which in float32 moved the steady state by 0.6 % of the
 * angle (0.28 deg at 45 deg); here a constant angle is a fixed point (e = 0).
 */
typedef struct {
    imf_real theta; /* angle, rad */
    imf_real i;     /* integral term I, rad/s (minus the gyro bias at rest) */
} imf_complementary1d_bias_state_t;

typedef struct {
    imf_real dt;      /* sample period, s */
    imf_real kp, ki;  /* the gains, 1/s and 1/s^2 (kept for set_dt) */
    imf_real b0a;     /* (Kp dt + Ki dt^2) / a0: weight of the angle error */
    imf_real b0w;     /* dt / a0: weight of the rate */
    imf_real ki_dt;   /* Ki dt */
    uint32_t skipped; /* samples rejected by the non-finite policy (state kept) */
    imf_complementary1d_bias_state_t
        x; /* the state (above): the estimate; write it only through the API */
} imf_complementary1d_bias_t;

/* The settings of imf_complementary1d_bias_init. Start from imf_complementary1d_bias_default_settings(), then set what
   differs. */
typedef struct {
    imf_real dt; /* sample period, s; > 0 (default 0.01: 100 Hz) */
    imf_real kp; /* proportional gain, 1/s, > 0 (default 2) */
    imf_real ki; /* integral gain, 1/s^2, >= 0 (default 0.3) */
} imf_complementary1d_bias_settings_t;

/* The defaults listed with each member. */
void imf_complementary1d_bias_default_settings(imf_complementary1d_bias_settings_t *settings);
/* Settings as documented above (not checked here: imufuse.reference checks them).
   State starts at 0. */
void imf_complementary1d_bias_init(imf_complementary1d_bias_t *self,
                                   const imf_complementary1d_bias_settings_t *settings);
/* One sample: rate rad/s (gyro), angle rad (accelerometer). A non-finite input, or an update whose result is not finite, is rejected: the state keeps its value and skipped counts it. */
void imf_complementary1d_bias_update(imf_complementary1d_bias_t *self, imf_real rate,
                                     imf_real angle);
/* dt: s; recomputes the constants derived from dt */
void imf_complementary1d_bias_set_dt(imf_complementary1d_bias_t *self, imf_real dt);

#ifdef __cplusplus
}
#endif

#endif /* IMF_FILTERS_1D_H */
