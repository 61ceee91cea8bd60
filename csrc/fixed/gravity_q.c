/* Fixed-point KK and MultiWii filters; see gravity_q.h for the Q formats.
 * Mirrored line for line by python/imufuse/reference/fixed_gravity.py. */
#include "gravity_q.h"
#include "imf_fixed_init.h"
#include "imf_fixed_scale.h"

int imf_kk_q_init_consts(imf_kk_q_t *const self, const imf_qscale_t kw, const uint16_t kp16_m,
                         const int kp16_j)
{
    /* kp16 = imf_gain16(kp, 15, 15), stored as given (no init-time arithmetic
     * in an integer-initialised firmware): kp in [0, 1], so j in [0, 4] with
     * m = 0 (kp = 0) or m in [2^8, 2^16), or j = -2, m = 0 (kp = 1 exactly).
     * kw: its shift kw.s - 28 in [0, 31] (kw < 2^-13 rad per count and sample) */
    self->kw = kw;
    self->kp16.m = kp16_m;
    self->kp16.j = (int16_t)kp16_j;
    self->x.t[0] = self->x.t[1] = 0;
    if (kw.m == 0 || !imf_qscale_ok(kw, 28, 59) || !imf_gain16_ok(kp16_m, kp16_j, 1)) {
        return -1;
    }
    return 0;
}

void imf_kk_q_default_settings(imf_kk_q_settings_t *const settings)
{
    settings->dt = 0.01;
    settings->kp = 0.01;
    settings->gyr_scale = 1.0642e-3;
}

int imf_kk_q_init(imf_kk_q_t *const self, const imf_kk_q_settings_t *const s)
{
    const imf_gain16_t kp16 = imf_gain16(imf_qscale_from_double(s->kp), 15, 15);
    const int r =
        imf_kk_q_init_consts(self, imf_qscale_from_double(s->gyr_scale * s->dt), kp16.m, kp16.j);
    if (!(s->dt > 0.0) || !(s->kp >= 0.0) || !(s->kp <= 1.0) || !(s->gyr_scale > 0.0)) {
        return -1;
    }
    return r;
}

/* round(w q / 2^15) for int32 w, int16 q (|q| < 2^15: no saturation): the
 * high part h = floor(w q / 2^16) and the low 16 bits from two 16x16
 * products, then 2 h plus the two top bits of the low word. */
static inline int32_t imf_kk_q_mul15(const int32_t w, const int16_t q)
{
    const int32_t lo = imf_mul16su(q, (uint16_t)((uint32_t)w & 0xFFFFu));
    const int32_t h = imf_mul16((int16_t)(w >> 16), q) + (lo >> 16);
    const uint16_t l = (uint16_t)lo;
    return h * 2 + (int32_t)(l >> 15) + (int32_t)((l >> 14) & 1u);
}

/* The state rounded to q15: imf_qn_to_q15s(t, 28).  On AVR in 16-bit steps
 * (the general shift is a 13-step loop): r = t + 2^12 (saturated: beyond the
 * q15 range either way), h = floor(r / 2^16); floor(r / 2^13) is 8 h plus
 * bits 13..15 of r, saturated to the symmetric q15 range. */
static inline int16_t imf_kk_q_q15(const int32_t t)
{
#if defined(__AVR__) || defined(IMF_SCALE_SHORT)
    const int32_t r = imf_add_sat32(t, 4096);
    const int16_t h = (int16_t)(r >> 16);
    int16_t v;
    if (h >= 4096) {
        return 32767;
    }
    if (h < -4096) {
        return -32767;
    }
    v = (int16_t)(h * 8 + (int16_t)((uint16_t)((uint32_t)r & 0xFFFFu) >> 13));
    return (v == -32768) ? (int16_t)-32767 : v;
#else
    return imf_qn_to_q15s(t, 28);
#endif
}

/* Eq. 4.5 for one angle theta_i (pitch: i = 0, neg = 1; roll: i = 1, neg = 0)
 * with theta_j the other one, wj = w_j dt and wz = w_z dt (q28 rad), and
 * a_i = -a_x (pitch) or a_y (roll) of the unit vector (ok = 0: none):
 *   theta_i + w_j dt -+ theta_j w_z dt + Kp (a_i - theta_i), q28. */
