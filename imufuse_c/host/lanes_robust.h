/*
 * RobustIMU / RobustAHRS lane by lane: one instance per lane width, included by lanes_body.h
 * (its LN, VR, VM, sqrt and select helpers) when IMF_LANES_ROBUST is defined.
 *
 * The lane twin of csrc/robust.c and its blocks csrc/robust_b3.h (B3's noise),
 * csrc/robust_blocks.h (B1-B3) and csrc/robust_mag.h (B6, B4): rl_<name> here is robust_<name> there, the same functions in
 * the same order. Every line of a lane step is the line of the scalar update with the same
 * operands in the same order. Where the scalar code branches on the state (rest, the first
 * sample, the gates, B6's start and schedule, B4's detector, the valid-attitude policy) or on
 * a setting (gyr_bias_max 0, mag_learn, latency), both outcomes are computed and each lane
 * keeps its own (RSEL); a branch no lane takes is not computed (LN(any)). Branches on the
 * inputs alone (a non-finite sample, no accelerometer or magnetometer reading) are the same
 * for every lane and stay branches. A lane whose sample is rejected computes on and its
 * result is dropped by the commit, as the scalar update drops its working copy. Every setting
 * is a lane's own, so any group of filters of one class shares lanes (the kernel returns 0
 * only for a group size outside 1..LW). B6's constants are copied below (tests/test_batch.py
 * checks them against csrc/robust_mag.h); the tests of the twin: tests/test_batch.py,
 * test_robust_lanes_*, bit for bit with each filter's own update at every width.
 */
#ifndef IMF_LANES_ROBUST_ONCE
#define IMF_LANES_ROBUST_ONCE
/* csrc/robust_mag.h's B6 model (the same names and values; see there) and its covariance
   index robust_pi */
#define ROBUST_MAG_QH IMF_R(1.0e-3)
#define ROBUST_MAG_QO IMF_R(1.0e-7)
#define ROBUST_MAG_P0 IMF_R(1.0)
#define ROBUST_MAG_GATE IMF_R(19.0)
#define ROBUST_MAG_MEAN IMF_R(8.0)
#define ROBUST_MAG_JUMP IMF_R(0.05)
#define ROBUST_MAG_EW IMF_R(0.02)
#define ROBUST_MAG_TRUST IMF_R(0.01)
#define ROBUST_MAG_EARLY IMF_R(0.05)
#define ROBUST_MAG_NORM2 IMF_R(0.001)
#define ROBUST_MAG_BETTER2 IMF_R(4.0)
#define ROBUST_MAG_RESET2 IMF_R(0.0025)
#define ROBUST_MAG_RANGE2 IMF_R(64.0)
#define ROBUST_MAG_RESTART IMF_R(1.0)
static const unsigned char robust_pi[6][6] = {
    { 0, 1, 2, 3, 4, 5 },     { 1, 6, 7, 8, 9, 10 },    { 2, 7, 11, 12, 13, 14 },
    { 3, 8, 12, 15, 16, 17 }, { 4, 9, 13, 16, 18, 19 }, { 5, 10, 14, 17, 19, 20 }
};
#endif

#define RSEL(m, a, b) LN(sel_r)((m), (a), (b))
#define RB(v) LN(bc)(v)
#define RX LN(rx_t)
#define RL LN(rl_t)

/* every lane of m set */
static inline int LN(all)(const VM m)
{
    int i, r = 1;
    for (i = 0; i < LW; i++) {
        r &= m[i] != 0;
    }
    return r;
}

static inline VR LN(bc)(const imf_real v)
{
    VR r;
    int i;
    for (i = 0; i < LW; i++) {
        r[i] = v;
    }
    return r;
}

/* imf_robust_state_t with a lane vector for each word, the same members in the same order */
typedef struct {
    VR q[4], s[4], c[4], f[3], v[3], pvv, pvg, pgg, b[3], lw[3], la[3], t, t_rest, bu, ref[3],
        cand[3], t_cand, t_dist, t_ok, lm[3], l0[3], w0[3], db[3], vb[3], dr[9], vr[9], bp[6], an,
        hi[6], P[21], u[3], so[3], m_n0, m_ew, m_d2, m_std, mn[4], m_axis, m_bad;
} RX;

typedef char LN(
    rx_words_check)[sizeof(RX) == sizeof(imf_robust_state_t) / sizeof(imf_real) * sizeof(VR) ? 1
                                                                                             : -1];

/* imf_robust_consts_t of the group's lanes (a lane beyond p repeats lane 0) */
typedef struct {
    VR dt, two_dt, dt2, r_d, qg0, qg_dt, pgg0, inv_rate_ref2, inv_tau_bias, inv_tau_p, qb, tau_b0,
        tau_h0, bias_var0, bias_w2, ku_motion, rest_gyr2, rest_acc2, k_rest, kb_rest, k_mag, k_ref,
        k_acc, c48, mag_noise2, mag_lag2, mag_min2, t_max;
    VR tau_acc, tau_bias, tau_bias_rest, rest_gyr, rest_time, tau_rest, latency, tau_mag, mag_norm,
        mag_dip, tau_mag_ref, mag_new_time, mag_hold, gyr_bias_max;
    VM gbm;   /* gyr_bias_max > 0 */
    VM learn; /* mag_learn */
    VM lat;   /* latency > 0 */
} RL;

/* robust_set_dt's dt-dependent constants, per lane */
static inline void LN(rl_set_dt)(RL *const L, const VR dt)
{
    L->dt = dt;
    L->two_dt = IMF_R(2.0) * dt;
    L->dt2 = dt * dt;
    L->r_d = IMF_R(1.0) / dt;
    L->qg_dt = L->qg0 * dt;
    L->pgg0 = RSEL(L->gbm, L->r_d * (L->r_d * L->r_d),
                   IMF_R(1.0) / (L->tau_acc * L->tau_acc * L->tau_acc));
    L->k_rest = dt / (L->tau_rest + dt);
    L->kb_rest = dt / (L->tau_bias_rest + dt);
    L->ku_motion = L->inv_tau_bias * dt;
    L->k_mag = dt / (L->tau_mag + dt);
    L->k_ref = dt / (L->tau_mag_ref + dt);
    L->k_acc = dt / (L->tau_acc + dt);
}

/* imf_qmul, imf_qrotate (imf_math.h) */
static inline void LN(rl_qmul)(VR *const o, const VR a0, const VR a1, const VR a2, const VR a3,
                               const VR b0, const VR b1, const VR b2, const VR b3)
{
    o[0] = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3;
    o[1] = a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2;
    o[2] = a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1;
    o[3] = a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0;
}

static inline void LN(rl_qrotate)(VR *const o, const VR w, const VR x, const VR y, const VR z,
                                  const VR vx, const VR vy, const VR vz)
{
    const VR tx = IMF_R(2.0) * (y * vz - z * vy);
    const VR ty = IMF_R(2.0) * (z * vx - x * vz);
    const VR tz = IMF_R(2.0) * (x * vy - y * vx);
    o[0] = vx + w * tx + (y * tz - z * ty);
    o[1] = vy + w * ty + (z * tx - x * tz);
    o[2] = vz + w * tz + (x * ty - y * tx);
}

