/* Fixed-point Mahony IMU filter; see mahony_q.h for the Q formats.
 * Mirrored line for line by python/imufuse/reference/fixed_mahony.py. */
#include "mahony_q.h"
#include "imf_fixed_init.h"
#include "imf_fixed_quat.h"

/* The 8-bit profile's constants from kg, kp, ki and hs in self (out of
 * line on AVR: fewer registers held across the calls of init_consts). */
static IMF_AVR_NOINLINE void imf_mahony_imu_q_init_p8(imf_mahony_imu_q_t *const self)
{
    const imf_qscale_t kp = self->kp;
    const int hs = self->hs;
    self->kg8 = imf_gain8(self->kg, 15 + hs);
    self->kp8 = imf_gain8(kp, hs);
    self->ki8 = imf_gain8(self->ki, 38 - 15);
    /* kp rounded to q38 for e in q15: imf_gain8's mantissa for the shift
     * kp.s - 7 >= 15 (kp.m 2, or kp.m rounded by kp.s - 23) */
    self->kpi = (uint16_t)(kp.s >= 22 ? imf_gain8(kp, 7).m : 0u);
    self->fast8 = (int16_t)(kp.s >= 22 && self->ki8.n == 16 && self->kg8.n == 16 && hs <= 6);
}

int imf_mahony_imu_q_init_consts(imf_mahony_imu_q_t *const self, const imf_qscale_t kg,
                                 const imf_qscale_t kp, const imf_qscale_t ki, const int profile)
{
    int i;
    /* kg: gyro full scale below 0.25 rad half angle per sample (s >= 31);
     * kp, ki: shifts of imf_scale16/32 in range */
    if (kg.m == 0 || !imf_qscale_ok(kg, 31, 61) || !imf_qscale_ok(kp, 16, 47)
        || !imf_qscale_ok(ki, 8, 54) || !imf_q_profile_ok(profile)) {
        return -1;
    }
    self->kg = kg;
    self->kp = kp;
    self->ki = ki;
    self->hs = imf_q_rate_exponent(kg);
    self->profile = (int16_t)(profile == 8 ? 8 : 32);
    self->x.q[0] = IMF_Q30_ONE;
    for (i = 0; i < 3; ++i) {
        self->x.q[i + 1] = self->x.i[i] = self->x.c[i] = 0;
    }
    if (IMF_Q_HAS_P8) {
        imf_mahony_imu_q_init_p8(self);
    } else {
        /* a build without the 8-bit profile (IMF_FIXED_PROFILE 32): its
         * constants are unused, left zero (no code linked to compute them) */
        self->kg8.m = self->kp8.m = self->ki8.m = self->kpi = 0u;
        self->kg8.n = self->kp8.n = self->ki8.n = self->fast8 = 0;
    }
    return 0;
}

void imf_mahony_imu_q_default_settings(imf_mahony_imu_q_settings_t *const settings)
{
    settings->dt = 0.01;
    settings->kp = 1.0;
    settings->ki = 0.0;
    settings->gyr_scale = 1.0642e-3;
    settings->profile = IMF_Q_DEFAULT_PROFILE;
}

int imf_mahony_imu_q_init(imf_mahony_imu_q_t *const self,
                          const imf_mahony_imu_q_settings_t *const s)
{
    const double dt = s->dt, kp = s->kp, ki = s->ki, gyr_scale = s->gyr_scale;
    const int profile = s->profile;
    const int r = imf_mahony_imu_q_init_consts(self, imf_qscale_from_double(0.5 * gyr_scale * dt),
                                               imf_qscale_from_double(0.5 * kp * dt),
                                               imf_qscale_from_double(0.5 * ki * dt * dt), profile);
    if (!(dt > 0.0) || !(gyr_scale > 0.0) || !(kp >= 0.0) || !(ki >= 0.0)) {
        return -1;
    }
    return r;
}

