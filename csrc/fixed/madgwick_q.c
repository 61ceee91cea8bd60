/* Fixed-point Madgwick IMU filter; see madgwick_q.h for the Q formats.
 * Mirrored line for line by python/imufuse/reference/fixed_madgwick.py. */
#include "madgwick_q.h"
#include "imf_fixed_init.h"
#include "imf_fixed_quat.h"

int imf_madgwick_imu_q_init_consts(imf_madgwick_imu_q_t *const self, const imf_qscale_t kg,
                                   const imf_qscale_t kb, const int profile)
{
    int i;
    self->kg = kg;
    self->kb = kb;
    self->hs = imf_q_rate_exponent(kg);
    if (IMF_Q_HAS_P8) {
        self->kg8 = imf_gain8(kg, 15 + self->hs);
        /* largest multiple of 8 with kb.s - kbf >= 16 (kb.s in [16, 46]) */
        self->kbf = (int16_t)(kb.s < 16 ? 0 : ((kb.s - 16) / 8) * 8);
    } else { /* no 8-bit profile compiled in: its constants unused, zero */
        self->kg8.m = 0u;
        self->kg8.n = self->kbf = 0;
    }
    self->profile = (int16_t)(profile == 8 ? 8 : 32);
    self->x.q[0] = IMF_Q30_ONE;
    for (i = 0; i < 3; ++i) {
        self->x.q[i + 1] = self->x.c[i] = 0;
    }
    if (kg.m == 0 || !imf_qscale_ok(kg, 31, 61) || !imf_qscale_ok(kb, 16, 46)
        || !imf_q_profile_ok(profile)) {
        return -1;
    }
    return 0;
}

void imf_madgwick_imu_q_default_settings(imf_madgwick_imu_q_settings_t *const settings)
{
    settings->dt = 0.01;
    settings->beta = 0.1;
    settings->gyr_scale = 1.0642e-3;
    settings->profile = IMF_Q_DEFAULT_PROFILE;
}

int imf_madgwick_imu_q_init(imf_madgwick_imu_q_t *const self,
                            const imf_madgwick_imu_q_settings_t *const s)
{
    const int r =
        imf_madgwick_imu_q_init_consts(self, imf_qscale_from_double(0.5 * s->gyr_scale * s->dt),
                                       imf_qscale_from_double(s->beta * s->dt), s->profile);
    if (!(s->dt > 0.0) || !(s->gyr_scale > 0.0) || !(s->beta >= 0.0)) {
        return -1;
    }
    return r;
}

/* Number of bits of a non-negative int32 (0 for 0); shifts only. */
static int imf_bitlen32(uint32_t v)
{
    int n = 0;
    if (v >= 65536u) { /* byte steps first (8-bit targets shift bytes cheaply) */
        v >>= 16;
        n = 16;
    }
    if (v >= 256u) {
        v >>= 8;
        n += 8;
    }
    while (v != 0u) {
        v >>= 1;
        ++n;
    }
    return n;
}

/* Appendix steps 2, 4, 5, 6: dq -= beta dt * normalised delta-s.
 * Nothing happens for a zero accelerometer vector or a zero delta-s. */
