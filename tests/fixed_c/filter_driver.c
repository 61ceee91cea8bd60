/* Test driver for the fixed-point filters of csrc/fixed: first line
 * "name profile p1 p2 ... ; s1 s2 ... ;" (parameters as C99 hex floats,
 * then an optional initial state, possibly empty), then one sample
 * per line (rate angle, or gx gy gz ax ay az); prints the int32 state
 * after every sample.  Built by tests/fixed_c/cbuild.py, also with UBSan. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "filters_1d_q.h"
#include "gravity_q.h"
#include "mahony_q.h"
#include "madgwick_q.h"

static void put(const int32_t *x, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        printf(i ? " %ld" : "%ld", (long)x[i]);
    }
    printf("\n");
}

int main(void)
{
    char name[64], tok[64];
    double p[8];
    int profile, np = 0, rc = -1;
    long v[6];
    int16_t g[3], a[3];
    imf_complementary1d_q_t c1;
    imf_mahony1d_bias_q_t m1;
    imf_kk_q_t kk;
    imf_multiwii_q_t mw;
    imf_mahony_imu_q_t mh;
    imf_madgwick_imu_q_t mg;
    if (scanf("%63s %d", name, &profile) != 2) return 2;
    while (np < 8 && scanf("%63s", tok) == 1 && strcmp(tok, ";") != 0) {
        p[np++] = strtod(tok, NULL);
    }
    if (!strcmp(name, "Complementary1DQ")) rc = imf_complementary1d_q_init(&c1, p[0], p[1], p[2], p[3]);
    else if (!strcmp(name, "Mahony1DBiasQ")) rc = imf_mahony1d_bias_q_init(&m1, p[0], p[1], p[2], (int)p[3], p[4], p[5]);
    else if (!strcmp(name, "KKQ")) rc = imf_kk_q_init(&kk, p[0], p[1], p[2]);
    else if (!strcmp(name, "MultiWiiQ")) rc = imf_multiwii_q_init(&mw, p[0], p[1], (int)p[2], p[3], p[4], p[5]);
    else if (!strcmp(name, "MahonyIMUQ")) rc = imf_mahony_imu_q_init(&mh, p[0], p[1], p[2], p[3], profile);
    else if (!strcmp(name, "MadgwickIMUQ")) rc = imf_madgwick_imu_q_init(&mg, p[0], p[1], p[2], profile);
    if (rc != 0) {
        fprintf(stderr, "init failed for %s\n", name);
        return 3;
    }
    {
        int32_t st[16];
        int ns = 0;
        while (ns < 16 && scanf("%63s", tok) == 1 && strcmp(tok, ";") != 0) {
            st[ns++] = (int32_t)strtol(tok, NULL, 10);
        }
        if (ns > 0) {
            if (!strcmp(name, "Complementary1DQ")) c1.x.theta = st[0];
            else if (!strcmp(name, "Mahony1DBiasQ")) { m1.x.theta = st[0]; m1.x.j = st[1]; }
            else if (!strcmp(name, "KKQ")) memcpy(kk.x.t, st, sizeof kk.x.t);
            else if (!strcmp(name, "MultiWiiQ")) { memcpy(mw.x.d, st, sizeof mw.x.d); memcpy(mw.x.l, st + 3, sizeof mw.x.l); }
            else if (!strcmp(name, "MahonyIMUQ")) memcpy(&mh.x, st, sizeof mh.x); /* q, i, c */
            else memcpy(&mg.x, st, sizeof mg.x);                                  /* q, c */
        }
    }
    if (!strcmp(name, "Complementary1DQ") || !strcmp(name, "Mahony1DBiasQ")) {
        while (scanf("%ld %ld", &v[0], &v[1]) == 2) {
            if (name[0] == 'C') { imf_complementary1d_q_update(&c1, (int16_t)v[0], (int16_t)v[1]); put(&c1.x.theta, 1); }
            else { int32_t s[2]; imf_mahony1d_bias_q_update(&m1, (int16_t)v[0], (int16_t)v[1]); s[0] = m1.x.theta; s[1] = m1.x.j; put(s, 2); }
        }
        return 0;
    }
    while (scanf("%ld %ld %ld %ld %ld %ld", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5]) == 6) {
        int i;
        for (i = 0; i < 3; ++i) { g[i] = (int16_t)v[i]; a[i] = (int16_t)v[3 + i]; }
        if (!strcmp(name, "KKQ")) { imf_kk_q_update(&kk, g, a); put(kk.x.t, 2); }
        else if (!strcmp(name, "MultiWiiQ")) { int32_t s6[6]; imf_multiwii_q_update(&mw, g, a); memcpy(s6, mw.x.d, sizeof mw.x.d); memcpy(s6 + 3, mw.x.l, sizeof mw.x.l); put(s6, 6); }
        else if (!strcmp(name, "MahonyIMUQ")) {
            int32_t s[10];
            imf_mahony_imu_q_update(&mh, g, a);
            memcpy(s, &mh.x, sizeof s); /* q, i, c: ten int32, no padding */
            put(s, 10);
        }
        else { int32_t s[7]; imf_madgwick_imu_q_update(&mg, g, a); memcpy(s, &mg.x, sizeof s); put(s, 7); }
    }
    return 0;
}
