/*
 * The gyroscope and accelerometer blocks of imufuse's recommended AHRS (B1 rest and the bias
 * at rest with the bias's get/set pair, the strapdown, B2 gravity, the levelling, B3 the bias
 * in motion). A private part of robust.c, included by it once (one translation unit per
 * family), after robust.c's helpers and robust_b3.h. Twins: python/imufuse/reference/
 * robust_blocks.py, the same functions in the same order; imufuse_c/host/lanes_robust.h.
 */
#ifndef IMF_ROBUST_BLOCKS_H
#define IMF_ROBUST_BLOCKS_H

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

/* The bias within the part's range, per axis (gyr_bias_max; 0: no bound) */
static inline void robust_bias_clip(const imf_robust_consts_t *const set, imf_real *const b)
{
    const imf_real m = set->s.gyr_bias_max;
    unsigned i;
    for (i = 0; m > IMF_R(0.0) && i < 3; i++) {
        b[i] = b[i] > m ? m : b[i] < -m ? -m : b[i];
    }
}

/* B1 with a magnetometer: at rest the field in the sensor frame is steady, and so is the
   rate (the bias alone). A turn about the vertical, which the accelerometer does not see and
   a gyro of unknown bias cannot tell from its bias, turns the field's horizontal part (across
   the low-passed gravity la): the low-passed field lm must not have turned since the rest
   window began (l0) by more than rest_gyr allows over the window (t_rest), beyond the noise
   of the two low-passes (3 sigma of mag_noise at the gain k, each: a turn accumulates, the
   noise averages). At the turning point of a swing the field is as steady for a moment,
   but the rate changes: the low-passed rate lw must not have changed since the window began
   (w0) by rest_gyr. Updates lm; passes without a reading (all zero: an IMU) and with a
   disturbed field (B4). */
static ROBUST_NOINLINE int robust_rest_mag(const imf_robust_consts_t *const set,
                                           imf_robust_state_t *const x, const imf_real *const m,
                                           const imf_real k)
{
    const imf_real *const la = x->la;
    imf_real d[3], a2, da, ma, m2, d2, h2, r, n2, l2;
    if (m[0] == IMF_R(0.0) && m[1] == IMF_R(0.0) && m[2] == IMF_R(0.0)) {
        return 1;
    }
    if (x->lm[0] == IMF_R(0.0) && x->lm[1] == IMF_R(0.0) && x->lm[2] == IMF_R(0.0)) {
        memcpy(x->lm, m, sizeof x->lm); /* the first reading */
        memcpy(x->l0, m, sizeof x->l0);
    } else {
        /* a reading beyond 8 times the low-passed field or below an eighth of it (a shock, a
           finite but absurd value) is no rest and is not low-passed: it would hold rest off
           for as long as the low-pass takes to forget it (minutes for 1e30) */
        n2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
        l2 = x->lm[0] * x->lm[0] + x->lm[1] * x->lm[1] + x->lm[2] * x->lm[2];
        if (!(n2 <= IMF_R(64.0) * l2 && n2 * IMF_R(64.0) >= l2)) {
            return 0;
        }
        robust_lp3(x->lm, m, k);
    }
    if (x->t_dist > IMF_R(0.0)) {
        return 1;
    }
    d[0] = x->lm[0] - x->l0[0];
    d[1] = x->lm[1] - x->l0[1];
    d[2] = x->lm[2] - x->l0[2];
    a2 = la[0] * la[0] + la[1] * la[1] + la[2] * la[2];
    da = d[0] * la[0] + d[1] * la[1] + d[2] * la[2];
    ma = x->lm[0] * la[0] + x->lm[1] * la[1] + x->lm[2] * la[2];
    m2 = x->lm[0] * x->lm[0] + x->lm[1] * x->lm[1] + x->lm[2] * x->lm[2];
    /* horizontal parts times a2: |d_h|^2 a2 and |lm_h|^2 a2 */
    d2 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * a2 - da * da;
    h2 = m2 * a2 - ma * ma;
    r = set->s.rest_gyr * x->t_rest;
    return d2 <= r * r * h2 + IMF_R(18.0) * set->mag_noise2 * k * (m2 * a2)
           && robust_off2(x->lw, x->w0) < set->rest_gyr2;
}