static void imf_madgwick_imu_q_correct_p32(const imf_madgwick_imu_q_t *const self,
                                           const int16_t qs[4], const int16_t acc[3], int32_t dq[4])
{
    int16_t a[3], s15[4];
    int32_t s[4], w;
    int16_t w15;
    uint32_t m = 0u, n2 = 0u, mag;
    uint16_t y;
    int sh, k, i;
    /* step 2: normalise a */
    if (!imf_q_normalise_acc(acc, a)) {
        return;
    }
    /* step 4 (simplified): s = delta-s/2 = 2 (q1^2 + q2^2) q
     *   + (q2 ax - q1 ay, -q3 ax - q0 ay + 2 q1 az, q0 ax - q3 ay + 2 q2 az, -q1 ax - q2 ay),
     * every q15 x q15 product (q30) rounded to q28 */
    w = imf_mul_q15_q30(qs[1], qs[1]) + imf_mul_q15_q30(qs[2], qs[2]); /* < 2^31 */
    w15 = imf_qn_to_q15s(w, 30);                                       /* q1^2+q2^2, q15 */
#define IMF_P2(a, b) imf_rshr32(imf_mul_q15_q30(a, b), 2)              /* q28 */
#define IMF_P1(a, b) imf_rshr32(imf_mul_q15_q30(a, b), 1)              /* 2 a b, q28 */
    s[0] = imf_add_sat32(IMF_P1(w15, qs[0]), IMF_P2(qs[2], a[0]) - IMF_P2(qs[1], a[1]));
    s[1] = imf_add_sat32(IMF_P1(w15, qs[1]),
                         -IMF_P2(qs[3], a[0]) - IMF_P2(qs[0], a[1]) + IMF_P1(qs[1], a[2]));
    s[2] = imf_add_sat32(IMF_P1(w15, qs[2]),
                         IMF_P2(qs[0], a[0]) - IMF_P2(qs[3], a[1]) + IMF_P1(qs[2], a[2]));
    s[3] = imf_add_sat32(IMF_P1(w15, qs[3]), -IMF_P2(qs[1], a[0]) - IMF_P2(qs[2], a[1]));
#undef IMF_P2
#undef IMF_P1
    /* step 5: normalise s.  First a power-of-two scaling that puts the
     * largest component in [2^14, 2^15) (block floating point: the
     * direction keeps 15 bits even when s is tiny near convergence). */
    for (i = 0; i < 4; ++i) {
        mag = (s[i] < 0) ? 0u - (uint32_t)s[i] : (uint32_t)s[i];
        if (mag > m) {
            m = mag;
        }
    }
    if (m == 0u) {
        return;
    }
    k = imf_bitlen32(m) - 15; /* in [-14, 17] */
    for (i = 0; i < 4; ++i) {
        s15[i] = imf_sat_q15s(imf_rshift_sat32(s[i], k));
        n2 += (uint32_t)((int32_t)s15[i] * s15[i]); /* 4 * 32767^2 < 2^32 */
    }
    y = imf_invsqrt_u32(n2, &sh); /* n2 >= 2^28 -> sh >= 30 */
    for (i = 0; i < 4; ++i) {
        /* unit delta-s, q15; |s15| < 2^15, y < 2^16: product fits int32 */
        const int32_t p = (int32_t)s15[i] * (int32_t)y;
        const int16_t u = imf_sat_q15s(imf_rshr32(p, sh - 15));
        /* step 6: dq' = dq - beta dt * unit delta-s, q30 */
        dq[i] = imf_sub_sat32(dq[i], imf_scale16(u, self->kb, 30 - 15));
    }
}

/* The same, 8-bit profile: s = delta-s/2 in q29 (the products of two
 * terms rounded once), block-scaled in byte and bit steps (left shifts
 * only) to q15 with a constant rounding shift, and the step kb * s / |s|
 * as s15 * yk / 2^kbf with yk = y kb.m rounded to int16 once per update. */
IMF_Q_OUTLINE void imf_madgwick_imu_q_correct_p8(const imf_madgwick_imu_q_t *const self,
                                                 const int16_t qs[4], const int16_t acc[3],
                                                 int32_t dq[4])
{
    int16_t a[3], s15[4], w15;
    int32_t s[4];
    uint32_t m = 0u, n2 = 0u;
    uint16_t y, yk;
    int e, i;
    if (!imf_q_unit3_p8(acc, a)) {
        return;
    }
    /* |q1^2 + q2^2| < 2^31; each pair of products below < 2^31 */
    w15 = imf_qn_to_q15s(imf_mul16(qs[1], qs[1]) + imf_mul16(qs[2], qs[2]), 30);
    s[0] = imf_add_sat32(imf_mul16(w15, qs[0]),
                         imf_rshr32(imf_mul16(qs[2], a[0]) - imf_mul16(qs[1], a[1]), 1));
    s[1] = imf_add_sat32(imf_mul16(w15, qs[1]) + imf_mul16(qs[1], a[2]),
                         imf_rshr32(-imf_mul16(qs[3], a[0]) - imf_mul16(qs[0], a[1]), 1));
    s[2] = imf_add_sat32(imf_mul16(w15, qs[2]) + imf_mul16(qs[2], a[2]),
                         imf_rshr32(imf_mul16(qs[0], a[0]) - imf_mul16(qs[3], a[1]), 1));
    s[3] = imf_add_sat32(imf_mul16(w15, qs[3]),
                         imf_rshr32(-imf_mul16(qs[1], a[0]) - imf_mul16(qs[2], a[1]), 1));
    for (i = 0; i < 4; ++i) {
        m |= (s[i] < 0) ? 0u - (uint32_t)s[i] : (uint32_t)s[i]; /* top bit of the max */
    }
    if (m == 0u) {
        return;
    }
    if (m >= 2147483648u) {
        for (i = 0; i < 4; ++i) {
            s15[i] = imf_sat_q15s(imf_rshr32(s[i], 17));
        }
    } else {
        while (m < 4194304u) { /* 2^22: byte steps, |s| < 2^22 */
            m <<= 8;
            for (i = 0; i < 4; ++i) {
                s[i] *= 256;
            }
        }
        while (m < 1073741824u) { /* 2^30 */
            m <<= 1;
            for (i = 0; i < 4; ++i) {
                s[i] += s[i];
            }
        }
        for (i = 0; i < 4; ++i) {
            s15[i] = imf_qn_to_q15s(s[i], 31);
        }
    }
    for (i = 0; i < 4; ++i) {
        n2 += (uint32_t)imf_mul16(s15[i], s15[i]); /* [2^28, 4 2^30) */
    }
    y = imf_invsqrt8_u32(n2, &e); /* 1/|s15| ~= y 2^(e - 31) */
    /* step: s15 y kb.m 2^(e - 1 - kb.s) (q30) = s15 yk 2^-kbf with
     * yk = y kb.m 2^-(kb.s + 1 - e - kbf), a shift in [16, 24]: yk < 2^15 */
    yk = (uint16_t)imf_rshr32((int32_t)imf_mulu16(y, (uint16_t)self->kb.m),
                              self->kb.s + 1 - e - self->kbf);
    for (i = 0; i < 4; ++i) {
        const int32_t p = imf_mul16su(s15[i], yk); /* |p| < 2^30 */
        int32_t c;
        if (self->kbf == 0) {
            c = p;
        } else if (self->kbf == 8) {
            c = imf_rshr32(p, 8);
        } else if (self->kbf == 16) {
            c = imf_rshr32(p, 16);
        } else {
            c = imf_rshr32(p, 24);
        }
        dq[i] = imf_sub_sat32(dq[i], c);
    }
}

