/*
 * imufuse's recommended AHRS. See robust.h. The pure-Python twin is
 * python/imufuse/reference/robust.py: the same functions, in the same order, with the same
 * comments.
 *
 * Longer than 500 lines because: it is one filter family read side by side with its twin
 * (also one file), block by block; the build tools take one source per family.
 *
 * One sample: robust_step (B1 rest and the bias at rest, the strapdown, B2 gravity, the
 * levelling, B3 the bias in motion), then robust_magnetometer (B6 the offset, B4 the
 * heading; RobustAHRS only), then robust_output (the latency and B5's clock); the
 * update keeps the new state only if every block accepted the sample.
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

/* B4 and B6 out of line: one copy of B6's scalar update (three calls per sample), and on
   the ATmega328P optimised for size (every soft-float operation is a call, and the
   inlined blocks did not fit its 32 KB of flash beside a driver; ROBUST_SMALL: the blocks
   those call, inlined into them); results are the same IEEE operations in any case */
#if defined(__AVR__)
#define ROBUST_NOINLINE __attribute__((noinline, optimize("Os")))
#define ROBUST_SMALL __attribute__((optimize("Os")))
#elif defined(__GNUC__)
#define ROBUST_NOINLINE __attribute__((noinline))
#define ROBUST_SMALL
#else
#define ROBUST_NOINLINE
#define ROBUST_SMALL
#endif

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
        return set->s.dt / (t + set->s.dt);
    }
    return k;
}

/* q (x) exp(1/2 w h) into o, h = dt or the latency: the series to 4th order (no sin/cos),
   w = g - b; 0 when the normalisation fails */
static inline int robust_turn_by(const imf_robust_consts_t *const set, imf_real *const o,
                                 const imf_real *const q, const imf_real *const g,
                                 const imf_real *const b, const imf_real h)
{
    const imf_real ox = (g[0] - b[0]) * h;
    const imf_real oy = (g[1] - b[1]) * h;
    const imf_real oz = (g[2] - b[2]) * h;
    const imf_real th2 = ox * ox + oy * oy + oz * oz;
    const imf_real cw = IMF_R(1.0) - th2 * IMF_R(0.125);
    const imf_real sv = IMF_R(0.5) - th2 * set->c48;
    imf_qmul(o, q[0], q[1], q[2], q[3], cw, sv * ox, sv * oy, sv * oz);
    return robust_norm4(o);
}

/* ---- init, dt, attitude ------------------------------------------------- */

static void robust_set_dt(imf_robust_consts_t *const set, const imf_real dt)
{
    set->s.dt = dt;
    set->two_dt = IMF_R(2.0) * dt;
    set->dt2 = dt * dt;
    set->r_d = IMF_R(1.0) / dt;
    set->qg_dt = set->qg0 * dt;
    set->k_rest = dt / (set->s.tau_rest + dt);
    set->kb_rest = dt / (set->s.tau_bias_rest + dt);
    set->k_mag = dt / (set->s.tau_mag + dt);
    set->k_ref = dt / (set->s.tau_mag_ref + dt);
}

