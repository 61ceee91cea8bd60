/*
 * imufuse's recommended AHRS. See robust.h. The pure-Python twin is
 * python/imufuse/reference/robust.py: the same functions, in the same order, with the same
 * comments.
 *
 * Its blocks are in three private headers it includes once (one translation unit, as the
 * build tools take one source per family): robust_b3.h (B3's noise, twin robust_b3.py),
 * robust_blocks.h (B1-B3, twin robust_blocks.py) and robust_mag.h (B6, B4, twin
 * robust_mag.py).
 * The host's lane twin of all three, imufuse_c/host/lanes_robust.h (imufuse_c.run_filters,
 * tune), repeats these steps for several filters at once, bit for bit: change both.
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

/* B1, B2, B3's Kalman rows, B4 and B6 out of line: one copy of B6's scalar update (three
   calls per sample), of the rotation, of the turn (the strapdown's and the latency's) and
   of B3's row, and on the ATmega328P optimised for
   size (every soft-float operation is a call, and the inlined blocks did not fit its 32 KB of
   flash beside a driver; ROBUST_SMALL: the blocks those call, inlined into them); on a
   64-bit host (imufuse_c) inlined where the compiler chooses: a third fewer instructions
   per update (the state stays in one frame, the rotations see their constant axes);
   results are the same IEEE operations in any case */