static inline int32_t imf_kk_q_angle(const imf_kk_q_t *const self, const int32_t ti,
                                     const int32_t tj, const int32_t wj, const int32_t wz,
                                     const int neg, const int ok, const int16_t ai)
{
    /* -+ theta_j w_z dt: the state rounded to q15 (imf_kk_q_q15), its sign
     * applied there (symmetric q15), times w_z dt in q28, / 2^15 rounded */
    int16_t q = imf_kk_q_q15(tj);
    int32_t x = imf_add_sat32(ti, wj);
    if (neg) {
        q = (int16_t)-q;
    }
    x = imf_add_sat32(x, imf_kk_q_mul15(wz, q));
    if (ok) {
        /* P controller Kp (a - theta_{n-1}), a in q28 (symmetric q15 -> q28
         * exactly); kp = 1 (kp16.j < 0): the whole error */
        const int32_t e = imf_sub_sat32(imf_mul16(ai, 8192), ti);
        x = imf_add_sat32(x, (self->kp16.j >= 0) ? imf_gain16_mul(e, self->kp16) : e);
    }
    return x;
}

void imf_kk_q_update_v(imf_kk_q_t *const self, const int16_t gyr[3], const int16_t acc[3])
{
    int32_t *const t = self->x.t;
    int16_t a[2] = { 0, 0 };
    int32_t w[3], n[2];
    int i;
    const int ok = imf_unit_xy_k(acc, a);
    /* w dt in q28 (imf_mulk16's value, its shift kw.s - 28 >= 0) */
    for (i = 0; i < 3; ++i) {
        w[i] = imf_rshrk(imf_mul16(gyr[i], self->kw.m), self->kw.s - 28);
    }
#if defined(__AVR__) || defined(IMF_SCALE_SHORT)
    /* on AVR pitch and roll in a loop (one copy of the code), elsewhere the
     * two calls written out (the Cortex-M0 pays for the loop); same values */
    for (i = 0; i < 2; ++i) {
        n[i] = imf_kk_q_angle(self, t[i], t[1 - i], w[1 - i], w[2], i == 0, ok,
                              i ? a[1] : (int16_t)-a[0]);
    }
#else
    n[0] = imf_kk_q_angle(self, t[0], t[1], w[1], w[2], 1, ok, (int16_t)-a[0]);
    n[1] = imf_kk_q_angle(self, t[1], t[0], w[0], w[2], 0, ok, a[1]);
#endif
    t[0] = n[0];
    t[1] = n[1];
}

void imf_multiwii_q_default_settings(imf_multiwii_q_settings_t *const settings)
{
    settings->dt = 0.01;
    settings->cmpf = 600.0;
    settings->acc_lpf_shift = 4;
    settings->acc_1g = 4096.0;
    settings->window = 0.15;
    settings->gyr_scale = 1.0642e-3;
}

int imf_multiwii_q_init_consts(imf_multiwii_q_t *const self, const imf_multiwii_q_consts_t *const c)
{
    const imf_qscale_t kw = c->kw, kc = c->kc;
    const int acc_lpf_shift = c->acc_lpf_shift;
    const int32_t acc_1g_q15 = c->acc_1g_q15;
    const int k = (acc_lpf_shift >= 0 && acc_lpf_shift <= 15) ? acc_lpf_shift : 0;
    int i;
    self->kw = kw;
    self->kc = kc;
    self->kw16 = imf_gain16(kw, 0, 16);
    self->kc16 = imf_gain16(kc, 15, 15);
    self->k = (int16_t)k;
    self->lo2 = c->lo2;
    self->hi2 = c->hi2;
    for (i = 0; i < 3; ++i) {
        self->x.d[i] = 0;
        self->x.l[i] = 0;
    }
    if (k != acc_lpf_shift || !(acc_1g_q15 > 0) || acc_1g_q15 > (int32_t)32767 * 32768 || kw.m == 0
        || !imf_qscale_ok(kw, 16, 62) || !imf_qscale_ok(kc, 14, 47)) {
        return -1;
    }
    /* start level: d = accSmooth = (0, 0, acc_1g) */
    self->x.d[2] = acc_1g_q15;
    self->x.l[2] = acc_1g_q15;
    return 0;
}

