/* Fixed-point Madgwick IMU filter; see madgwick_q.h for the Q formats.
 * Mirrored line for line by python/imufuse/reference/fixed_madgwick.py. */
#include "madgwick_q.h"
#include "imf_fixed_init.h"
#include "imf_fixed_quat.h"

int imf_madgwick_imu_q_init_consts(imf_madgwick_imu_q_t *const self, const imf_qscale_t kg,
                                   const imf_qscale_t kb, const int profile)
{
    self->kg = kg;
    self->kb = kb;
    self->hs = imf_q_rate_exponent(kg);
    self->profile = (int16_t)(profile == 8 ? 8 : 32);
    self->x.q[0] = IMF_Q30_ONE;
    self->x.q[1] = self->x.q[2] = self->x.q[3] = 0;
    if (kg.m == 0 || !imf_qscale_ok(kg, 31, 61) || !imf_qscale_ok(kb, 16, 46)) {
        return -1;
    }
    return 0;
}

int imf_madgwick_imu_q_init(imf_madgwick_imu_q_t *const self, const double dt, const double beta,
                            const double gyr_scale, const int profile)
{
    const int r = imf_madgwick_imu_q_init_consts(self, imf_qscale_from_double(0.5 * gyr_scale * dt),
                                                 imf_qscale_from_double(beta * dt), profile);
    if (!(dt > 0.0) || !(gyr_scale > 0.0) || !(beta >= 0.0)) {
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
static void imf_madgwick_imu_q_correct(const imf_madgwick_imu_q_t *const self, const int16_t qs[4],
                                       const int16_t acc[3], int32_t dq[4], const int narrow)
{
    int16_t a[3], s15[4];
    int32_t s[4], w;
    int16_t w15;
    uint32_t m = 0u, n2 = 0u, mag;
    uint16_t y;
    int sh, k, i;
    /* step 2: normalise a (8-bit profile: block-scaled, short inverse sqrt) */
    if (!(narrow ? imf_q8_unit3(acc, a) : imf_q_normalise_acc(acc, a))) {
        return;
    }
    /* step 4 (simplified): s = delta-s/2 = 2 (q1^2 + q2^2) q
     *   + (q2 ax - q1 ay, -q3 ax - q0 ay + 2 q1 az, q0 ax - q3 ay + 2 q2 az, -q1 ax - q2 ay),
     * every q15 x q15 product (q30) rounded to q28 */
    w = imf_mul_q15_q30(qs[1], qs[1]) + imf_mul_q15_q30(qs[2], qs[2]); /* < 2^31 */
    w15 = imf_sat_q15s(imf_rshr32(w, 15));                             /* q1^2+q2^2, q15 */
#define IMF_P2(a, b) imf_rshr32(imf_mul_q15_q30(a, b), 2) /* q28 */
#define IMF_P1(a, b) imf_rshr32(imf_mul_q15_q30(a, b), 1) /* 2 a b, q28 */
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
    if (narrow) {
        /* n2 in [2^28, 2^32): 1/sqrt(n2) ~= y 2^(e - 31), e in {0, 1} */
        y = imf_invsqrt8_u32(n2, &sh);
        sh = 31 - sh;
    } else {
        y = imf_invsqrt_u32(n2, &sh); /* n2 >= 2^28 -> sh >= 30 */
    }
    for (i = 0; i < 4; ++i) {
        /* unit delta-s, q15; |s15| < 2^15, y < 2^16: product fits int32 */
        const int32_t p = (int32_t)s15[i] * (int32_t)y;
        const int16_t u = imf_sat_q15s(!narrow ? imf_rshr32(p, sh - 15)
                                                : (sh == 30 ? imf_rshr32(p, 15) : imf_rshr32(p, 16)));
        /* step 6: dq' = dq - beta dt * unit delta-s, q30 */
        dq[i] = imf_sub_sat32(dq[i], imf_scale16(u, self->kb, 30 - 15));
    }
}

void imf_madgwick_imu_q32_update(imf_madgwick_imu_q_t *const self, const int16_t gyr[3],
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
    imf_q_rate32(qs, h, dq);
    imf_madgwick_imu_q_correct(self, qs, acc, dq, 0);
    /* steps 7, 8: q += dq'; normalise */
    imf_q_add_normalise(q, dq);
}

void imf_madgwick_imu_q8_update(imf_madgwick_imu_q_t *const self, const int16_t gyr[3],
                                const int16_t acc[3])
{
    int32_t *const q = self->x.q;
    int32_t h[3], dq[4];
    int16_t qs[4];
    int i;
    imf_q_snapshot(q, qs);
    for (i = 0; i < 3; ++i) {
        h[i] = imf_scale16(gyr[i], self->kg, 15 + self->hs); /* q(15+hs) */
    }
    imf_q8_rate(qs, h, self->hs, dq);
    imf_madgwick_imu_q_correct(self, qs, acc, dq, 1);
    imf_q8_add_normalise(q, dq);
}

void imf_madgwick_imu_q_update(imf_madgwick_imu_q_t *const self, const int16_t gyr[3],
                               const int16_t acc[3])
{
    if (self->profile == 8) {
        imf_madgwick_imu_q8_update(self, gyr, acc);
    } else {
        imf_madgwick_imu_q32_update(self, gyr, acc);
    }
}
