/* The blocks of the fixed-point RobustIMU and RobustAHRS (robust_q.h), one function each, named
 * as csrc/robust.c's: the accelerometer reading, B1 rest, the strapdown, B2 gravity (B5 its
 * start), the levelling, B3 bias, the output (latency and clock); B4 in robust_q_mag.h. Private to
 * csrc/fixed/robust_q.c, which includes this file once and composes them (static functions,
 * one translation unit: the filter is one source for the harnesses). Mirrored line for line
 * by python/imufuse/reference/fixed_robust_blocks.py. */
#ifndef IMF_ROBUST_Q_BLOCKS_H
#define IMF_ROBUST_Q_BLOCKS_H

#include "robust_q.h"
#include "robust_q_ops.h"

/* the accelerometer is a reading: not all zero (then gyro only, and no start without
 * one), and after the first sample not beyond 100 times the gravity estimate (100 g: a
 * shock or a hostile value) */
static int robust_q_acc_reading(const imf_robust_imu_q_state_t *const x, const int16_t acc[3],
                                const int first)
{
    const int has_acc = !(acc[0] == 0 && acc[1] == 0 && acc[2] == 0);
    if (has_acc && !first) {
        const uint32_t f2 = robust_q_norm2_counts(x->f);
        const uint32_t an2 = robust_q_norm2(acc[0], acc[1], acc[2]);
        if (f2 < 429497u && an2 > f2 * 10000u) {
            return 0;
        }
    }
    return has_acc;
}

/* B1: rest detection from low-passes of gyro and accelerometer in the sensor frame, and
 * the bias observed at rest (Eq. 3.1: b_k = b_{k-1}); returns 1 at rest; w2: |low-passed
 * gyro|^2, counts^2 (B2's process noise) */
static int robust_q_rest(const imf_robust_imu_q_consts_t *const k,
                         imf_robust_imu_q_state_t *const x, const int16_t gyr[3],
                         const int16_t acc[3], const int has_acc, uint32_t *const w2)
{
    const imf_qscale_t kk = robust_q_gain(ROBUST_Q_IS_P8(k), x->n, k->n_tau, k->k_rest);
    int still, i;
    robust_q_lowpass3(x->lw, gyr, kk);
    if (has_acc) {
        robust_q_lowpass3(x->la, acc, kk);
    }
    *w2 = robust_q_norm2_counts(x->lw);
    /* at rest: the low-passed and the raw gyro below rest_gyr, the accelerometer within
       rest_acc of its low-pass (each test only where the ones before hold) */
    still = has_acc && *w2 < k->rest_g2 && robust_q_norm2(gyr[0], gyr[1], gyr[2]) < k->rest_g2;
    if (still) {
        int16_t lc[3], de[3];
        for (i = 0; i < 3; ++i) {
            /* the accelerometer's difference from its low-pass, counts, within +-32767 */
            lc[i] = (int16_t)robust_q_counts(x->la[i]);
            de[i] = imf_sat_q15s((int32_t)acc[i] - lc[i]);
        }
        still = (int32_t)(robust_q_norm2(de[0], de[1], de[2]) >> 2) < imf_scale32_s(
                    (int32_t)(robust_q_norm2(lc[0], lc[1], lc[2]) >> 2), k->kacc2, 0, 0);
    }
    if (still) {
        if (x->n_rest < k->n_rest) {
            x->n_rest++;
        }
    } else {
        x->n_rest = 0;
    }
    if (x->n_rest < k->n_rest) {
        return 0;
    }
    robust_q_lowpass3(x->b, gyr, k->kb_rest);
    return 1;
}

/* strapdown: s = s (x) exp(1/2 (w - b) dt), the series of the float filter; sn: the new
 * s's q15 snapshot (s is not changed again in the update) */
static void robust_q_strapdown(const imf_robust_imu_q_consts_t *const k,
                               imf_robust_imu_q_state_t *const x, const int16_t gyr[3],
                               int16_t sn[4])
{
    robust_q_integrate(ROBUST_Q_IS_P8(k), x->s, gyr, x->b, k->kg, sn);
}

/* B5: gravity from the first sample (ai: the accelerometer in the inertial frame) */
static void robust_q_gravity_start(const imf_robust_imu_q_consts_t *const k,
                                   imf_robust_imu_q_state_t *const x, const int32_t ai[3])
{
    int i;
    for (i = 0; i < 3; ++i) {
        x->f[i] = ai[i];
        x->v[i] = 0;
    }
    x->p[0] = x->p[1] = 0;
    x->p[2] = k->pg0;
}