void imf_madgwick_imu_q_update_p32(imf_madgwick_imu_q_t *const self, const int16_t gyr[3],
                                   const int16_t acc[3])
{
    int32_t *const q = self->x.q;
    int32_t h[3], dq[4];
    int16_t qs[4];
    int i;
    imf_q_snapshot(q, qs);
    /* step 3: dq = 0.5 q (x) w dt, h = 0.5 w dt in q30 */
    for (i = 0; i < 3; ++i) {
        h[i] = imf_scale16(gyr[i], self->kg, 30);
    }
    imf_q_rate_p32(qs, h, dq);
    imf_madgwick_imu_q_correct_p32(self, qs, acc, dq);
    /* steps 7, 8: q += dq'; normalise */
    imf_q_add_normalise(q, dq);
}

void imf_madgwick_imu_q_update_p8(imf_madgwick_imu_q_t *const self, const int16_t gyr[3],
                                  const int16_t acc[3])
{
    int32_t *const q = self->x.q;
    int32_t *const c = self->x.c;
    const uint16_t m = self->kg8.m;
    int32_t h[3], dq[4];
    int16_t qs[4], d16;
    d16 = imf_q_snapshot_norm_p8(q, qs);
    /* step 3: h = 0.5 w dt in q(15+hs), from the product in q(31+hs) with
     * the remainder carried: kg8 has the shift 16 for every kg init accepts
     * (kg.s in [31, 61], hs = kg.s - 31 clamped to [0, 15], so
     * kg.s - 15 - hs >= 16) */
    h[0] = imf_q_carry_p8(imf_mul16su(gyr[0], m), &c[0]);
    h[1] = imf_q_carry_p8(imf_mul16su(gyr[1], m), &c[1]);
    h[2] = imf_q_carry_p8(imf_mul16su(gyr[2], m), &c[2]);
    imf_q_rate_p8(qs, h, self->hs, dq);
    imf_madgwick_imu_q_correct_p8(self, qs, acc, dq);
    imf_q_add_step_p8(q, dq, qs, d16);
}

void imf_madgwick_imu_q_update_v(imf_madgwick_imu_q_t *const self, const int16_t gyr[3],
                                 const int16_t acc[3])
{
#if IMF_Q_HAS_P8 && IMF_Q_HAS_P32
    if (self->profile == 8) {
        imf_madgwick_imu_q_update_p8(self, gyr, acc);
    } else {
        imf_madgwick_imu_q_update_p32(self, gyr, acc);
    }
#elif IMF_Q_HAS_P8
    imf_madgwick_imu_q_update_p8(self, gyr, acc);
#else
    imf_madgwick_imu_q_update_p32(self, gyr, acc);
#endif
}
