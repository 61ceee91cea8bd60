/*
 * Hostile-input driver for every fixed-point filter of csrc/fixed (both
 * profiles), built by tests/test_sanitizers.py with
 * -fsanitize=address,undefined -fno-sanitize-recover=all. The contract
 * (docs/internals.md, numerical contract 6): no int16 input can cause undefined
 * behaviour. Inputs are random counts, the extremes -32768, -32767, -1, 0,
 * 1, 32767 and long constant stretches of them; an init that rejects its
 * constants is an error here (the parameters are the registry's).
 *
 * main(): `fixed_filters <samples per filter> <seed>`; with -DIMF_FUZZ a
 * libFuzzer target (the bytes choose filter, profile and the int16 samples).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "filters_1d_q.h"
#include "gravity_q.h"
#include "madgwick_q.h"
#include "mahony_q.h"

#define N_FIXED 6

typedef union {
    imf_complementary1d_q_t c1;
    imf_mahony1d_bias_q_t mb;
    imf_kk_q_t kk;
    imf_multiwii_q_t mw;
    imf_mahony_imu_q_t mi;
    imf_madgwick_imu_q_t gi;
} any_fixed_t;

static const char *const NAMES[N_FIXED] = {"Complementary1DQ", "Mahony1DBiasQ", "KKQ",
                                           "MultiWiiQ", "MahonyIMUQ", "MadgwickIMUQ"};

static int init_fixed(const int which, const int profile, any_fixed_t *const f)
{
    imf_mahony1d_bias_q_settings_t mb;
    imf_multiwii_q_settings_t mw;
    imf_mahony_imu_q_settings_t mi;
    memset(f, 0, sizeof *f);
    switch (which) {
    case 0: return imf_complementary1d_q_init(&f->c1, 0.002, 0.995, 1e-3, 1e-4);
    case 1:
        imf_mahony1d_bias_q_default_settings(&mb);
        mb.dt = 0.002;
        mb.ki = 0.2;
        mb.gyr_scale = 1e-3;
        return imf_mahony1d_bias_q_init(&f->mb, &mb);
    case 2: return imf_kk_q_init(&f->kk, 0.002, 0.002, 1.0642e-3);
    case 3:
        imf_multiwii_q_default_settings(&mw);
        mw.dt = 1.0 / 400;
        return imf_multiwii_q_init(&f->mw, &mw);
    case 4:
        imf_mahony_imu_q_default_settings(&mi);
        mi.dt = 1.0 / 512;
        mi.ki = 0.05;
        mi.profile = profile;
        return imf_mahony_imu_q_init(&f->mi, &mi);
    default: return imf_madgwick_imu_q_init(&f->gi, 1.0 / 512, 0.1, 1.0642e-3, profile);
    }
}

static void update_fixed(const int which, any_fixed_t *const f, const int16_t *const v)
{
    switch (which) {
    case 0: imf_complementary1d_q_update(&f->c1, v[0], v[1]); break;
    case 1: imf_mahony1d_bias_q_update(&f->mb, v[0], v[1]); break;
    case 2: imf_kk_q_update(&f->kk, v, v + 3); break;
    case 3: imf_multiwii_q_update(&f->mw, v, v + 3); break;
    case 4: imf_mahony_imu_q_update(&f->mi, v, v + 3); break;
    default: imf_madgwick_imu_q_update(&f->gi, v, v + 3); break;
    }
}

#ifdef IMF_FUZZ
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    any_fixed_t f;
    int16_t v[6];
    int which;
    if (size < 1) {
        return 0;
    }
    which = data[0] % N_FIXED;
    if (init_fixed(which, (data[0] / N_FIXED) % 2 ? 8 : 32, &f) != 0) {
        abort();
    }
    data++;
    size--;
    while (size >= sizeof v) {
        memcpy(v, data, sizeof v);
        update_fixed(which, &f, v);
        data += sizeof v;
        size -= sizeof v;
    }
    return 0;
}
#else
static uint64_t rng_state;

static uint64_t rng(void)
{
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return rng_state * UINT64_C(2685821657736338717);
}

int main(int argc, char **argv)
{
    static const int16_t extremes[] = {-32768, -32767, -1, 0, 1, 32767};
    const long n = argc > 1 ? atol(argv[1]) : 100000;
    int which, profile;
    rng_state = argc > 2 ? (uint64_t)atoll(argv[2]) | 1u : 88172645463325252u;
    for (which = 0; which < N_FIXED; which++) {
        for (profile = 8; profile <= 32; profile += 24) {
            any_fixed_t f;
            int16_t v[6];
            long k;
            int mode = 0, i;
            if (init_fixed(which, profile, &f) != 0) {
                fprintf(stderr, "%s/q%d: init rejected the registry parameters\n", NAMES[which],
                        profile);
                return 1;
            }
            for (k = 0; k < n; k++) {
                if (k % 500 == 0) {
                    mode = (int)(rng() % 3);   /* random, extremes, one constant extreme */
                    for (i = 0; i < 6; i++) {
                        v[i] = extremes[rng() % 6];
                    }
                }
                for (i = 0; i < 6 && mode != 2; i++) {
                    const uint64_t r = rng();
                    v[i] = mode == 0 ? (int16_t)(int32_t)(r % 65536u - 32768)
                                     : extremes[r % 6];
                }
                update_fixed(which, &f, v);
            }
            printf("%s/q%d: %ld samples\n", NAMES[which], profile, n);
        }
    }
    return 0;
}
#endif