/* 32-bit profile: t + c in q46 -> q38 (floor), the low 8 bits kept in c
 * for the next sample.  The integral's component along gravity is not
 * observed (e = a x d is perpendicular to a): rounding each increment to
 * q38 on its own let that component walk (1.8e-6 rad/s after 10 minutes
 * of a slow rotation about the vertical, 0.1 deg of yaw); carried, the
 * sum of the increments is exact to one LSB of q46. */
static inline int32_t imf_mahony_imu_q_carry_i(const int32_t t, int32_t *const c)
{
    const int32_t u = imf_add_sat32(t, *c);
    *c = (int32_t)((uint32_t)u & 0xFFu);
    return imf_asr32(u, 8);
}

/* Appendix steps 2-6, 32-bit profile: h = 0.5 w' dt (q30).  Returns with
 * h holding the gyro term only when acc is the zero vector. */
static IMF_AVR_NOINLINE void imf_mahony_imu_q_feedback_p32(imf_mahony_imu_q_t *const self,
                                                           const int16_t qs[4],
                                                           const int16_t acc[3], int32_t h[3])
{
    imf_mahony_imu_q_state_t *const x = &self->x;
    int16_t a[3], d[3];
    int32_t e[3];
    int i;
    /* step 2: normalise a */
    if (!imf_q_normalise_acc(acc, a)) {
        return;
    }
    /* step 3: d = 2 (q1 q3 - q0 q2, q0 q1 + q2 q3, q0^2 + q3^2 - 1/2), q15;
     * symmetric q15 products < 2^30, so the q30 sums cannot overflow */
    d[0] = imf_qn_to_q15s(imf_mul_q15_q30(qs[1], qs[3]) - imf_mul_q15_q30(qs[0], qs[2]), 29);
    d[1] = imf_qn_to_q15s(imf_mul_q15_q30(qs[0], qs[1]) + imf_mul_q15_q30(qs[2], qs[3]), 29);
    d[2] = imf_qn_to_q15s(
        imf_mul_q15_q30(qs[0], qs[0]) + imf_mul_q15_q30(qs[3], qs[3]) - 536870912L, 29);
    /* step 4: e = a x d, q30 */
    e[0] = imf_mul_q15_q30(a[1], d[2]) - imf_mul_q15_q30(a[2], d[1]);
    e[1] = imf_mul_q15_q30(a[2], d[0]) - imf_mul_q15_q30(a[0], d[2]);
    e[2] = imf_mul_q15_q30(a[0], d[1]) - imf_mul_q15_q30(a[1], d[0]);
    for (i = 0; i < 3; ++i) {
        int32_t ip, pp;
        if (self->ki.s >= 31) {
            /* Ki dt e in q46 (|.| < 2^31 for |e| <= 2), its 8 bits below q38
             * carried to the next sample (imf_mahony_imu_q_carry_i) */
            ip = imf_mahony_imu_q_carry_i(imf_mul_32x16_s(e[i], self->ki.m, self->ki.s - 16),
                                          &x->c[i]);
        } else {
            ip = imf_scale32_s(e[i], self->ki, 30, 38);
        }
        pp = imf_scale32_s(e[i], self->kp, 30, 30);
        /* step 5: I_n = I_{n-1} + Ki dt e (as 0.5 I dt, q38) */
        x->i[i] = imf_add_sat32(x->i[i], ip);
        /* step 6: w' = w + Kp e + I_n (as 0.5 w' dt, q30) */
        h[i] = imf_add_sat32(imf_add_sat32(h[i], pp), imf_rshr32(x->i[i], 8));
    }
}

/* The same, 8-bit profile: a block-scaled with the short inverse sqrt; e
 * in q15, one 16x16 product per term with the gains prepared at init.
 * Short path (fast8): h in q(31+hs), Kp e + I summed in q38 and added to it
 * rounded once; otherwise h and Kp e in q(15+hs). */