/* B2: the Kalman filter of gravity in the inertial frame (ai: the accelerometer there,
 * q15 counts; w2: B1's |low-passed gyro|^2) */
static void robust_q_gravity_update(const imf_robust_imu_q_consts_t *const k,
                                    imf_robust_imu_q_state_t *const x, const int32_t ai[3],
                                    const uint32_t w2)
{
    int32_t qg, pe, pvv, pvg, pgg, kv, kg;
    imf_qscale_t inv, kvs, kgs;
    int sv, sg, i;
    const int p8 = ROBUST_Q_IS_P8(k);
    /* predict: v' = (a - g) / tau_acc, g' = 0 (+ process noise growing with the rate) */
    for (i = 0; i < 3; ++i) {
        x->v[i] =
            imf_add_sat32(x->v[i], imf_scale32_s(imf_sub_sat32(ai[i], x->f[i]), k->eps, 15, 15));
    }
    /* e^2 (1 + |w|^2 / rate_ref^2), the rate term capped at 1e4 e^2 */
    qg = k->kq.m != 0 ? imf_scale32_s((int32_t)(w2 >> 2), k->kq, 0, 30) : 0;
    if (qg > k->qcap) {
        qg = k->qcap;
    }
    qg = k->qg0 + qg;
    pe = imf_scale32_s(x->p[2], k->eps, 30, 30); /* e pgg */
    pvv = imf_add_sat32(imf_sub_sat32(x->p[0], imf_scale32_s(x->p[1], k->eps, 29, 30)),
                        imf_scale32_s(pe, k->eps, 30, 30));
    pvg = imf_sub_sat32(x->p[1], pe);
    pgg = imf_add_sat32(x->p[2], qg);
    /* update with the pseudo-measurement v = 0 (noise 1): gains P / (pvv + 1) */
    inv = ROBUST_Q_RECIP(p8, (uint32_t)(pvv < 0 ? 0 : pvv >> 1) + 536870912u, 29);
    {
        /* the 8-bit profile's in q27: a shift of inv.s + 3 >= 17 (imf_mul_32x16's
           fast path on AVR); kvs and kgs keep their 15 leading bits */
        const int ng = p8 ? 27 : 30;
        kv = imf_scale32_s(pvv, inv, 30, ng);
        kg = imf_scale32_s(pvg, inv, 30, ng);
        kvs = robust_q_scale_of(kv, ng, &sv);
        kgs = robust_q_scale_of(kg, ng, &sg);
    }
    for (i = 0; i < 3; ++i) {
        x->f[i] = imf_sub_sat32(x->f[i], robust_q_mul_signed(x->v[i], kgs, sg, 15, 15));
        x->v[i] = imf_sub_sat32(x->v[i], robust_q_mul_signed(x->v[i], kvs, sv, 15, 15));
    }
    x->p[2] = imf_sub_sat32(pgg, robust_q_mul_signed(pvg, kgs, sg, 30, 30));
    x->p[1] = imf_sub_sat32(pvg, robust_q_mul_signed(pvg, kvs, sv, 30, 30));
    x->p[0] = imf_sub_sat32(pvv, robust_q_mul_signed(pvv, kvs, sv, 30, 30));
}

/* B2: the accelerometer in the inertial frame (sn: the new s's q15 snapshot), gravity
 * from it: B5 at the first sample, else the Kalman filter where there is a reading */
static void robust_q_gravity(const imf_robust_imu_q_consts_t *const k,
                             imf_robust_imu_q_state_t *const x, const int16_t acc[3],
                             const int16_t sn[4], const int first, const int has_acc,
                             const uint32_t w2)
{
    int16_t rm[9];
    int32_t ai[3];
    robust_q_matrix(sn, rm, 3);
    robust_q_rotate16(rm, 0, acc, ai); /* q15 counts */
    if (first) {
        robust_q_gravity_start(k, x, ai);
    } else if (has_acc) {
        robust_q_gravity_update(k, x, ai, w2);
    }
}

