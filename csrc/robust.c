/*
 * imufuse's recommended AHRS. See robust.h. The pure-Python twin is
 * python/imufuse/reference/robust.py: the same lines in the same order.
 */
#include "robust.h"

#include <stddef.h>
#include <string.h>

/* ---- helpers (quaternion product and rotation: imf_math.h) ----------------- */

/* B6's fixed model (relative to the field, docs/recommended-ahrs.md): the random walk of
   the field in the inertial frame (gyro drift turns that frame; the field changes along
   the path) and of the offset, per s; the offset's prior variance; the normalised
   innovation of one axis above which the offset may have changed (a magnet attached or
   removed: chi-square of one degree of freedom, odds 1.3e-5; its variance grows by
   MAG_JUMP, up to the prior); the weight of the innovation's running mean and the mean
   (about 1 when the model holds) below which the estimate is consistent; the standard
   deviation below which it is trusted. */
#define ROBUST_MAG_QH IMF_R(1.0e-3)
#define ROBUST_MAG_QO IMF_R(1.0e-7)
#define ROBUST_MAG_P0 IMF_R(1.0)
#define ROBUST_MAG_GATE IMF_R(19.0)
#define ROBUST_MAG_MEAN IMF_R(8.0)
#define ROBUST_MAG_JUMP IMF_R(0.05)
#define ROBUST_MAG_EW IMF_R(0.02)
#define ROBUST_MAG_TRUST IMF_R(0.01)
/* B6: a reading whose norm is beyond 8 times the field unit, or below 1/8 of it, is no
   reading of this field (a hostile value, a magnet on the sensor): not used; after
   ROBUST_MAG_RESTART s of them the estimator starts again from the next reading */
#define ROBUST_MAG_RANGE2 IMF_R(64.0)
#define ROBUST_MAG_RESTART IMF_R(1.0)

/* Unit quaternion in place; 0 when the normalisation fails (squared norm
   zero, subnormal, overflowed or NaN: valid-attitude policy). */
static inline int robust_norm4(imf_real *const q)
{
    const imf_real n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    imf_real r;
    if (!(n2 >= IMF_REAL_MIN && n2 <= IMF_REAL_MAX)) {
        return 0;
    }
    r = IMF_R(1.0) / imf_sqrt(n2);
    q[0] *= r;
    q[1] *= r;
    q[2] *= r;
    q[3] *= r;
    return 1;
}

/* B5: a running mean until tau, then the low-pass gain k = dt / (tau + dt) */
static inline imf_real robust_gain(const imf_robust_consts_t *const set, const imf_real t,
                                   const imf_real tau, const imf_real k)
{
    if (t < tau) {
        return set->dt / (t + set->dt);
    }
    return k;
}

/* ---- init, dt, attitude ------------------------------------------------- */

static void robust_set_dt(imf_robust_consts_t *const set, const imf_real dt)
{
    set->dt = dt;
    set->two_dt = IMF_R(2.0) * dt;
    set->dt2 = dt * dt;
    set->r_d = IMF_R(1.0) / dt;
    set->qg_dt = set->qg0 * dt;
    set->k_rest = dt / (set->tau_rest + dt);
    set->kb_rest = dt / (set->tau_bias_rest + dt);
    set->k_mag = dt / (set->tau_mag + dt);
    set->k_ref = dt / (set->tau_mag_ref + dt);
}

/* B4 and B6 out of line: one copy of B6's scalar update (three calls per sample), and on
   the ATmega328P optimised for size (every soft-float operation is a call, and the
   inlined blocks did not fit its 32 KB of flash beside a driver); results are the same
   IEEE operations in any case */
#if defined(__AVR__)
#define ROBUST_NOINLINE __attribute__((noinline, optimize("Os")))
#elif defined(__GNUC__)
#define ROBUST_NOINLINE __attribute__((noinline))
#else
#define ROBUST_NOINLINE
#endif

/* B6: index of P[i][j] in mp[21], the covariance's upper triangle by rows */
static const unsigned char robust_pi[6][6] = {
    { 0, 1, 2, 3, 4, 5 },     { 1, 6, 7, 8, 9, 10 },    { 2, 7, 11, 12, 13, 14 },
    { 3, 8, 12, 15, 16, 17 }, { 4, 9, 13, 16, 18, 19 }, { 5, 10, 14, 17, 19, 20 }
};

/* B6: the covariance's members p00 .. p55 into mp[21] and back */
static void robust_p_get(const imf_robust_state_t *const x, imf_real mp[21])
{
    mp[0] = x->p00;
    mp[1] = x->p01;
    mp[2] = x->p02;
    mp[3] = x->p03;
    mp[4] = x->p04;
    mp[5] = x->p05;
    mp[6] = x->p11;
    mp[7] = x->p12;
    mp[8] = x->p13;
    mp[9] = x->p14;
    mp[10] = x->p15;
    mp[11] = x->p22;
    mp[12] = x->p23;
    mp[13] = x->p24;
    mp[14] = x->p25;
    mp[15] = x->p33;
    mp[16] = x->p34;
    mp[17] = x->p35;
    mp[18] = x->p44;
    mp[19] = x->p45;
    mp[20] = x->p55;
}