IMF_Q_OUTLINE void imf_mahony_imu_q_feedback_p8(imf_mahony_imu_q_t *const self, const int16_t qs[4],
                                                const int16_t acc[3], int32_t h[3])
{
    imf_mahony_imu_q_state_t *const x = &self->x;
#if !defined(__AVR__)
    const imf_gain8_t ki8 = self->ki8, kp8 = self->kp8;
    const int hs = self->hs;
#endif
    int16_t a[3], d[3], e15[3];
    int i;
    /* step 2: normalise a (block-scaled, short inverse sqrt) */
    if (!imf_q_unit3_p8(acc, a)) {
        return;
    }
    /* step 3: d, q15; a loop on AVR (flash): d_i = u v + w z - k with
     * (u, v, w, z, k) = (q1, q3, -q0, q2, 0), (q0, q1, q2, q3, 0),
     * (q0, q0, q3, q3, 2^29): after step i, (v, w) = (u, z),
     * (u, z) = (q0, q3), k = i 2^29 */
#if defined(__AVR__)
    {
        int16_t u = qs[1], v = qs[3], w = (int16_t)-qs[0], z = qs[2];
        int32_t k = 0;
        for (i = 0; i < 3; ++i) {
            d[i] = imf_qn_to_q15s(imf_mul16(u, v) + imf_mul16(w, z) - k, 29);
            v = u;
            w = z;
            u = qs[0];
            z = qs[3];
            k = (int32_t)i * 536870912L;
        }
    }
#else
    d[0] = imf_qn_to_q15s(imf_mul16(qs[1], qs[3]) - imf_mul16(qs[0], qs[2]), 29);
    d[1] = imf_qn_to_q15s(imf_mul16(qs[0], qs[1]) + imf_mul16(qs[2], qs[3]), 29);
    d[2] = imf_qn_to_q15s(imf_mul16(qs[0], qs[0]) + imf_mul16(qs[3], qs[3]) - 536870912L, 29);
#endif
    /* step 4: e = a x d, rounded to q15; a loop on AVR (flash), unrolled
     * elsewhere */
#if defined(__AVR__)
    {
        int i1 = 1, i2 = 2;
        for (i = 0; i < 3; ++i) { /* (i1, i2) = (i + 1, i + 2) mod 3 */
            e15[i] = imf_qn_to_q15s(imf_mul16(a[i1], d[i2]) - imf_mul16(a[i2], d[i1]), 30);
            i1 = i2;
            i2 = i;
        }
    }
#else
    e15[0] = imf_qn_to_q15s(imf_mul16(a[1], d[2]) - imf_mul16(a[2], d[1]), 30);
    e15[1] = imf_qn_to_q15s(imf_mul16(a[2], d[0]) - imf_mul16(a[0], d[2]), 30);
    e15[2] = imf_qn_to_q15s(imf_mul16(a[0], d[1]) - imf_mul16(a[1], d[0]), 30);
#endif
    if (self->fast8) {
        /* steps 5, 6: Kp e + I summed in q38, rounded once to q(31+hs) */
        const uint16_t kpi = self->kpi;
#if defined(__AVR__)
        /* AVR: the gains read here, not held in registers through steps
         * 2-4 (fewer spills: faster, smaller) */
        const imf_gain8_t ki8 = self->ki8;
        const int hs = self->hs;
#endif
        for (i = 0; i < 3; ++i) {
            const int32_t ii = imf_add_sat32(x->i[i], imf_rshr32(imf_mul16su(e15[i], ki8.m), 16));
            const int32_t v = imf_add_sat32(ii, imf_mul16su(e15[i], kpi));
            x->i[i] = ii;
            h[i] = imf_add_sat32(h[i], imf_q_rshr_hs_p8(v, 7 - hs)); /* shift in [1, 7] */
        }
    } else {
#if defined(__AVR__)
        const imf_gain8_t ki8 = self->ki8, kp8 = self->kp8;
        const int hs = self->hs;
#endif
        for (i = 0; i < 3; ++i) {
            x->i[i] = imf_add_sat32(x->i[i], imf_gain8_mul(e15[i], ki8));
            h[i] = imf_add_sat32(imf_add_sat32(h[i], imf_gain8_mul(e15[i], kp8)),
                                 imf_rshr32(x->i[i], 23 - hs));
        }
    }
}