static void robust_init(imf_robust_consts_t *const set, uint32_t *const skipped,
                        imf_robust_state_t *const x, const imf_robust_settings_t *const s)
{
    const imf_real rate_ref = s->rate_ref, rest_gyr = s->rest_gyr, rest_acc = s->rest_acc;
    imf_real *const w = (imf_real *)x;
    imf_real ta2, tmax;
    unsigned i;
    set->s = *s;
    /* B2: gravity process noise q_g = (1 + |w|^2 / rate_ref^2) / tau_acc^4 per s, with
       the velocity measurement noise 1 (any acc unit): the steady state is a
       second-order low-pass with omega_0 = 1 / tau_acc and damping 1/sqrt(2) at rest */
    ta2 = s->tau_acc * s->tau_acc;
    set->qg0 = IMF_R(1.0) / (ta2 * ta2);
    set->pgg0 = IMF_R(1.0) / (ta2 * s->tau_acc);
    set->inv_rate_ref2 = rate_ref > IMF_R(0.0) ? IMF_R(1.0) / (rate_ref * rate_ref) : IMF_R(0.0);
    set->inv_tau_bias = s->tau_bias > IMF_R(0.0) ? IMF_R(1.0) / s->tau_bias : IMF_R(0.0);
    set->rest_gyr2 = rest_gyr * rest_gyr;
    set->rest_acc2 = rest_acc * rest_acc;
    set->c48 = IMF_R(1.0) / IMF_R(48.0);
    set->mag_noise2 = s->mag_noise * s->mag_noise;
    set->mag_lag2 = s->mag_lag * s->mag_lag;
    set->mag_min2 = s->mag_offset_min * s->mag_offset_min;
    /* t saturates at the longest start-up horizon */
    tmax = s->tau_acc;
    if (s->tau_rest > tmax) {
        tmax = s->tau_rest;
    }
    if (s->tau_mag > tmax) {
        tmax = s->tau_mag;
    }
    if (s->tau_mag_ref > tmax) {
        tmax = s->tau_mag_ref;
    }
    set->t_max = tmax;
    robust_set_dt(set, s->dt);
    *skipped = 0;
    /* every word 0; the three quaternions the identity; B6: no offset stored, the
       estimator starts at the first reading, its standard deviation 1 */
    for (i = 0; i < sizeof(*x) / sizeof(imf_real); i++) {
        w[i] = IMF_R(0.0);
    }
    x->q[0] = IMF_R(1.0);
    x->s[0] = IMF_R(1.0);
    x->c[0] = IMF_R(1.0);
    x->m_std = IMF_R(1.0);
}