static void robust_p_put(imf_robust_state_t *const x, const imf_real mp[21])
{
    x->p00 = mp[0];
    x->p01 = mp[1];
    x->p02 = mp[2];
    x->p03 = mp[3];
    x->p04 = mp[4];
    x->p05 = mp[5];
    x->p11 = mp[6];
    x->p12 = mp[7];
    x->p13 = mp[8];
    x->p14 = mp[9];
    x->p15 = mp[10];
    x->p22 = mp[11];
    x->p23 = mp[12];
    x->p24 = mp[13];
    x->p25 = mp[14];
    x->p33 = mp[15];
    x->p34 = mp[16];
    x->p35 = mp[17];
    x->p44 = mp[18];
    x->p45 = mp[19];
    x->p55 = mp[20];
}

/* B6 at init: no offset stored, the estimator starts at the first reading */
static void robust_offset_clear(imf_robust_state_t *const x)
{
    static const imf_real zero[21] = { IMF_R(0.0) };
    x->hx = IMF_R(0.0);
    x->hy = IMF_R(0.0);
    x->hz = IMF_R(0.0);
    x->ix = IMF_R(0.0);
    x->iy = IMF_R(0.0);
    x->iz = IMF_R(0.0);
    robust_p_put(x, zero);
    x->ux = IMF_R(0.0);
    x->uy = IMF_R(0.0);
    x->uz = IMF_R(0.0);
    x->sx = IMF_R(0.0);
    x->sy = IMF_R(0.0);
    x->sz = IMF_R(0.0);
    x->m_n0 = IMF_R(0.0);
    x->m_ew = IMF_R(0.0);
    x->m_d2 = IMF_R(0.0);
    x->m_std = IMF_R(1.0);
    x->m_axis = IMF_R(0.0);
    x->m_bad = IMF_R(0.0);
}

static void robust_init(imf_robust_consts_t *const set, uint32_t *const skipped,
                        imf_robust_state_t *const x, const imf_robust_ahrs_settings_t *const s)
{
    const imf_real rate_ref = s->rate_ref, rest_gyr = s->rest_gyr, rest_acc = s->rest_acc;
    imf_real ta2, tmax;
    set->tau_acc = s->tau_acc;
    set->tau_bias = s->tau_bias;
    set->tau_bias_rest = s->tau_bias_rest;
    set->tau_rest = s->tau_rest;
    set->latency = s->latency;
    set->tau_mag = s->tau_mag;
    set->tau_mag_ref = s->tau_mag_ref;
    /* B2: gravity process noise q_g = (1 + |w|^2 / rate_ref^2) / tau_acc^4 per s, with
       the velocity measurement noise 1 (any acc unit): the steady state is a
       second-order low-pass with omega_0 = 1 / tau_acc and damping 1/sqrt(2) at rest */
    ta2 = set->tau_acc * set->tau_acc;
    set->qg0 = IMF_R(1.0) / (ta2 * ta2);
    set->pgg0 = IMF_R(1.0) / (ta2 * set->tau_acc);
    set->inv_rate_ref2 = rate_ref > IMF_R(0.0) ? IMF_R(1.0) / (rate_ref * rate_ref) : IMF_R(0.0);
    set->inv_tau_bias = set->tau_bias > IMF_R(0.0) ? IMF_R(1.0) / set->tau_bias : IMF_R(0.0);
    set->rest_gyr2 = rest_gyr * rest_gyr;
    set->rest_acc2 = rest_acc * rest_acc;
    set->rest_time = s->rest_time;
    set->mag_norm = s->mag_norm;
    set->mag_dip = s->mag_dip;
    set->mag_new_time = s->mag_new_time;
    set->mag_hold = s->mag_hold;
    set->c48 = IMF_R(1.0) / IMF_R(48.0);
    set->mag_learn = s->mag_learn;
    set->mag_noise2 = s->mag_noise * s->mag_noise;
    set->mag_lag2 = s->mag_lag * s->mag_lag;
    set->mag_min2 = s->mag_offset_min * s->mag_offset_min;
    /* t saturates at the longest start-up horizon */
    tmax = set->tau_acc;
    if (set->tau_rest > tmax) {
        tmax = set->tau_rest;
    }
    if (set->tau_mag > tmax) {
        tmax = set->tau_mag;
    }
    if (set->tau_mag_ref > tmax) {
        tmax = set->tau_mag_ref;
    }
    set->t_max = tmax;
    robust_set_dt(set, s->dt);
    *skipped = 0;
    x->q0 = IMF_R(1.0);
    x->q1 = IMF_R(0.0);
    x->q2 = IMF_R(0.0);
    x->q3 = IMF_R(0.0);
    x->s0 = IMF_R(1.0);
    x->s1 = IMF_R(0.0);
    x->s2 = IMF_R(0.0);
    x->s3 = IMF_R(0.0);
    x->c0 = IMF_R(1.0);
    x->c1 = IMF_R(0.0);
    x->c2 = IMF_R(0.0);
    x->c3 = IMF_R(0.0);
    x->fx = IMF_R(0.0);
    x->fy = IMF_R(0.0);
    x->fz = IMF_R(0.0);
    x->vx = IMF_R(0.0);
    x->vy = IMF_R(0.0);
    x->vz = IMF_R(0.0);
    x->pvv = IMF_R(0.0);
    x->pvg = IMF_R(0.0);
    x->pgg = IMF_R(0.0);
    x->bx = IMF_R(0.0);
    x->by = IMF_R(0.0);
    x->bz = IMF_R(0.0);
    x->lwx = IMF_R(0.0);
    x->lwy = IMF_R(0.0);
    x->lwz = IMF_R(0.0);
    x->lax = IMF_R(0.0);
    x->lay = IMF_R(0.0);
    x->laz = IMF_R(0.0);
    x->t = IMF_R(0.0);
    x->t_rest = IMF_R(0.0);
    x->rn = IMF_R(0.0);
    x->rh = IMF_R(0.0);
    x->rz = IMF_R(0.0);
    x->cn = IMF_R(0.0);
    x->ch = IMF_R(0.0);
    x->cz = IMF_R(0.0);
    x->t_cand = IMF_R(0.0);
    x->t_dist = IMF_R(0.0);
    x->t_ok = IMF_R(0.0);
    robust_offset_clear(x);
}

