/*
 * One instance of the lane kernels and the scoring, for LW lanes, named with the suffix
 * LSFX; included by lanes.c once per instruction set (see lanes.h). LSQRT_R / LSQRT_D, when
 * defined, are the instruction set's vector square roots of imf_real and double lanes;
 * otherwise each lane takes the C library's correctly rounded sqrt.
 *
 * The lane twin of csrc/madgwick.c (madgwick_* here is madgwick_* there; the gate is
 * imf_gate.h's own code); lanes_robust.h, included below, is that of csrc/robust.c. Every
 * line of a lane step is the line of the scalar update with the same operands in the same
 * order; where the scalar code branches on the state, both outcomes are computed and each
 * lane keeps its own (LN(sel_*)). Branches on the inputs alone are the same for every lane
 * and stay branches.
 */
#define LCAT2(a, b) a##_##b
#define LCAT(a, b) LCAT2(a, b)
#define LN(name) LCAT(name, LSFX)

#ifdef IMF_DOUBLE
typedef int64_t LN(vm) __attribute__((vector_size(LW * 8)));
typedef uint64_t LN(vu) __attribute__((vector_size(LW * 8)));
#else
typedef int32_t LN(vm) __attribute__((vector_size(LW * 4)));
typedef uint32_t LN(vu) __attribute__((vector_size(LW * 4)));
#endif
typedef imf_real LN(vr) __attribute__((vector_size(LW * sizeof(imf_real))));
typedef double LN(vd) __attribute__((vector_size(LW * 8)));
typedef int64_t LN(vmd) __attribute__((vector_size(LW * 8)));

#define VR LN(vr)
#define VD LN(vd)
#define VM LN(vm)
#define VU LN(vu)
#define VMD LN(vmd)

static inline VD LN(zd)(void)
{
    const VD z = {0};
    return z;
}

static inline VM LN(zm)(void)
{
    const VM z = {0};
    return z;
}

static inline VR LN(sqrt_r)(const VR x)
{
#ifdef LSQRT_R
    return (VR)LSQRT_R(x);
#else
    VR r;
    int i;
    for (i = 0; i < LW; i++) {
        r[i] = imf_sqrt(x[i]);
    }
    return r;
#endif
}

static inline VD LN(sqrt_d)(const VD x)
{
#ifdef LSQRT_D
    return (VD)LSQRT_D(x);
#else
    VD r;
    int i;
    for (i = 0; i < LW; i++) {
        r[i] = sqrt(x[i]);
    }
    return r;
#endif
}

static inline VR LN(sel_r)(const VM m, const VR a, const VR b)
{
    return (VR)(((VM)a & m) | ((VM)b & ~m));
}

static inline VD LN(sel_d)(const VMD m, const VD a, const VD b)
{
    return (VD)(((VMD)a & m) | ((VMD)b & ~m));
}

static inline int LN(any)(const VM m)
{
    int i, r = 0;
    for (i = 0; i < LW; i++) {
        r |= m[i] != 0;
    }
    return r;
}

/* 1/sqrt(x) per lane: imf_invsqrt's two forms, the same operations. */
static inline VR LN(invsqrt)(const VR x, const int mode)
{
    if (mode == IMF_INVSQRT_FAST) {
        const VR halfx = IMF_R(0.5) * x;
        VU i = (VU)x;
        VR y;
#ifdef IMF_DOUBLE
        i = UINT64_C(0x5fe6eb50c7b537a9) - (i >> 1);
#else
        i = UINT32_C(0x5f3759df) - (i >> 1);
#endif
        y = (VR)i;
        return y * (IMF_R(1.5) - halfx * y * y);
    }
    return IMF_R(1.0) / LN(sqrt_r)(x);
}

/* imf_inverse_norm per lane: the lanes where it is IMF_NORM_OK (r set), *tiny those where
   it is IMF_NORM_TINY (the rest are IMF_NORM_HUGE). */
static inline VM LN(inverse_norm)(const VR n2, const int mode, VR *const r, VM *const tiny)
{
    const VM notbig = n2 <= IMF_REAL_MAX;
    const VM tn = notbig & (n2 < IMF_REAL_MIN);
    const VR rr = LN(invsqrt)(n2, mode);
    *tiny = tn;
    *r = rr;
    return notbig & ~tn & (rr > IMF_R(0.0)) & (rr <= IMF_REAL_MAX);
}