#if IMF_Q_HAS_P8
/* robust_q_level in the 8-bit profile: f narrowed to int16 (its largest at most
 * 2^14), rotated by R(c) and rounded to f's format, the unit vector of its 15 leading bits
 * (imf_q_unit3_p8); c += d (x) c with d = r - 1 in 16-bit products. For u_z >= 0, r = (1 +
 * u_z, u_y, -u_x) / 2, not normalised (the normalisation of c takes it: the same
 * direction); below (turned over), r normalised with 1 + u_z from its product with 1 - u_z
 * (below). B3 takes 2 (r1, r2): (u_y, -u_x) for the first, the doubled r for the second.
 * ss: c's q15 snapshot (overwritten). */
static void robust_q_level_p8(imf_robust_imu_q_state_t *const x, const int16_t sn[4], int16_t ss[4],
                              int16_t r[4])
{
    int16_t rm[9], u[3], f16[3], g16[3], d[4];
    int32_t ge[3], t[4];
    int half = 0, i;
    robust_q_narrow_p8(x->f, 3, robust_q_exponent_p8(x->f, 3) + 1, f16);
    robust_q_matrix(ss, rm, 3);
    robust_q_rotate16(rm, 0, f16, ge); /* |ge| < 2^30 */
    g16[0] = imf_sat_q15s(imf_rshr32(ge[0], 15));
    g16[1] = imf_sat_q15s(imf_rshr32(ge[1], 15));
    g16[2] = imf_sat_q15s(imf_rshr32(ge[2], 15));
    d[0] = d[1] = d[2] = d[3] = 0;
    r[1] = r[2] = 0;
    if (imf_q_unit3_p8(g16, u)) {
        if (u[2] >= 0) {
            d[0] = (int16_t)(u[2] - 32768L); /* [-32768, -1] */
            d[1] = r[1] = u[1];
            d[2] = r[2] = (int16_t)-u[0];
            half = 1; /* d is twice r - 1 */
        } else {
            /* turned over (the first samples only: c takes the whole r): r = (1 + u_z, u_y,
               -u_x) normalised, as the direction of its product with 1 - u_z, (u_x^2 +
               u_y^2, u_y (1 - u_z), -u_x (1 - u_z)) in q30 (no difference of nearly equal
               numbers; u's norm error scales the first by 1.2e-3 at most), narrowed to its
               15 leading bits; (0, 1, 0) where it is 0 (exactly upside down: the half turn
               about x, as robust_q_half) */
            const uint16_t w = (uint16_t)(32768L - u[2]);          /* 1 - u_z, (2^15, 2^16) */
            ge[0] = imf_mul16(u[0], u[0]) + imf_mul16(u[1], u[1]); /* < 2^31 */
            ge[1] = imf_mul16su(u[1], w);                          /* |.| < 2^31 */
            ge[2] = -imf_mul16su(u[0], w);
            robust_q_narrow_p8(ge, 3, robust_q_exponent_p8(ge, 3), r);
            if (!imf_q_unit3_p8(r, r)) {
                r[0] = 0;
                r[1] = 32767;
                r[2] = 0;
            }
            d[0] = (int16_t)(r[0] - 32768L); /* [-32768, -1] */
            d[1] = r[1];
            d[2] = r[2];
            r[1] = imf_sat_q15s(2L * r[1]);
            r[2] = imf_sat_q15s(2L * r[2]);
        }
    }
    robust_q_mul_p8(d, ss, t);
    for (i = 0; i < 4; ++i) {
        x->c[i] = imf_add_sat32(x->c[i], imf_rshr32(t[i], half));
        ss[i] = imf_qn_to_q15s(x->c[i], 30);
    }
    robust_q_renorm_p8(x->c, ss);  /* c's snapshot, then its new one */
    robust_q_mul_p8(ss, sn, x->q); /* |q|^2 - 1: c's and the snapshots' rounding */
}
#endif

#if IMF_Q_HAS_P32
/* robust_q_level in the 32-bit profile: r = (1 + u_z, u_y, -u_x, 0) normalised by
 * robust_q_half, c = r (x) c and q = c (x) s, each normalised; ss: c's q15 snapshot
 * (overwritten) */