void imf_mahony_imu_q_update_p32(imf_mahony_imu_q_t *const self, const int16_t gyr[3],
                                 const int16_t acc[3])
{
    int32_t *const q = self->x.q;
    int32_t h[3], dq[4];
    int16_t qs[4];
    int i;
    imf_q_snapshot(q, qs);
    /* step 1: gyro counts -> half angle per sample, q30 */
    for (i = 0; i < 3; ++i) {
        h[i] = imf_scale16(gyr[i], self->kg, 30);
    }
    imf_mahony_imu_q_feedback_p32(self, qs, acc, h);
    /* step 7: q += 0.5 q (x) w' dt */
    imf_q_rate_p32(qs, h, dq);
    /* step 8 */
    imf_q_add_normalise(q, dq);
}

void imf_mahony_imu_q_update_p8(imf_mahony_imu_q_t *const self, const int16_t gyr[3],
                                const int16_t acc[3])
{
    int32_t *const q = self->x.q;
    int32_t *const c = self->x.c;
    const uint16_t m = self->kg8.m;
    int32_t h[3], dq[4];
    int16_t qs[4], d16;
    d16 = imf_q_snapshot_norm_p8(q, qs);
    /* step 1: kg8 has the shift 16 for every kg init accepts (kg.s in
     * [31, 61], hs = kg.s - 31 clamped to [0, 15], so kg.s - 15 - hs >= 16):
     * gyr m is h in q(31+hs) */
    if (self->fast8) {
        /* steps 2-6 on h in q(31+hs), then h to q(15+hs) with the remainder
         * carried */
#if defined(__AVR__)
        /* loops on AVR (flash), unrolled elsewhere */
        int i;
        for (i = 0; i < 3; ++i) {
            h[i] = imf_mul16su(gyr[i], m);
        }
        imf_mahony_imu_q_feedback_p8(self, qs, acc, h);
        for (i = 0; i < 3; ++i) {
            h[i] = imf_q_carry_p8(h[i], &c[i]);
        }
#else
        h[0] = imf_mul16su(gyr[0], m);
        h[1] = imf_mul16su(gyr[1], m);
        h[2] = imf_mul16su(gyr[2], m);
        imf_mahony_imu_q_feedback_p8(self, qs, acc, h);
        h[0] = imf_q_carry_p8(h[0], &c[0]);
        h[1] = imf_q_carry_p8(h[1], &c[1]);
        h[2] = imf_q_carry_p8(h[2], &c[2]);
#endif
    } else {
        /* h rounded to q(15+hs); steps 2-6 add Kp e and I rounded */
#if defined(__AVR__)
        int i;
        for (i = 0; i < 3; ++i) {
            h[i] = imf_gain8_mul(gyr[i], self->kg8); /* the same value, out of line (flash) */
        }
#else
        h[0] = imf_rshr32(imf_mul16su(gyr[0], m), 16);
        h[1] = imf_rshr32(imf_mul16su(gyr[1], m), 16);
        h[2] = imf_rshr32(imf_mul16su(gyr[2], m), 16);
#endif
        imf_mahony_imu_q_feedback_p8(self, qs, acc, h);
    }
    /* step 7 */
    imf_q_rate_p8(qs, h, self->hs, dq);
    imf_q_add_step_p8(q, dq, qs, d16);
}

void imf_mahony_imu_q_update_v(imf_mahony_imu_q_t *const self, const int16_t gyr[3],
                               const int16_t acc[3])
{
#if IMF_Q_HAS_P8 && IMF_Q_HAS_P32
    if (self->profile == 8) {
        imf_mahony_imu_q_update_p8(self, gyr, acc);
    } else {
        imf_mahony_imu_q_update_p32(self, gyr, acc);
    }
#elif IMF_Q_HAS_P8
    imf_mahony_imu_q_update_p8(self, gyr, acc);
#else
    imf_mahony_imu_q_update_p32(self, gyr, acc);
#endif
}
