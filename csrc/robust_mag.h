/*
 * The magnetometer blocks of imufuse's recommended AHRS (B6 the offset learnt while turning,
 * B4 the heading with its disturbance detector) and the offset's API. A private part of
 * robust.c, included by it once (one translation unit per family: the build tools take one
 * source per filter); it uses robust.c's helpers above its #include. The pure-Python twin
 * is python/imufuse/reference/robust_mag.py: the same functions, in the same order.
 * The host's lane twin: imufuse_c/host/lanes_robust.h (change both).
 */
#ifndef IMF_ROBUST_MAG_H
#define IMF_ROBUST_MAG_H

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
/* B6: before it is trusted, while the offset in use is still the stored one, an estimate
   with a standard deviation below MAG_EARLY replaces it when the reading's norm says the
   stored one is wrong: with it the norm moves by more than MAG_NORM of the field (squared:
   the low-passed squared deviation from its low-pass) and by MAG_BETTER times (squared)
   more than with the estimate (an offset of tens of uT is clear long before it is known to
   1 %; the norm does not depend on the attitude, which a fast turn's model errors spoil),
   and the estimate differs from the stored offset by more than mag_offset_min. A change of
   the offset in use beyond MAG_RESET of the field (squared) changes the field B4 sees: B4's
   reference starts again from the next reading. */
#define ROBUST_MAG_EARLY IMF_R(0.05)
#define ROBUST_MAG_NORM2 IMF_R(0.001)
#define ROBUST_MAG_BETTER2 IMF_R(4.0)
#define ROBUST_MAG_RESET2 IMF_R(0.0025)
/* B6: a reading whose norm is beyond 8 times the field unit, or below 1/8 of it, is no
   reading of this field (a hostile value, a magnet on the sensor): not used; after
   ROBUST_MAG_RESTART s of them the estimator starts again from the next reading */
#define ROBUST_MAG_RANGE2 IMF_R(64.0)
#define ROBUST_MAG_RESTART IMF_R(1.0)

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
    unsigned j;
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
#if defined(__AVR__)
    for (j = 0; j < 6; j++) {
        unsigned k;
        for (k = j; k < 6; k++) {
            mp[robust_pi[j][k]] = mp[robust_pi[j][k]] - ph[j] * kk[k];
        }
    }
#else
    /* the same, written out (no loop branches): P[n] = P[j][k], the upper triangle by rows */
    mp[0] = mp[0] - ph[0] * kk[0];
    mp[1] = mp[1] - ph[0] * kk[1];
    mp[2] = mp[2] - ph[0] * kk[2];
    mp[3] = mp[3] - ph[0] * kk[3];
    mp[4] = mp[4] - ph[0] * kk[4];
    mp[5] = mp[5] - ph[0] * kk[5];
    mp[6] = mp[6] - ph[1] * kk[1];
    mp[7] = mp[7] - ph[1] * kk[2];
    mp[8] = mp[8] - ph[1] * kk[3];
    mp[9] = mp[9] - ph[1] * kk[4];
    mp[10] = mp[10] - ph[1] * kk[5];
    mp[11] = mp[11] - ph[2] * kk[2];
    mp[12] = mp[12] - ph[2] * kk[3];
    mp[13] = mp[13] - ph[2] * kk[4];
    mp[14] = mp[14] - ph[2] * kk[5];
    mp[15] = mp[15] - ph[3] * kk[3];
    mp[16] = mp[16] - ph[3] * kk[4];
    mp[17] = mp[17] - ph[3] * kk[5];
    mp[18] = mp[18] - ph[4] * kk[4];
    mp[19] = mp[19] - ph[4] * kk[5];
    mp[20] = mp[20] - ph[5] * kk[5];