/* The defaults of the settings both filters have (robust.h lists them): one list for the
   two settings structs. */
#define ROBUST_COMMON_DEFAULTS(s) \
    do { \
        (s)->dt = IMF_R(0.01); \
        (s)->tau_acc = IMF_R(2.5); \
        (s)->rate_ref = (imf_real)1.7453292519943295; /* 100 deg/s */ \
        (s)->tau_bias = IMF_R(100.0); \
        (s)->tau_bias_rest = IMF_R(3.0); \
        (s)->rest_gyr = (imf_real)0.03490658503988659; /* 2 deg/s */ \
        (s)->rest_acc = IMF_R(0.05); \
        (s)->rest_time = IMF_R(1.5); \
        (s)->tau_rest = IMF_R(0.5); \
        (s)->latency = IMF_R(0.0); \
    } while (0)

void imf_robust_imu_default_settings(imf_robust_imu_settings_t *const settings)
{
    ROBUST_COMMON_DEFAULTS(settings);
}

void imf_robust_ahrs_default_settings(imf_robust_ahrs_settings_t *const settings)
{
    ROBUST_COMMON_DEFAULTS(settings);
    settings->tau_mag = IMF_R(10.0);
    settings->mag_norm = IMF_R(0.1);
    settings->mag_dip = (imf_real)0.17364817766693033; /* sin(10 deg) */
    settings->tau_mag_ref = IMF_R(20.0);
    settings->mag_new_time = IMF_R(20.0);
    settings->mag_hold = IMF_R(0.5);
    settings->mag_learn = 1;
    settings->mag_noise = IMF_R(0.02);
    settings->mag_lag = IMF_R(0.003);
    settings->mag_offset_min = IMF_R(0.1);
}

/* The IMU filter is the AHRS filter without a magnetometer: the magnetic settings are
   inert (never read without a field); tau_mag and tau_mag_ref = tau_rest keep the
   start-up horizon t_max that of the IMU blocks. */
void imf_robust_imu_init(imf_robust_imu_t *const self, const imf_robust_imu_settings_t *const s)
{
    imf_robust_ahrs_settings_t a;
    a.dt = s->dt;
    a.tau_acc = s->tau_acc;
    a.rate_ref = s->rate_ref;
    a.tau_bias = s->tau_bias;
    a.tau_bias_rest = s->tau_bias_rest;
    a.rest_gyr = s->rest_gyr;
    a.rest_acc = s->rest_acc;
    a.rest_time = s->rest_time;
    a.tau_rest = s->tau_rest;
    a.latency = s->latency;
    a.tau_mag = s->tau_rest;
    a.mag_norm = IMF_R(0.0);
    a.mag_dip = IMF_R(0.0);
    a.tau_mag_ref = s->tau_rest;
    a.mag_new_time = IMF_R(0.0);
    a.mag_hold = IMF_R(0.0);
    a.mag_learn = 0;
    a.mag_noise = IMF_R(0.0);
    a.mag_lag = IMF_R(0.0);
    a.mag_offset_min = IMF_R(0.0);
    robust_init(&self->set, &self->skipped, &self->x, &a);
}

void imf_robust_ahrs_init(imf_robust_ahrs_t *const self, const imf_robust_ahrs_settings_t *const s)
{
    robust_init(&self->set, &self->skipped, &self->x, s);
}

void imf_robust_imu_set_dt(imf_robust_imu_t *const self, const imf_real dt)
{
    robust_set_dt(&self->set, dt);
}

void imf_robust_ahrs_set_dt(imf_robust_ahrs_t *const self, const imf_real dt)
{
    robust_set_dt(&self->set, dt);
}

/* start again from att (the next sample is the first) */
static void robust_set_attitude(imf_robust_state_t *const x, const imf_attitude_t *const att)
{
    x->q0 = att->q[0];
    x->q1 = att->q[1];
    x->q2 = att->q[2];
    x->q3 = att->q[3];
    x->s0 = att->q[0];
    x->s1 = att->q[1];
    x->s2 = att->q[2];
    x->s3 = att->q[3];
    x->c0 = IMF_R(1.0);
    x->c1 = IMF_R(0.0);
    x->c2 = IMF_R(0.0);
    x->c3 = IMF_R(0.0);
    x->t = IMF_R(0.0);
    x->rn = IMF_R(0.0);
    x->m_n0 = IMF_R(0.0);
}

void imf_robust_imu_set_attitude(imf_robust_imu_t *const self, const imf_attitude_t *const att)
{
    robust_set_attitude(&self->x, att);
}

void imf_robust_ahrs_set_attitude(imf_robust_ahrs_t *const self, const imf_attitude_t *const att)
{
    robust_set_attitude(&self->x, att);
}

/* ---- the update --------------------------------------------------------- */