void imf_robust_default_settings(imf_robust_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->tau_acc = IMF_R(2.5);
    settings->rate_ref = (imf_real)1.7453292519943295; /* 100 deg/s */
    settings->tau_bias = IMF_R(100.0);
    settings->tau_bias_rest = IMF_R(3.0);
    settings->rest_gyr = (imf_real)0.03490658503988659; /* 2 deg/s */
    settings->rest_acc = IMF_R(0.05);
    settings->rest_time = IMF_R(1.5);
    settings->tau_rest = IMF_R(0.5);
    settings->latency = IMF_R(0.0);
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

void imf_robust_init(imf_robust_t *const self, const imf_robust_settings_t *const s)
{
    robust_init(&self->set, &self->skipped, &self->x, s);
}

void imf_robust_set_dt(imf_robust_t *const self, const imf_real dt)
{
    robust_set_dt(&self->set, dt);
}

/* start again from att (the next sample is the first) */
static void robust_set_attitude(imf_robust_state_t *const x, const imf_attitude_t *const att)
{
    unsigned i;
    for (i = 0; i < 4; i++) {
        x->q[i] = att->q[i];
        x->s[i] = att->q[i];
        x->c[i] = IMF_R(0.0);
    }
    x->c[0] = IMF_R(1.0);
    x->t = IMF_R(0.0);
    x->ref[0] = IMF_R(0.0);
    x->m_n0 = IMF_R(0.0);
}

void imf_robust_set_attitude(imf_robust_t *const self, const imf_attitude_t *const att)
{
    robust_set_attitude(&self->x, att);
}

/* ---- gyro and accelerometer: B1, strapdown, B2, levelling, B3 ----------------- */

/* The accelerometer reading a is one: not all zero (no reading: gyro only), and within
   100 times the gravity estimate (beyond, a shock or a hostile value that says nothing
   about gravity) */
static int robust_acc_reading(const imf_robust_state_t *const x, const imf_real *const a,
                              const int first)
{
    imf_real f2;
    if (a[0] == IMF_R(0.0) && a[1] == IMF_R(0.0) && a[2] == IMF_R(0.0)) {
        return 0;
    }
    if (first) {
        return 1;
    }
    f2 = x->f[0] * x->f[0] + x->f[1] * x->f[1] + x->f[2] * x->f[2];
    return a[0] * a[0] + a[1] * a[1] + a[2] * a[2] <= IMF_R(1.0e4) * f2;
}

/* B1: rest detection from low-passes of gyro and accelerometer in the sensor frame, and
   the bias observed at rest (Eq. 3.1: b_k = b_{k-1}). g2: |g|^2. Returns rest; *w2: the
   low-passed rate squared (B2's process noise). */
static int robust_rest(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                       const imf_real *const g, const imf_real *const a, const int has_acc,
                       const imf_real g2, imf_real *const w2)
{
    const imf_real k = robust_gain(set, x->t, set->s.tau_rest, set->k_rest);
    imf_real dx, dy, dz, d2, a2;
    x->lw[0] = x->lw[0] + k * (g[0] - x->lw[0]);
    x->lw[1] = x->lw[1] + k * (g[1] - x->lw[1]);
    x->lw[2] = x->lw[2] + k * (g[2] - x->lw[2]);
    if (has_acc) {
        x->la[0] = x->la[0] + k * (a[0] - x->la[0]);
        x->la[1] = x->la[1] + k * (a[1] - x->la[1]);
        x->la[2] = x->la[2] + k * (a[2] - x->la[2]);
    }
    *w2 = x->lw[0] * x->lw[0] + x->lw[1] * x->lw[1] + x->lw[2] * x->lw[2];
    dx = a[0] - x->la[0];
    dy = a[1] - x->la[1];
    dz = a[2] - x->la[2];
    d2 = dx * dx + dy * dy + dz * dz;
    a2 = x->la[0] * x->la[0] + x->la[1] * x->la[1] + x->la[2] * x->la[2];
    if (has_acc && *w2 < set->rest_gyr2 && g2 < set->rest_gyr2 && d2 < set->rest_acc2 * a2) {
        x->t_rest = x->t_rest + set->s.dt;
        if (x->t_rest > set->s.rest_time) {
            x->t_rest = set->s.rest_time;
        }
    } else {
        x->t_rest = IMF_R(0.0);
    }
    if (!(x->t_rest >= set->s.rest_time)) {
        return 0;
    }
    x->b[0] = x->b[0] + set->kb_rest * (g[0] - x->b[0]);
    x->b[1] = x->b[1] + set->kb_rest * (g[1] - x->b[1]);
    x->b[2] = x->b[2] + set->kb_rest * (g[2] - x->b[2]);
    return 1;
}

/* strapdown: s = s (x) exp(1/2 (w - b) dt) */
static int robust_strapdown(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                            const imf_real *const g)
{
    imf_real s[4];
    if (!robust_turn_by(set, s, x->s, g, x->b, set->s.dt)) {
        return 0;
    }
    memcpy(x->s, s, sizeof s);
    return 1;
}

/* B2: gravity in the inertial frame, a Kalman filter of (v, f) per axis fed with the
   accelerometer in that frame; from the first sample (B5) */
static void robust_gravity(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                           const imf_real *const a, const int first, const int has_acc,
                           const imf_real w2)
{
    const imf_real dt = set->s.dt;
    imf_real ai[3], rr, qg, pvv, pvg, pgg, inv, kv, kg;
    imf_qrotate(ai, x->s[0], x->s[1], x->s[2], x->s[3], a[0], a[1], a[2]);
    if (first) {
        /* B5: gravity from the first sample */
        x->f[0] = ai[0];
        x->f[1] = ai[1];
        x->f[2] = ai[2];
        x->v[0] = IMF_R(0.0);
        x->v[1] = IMF_R(0.0);
        x->v[2] = IMF_R(0.0);
        x->pvv = IMF_R(0.0);
        x->pvg = IMF_R(0.0);
        x->pgg = set->pgg0;
        return;
    }
    if (!has_acc) {
        return;
    }
    /* predict: v' = a - g, g' = 0 (+ process noise growing with the rotation rate) */
    x->v[0] = x->v[0] + dt * (ai[0] - x->f[0]);
    x->v[1] = x->v[1] + dt * (ai[1] - x->f[1]);
    x->v[2] = x->v[2] + dt * (ai[2] - x->f[2]);
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
    x->f[0] = x->f[0] - kg * x->v[0];
    x->f[1] = x->f[1] - kg * x->v[1];
    x->f[2] = x->f[2] - kg * x->v[2];
    x->v[0] = x->v[0] - kv * x->v[0];
    x->v[1] = x->v[1] - kv * x->v[1];
    x->v[2] = x->v[2] - kv * x->v[2];
    x->pgg = pgg - kg * pvg;
    x->pvg = pvg - kv * pvg;
    x->pvv = pvv - kv * pvv;
}

/* levelling: the smallest rotation r that turns the gravity estimate onto earth z, into
   the correction c, and q = c (x) s; 0 rejects the sample */
static int robust_level(imf_robust_state_t *const x, imf_real *const r)
{
    imf_real ge[3], gn, c[4], q[4];
    imf_qrotate(ge, x->c[0], x->c[1], x->c[2], x->c[3], x->f[0], x->f[1], x->f[2]);
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
    c[0] = r[0] * x->c[0] - r[1] * x->c[1] - r[2] * x->c[2];
    c[1] = r[0] * x->c[1] + r[1] * x->c[0] + r[2] * x->c[3];
    c[2] = r[0] * x->c[2] - r[1] * x->c[3] + r[2] * x->c[0];
    c[3] = r[0] * x->c[3] + r[1] * x->c[2] - r[2] * x->c[1];
    if (!robust_norm4(c)) {
        return 0;
    }
    memcpy(x->c, c, sizeof c);
    imf_qmul(q, c[0], c[1], c[2], c[3], x->s[0], x->s[1], x->s[2], x->s[3]);
    if (!robust_norm4(q)) {
        return 0;
    }
    memcpy(x->q, q, sizeof q);
    return 1;
}

/* B3: in motion, the correction rate seen in the sensor frame is minus the bias error
   (Eq. 3.6, I_k = I_{k-1} + Ki dt e_k, with Ki dt = 1 / tau_bias) */
static void robust_bias(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                        const imf_real *const r, const int rest)
{
    imf_real e[3];
    if (!rest && x->t >= set->s.tau_acc && set->inv_tau_bias > IMF_R(0.0)) {
        imf_qrotate(e, x->q[0], -x->q[1], -x->q[2], -x->q[3], IMF_R(2.0) * r[1], IMF_R(2.0) * r[2],
                    IMF_R(0.0));
        x->b[0] = x->b[0] - e[0] * set->inv_tau_bias;
        x->b[1] = x->b[1] - e[1] * set->inv_tau_bias;
        x->b[2] = x->b[2] - e[2] * set->inv_tau_bias;
    }
}

/* Gyro (rad/s) and accelerometer of one sample through B1, the strapdown, B2, the
   levelling and B3, on the working state x; 0 rejects the sample. */
static int robust_step(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                       const imf_real *const g, const imf_real *const a, const imf_real g2)
{
    const int first = x->t == IMF_R(0.0);
    const int has_acc = robust_acc_reading(x, a, first);
    imf_real w2, r[4];
    int rest;
    if (first && !has_acc) {
        return 0; /* no start without an accelerometer reading */
    }
    rest = robust_rest(set, x, g, a, has_acc, g2, &w2); /* B1 */
    if (!robust_strapdown(set, x, g)) {
        return 0;
    }
    robust_gravity(set, x, a, first, has_acc, w2); /* B2 */
    if (!robust_level(x, r)) {
        return 0;
    }
    robust_bias(set, x, r, rest); /* B3 */
    return 1;
}

/* ---- magnetometer: B6, B4 ---------------------------------------------------- */

/* B6: index of P[i][j] in P[21], the covariance's upper triangle by rows */
static const unsigned char robust_pi[6][6] = {
    { 0, 1, 2, 3, 4, 5 },     { 1, 6, 7, 8, 9, 10 },    { 2, 7, 11, 12, 13, 14 },
    { 3, 8, 12, 15, 16, 17 }, { 4, 9, 13, 16, 18, 19 }, { 5, 10, 14, 17, 19, 20 }
};

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

/* B6 start: field unit n0 = |m - u| (o2 = its square), h = R(s) (m - u) / n0 (c: the
   rotated reading), o = u / n0, both with the prior variance; returns 1 / n0 */
static ROBUST_SMALL imf_real robust_offset_start(imf_robust_state_t *const x,
                                                 const imf_real *const c, const imf_real o2)
{
    imf_real inv;
    unsigned k;
    x->m_n0 = imf_sqrt(o2);
    inv = IMF_R(1.0) / x->m_n0;
    for (k = 0; k < 3; k++) {
        x->hi[k] = c[k] * inv;
        x->hi[3 + k] = x->u[k] * inv;
    }
    for (k = 0; k < 21; k++) {
        x->P[k] = IMF_R(0.0);
    }
    for (k = 0; k < 6; k++) {
        x->P[robust_pi[k][k]] = ROBUST_MAG_P0;
    }
    x->m_ew = IMF_R(1.0);
    x->m_d2 = IMF_R(0.0);
    return inv;
}

/* B6 step: predict (the field and the offset walk; after an innovation beyond the gate
   the offset may have jumped: a magnet attached or removed), then the measurement y of
   axis i (c: column i of R(s)), its noise growing with the rate (timing mismatch) */
static ROBUST_SMALL void robust_offset_update(const imf_robust_consts_t *const set,
                                              imf_robust_state_t *const x, const unsigned i,
                                              const imf_real *const c, const imf_real y,
                                              const imf_real g2)
{
    imf_real pb, rr;
    unsigned k;
    for (k = 0; k < 6; k++) {
        pb = x->P[robust_pi[k][k]] + (k < 3 ? ROBUST_MAG_QH : ROBUST_MAG_QO) * set->s.dt;
        if (k >= 3 && x->m_d2 > ROBUST_MAG_GATE && pb < ROBUST_MAG_P0) {
            pb = pb + ROBUST_MAG_JUMP;
        }
        x->P[robust_pi[k][k]] = pb;
    }
    rr = g2 * set->mag_lag2;
    if (!(rr <= IMF_R(1.0))) {
        rr = IMF_R(1.0);
    }
    rr = set->mag_noise2 + rr;
    x->m_d2 = robust_offset_axis(x->P, x->hi, i, c[0], c[1], c[2], y, rr);
    x->m_ew = x->m_ew + ROBUST_MAG_EW * (x->m_d2 - x->m_ew);
    x->m_axis = i == 2u ? IMF_R(0.0) : x->m_axis + IMF_R(1.0);
}

/* B6: the offset's standard deviation (its largest variance, never below 0); trusted
   and consistent, the offset in use u is the stored offset while the estimate agrees
   with it within mag_offset_min, else the estimate. inv: 1 / m_n0. */
static ROBUST_SMALL void robust_offset_use(const imf_robust_consts_t *const set,
                                           imf_robust_state_t *const x, const imf_real inv)
{
    imf_real pb, o2, e[3], u[3];
    unsigned k;
    pb = IMF_R(0.0);
    for (k = 3; k < 6; k++) {
        if (x->P[robust_pi[k][k]] > pb) {
            pb = x->P[robust_pi[k][k]];
        }
    }
    x->m_std = imf_sqrt(pb);
    if (x->m_std < ROBUST_MAG_TRUST && x->m_ew < ROBUST_MAG_MEAN) {
        o2 = IMF_R(0.0);
        for (k = 0; k < 3; k++) {
            e[k] = x->hi[3 + k] - x->so[k] * inv;
            o2 = o2 + e[k] * e[k];
            u[k] = x->hi[3 + k] * x->m_n0;
        }
        if (o2 < set->mag_min2) {
            memcpy(u, x->so, sizeof u);
        }
        memcpy(x->u, u, sizeof u);
    }
}

/* B6: one reading (m, not all zero) into the estimator of (h, o), m = R(s)^T h + o in
   units of m_n0, one axis per sample in turn (x, y, z: a third of the work, the same
   information every three samples); then the offset in use u. g2: |w|^2 of this sample,
   (rad/s)^2. Written with arrays and loops: on a soft-float target every operation is a
   call. */
static ROBUST_NOINLINE void robust_offset(const imf_robust_consts_t *const set,
                                          imf_robust_state_t *const x, const imf_real *const m,
                                          const imf_real g2)
{
    const unsigned i = x->m_axis == IMF_R(1.0) ? 1u : x->m_axis == IMF_R(2.0) ? 2u : 0u;
    const int start = x->m_n0 == IMF_R(0.0);
    imf_real e[3], c[3], inv, o2;
    unsigned k;
    if (!set->s.mag_learn) {
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
            x->m_bad = x->m_bad + set->s.dt;
            if (x->m_bad >= ROBUST_MAG_RESTART) {
                x->m_n0 = IMF_R(0.0);
                x->m_bad = IMF_R(0.0);
            }
            return;
        }
        x->m_bad = IMF_R(0.0);
    }
    o2 = IMF_R(0.0);
    for (k = 0; k < 3; k++) {
        if (start) {
            e[k] = m[k] - x->u[k];
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
    imf_qrotate(c, x->s[0], x->s[1], x->s[2], x->s[3], e[0], e[1], e[2]);
    if (start) {
        inv = robust_offset_start(x, c, o2);
    } else {
        robust_offset_update(set, x, i, c, m[i] * inv, g2);
    }
    robust_offset_use(set, x, inv);
}

/* B4: the field (mn, hn, zn) in fn matches the reference (n, h, z) in rf: norm within
   mag_norm n and dip within mag_dip (sine of the dip difference = zn h - hn z) */
static inline int robust_mag_test(const imf_robust_consts_t *const set, const imf_real *const fn,
                                  const imf_real *const rf)
{
    const imf_real dn = fn[0] - rf[0];
    const imf_real dd = fn[2] * rf[1] - fn[1] * rf[2];
    const imf_real tn = set->s.mag_norm * rf[0];
    return dn < tn && -dn < tn && dd < set->s.mag_dip && -dd < set->s.mag_dip;
}

/* B4: the disturbance detector. The field fn = (norm, cos dip, vertical part) is used
   (returns 1) when it has matched the reference for mag_hold, and the reference learns
   it; otherwise (disturbed) a new field that stays the same for mag_new_time of motion
   becomes the reference. */
static ROBUST_SMALL int robust_field_used(const imf_robust_consts_t *const set,
                                          imf_robust_state_t *const x, const imf_real *const fn)
{
    imf_real k;
    int match;
    if (x->ref[0] == IMF_R(0.0)) {
        /* first reading: it is the reference */
        memcpy(x->ref, fn, sizeof x->ref);
        memcpy(x->cand, fn, sizeof x->cand);
        x->t_ok = set->s.mag_hold;
    }
    match = robust_mag_test(set, fn, x->ref);
    if (match) {
        x->t_ok = x->t_ok + set->s.dt;
        if (x->t_ok > set->s.mag_hold) {
            x->t_ok = set->s.mag_hold;
        }
    } else {
        x->t_ok = IMF_R(0.0);
    }
    if (match && x->t_ok >= set->s.mag_hold) {
        x->t_dist = IMF_R(0.0);
        x->t_cand = IMF_R(0.0);
        k = robust_gain(set, x->t, set->s.tau_mag_ref, set->k_ref);
        x->ref[0] = x->ref[0] + k * (fn[0] - x->ref[0]);
        x->ref[1] = x->ref[1] + k * (fn[1] - x->ref[1]);
        x->ref[2] = x->ref[2] + k * (fn[2] - x->ref[2]);
        memcpy(x->cand, fn, sizeof x->cand);
        return 1;
    }
    /* disturbed (or not yet matching for mag_hold): no heading correction */
    x->t_dist = x->t_dist + set->s.dt;
    if (robust_mag_test(set, fn, x->cand)) {
        x->cand[0] = x->cand[0] + set->k_rest * (fn[0] - x->cand[0]);
        x->cand[1] = x->cand[1] + set->k_rest * (fn[1] - x->cand[1]);
        x->cand[2] = x->cand[2] + set->k_rest * (fn[2] - x->cand[2]);
        if (x->t_rest < set->s.rest_time) {
            /* only motion counts: at rest an attached magnet's field is steady too */
            x->t_cand = x->t_cand + set->s.dt;
        }
        if (x->t_cand >= set->s.mag_new_time) {
            memcpy(x->ref, x->cand, sizeof x->ref);
            x->t_cand = IMF_R(0.0);
        }
    } else {
        memcpy(x->cand, fn, sizeof x->cand);
        x->t_cand = IMF_R(0.0);
    }
    return 0;
}

/* B4: heading, the rotation about earth z that turns the horizontal field me (its norm
   mh) onto north (+x), (1 + cos, 0, 0, -sin) normalised, taken by the fraction k into c,
   and q = c (x) s; 0 rejects the sample */
static ROBUST_SMALL int robust_heading(const imf_robust_consts_t *const set,
                                       imf_robust_state_t *const x, const imf_real *const me,
                                       const imf_real mh)
{
    const imf_real ih = IMF_R(1.0) / mh;
    imf_real fw = IMF_R(1.0) + me[0] * ih;
    imf_real fz = -(me[1] * ih);
    const imf_real f2 = fw * fw + fz * fz;
    imf_real fr, k, zw, zz, z2, zr, c[4];
    if (f2 >= IMF_REAL_MIN) {
        fr = IMF_R(1.0) / imf_sqrt(f2);
        fw = fw * fr;
        fz = fz * fr;
    } else {
        fw = IMF_R(0.0);
        fz = IMF_R(1.0);
    }
    k = robust_gain(set, x->t, set->s.tau_mag, set->k_mag);
    zw = IMF_R(1.0) - k + k * fw;
    zz = k * fz;
    z2 = zw * zw + zz * zz;
    if (!(z2 >= IMF_REAL_MIN)) {
        return 0;
    }
    zr = IMF_R(1.0) / imf_sqrt(z2);
    zw = zw * zr;
    zz = zz * zr;
    c[0] = zw * x->c[0] - zz * x->c[3];
    c[1] = zw * x->c[1] - zz * x->c[2];
    c[2] = zw * x->c[2] + zz * x->c[1];
    c[3] = zw * x->c[3] + zz * x->c[0];
    if (!robust_norm4(c)) {
        return 0;
    }
    memcpy(x->c, c, sizeof c);
    imf_qmul(x->q, c[0], c[1], c[2], c[3], x->s[0], x->s[1], x->s[2], x->s[3]);
    return robust_norm4(x->q);
}

/* B6 and B4: the magnetometer m (all zero: none); 0 rejects the sample. g2: |w|^2. */
static ROBUST_NOINLINE int robust_magnetometer(const imf_robust_consts_t *const set,
                                               imf_robust_state_t *const x, const imf_real *const m,
                                               const imf_real g2)
{
    imf_real me[3], h2, n2, mh, inv, fn[3];
    if (m[0] == IMF_R(0.0) && m[1] == IMF_R(0.0) && m[2] == IMF_R(0.0)) {
        return 1; /* no reading: gyro and accelerometer only */
    }
    robust_offset(set, x, m, g2); /* B6, then the reading less the offset in use */
    imf_qrotate(me, x->q[0], x->q[1], x->q[2], x->q[3], m[0] - x->u[0], m[1] - x->u[1],
                m[2] - x->u[2]);
    h2 = me[0] * me[0] + me[1] * me[1];
    n2 = h2 + me[2] * me[2];
    if (!(n2 >= IMF_REAL_MIN && n2 <= IMF_REAL_MAX)) {
        return 1; /* no usable reading: gyro and accelerometer only */
    }
    fn[0] = imf_sqrt(n2);
    mh = imf_sqrt(h2);
    inv = IMF_R(1.0) / fn[0];
    fn[1] = mh * inv;
    fn[2] = me[2] * inv;
    if (!robust_field_used(set, x, fn)) {
        return 1; /* B4: disturbed */
    }
    if (!(h2 >= IMF_REAL_MIN)) {
        return 1; /* field vertical: no heading information */
    }
    return robust_heading(set, x, me, mh);
}

imf_real imf_robust_get_mag_offset(const imf_robust_t *const self, imf_real offset[3])
{
    memcpy(offset, self->x.u, sizeof self->x.u);
    return self->x.m_std;
}

void imf_robust_set_mag_offset(imf_robust_t *const self, const imf_real offset[3])
{
    memcpy(self->x.so, offset, sizeof self->x.so);
    memcpy(self->x.u, offset, sizeof self->x.u);
    self->x.m_n0 = IMF_R(0.0);
    self->x.m_std = IMF_R(1.0);
}

/* ---- the output, the clock, the update ----------------------------------------- */

/* The end of every update: the output q = c (x) s predicted by the sensor's latency with
   the bias-corrected rate (q (x) exp(1/2 (w - b) latency)), then B5's clock of the
   start-up (saturating: no growth once every start is over); 0 rejects the sample. */
static int robust_output(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                         const imf_real *const g)
{
    if (set->s.latency > IMF_R(0.0) && !robust_turn_by(set, x->q, x->q, g, x->b, set->s.latency)) {
        return 0;
    }
    x->t = x->t + set->s.dt;
    if (x->t > set->t_max) {
        x->t = set->t_max;
    }
    return 1;
}

/* The bytes of the state an update can change: all of it for the AHRS; the IMU (and the
   AHRS with B6 off) never changes B6's members (from hi on), so its update checks and
   keeps only those before them (the IMU copies only those too: B4 reads u). */
#define ROBUST_AHRS_BYTES sizeof(imf_robust_state_t)
#define ROBUST_IMU_BYTES offsetof(imf_robust_state_t, hi)

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

void imf_robust_update_imu(imf_robust_t *const self, const imf_real gx, const imf_real gy,
                           const imf_real gz, const imf_real ax, const imf_real ay,
                           const imf_real az)
{
    const imf_real g[3] = { gx, gy, gz }, a[3] = { ax, ay, az };
    imf_robust_state_t x;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az))) {
        self->skipped++;
        return;
    }
    memcpy(&x, &self->x, ROBUST_IMU_BYTES);
    robust_commit(&self->x, &self->skipped, &x,
                  robust_step(&self->set, &x, g, a, gx * gx + gy * gy + gz * gz)
                      && robust_output(&self->set, &x, g),
                  ROBUST_IMU_BYTES);
}

void imf_robust_update(imf_robust_t *const self, const imf_real gx, const imf_real gy,
                       const imf_real gz, const imf_real ax, const imf_real ay, const imf_real az,
                       const imf_real mx, const imf_real my, const imf_real mz)
{
    const imf_real g[3] = { gx, gy, gz }, a[3] = { ax, ay, az }, m[3] = { mx, my, mz };
    const imf_real g2 = gx * gx + gy * gy + gz * gz;
    imf_robust_state_t x;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az) && imf_finite3(mx, my, mz))) {
        self->skipped++;
        return;
    }
    x = self->x;
    robust_commit(&self->x, &self->skipped, &x,
                  robust_step(&self->set, &x, g, a, g2)
                      && robust_magnetometer(&self->set, &x, m, g2)
                      && robust_output(&self->set, &x, g),
                  self->set.s.mag_learn ? ROBUST_AHRS_BYTES : ROBUST_IMU_BYTES);
}