static inline VM LN(finite_r)(const VR x)
{
    return (x - x) == IMF_R(0.0);
}

static inline VMD LN(finite_d)(const VD x)
{
    return (x - x) == 0.0;
}

/* ---- the scores (lanes.h): arctangent of x >= 0 (NaN stays NaN), Cephes' reduction and
   rational approximation (relative error about 1e-16) */
static inline VD LN(atan_pos)(const VD x)
{
    const VMD big = x > 2.41421356237309504880;  /* tan(3 pi/8) */
    const VMD mid = (x > 0.66) & ~big;
    const VD zero = LN(zd)();
    const VD y = LN(sel_d)(big, zero + 1.57079632679489661923,
                           LN(sel_d)(mid, zero + 0.785398163397448309616, zero));
    const VD xr = LN(sel_d)(big, -1.0 / x, LN(sel_d)(mid, (x - 1.0) / (x + 1.0), x));
    const VD z = xr * xr;
    const VD p = (((-8.750608600031904122785e-1 * z - 1.615753718733365076637e1) * z
                   - 7.500855792314704667340e1) * z - 1.228866684490136173410e2) * z
                 - 6.485021904942025371773e1;
    const VD q = ((((z + 2.485846490142306297962e1) * z + 1.650270098316988542046e2) * z
                   + 4.328810604912902668951e2) * z + 4.853903996359136964868e2) * z
                 + 1.945506571482613964425e2;
    VD t = z * p / q;
    t = xr * t + xr;
    t = t + LN(sel_d)(big, zero + 6.123233995736765886130e-17,
                      LN(sel_d)(mid, zero + 3.061616997868382943065e-17, zero));
    return y + t;
}

/* atan2(y, x) for y, x >= 0 (0 at y = 0, as numpy's arctan2(0, 0)) */
static inline VD LN(atan2_pos)(const VD y, const VD x)
{
    return LN(sel_d)(y == 0.0, LN(zd)(), LN(atan_pos)(y / x));
}

/* arccos(c) for 0 <= c <= 1: atan2(sqrt((1 - c)(1 + c)), c) */
static inline VD LN(acos_pos)(const VD c)
{
    return LN(atan2_pos)(LN(sqrt_d)((1.0 - c) * (1.0 + c)), c);
}

/* min(|x|, 1) with NaN kept (numpy's minimum) */
static inline VD LN(abs1)(const VD x)
{
    const VD a = LN(sel_d)(x < 0.0, -x, x);
    return LN(sel_d)(a > 1.0, LN(zd)() + 1.0, a);
}

/* Score sample k of the lanes' estimates w x y z (NWU, sensor-to-earth, any norm): the
   error quaternion e = q_ENU (x) r^-1, then either e_w, e_z stored (sc->store) or the
   squared errors summed into sq[0..2]; bad counts estimates that are not finite. */
static inline void LN(score)(const imf_scorer_t *const sc, const ptrdiff_t k, VD w, VD x, VD y,
                             VD z, VD sq[3], VD *const bad, imf_score_acc_t *const accs,
                             const int p)
{
    const double s = 0.70710678118654757; /* sqrt(0.5): NWU -> ENU, +90 deg about z */
    const double *const r = sc->r + 4 * k;
    const VD n2 = w * w + x * x + y * y + z * z;
    const VD n = LN(sqrt_d)(n2);
    VD a, b, c, d, m, ew, ez;
    VMD fin;
    int i;
    if (!sc->use[k]) {
        return;
    }
    w = w / n;
    x = x / n;
    y = y / n;
    z = z / n;
    fin = LN(finite_d)(w) & LN(finite_d)(x) & LN(finite_d)(y) & LN(finite_d)(z)
          & LN(finite_d)(n2) & (n2 > 1e-12);
    *bad = *bad + LN(sel_d)(fin, LN(zd)(), LN(zd)() + 1.0);
    a = s * w - s * z;
    b = s * x - s * y;
    c = s * y + s * x;
    d = s * z + s * w;
    /* evaluate() normalises again after the frame change (error_quaternion) */
    m = LN(sqrt_d)(a * a + b * b + c * c + d * d);
    a = a / m;
    b = b / m;
    c = c / m;
    d = d / m;
    ew = a * r[0] + b * r[1] + c * r[2] + d * r[3];
    ez = -a * r[3] - b * r[2] + c * r[1] + d * r[0];
    if (sc->store) {
        for (i = 0; i < p; i++) {
            imf_score_acc_t *const o = &accs[i];
            o->ew[o->j] = ew[i];
            o->ez[o->j] = ez[i];
            o->ok[o->j] = fin[i] != 0;
            o->j++;
        }
    } else {
        const double deg = 57.295779513082323; /* 180 / pi */
        const VD aw = LN(abs1)(ew);
        const VD az = LN(sel_d)(ez < 0.0, -ez, ez);
        const VD t = 2.0 * LN(acos_pos)(aw) * deg;
        const VD h = 2.0 * LN(atan2_pos)(az, LN(sel_d)(ew < 0.0, -ew, ew)) * deg;
        const VD c2 = 2.0 * LN(acos_pos)(LN(abs1)(LN(sqrt_d)(ew * ew + ez * ez))) * deg;
        sq[0] = sq[0] + t * t;
        sq[1] = sq[1] + h * h;
        sq[2] = sq[2] + c2 * c2;
    }
}