/* Gyro + accelerometer part on the working state x; 0 rejects the sample. */
static int robust_step(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                       const imf_real gx, const imf_real gy, const imf_real gz, const imf_real ax,
                       const imf_real ay, const imf_real az)
{
    const imf_real dt = set->dt;
    const int first = x->t == IMF_R(0.0);
    /* an all-zero accelerometer is no reading: gyro only (and no start without one) */
    int has_acc = !(ax == IMF_R(0.0) && ay == IMF_R(0.0) && az == IMF_R(0.0));
    imf_real k, w2, g2, dx, dy, dz, d2, a2, ox, oy, oz, th2, cw, sv, gn;
    imf_real s[4], ai[3], ge[3], r[4], c[4], q[4], e[3];
    int rest;
    if (first && !has_acc) {
        return 0;
    }
    if (has_acc && !first) {
        /* a reading beyond 100 times the gravity estimate (100 g) is a shock or a
           hostile value: it says nothing about gravity, and is no reading */
        const imf_real f2 = x->fx * x->fx + x->fy * x->fy + x->fz * x->fz;
        if (!(ax * ax + ay * ay + az * az <= IMF_R(1.0e4) * f2)) {
            has_acc = 0;
        }
    }
    /* B1: rest detection, low-passes of gyro and accelerometer in the sensor frame */
    k = robust_gain(set, x->t, set->tau_rest, set->k_rest);
    x->lwx = x->lwx + k * (gx - x->lwx);
    x->lwy = x->lwy + k * (gy - x->lwy);
    x->lwz = x->lwz + k * (gz - x->lwz);
    if (has_acc) {
        x->lax = x->lax + k * (ax - x->lax);
        x->lay = x->lay + k * (ay - x->lay);
        x->laz = x->laz + k * (az - x->laz);
    }
    w2 = x->lwx * x->lwx + x->lwy * x->lwy + x->lwz * x->lwz;
    g2 = gx * gx + gy * gy + gz * gz;
    dx = ax - x->lax;
    dy = ay - x->lay;
    dz = az - x->laz;
    d2 = dx * dx + dy * dy + dz * dz;
    a2 = x->lax * x->lax + x->lay * x->lay + x->laz * x->laz;
    if (has_acc && w2 < set->rest_gyr2 && g2 < set->rest_gyr2 && d2 < set->rest_acc2 * a2) {
        x->t_rest = x->t_rest + dt;
        if (x->t_rest > set->rest_time) {
            x->t_rest = set->rest_time;
        }
    } else {
        x->t_rest = IMF_R(0.0);
    }
    rest = x->t_rest >= set->rest_time;
    if (rest) {
        /* Eq. 3.1: b_k = b_{k-1}, observed directly at rest */
        x->bx = x->bx + set->kb_rest * (gx - x->bx);
        x->by = x->by + set->kb_rest * (gy - x->by);
        x->bz = x->bz + set->kb_rest * (gz - x->bz);
    }
    /* strapdown: s = s (x) exp(1/2 (w - b) dt), series to 4th order (no sin/cos) */
    ox = (gx - x->bx) * dt;
    oy = (gy - x->by) * dt;
    oz = (gz - x->bz) * dt;
    th2 = ox * ox + oy * oy + oz * oz;
    cw = IMF_R(1.0) - th2 * IMF_R(0.125);
    sv = IMF_R(0.5) - th2 * set->c48;
    imf_qmul(s, x->s0, x->s1, x->s2, x->s3, cw, sv * ox, sv * oy, sv * oz);
    if (!robust_norm4(s)) {
        return 0;
    }
    x->s0 = s[0];
    x->s1 = s[1];
    x->s2 = s[2];
    x->s3 = s[3];
    /* B2: the accelerometer in the inertial frame */
    imf_qrotate(ai, s[0], s[1], s[2], s[3], ax, ay, az);
    if (first) {
        /* B5: gravity from the first sample */
        x->fx = ai[0];
        x->fy = ai[1];
        x->fz = ai[2];
        x->vx = IMF_R(0.0);
        x->vy = IMF_R(0.0);
        x->vz = IMF_R(0.0);
        x->pvv = IMF_R(0.0);
        x->pvg = IMF_R(0.0);
        x->pgg = set->pgg0;
    } else if (has_acc) {
        imf_real rr, qg, pvv, pvg, pgg, inv, kv, kg;
        /* predict: v' = a - g, g' = 0 (+ process noise growing with the rotation rate) */
        x->vx = x->vx + dt * (ai[0] - x->fx);
        x->vy = x->vy + dt * (ai[1] - x->fy);
        x->vz = x->vz + dt * (ai[2] - x->fz);
        /* (w / rate_ref)^2 capped at 10^4 (100 rate_ref: beyond any gyro's range), so
           that hostile rates cannot blow the covariance up */
        rr = w2 * set->inv_rate_ref2;
        if (!(rr <= IMF_R(1.0e4))) {
            rr = IMF_R(1.0e4);
        }
        qg = set->qg_dt + set->qg_dt * rr;
        pvv = x->pvv - set->two_dt * x->pvg + set->dt2 * x->pgg;
        pvg = x->pvg - dt * x->pgg;
        pgg = x->pgg + qg;
        /* update with the pseudo-measurement v = 0 (noise 1 / dt per sample) */
        inv = IMF_R(1.0) / (pvv + set->r_d);
        kv = pvv * inv;
        kg = pvg * inv;
        x->fx = x->fx - kg * x->vx;
        x->fy = x->fy - kg * x->vy;
        x->fz = x->fz - kg * x->vz;
        x->vx = x->vx - kv * x->vx;
        x->vy = x->vy - kv * x->vy;
        x->vz = x->vz - kv * x->vz;
        x->pgg = pgg - kg * pvg;
        x->pvg = pvg - kv * pvg;
        x->pvv = pvv - kv * pvv;
    }
    /* inclination: the smallest rotation r that turns the gravity estimate onto earth z */
    imf_qrotate(ge, x->c0, x->c1, x->c2, x->c3, x->fx, x->fy, x->fz);
    gn = imf_sqrt(ge[0] * ge[0] + ge[1] * ge[1] + ge[2] * ge[2]);
    r[0] = gn + ge[2];
    r[1] = ge[1];
    r[2] = -ge[0];
    r[3] = IMF_R(0.0);
    if (!robust_norm4(r)) {
        /* gravity straight down (upside down, r = 0): any half turn about a horizontal
           axis is a smallest rotation; about x. Otherwise (not finite) reject. */
        if (!(gn > IMF_R(0.0) && gn <= IMF_REAL_MAX)) {
            return 0;
        }
        r[0] = IMF_R(0.0);
        r[1] = IMF_R(1.0);
        r[2] = IMF_R(0.0);
    }
    c[0] = r[0] * x->c0 - r[1] * x->c1 - r[2] * x->c2;
    c[1] = r[0] * x->c1 + r[1] * x->c0 + r[2] * x->c3;
    c[2] = r[0] * x->c2 - r[1] * x->c3 + r[2] * x->c0;
    c[3] = r[0] * x->c3 + r[1] * x->c2 - r[2] * x->c1;
    if (!robust_norm4(c)) {
        return 0;
    }
    x->c0 = c[0];
    x->c1 = c[1];
    x->c2 = c[2];
    x->c3 = c[3];
    imf_qmul(q, c[0], c[1], c[2], c[3], s[0], s[1], s[2], s[3]);
    if (!robust_norm4(q)) {
        return 0;
    }
    x->q0 = q[0];
    x->q1 = q[1];
    x->q2 = q[2];
    x->q3 = q[3];
    /* B3: the correction rate seen in the sensor frame is minus the bias error
       (Eq. 3.6, I_k = I_{k-1} + Ki dt e_k, with Ki dt = 1 / tau_bias) */
    if (!rest && x->t >= set->tau_acc && set->inv_tau_bias > IMF_R(0.0)) {
        imf_qrotate(e, q[0], -q[1], -q[2], -q[3], IMF_R(2.0) * r[1], IMF_R(2.0) * r[2], IMF_R(0.0));
        x->bx = x->bx - e[0] * set->inv_tau_bias;
        x->by = x->by - e[1] * set->inv_tau_bias;
        x->bz = x->bz - e[2] * set->inv_tau_bias;
    }
    return 1;
}