static void robust_q_level_p32(imf_robust_imu_q_state_t *const x, int16_t ss[4], int16_t r[4])
{
    int16_t rm[9], u[3];
    int32_t ge[3], t[4];
    int i;
    robust_q_matrix(ss, rm, 3);
    robust_q_rotate(rm, 0, x->f, ge);
    if (robust_q_unit(ge, u)) {
        /* gravity straight down (upside down): the half turn about x */
        robust_q_half(u[2], u[1], (int16_t)-u[0], r);
    } else {
        /* no gravity estimate (a zero vector): no correction */
        r[0] = 32767;
        r[1] = r[2] = 0;
    }
    r[3] = 0;
    robust_q_mul(r, x->c, t);
    for (i = 0; i < 4; ++i) {
        x->c[i] = t[i];
    }
    robust_q_renorm(x->c);
    imf_q_snapshot(x->c, ss);
    robust_q_mul(ss, x->s, x->q);
    robust_q_renorm(x->q);
}
#endif

/* levelling (B2's inclination): the smallest rotation r that turns the gravity estimate onto earth
 * z, (1 + u_z, u_y, -u_x, 0) normalised for the unit gravity u in the earth frame, taken
 * into c, then q = c (x) s (sn: s's q15 snapshot); r: what B3 takes */
static void robust_q_level(const imf_robust_imu_q_consts_t *const k,
                           imf_robust_imu_q_state_t *const x, const int16_t sn[4], int16_t r[4])
{
    int16_t ss[4];
    imf_q_snapshot(x->c, ss); /* c's q15 snapshot */
#if IMF_Q_HAS_P8
    if (ROBUST_Q_IS_P8(k)) {
        robust_q_level_p8(x, sn, ss, r);
        return;
    }
#endif
#if IMF_Q_HAS_P32
    robust_q_level_p32(x, ss, r);
#endif
    (void)k;
    (void)sn;
}

/* B3: the correction rate seen in the sensor frame is minus the bias error (Eq. 3.6, with
 * Ki dt = 1 / tau_bias): b -= R(q)^T (2 r1, 2 r2, 0) / tau_bias, in motion after tau_acc.
 * rq: NULL, or where the rotation matrix of q is written (all three rows, for B4) */
static void robust_q_bias(const imf_robust_imu_q_consts_t *const k,
                          imf_robust_imu_q_state_t *const x, const int at_rest, const int16_t r[4],
                          int16_t *const rq)
{
    int16_t ss[4], rm[9], u[3];
    int32_t e[3];
    int i;
    const int p8 = ROBUST_Q_IS_P8(k);
    const int b3 = !at_rest && x->n >= k->n_acc && k->kbias.m != 0;
    const int16_t *const m = rq != NULL ? rq : rm;
    if (b3 || rq != NULL) {
        imf_q_snapshot(x->q, ss);
        robust_q_matrix(ss, rq != NULL ? rq : rm, rq != NULL ? 3 : 2);
    }
    if (!b3) {
        return;
    }
    /* R^T (r1, r2, 0) in q30 (the error is twice that); the 8-bit profile's six products
       inline (the same sums: cycles), the 32-bit profile's by robust_q_rotate16 (flash) */
    if (p8) {
        for (i = 0; i < 3; ++i) {
            e[i] = imf_mul16(m[i], r[1]) + imf_mul16(m[3 + i], r[2]); /* < 2^31 */
        }
    } else {
        u[0] = r[1];
        u[1] = r[2];
        u[2] = 0;
        robust_q_rotate16(m, 1, u, e);
    }
    for (i = 0; i < 3; ++i) {
#if IMF_Q_HAS_P8
        if (p8) {
            /* 8-bit profile: R^T 2 r in q15 (2 r is q15) times kbias, one 16x16 product */
            x->b[i] = imf_sub_sat32(
                x->b[i],
                robust_q_shift_p8(imf_mul16(imf_sat_q15s(imf_rshr32(e[i], 15)), k->kbias.m),
                                  k->kbias.s)); /* imf_scale16's value */
            continue;
        }
#endif
        x->b[i] =
            imf_sub_sat32(x->b[i], imf_scale32_s(imf_add_sat32(e[i], e[i]), k->kbias, 30, 15));
    }
}

/* the end of every update: the output predicted by the latency with the bias-corrected
 * rate, then the clock of the start-up (saturating) */
static void robust_q_output(const imf_robust_imu_q_consts_t *const k,
                            imf_robust_imu_q_state_t *const x, const int16_t gyr[3])
{
    if (k->klat.m != 0) {
        int16_t qs[4];
        robust_q_integrate(ROBUST_Q_IS_P8(k), x->q, gyr, x->b, k->klat, qs);
    }
    if (x->n < k->n_max) {
        x->n++;
    }
}

#endif /* IMF_ROBUST_Q_BLOCKS_H */
