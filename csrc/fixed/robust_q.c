/* Fixed-point RobustIMU and RobustAHRS (B4 and B6); see robust_q.h for the Q formats and
 * ranges. This file: the settings, the constants, init and the updates, which compose the
 * blocks of robust_q_blocks.h, robust_q_mag.h and robust_q_b6.h (their helpers in robust_q_ops.h and, for
 * the 8-bit profile, robust_q8.h: private headers included once, one translation unit).
 * Mirrored line for line by python/imufuse/reference/fixed_robust.py; the blocks and
 * their order are those of csrc/robust.c. */
#include <stddef.h>
#include <string.h>
#include "robust_q.h"
#include "imf_fixed_init.h"
#include "imf_fixed_quat.h"
#include "robust_q_blocks.h"
#include "robust_q_mag.h"
#include "robust_q_b6.h"

/* ---- init ----------------------------------------------------------------------- */

/* a q-scale constant: 0, or its shift within [smin, smax] */
static int robust_q_ok(const imf_qscale_t c, const int smin, const int smax)
{
    return c.m == 0 || imf_qscale_ok(c, smin, smax);
}

void imf_robust_imu_q_default_settings(imf_robust_imu_q_settings_t *const s)
{
    s->dt = 0.01;
    s->tau_acc = 2.5;
    s->rate_ref = 1.7453292519943295; /* 100 deg/s */
    s->tau_bias = 100.0;
    s->tau_bias_rest = 3.0;
    s->rest_gyr = 0.03490658503988659; /* 2 deg/s */
    s->rest_acc = 0.05;
    s->rest_time = 1.5;
    s->tau_rest = 0.5;
    s->latency = 0.0;
    s->gyr_scale = 1.0642e-3;
    s->profile = IMF_Q_DEFAULT_PROFILE;
}

/* the IMU constants in range (shifts of imf_scale32_s: kg (gyr_scale dt < 2^-15), klat,
 * eps (e in [1/8192, 1/200]), kq, the low-pass gains, kbias, kacc2) */
static int robust_q_consts_ok(const imf_robust_imu_q_consts_t *const k)
{
    return !(k->kg.m == 0 || !imf_qscale_ok(k->kg, 31, 62) || !robust_q_ok(k->klat, 15, 62)
             || k->eps.m == 0 || !imf_qscale_ok(k->eps, 22, 27) || !robust_q_ok(k->kq, 30, 62)
             || k->k_rest.m == 0 || !imf_qscale_ok(k->k_rest, 0, 47) || k->kb_rest.m == 0
             || !imf_qscale_ok(k->kb_rest, 0, 47) || !robust_q_ok(k->kbias, -15, 32)
             || !imf_qscale_ok(k->kacc2, 14, 47) || k->qg0 < 16 || k->qcap < k->qg0 || k->pg0 <= 0
             || k->n_tau < 0 || k->n_acc < 0 || k->n_rest < 0 || k->n_max < k->n_tau
             || k->n_max < k->n_acc || k->n_max > 1073741824L || !imf_q_profile_ok(k->profile));
}

/* the IMU state at power-up: zero, but the three quaternions the identity (one memset:
 * the stores one by one were 250 bytes of AVR flash) */
static void robust_q_clear(imf_robust_imu_q_state_t *const x)
{
    memset(x, 0, sizeof *x);
    x->q[0] = x->s[0] = x->c[0] = IMF_Q30_ONE;
}

int imf_robust_imu_q_init_consts(imf_robust_imu_q_t *const self,
                                 const imf_robust_imu_q_consts_t *const k)
{
    if (!robust_q_consts_ok(k)) {
        return -1;
    }
    self->k = *k;
    robust_q_clear(&self->x);
    return 0;
}

/* ceil(v) for v in [0, 2^30] (else -1: refused) */
static int32_t robust_q_ceil(const double v)
{
    const double c = ceil(v);
    return (c >= 0.0 && c <= 1073741824.0) ? (int32_t)c : -1;
}