/* ---- Madgwick (csrc/madgwick.c), lane by lane */
#ifdef IMF_LANES_MADGWICK

/* Step 3: dq = 1/2 q (x) omega */
static inline void LN(madgwick_rate)(const VR q[4], const imf_real gx, const imf_real gy,
                               const imf_real gz, VR dq[4])
{
    dq[0] = IMF_R(0.5) * (-q[1] * gx - q[2] * gy - q[3] * gz);
    dq[1] = IMF_R(0.5) * (q[0] * gx + q[2] * gz - q[3] * gy);
    dq[2] = IMF_R(0.5) * (q[0] * gy - q[1] * gz + q[3] * gx);
    dq[3] = IMF_R(0.5) * (q[0] * gz + q[1] * gy - q[2] * gx);
}

/* Step 4, full form */
static inline void LN(madgwick_ds_full)(const VR qv[4], const imf_real ax, const imf_real ay,
                                  const imf_real az, VR s[4])
{
    const VR q0 = qv[0], q1 = qv[1], q2 = qv[2], q3 = qv[3];
    const VR two_q0 = IMF_R(2.0) * q0;
    const VR two_q1 = IMF_R(2.0) * q1;
    const VR two_q2 = IMF_R(2.0) * q2;
    const VR two_q3 = IMF_R(2.0) * q3;
    const VR four_q0 = IMF_R(4.0) * q0;
    const VR four_q1 = IMF_R(4.0) * q1;
    const VR four_q2 = IMF_R(4.0) * q2;
    const VR eight_q1 = IMF_R(8.0) * q1;
    const VR eight_q2 = IMF_R(8.0) * q2;
    const VR q0q0 = q0 * q0;
    const VR q1q1 = q1 * q1;
    const VR q2q2 = q2 * q2;
    const VR q3q3 = q3 * q3;
    s[0] = four_q0 * q2q2 + two_q2 * ax + four_q0 * q1q1 - two_q1 * ay;
    s[1] = four_q1 * q3q3 - two_q3 * ax + IMF_R(4.0) * q0q0 * q1 - two_q0 * ay - four_q1
           + eight_q1 * q1q1 + eight_q1 * q2q2 + four_q1 * az;
    s[2] = IMF_R(4.0) * q0q0 * q2 + two_q0 * ax + four_q2 * q3q3 - two_q3 * ay - four_q2
           + eight_q2 * q1q1 + eight_q2 * q2q2 + four_q2 * az;
    s[3] = IMF_R(4.0) * q1q1 * q3 - two_q1 * ax + IMF_R(4.0) * q2q2 * q3 - two_q2 * ay;
}

/* Step 4, simplified form */
static inline void LN(madgwick_ds_simplified)(const VR qv[4], const imf_real ax, const imf_real ay,
                                        const imf_real az, VR s[4])
{
    const VR q0 = qv[0], q1 = qv[1], q2 = qv[2], q3 = qv[3];
    const VR c = IMF_R(4.0) * (q1 * q1 + q2 * q2);
    s[0] = c * q0 + IMF_R(2.0) * (q2 * ax - q1 * ay);
    s[1] = c * q1 + IMF_R(2.0) * (-q3 * ax - q0 * ay + IMF_R(2.0) * q1 * az);
    s[2] = c * q2 + IMF_R(2.0) * (q0 * ax - q3 * ay + IMF_R(2.0) * q2 * az);
    s[3] = c * q3 + IMF_R(2.0) * (-q1 * ax - q2 * ay);
}

