/*
 * The lane kernels (lanes.h) for every instruction set this build can use, and the choice
 * among them at run time. Compiled once per precision, like csrc/ (imf_config.h).
 */
#include <stdlib.h>
#include <string.h>

#include "lanes.h"
#include "imf_math.h"
#include "madgwick.h"
#include "robust.h"

#define IMF_LANES_MADGWICK
#define IMF_LANES_ROBUST

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define IMF_LANES_X86 1
#include <immintrin.h>
#endif

/* one lane: the scalar path's scoring, and the kernels' reference width */
#define LW 1
#define LSFX w1
#include "lanes_body.h"
#undef LW
#undef LSFX

/* two lanes: SSE2 on x86-64, generic vectors elsewhere */
#define LW 2
#define LSFX w2
#ifdef IMF_LANES_X86
#define LSQRT_D(x) _mm_sqrt_pd((__m128d)(x))
#ifdef IMF_DOUBLE
#define LSQRT_R(x) _mm_sqrt_pd((__m128d)(x))
#endif
#endif
#include "lanes_body.h"
#undef LW
#undef LSFX
#undef LSQRT_D
#undef LSQRT_R

#ifdef IMF_LANES_X86
#pragma GCC push_options
#pragma GCC target("avx2")
#define LW 4
#define LSFX w4
#define LSQRT_D(x) _mm256_sqrt_pd((__m256d)(x))
#ifdef IMF_DOUBLE
#define LSQRT_R(x) _mm256_sqrt_pd((__m256d)(x))
#else
#define LSQRT_R(x) _mm_sqrt_ps((__m128)(x))
#endif
#include "lanes_body.h"
#undef LW
#undef LSFX
#undef LSQRT_D
#undef LSQRT_R
#pragma GCC pop_options

#pragma GCC push_options
#pragma GCC target("avx512f")
#define LW 8
#define LSFX w8
#define LSQRT_D(x) _mm512_sqrt_pd((__m512d)(x))
#ifdef IMF_DOUBLE
#define LSQRT_R(x) _mm512_sqrt_pd((__m512d)(x))
#else
#define LSQRT_R(x) _mm256_sqrt_ps((__m256)(x))
#endif
#include "lanes_body.h"
#undef LW
#undef LSFX
#undef LSQRT_D
#undef LSQRT_R
#pragma GCC pop_options
#endif

void imf_score_q(const imf_scorer_t *const sc, imf_score_acc_t *const acc, const ptrdiff_t k,
                 const double q[4])
{
    vd_w1 sq[3], bad;
    int j;
    for (j = 0; j < 3; j++) {
        sq[j][0] = 0.0;
    }
    bad[0] = 0.0;
    score_w1(sc, k, (vd_w1){q[0]}, (vd_w1){q[1]}, (vd_w1){q[2]}, (vd_w1){q[3]}, sq, &bad, acc, 1);
    for (j = 0; j < 3; j++) {
        acc->sq[j] += sq[j][0];
    }
    acc->n_est_nan += bad[0];
}

/* imufuse.shared.estimate's adapters, the same formulas (numpy's order where it matters) */
static void est_euler(const double roll, const double pitch, const double yaw, double q[4])
{
    const double hr = 0.5 * roll, hp = 0.5 * pitch, hy = 0.5 * yaw;
    const double cr = cos(hr), sr = sin(hr), cp = cos(hp), sp = sin(hp), cy = cos(hy),
                 sy = sin(hy);
    q[0] = cr * cp * cy + sr * sp * sy;
    q[1] = sr * cp * cy - cr * sp * sy;
    q[2] = cr * sp * cy + sr * cp * sy;
    q[3] = cr * cp * sy - sr * sp * cy;
}