/* the IMU constants from the settings: 0, or -1 for a parameter out of range */
static int robust_q_consts(const imf_robust_imu_q_settings_t *const s,
                           imf_robust_imu_q_consts_t *const kp)
{
    imf_robust_imu_q_consts_t k;
    const double dt = s->dt, gs = s->gyr_scale, e = s->dt / s->tau_acc;
    const double g2 = s->rest_gyr / gs;
    if (!(dt > 0.0) || !(gs > 0.0) || !(s->tau_acc >= 200.0 * dt && s->tau_acc <= 8192.0 * dt)
        || !(s->rate_ref >= 0.0) || !(s->tau_bias == 0.0 || s->tau_bias >= 4.0 * s->tau_acc)
        || !(s->tau_bias_rest > 0.0) || !imf_param_ok(s->rest_gyr, 0.0, 1e30)
        || !imf_param_ok(s->rest_acc, 0.0, 1.0) || !imf_param_ok(s->rest_time, 0.0, 1e30)
        || !(s->tau_rest > 0.0) || !imf_param_ok(s->latency, 0.0, 0.1)
        || !imf_q_profile_ok(s->profile)) {
        return -1;
    }
    k.kg = imf_qscale_from_double(0.5 * gs * dt);
    k.klat = imf_qscale_from_double(0.5 * gs * s->latency);
    k.eps = imf_qscale_from_double(e);
    k.kq = imf_qscale_from_double(
        s->rate_ref > 0.0 ? 4.0 * e * e * (gs / s->rate_ref) * (gs / s->rate_ref) : 0.0);
    k.k_rest = imf_qscale_from_double(dt / (s->tau_rest + dt));
    k.kb_rest = imf_qscale_from_double(dt / (s->tau_bias_rest + dt));
    k.kbias = imf_qscale_from_double(s->tau_bias > 0.0 ? 1.0 / (s->tau_bias * gs) : 0.0);
    k.kacc2 = imf_qscale_from_double(s->rest_acc * s->rest_acc);
    k.qg0 = (int32_t)floor(e * e * 1073741824.0 + 0.5);
    k.qcap = (int32_t)floor(1e4 * e * e * 1073741824.0 + 0.5);
    k.pg0 = (int32_t)floor(e * 1073741824.0 + 0.5);
    k.rest_g2 = g2 * g2 >= 4294967295.0 ? 4294967295u : (uint32_t)ceil(g2 * g2);
    k.n_tau = robust_q_ceil(s->tau_rest / dt);
    k.n_acc = robust_q_ceil(s->tau_acc / dt);
    k.n_rest = robust_q_ceil(s->rest_time / dt);
    k.n_max = k.n_tau > k.n_acc ? k.n_tau : k.n_acc;
    k.profile = s->profile;
    /* a constant of a block that is on must not underflow to 0 (off) */
    if ((s->rate_ref > 0.0 && k.kq.m == 0) || (s->tau_bias > 0.0 && k.kbias.m == 0)
        || (s->latency > 0.0 && k.klat.m == 0) || (s->rest_acc > 0.0 && k.kacc2.m == 0)) {
        return -1;
    }
    *kp = k;
    return 0;
}

int imf_robust_imu_q_init(imf_robust_imu_q_t *const self,
                          const imf_robust_imu_q_settings_t *const s)
{
    imf_robust_imu_q_consts_t k;
    if (robust_q_consts(s, &k) != 0) {
        return -1;
    }
    return imf_robust_imu_q_init_consts(self, &k);
}

/* ---- the update ----------------------------------------------------------------- */

/* B1, B2, B3 and B5 of one sample; returns 0 when the sample is not taken (no start
 * without an accelerometer reading), then nothing else runs. rq: NULL, or where the
 * rotation matrix of the new q is written (all three rows, for B4; B3 uses it too). Out
 * of line, as robust_q_magnetometer: inlined into one update (LTO), their register spills cost
 * the Uno 0.8 KB of flash more than the calls */