/* The output: q = c (x) s, then predicted by the sensor's latency with the
   bias-corrected rate (q (x) exp(1/2 (w - b) latency), series as the strapdown);
   0 rejects the sample. */
static int robust_predict(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                          const imf_real gx, const imf_real gy, const imf_real gz)
{
    imf_real ox, oy, oz, th2, cw, sv, q[4];
    if (!(set->latency > IMF_R(0.0))) {
        return 1;
    }
    ox = (gx - x->bx) * set->latency;
    oy = (gy - x->by) * set->latency;
    oz = (gz - x->bz) * set->latency;
    th2 = ox * ox + oy * oy + oz * oz;
    cw = IMF_R(1.0) - th2 * IMF_R(0.125);
    sv = IMF_R(0.5) - th2 * set->c48;
    imf_qmul(q, x->q0, x->q1, x->q2, x->q3, cw, sv * ox, sv * oy, sv * oz);
    if (!robust_norm4(q)) {
        return 0;
    }
    x->q0 = q[0];
    x->q1 = q[1];
    x->q2 = q[2];
    x->q3 = q[3];
    return 1;
}

/* B6: the scalar update of axis i, measurement y with noise rr, H = (h0, h1, h2, e_i):
   state xs[6], covariance mp[21]; returns the normalised innovation nu^2 / s */
static ROBUST_NOINLINE imf_real robust_offset_axis(imf_real mp[21], imf_real xs[6],
                                                   const unsigned i, const imf_real h0,
                                                   const imf_real h1, const imf_real h2,
                                                   const imf_real y, const imf_real rr)
{
    imf_real ph[6], kk[6], sv, nu, ri;
    unsigned j, k;
    for (j = 0; j < 6; j++) {
        ph[j] = mp[robust_pi[j][0]] * h0 + mp[robust_pi[j][1]] * h1 + mp[robust_pi[j][2]] * h2
                + mp[robust_pi[j][3 + i]];
    }
    sv = h0 * ph[0] + h1 * ph[1] + h2 * ph[2] + ph[3 + i] + rr;
    nu = y - (h0 * xs[0] + h1 * xs[1] + h2 * xs[2] + xs[3 + i]);
    ri = IMF_R(1.0) / sv;
    for (j = 0; j < 6; j++) {
        kk[j] = ph[j] * ri;
        xs[j] = xs[j] + kk[j] * nu;
    }
    for (j = 0; j < 6; j++) {
        for (k = j; k < 6; k++) {
            mp[robust_pi[j][k]] = mp[robust_pi[j][k]] - ph[j] * kk[k];
        }
    }
    return nu * nu * ri;
}