/* ds = J^T f for gravity and field (AHRS) */
static inline void LN(madgwick_ds_ahrs)(const VR qv[4], const imf_real ax, const imf_real ay,
                                  const imf_real az, const imf_real mx, const imf_real my,
                                  const imf_real mz, VR s[4])
{
    const VR q0 = qv[0], q1 = qv[1], q2 = qv[2], q3 = qv[3];
    const VR two_q0 = IMF_R(2.0) * q0;
    const VR two_q1 = IMF_R(2.0) * q1;
    const VR two_q2 = IMF_R(2.0) * q2;
    const VR two_q3 = IMF_R(2.0) * q3;
    const VR two_q0mx = two_q0 * mx;
    const VR two_q0my = two_q0 * my;
    const VR two_q0mz = two_q0 * mz;
    const VR two_q1mx = two_q1 * mx;
    const VR two_q0q2 = two_q0 * q2;
    const VR two_q2q3 = two_q2 * q3;
    const VR q0q0 = q0 * q0;
    const VR q0q1 = q0 * q1;
    const VR q0q2 = q0 * q2;
    const VR q0q3 = q0 * q3;
    const VR q1q1 = q1 * q1;
    const VR q1q2 = q1 * q2;
    const VR q1q3 = q1 * q3;
    const VR q2q2 = q2 * q2;
    const VR q2q3 = q2 * q3;
    const VR q3q3 = q3 * q3;
    VR hx, hy, two_bx, two_bz, four_bx, four_bz, f1, f2, f3, f4, f5, f6;
    hx = mx * q0q0 - two_q0my * q3 + two_q0mz * q2 + mx * q1q1 + two_q1 * my * q2 + two_q1 * mz * q3
         - mx * q2q2 - mx * q3q3;
    hy = two_q0mx * q3 + my * q0q0 - two_q0mz * q1 + two_q1mx * q2 - my * q1q1 + my * q2q2
         + two_q2 * mz * q3 - my * q3q3;
    two_bx = LN(sqrt_r)(hx * hx + hy * hy);
    two_bz = -two_q0mx * q2 + two_q0my * q1 + mz * q0q0 + two_q1mx * q3 - mz * q1q1
             + two_q2 * my * q3 - mz * q2q2 + mz * q3q3;
    four_bx = IMF_R(2.0) * two_bx;
    four_bz = IMF_R(2.0) * two_bz;
    f1 = IMF_R(2.0) * q1q3 - two_q0q2 - ax;
    f2 = IMF_R(2.0) * q0q1 + two_q2q3 - ay;
    f3 = IMF_R(1.0) - IMF_R(2.0) * q1q1 - IMF_R(2.0) * q2q2 - az;
    f4 = two_bx * (IMF_R(0.5) - q2q2 - q3q3) + two_bz * (q1q3 - q0q2) - mx;
    f5 = two_bx * (q1q2 - q0q3) + two_bz * (q0q1 + q2q3) - my;
    f6 = two_bx * (q0q2 + q1q3) + two_bz * (IMF_R(0.5) - q1q1 - q2q2) - mz;
    s[0] = -two_q2 * f1 + two_q1 * f2 - two_bz * q2 * f4 + (-two_bx * q3 + two_bz * q1) * f5
           + two_bx * q2 * f6;
    s[1] = two_q3 * f1 + two_q0 * f2 - IMF_R(4.0) * q1 * f3 + two_bz * q3 * f4
           + (two_bx * q2 + two_bz * q0) * f5 + (two_bx * q3 - four_bz * q1) * f6;
    s[2] = -two_q0 * f1 + two_q3 * f2 - IMF_R(4.0) * q2 * f3 + (-four_bx * q2 - two_bz * q0) * f4
           + (two_bx * q1 + two_bz * q3) * f5 + (two_bx * q0 - four_bz * q2) * f6;
    s[3] = two_q1 * f1 + two_q2 * f2 + (-four_bx * q3 + two_bz * q1) * f4
           + (-two_bx * q0 + two_bz * q2) * f5 + two_bx * q1 * f6;
}

/* The settings of the group's lanes (a lane beyond p repeats lane 0). */
typedef struct {
    VR beta, dt, lo2, hi2;
    VM gate;
    int mode, simplified;
} LN(madgwick_lanes_t);