static IMF_Q_NOINLINE int robust_q_step(const imf_robust_imu_q_consts_t *const k,
                                        imf_robust_imu_q_state_t *const x, const int16_t gyr[3],
                                        const int16_t acc[3], int16_t *const rq)
{
    int16_t sn[4], r[4];
    uint32_t w2;
    const int first = x->n == 0;
    const int has_acc = robust_q_acc_reading(x, acc, first);
    int at_rest;
    if (first && !has_acc) {
        return 0; /* no start without an accelerometer reading */
    }
    at_rest = robust_q_rest(k, x, gyr, acc, has_acc, &w2); /* B1 */
    robust_q_strapdown(k, x, gyr, sn);
    robust_q_gravity(k, x, acc, sn, first, has_acc, w2); /* B2 */
    robust_q_level(k, x, sn, r);
    robust_q_bias(k, x, at_rest, r, rq); /* B3 */
    return 1;
}

void imf_robust_imu_q_update_v(imf_robust_imu_q_t *const self, const int16_t gyr[3],
                               const int16_t acc[3])
{
    if (robust_q_step(&self->k, &self->x, gyr, acc, NULL)) {
        robust_q_output(&self->k, &self->x, gyr);
    }
}

/* ---- RobustAHRSQ: B4, the magnetometer confined to heading, and B6 ----------------- */

void imf_robust_ahrs_q_default_settings(imf_robust_ahrs_q_settings_t *const s)
{
    imf_robust_imu_q_settings_t m;
    imf_robust_imu_q_default_settings(&m);
    s->dt = m.dt;
    s->tau_acc = m.tau_acc;
    s->rate_ref = m.rate_ref;
    s->tau_bias = m.tau_bias;
    s->tau_bias_rest = m.tau_bias_rest;
    s->rest_gyr = m.rest_gyr;
    s->rest_acc = m.rest_acc;
    s->rest_time = m.rest_time;
    s->tau_rest = m.tau_rest;
    s->latency = m.latency;
    s->tau_mag = 10.0;
    s->mag_norm = 0.1;
    s->mag_dip = 0.17364817766693033; /* sin 10 deg */
    s->tau_mag_ref = 20.0;
    s->mag_new_time = 20.0;
    s->mag_hold = 0.5;
    s->mag_learn = 0;
    s->mag_noise = 0.02;
    s->mag_lag = 0.003;
    s->mag_offset_min = 0.1;
    s->gyr_scale = m.gyr_scale;
    s->profile = m.profile;
}

int imf_robust_ahrs_q_init_consts(imf_robust_ahrs_q_t *const self,
                                  const imf_robust_ahrs_q_consts_t *const k)
{
    imf_robust_ahrs_q_state_t *const x = &self->x;
    /* the IMU's; mag_norm <= 1; B4's horizons within n_max */
    if (!robust_q_consts_ok(&k->imu) || k->k_mag.m == 0 || !imf_qscale_ok(k->k_mag, 0, 47)
        || k->k_ref.m == 0 || !imf_qscale_ok(k->k_ref, 0, 47) || !robust_q_ok(k->knorm, 14, 47)
        || k->kdip < 0 || k->n_mag < 0 || k->n_ref < 0 || k->n_hold < 0 || k->n_new < 0
        || k->imu.n_max < k->n_mag || k->imu.n_max < k->n_ref || k->learn < 0
        || k->learn > IMF_ROBUST_Q_B6 || k->kqh < 0 || k->kqo < 0 || k->kqo > 1073741824L
        || k->knoise2 < 26843L || k->knoise2 > 268435456L || !robust_q_ok(k->klag2, 29, 62)
        || k->kmin2 < 0 || k->kmin2 > 1073741824L || k->n_bad < 1) {
        return -1;
    }
    self->k = *k;
    memset(x, 0, sizeof *x);
    robust_q_clear(&x->imu);
    x->m_var = IMF_Q30_ONE;
    return 0;
}

