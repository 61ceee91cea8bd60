/*
 * Hostile-input driver for every float filter of csrc, built by
 * tests/test_sanitizers.py with -fsanitize=address,undefined
 * -fno-sanitize-recover=all (float32, and float64 with -DIMF_DOUBLE).
 *
 * Each filter is fed samples whose components are random, or picked from a
 * table of extremes (NaN, +-Inf, the largest and smallest normal and
 * subnormal numbers, -0, 1e30, a 1e6 rad/s gyro, ...), or raw random bit
 * patterns. After every update the C-level invariants of the valid-attitude
 * policy (csrc/imf_math.h) are checked: `skipped` grows by at most one; a
 * sample with a non-finite input is counted and leaves the state bytes
 * unchanged; the state is finite and a valid attitude (unit quaternion,
 * orthonormal R, gravity vector of valid length). A violation prints the
 * filter and sample and exits 1; the sanitizers abort on undefined
 * behaviour or a memory error.
 *
 * RobustIMU/AHRS (the recommended filter), the variometer (dt per sample) and
 * FusionAHRS (dt per sample) are driven the same way; their states mix other
 * members, so the state is compared as bytes and checked member by member.
 *
 * main(): `float_filters <samples per filter> <seed>`.
 * With -DIMF_FUZZ it is a libFuzzer target instead (LLVMFuzzerTestOneInput):
 * the input bytes choose the filter and its samples (raw bit patterns).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dcm.h"
#include "filters_1d.h"
#include "fusion_ahrs.h"
#include "kk.h"
#include "madgwick.h"
#include "mahony.h"
#include "mahony2d.h"
#include "multiwii.h"
#include "robust.h"
#include "vario.h"

#define N_FILTERS 20
enum { F_ROBUST_IMU = 16, F_ROBUST_AHRS = 17, F_VARIO = 18, F_FUSION = 19 };
/* the accelerometer gate (Nair 2016) on at 0.6 .. 1.4 g (the default settings: off) */
#define GATE_ON(s) ((s).acc_gate_lo = IMF_R(0.6), (s).acc_gate_hi = IMF_R(1.4))

typedef union {
    imf_complementary1d_t c1;
    imf_kalman1d_t k1;
    imf_mahony1d_t m1;
    imf_kalman1d_bias_t kb;
    imf_mahony1d_bias_t mb;
    imf_complementary1d_bias_t cb;
    imf_mahony_imu_t mi;
    imf_mahony_ahrs_t ma;
    imf_madgwick_imu_t gi;
    imf_madgwick_ahrs_t ga;
    imf_multiwii_t mw;
    imf_kk_t kk;
    imf_mahony2d_t m2;
    imf_dcm_t dc;
    imf_robust_imu_t ri;
    imf_robust_ahrs_t ra;
    imf_vario_t va;
    imf_fusion_ahrs_t fa;
} any_filter_t;

static const char *const NAMES[N_FILTERS] = {
    "Complementary1D", "Kalman1D", "Mahony1D", "Kalman1DBias", "Mahony1DBias",
    "Complementary1DBias", "MahonyIMU", "MahonyIMU-fast", "MahonyAHRS-gate", "MadgwickIMU",
    "MadgwickIMU-simplified-fast-gate", "MadgwickAHRS", "MultiWii", "KK", "Mahony2D-exact", "DCM",
    "RobustIMU", "RobustAHRS-latency", "VarioKF", "FusionAHRS-rejection"};

