/*
 * Single-axis filters of the article, chapters 2 and 3. See filters_1d.h.
 * The pure-Python twin is python/imufuse/reference/filters_1d.py: the same
 * lines in the same order.
 */
#include <stddef.h>
#include "filters_1d.h"
#include "imf_math.h"

/* Complementary1D, Kalman1D and Mahony1D begin with their settings' two members, of the
   same types in the same order (checked here). init copies them (the twin's _init sets
   them one by one): on AVR as one block, a loop about half the size of its 8-bit loads and
   stores member by member; elsewhere member by member, in aligned words (a block copy
   through pointers of unknown alignment is bytewise on RV32). The same values either way. */
#define IMF_HEAD_IS_SETTINGS(f, second) \
    typedef char imf_##f##_head_is_its_settings \
        [offsetof(imf_##f##_t, second) == offsetof(imf_##f##_settings_t, second) \
                 && sizeof(imf_##f##_settings_t) \
                        == offsetof(imf_##f##_t, second) + sizeof(imf_real) \
             ? 1 \
             : -1]
IMF_HEAD_IS_SETTINGS(complementary1d, alpha);
IMF_HEAD_IS_SETTINGS(kalman1d, k0);
IMF_HEAD_IS_SETTINGS(mahony1d, kp);
#if defined(__AVR__)
#define IMF_COPY_HEAD(self, s, first, second) memcpy((self), (s), sizeof *(s))
#else
#define IMF_COPY_HEAD(self, s, first, second) \
    ((self)->first = (s)->first, (self)->second = (s)->second)
#endif

/* ---- Eq. 2.2 ----------------------------------------------------------- */
void imf_complementary1d_default_settings(imf_complementary1d_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->alpha = IMF_R(0.9803921568627451);
}

void imf_complementary1d_init(imf_complementary1d_t *const self,
                              const imf_complementary1d_settings_t *const s)
{
    IMF_COPY_HEAD(self, s, dt, alpha);
    self->one_minus_alpha = IMF_R(1.0) - self->alpha;
    self->skipped = 0;
    self->x.theta = IMF_R(0.0);
}

void imf_complementary1d_set_dt(imf_complementary1d_t *const self, const imf_real dt)
{
    self->dt = dt;
}

void imf_complementary1d_update(imf_complementary1d_t *const self, const imf_real rate,
                                const imf_real angle)
{
    imf_real theta;
    if (!imf_finite2(rate, angle)) {
        self->skipped++;
        return;
    }
    /* Eq. 2.2: theta_k = alpha (theta_{k-1} + w_k dt) + (1 - alpha) a_k */
    theta = self->alpha * (self->x.theta + rate * self->dt) + self->one_minus_alpha * angle;
    if (!isfinite(theta)) {
        self->skipped++;
        return;
    }
    self->x.theta = theta;
}

/* ---- Eq. 2.5 ----------------------------------------------------------- */
void imf_kalman1d_default_settings(imf_kalman1d_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->k0 = IMF_R(0.01);
}

void imf_kalman1d_init(imf_kalman1d_t *const self, const imf_kalman1d_settings_t *const s)
{
    IMF_COPY_HEAD(self, s, dt, k0);
    self->one_minus_k0 = IMF_R(1.0) - self->k0;
    self->skipped = 0;
    self->x.theta = IMF_R(0.0);
}

void imf_kalman1d_set_dt(imf_kalman1d_t *const self, const imf_real dt)
{
    self->dt = dt;
}

void imf_kalman1d_update(imf_kalman1d_t *const self, const imf_real rate, const imf_real angle)
{
    imf_real theta_pred, theta;
    if (!imf_finite2(rate, angle)) {
        self->skipped++;
        return;
    }
    /* Eq. 2.5: predict with the gyro, then correct with the accelerometer */
    theta_pred = self->x.theta + rate * self->dt;
    theta = self->one_minus_k0 * theta_pred + self->k0 * angle;
    if (!isfinite(theta)) {
        self->skipped++;
        return;
    }
    self->x.theta = theta;
}

/* ---- Eq. 2.8 ----------------------------------------------------------- */
void imf_mahony1d_default_settings(imf_mahony1d_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->kp = IMF_R(2.0);
}

void imf_mahony1d_init(imf_mahony1d_t *const self, const imf_mahony1d_settings_t *const s)
{
    IMF_COPY_HEAD(self, s, dt, kp);
    self->skipped = 0;
    self->x.theta = IMF_R(0.0);
}

void imf_mahony1d_set_dt(imf_mahony1d_t *const self, const imf_real dt)
{
    self->dt = dt;
}

void imf_mahony1d_update(imf_mahony1d_t *const self, const imf_real rate, const imf_real angle)
{
    imf_real e, theta;
    if (!imf_finite2(rate, angle)) {
        self->skipped++;
        return;
    }
    /* Eq. 2.8: the error uses the previous estimate theta_{k-1} (Eq. 2.12) */
    e = angle - self->x.theta;
    theta = self->x.theta + (self->kp * e + rate) * self->dt;
    if (!isfinite(theta)) {
        self->skipped++;
        return;
    }
    self->x.theta = theta;
}

/* ---- Eq. 3.3 ----------------------------------------------------------- */
void imf_kalman1d_bias_default_settings(imf_kalman1d_bias_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->k0 = IMF_R(0.01);
    settings->k1 = IMF_R(-0.02);
    settings->bias_sign = -1;
}

void imf_kalman1d_bias_init(imf_kalman1d_bias_t *const self,
                            const imf_kalman1d_bias_settings_t *const s)
{
    imf_kalman1d_bias_set_dt(self, s->dt);
    self->k0 = s->k0;
    self->one_minus_k0 = IMF_R(1.0) - s->k0;
    self->k1 = s->k1;
    self->bias_sign = s->bias_sign < 0 ? IMF_R(-1.0) : IMF_R(1.0);
    self->skipped = 0;
    self->x.theta = IMF_R(0.0);
    self->x.b = IMF_R(0.0);
}

void imf_kalman1d_bias_set_dt(imf_kalman1d_bias_t *const self, const imf_real dt)
{
    self->dt = dt;
}

void imf_kalman1d_bias_update(imf_kalman1d_bias_t *const self, const imf_real rate,
                              const imf_real angle)
{
    imf_real theta_pred, theta, b;
    if (!imf_finite2(rate, angle)) {
        self->skipped++;
        return;
    }
    /* Eq. 3.3: theta^-_k = theta_{k-1} + (w_k -+ b_{k-1}) dt; the sign only
       enters here, the bias update law is the same for both (Corollary #2) */
    theta_pred = self->x.theta + (rate + self->bias_sign * self->x.b) * self->dt;
    theta = self->one_minus_k0 * theta_pred + self->k0 * angle;
    b = self->x.b + self->k1 * (angle - theta_pred);
    if (!imf_finite2(theta, b)) {
        self->skipped++;
        return;
    }
    self->x.theta = theta;
    self->x.b = b;
}

/* ---- Eq. 3.6 / 3.9 ----------------------------------------------------- */
void imf_mahony1d_bias_default_settings(imf_mahony1d_bias_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->kp = IMF_R(2.0);
    settings->ki = IMF_R(0.3);
    settings->integrate_first = 0;
}

void imf_mahony1d_bias_init(imf_mahony1d_bias_t *const self,
                            const imf_mahony1d_bias_settings_t *const s)
{
    self->kp = s->kp;
    self->ki = s->ki;
    imf_mahony1d_bias_set_dt(self, s->dt);
    self->integrate_first = s->integrate_first != 0;
    self->skipped = 0;
    self->x.theta = IMF_R(0.0);
    self->x.i = IMF_R(0.0);
}

void imf_mahony1d_bias_set_dt(imf_mahony1d_bias_t *const self, const imf_real dt)
{
    self->dt = dt;
    self->ki_dt = self->ki * dt;
}

void imf_mahony1d_bias_update(imf_mahony1d_bias_t *const self, const imf_real rate,
                              const imf_real angle)
{
    imf_real e, i, theta;
    if (!imf_finite2(rate, angle)) {
        self->skipped++;
        return;
    }
    e = angle - self->x.theta;
    if (!self->integrate_first) {
        /* Eq. 3.6: I_k = I_{k-1} + Ki dt e_k; theta_k = theta_{k-1} + (Kp e_k + I_k + w_k) dt */
        i = self->x.i + self->ki_dt * e;
        theta = self->x.theta + (self->kp * e + i + rate) * self->dt;
    } else {
        /* Eq. 3.9: theta_k = theta_{k-1} + (w_k + I_{k-1}) dt + Kp' dt e_k; then I_k */
        theta = self->x.theta + (rate + self->x.i) * self->dt;
        theta = theta + self->kp * self->dt * e;
        i = self->x.i + self->ki_dt * e;
    }
    if (!imf_finite2(theta, i)) {
        self->skipped++;
        return;
    }
    self->x.theta = theta;
    self->x.i = i;
}

/* ---- Eq. 3.10 ---------------------------------------------------------- */
void imf_complementary1d_bias_default_settings(imf_complementary1d_bias_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->kp = IMF_R(2.0);
    settings->ki = IMF_R(0.3);
}

void imf_complementary1d_bias_init(imf_complementary1d_bias_t *const self,
                                   const imf_complementary1d_bias_settings_t *const s)
{
    self->kp = s->kp;
    self->ki = s->ki;
    imf_complementary1d_bias_set_dt(self, s->dt);
    self->skipped = 0;
    self->x.theta = IMF_R(0.0);
    self->x.i = IMF_R(0.0);
}

void imf_complementary1d_bias_set_dt(imf_complementary1d_bias_t *const self, const imf_real dt)
{
    /* a0 = 1 + Kp dt + Ki dt^2: the z^0 term of (1 - z^-1)^2 + Kp dt (1 - z^-1) + Ki dt^2 */
    const imf_real kp_dt = self->kp * dt;
    const imf_real ki_dt2 = self->ki * dt * dt;
    const imf_real a0 = IMF_R(1.0) + kp_dt + ki_dt2;
    self->dt = dt;
    self->b0a = (kp_dt + ki_dt2) / a0;
    self->b0w = dt / a0;
    self->ki_dt = self->ki * dt;
}

void imf_complementary1d_bias_update(imf_complementary1d_bias_t *const self, const imf_real rate,
                                     const imf_real angle)
{
    imf_real theta, i;
    if (!imf_finite2(rate, angle)) {
        self->skipped++;
        return;
    }
    /* Eq. 3.10 by backward difference, solved for theta_k:
       theta_k = theta_{k-1} + (dt (w_k + I_{k-1}) + (Kp dt + Ki dt^2)(a_k - theta_{k-1})) / a0 */
    theta = self->x.theta + (self->b0w * (rate + self->x.i) + self->b0a * (angle - self->x.theta));
    /* I_k = I_{k-1} + Ki dt e_k, e_k = a_k - theta_k */
    i = self->x.i + self->ki_dt * (angle - theta);
    if (!imf_finite2(theta, i)) {
        self->skipped++;
        return;
    }
    self->x.theta = theta;
    self->x.i = i;
}