#endif
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
    x->mn[0] = IMF_R(1.0);
    x->mn[1] = IMF_R(0.0);
    x->mn[2] = IMF_R(1.0);
    x->mn[3] = IMF_R(0.0);
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
#if defined(__AVR__)
    for (k = 0; k < 6; k++) {
        pb = x->P[robust_pi[k][k]] + (k < 3 ? ROBUST_MAG_QH : ROBUST_MAG_QO) * set->s.dt;
        if (k >= 3 && x->m_d2 > ROBUST_MAG_GATE && pb < ROBUST_MAG_P0) {
            pb = pb + ROBUST_MAG_JUMP;
        }
        x->P[robust_pi[k][k]] = pb;
    }
#else
    /* the same: the field's diagonal (P[0], P[6], P[11]), then the offset's */
    const imf_real qh = ROBUST_MAG_QH * set->s.dt, qo = ROBUST_MAG_QO * set->s.dt;
    const int jump = x->m_d2 > ROBUST_MAG_GATE;
    x->P[0] = x->P[0] + qh;
    x->P[6] = x->P[6] + qh;
    x->P[11] = x->P[11] + qh;
    for (k = 3; k < 6; k++) {
        pb = x->P[robust_pi[k][k]] + qo;
        if (jump && pb < ROBUST_MAG_P0) {
            pb = pb + ROBUST_MAG_JUMP;
        }
        x->P[robust_pi[k][k]] = pb;
    }
#endif
    rr = g2 * set->mag_lag2;
    if (!(rr <= IMF_R(1.0))) {
        rr = IMF_R(1.0);
    }
    rr = set->mag_noise2 + rr;
    x->m_d2 = robust_offset_axis(x->P, x->hi, i, c[0], c[1], c[2], y, rr);
    x->m_ew = x->m_ew + ROBUST_MAG_EW * (x->m_d2 - x->m_ew);
    x->m_axis = i == 2u ? IMF_R(0.0) : x->m_axis + IMF_R(1.0);
}

/* B6: the norm of the reading less an offset c s, in field units (inv = 1 / n0), into a
   low-pass w[0] and the square of its deviation from that low-pass into a low-pass w[1]
   (gain k) */
static ROBUST_NOINLINE void robust_norm_lp(imf_real *const w, const imf_real *const m,
                                           const imf_real *const c, const imf_real s,
                                           const imf_real inv, const imf_real k)
{
    imf_real n2 = IMF_R(0.0), d;
    unsigned i;
    for (i = 0; i < 3; i++) {
        d = m[i] - c[i] * s;
        n2 = n2 + d * d;
    }
    d = imf_sqrt(n2) * inv - w[0];
    w[0] = w[0] + k * d;
    w[1] = w[1] + k * (d * d - w[1]);
}

/* B6: how well the offset in use and the estimate each explain the reading's norm (mn:
   with u, then with the estimate o n0), every third sample (the axis cycle) with the gain
   of three samples of k_mag (over tau_mag): an offset wrong by d moves the norm by up to d
   as the sensor turns, a right one leaves it still, whatever the attitude */
static inline void robust_offset_norms(const imf_robust_consts_t *const set,
                                       imf_robust_state_t *const x, const imf_real *const m,
                                       const imf_real inv)
{
    const imf_real e = IMF_R(1.0) - set->k_mag;
    const imf_real k3 = IMF_R(1.0) - e * e * e;
    robust_norm_lp(x->mn, m, x->u, IMF_R(1.0), inv, k3);
    robust_norm_lp(x->mn + 2, m, x->hi + 3, x->m_n0, inv, k3);
}

/* B6: the offset's standard deviation (its largest variance, never below 0). The offset
   in use u: trusted and consistent, the stored offset while the estimate agrees with it
   within mag_offset_min, else the estimate; consistent but not yet trusted, the estimate
   when it is below MAG_EARLY and the reading's norm says the stored offset, still in use,
   is wrong (MAG_NORM, MAG_BETTER) and the estimate differs from it by more than
   mag_offset_min. A change beyond MAG_RESET starts B4's reference again. inv: 1 / m_n0. */