/* B6: one reading (m, not all zero) into the estimator of (h, o), m = R(s)^T h + o in
   units of m_n0, one axis per sample in turn (x, y, z: a third of the work, the same
   information every three samples); then the offset in use u. g2: |w|^2 of this sample,
   (rad/s)^2. Written with arrays and loops: on a soft-float target every operation is a
   call. */
static ROBUST_NOINLINE void robust_offset(const imf_robust_consts_t *const set,
                                          imf_robust_state_t *const x, const imf_real mx,
                                          const imf_real my, const imf_real mz, const imf_real g2)
{
    const imf_real m[3] = { mx, my, mz };
    const unsigned i = x->m_axis == IMF_R(1.0) ? 1u : x->m_axis == IMF_R(2.0) ? 2u : 0u;
    const int start = x->m_n0 == IMF_R(0.0);
    imf_real u[3], st[3], e[3], c[3], xs[6], mp[21], inv, rr, pb, o2;
    unsigned k;
    if (!set->mag_learn) {
        return;
    }
    inv = IMF_R(0.0);
    if (!start) {
        /* the reading against the field unit: absurd readings are not used */
        inv = IMF_R(1.0) / x->m_n0;
        o2 = IMF_R(0.0);
        for (k = 0; k < 3; k++) {
            o2 = o2 + (m[k] * inv) * (m[k] * inv);
        }
        if (!(o2 <= ROBUST_MAG_RANGE2 && o2 * ROBUST_MAG_RANGE2 >= IMF_R(1.0))) {
            x->m_bad = x->m_bad + set->dt;
            if (x->m_bad >= ROBUST_MAG_RESTART) {
                x->m_n0 = IMF_R(0.0);
                x->m_bad = IMF_R(0.0);
            }
            return;
        }
        x->m_bad = IMF_R(0.0);
    }
    u[0] = x->ux;
    u[1] = x->uy;
    u[2] = x->uz;
    o2 = IMF_R(0.0);
    for (k = 0; k < 3; k++) {
        if (start) {
            e[k] = m[k] - u[k];
            o2 = o2 + e[k] * e[k];
        } else {
            e[k] = k == i ? IMF_R(1.0) : IMF_R(0.0);
        }
    }
    if (start && !(o2 >= IMF_REAL_MIN && o2 <= IMF_REAL_MAX)) {
        return;
    }
    /* start: the field in I, R(s) (m - u); else column i of R(s), the row of axis i in
       m = R^T h + o */
    imf_qrotate(c, x->s0, x->s1, x->s2, x->s3, e[0], e[1], e[2]);
    if (start) {
        /* field unit n0 = |m - u|: h = R(s) (m - u) / n0, o = u / n0, both with the prior
           variance */
        x->m_n0 = imf_sqrt(o2);
        inv = IMF_R(1.0) / x->m_n0;
        for (k = 0; k < 3; k++) {
            xs[k] = c[k] * inv;
            xs[3 + k] = u[k] * inv;
        }
        for (k = 0; k < 21; k++) {
            mp[k] = IMF_R(0.0);
        }
        for (k = 0; k < 6; k++) {
            mp[robust_pi[k][k]] = ROBUST_MAG_P0;
        }
        x->m_ew = IMF_R(1.0);
        x->m_d2 = IMF_R(0.0);
    } else {
        xs[0] = x->hx;
        xs[1] = x->hy;
        xs[2] = x->hz;
        xs[3] = x->ix;
        xs[4] = x->iy;
        xs[5] = x->iz;
        robust_p_get(x, mp);
        /* predict: the field and the offset walk; after an innovation beyond the gate the
           offset may have jumped (a magnet attached or removed) */
        for (k = 0; k < 6; k++) {
            pb = mp[robust_pi[k][k]] + (k < 3 ? ROBUST_MAG_QH : ROBUST_MAG_QO) * set->dt;
            if (k >= 3 && x->m_d2 > ROBUST_MAG_GATE && pb < ROBUST_MAG_P0) {
                pb = pb + ROBUST_MAG_JUMP;
            }
            mp[robust_pi[k][k]] = pb;
        }
        /* the measurement of axis i, relative; its noise grows with the rate (timing
           mismatch) */
        rr = g2 * set->mag_lag2;
        if (!(rr <= IMF_R(1.0))) {
            rr = IMF_R(1.0);
        }
        rr = set->mag_noise2 + rr;
        x->m_d2 = robust_offset_axis(mp, xs, i, c[0], c[1], c[2], m[i] * inv, rr);
        x->m_ew = x->m_ew + ROBUST_MAG_EW * (x->m_d2 - x->m_ew);
        x->m_axis = i == 2u ? IMF_R(0.0) : x->m_axis + IMF_R(1.0);
    }
    x->hx = xs[0];
    x->hy = xs[1];
    x->hz = xs[2];
    x->ix = xs[3];
    x->iy = xs[4];
    x->iz = xs[5];
    robust_p_put(x, mp);
    /* the offset's standard deviation: its largest variance (never below 0) */
    pb = IMF_R(0.0);
    for (k = 3; k < 6; k++) {
        if (mp[robust_pi[k][k]] > pb) {
            pb = mp[robust_pi[k][k]];
        }
    }
    x->m_std = imf_sqrt(pb);
    /* trusted and consistent: the stored offset while the estimate agrees with it within
       mag_offset_min, else the estimate */
    if (x->m_std < ROBUST_MAG_TRUST && x->m_ew < ROBUST_MAG_MEAN) {
        st[0] = x->sx;
        st[1] = x->sy;
        st[2] = x->sz;
        o2 = IMF_R(0.0);
        for (k = 0; k < 3; k++) {
            e[k] = xs[3 + k] - st[k] * inv;
            o2 = o2 + e[k] * e[k];
            u[k] = xs[3 + k] * x->m_n0;
        }
        if (o2 < set->mag_min2) {
            u[0] = st[0];
            u[1] = st[1];
            u[2] = st[2];
        }
        x->ux = u[0];
        x->uy = u[1];
        x->uz = u[2];
    }
}