/* One sample of every lane: madgwick_imu_step / madgwick_ahrs_step and madgwick_commit.
   Returns the lanes that rejected it. */
static inline VM LN(madgwick_step)(const LN(madgwick_lanes_t) *const L, const VR dt, VR q[4], const int ahrs,
                             const imf_real *const g, const imf_real *const a,
                             const imf_real *const m)
{
    const VM none = LN(zm)();
    VM rej = none, okq, tiny;
    VR dq[4], s[4], x[4], r;
    int i;
    const int use_mag = ahrs && !imf_is_zero3(m[0], m[1], m[2]);
    if (!(imf_finite3(g[0], g[1], g[2]) && imf_finite3(a[0], a[1], a[2])
          && (!ahrs || imf_finite3(m[0], m[1], m[2])))) {
        return ~none;
    }
    LN(madgwick_rate)(q, g[0], g[1], g[2], dq);
    if (!imf_is_zero3(a[0], a[1], a[2])) {
        /* imf_acc_gate_pass, lane by lane (imf_gate.h) */
        const imf_real n2a = imf_acc_gate_norm2(a[0], a[1], a[2]);
        const VM c = ~L->gate | IMF_ACC_GATE_IN(n2a, L->lo2, L->hi2, &);
        if (LN(any)(c)) {
            imf_real an[3], mn[3];
            int okn;
            an[0] = a[0];
            an[1] = a[1];
            an[2] = a[2];
            okn = imf_normalise3(&an[0], &an[1], &an[2], L->mode) == IMF_NORM_OK;
            if (okn && use_mag) {
                mn[0] = m[0];
                mn[1] = m[1];
                mn[2] = m[2];
                okn = imf_normalise3(&mn[0], &mn[1], &mn[2], L->mode) == IMF_NORM_OK;
            }
            if (!okn) {
                rej |= c;
            } else {
                VM oks;
                if (use_mag) {
                    LN(madgwick_ds_ahrs)(q, an[0], an[1], an[2], mn[0], mn[1], mn[2], s);
                } else if (L->simplified) {
                    LN(madgwick_ds_simplified)(q, an[0], an[1], an[2], s);
                } else {
                    LN(madgwick_ds_full)(q, an[0], an[1], an[2], s);
                }
                /* madgwick_feedback: normalise ds (a tiny one stays), reject an overflow */
                oks = LN(inverse_norm)(s[0] * s[0] + s[1] * s[1] + s[2] * s[2] + s[3] * s[3],
                                       L->mode, &r, &tiny);
                for (i = 0; i < 4; i++) {
                    s[i] = LN(sel_r)(oks, s[i] * r, s[i]);
                }
                rej |= c & ~oks & ~tiny;
                for (i = 0; i < 4; i++) {
                    dq[i] = LN(sel_r)(c, dq[i] - L->beta * s[i], dq[i]);
                }
            }
        }
    }
    /* madgwick_integrate */
    for (i = 0; i < 4; i++) {
        x[i] = q[i] + dq[i] * dt;
    }
    okq = LN(inverse_norm)(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3], L->mode, &r,
                           &tiny);
    for (i = 0; i < 4; i++) {
        x[i] = LN(sel_r)(okq, x[i] * r, x[i]);
    }
    /* madgwick_commit */
    okq = okq & ~rej & LN(finite_r)(x[0]) & LN(finite_r)(x[1]) & LN(finite_r)(x[2])
          & LN(finite_r)(x[3]);
    for (i = 0; i < 4; i++) {
        q[i] = LN(sel_r)(okq, x[i], q[i]);
    }
    return ~okq;
}