static ROBUST_SMALL void robust_offset_use(const imf_robust_consts_t *const set,
                                           imf_robust_state_t *const x, const imf_real inv)
{
    imf_real pb, o2, d, e[3], u[3];
    int trust;
    unsigned k;
    pb = IMF_R(0.0);
    for (k = 3; k < 6; k++) {
        if (x->P[robust_pi[k][k]] > pb) {
            pb = x->P[robust_pi[k][k]];
        }
    }
    x->m_std = imf_sqrt(pb);
    if (!(x->m_ew < ROBUST_MAG_MEAN)) {
        return;
    }
    trust = x->m_std < ROBUST_MAG_TRUST;
    if (!(trust
          || (x->m_std < ROBUST_MAG_EARLY && x->u[0] == x->so[0] && x->u[1] == x->so[1]
              && x->u[2] == x->so[2] && x->t_dist == IMF_R(0.0) && x->mn[1] > ROBUST_MAG_NORM2
              && ROBUST_MAG_BETTER2 * x->mn[3] < x->mn[1]))) {
        return;
    }
    o2 = IMF_R(0.0);
    for (k = 0; k < 3; k++) {
        e[k] = x->hi[3 + k] - x->so[k] * inv;
        o2 = o2 + e[k] * e[k];
        u[k] = x->hi[3 + k] * x->m_n0;
    }
    if (o2 < set->mag_min2) {
        if (!trust) {
            return; /* early: only an estimate that differs from the stored offset */
        }
        memcpy(u, x->so, sizeof u);
    }
    o2 = IMF_R(0.0);
    for (k = 0; k < 3; k++) {
        d = u[k] - x->u[k];
        o2 = o2 + d * d;
    }
    if (o2 * (inv * inv) > ROBUST_MAG_RESET2) {
        x->ref[0] = IMF_R(0.0); /* B4: a new reference from the next reading */
    }
    memcpy(x->u, u, sizeof u);
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
        if (i == 2u) {
            robust_offset_norms(set, x, m, inv); /* with the axis cycle: every third sample */
        }
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
        robust_lp3(x->ref, fn, k);
        memcpy(x->cand, fn, sizeof x->cand);
        return 1;
    }
    /* disturbed (or not yet matching for mag_hold): no heading correction */
    x->t_dist = x->t_dist + set->s.dt;
    if (robust_mag_test(set, fn, x->cand)) {
        robust_lp3(x->cand, fn, set->k_rest);
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
    /* B3 from the heading: in motion, once the heading has started (tau_mag) and the
       offset in use is trusted (B6: a heading through an unknown offset is no measure of
       the bias); not for a calibrated gyro (gyr_bias_max 0: the fixed-point filters' B3) */
    if (x->t >= set->s.tau_mag && set->inv_tau_bias > IMF_R(0.0) && set->s.gyr_bias_max > IMF_R(0.0)
        && !(x->t_rest >= set->s.rest_time)
        && (!set->s.mag_learn || (x->m_std < ROBUST_MAG_TRUST && x->m_ew < ROBUST_MAG_MEAN))) {
        robust_bias_from(set, x, IMF_R(0.0), IMF_R(0.0), IMF_R(2.0) * zz,
                         robust_bias_gain(set, x, set->tau_h0));
    }
    c[0] = zw * x->c[0] - zz * x->c[3];
    c[1] = zw * x->c[1] - zz * x->c[2];
    c[2] = zw * x->c[2] + zz * x->c[1];
    c[3] = zw * x->c[3] + zz * x->c[0];
    /* z and c are unit quaternions: so are c and q = c (x) s, within a few roundings (no
       normalisation: the levelling normalises c every sample; a non-finite c or q fails
       the commit's check) */
    memcpy(x->c, c, sizeof c);
    imf_qmul(x->q, c[0], c[1], c[2], c[3], x->s[0], x->s[1], x->s[2], x->s[3]);
    return 1;
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

#endif /* IMF_ROBUST_MAG_H */