/* the field (mn, hn, zn) matches the reference (n, h, z): norm within mag_norm n
   and dip within mag_dip (sine of the dip difference = zn h - hn z) */
static inline int robust_mag_test(const imf_robust_consts_t *const set, const imf_real mn,
                                  const imf_real hn, const imf_real zn, const imf_real n,
                                  const imf_real h, const imf_real z)
{
    const imf_real dn = mn - n;
    const imf_real dd = zn * h - hn * z;
    const imf_real tn = set->mag_norm * n;
    return dn < tn && -dn < tn && dd < set->mag_dip && -dd < set->mag_dip;
}

/* B4: heading from the magnetometer; 0 rejects the sample. */
static ROBUST_NOINLINE int robust_mag(const imf_robust_consts_t *const set,
                                      imf_robust_state_t *const x, const imf_real mx,
                                      const imf_real my, const imf_real mz, const imf_real g2)
{
    const imf_real dt = set->dt;
    imf_real me[3], h2, n2, mn, mh, inv, hn, zn, k;
    int match;
    if (mx == IMF_R(0.0) && my == IMF_R(0.0) && mz == IMF_R(0.0)) {
        return 1; /* no reading: gyro and accelerometer only */
    }
    /* B6, then the reading less the offset in use */
    robust_offset(set, x, mx, my, mz, g2);
    imf_qrotate(me, x->q0, x->q1, x->q2, x->q3, mx - x->ux, my - x->uy, mz - x->uz);
    h2 = me[0] * me[0] + me[1] * me[1];
    n2 = h2 + me[2] * me[2];
    if (!(n2 >= IMF_REAL_MIN && n2 <= IMF_REAL_MAX)) {
        return 1; /* no usable reading: gyro and accelerometer only */
    }
    mn = imf_sqrt(n2);
    mh = imf_sqrt(h2);
    inv = IMF_R(1.0) / mn;
    hn = mh * inv;
    zn = me[2] * inv;
    if (x->rn == IMF_R(0.0)) {
        /* first reading: it is the reference */
        x->rn = mn;
        x->rh = hn;
        x->rz = zn;
        x->cn = mn;
        x->ch = hn;
        x->cz = zn;
        x->t_ok = set->mag_hold;
    }
    match = robust_mag_test(set, mn, hn, zn, x->rn, x->rh, x->rz);
    if (match) {
        x->t_ok = x->t_ok + dt;
        if (x->t_ok > set->mag_hold) {
            x->t_ok = set->mag_hold;
        }
    } else {
        x->t_ok = IMF_R(0.0);
    }
    if (match && x->t_ok >= set->mag_hold) {
        imf_real ih, fw, fz, f2, fr, zw, zz, z2, zr, c[4], q[4];
        x->t_dist = IMF_R(0.0);
        x->t_cand = IMF_R(0.0);
        k = robust_gain(set, x->t, set->tau_mag_ref, set->k_ref);
        x->rn = x->rn + k * (mn - x->rn);
        x->rh = x->rh + k * (hn - x->rh);
        x->rz = x->rz + k * (zn - x->rz);
        x->cn = mn;
        x->ch = hn;
        x->cz = zn;
        if (!(h2 >= IMF_REAL_MIN)) {
            return 1; /* field vertical: no heading information */
        }
        /* heading: the rotation about earth z that turns the horizontal field onto
           north (+x), (1 + cos, 0, 0, -sin) normalised, taken by the fraction k */
        ih = IMF_R(1.0) / mh;
        fw = IMF_R(1.0) + me[0] * ih;
        fz = -(me[1] * ih);
        f2 = fw * fw + fz * fz;
        if (f2 >= IMF_REAL_MIN) {
            fr = IMF_R(1.0) / imf_sqrt(f2);
            fw = fw * fr;
            fz = fz * fr;
        } else {
            fw = IMF_R(0.0);
            fz = IMF_R(1.0);
        }
        k = robust_gain(set, x->t, set->tau_mag, set->k_mag);
        zw = IMF_R(1.0) - k + k * fw;
        zz = k * fz;
        z2 = zw * zw + zz * zz;
        if (!(z2 >= IMF_REAL_MIN)) {
            return 0;
        }
        zr = IMF_R(1.0) / imf_sqrt(z2);
        zw = zw * zr;
        zz = zz * zr;
        c[0] = zw * x->c0 - zz * x->c3;
        c[1] = zw * x->c1 - zz * x->c2;
        c[2] = zw * x->c2 + zz * x->c1;
        c[3] = zw * x->c3 + zz * x->c0;
        if (!robust_norm4(c)) {
            return 0;
        }
        x->c0 = c[0];
        x->c1 = c[1];
        x->c2 = c[2];
        x->c3 = c[3];
        imf_qmul(q, c[0], c[1], c[2], c[3], x->s0, x->s1, x->s2, x->s3);
        if (!robust_norm4(q)) {
            return 0;
        }
        x->q0 = q[0];
        x->q1 = q[1];
        x->q2 = q[2];
        x->q3 = q[3];
    } else {
        /* disturbed (or not yet matching for mag_hold): no heading correction; a new
           field that stays the same for mag_new_time of motion becomes the reference */
        x->t_dist = x->t_dist + dt;
        if (robust_mag_test(set, mn, hn, zn, x->cn, x->ch, x->cz)) {
            x->cn = x->cn + set->k_rest * (mn - x->cn);
            x->ch = x->ch + set->k_rest * (hn - x->ch);
            x->cz = x->cz + set->k_rest * (zn - x->cz);
            if (x->t_rest < set->rest_time) {
                /* only motion counts: at rest an attached magnet's field is steady too */
                x->t_cand = x->t_cand + dt;
            }
            if (x->t_cand >= set->mag_new_time) {
                x->rn = x->cn;
                x->rh = x->ch;
                x->rz = x->cz;
                x->t_cand = IMF_R(0.0);
            }
        } else {
            x->cn = mn;
            x->ch = hn;
            x->cz = zn;
            x->t_cand = IMF_R(0.0);
        }
    }
    return 1;
}