/* B1: rest detection from low-passes of gyro and accelerometer in the sensor frame, and
   the bias observed at rest (Eq. 3.1: b_k = b_{k-1}). The rates are compared after the
   bias estimate is taken off, within rest_gyr plus what is still unknown of the bias
   (bu: at the start any bias up to gyr_bias_max per axis passes). Returns rest; *w2: the
   low-passed rate squared (B2's process noise). m: the magnetometer (all zero: none), whose
   field must be steady too (robust_rest_mag). */
static ROBUST_NOINLINE int robust_rest(const imf_robust_consts_t *const set,
                                       imf_robust_state_t *const x, const imf_real *const g,
                                       const imf_real *const a, const imf_real *const m,
                                       const int has_acc, imf_real *const w2)
{
    const imf_real k = robust_gain(set, x->t, set->s.tau_rest, set->k_rest);
    const imf_real win = set->rest_gyr2 + set->bias_var0 * (x->bu * x->bu);
    /* the bias taken off; gyr_bias_max 0: the raw rates (the fixed-point filters' B1) */
    const imf_real *const bb = set->s.gyr_bias_max > IMF_R(0.0) ? x->b : robust_zero3;
    imf_real dx, dy, dz, d2, a2, kb, pr;
    unsigned i;
    int steady;
    robust_lp3(x->lw, g, k);
    if (has_acc) {
        robust_lp3(x->la, a, k);
    }
    *w2 = x->lw[0] * x->lw[0] + x->lw[1] * x->lw[1] + x->lw[2] * x->lw[2];
    dx = a[0] - x->la[0];
    dy = a[1] - x->la[1];
    dz = a[2] - x->la[2];
    d2 = dx * dx + dy * dy + dz * dz;
    a2 = x->la[0] * x->la[0] + x->la[1] * x->la[1] + x->la[2] * x->la[2];
    /* the field steady too; gyr_bias_max 0: the fixed-point filters' B1 (no field) */
    steady = set->s.gyr_bias_max > IMF_R(0.0) ? robust_rest_mag(set, x, m, k) : 1;
    if (has_acc && robust_off2(x->lw, bb) < win && robust_off2(g, bb) < win
        && d2 < set->rest_acc2 * a2 && steady) {
        x->t_rest = x->t_rest + set->s.dt;
        if (x->t_rest > set->s.rest_time) {
            x->t_rest = set->s.rest_time;
        }
    } else {
        x->t_rest = IMF_R(0.0);
    }
    if (x->t_rest == IMF_R(0.0) || x->t < set->s.tau_rest) {
        memcpy(x->l0, x->lm, sizeof x->l0); /* the next window begins here */
        memcpy(x->w0, x->lw, sizeof x->w0);
    }
    if (!(x->t_rest >= set->s.rest_time)) {
        return 0;
    }
    /* the bias's low-pass: tau_bias_rest once known, tau_rest while unknown (bu) */
    kb = set->kb_rest + x->bu * (set->k_rest - set->kb_rest);
    robust_lp3(x->b, g, kb);
    robust_bias_clip(set, x->b);
    /* B3's covariance learns with it: a rest counts as (1 - bu) tau_bias of motion (as
       robust_bias_gain), so its information 1 / P grows from tau_p + (1 - bu) tau_bias by
       kb bu tau_bias (in units of 1 / tau_p) */
    pr = kb * x->bu * set->s.tau_bias * set->inv_tau_p;
    pr = IMF_R(1.0) + pr / (IMF_R(1.0) + (IMF_R(1.0) - x->bu) * set->s.tau_bias * set->inv_tau_p);
    for (i = 0; i < 6; i++) {
        x->bp[i] = x->bp[i] / pr;
    }
    x->bu = x->bu - kb * x->bu;
    /* B2 at rest: the accelerometer is gravity, so B1's low-pass of it, in I, is B2's gravity
       and v is 0 (the tilt an uncalibrated gyro drifted before the rest taken back at once);
       not with gyr_bias_max 0 (the fixed-point filters' B1 and B2) */
    if (set->s.gyr_bias_max > IMF_R(0.0)) {
        imf_qrotate(x->f, x->s[0], x->s[1], x->s[2], x->s[3], x->la[0], x->la[1], x->la[2]);
        memset(x->v, 0, sizeof x->v);
    }
    return 1;
}