void imf_estimate_q(const int adapter, const double *const s, const int *const idx, double q[4])
{
    if (adapter == IMF_EST_QUATERNION) {
        q[0] = s[idx[0]];
        q[1] = s[idx[1]];
        q[2] = s[idx[2]];
        q[3] = s[idx[3]];
    } else if (adapter == IMF_EST_GRAVITY) {
        const double ux = s[idx[0]], uy = s[idx[1]], uz = s[idx[2]];
        est_euler(atan2(uy, uz), atan2(-ux, hypot(uy, uz)), 0.0, q);
    } else if (adapter == IMF_EST_EULER) {
        est_euler(s[idx[0]], s[idx[1]], idx[2] >= 0 ? s[idx[2]] : 0.0, q);
    } else {
        /* rotation matrix, row-major (Shepperd's method, rotations.matrix_to_quat) */
        const double r00 = s[idx[0]], r01 = s[idx[1]], r02 = s[idx[2]], r10 = s[idx[3]],
                     r11 = s[idx[4]], r12 = s[idx[5]], r20 = s[idx[6]], r21 = s[idx[7]],
                     r22 = s[idx[8]];
        const double d[4] = {1.0 + r00 + r11 + r22, 1.0 + r00 - r11 - r22,
                             1.0 - r00 + r11 - r22, 1.0 - r00 - r11 + r22};
        double t, h, n;
        int i = 0, j;
        for (j = 1; j < 4; j++) {
            if (d[j] > d[i]) {
                i = j;
            }
        }
        t = sqrt(d[i] > 0.0 ? d[i] : 0.0);
        h = 0.5 / t;
        if (i == 0) {
            q[0] = t * t, q[1] = r21 - r12, q[2] = r02 - r20, q[3] = r10 - r01;
        } else if (i == 1) {
            q[0] = r21 - r12, q[1] = t * t, q[2] = r01 + r10, q[3] = r02 + r20;
        } else if (i == 2) {
            q[0] = r02 - r20, q[1] = r01 + r10, q[2] = t * t, q[3] = r12 + r21;
        } else {
            q[0] = r10 - r01, q[1] = r02 + r20, q[2] = r12 + r21, q[3] = t * t;
        }
        for (j = 0; j < 4; j++) {
            q[j] *= h;
        }
        if (q[0] < 0.0) {
            for (j = 0; j < 4; j++) {
                q[j] = -q[j];
            }
        }
        n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        for (j = 0; j < 4; j++) {
            q[j] /= n;
        }
    }
}

/* ---- dispatch */
static int cpu_width(void)
{
#ifdef IMF_LANES_X86
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f")) {
        return 8;
    }
    if (__builtin_cpu_supports("avx2")) {
        return 4;
    }
#endif
    return 2;
}

int imf_lanes_best(void)
{
    return cpu_width();
}

const char *imf_lanes_isa(const int width)
{
#ifdef IMF_LANES_X86
    return width == 8 ? "avx512f" : width == 4 ? "avx2" : width == 2 ? "sse2" : "scalar";
#else
    return width == 2 ? "generic" : "scalar";
#endif
}

typedef struct {
    const char *c_update; /* the scalar update the kernel runs lane by lane */
    imf_lanes_fn fn[4]; /* widths 1, 2, 4, 8 */
} kernel_t;

#ifdef IMF_LANES_X86
#define KERNELS(f) {f##_w1, f##_w2, f##_w4, f##_w8}
#else
#define KERNELS(f) {f##_w1, f##_w2, NULL, NULL}
#endif

static const kernel_t kernels[] = {
    {"imf_madgwick_update_imu", KERNELS(madgwick_imu)},
    {"imf_madgwick_update", KERNELS(madgwick_ahrs)},
    {"imf_robust_update_imu", KERNELS(robust_imu)},
    {"imf_robust_update", KERNELS(robust_ahrs)},
};

imf_lanes_fn imf_lanes_kernel(const char *const c_update, const int width)
{
    size_t i;
    const int slot = width == 1 ? 0 : width == 2 ? 1 : width == 4 ? 2 : width == 8 ? 3 : -1;
    if (slot < 0 || width > cpu_width()) {
        return NULL;
    }
    for (i = 0; i < sizeof kernels / sizeof kernels[0]; i++) {
        if (strcmp(kernels[i].c_update, c_update) == 0) {
            return kernels[i].fn[slot];
        }
    }
    return NULL;
}