imf_real imf_robust_ahrs_get_mag_offset(const imf_robust_ahrs_t *const self, imf_real offset[3])
{
    offset[0] = self->x.ux;
    offset[1] = self->x.uy;
    offset[2] = self->x.uz;
    return self->x.m_std;
}

void imf_robust_ahrs_set_mag_offset(imf_robust_ahrs_t *const self, const imf_real offset[3])
{
    self->x.sx = offset[0];
    self->x.sy = offset[1];
    self->x.sz = offset[2];
    self->x.ux = offset[0];
    self->x.uy = offset[1];
    self->x.uz = offset[2];
    self->x.m_n0 = IMF_R(0.0);
    self->x.m_std = IMF_R(1.0);
}

/* the clock of the start-up (saturating: no growth once every start is over) */
static inline void robust_advance(const imf_robust_consts_t *const set, imf_robust_state_t *const x)
{
    x->t = x->t + set->dt;
    if (x->t > set->t_max) {
        x->t = set->t_max;
    }
}

/* The end of every update: the output prediction, then the clock. Returns 0
   to reject the sample. */
static int robust_finish(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                         const imf_real gx, const imf_real gy, const imf_real gz)
{
    if (!robust_predict(set, x, gx, gy, gz)) {
        return 0;
    }
    robust_advance(set, x);
    return 1;
}

/* The bytes of the state an update can change: all of it for the AHRS; the IMU (and the
   AHRS with B6 off) never changes B6's members (from hx on), so its update checks and
   keeps only those before them (the IMU copies only those too: B4 reads u). */
#define ROBUST_AHRS_BYTES sizeof(imf_robust_state_t)
#define ROBUST_IMU_BYTES offsetof(imf_robust_state_t, hx)

/* valid-attitude policy: the new state (its first `bytes`) must be finite */
static int robust_finite(const imf_robust_state_t *const x, const size_t bytes)
{
    const imf_real *const v = (const imf_real *)x;
    const unsigned n = (unsigned)(bytes / sizeof(imf_real));
    unsigned i;
    for (i = 0; i < n; i++) {
        if (!isfinite(v[i])) {
            return 0;
        }
    }
    return 1;
}

/* Keep the new state (its first `bytes`) only if every block accepted the sample and
   left it finite (valid-attitude policy, imf_math.h). */
static void robust_commit(imf_robust_state_t *const dst, uint32_t *const skipped,
                          const imf_robust_state_t *const x, const int ok, const size_t bytes)
{
    if (!(ok && robust_finite(x, bytes))) {
        (*skipped)++;
        return;
    }
    memcpy(dst, x, bytes);
}

void imf_robust_imu_update(imf_robust_imu_t *const self, const imf_real gx, const imf_real gy,
                           const imf_real gz, const imf_real ax, const imf_real ay,
                           const imf_real az)
{
    imf_robust_state_t x;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az))) {
        self->skipped++;
        return;
    }
    memcpy(&x, &self->x, ROBUST_IMU_BYTES);
    robust_commit(&self->x, &self->skipped, &x,
                  robust_step(&self->set, &x, gx, gy, gz, ax, ay, az)
                      && robust_finish(&self->set, &x, gx, gy, gz),
                  ROBUST_IMU_BYTES);
}

void imf_robust_ahrs_update(imf_robust_ahrs_t *const self, const imf_real gx, const imf_real gy,
                            const imf_real gz, const imf_real ax, const imf_real ay,
                            const imf_real az, const imf_real mx, const imf_real my,
                            const imf_real mz)
{
    imf_robust_state_t x;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az) && imf_finite3(mx, my, mz))) {
        self->skipped++;
        return;
    }
    x = self->x;
    robust_commit(&self->x, &self->skipped, &x,
                  robust_step(&self->set, &x, gx, gy, gz, ax, ay, az)
                      && robust_mag(&self->set, &x, mx, my, mz, gx * gx + gy * gy + gz * gz)
                      && robust_finish(&self->set, &x, gx, gy, gz),
                  self->set.mag_learn ? ROBUST_AHRS_BYTES : ROBUST_IMU_BYTES);
}
