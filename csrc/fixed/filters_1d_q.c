/* Fixed-point single-axis filters; see filters_1d_q.h for the Q formats.
 * Mirrored line for line by python/imufuse/reference/fixed_1d.py. */
#include "filters_1d_q.h"
#include "imf_fixed_init.h"
#include "imf_fixed_scale.h"

/* Constant ranges: imf_scale16 shifts c.s - 15 and imf_scale32 shifts
 * c.s + K - N must lie in [-31, 31] and [0, 47]. */
static int imf_1d_q_kr_ok(const imf_qscale_t kr)
{
    return kr.m != 0 && imf_qscale_ok(kr, -14, 46);
}

int imf_complementary1d_q_init_consts(imf_complementary1d_q_t *const self, const imf_qscale_t kr,
                                      const uint16_t ka16_m, const int ka16_j)
{
    /* ka16 = imf_gain16(1 - alpha, 15, 15), stored as given (no init-time
     * arithmetic in an integer-initialised firmware): j in [0, 4] with m = 0
     * (alpha = 1) or m in [2^8, 2^16), or j = -2, m = 0 (alpha = 0, exactly 1) */
    self->kr = kr;
    self->ka16.m = ka16_m;
    self->ka16.j = (int16_t)ka16_j;
    self->x.theta = 0;
    if (!imf_1d_q_kr_ok(kr) || !imf_gain16_ok(ka16_m, ka16_j, 1)) {
        return -1;
    }
    return 0;
}

void imf_complementary1d_q_default_settings(imf_complementary1d_q_settings_t *const settings)
{
    settings->dt = 0.01;
    settings->alpha = 0.9803921568627451;
    settings->gyr_scale = 1.0642e-3;
    settings->angle_scale = 1e-4;
}

int imf_complementary1d_q_init(imf_complementary1d_q_t *const self,
                               const imf_complementary1d_q_settings_t *const s)
{
    const imf_gain16_t ka16 = imf_gain16(imf_qscale_from_double(1.0 - s->alpha), 15, 15);
    const int r = imf_complementary1d_q_init_consts(
        self, imf_qscale_from_double(s->gyr_scale * s->dt / s->angle_scale), ka16.m, ka16.j);
    if (!(s->dt > 0.0) || !imf_param_ok(s->alpha, 0.0, 1.0) || !(s->gyr_scale > 0.0)
        || !(s->angle_scale > 0.0)) {
        return -1;
    }
    return r;
}

void imf_complementary1d_q_update(imf_complementary1d_q_t *const self, const int16_t rate,
                                  const int16_t angle)
{
    /* Eq. 2.2 as Eq. 2.12: theta^- = theta + w dt; theta = theta^- + (1 - alpha)(a - theta^-) */
    const int32_t tp = imf_add_sat32(self->x.theta, imf_mulk16(rate, self->kr, 15));
    const int32_t e = imf_sub_sat32(imf_i16_to_q15(angle), tp); /* a in q15 counts */
    /* (1 - alpha) e; 1 - alpha >= 1 (ka16.j < 0) is exactly 1 (alpha in [0, 1]) */
    self->x.theta = imf_add_sat32(tp, (self->ka16.j >= 0) ? imf_gain16_mul(e, self->ka16) : e);
}

void imf_mahony1d_bias_q_default_settings(imf_mahony1d_bias_q_settings_t *const settings)
{
    settings->dt = 0.01;
    settings->kp = 2.0;
    settings->ki = 0.3;
    settings->integrate_first = 0;
    settings->gyr_scale = 1.0642e-3;
    settings->angle_scale = 1e-4;
}

int imf_mahony1d_bias_q_init_consts(imf_mahony1d_bias_q_t *const self,
                                    const imf_mahony1d_bias_q_consts_t *const c)
{
    /* kp16 = imf_gain16(Kp dt, 15, 15), ki16 = imf_gain16(Ki dt^2, 15, 23),
     * stored as given (no init-time arithmetic in an integer-initialised
     * firmware): Kp dt < 1 and Ki dt^2 < 2^-8, so both are 16-bit gains */
    self->kr = c->kr;
    self->kp16.m = c->kp16_m;
    self->kp16.j = (int16_t)c->kp16_j;
    self->ki16.m = c->ki16_m;
    self->ki16.j = (int16_t)c->ki16_j;
    self->integrate_first = (int16_t)(c->integrate_first != 0);
    self->x.theta = 0;
    self->x.j = 0;
    if (!imf_1d_q_kr_ok(c->kr) || !imf_gain16_ok(c->kp16_m, c->kp16_j, 0)
        || !imf_gain16_ok(c->ki16_m, c->ki16_j, 0)) {
        return -1;
    }
    return 0;
}