static void init_filter(const int which, any_filter_t *const f)
{
    memset(f, 0, sizeof *f);
    switch (which) {
    case 0: imf_complementary1d_init(&f->c1, IMF_R(0.01), IMF_R(0.98)); break;
    case 1: imf_kalman1d_init(&f->k1, IMF_R(0.01), IMF_R(0.02)); break;
    case 2: imf_mahony1d_init(&f->m1, IMF_R(0.01), IMF_R(2.0)); break;
    case 3: imf_kalman1d_bias_init(&f->kb, IMF_R(0.01), IMF_R(0.02), IMF_R(-0.5), -1); break;
    case 4: imf_mahony1d_bias_init(&f->mb, IMF_R(0.01), IMF_R(2.0), IMF_R(0.3), 0); break;
    case 5: imf_complementary1d_bias_init(&f->cb, IMF_R(0.01), IMF_R(2.0), IMF_R(0.3)); break;
    case 6: case 7: case 8: {
        imf_mahony_imu_settings_t s;
        imf_mahony_imu_default_settings(&s);
        s.dt = which == 8 ? IMF_R(0.01) : IMF_R(0.005);
        s.kp = which == 6 ? IMF_R(1.0) : which == 7 ? IMF_R(0.5) : IMF_R(2.0);
        s.ki = which == 6 ? IMF_R(0.3) : which == 7 ? IMF_R(0.0) : IMF_R(0.5);
        s.invsqrt = which == 6 ? IMF_INVSQRT_EXACT : IMF_INVSQRT_FAST;
        if (which == 8) {
            GATE_ON(s);
            imf_mahony_ahrs_init(&f->ma, &s);
        } else {
            imf_mahony_imu_init(&f->mi, &s);
        }
        break;
    }
    case 9: case 10: {
        imf_madgwick_imu_settings_t s;
        imf_madgwick_imu_default_settings(&s);
        s.dt = which == 9 ? IMF_R(0.01) : IMF_R(0.005);
        s.beta = which == 9 ? IMF_R(0.1) : IMF_R(0.3);
        if (which == 10) {
            s.delta_s = IMF_MADGWICK_DS_SIMPLIFIED;
            s.invsqrt = IMF_INVSQRT_FAST;
            GATE_ON(s);
        }
        imf_madgwick_imu_init(&f->gi, &s);
        break;
    }
    case 11: {
        imf_madgwick_ahrs_settings_t s;
        imf_madgwick_ahrs_default_settings(&s);
        imf_madgwick_ahrs_init(&f->ga, &s);
        break;
    }
    case 12: {
        imf_multiwii_settings_t s;
        imf_multiwii_default_settings(&s);
        s.dt = IMF_R(0.0025);
        s.acc_1g = IMF_R(512.0);
        imf_multiwii_init(&f->mw, &s);
        break;
    }
    case F_ROBUST_IMU: {
        imf_robust_imu_settings_t s;
        imf_robust_imu_default_settings(&s);
        imf_robust_imu_init(&f->ri, &s);
        break;
    }
    case F_ROBUST_AHRS: {
        imf_robust_ahrs_settings_t s;
        imf_robust_ahrs_default_settings(&s);
        s.dt = IMF_R(0.005);
        s.latency = IMF_R(0.002);
        s.rest_time = IMF_R(0.1);     /* reach the rest and magnetic branches quickly */
        s.mag_new_time = IMF_R(0.5);
        imf_robust_ahrs_init(&f->ra, &s);
        break;
    }
    case F_VARIO: {
        imf_vario_settings_t s;
        imf_vario_default_settings(&s);
        imf_vario_init(&f->va, &s);
        break;
    }
    case F_FUSION: {
        imf_fusion_ahrs_settings_t s;
        imf_fusion_ahrs_default_settings(&s);
        s.gain = IMF_R(0.5);
        s.gyroscope_range = IMF_R(2000.0);
        s.acceleration_rejection = IMF_R(10.0);
        s.magnetic_rejection = IMF_R(10.0);
        s.recovery_trigger_period = 50;
        imf_fusion_ahrs_init(&f->fa, &s, IMF_FUSION_INVSQRT_EXACT);
        break;
    }
    case 13: imf_kk_init(&f->kk, IMF_R(0.005), IMF_R(0.01)); break;
    case 14: imf_mahony2d_init(&f->m2, IMF_R(0.005), IMF_R(2.0), IMF_R(0.5), 1); break;
    default: imf_dcm_init(&f->dc, IMF_R(0.005), IMF_R(2.0), IMF_R(0.5)); break;
    }
}