#if defined(__AVR__)
#define ROBUST_NOINLINE __attribute__((noinline, optimize("Os")))
#define ROBUST_SMALL __attribute__((optimize("Os")))
#elif defined(__GNUC__) && (defined(__x86_64__) || defined(__aarch64__))
#define ROBUST_NOINLINE
#define ROBUST_SMALL
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
static ROBUST_NOINLINE int robust_turn_by(const imf_robust_consts_t *const set, imf_real *const o,
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

/* the low-pass v <- v + k (u - v) of three words (one copy on the MCUs: every low-pass of a
   vector in the blocks) */
static ROBUST_NOINLINE void robust_lp3(imf_real *const v, const imf_real *const u, const imf_real k)
{
#if defined(__AVR__)
    unsigned i;
    for (i = 0; i < 3; i++) {
        v[i] = v[i] + k * (u[i] - v[i]);
    }
#else
    v[0] = v[0] + k * (u[0] - v[0]);
    v[1] = v[1] + k * (u[1] - v[1]);
    v[2] = v[2] + k * (u[2] - v[2]);
#endif
}

static const imf_real robust_zero3[3] = { IMF_R(0.0), IMF_R(0.0), IMF_R(0.0) };

/* R(q)'s columns (the sensor axes turned by q) into o[9], from the products of q's
   components: the matrix, not three rotations of the axes */
static void robust_axes(imf_real *const o, const imf_real *const q)
{
    const imf_real xx = q[1] * q[1], yy = q[2] * q[2], zz = q[3] * q[3];
    const imf_real xy = q[1] * q[2], xz = q[1] * q[3], yz = q[2] * q[3];
    const imf_real wx = q[0] * q[1], wy = q[0] * q[2], wz = q[0] * q[3];
    o[0] = IMF_R(1.0) - IMF_R(2.0) * (yy + zz);
    o[1] = IMF_R(2.0) * (xy + wz);
    o[2] = IMF_R(2.0) * (xz - wy);
    o[3] = IMF_R(2.0) * (xy - wz);
    o[4] = IMF_R(1.0) - IMF_R(2.0) * (xx + zz);
    o[5] = IMF_R(2.0) * (yz + wx);
    o[6] = IMF_R(2.0) * (xz + wy);
    o[7] = IMF_R(2.0) * (yz - wx);
    o[8] = IMF_R(1.0) - IMF_R(2.0) * (xx + yy);
}

/* R(q) v into o, one copy (B3 turns four vectors) */
static ROBUST_NOINLINE void robust_rotate(imf_real *const o, const imf_real *const q,
                                          const imf_real *const v)
{
    imf_qrotate(o, q[0], q[1], q[2], q[3], v[0], v[1], v[2]);
}

/* |v - b|^2 */
static inline imf_real robust_off2(const imf_real *const v, const imf_real *const b)
{
    const imf_real x = v[0] - b[0], y = v[1] - b[1], z = v[2] - b[2];
    return x * x + y * y + z * z;
}

/* ---- init, dt, attitude ------------------------------------------------- */

static void robust_set_dt(imf_robust_consts_t *const set, const imf_real dt)
{
    set->s.dt = dt;
    set->two_dt = IMF_R(2.0) * dt;
    set->dt2 = dt * dt;
    set->r_d = IMF_R(1.0) / dt;
    set->qg_dt = set->qg0 * dt;
    /* B5: the first accelerometer sample is one sample, not a settled estimate: gravity's
       initial variance is what one velocity measurement (noise 1 / dt per sample) says of an
       acceleration over dt, 1 / dt^3, where 1 / tau_acc^3 (the settled variance, worth
       tau_acc of samples) would hold a moving start's first reading for tau_acc.
       gyr_bias_max 0: 1 / tau_acc^3, as the fixed-point filters start */
    if (set->s.gyr_bias_max > IMF_R(0.0)) {
        set->pgg0 = set->r_d * (set->r_d * set->r_d);
    } else {
        set->pgg0 = IMF_R(1.0) / (set->s.tau_acc * set->s.tau_acc * set->s.tau_acc);
    }
    set->k_rest = dt / (set->s.tau_rest + dt);
    set->kb_rest = dt / (set->s.tau_bias_rest + dt);
    set->ku_motion = set->inv_tau_bias * dt;
    set->k_mag = dt / (set->s.tau_mag + dt);
    set->k_ref = dt / (set->s.tau_mag_ref + dt);
    set->k_acc = dt / (set->s.tau_acc + dt);
}

static void robust_init(imf_robust_consts_t *const set, uint32_t *const skipped,
                        imf_robust_state_t *const x, const imf_robust_settings_t *const s)
{
    const imf_real rate_ref = s->rate_ref, rest_gyr = s->rest_gyr, rest_acc = s->rest_acc;
    imf_real *const w = (imf_real *)x;
    imf_real ta2, p0, tmax;
    unsigned i;
    set->s = *s;
    /* B2: gravity process noise q_g = (1 + |w|^2 / rate_ref^2) / tau_acc^4 per s, with
       the velocity measurement noise 1 (any acc unit): the steady state is a
       second-order low-pass with omega_0 = 1 / tau_acc and damping 1/sqrt(2) at rest */
    ta2 = s->tau_acc * s->tau_acc;
    set->qg0 = IMF_R(1.0) / (ta2 * ta2);
    set->inv_rate_ref2 = rate_ref > IMF_R(0.0) ? IMF_R(1.0) / (rate_ref * rate_ref) : IMF_R(0.0);
    set->inv_tau_bias = s->tau_bias > IMF_R(0.0) ? IMF_R(1.0) / s->tau_bias : IMF_R(0.0);
    set->tau_b0 = IMF_R(4.0) * s->tau_acc;
    set->tau_h0 = IMF_R(4.0) * s->tau_mag;
    /* B3's Kalman filter of the bias, relative to the noise of its measurement (the
       correction rate; robust_bias): in motion the accelerometer differs from gravity by up
       to rest_acc (what B1 calls motion), which B2 passes on as a tilt error changing over
       tau_acc, noise of density rest_acc^2 / tau_acc in the rate; the prior, any bias in
       the part's range in any direction, |b|^2 <= 3 gyr_bias_max^2: 1 / tau_p =
       3 gyr_bias_max^2 tau_acc / rest_acc^2 (no weaker than one sample's worth, 1 / dt);
       its random walk makes the steady state 1 / tau_bias (learnt over tau_bias) */
    p0 = IMF_R(3.0) * (s->gyr_bias_max * s->gyr_bias_max) * s->tau_acc;
    set->inv_tau_p =
        p0 * s->dt < rest_acc * rest_acc ? p0 / (rest_acc * rest_acc) : IMF_R(1.0) / s->dt;
    set->qb = set->inv_tau_bias * set->inv_tau_bias;
    /* rest_gyr 0: no rest (B1 off) at any bias */
    set->bias_var0 =
        rest_gyr > IMF_R(0.0) ? IMF_R(3.0) * s->gyr_bias_max * s->gyr_bias_max : IMF_R(0.0);
    set->bias_w2 = IMF_R(3600.0) * (s->gyr_bias_max * s->gyr_bias_max);
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
    x->bu = s->gyr_bias_max > IMF_R(0.0) ? IMF_R(1.0) : IMF_R(0.0);
    if (s->gyr_bias_max > IMF_R(0.0)) {
        /* B3: the bias's prior, worth tau_p of measurement */
        x->bp[0] = set->inv_tau_p;
        x->bp[3] = set->inv_tau_p;
        x->bp[5] = set->inv_tau_p;
    }
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
    settings->gyr_bias_max = (imf_real)0.10471975511965978; /* 6 deg/s */
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

/* ---- B3's noise (robust_b3.h) ------------------------------------------------------ */
#include "robust_b3.h"

/* ---- gyro and accelerometer: B1, strapdown, B2, levelling, B3 (robust_blocks.h) ---- */
#include "robust_blocks.h"

/* ---- magnetometer: B6, B4 (robust_mag.h) ------------------------------------------ */
#include "robust_mag.h"

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

/* The words of the state an update can change: all of it for the AHRS; the IMU (and the
   AHRS with B6 off) never changes B6's members (from hi on), so its update checks and
   keeps only those before them (the IMU copies only those too: B4 reads u). */
#define ROBUST_AHRS_WORDS (sizeof(imf_robust_state_t) / sizeof(imf_real))
#define ROBUST_IMU_WORDS (offsetof(imf_robust_state_t, hi) / sizeof(imf_real))

/* valid-attitude policy: the first n words of the new state finite. With hardware
   floating point, w - w is 0 for a finite w and NaN for an infinite or NaN one, and a NaN
   stays in a sum: four sums of them (branch-free) are 0 only if every word is finite;
   without (every operation a call), isfinite on each word. On x86-64 (SSE2, GCC or
   Clang) the sums run on 16-byte vectors of words, four of them (the same test in fewer
   instructions and shorter chains of additions). */
static inline int robust_finite(const imf_robust_state_t *const x, const unsigned n)
{
    const imf_real *const w = (const imf_real *)x;
    unsigned i;
#if defined(__AVR__) || defined(__SOFTFP__)
    for (i = 0; i < n; i++) {
        if (!isfinite(w[i])) {
            return 0;
        }
    }
    return 1;
#elif defined(__GNUC__) && defined(__SSE2__)
    typedef imf_real robust_vec __attribute__((vector_size(16), aligned(sizeof(imf_real))));
    enum { L = 16 / sizeof(imf_real) };
    robust_vec a0 = { 0 }, a1 = { 0 }, a2 = { 0 }, a3 = { 0 }, v;
    imf_real s = IMF_R(0.0);
#pragma GCC unroll 16
    for (i = 0; i + 4 * L <= n; i += 4 * L) {
        memcpy(&v, w + i, sizeof v);
        a0 = a0 + (v - v);
        memcpy(&v, w + i + L, sizeof v);
        a1 = a1 + (v - v);
        memcpy(&v, w + i + 2 * L, sizeof v);
        a2 = a2 + (v - v);
        memcpy(&v, w + i + 3 * L, sizeof v);
        a3 = a3 + (v - v);
    }
    for (; i < n; i++) {
        s = s + (w[i] - w[i]);
    }
    a0 = (a0 + a1) + (a2 + a3);
    for (i = 0; i < L; i++) {
        s = s + a0[i];
    }
    return s == IMF_R(0.0);
#else
    imf_real a0 = IMF_R(0.0), a1 = IMF_R(0.0), a2 = IMF_R(0.0), a3 = IMF_R(0.0);
    for (i = 0; i + 4 <= n; i += 4) {
        a0 = a0 + (w[i] - w[i]);
        a1 = a1 + (w[i + 1] - w[i + 1]);
        a2 = a2 + (w[i + 2] - w[i + 2]);
        a3 = a3 + (w[i + 3] - w[i + 3]);
    }
    for (; i < n; i++) {
        a0 = a0 + (w[i] - w[i]);
    }
    return (a0 + a1) + (a2 + a3) == IMF_R(0.0);
#endif
}

/* The update works on the state in place, its first n words (those it can change) kept in
   old before; it keeps the new state only if every block accepted the sample and left it
   finite (valid-attitude policy, imf_math.h), else the old words go back: one copy of the
   state per sample, and a second only for a rejected sample. */
static inline void robust_commit(imf_robust_state_t *const x, uint32_t *const skipped,
                                 const imf_robust_state_t *const old, const int ok,
                                 const unsigned n)
{
    if (!(ok && robust_finite(x, n))) {
        (*skipped)++;
        memcpy(x, old, n * sizeof(imf_real));
    }
}

void imf_robust_update_imu(imf_robust_t *const self, const imf_real gx, const imf_real gy,
                           const imf_real gz, const imf_real ax, const imf_real ay,
                           const imf_real az)
{
    const imf_real g[3] = { gx, gy, gz }, a[3] = { ax, ay, az };
    imf_robust_state_t old;
    int ok;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az))) {
        self->skipped++;
        return;
    }
    memcpy(&old, &self->x, ROBUST_IMU_WORDS * sizeof(imf_real));
    ok = robust_step(&self->set, &self->x, g, a, robust_zero3)
         && robust_output(&self->set, &self->x, g);
    robust_commit(&self->x, &self->skipped, &old, ok, ROBUST_IMU_WORDS);
}

void imf_robust_update(imf_robust_t *const self, const imf_real gx, const imf_real gy,
                       const imf_real gz, const imf_real ax, const imf_real ay, const imf_real az,
                       const imf_real mx, const imf_real my, const imf_real mz)
{
    const imf_real g[3] = { gx, gy, gz }, a[3] = { ax, ay, az }, m[3] = { mx, my, mz };
    const imf_real g2 = gx * gx + gy * gy + gz * gz;
    const unsigned n = self->set.s.mag_learn ? ROBUST_AHRS_WORDS : ROBUST_IMU_WORDS;
    imf_robust_state_t old;
    int ok;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az) && imf_finite3(mx, my, mz))) {
        self->skipped++;
        return;
    }
    memcpy(&old, &self->x, n * sizeof(imf_real));
    ok = robust_step(&self->set, &self->x, g, a, m)
         && robust_magnetometer(&self->set, &self->x, m, g2)
         && robust_output(&self->set, &self->x, g);
    robust_commit(&self->x, &self->skipped, &old, ok, n);
}
