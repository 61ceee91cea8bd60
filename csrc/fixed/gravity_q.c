/* Fixed-point KK and MultiWii filters; see gravity_q.h for the Q formats.
 * Mirrored line for line by python/imufuse/reference/fixed_gravity.py. */
#include "gravity_q.h"
#include "imf_fixed_init.h"

int imf_kk_q_init(imf_kk_q_t *const self, const double dt, const double kp, const double gyr_scale,
                  const double acc_1g)
{
    self->kw = imf_qscale_from_double(gyr_scale * dt);
    self->ka = imf_qscale_from_double(acc_1g > 0.0 ? 1.0 / acc_1g : 0.0);
    self->kp = imf_qscale_from_double(kp);
    self->x.t[0] = self->x.t[1] = 0;
    /* shifts: kw.s - 28 and kw.s + 15 - 28 (>= 0), ka.s - 28, kp.s */
    if (!(dt > 0.0) || !imf_param_ok(kp, 0.0, 1.0) || !(gyr_scale > 0.0)
        || !imf_param_ok(acc_1g, 1.0, 32767.0) || self->kw.m == 0 || self->kw.s < 28
        || self->kw.s > 59 || self->ka.s > 59 || self->kp.s < 14 || self->kp.s > 47) {
        return -1;
    }
    return 0;
}

void imf_kk_q_update(imf_kk_q_t *const self, const int16_t gyr[3], const int16_t acc[3])
{
    int32_t *const t = self->x.t;
    /* small-angle operands of the yaw cross terms, q15 rad */
    const int16_t tx15 = imf_qn_to_q15s(t[0], 28), ty15 = imf_qn_to_q15s(t[1], 28);
    /* w dt per axis, q28 rad */
    const int32_t wx = imf_scale16(gyr[0], self->kw, 28), wy = imf_scale16(gyr[1], self->kw, 28);
    /* theta_y w_z dt and theta_x w_z dt: (q15 x counts) then x kw -> q28 */
    const int32_t cx = imf_scale32((int32_t)ty15 * gyr[2], self->kw, 15, 28);
    const int32_t cy = imf_scale32((int32_t)tx15 * gyr[2], self->kw, 15, 28);
    /* accelerometer angles, q28 rad (a_x = -acc_x / 1g) */
    const int32_t ax = imf_sub_sat32(0, imf_scale16(acc[0], self->ka, 28));
    const int32_t ay = imf_scale16(acc[1], self->ka, 28);
    /* Kp (a - theta_{n-1}) */
    const int32_t px = imf_scale32(imf_sub_sat32(ax, t[0]), self->kp, 28, 28);
    const int32_t py = imf_scale32(imf_sub_sat32(ay, t[1]), self->kp, 28, 28);
    const int32_t nx = imf_add_sat32(imf_add_sat32(imf_add_sat32(t[0], wy), cx), px);
    const int32_t ny = imf_add_sat32(imf_add_sat32(imf_sub_sat32(t[1], cy), wx), py);
    t[0] = nx;
    t[1] = ny;
}

int imf_multiwii_q_init(imf_multiwii_q_t *const self, const double dt, const double cmpf,
                        const double gyr_scale, const double acc_1g)
{
    const double lo = 0.85 * acc_1g, hi = 1.15 * acc_1g;
    self->kw = imf_qscale_from_double(gyr_scale * dt);
    self->kc = imf_qscale_from_double(cmpf >= 0.0 ? 1.0 / (cmpf + 1.0) : 0.0);
    self->lo2 = (uint32_t)floor(lo * lo);
    self->hi2 = (uint32_t)ceil(hi * hi);
    self->one_g = (int32_t)floor(acc_1g * 32768.0 + 0.5);
    self->x.d[0] = self->x.d[1] = 0;
    self->x.d[2] = self->one_g;
    /* shifts: kw.s + 0 - 15 in [0, 47] (after a q15 x counts product), kc.s */
    if (!(dt > 0.0) || !(cmpf >= 0.0) || !(cmpf <= 1.0e9) || !(gyr_scale > 0.0)
        || !imf_param_ok(acc_1g, 1.0, 32767.0) || self->kw.m == 0 || self->kw.s < 15
        || self->kw.s > 62 || self->kc.s < 14 || self->kc.s > 47) {
        return -1;
    }
    return 0;
}

void imf_multiwii_q_update(imf_multiwii_q_t *const self, const int16_t gyr[3], const int16_t acc[3])
{
    int32_t *const d = self->x.d;
    int32_t c[3];
    uint32_t n2;
    int i;
    /* step 3: d_n = d_{n-1} + d_{n-1} x w dt; each product d_j w_k first in
     * acc counts x gyro counts (d q15 x counts / 2^15), then x kw -> q15 */
    c[0] = imf_sub_sat32(imf_mul_32x16(d[1], gyr[2], 15), imf_mul_32x16(d[2], gyr[1], 15));
    c[1] = imf_sub_sat32(imf_mul_32x16(d[2], gyr[0], 15), imf_mul_32x16(d[0], gyr[2], 15));
    c[2] = imf_sub_sat32(imf_mul_32x16(d[0], gyr[1], 15), imf_mul_32x16(d[1], gyr[0], 15));
    for (i = 0; i < 3; ++i) {
        d[i] = imf_add_sat32(d[i], imf_scale32(c[i], self->kw, 0, 15));
    }
    /* step 4: complementary weighting while |a| is within 1 +- 0.15 g;
     * squares <= 2^30, three < 2^32 */
    n2 = (uint32_t)((int32_t)acc[0] * acc[0]) + (uint32_t)((int32_t)acc[1] * acc[1])
       + (uint32_t)((int32_t)acc[2] * acc[2]);
    if (n2 > self->lo2 && n2 < self->hi2) {
        for (i = 0; i < 3; ++i) {
            /* (d F + a)/(F + 1) = d + (a - d)/(F + 1) */
            const int32_t e = imf_sub_sat32(imf_q15_to_q30(acc[i]), d[i]);
            d[i] = imf_add_sat32(d[i], imf_scale32(e, self->kc, 15, 15));
        }
    }
}