/* the state member x (its bytes) and the counter of filter `which` */
static void parts(const int which, any_filter_t *const f, const imf_real **x, size_t *n,
                  uint32_t **skipped)
{
#define PART(m) do { *x = (const imf_real *)(const void *)&f->m.x; *n = sizeof f->m.x; \
                     *skipped = &f->m.skipped; } while (0)
    switch (which) {
    case F_ROBUST_IMU: PART(ri); break;
    case F_ROBUST_AHRS: PART(ra); break;
    case F_VARIO: PART(va); break;
    case F_FUSION: PART(fa); break;
    case 0: PART(c1); break;
    case 1: PART(k1); break;
    case 2: PART(m1); break;
    case 3: PART(kb); break;
    case 4: PART(mb); break;
    case 5: PART(cb); break;
    case 6: case 7: PART(mi); break;
    case 8: PART(ma); break;
    case 9: case 10: PART(gi); break;
    case 11: PART(ga); break;
    case 12: PART(mw); break;
    case 13: PART(kk); break;
    case 14: PART(m2); break;
    default: PART(dc); break;
    }
#undef PART
}

static void update(const int which, any_filter_t *const f, const imf_real *const v)
{
    switch (which) {
    case 0: imf_complementary1d_update(&f->c1, v[0], v[1]); break;
    case 1: imf_kalman1d_update(&f->k1, v[0], v[1]); break;
    case 2: imf_mahony1d_update(&f->m1, v[0], v[1]); break;
    case 3: imf_kalman1d_bias_update(&f->kb, v[0], v[1]); break;
    case 4: imf_mahony1d_bias_update(&f->mb, v[0], v[1]); break;
    case 5: imf_complementary1d_bias_update(&f->cb, v[0], v[1]); break;
    case 6: case 7: imf_mahony_imu_update(&f->mi, v[0], v[1], v[2], v[3], v[4], v[5]); break;
    case 8: imf_mahony_ahrs_update(&f->ma, v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]);
        break;
    case 9: case 10: imf_madgwick_imu_update(&f->gi, v[0], v[1], v[2], v[3], v[4], v[5]); break;
    case 11: imf_madgwick_ahrs_update(&f->ga, v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7],
                                      v[8]);
        break;
    case 12: imf_multiwii_update(&f->mw, v[0], v[1], v[2], v[3], v[4], v[5]); break;
    case 13: imf_kk_update(&f->kk, v[0], v[1], v[2], v[3], v[4], v[5]); break;
    case 14: imf_mahony2d_update(&f->m2, v[0], v[1], v[2], v[3], v[4], v[5]); break;
    case F_ROBUST_IMU: imf_robust_imu_update(&f->ri, v[0], v[1], v[2], v[3], v[4], v[5]); break;
    case F_ROBUST_AHRS: imf_robust_ahrs_update(&f->ra, v[0], v[1], v[2], v[3], v[4], v[5], v[6],
                                               v[7], v[8]);
        break;
    case F_VARIO: imf_vario_update(&f->va, v[0], v[1], v[2]); break;
    case F_FUSION: imf_fusion_ahrs_update(&f->fa, v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7],
                                          v[8], v[9]);
        break;
    default: imf_dcm_update(&f->dc, v[0], v[1], v[2], v[3], v[4], v[5]); break;
    }
}

static int n_inputs(const int which)
{
    switch (which) {
    case F_ROBUST_AHRS: return 9;
    case F_VARIO: return 3;
    case F_FUSION: return 10;   /* gyro deg/s, acc g, mag, dt */
    default: return which < 6 ? 2 : (which == 8 || which == 11) ? 9 : 6;
    }
}

static int unit4(const imf_real a, const imf_real b, const imf_real c, const imf_real d)
{
    const imf_real n2 = a * a + b * b + c * c + d * d;
    return n2 >= IMF_R(0.99) && n2 <= IMF_R(1.01);
}

/* RobustIMU/AHRS: q, s, c unit; variances, times and field norms not negative (the state
   writes' policy, imufuse.reference.robust) */
static int robust_valid(const imf_robust_state_t *const x)
{
    return unit4(x->q0, x->q1, x->q2, x->q3) && unit4(x->s0, x->s1, x->s2, x->s3)
           && unit4(x->c0, x->c1, x->c2, x->c3) && x->pvv >= IMF_R(0.0)
           && x->pgg >= IMF_R(0.0) && x->t >= IMF_R(0.0) && x->t_rest >= IMF_R(0.0)
           && x->rn >= IMF_R(0.0) && x->cn >= IMF_R(0.0) && x->t_cand >= IMF_R(0.0)
           && x->t_dist >= IMF_R(0.0) && x->t_ok >= IMF_R(0.0);
}

static imf_real sq3(const imf_real *const d)
{
    return d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
}