int imf_mahony1d_bias_q_init(imf_mahony1d_bias_q_t *const self,
                             const imf_mahony1d_bias_q_settings_t *const s)
{
    const double dt = s->dt, kp = s->kp, ki = s->ki;
    const double gyr_scale = s->gyr_scale, angle_scale = s->angle_scale;
    const imf_qscale_t kpq = imf_qscale_from_double(kp * dt);
    const imf_qscale_t kiq = imf_qscale_from_double(ki * dt * dt);
    const imf_gain16_t kp16 = imf_gain16(kpq, 15, 15);
    const imf_gain16_t ki16 = imf_gain16(kiq, 15, 23);
    imf_mahony1d_bias_q_consts_t c;
    int r;
    c.kr = imf_qscale_from_double(gyr_scale * dt / angle_scale);
    c.kp16_m = kp16.m;
    c.kp16_j = kp16.j;
    c.ki16_m = ki16.m;
    /* Ki = 0: the gain 0 (imf_gain16 gives j = -1 for its q-scale 0 2^-16) */
    c.ki16_j = (kiq.m == 0) ? 0 : ki16.j;
    c.integrate_first = s->integrate_first;
    r = imf_mahony1d_bias_q_init_consts(self, &c);
    /* Kp dt < 1, Ki dt^2 < 2^-8: q-scale s >= 15, >= 23 (Ki = 0: 0 2^-16) */
    if (!(dt > 0.0) || !(kp >= 0.0) || !(ki >= 0.0) || !(gyr_scale > 0.0) || !(angle_scale > 0.0)
        || !imf_qscale_ok(kpq, 15, 47) || !(kiq.m == 0 || imf_qscale_ok(kiq, 23, 55))) {
        return -1;
    }
    return r;
}

/* y0 = imf_gain16_mul(x, g0); y1 = imf_gain16_mul(x, g1): on AVR one copy of
 * the product in a loop, elsewhere the two statements.  Same values. */
#if defined(__AVR__) || defined(IMF_SCALE_SHORT)
#define IMF_1D_Q_GAIN16_MUL_2(y0, g0, y1, g1, x) \
    do { \
        int32_t imf_y_[2]; \
        int imf_i_; \
        for (imf_i_ = 0; imf_i_ < 2; ++imf_i_) { \
            imf_y_[imf_i_] = imf_gain16_mul((x), imf_i_ ? (g1) : (g0)); \
        } \
        (y0) = imf_y_[0]; \
        (y1) = imf_y_[1]; \
    } while (0)
#else
#define IMF_1D_Q_GAIN16_MUL_2(y0, g0, y1, g1, x) \
    do { \
        (y0) = imf_gain16_mul((x), (g0)); \
        (y1) = imf_gain16_mul((x), (g1)); \
    } while (0)
#endif

void imf_mahony1d_bias_q_update(imf_mahony1d_bias_q_t *const self, const int16_t rate,
                                const int16_t angle)
{
    imf_mahony1d_bias_q_state_t *const x = &self->x;
    /* e_k = a_k - theta_{k-1} (q15 counts) */
    const int32_t e = imf_sub_sat32(imf_i16_to_q15(angle), x->theta);
    const int32_t w = imf_mulk16(rate, self->kr, 15); /* w dt, q15 counts */
    int32_t p, di;
    IMF_1D_Q_GAIN16_MUL_2(p, self->kp16, di, self->ki16, e); /* Kp dt e (q15), Ki dt^2 e (q23) */
    /* I_k = I_{k-1} + Ki dt e_k */
    const int32_t j = imf_add_sat32(x->j, di);
    /* Eq. 3.6: theta_k = theta_{k-1} + (Kp e_k + I_k + w_k) dt.
     * Eq. 3.9 (integrate_first): theta_k = theta_{k-1} + (w_k + I_{k-1}) dt + Kp' dt e_k
     * (one angle step for both: only the I term it adds differs) */
    const int32_t jt = self->integrate_first ? x->j : j;
    x->theta = imf_add_sat32(imf_add_sat32(imf_add_sat32(x->theta, p), imf_rshr32(jt, 8)), w);
    x->j = j;
}