/* robust_axes: R(q)'s columns into o[9] */
static inline void LN(rl_axes)(VR *const o, const VR *const q)
{
    const VR xx = q[1] * q[1], yy = q[2] * q[2], zz = q[3] * q[3];
    const VR xy = q[1] * q[2], xz = q[1] * q[3], yz = q[2] * q[3];
    const VR wx = q[0] * q[1], wy = q[0] * q[2], wz = q[0] * q[3];
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

/* robust_norm4: the lanes where it succeeds (q normalised there, kept elsewhere) */
static inline VM LN(rl_norm4)(VR *const q)
{
    const VR n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    const VM ok = (n2 >= IMF_REAL_MIN) & (n2 <= IMF_REAL_MAX);
    const VR r = IMF_R(1.0) / LN(sqrt_r)(n2);
    int i;
    for (i = 0; i < 4; i++) {
        q[i] = RSEL(ok, q[i] * r, q[i]);
    }
    return ok;
}

/* robust_gain (the running mean's division only while some lane needs it) */
static inline VR LN(rl_gain)(const RL *const L, const VR t, const VR tau, const VR k)
{
    const VM early = t < tau;
    return LN(any)(early) ? RSEL(early, L->dt / (t + L->dt), k) : k;
}

/* robust_turn_by: o may be q */
static inline VM LN(rl_turn_by)(const RL *const L, VR *const o, const VR *const q,
                                const imf_real *const g, const VR *const b, const VR h)
{
    const VR ox = (g[0] - b[0]) * h;
    const VR oy = (g[1] - b[1]) * h;
    const VR oz = (g[2] - b[2]) * h;
    const VR th2 = ox * ox + oy * oy + oz * oz;
    const VR cw = IMF_R(1.0) - th2 * IMF_R(0.125);
    const VR sv = IMF_R(0.5) - th2 * L->c48;
    LN(rl_qmul)(o, q[0], q[1], q[2], q[3], cw, sv * ox, sv * oy, sv * oz);
    return LN(rl_norm4)(o);
}

/* robust_bias_clip */
static inline void LN(rl_bias_clip)(const RL *const L, VR *const b)
{
    const VR m = L->gyr_bias_max;
    int i;
    for (i = 0; i < 3; i++) {
        const VR c = RSEL(b[i] > m, m, RSEL(b[i] < -m, -m, b[i]));
        b[i] = RSEL(L->gbm, c, b[i]);
    }
}

/* robust_off2 */
static inline VR LN(rl_off2)(const VR v0, const VR v1, const VR v2, const VR b0, const VR b1,
                             const VR b2)
{
    const VR x = v0 - b0, y = v1 - b1, z = v2 - b2;
    return x * x + y * y + z * z;
}

/* robust_rest_mag for the lanes act, m not all zero: the lanes that pass */
static inline VM LN(rl_rest_mag)(const RL *const L, RX *const x, const imf_real *const m,
                                 const VR k, const VM act)
{
    const VR *const la = x->la;
    const VM lz = (x->lm[0] == IMF_R(0.0)) & (x->lm[1] == IMF_R(0.0)) & (x->lm[2] == IMF_R(0.0));
    const imf_real n2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
    const VR l2 = x->lm[0] * x->lm[0] + x->lm[1] * x->lm[1] + x->lm[2] * x->lm[2];
    const VM in = (n2 <= IMF_R(64.0) * l2) & (n2 * IMF_R(64.0) >= l2);
    const VM first = act & lz, upd = act & ~lz & in;
    VR d[3], a2, da, ma, m2, d2, h2, r;
    VM test;
    int i;
    for (i = 0; i < 3; i++) {
        const VR nl = x->lm[i] + k * (m[i] - x->lm[i]);
        x->lm[i] = RSEL(first, RB(m[i]), RSEL(upd, nl, x->lm[i]));
        x->l0[i] = RSEL(first, RB(m[i]), x->l0[i]);
    }
    d[0] = x->lm[0] - x->l0[0];
    d[1] = x->lm[1] - x->l0[1];
    d[2] = x->lm[2] - x->l0[2];
    a2 = la[0] * la[0] + la[1] * la[1] + la[2] * la[2];
    da = d[0] * la[0] + d[1] * la[1] + d[2] * la[2];
    ma = x->lm[0] * la[0] + x->lm[1] * la[1] + x->lm[2] * la[2];
    m2 = x->lm[0] * x->lm[0] + x->lm[1] * x->lm[1] + x->lm[2] * x->lm[2];
    d2 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * a2 - da * da;
    h2 = m2 * a2 - ma * ma;
    r = L->rest_gyr * x->t_rest;
    test =
        (d2 <= r * r * h2 + IMF_R(18.0) * L->mag_noise2 * k * (m2 * a2))
        & (LN(rl_off2)(x->lw[0], x->lw[1], x->lw[2], x->w0[0], x->w0[1], x->w0[2]) < L->rest_gyr2);
    return (lz | in) & ((x->t_dist > IMF_R(0.0)) | test);
}

/* robust_rest: the lanes at rest; *w2 the low-passed rate squared. m: NULL without a
   magnetometer reading */
static inline VM LN(rl_rest)(const RL *const L, RX *const x, const imf_real *const g,
                             const imf_real *const a, const imf_real *const m, const VM has_acc,
                             VR *const w2)
{
    const VR k = LN(rl_gain)(L, x->t, L->tau_rest, L->k_rest);
    const VR win = L->rest_gyr2 + L->bias_var0 * (x->bu * x->bu);
    const VR zero = RB(IMF_R(0.0));
    const VM ones = ~LN(zm)();
    VR bb[3], dx, dy, dz, d2, a2, tr;
    VM steady = ones, cond, rest;
    int i;
    for (i = 0; i < 3; i++) {
        bb[i] = RSEL(L->gbm, x->b[i], zero);
    }
    x->lw[0] = x->lw[0] + k * (g[0] - x->lw[0]);
    x->lw[1] = x->lw[1] + k * (g[1] - x->lw[1]);
    x->lw[2] = x->lw[2] + k * (g[2] - x->lw[2]);
    x->la[0] = RSEL(has_acc, x->la[0] + k * (a[0] - x->la[0]), x->la[0]);
    x->la[1] = RSEL(has_acc, x->la[1] + k * (a[1] - x->la[1]), x->la[1]);
    x->la[2] = RSEL(has_acc, x->la[2] + k * (a[2] - x->la[2]), x->la[2]);
    *w2 = x->lw[0] * x->lw[0] + x->lw[1] * x->lw[1] + x->lw[2] * x->lw[2];
    dx = a[0] - x->la[0];
    dy = a[1] - x->la[1];
    dz = a[2] - x->la[2];
    d2 = dx * dx + dy * dy + dz * dz;
    a2 = x->la[0] * x->la[0] + x->la[1] * x->la[1] + x->la[2] * x->la[2];
    if (m != NULL && LN(any)(L->gbm)) {
        steady = LN(rl_rest_mag)(L, x, m, k, L->gbm) | ~L->gbm;
    }
    cond = has_acc & (LN(rl_off2)(x->lw[0], x->lw[1], x->lw[2], bb[0], bb[1], bb[2]) < win)
           & (LN(rl_off2)(RB(g[0]), RB(g[1]), RB(g[2]), bb[0], bb[1], bb[2]) < win)
           & (d2 < L->rest_acc2 * a2) & steady;
    tr = x->t_rest + L->dt;
    tr = RSEL(tr > L->rest_time, L->rest_time, tr);
    x->t_rest = RSEL(cond, tr, zero);
    {
        const VM nw = (x->t_rest == IMF_R(0.0)) | (x->t < L->tau_rest);
        for (i = 0; i < 3; i++) {
            x->l0[i] = RSEL(nw, x->lm[i], x->l0[i]);
            x->w0[i] = RSEL(nw, x->lw[i], x->w0[i]);
        }
    }
    rest = x->t_rest >= L->rest_time;
    if (LN(any)(rest)) {
        const VR kb = L->kb_rest + x->bu * (L->k_rest - L->kb_rest);
        VR nb[3], pr;
        nb[0] = x->b[0] + kb * (g[0] - x->b[0]);
        nb[1] = x->b[1] + kb * (g[1] - x->b[1]);
        nb[2] = x->b[2] + kb * (g[2] - x->b[2]);
        LN(rl_bias_clip)(L, nb);
        for (i = 0; i < 3; i++) {
            x->b[i] = RSEL(rest, nb[i], x->b[i]);
        }
        /* B3's covariance learns with it */
        pr = kb * x->bu * L->tau_bias * L->inv_tau_p;
        pr = IMF_R(1.0) + pr / (IMF_R(1.0) + (IMF_R(1.0) - x->bu) * L->tau_bias * L->inv_tau_p);
        for (i = 0; i < 6; i++) {
            x->bp[i] = RSEL(rest, x->bp[i] / pr, x->bp[i]);
        }
        x->bu = RSEL(rest, x->bu - kb * x->bu, x->bu);
        {
            /* B2 at rest (robust_rest): B1's low-pass of the accelerometer, in I */
            const VM lv = rest & L->gbm;
            VR fr[3];
            LN(rl_qrotate)(fr, x->s[0], x->s[1], x->s[2], x->s[3], x->la[0], x->la[1], x->la[2]);
            for (i = 0; i < 3; i++) {
                x->f[i] = RSEL(lv, fr[i], x->f[i]);
                x->v[i] = RSEL(lv, zero, x->v[i]);
            }
        }
    }
    return rest;
}

/* robust_turn_lp, n values, in the lanes act */
static inline void LN(rl_turn_lp)(const RL *const L, VR *const d, VR *const v, const VR *const u,
                                  VR *const o, const int n, const VR kg, const VR kv, const VM act)
{
    const VR dt = L->dt;
    VR du, vp;
    int j;
    for (j = 0; j < n; j++) {
        du = u[j] * dt;
        vp = v[j] + dt * (d[j] + du);
        o[j] = RSEL(act, -(kg * vp) * L->r_d, o[j]);
        d[j] = RSEL(act, d[j] + du + kg * vp, d[j]);
        v[j] = RSEL(act, vp - kv * vp, v[j]);
    }
}

/* csrc/robust_b3.h's ROBUST_AN_MIN (the same value) */
#define ROBUST_AN_MIN IMF_R(1.0e-2)

/* robust_acc_noise (csrc/robust_b3.h) */
static inline void LN(rl_acc_noise)(const RL *const L, RX *const x, const VR *const ai,
                                    const VM first, const VM has_acc)
{
    const VM m = ~first & has_acc & L->gbm;
    if (LN(any)(m)) {
        const VR dx = ai[0] - x->f[0], dy = ai[1] - x->f[1], dz = ai[2] - x->f[2];
        const VR d2 = dx * dx + dy * dy + dz * dz;
        const VR den = L->rest_acc2 * (x->f[0] * x->f[0] + x->f[1] * x->f[1] + x->f[2] * x->f[2]);
        const VR e = RSEL(d2 < den, d2 / den, RB(IMF_R(1.0)));
        x->an = RSEL(m, x->an + L->k_acc * (e - x->an), x->an);
    }
    x->an = RSEL(first, RB(IMF_R(1.0)), x->an);
}

/* robust_an (csrc/robust_b3.h) */
static inline VR LN(rl_an)(const RX *const x)
{
    return RSEL(x->an > ROBUST_AN_MIN, x->an, RB(ROBUST_AN_MIN));
}

/* robust_gravity; hb[3], hr[9]: B2's model of the bias (0 where gravity is not updated or
   gyr_bias_max is 0) */
static inline void LN(rl_gravity)(const RL *const L, RX *const x, const imf_real *const a,
                                  const VM first, const VM has_acc, const VR w2, VR *const hb,
                                  VR *const hr)
{
    const VR dt = L->dt;
    const VR zero = RB(IMF_R(0.0));
    const VM kf = ~first & has_acc;
    VR ai[3], ri[9], rr, qg, ub, pvv, pvg, pgg, inv, kv, kg, v[3];
    int i;
    for (i = 0; i < 9; i++) {
        hr[i] = hb[i % 3] = zero;
    }
    LN(rl_qrotate)(ai, x->s[0], x->s[1], x->s[2], x->s[3], RB(a[0]), RB(a[1]), RB(a[2]));
    LN(rl_acc_noise)(L, x, ai, first, has_acc); /* B3's noise, before the update */
    if (LN(any)(kf)) {
        v[0] = x->v[0] + dt * (ai[0] - x->f[0]);
        v[1] = x->v[1] + dt * (ai[1] - x->f[1]);
        v[2] = x->v[2] + dt * (ai[2] - x->f[2]);
        rr = w2;
        if (LN(any)(x->bu > IMF_R(0.0))) {
            ub = L->tau_b0 / (L->tau_b0 + (IMF_R(1.0) - x->bu) * L->tau_bias);
            ub = RSEL(x->bu < ub, x->bu, ub);
            rr = RSEL(x->bu > IMF_R(0.0), rr + L->bias_w2 * (ub * ub), rr);
        }
        rr = rr * L->inv_rate_ref2;
        rr = RSEL(rr <= IMF_R(1.0e4), rr, RB(IMF_R(1.0e4)));
        qg = L->qg_dt + L->qg_dt * rr;
        pvv = x->pvv - L->two_dt * x->pvg + L->dt2 * x->pgg;
        pvg = x->pvg - dt * x->pgg;
        pgg = x->pgg + qg;
        inv = IMF_R(1.0) / (pvv + L->r_d);
        kv = pvv * inv;
        kg = pvg * inv;
        for (i = 0; i < 3; i++) {
            x->f[i] = RSEL(kf, x->f[i] - kg * v[i], x->f[i]);
            x->v[i] = RSEL(kf, v[i] - kv * v[i], x->v[i]);
        }
        x->pgg = RSEL(kf, pgg - kg * pvg, x->pgg);
        x->pvg = RSEL(kf, pvg - kv * pvg, x->pvg);
        x->pvv = RSEL(kf, pvv - kv * pvv, x->pvv);
        {
            const VM bm = kf & L->gbm;
            if (LN(any)(bm)) {
                VR rb[3];
                LN(rl_axes)(ri, x->s);
                for (i = 0; i < 3; i++) {
                    rb[i] = ri[i] * x->b[0] + ri[3 + i] * x->b[1] + ri[6 + i] * x->b[2];
                }
                LN(rl_turn_lp)(L, x->db, x->vb, rb, hb, 3, kg, kv, bm);
                LN(rl_turn_lp)(L, x->dr, x->vr, ri, hr, 9, kg, kv, bm);
            }
        }
    }
    if (LN(any)(first)) {
        for (i = 0; i < 9; i++) {
            x->dr[i] = RSEL(first, zero, x->dr[i]);
            x->vr[i] = RSEL(first, zero, x->vr[i]);
            x->db[i % 3] = RSEL(first, zero, x->db[i % 3]);
            x->vb[i % 3] = RSEL(first, zero, x->vb[i % 3]);
        }
        for (i = 0; i < 3; i++) {
            x->f[i] = RSEL(first, ai[i], x->f[i]);
            x->v[i] = RSEL(first, zero, x->v[i]);
        }
        x->pvv = RSEL(first, zero, x->pvv);
        x->pvg = RSEL(first, zero, x->pvg);
        x->pgg = RSEL(first, L->pgg0, x->pgg);
    }
}

/* robust_level: the lanes it rejects */
static inline VM LN(rl_level)(RX *const x, VR *const r)
{
    VR ge[3], gn, c[4];
    VM okr, rej;
    int i;
    LN(rl_qrotate)(ge, x->c[0], x->c[1], x->c[2], x->c[3], x->f[0], x->f[1], x->f[2]);
    gn = LN(sqrt_r)(ge[0] * ge[0] + ge[1] * ge[1] + ge[2] * ge[2]);
    r[0] = gn + ge[2];
    r[1] = ge[1];
    r[2] = -ge[0];
    r[3] = RB(IMF_R(0.0));
    okr = LN(rl_norm4)(r);
    rej = ~okr & ~((gn > IMF_R(0.0)) & (gn <= IMF_REAL_MAX));
    r[0] = RSEL(okr, r[0], RB(IMF_R(0.0)));
    r[1] = RSEL(okr, r[1], RB(IMF_R(1.0)));
    r[2] = RSEL(okr, r[2], RB(IMF_R(0.0)));
    c[0] = r[0] * x->c[0] - r[1] * x->c[1] - r[2] * x->c[2];
    c[1] = r[0] * x->c[1] + r[1] * x->c[0] + r[2] * x->c[3];
    c[2] = r[0] * x->c[2] - r[1] * x->c[3] + r[2] * x->c[0];
    c[3] = r[0] * x->c[3] + r[1] * x->c[2] - r[2] * x->c[1];
    rej |= ~LN(rl_norm4)(c);
    for (i = 0; i < 4; i++) {
        x->c[i] = c[i];
    }
    LN(rl_qmul)(x->q, c[0], c[1], c[2], c[3], x->s[0], x->s[1], x->s[2], x->s[3]);
    return rej;
}

/* robust_turn_div */
static inline VR LN(rl_turn_div)(const RL *const L, const RX *const x)
{
    const VR d =
        IMF_R(1.0)
        + LN(rl_off2)(x->lw[0], x->lw[1], x->lw[2], x->b[0], x->b[1], x->b[2]) * L->inv_rate_ref2;
    return d * d;
}

/* robust_bias_gain (td: robust_turn_div's value) */
static inline VR LN(rl_bias_gain)(const RL *const L, const RX *const x, const VR tau0, const VR td)
{
    const VR tm = (IMF_R(1.0) - x->bu) * L->tau_bias;
    const VR tau = RSEL(x->bu > IMF_R(0.0), RSEL(tm > tau0, tm, tau0), L->tau_bias);
    return RSEL(L->gbm, IMF_R(1.0) / (tau * td), L->inv_tau_bias);
}

/* robust_bias_from in the lanes act */
static inline void LN(rl_bias_from)(const RL *const L, RX *const x, const VR cx, const VR cy,
                                    const VR cz, const VR k, const VM act)
{
    VR e[3], nb[3];
    int i;
    LN(rl_qrotate)(e, x->q[0], -x->q[1], -x->q[2], -x->q[3], cx, cy, cz);
    nb[0] = x->b[0] - e[0] * k;
    nb[1] = x->b[1] - e[1] * k;
    nb[2] = x->b[2] - e[2] * k;
    LN(rl_bias_clip)(L, nb);
    for (i = 0; i < 3; i++) {
        x->b[i] = RSEL(act, nb[i], x->b[i]);
    }
}

/* robust_bias_row in the lanes act: h[0], h[3], h[6] the row */
static inline void LN(rl_bias_row)(RX *const x, const VR *const h, const VR y, const VR w,
                                   const VM act)
{
    static const unsigned char bi[3][3] = { { 0, 1, 2 }, { 1, 3, 4 }, { 2, 4, 5 } };
    VR *const p = x->bp;
    VR ph[3], ri, e, k;
    int i, j;
    for (i = 0; i < 3; i++) {
        ph[i] = p[bi[i][0]] * h[0] + p[bi[i][1]] * h[3] + p[bi[i][2]] * h[6];
    }
    ri = IMF_R(1.0) / (h[0] * ph[0] + h[3] * ph[1] + h[6] * ph[2] + w);
    e = (y - (h[0] * x->b[0] + h[3] * x->b[1] + h[6] * x->b[2])) * ri;
    for (i = 0; i < 3; i++) {
        x->b[i] = RSEL(act, x->b[i] + ph[i] * e, x->b[i]);
    }
    for (i = 0; i < 3; i++) {
        k = ph[i] * ri;
        for (j = i; j < 3; j++) {
            p[bi[i][j]] = RSEL(act, p[bi[i][j]] - k * ph[j], p[bi[i][j]]);
        }
    }
}

/* robust_bias: gyr_bias_max 0, the integral of the correction (robust_bias_from); else
   B3's Kalman filter from B2's model of the bias (hb, hr) */
static inline void LN(rl_bias)(const RL *const L, RX *const x, const VR *const r, const VM rest,
                               const VR *const hb, const VR *const hr)
{
    const VM cond = ~rest & (x->t >= L->tau_acc) & (L->inv_tau_bias > IMF_R(0.0));
    if (LN(any)(cond)) {
        const VR td = LN(rl_turn_div)(L, x);
        const VM kal = cond & L->gbm, integ = cond & ~L->gbm;
        VR bu = x->bu - L->ku_motion / td;
        bu = RSEL(bu < IMF_R(0.0), RB(IMF_R(0.0)), bu);
        x->bu = RSEL(cond & (x->bu > IMF_R(0.0)), bu, x->bu);
        if (LN(any)(integ)) {
            const VR k = LN(rl_bias_gain)(L, x, L->tau_b0, td);
            LN(rl_bias_from)(L, x, IMF_R(2.0) * r[1], IMF_R(2.0) * r[2], RB(IMF_R(0.0)), k, integ);
        }
        if (LN(any)(kal)) {
            VR y[3], h[9], kw, nb[3];
            int i;
            LN(rl_qrotate)(y, x->c[0], x->c[1], x->c[2], x->c[3], hb[0], hb[1], hb[2]);
            for (i = 0; i < 9; i += 3) {
                LN(rl_qrotate)
                (h + i, x->c[0], x->c[1], x->c[2], x->c[3], hr[i], hr[i + 1], hr[i + 2]);
            }
            kw = L->qb * L->dt; /* the random walk */
            x->bp[0] = RSEL(kal, x->bp[0] + kw, x->bp[0]);
            x->bp[3] = RSEL(kal, x->bp[3] + kw, x->bp[3]);
            x->bp[5] = RSEL(kal, x->bp[5] + kw, x->bp[5]);
            kw = LN(rl_turn_div)(L, x) * L->r_d * LN(rl_an)(x);
            LN(rl_bias_row)(x, h, y[0] - IMF_R(2.0) * r[1] * L->r_d, kw, kal);
            LN(rl_bias_row)(x, h + 1, y[1] - IMF_R(2.0) * r[2] * L->r_d, kw, kal);
            for (i = 0; i < 3; i++) {
                nb[i] = x->b[i];
            }
            LN(rl_bias_clip)(L, nb);
            for (i = 0; i < 3; i++) {
                x->b[i] = RSEL(kal, nb[i], x->b[i]);
            }
        }
    }
}

/* robust_step: the lanes it rejects. m: NULL without a magnetometer reading */
static inline VM LN(rl_step)(const RL *const L, RX *const x, const imf_real *const g,
                             const imf_real *const a, const imf_real *const m)
{
    const VM first = x->t == IMF_R(0.0);
    VM has_acc, rej, rest;
    VR w2, r[4], hb[3], hr[9];
    if (a[0] == IMF_R(0.0) && a[1] == IMF_R(0.0) && a[2] == IMF_R(0.0)) {
        has_acc = LN(zm)();
    } else {
        /* robust_acc_reading */
        const VR f2 = x->f[0] * x->f[0] + x->f[1] * x->f[1] + x->f[2] * x->f[2];
        has_acc = first | (a[0] * a[0] + a[1] * a[1] + a[2] * a[2] <= IMF_R(1.0e4) * f2);
    }
    rej = first & ~has_acc;
    rest = LN(rl_rest)(L, x, g, a, m, has_acc, &w2); /* B1 */
    {
        /* robust_strapdown */
        VR s[4];
        int i;
        rej |= ~LN(rl_turn_by)(L, s, x->s, g, x->b, L->dt);
        for (i = 0; i < 4; i++) {
            x->s[i] = s[i];
        }
    }
    LN(rl_gravity)(L, x, a, first, has_acc, w2, hb, hr); /* B2 */
    rej |= LN(rl_level)(x, r);
    LN(rl_bias)(L, x, r, rest, hb, hr); /* B3 */
    return rej;
}

/* ---- B6 */

/* robust_offset_axis per lane: axis ax (0, 1, 2 per lane), state xs, covariance mp */
static inline VR LN(rl_offset_axis)(VR *const mp, VR *const xs, const VM ax1, const VM ax2,
                                    const VR h0, const VR h1, const VR h2, const VR y, const VR rr)
{
    VR ph[6], kk[6], sv, nu, ri, pi3, xi;
    int j;
    for (j = 0; j < 6; j++) {
        const VR pa = mp[robust_pi[j][3]], pb = mp[robust_pi[j][4]], pc = mp[robust_pi[j][5]];
        pi3 = RSEL(ax1, pb, RSEL(ax2, pc, pa));
        ph[j] =
            mp[robust_pi[j][0]] * h0 + mp[robust_pi[j][1]] * h1 + mp[robust_pi[j][2]] * h2 + pi3;
    }
    pi3 = RSEL(ax1, ph[4], RSEL(ax2, ph[5], ph[3]));
    xi = RSEL(ax1, xs[4], RSEL(ax2, xs[5], xs[3]));
    sv = h0 * ph[0] + h1 * ph[1] + h2 * ph[2] + pi3 + rr;
    nu = y - (h0 * xs[0] + h1 * xs[1] + h2 * xs[2] + xi);
    ri = IMF_R(1.0) / sv;
    for (j = 0; j < 6; j++) {
        kk[j] = ph[j] * ri;
        xs[j] = xs[j] + kk[j] * nu;
    }
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
    return nu * nu * ri;
}

/* robust_offset_update in the lanes act (every lane: in place; some: on a copy, the
   other lanes keep theirs) */
static inline void LN(rl_offset_update)(const RL *const L, RX *const x, const VM ax1, const VM ax2,
                                        const VR *const c, const VR y, const imf_real g2,
                                        const VM act)
{
    VR Pc[21], hic[6], pb, rr, d2;
    const int every = LN(all)(act);
    VR *const P = every ? x->P : Pc;
    VR *const hi = every ? x->hi : hic;
    int k;
    if (!every) {
        for (k = 0; k < 21; k++) {
            P[k] = x->P[k];
        }
        for (k = 0; k < 6; k++) {
            hi[k] = x->hi[k];
        }
    }
    for (k = 0; k < 6; k++) {
        pb = P[robust_pi[k][k]] + (k < 3 ? ROBUST_MAG_QH : ROBUST_MAG_QO) * L->dt;
        if (k >= 3) {
            pb = RSEL((x->m_d2 > ROBUST_MAG_GATE) & (pb < ROBUST_MAG_P0), pb + ROBUST_MAG_JUMP, pb);
        }
        P[robust_pi[k][k]] = pb;
    }
    rr = g2 * L->mag_lag2;
    rr = RSEL(rr <= IMF_R(1.0), rr, RB(IMF_R(1.0)));
    rr = L->mag_noise2 + rr;
    d2 = LN(rl_offset_axis)(P, hi, ax1, ax2, c[0], c[1], c[2], y, rr);
    if (!every) {
        for (k = 0; k < 21; k++) {
            x->P[k] = RSEL(act, P[k], x->P[k]);
        }
        for (k = 0; k < 6; k++) {
            x->hi[k] = RSEL(act, hi[k], x->hi[k]);
        }
    }
    x->m_d2 = RSEL(act, d2, x->m_d2);
    x->m_ew = RSEL(act, x->m_ew + ROBUST_MAG_EW * (x->m_d2 - x->m_ew), x->m_ew);
    x->m_axis = RSEL(act, RSEL(ax2, RB(IMF_R(0.0)), x->m_axis + IMF_R(1.0)), x->m_axis);
}

/* robust_offset_start in the lanes act: returns 1 / n0 */
static inline VR LN(rl_offset_start)(RX *const x, const VR *const c, const VR o2, const VM act)
{
    const VR n0 = LN(sqrt_r)(o2);
    const VR inv = IMF_R(1.0) / n0;
    int k;
    x->m_n0 = RSEL(act, n0, x->m_n0);
    for (k = 0; k < 3; k++) {
        x->hi[k] = RSEL(act, c[k] * inv, x->hi[k]);
        x->hi[3 + k] = RSEL(act, x->u[k] * inv, x->hi[3 + k]);
    }
    for (k = 0; k < 21; k++) {
        x->P[k] = RSEL(act, RB(IMF_R(0.0)), x->P[k]);
    }
    for (k = 0; k < 6; k++) {
        x->P[robust_pi[k][k]] = RSEL(act, RB(ROBUST_MAG_P0), x->P[robust_pi[k][k]]);
    }
    x->m_ew = RSEL(act, RB(IMF_R(1.0)), x->m_ew);
    x->m_d2 = RSEL(act, RB(IMF_R(0.0)), x->m_d2);
    x->mn[0] = RSEL(act, RB(IMF_R(1.0)), x->mn[0]);
    x->mn[1] = RSEL(act, RB(IMF_R(0.0)), x->mn[1]);
    x->mn[2] = RSEL(act, RB(IMF_R(1.0)), x->mn[2]);
    x->mn[3] = RSEL(act, RB(IMF_R(0.0)), x->mn[3]);
    return inv;
}

/* robust_norm_lp in the lanes act */
static inline void LN(rl_norm_lp)(VR *const w, const imf_real *const m, const VR *const c,
                                  const VR s, const VR inv, const VR k, const VM act)
{
    VR n2 = RB(IMF_R(0.0)), d;
    int i;
    for (i = 0; i < 3; i++) {
        d = m[i] - c[i] * s;
        n2 = n2 + d * d;
    }
    d = LN(sqrt_r)(n2) * inv - w[0];
    w[0] = RSEL(act, w[0] + k * d, w[0]);
    w[1] = RSEL(act, w[1] + k * (d * d - w[1]), w[1]);
}

/* robust_offset_norms in the lanes act */
static inline void LN(rl_offset_norms)(const RL *const L, RX *const x, const imf_real *const m,
                                       const VR inv, const VM act)
{
    const VR e = IMF_R(1.0) - L->k_mag;
    const VR k3 = IMF_R(1.0) - e * e * e;
    LN(rl_norm_lp)(x->mn, m, x->u, RB(IMF_R(1.0)), inv, k3, act);
    LN(rl_norm_lp)(x->mn + 2, m, x->hi + 3, x->m_n0, inv, k3, act);
}

/* robust_offset_use in the lanes act */
static inline void LN(rl_offset_use)(const RL *const L, RX *const x, const VR inv, const VM act)
{
    VR pb = RB(IMF_R(0.0)), o2, d2, e, u[3];
    VM tr, upd, keep;
    int k;
    for (k = 3; k < 6; k++) {
        const VR p = x->P[robust_pi[k][k]];
        pb = RSEL(p > pb, p, pb);
    }
    x->m_std = RSEL(act, LN(sqrt_r)(pb), x->m_std);
    tr = act & (x->m_ew < ROBUST_MAG_MEAN);
    if (!LN(any)(tr)) {
        return;
    }
    o2 = RB(IMF_R(0.0));
    for (k = 0; k < 3; k++) {
        e = x->hi[3 + k] - x->so[k] * inv;
        o2 = o2 + e * e;
        u[k] = x->hi[3 + k] * x->m_n0;
    }
    keep = o2 < L->mag_min2;
    upd = tr
          & ((x->m_std < ROBUST_MAG_TRUST)
             | ((x->m_std < ROBUST_MAG_EARLY) & (x->u[0] == x->so[0]) & (x->u[1] == x->so[1])
                & (x->u[2] == x->so[2]) & (x->t_dist == IMF_R(0.0)) & (x->mn[1] > ROBUST_MAG_NORM2)
                & (ROBUST_MAG_BETTER2 * x->mn[3] < x->mn[1]) & ~keep));
    if (!LN(any)(upd)) {
        return;
    }
    d2 = RB(IMF_R(0.0));
    for (k = 0; k < 3; k++) {
        u[k] = RSEL(keep, x->so[k], u[k]);
        e = u[k] - x->u[k];
        d2 = d2 + e * e;
    }
    x->ref[0] = RSEL(upd & (d2 * (inv * inv) > ROBUST_MAG_RESET2), RB(IMF_R(0.0)), x->ref[0]);
    for (k = 0; k < 3; k++) {
        x->u[k] = RSEL(upd, u[k], x->u[k]);
    }
}

/* robust_offset (m not all zero) */
static inline void LN(rl_offset)(const RL *const L, RX *const x, const imf_real *const m,
                                 const imf_real g2)
{
    const VM ax1 = x->m_axis == IMF_R(1.0);
    const VM ax2 = ~ax1 & (x->m_axis == IMF_R(2.0));
    const VM ax0 = ~ax1 & ~ax2;
    const VM start = L->learn & (x->m_n0 == IMF_R(0.0));
    const VM run = L->learn & ~start;
    VR inv = RB(IMF_R(0.0)), e[3], c[3], o2;
    VM ok = LN(zm)(), upd = LN(zm)();
    int k;
    if (LN(any)(run)) {
        VM bad;
        inv = RSEL(run, IMF_R(1.0) / x->m_n0, inv);
        o2 = RB(IMF_R(0.0));
        for (k = 0; k < 3; k++) {
            o2 = o2 + (m[k] * inv) * (m[k] * inv);
        }
        bad = run & ~((o2 <= ROBUST_MAG_RANGE2) & (o2 * ROBUST_MAG_RANGE2 >= IMF_R(1.0)));
        upd = run & ~bad;
        if (LN(any)(bad)) {
            const VR mb = x->m_bad + L->dt;
            const VM rs = bad & (mb >= ROBUST_MAG_RESTART);
            x->m_bad = RSEL(bad, mb, x->m_bad);
            x->m_n0 = RSEL(rs, RB(IMF_R(0.0)), x->m_n0);
            x->m_bad = RSEL(rs, RB(IMF_R(0.0)), x->m_bad);
        }
        x->m_bad = RSEL(upd, RB(IMF_R(0.0)), x->m_bad);
    }
    if (LN(any)(upd)) {
        const VR one = RB(IMF_R(1.0)), zero = RB(IMF_R(0.0));
        e[0] = RSEL(ax0, one, zero);
        e[1] = RSEL(ax1, one, zero);
        e[2] = RSEL(ax2, one, zero);
        LN(rl_qrotate)(c, x->s[0], x->s[1], x->s[2], x->s[3], e[0], e[1], e[2]);
        LN(rl_offset_update)
        (L, x, ax1, ax2, c, RSEL(ax1, m[1] * inv, RSEL(ax2, m[2] * inv, m[0] * inv)), g2, upd);
        LN(rl_offset_norms)(L, x, m, inv, upd & ax2);
        ok = upd;
    }
    if (LN(any)(start)) {
        VM st;
        VR is;
        o2 = RB(IMF_R(0.0));
        for (k = 0; k < 3; k++) {
            e[k] = m[k] - x->u[k];
            o2 = o2 + e[k] * e[k];
        }
        st = start & (o2 >= IMF_REAL_MIN) & (o2 <= IMF_REAL_MAX);
        LN(rl_qrotate)(c, x->s[0], x->s[1], x->s[2], x->s[3], e[0], e[1], e[2]);
        is = LN(rl_offset_start)(x, c, o2, st);
        inv = RSEL(st, is, inv);
        ok |= st;
    }
    if (LN(any)(ok)) {
        LN(rl_offset_use)(L, x, inv, ok);
    }
}

/* robust_mag_test */
static inline VM LN(rl_mag_test)(const RL *const L, const VR *const fn, const VR *const rf)
{
    const VR dn = fn[0] - rf[0];
    const VR dd = fn[2] * rf[1] - fn[1] * rf[2];
    const VR tn = L->mag_norm * rf[0];
    return (dn < tn) & (-dn < tn) & (dd < L->mag_dip) & (-dd < L->mag_dip);
}

/* robust_field_used in the lanes act: the lanes that use the field */
static inline VM LN(rl_field_used)(const RL *const L, RX *const x, const VR *const fn, const VM act)
{
    const VM rz = act & (x->ref[0] == IMF_R(0.0));
    VM match, used, dist;
    VR to;
    int i;
    if (LN(any)(rz)) {
        for (i = 0; i < 3; i++) {
            x->ref[i] = RSEL(rz, fn[i], x->ref[i]);
            x->cand[i] = RSEL(rz, fn[i], x->cand[i]);
        }
        x->t_ok = RSEL(rz, L->mag_hold, x->t_ok);
    }
    match = LN(rl_mag_test)(L, fn, x->ref);
    to = x->t_ok + L->dt;
    to = RSEL(to > L->mag_hold, L->mag_hold, to);
    x->t_ok = RSEL(act, RSEL(match, to, RB(IMF_R(0.0))), x->t_ok);
    used = act & match & (x->t_ok >= L->mag_hold);
    dist = act & ~used;
    if (LN(any)(used)) {
        const VR k = LN(rl_gain)(L, x->t, L->tau_mag_ref, L->k_ref);
        x->t_dist = RSEL(used, RB(IMF_R(0.0)), x->t_dist);
        x->t_cand = RSEL(used, RB(IMF_R(0.0)), x->t_cand);
        for (i = 0; i < 3; i++) {
            x->ref[i] = RSEL(used, x->ref[i] + k * (fn[i] - x->ref[i]), x->ref[i]);
            x->cand[i] = RSEL(used, fn[i], x->cand[i]);
        }
    }
    if (LN(any)(dist)) {
        VM mc, nc, tc;
        VR c;
        x->t_dist = RSEL(dist, x->t_dist + L->dt, x->t_dist);
        mc = dist & LN(rl_mag_test)(L, fn, x->cand);
        nc = dist & ~mc;
        for (i = 0; i < 3; i++) {
            c = x->cand[i] + L->k_rest * (fn[i] - x->cand[i]);
            x->cand[i] = RSEL(mc, c, RSEL(nc, fn[i], x->cand[i]));
        }
        x->t_cand = RSEL(mc & (x->t_rest < L->rest_time), x->t_cand + L->dt, x->t_cand);
        tc = mc & (x->t_cand >= L->mag_new_time);
        for (i = 0; i < 3; i++) {
            x->ref[i] = RSEL(tc, x->cand[i], x->ref[i]);
        }
        x->t_cand = RSEL(tc | nc, RB(IMF_R(0.0)), x->t_cand);
    }
    return used;
}

/* robust_heading in the lanes act: the lanes it rejects */
static inline VM LN(rl_heading)(const RL *const L, RX *const x, const VR *const me, const VR mh,
                                const VM act)
{
    const VR ih = IMF_R(1.0) / mh;
    VR fw = IMF_R(1.0) + me[0] * ih;
    VR fz = -(me[1] * ih);
    const VR f2 = fw * fw + fz * fz;
    const VM big = f2 >= IMF_REAL_MIN;
    const VR fr = IMF_R(1.0) / LN(sqrt_r)(f2);
    VR k, zw, zz, z2, zr, c[4];
    VM ok, cond;
    int i;
    fw = RSEL(big, fw * fr, RB(IMF_R(0.0)));
    fz = RSEL(big, fz * fr, RB(IMF_R(1.0)));
    k = LN(rl_gain)(L, x->t, L->tau_mag, L->k_mag);
    zw = IMF_R(1.0) - k + k * fw;
    zz = k * fz;
    z2 = zw * zw + zz * zz;
    ok = z2 >= IMF_REAL_MIN;
    zr = IMF_R(1.0) / LN(sqrt_r)(z2);
    zw = zw * zr;
    zz = zz * zr;
    cond = act & (x->t >= L->tau_mag) & (L->inv_tau_bias > IMF_R(0.0)) & L->gbm
           & ~(x->t_rest >= L->rest_time)
           & (~L->learn | ((x->m_std < ROBUST_MAG_TRUST) & (x->m_ew < ROBUST_MAG_MEAN)));
    if (LN(any)(cond)) {
        const VR td = LN(rl_turn_div)(L, x);
        LN(rl_bias_from)
        (L, x, RB(IMF_R(0.0)), RB(IMF_R(0.0)), IMF_R(2.0) * zz,
         LN(rl_bias_gain)(L, x, L->tau_h0, td), cond);
    }
    c[0] = zw * x->c[0] - zz * x->c[3];
    c[1] = zw * x->c[1] - zz * x->c[2];
    c[2] = zw * x->c[2] + zz * x->c[1];
    c[3] = zw * x->c[3] + zz * x->c[0];
    for (i = 0; i < 4; i++) {
        x->c[i] = RSEL(act, c[i], x->c[i]);
    }
    {
        VR q[4];
        LN(rl_qmul)(q, c[0], c[1], c[2], c[3], x->s[0], x->s[1], x->s[2], x->s[3]);
        for (i = 0; i < 4; i++) {
            x->q[i] = RSEL(act, q[i], x->q[i]);
        }
    }
    return act & ~ok;
}

/* robust_magnetometer (m not all zero): the lanes it rejects */
static inline VM LN(rl_magnetometer)(const RL *const L, RX *const x, const imf_real *const m,
                                     const imf_real g2)
{
    VR me[3], h2, n2, mh, inv, fn[3];
    VM use, used;
    LN(rl_offset)(L, x, m, g2); /* B6 */
    LN(rl_qrotate)
    (me, x->q[0], x->q[1], x->q[2], x->q[3], m[0] - x->u[0], m[1] - x->u[1], m[2] - x->u[2]);
    h2 = me[0] * me[0] + me[1] * me[1];
    n2 = h2 + me[2] * me[2];
    use = (n2 >= IMF_REAL_MIN) & (n2 <= IMF_REAL_MAX);
    if (!LN(any)(use)) {
        return LN(zm)();
    }
    fn[0] = LN(sqrt_r)(n2);
    mh = LN(sqrt_r)(h2);
    inv = IMF_R(1.0) / fn[0];
    fn[1] = mh * inv;
    fn[2] = me[2] * inv;
    used = LN(rl_field_used)(L, x, fn, use) & (h2 >= IMF_REAL_MIN);
    if (!LN(any)(used)) {
        return LN(zm)();
    }
    return LN(rl_heading)(L, x, me, mh, used);
}

/* robust_output: the lanes it rejects */
static inline VM LN(rl_output)(const RL *const L, RX *const x, const imf_real *const g)
{
    VM rej = LN(zm)();
    if (LN(any)(L->lat)) {
        VR q[4];
        int i;
        rej = L->lat & ~LN(rl_turn_by)(L, q, x->q, g, x->b, L->latency);
        for (i = 0; i < 4; i++) {
            x->q[i] = RSEL(L->lat, q[i], x->q[i]);
        }
    }
    x->t = x->t + L->dt;
    x->t = RSEL(x->t > L->t_max, L->t_max, x->t);
    return rej;
}

#define RL_WORDS ((int)(sizeof(imf_robust_state_t) / sizeof(imf_real)))
#define RL_IMU_WORDS ((int)(offsetof(imf_robust_state_t, hi) / sizeof(imf_real)))

/* robust_finite of words w0..w1, per lane (w - w is 0 for a finite w, NaN otherwise, and
   a NaN stays in a sum: four sums, as the scalar commit, are 0 only if every word is finite) */
static inline VM LN(rl_finite)(const VR *const w, const int w0, const int w1)
{
    VR s0 = RB(IMF_R(0.0)), s1 = s0, s2 = s0, s3 = s0;
    int i;
    for (i = w0; i + 4 <= w1; i += 4) {
        s0 = s0 + (w[i] - w[i]);
        s1 = s1 + (w[i + 1] - w[i + 1]);
        s2 = s2 + (w[i + 2] - w[i + 2]);
        s3 = s3 + (w[i + 3] - w[i + 3]);
    }
    for (; i < w1; i++) {
        s0 = s0 + (w[i] - w[i]);
    }
    return (s0 + s1) + (s2 + s3) == IMF_R(0.0);
}

/* The group run: settings and state of f[0..p) into lanes, the samples, the state back. */
static int LN(robust_run)(void *const *f, const int p, const int ahrs, const ptrdiff_t k0,
                          const ptrdiff_t k1, const imf_real *gyr, const imf_real *acc,
                          const imf_real *mag, const imf_real *dts, const imf_scorer_t *sc,
                          imf_score_acc_t *accs, imf_real *const *out)
{
    RL L;
    RX X, x;
    VR *const xw = (VR *)&X;
    VR *const ww = (VR *)&x;
    VU skipped;
    VD sq[3], bad;
    ptrdiff_t k;
    int i, j;
    imf_robust_t *r[LW];
    if (p < 1 || p > LW) {
        return 0;
    }
    for (i = 0; i < LW; i++) {
        r[i] = (imf_robust_t *)f[i < p ? i : 0];
    }
    for (i = 0; i < LW; i++) {
        const imf_robust_consts_t *const s = &r[i]->set;
        const imf_real *const w = (const imf_real *)&r[i]->x;
        L.dt[i] = s->s.dt;
        L.two_dt[i] = s->two_dt;
        L.dt2[i] = s->dt2;
        L.r_d[i] = s->r_d;
        L.qg0[i] = s->qg0;
        L.qg_dt[i] = s->qg_dt;
        L.pgg0[i] = s->pgg0;
        L.inv_rate_ref2[i] = s->inv_rate_ref2;
        L.inv_tau_bias[i] = s->inv_tau_bias;
        L.inv_tau_p[i] = s->inv_tau_p;
        L.qb[i] = s->qb;
        L.tau_b0[i] = s->tau_b0;
        L.tau_h0[i] = s->tau_h0;
        L.bias_var0[i] = s->bias_var0;
        L.bias_w2[i] = s->bias_w2;
        L.ku_motion[i] = s->ku_motion;
        L.rest_gyr2[i] = s->rest_gyr2;
        L.rest_acc2[i] = s->rest_acc2;
        L.k_rest[i] = s->k_rest;
        L.kb_rest[i] = s->kb_rest;
        L.k_mag[i] = s->k_mag;
        L.k_ref[i] = s->k_ref;
        L.k_acc[i] = s->k_acc;
        L.c48[i] = s->c48;
        L.mag_noise2[i] = s->mag_noise2;
        L.mag_lag2[i] = s->mag_lag2;
        L.mag_min2[i] = s->mag_min2;
        L.t_max[i] = s->t_max;
        L.tau_acc[i] = s->s.tau_acc;
        L.tau_bias[i] = s->s.tau_bias;
        L.tau_bias_rest[i] = s->s.tau_bias_rest;
        L.rest_gyr[i] = s->s.rest_gyr;
        L.rest_time[i] = s->s.rest_time;
        L.tau_rest[i] = s->s.tau_rest;
        L.latency[i] = s->s.latency;
        L.tau_mag[i] = s->s.tau_mag;
        L.mag_norm[i] = s->s.mag_norm;
        L.mag_dip[i] = s->s.mag_dip;
        L.tau_mag_ref[i] = s->s.tau_mag_ref;
        L.mag_new_time[i] = s->s.mag_new_time;
        L.mag_hold[i] = s->s.mag_hold;
        L.gyr_bias_max[i] = s->s.gyr_bias_max;
        L.gbm[i] = s->s.gyr_bias_max > IMF_R(0.0) ? -1 : 0;
        L.learn[i] = ahrs && s->s.mag_learn ? -1 : 0;
        L.lat[i] = s->s.latency > IMF_R(0.0) ? -1 : 0;
        for (j = 0; j < RL_WORDS; j++) {
            xw[j][i] = w[j];
        }
    }
    x = X; /* the working copy: after each sample's commit it is the state again */
    skipped = (VU)LN(zm)();
    for (j = 0; j < 3; j++) {
        sq[j] = LN(zd)();
    }
    bad = LN(zd)();
    for (k = k0; k < k1; k++) {
        const imf_real *const g = gyr + 3 * k, *const a = acc + 3 * k;
        const imf_real *const m = ahrs ? mag + 3 * k : NULL;
        VM rej;
        if (dts) {
            LN(rl_set_dt)(&L, RB(dts[k]));
        }
        if (!(imf_finite3(g[0], g[1], g[2]) && imf_finite3(a[0], a[1], a[2])
              && (!ahrs || imf_finite3(m[0], m[1], m[2])))) {
            rej = ~LN(zm)();
        } else {
            const int has_m =
                ahrs && !(m[0] == IMF_R(0.0) && m[1] == IMF_R(0.0) && m[2] == IMF_R(0.0));
            VM ok;
            rej = LN(rl_step)(&L, &x, g, a, has_m ? m : NULL);
            if (has_m) {
                const imf_real g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
                rej |= LN(rl_magnetometer)(&L, &x, m, g2);
            }
            rej |= LN(rl_output)(&L, &x, g);
            /* robust_commit */
            ok = ~rej & LN(rl_finite)(ww, 0, RL_IMU_WORDS);
            if (ahrs) {
                ok &= ~L.learn | LN(rl_finite)(ww, RL_IMU_WORDS, RL_WORDS);
            }
            {
                /* the AHRS with B6 off never changes B6's words: all of them kept alike */
                const int n = ahrs ? RL_WORDS : RL_IMU_WORDS;
                if (LN(all)(ok)) {
                    memcpy(xw, ww, (size_t)n * sizeof(VR));
                } else {
                    for (j = 0; j < n; j++) {
                        ww[j] = xw[j] = RSEL(ok, ww[j], xw[j]);
                    }
                }
            }
            rej = ~ok;
        }
        skipped -= (VU)rej;
        if (out) {
            for (i = 0; i < p; i++) {
                imf_real *const o = out[i] + RL_WORDS * k;
                for (j = 0; j < RL_WORDS; j++) {
                    o[j] = xw[j][i];
                }
            }
        }
        if (sc) {
#ifdef IMF_DOUBLE
            LN(score)(sc, k, X.q[0], X.q[1], X.q[2], X.q[3], sq, &bad, accs, p);
#else
            LN(score)
            (sc, k, __builtin_convertvector(X.q[0], VD), __builtin_convertvector(X.q[1], VD),
             __builtin_convertvector(X.q[2], VD), __builtin_convertvector(X.q[3], VD), sq, &bad,
             accs, p);
#endif
        }
    }
    for (i = 0; i < p; i++) {
        imf_real *const w = (imf_real *)&r[i]->x;
        for (j = 0; j < RL_WORDS; j++) {
            w[j] = xw[j][i];
        }
        r[i]->skipped += (uint32_t)skipped[i];
        if (sc) {
            for (j = 0; j < 3; j++) {
                accs[i].sq[j] += sq[j][i];
            }
            accs[i].n_est_nan += bad[i];
        }
    }
    return 1;
}

static int LN(robust_imu)(void *const *f, int p, ptrdiff_t k0, ptrdiff_t k1, const imf_real *gyr,
                          const imf_real *acc, const imf_real *mag, const imf_real *dts,
                          const imf_scorer_t *sc, imf_score_acc_t *accs, imf_real *const *out)
{
    (void)mag;
    return LN(robust_run)(f, p, 0, k0, k1, gyr, acc, NULL, dts, sc, accs, out);
}

static int LN(robust_ahrs)(void *const *f, int p, ptrdiff_t k0, ptrdiff_t k1, const imf_real *gyr,
                           const imf_real *acc, const imf_real *mag, const imf_real *dts,
                           const imf_scorer_t *sc, imf_score_acc_t *accs, imf_real *const *out)
{
    return LN(robust_run)(f, p, 1, k0, k1, gyr, acc, mag, dts, sc, accs, out);
}

#undef RL_WORDS
#undef RL_IMU_WORDS
#undef RSEL
#undef RB
#undef RX
#undef RL