/* The valid-attitude invariant of the state x; 0 if violated. */
static int valid(const int which, const any_filter_t *const f, const imf_real *const x,
                 const size_t n)
{
    size_t i;
    if (which == F_FUSION) {   /* reals and int32 flags: the reals finite, q unit */
        const imf_fusion_ahrs_state_t *const s = &f->fa.x;
        const imf_real r[] = {s->q0, s->q1, s->q2, s->q3, s->acc_x, s->acc_y, s->acc_z,
                              s->ramped_gain, s->half_acc_fb_x, s->half_acc_fb_y,
                              s->half_acc_fb_z, s->half_mag_fb_x, s->half_mag_fb_y,
                              s->half_mag_fb_z};
        for (i = 0; i < sizeof r / sizeof r[0]; i++) {
            if (!isfinite(r[i])) {
                return 0;
            }
        }
        return unit4(s->q0, s->q1, s->q2, s->q3);
    }
    for (i = 0; i < n / sizeof(imf_real); i++) {
        if (!isfinite(x[i])) {
            return 0;
        }
    }
    if (which == F_ROBUST_IMU || which == F_ROBUST_AHRS) {
        return robust_valid(which == F_ROBUST_IMU ? &f->ri.x : &f->ra.x);
    }
    if (which == F_VARIO) {
        return 1;
    }
    if (which >= 6 && which <= 11) {
        const imf_real n2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3];
        return n2 >= IMF_R(0.99) && n2 <= IMF_R(1.01);
    }
    if (which == 12) {
        return sq3(x) >= IMF_REAL_MIN && sq3(x) <= f->mw.d2_max;
    }
    if (which == 14) { /* Eq. 4.3: d renormalised every update */
        return sq3(x) >= IMF_R(0.99) && sq3(x) <= IMF_R(1.01) && sq3(x) <= f->m2.d2_max;
    }
    if (which == 15) {
        const imf_real t = IMF_DCM_ORTHO_TOL;
        const imf_real *r = x;
        const imf_real nx = sq3(r), ny = sq3(r + 3), nz = sq3(r + 6);
        const imf_real xy = r[0] * r[3] + r[1] * r[4] + r[2] * r[5];
        return nx - IMF_R(1.0) <= t && IMF_R(1.0) - nx <= t && ny - IMF_R(1.0) <= t
               && IMF_R(1.0) - ny <= t && nz - IMF_R(1.0) <= t && IMF_R(1.0) - nz <= t
               && xy <= t && -xy <= t;
    }
    return 1;
}

/* One checked update; 0 (with a message) if an invariant failed. */
static int checked_update(const int which, any_filter_t *const f, const imf_real *const v,
                          const long k)
{
    const imf_real *x;
    size_t n, i;
    uint32_t *skipped, before;
    unsigned char old[sizeof(any_filter_t)];
    int finite = 1;
    parts(which, f, &x, &n, &skipped);
    memcpy(old, x, n);
    before = *skipped;
    for (i = 0; i < (size_t)n_inputs(which); i++) {
        finite = finite && isfinite(v[i]);
    }
    update(which, f, v);
    if (*skipped != before && *skipped != before + 1) {
        fprintf(stderr, "%s sample %ld: skipped jumped from %u to %u\n", NAMES[which], k,
                (unsigned)before, (unsigned)*skipped);
        return 0;
    }
    if (!finite && (*skipped != before + 1 || memcmp(old, x, n) != 0)) {
        fprintf(stderr, "%s sample %ld: a non-finite sample was not rejected\n", NAMES[which], k);
        return 0;
    }
    if (*skipped == before + 1 && memcmp(old, x, n) != 0) {
        fprintf(stderr, "%s sample %ld: a rejected sample changed the state\n", NAMES[which], k);
        return 0;
    }
    if (!valid(which, f, x, n)) {
        fprintf(stderr, "%s sample %ld: state is not a valid attitude\n", NAMES[which], k);
        return 0;
    }
    return 1;
}

#ifdef IMF_FUZZ
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    any_filter_t f;
    imf_real v[10];
    int which;
    long k = 0;
    size_t per;
    if (size < 1) {
        return 0;
    }
    which = data[0] % N_FILTERS;
    data++;
    size--;
    init_filter(which, &f);
    per = (size_t)n_inputs(which) * sizeof(imf_real);
    while (size >= per) {
        memcpy(v, data, per);   /* raw bit patterns: NaN, Inf, subnormals, anything */
        if (!checked_update(which, &f, v, k++)) {
            abort();
        }
        data += per;
        size -= per;
    }
    return 0;
}
#else
static uint64_t rng_state;