int imf_multiwii_q_init(imf_multiwii_q_t *const self, const imf_multiwii_q_settings_t *const s)
{
    const double dt = s->dt, cmpf = s->cmpf, acc_1g = s->acc_1g, window = s->window;
    const double lo = (1.0 - window) * acc_1g, hi = (1.0 + window) * acc_1g;
    const int ok_1g = imf_param_ok(acc_1g, 0.0, 32767.0) && acc_1g > 0.0;
    /* 0 < window <= 1 (lo, hi finite) */
    const int ok_w = ok_1g && imf_param_ok(window, 0.0, 1.0) && window > 0.0;
    imf_multiwii_q_consts_t c;
    int r;
    c.kw = imf_qscale_from_double(s->gyr_scale * dt);
    c.kc = imf_qscale_from_double(cmpf >= 0.0 ? 1.0 / (cmpf + 1.0) : 0.0);
    c.acc_lpf_shift = s->acc_lpf_shift;
    c.lo2 = (ok_w && lo > 0.0) ? (uint32_t)floor(lo * lo) : 0u;
    c.hi2 = (!ok_w || hi * hi >= 4294967295.0) ? 4294967295u : (uint32_t)ceil(hi * hi);
    c.acc_1g_q15 = ok_1g ? (int32_t)floor(acc_1g * 32768.0 + 0.5) : 0;
    r = imf_multiwii_q_init_consts(self, &c);
    if (!(dt > 0.0) || !(cmpf >= 0.0) || !(cmpf <= 1.0e9) || !ok_w || !(s->gyr_scale > 0.0)) {
        return -1;
    }
    return r;
}

#if !(defined(__AVR__) || defined(IMF_SCALE_SHORT)) && defined(__GNUC__)
/* imf_gain16_or_mulk32, one copy called from the three products below (GCC
 * inlines a static function with a single caller: 356 bytes more on the
 * Cortex-M0 than this call) */
__attribute__((noinline)) static int32_t imf_multiwii_q_gain(const int32_t x, const imf_gain16_t g,
                                                             const imf_qscale_t c, const int K,
                                                             const int N)
{
    return imf_gain16_or_mulk32(x, g, c, K, N);
}
#else
#define imf_multiwii_q_gain imf_gain16_or_mulk32
#endif

void imf_multiwii_q_update_v(imf_multiwii_q_t *const self, const int16_t gyr[3],
                             const int16_t acc[3])
{
    int32_t *const d = self->x.d;
    int32_t *const l = self->x.l;
    const int k = self->k;
    int32_t c[3];
    uint32_t n2 = 0u;
    int16_t sc;
    int i;
    /* accelerometer LPF, MultiWii's accLPF32 -= accLPF32 >> k; += acc divided by
     * 2^k: accSmooth += (acc - accSmooth) / 2^k, in q15 counts (rounded) */
    for (i = 0; i < 3; ++i) {
        l[i] = imf_add_sat32(l[i], imf_rshrk(imf_sub_sat32(imf_i16_to_q15(acc[i]), l[i]), k));
        sc = imf_sat_q15(imf_rshr32(l[i], 15)); /* accSmooth, counts */
        n2 += (uint32_t)imf_mul16(sc, sc);      /* three squares <= 2^30: no wrap */
    }
    /* step 3: d_n = d_{n-1} + d_{n-1} x w dt; the cross product d x w first,
     * in half acc counts x gyro counts (d q15 x counts / 2^16, each component
     * rounded once), then x kw -> q15 */
    imf_cross3_16(d, gyr, c);
#if defined(__AVR__) || defined(IMF_SCALE_SHORT)
    /* on AVR steps 3 and 4 as two passes of one loop (one copy of the 16-bit
     * gain product; the same values as the two loops below) */
    {
        const int passes = (n2 > self->lo2 && n2 < self->hi2) ? 2 : 1;
        imf_gain16_t g = self->kw16;
        imf_qscale_t q = self->kw;
        int kq = 0, nq = 16, p = 0;
        for (;;) {
            for (i = 0; i < 3; ++i) {
                d[i] = imf_add_sat32(d[i], imf_gain16_or_mulk32(c[i], g, q, kq, nq));
            }
            if (++p == passes) {
                break;
            }
            /* step 4: (d F + s)/(F + 1) = d + (s - d)/(F + 1) */
            for (i = 0; i < 3; ++i) {
                c[i] = imf_sub_sat32(l[i], d[i]);
            }
            g = self->kc16;
            q = self->kc;
            kq = 15;
            nq = 15;
        }
    }
#else
    for (i = 0; i < 3; ++i) {
        d[i] = imf_add_sat32(d[i], imf_multiwii_q_gain(c[i], self->kw16, self->kw, 0, 16));
    }
    /* step 4: complementary weighting while |accSmooth| is within the window */
    if (n2 > self->lo2 && n2 < self->hi2) {
        for (i = 0; i < 3; ++i) {
            /* (d F + s)/(F + 1) = d + (s - d)/(F + 1) */
            d[i] = imf_add_sat32(
                d[i], imf_multiwii_q_gain(imf_sub_sat32(l[i], d[i]), self->kc16, self->kc, 15, 15));
        }
    }
#endif
}