imf_real imf_robust_get_gyr_bias(const imf_robust_t *const self, imf_real bias[3])
{
    memcpy(bias, self->x.b, sizeof self->x.b);
    return self->x.bu;
}

void imf_robust_set_gyr_bias(imf_robust_t *const self, const imf_real bias[3])
{
    unsigned i;
    memcpy(self->x.b, bias, sizeof self->x.b);
    self->x.bu = IMF_R(0.0);
    /* B3: as learnt at the bound of its noise (an = 1: steady state 1 / tau_bias; a smooth
       motion's smaller an learns it tighter) */
    for (i = 0; i < 6; i++) {
        self->x.bp[i] = IMF_R(0.0);
    }
    self->x.bp[0] = self->set.inv_tau_bias;
    self->x.bp[3] = self->set.inv_tau_bias;
    self->x.bp[5] = self->set.inv_tau_bias;
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

/* B2's model of the bias (for B3), n values: the strapdown turns I through the bias
   estimate by u dt per sample (u: R(s) b, or R(s) for its dependence on b), gravity in I turns
   with it, and B2's gravity follows that turn through its low-pass, whose rate the levelling
   corrects. d: the summed turn less its low-pass, v: the velocity-like state, through the
   same Kalman gains as gravity (kg, kv); o: the low-pass's rate this sample */
static ROBUST_NOINLINE void robust_turn_lp(const imf_robust_consts_t *const set, imf_real *const d,
                                           imf_real *const v, const imf_real *const u,
                                           imf_real *const o, const unsigned n, const imf_real kg,
                                           const imf_real kv)
{
    const imf_real dt = set->s.dt;
    imf_real du, vp;
    unsigned j;
    for (j = 0; j < n; j++) {
        du = u[j] * dt;
        vp = v[j] + dt * (d[j] + du);
        o[j] = -(kg * vp) * set->r_d;
        d[j] = d[j] + du + kg * vp;
        v[j] = vp - kv * vp;
    }
}

/* B2: gravity in the inertial frame, a Kalman filter of (v, f) per axis fed with the
   accelerometer in that frame; from the first sample (B5). With gyr_bias_max > 0 also B2's
   model of the bias (robust_turn_lp): hb, the rate of its low-pass of R(s) b, and hr, of
   R(s) (columns), both in I; 0 when gravity is not updated. */
static ROBUST_NOINLINE void robust_gravity(const imf_robust_consts_t *const set,
                                           imf_robust_state_t *const x, const imf_real *const a,
                                           const int first, const int has_acc, const imf_real w2,
                                           imf_real *const hb, imf_real *const hr)
{
    const imf_real dt = set->s.dt;
    imf_real ai[3], ri[9], rb[3], rr, qg, ub, pvv, pvg, pgg, inv, kv, kg;
    unsigned j;
    imf_qrotate(ai, x->s[0], x->s[1], x->s[2], x->s[3], a[0], a[1], a[2]);
    robust_acc_noise(set, x, ai, first, has_acc); /* B3's noise, before the update */
    if (first || !has_acc || !(set->s.gyr_bias_max > IMF_R(0.0))) {
        for (j = 0; j < 9; j++) {
            hr[j] = hb[j % 3u] = IMF_R(0.0); /* no rate of B2's model this sample */
        }
    }
    if (first) {
        for (j = 0; j < 9; j++) {
            x->dr[j] = x->vr[j] = x->db[j % 3u] = x->vb[j % 3u] = IMF_R(0.0); /* no turn yet */
            x->v[j % 3u] = IMF_R(0.0);
            x->f[j % 3u] = ai[j % 3u]; /* B5: gravity from the first sample */
        }
        x->pvv = IMF_R(0.0);
        x->pvg = IMF_R(0.0);
        x->pgg = set->pgg0;
        return;
    }
    if (!has_acc) {
        return;
    }
    /* predict: v' = a - g, g' = 0 (+ process noise growing with the rotation rate) */
#if defined(__AVR__)
    for (j = 0; j < 3; j++) {
        x->v[j] = x->v[j] + dt * (ai[j] - x->f[j]);
    }
#else
    x->v[0] = x->v[0] + dt * (ai[0] - x->f[0]);
    x->v[1] = x->v[1] + dt * (ai[1] - x->f[1]);
    x->v[2] = x->v[2] + dt * (ai[2] - x->f[2]);
#endif
    /* (w / rate_ref)^2 capped at 10^4 (100 rate_ref: beyond any gyro's range), so
       that hostile rates cannot blow the covariance up. While the bias is still unknown,
       its error sigma_b (the error of a running mean after (1 - bu) tau_bias of learning,
       at most bu gyr_bias_max; the part's range gyr_bias_max at first) turns I as a
       rotation 60 times faster does through a scale error of 1/60: it adds (60 sigma_b)^2
       to w^2 */
    rr = w2;
    if (x->bu > IMF_R(0.0)) {
        ub = set->tau_b0 / (set->tau_b0 + (IMF_R(1.0) - x->bu) * set->s.tau_bias);
        if (x->bu < ub) {
            ub = x->bu; /* learnt at rest (or B3 off): what is left of it */
        }
        rr = rr + set->bias_w2 * (ub * ub);
    }
    rr = rr * set->inv_rate_ref2;
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
#if defined(__AVR__)
    for (j = 0; j < 3; j++) {
        x->f[j] = x->f[j] - kg * x->v[j];
        x->v[j] = x->v[j] - kv * x->v[j];
    }
#else
    x->f[0] = x->f[0] - kg * x->v[0];
    x->f[1] = x->f[1] - kg * x->v[1];
    x->f[2] = x->f[2] - kg * x->v[2];
    x->v[0] = x->v[0] - kv * x->v[0];
    x->v[1] = x->v[1] - kv * x->v[1];
    x->v[2] = x->v[2] - kv * x->v[2];
#endif
    x->pgg = pgg - kg * pvg;
    x->pvg = pvg - kv * pvg;
    x->pvv = pvv - kv * pvv;
    if (set->s.gyr_bias_max > IMF_R(0.0)) {
        robust_axes(ri, x->s); /* R(s), then R(s) b from its columns */
        for (j = 0; j < 3; j++) {
            rb[j] = ri[j] * x->b[0] + ri[3 + j] * x->b[1] + ri[6 + j] * x->b[2];
        }
        robust_turn_lp(set, x->db, x->vb, rb, hb, 3u, kg, kv);
        robust_turn_lp(set, x->dr, x->vr, ri, hr, 9u, kg, kv);
    }
}

/* levelling: the smallest rotation r that turns the gravity estimate onto earth z, into
   the correction c, and q = c (x) s; 0 rejects the sample */
static int robust_level(imf_robust_state_t *const x, imf_real *const r)
{
    imf_real ge[3], gn, c[4];
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
    /* c and s are unit quaternions: so is their product, within a few roundings (no
       normalisation; a non-finite q fails the commit's check) */
    imf_qmul(x->q, c[0], c[1], c[2], c[3], x->s[0], x->s[1], x->s[2], x->s[3]);
    return 1;
}

/* How much less a correction says of the bias while the sensor turns at w - b: d^2, with
   d = 1 + (|w - b| / rate_ref)^2. Two errors grow alike with the rate: B2's gravity is less
   certain (its process noise grows by d), so the correction is noisier by d; and the gyro's
   scale and alignment errors add a false bias s |w - b| (s = 1/60, B2's scale error, as
   large as B2's own noise at rate_ref) that a running mean does not average away while a
   rotation lasts, so of the rest only 1 / d is bias. */
static inline imf_real robust_turn_div(const imf_robust_consts_t *const set,
                                       const imf_robust_state_t *const x)
{
    const imf_real d = IMF_R(1.0) + robust_off2(x->lw, x->b) * set->inv_rate_ref2;
    return d * d;
}

/* B3's integral gain, 1/s: 1 / tau while the sensor turns slowly; while the bias is still
   unknown (bu > 0) tau is the time it has been learnt for, (1 - bu) tau_bias, from tau0
   (the fastest damped loop, Eq. 3.12: 4 times the correction's time constant) up to
   tau_bias (a running mean), then tau_bias. Divided by robust_turn_div: while the sensor
   turns fast the corrections are mostly B2's noise and the gyro's scale and alignment
   errors, not its bias. gyr_bias_max 0 (a calibrated gyro): 1 / tau_bias. */
static imf_real robust_bias_gain(const imf_robust_consts_t *const set,
                                 const imf_robust_state_t *const x, const imf_real tau0)
{
    imf_real tm, tau = set->s.tau_bias;
    if (!(set->s.gyr_bias_max > IMF_R(0.0))) {
        return set->inv_tau_bias; /* a calibrated gyro: 1 / tau_bias (the fixed-point B3) */
    }
    if (x->bu > IMF_R(0.0)) {
        tm = (IMF_R(1.0) - x->bu) * set->s.tau_bias;
        tau = tm > tau0 ? tm : tau0;
    }
    return IMF_R(1.0) / (tau * robust_turn_div(set, x));
}

/* The bias from a correction rotation (its rotation vector (cx, cy, cz) in the earth frame,
   one sample) with the gain k: seen in the sensor frame it is minus the bias error (Eq. 3.6) */
static void robust_bias_from(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                             const imf_real cx, const imf_real cy, const imf_real cz,
                             const imf_real k)
{
    imf_real e[3];
    imf_qrotate(e, x->q[0], -x->q[1], -x->q[2], -x->q[3], cx, cy, cz);
    x->b[0] = x->b[0] - e[0] * k;
    x->b[1] = x->b[1] - e[1] * k;
    x->b[2] = x->b[2] - e[2] * k;
    robust_bias_clip(set, x->b);
}

/* B3: one row of the bias's measurement, y = (h[0], h[3], h[6]) . b + noise of variance w:
   the Kalman update of b and of its covariance bp */
static ROBUST_NOINLINE void robust_bias_row(imf_robust_state_t *const x, const imf_real *const h,
                                            const imf_real y, const imf_real w)
{
    /* bp[robust_bi[i][j]] = P[i][j] */
    static const unsigned char robust_bi[3][3] = { { 0, 1, 2 }, { 1, 3, 4 }, { 2, 4, 5 } };
    imf_real *const p = x->bp;
    imf_real ph[3], ri, e, k;
    unsigned i, j;
    for (i = 0; i < 3; i++) {
        ph[i] = p[robust_bi[i][0]] * h[0] + p[robust_bi[i][1]] * h[3] + p[robust_bi[i][2]] * h[6];
    }
    ri = IMF_R(1.0) / (h[0] * ph[0] + h[3] * ph[1] + h[6] * ph[2] + w); /* one division */
    e = (y - (h[0] * x->b[0] + h[3] * x->b[1] + h[6] * x->b[2])) * ri;
    for (i = 0; i < 3; i++) {
        x->b[i] = x->b[i] + ph[i] * e;
    }
#if defined(__AVR__)
    for (i = 0; i < 3; i++) {
        k = ph[i] * ri;
        for (j = i; j < 3; j++) {
            p[robust_bi[i][j]] = p[robust_bi[i][j]] - k * ph[j];
        }
    }
#else
    /* the same, written out (no loop branches) */
    (void)j;
    k = ph[0] * ri;
    p[0] = p[0] - k * ph[0];
    p[1] = p[1] - k * ph[1];
    p[2] = p[2] - k * ph[2];
    k = ph[1] * ri;
    p[3] = p[3] - k * ph[1];
    p[4] = p[4] - k * ph[2];
    k = ph[2] * ri;
    p[5] = p[5] - k * ph[2];
#endif
}

/* B3: in motion, from the levelling. The correction is B2's low-pass of the strapdown's turn
   by the bias error; B2's model of the bias (robust_gravity) low-passes the turn by the
   estimate (hb) and by each sensor axis (hr) alike, so in the earth frame (c) the low-pass
   of the turn by the true bias is y = c hb - 2 r / dt, and y = H b_true with H the horizontal
   rows of c hr: a Kalman filter of b (covariance bp: prior, random walk, robust_init) with
   the noise d^2 an / dt per row (robust_turn_div, robust_an), no loop to damp or lag, and
   a bias turning with the sensor faster than B2 follows is seen as small as it is. Each
   sample teaches bu by dt / tau_bias, less while the sensor turns fast. gyr_bias_max 0: the
   integral of the correction (Eq. 3.6, I_k = I_{k-1} + Ki dt e_k, Ki dt = 1 / tau_bias) */
static ROBUST_NOINLINE void robust_bias(const imf_robust_consts_t *const set,
                                        imf_robust_state_t *const x, const imf_real *const r,
                                        const int rest, const imf_real *const hb,
                                        const imf_real *const hr)
{
    imf_real k, y[3], h[9];
    unsigned i;
    if (!rest && x->t >= set->s.tau_acc && set->inv_tau_bias > IMF_R(0.0)) {
        if (x->bu > IMF_R(0.0)) {
            /* less learnt while the sensor turns fast (robust_bias_gain) */
            x->bu = x->bu - set->ku_motion / robust_turn_div(set, x);
            if (x->bu < IMF_R(0.0)) {
                x->bu = IMF_R(0.0);
            }
        }
        if (!(set->s.gyr_bias_max > IMF_R(0.0))) {
            k = robust_bias_gain(set, x, set->tau_b0);
            robust_bias_from(set, x, IMF_R(2.0) * r[1], IMF_R(2.0) * r[2], IMF_R(0.0), k);
            return;
        }
        robust_rotate(y, x->c, hb);
        for (i = 0; i < 9; i += 3) {
            robust_rotate(h + i, x->c, hr + i);
        }
        k = set->qb * set->s.dt; /* the random walk */
        x->bp[0] = x->bp[0] + k;
        x->bp[3] = x->bp[3] + k;
        x->bp[5] = x->bp[5] + k;
        k = robust_turn_div(set, x) * set->r_d * robust_an(x);
        robust_bias_row(x, h, y[0] - IMF_R(2.0) * r[1] * set->r_d, k);
        robust_bias_row(x, h + 1, y[1] - IMF_R(2.0) * r[2] * set->r_d, k);
        robust_bias_clip(set, x->b);
    }
}

/* Gyro (rad/s), accelerometer (and magnetometer m for B1's rest; all zero: none) of one
   sample through B1, the strapdown, B2, the levelling and B3, on the working state x;
   0 rejects the sample. */
static int robust_step(const imf_robust_consts_t *const set, imf_robust_state_t *const x,
                       const imf_real *const g, const imf_real *const a, const imf_real *const m)
{
    const int first = x->t == IMF_R(0.0);
    const int has_acc = robust_acc_reading(x, a, first);
    imf_real w2, r[4], hb[3], hr[9];
    int rest;
    if (first && !has_acc) {
        return 0; /* no start without an accelerometer reading */
    }
    rest = robust_rest(set, x, g, a, m, has_acc, &w2); /* B1 */
    if (!robust_strapdown(set, x, g)) {
        return 0;
    }
    robust_gravity(set, x, a, first, has_acc, w2, hb, hr); /* B2 */
    if (!robust_level(x, r)) {
        return 0;
    }
    robust_bias(set, x, r, rest, hb, hr); /* B3 */
    return 1;
}

#endif /* IMF_ROBUST_BLOCKS_H */