static uint64_t rng(void)
{
    /* xorshift64*: a reproducible stream from the seed */
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return rng_state * UINT64_C(2685821657736338717);
}

static imf_real uniform(void)
{
    return (imf_real)((double)(rng() >> 11) / 9007199254740992.0);
}

static imf_real pick(void)
{
    static const double extremes[] = {0.0, -0.0, 1e30, -1e30, 3.4e38, -3.4e38, 1e300, -1e300,
                                      1e-40, -1e-40, 5e-324, 1e-300, 1e6, -1e6, 2000.0, 1.0};
    const uint64_t r = rng();
    const int mode = (int)(r % 8);
    imf_real v;
    if (mode == 0) {
        switch ((r >> 8) % 3) {
        case 0: return (imf_real)NAN;
        case 1: return (imf_real)INFINITY;
        default: return -(imf_real)INFINITY;
        }
    }
    if (mode == 1) {
        return (imf_real)extremes[(r >> 8) % (sizeof extremes / sizeof extremes[0])];
    }
    if (mode == 2) {
        memcpy(&v, &r, sizeof v);   /* raw bits */
        return v;
    }
    return IMF_R(4.0) * uniform() - IMF_R(2.0);
}

int main(int argc, char **argv)
{
    const long n = argc > 1 ? atol(argv[1]) : 100000;
    int which;
    rng_state = argc > 2 ? (uint64_t)atoll(argv[2]) | 1u : 88172645463325252u;
    for (which = 0; which < N_FILTERS; which++) {
        any_filter_t f;
        imf_real v[10];
        long k;
        int burst = 0;
        init_filter(which, &f);
        for (k = 0; k < n; k++) {
            int i;
            /* alternate hostile bursts with sane stretches */
            if (k % 1000 == 0) {
                burst = (rng() % 2) != 0;
            }
            for (i = 0; i < 10; i++) {
                v[i] = burst ? pick() : IMF_R(0.2) * (uniform() - IMF_R(0.5));
            }
            if (!burst && which >= 6 && which != F_VARIO) {
                v[5] += IMF_R(1.0);                      /* gravity */
                if (which == 12) {
                    v[3] *= IMF_R(512.0);
                    v[4] *= IMF_R(512.0);
                    v[5] *= IMF_R(512.0);
                }
                if (which == F_ROBUST_AHRS || which == F_FUSION) {
                    v[6] += IMF_R(0.5);                  /* the earth's field */
                    v[8] -= IMF_R(0.8);
                }
                if (which == F_FUSION) {
                    v[9] = IMF_R(0.01);                  /* dt, s */
                }
            }
            if (!burst && which == F_VARIO) {
                v[0] *= IMF_R(100.0);                    /* cm/s^2 */
                v[1] = IMF_R(1000.0) + IMF_R(50.0) * v[1];   /* cm */
                v[2] = IMF_R(0.02);                      /* dt, s */
            }
            if (!checked_update(which, &f, v, k)) {
                return 1;
            }
        }
        printf("%s: %ld samples, %u rejected\n", NAMES[which], n, (unsigned)*(
            which == 0 ? &f.c1.skipped : which == 1 ? &f.k1.skipped : which == 2 ? &f.m1.skipped
            : which == 3 ? &f.kb.skipped : which == 4 ? &f.mb.skipped : which == 5 ? &f.cb.skipped
            : which <= 7 ? &f.mi.skipped : which == 8 ? &f.ma.skipped : which <= 10 ? &f.gi.skipped
            : which == 11 ? &f.ga.skipped : which == 12 ? &f.mw.skipped : which == 13 ? &f.kk.skipped
            : which == 14 ? &f.m2.skipped : which == 15 ? &f.dc.skipped
            : which == F_ROBUST_IMU ? &f.ri.skipped : which == F_ROBUST_AHRS ? &f.ra.skipped
            : which == F_VARIO ? &f.va.skipped : &f.fa.skipped));
    }
    return 0;
}
#endif