/* The group run: settings and state of f[0..p) into lanes, the samples, the state back. */
static int LN(madgwick_run)(void *const *f, const int p, const int ahrs, const ptrdiff_t k0,
                      const ptrdiff_t k1, const imf_real *gyr, const imf_real *acc,
                      const imf_real *mag, const imf_real *dts, const imf_scorer_t *sc,
                      imf_score_acc_t *accs, imf_real *const *out)
{
    LN(madgwick_lanes_t) L;
    VR q[4];
    VU skipped;
    VD sq[3], bad;
    ptrdiff_t k;
    int i, j;
    const imf_madgwick_consts_t *set[LW];
    imf_madgwick_state_t *x[LW];
    uint32_t *sk[LW];
    if (p < 1 || p > LW) {
        return 0;
    }
    for (i = 0; i < LW; i++) {
        void *const fi = f[i < p ? i : 0];
        imf_madgwick_t *const s = (imf_madgwick_t *)fi;
        set[i] = &s->set;
        x[i] = &s->x;
        sk[i] = &s->skipped;
    }
    L.mode = set[0]->invsqrt;
    L.simplified = !ahrs && set[0]->delta_s == IMF_MADGWICK_DS_SIMPLIFIED;
    for (i = 1; i < p; i++) {
        if (set[i]->invsqrt != L.mode
            || (!ahrs && (set[i]->delta_s == IMF_MADGWICK_DS_SIMPLIFIED) != L.simplified)) {
            return 0; /* code paths differ: not one group */
        }
    }
    for (i = 0; i < LW; i++) {
        L.beta[i] = set[i]->beta;
        L.dt[i] = set[i]->dt;
        L.lo2[i] = set[i]->acc_lo2;
        L.hi2[i] = set[i]->acc_hi2;
        L.gate[i] = set[i]->acc_gate ? -1 : 0;
        q[0][i] = x[i]->q0;
        q[1][i] = x[i]->q1;
        q[2][i] = x[i]->q2;
        q[3][i] = x[i]->q3;
    }
    skipped = (VU)LN(zm)();
    for (j = 0; j < 3; j++) {
        sq[j] = LN(zd)();
    }
    bad = LN(zd)();
    for (k = k0; k < k1; k++) {
        const VR d = dts ? (VR)LN(zm)() + dts[k] : L.dt;
        const VM rej = LN(madgwick_step)(&L, d, q, ahrs, gyr + 3 * k, acc + 3 * k,
                                   mag ? mag + 3 * k : gyr + 3 * k);
        skipped -= (VU)rej;
        if (out) {
            for (i = 0; i < p; i++) {
                imf_real *const o = out[i] + 4 * k;
                o[0] = q[0][i];
                o[1] = q[1][i];
                o[2] = q[2][i];
                o[3] = q[3][i];
            }
        }
        if (sc) {
#ifdef IMF_DOUBLE
            LN(score)(sc, k, q[0], q[1], q[2], q[3], sq, &bad, accs, p);
#else
            LN(score)(sc, k, __builtin_convertvector(q[0], VD), __builtin_convertvector(q[1], VD),
                      __builtin_convertvector(q[2], VD), __builtin_convertvector(q[3], VD), sq,
                      &bad, accs, p);
#endif
        }
    }
    for (i = 0; i < p; i++) {
        x[i]->q0 = q[0][i];
        x[i]->q1 = q[1][i];
        x[i]->q2 = q[2][i];
        x[i]->q3 = q[3][i];
        *sk[i] += (uint32_t)skipped[i];
        if (sc) {
            for (j = 0; j < 3; j++) {
                accs[i].sq[j] += sq[j][i];
            }
            accs[i].n_est_nan += bad[i];
        }
    }
    return 1;
}

static int LN(madgwick_imu)(void *const *f, int p, ptrdiff_t k0, ptrdiff_t k1,
                            const imf_real *gyr, const imf_real *acc, const imf_real *mag,
                            const imf_real *dts, const imf_scorer_t *sc, imf_score_acc_t *accs,
                            imf_real *const *out)
{
    (void)mag;
    return LN(madgwick_run)(f, p, 0, k0, k1, gyr, acc, NULL, dts, sc, accs, out);
}

static int LN(madgwick_ahrs)(void *const *f, int p, ptrdiff_t k0, ptrdiff_t k1,
                             const imf_real *gyr, const imf_real *acc, const imf_real *mag,
                             const imf_real *dts, const imf_scorer_t *sc, imf_score_acc_t *accs,
                             imf_real *const *out)
{
    return LN(madgwick_run)(f, p, 1, k0, k1, gyr, acc, mag, dts, sc, accs, out);
}
#endif /* IMF_LANES_MADGWICK */

/* ---- RobustIMU / RobustAHRS (csrc/robust.c): lanes_robust.h, its lane twin */
#ifdef IMF_LANES_ROBUST
#include "lanes_robust.h"
#endif

#undef VR
#undef VD
#undef VM
#undef VU
#undef VMD
#undef LN
#undef LCAT
#undef LCAT2