int imf_robust_ahrs_q_init(imf_robust_ahrs_q_t *const self,
                           const imf_robust_ahrs_q_settings_t *const s)
{
    imf_robust_ahrs_q_consts_t k;
    imf_robust_imu_q_settings_t m;
    const double dt = s->dt;
    m.dt = dt;
    m.tau_acc = s->tau_acc;
    m.rate_ref = s->rate_ref;
    m.tau_bias = s->tau_bias;
    m.tau_bias_rest = s->tau_bias_rest;
    m.rest_gyr = s->rest_gyr;
    m.rest_acc = s->rest_acc;
    m.rest_time = s->rest_time;
    m.tau_rest = s->tau_rest;
    m.latency = s->latency;
    m.gyr_scale = s->gyr_scale;
    m.profile = s->profile;
    if (robust_q_consts(&m, &k.imu) != 0 || !(s->tau_mag > 0.0) || !(s->tau_mag_ref > 0.0)
        || !imf_param_ok(s->mag_norm, 0.0, 1.0) || !imf_param_ok(s->mag_dip, 0.0, 1e30)
        || !imf_param_ok(s->mag_new_time, 0.0, 1e30) || !imf_param_ok(s->mag_hold, 0.0, 1e30)
        || (s->mag_learn != 0 && s->mag_learn != IMF_ROBUST_Q_B6)
        || !imf_param_ok(s->mag_noise, 0.01, 1.0) || !imf_param_ok(s->mag_lag, 0.0, 0.1)
        || !imf_param_ok(s->mag_offset_min, 0.0, 1.0)) {
        return -1;
    }
    k.k_mag = imf_qscale_from_double(dt / (s->tau_mag + dt));
    k.k_ref = imf_qscale_from_double(dt / (s->tau_mag_ref + dt));
    k.knorm = imf_qscale_from_double(s->mag_norm);
    k.kdip = s->mag_dip >= 2.0 ? 2147483647L : (int32_t)floor(s->mag_dip * 1073741824.0 + 0.5);
    k.n_mag = robust_q_ceil(s->tau_mag / dt);
    k.n_ref = robust_q_ceil(s->tau_mag_ref / dt);
    k.n_hold = robust_q_ceil(s->mag_hold / dt);
    k.n_new = robust_q_ceil(s->mag_new_time / dt);
    k.learn = s->mag_learn;
    k.kqh = (int32_t)floor(1e-3 * dt * 1073741824.0 + 0.5);
    k.kqo = (int32_t)floor(1e-7 * dt * 70368744177664.0 + 0.5);
    k.knoise2 = (int32_t)floor(s->mag_noise * s->mag_noise * 268435456.0 + 0.5);
    k.klag2 = imf_qscale_from_double((s->gyr_scale * s->mag_lag) * (s->gyr_scale * s->mag_lag));
    k.kmin2 = (int32_t)floor(s->mag_offset_min * s->mag_offset_min * 1073741824.0 + 0.5);
    k.n_bad = robust_q_ceil(1.0 / dt);
    k.imu.n_max = k.imu.n_max > k.n_mag ? k.imu.n_max : k.n_mag;
    k.imu.n_max = k.imu.n_max > k.n_ref ? k.imu.n_max : k.n_ref;
    if ((s->mag_norm > 0.0 && k.knorm.m == 0) || (s->mag_lag > 0.0 && k.klag2.m == 0)
        || k.n_bad < 1) {
        return -1;
    }
    return imf_robust_ahrs_q_init_consts(self, &k);
}

void imf_robust_ahrs_q_set_mag_offset(imf_robust_ahrs_q_t *const self, const int16_t offset[3])
{
    int i;
    for (i = 0; i < 3; ++i) {
        self->x.u[i] = offset[i];
        self->x.so[i] = offset[i];
    }
    self->x.m_n2 = 0; /* B6 starts again from it */
    self->x.m_var = IMF_Q30_ONE;
}

void imf_robust_ahrs_q_update_v(imf_robust_ahrs_q_t *const self, const int16_t gyr[3],
                                const int16_t acc[3], const int16_t mag[3])
{
    int16_t rq[9];
    if (robust_q_step(&self->k.imu, &self->x.imu, gyr, acc, rq)) {
        robust_q_offset(&self->k, &self->x, gyr, mag); /* B6 */
        robust_q_magnetometer(&self->k, &self->x, mag, rq);
        robust_q_output(&self->k.imu, &self->x.imu, gyr);
    }
}
