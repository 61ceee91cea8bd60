/* B4 of the fixed-point RobustAHRS (robust_q.h, RobustAHRSQ): the magnetometer confined to
 * heading, one function a step, named as csrc/robust.c's (the field, its test against the
 * reference, the reference learnt, the candidate of a new field, the field used, the
 * heading turned; robust_q_magnetometer composes them). Private to
 * csrc/fixed/robust_q.c, which includes this file once (static functions, one translation
 * unit: the filter is one source for the harnesses). Mirrored line for line by
 * python/imufuse/reference/fixed_robust_mag.py. */
#ifndef IMF_ROBUST_Q_MAG_H
#define IMF_ROBUST_Q_MAG_H

#include "robust_q.h"
#include "robust_q_ops.h"

/* the field matches the reference (n, h, z): norm within mag_norm n and dip within
 * mag_dip (the sine of the dip difference: zn h - hn z, q30) */
static IMF_Q_NOINLINE int robust_q_mag_test(const imf_robust_ahrs_q_consts_t *const k,
                                            const int32_t mn, const int16_t hn, const int16_t zn,
                                            const int32_t n, const int32_t h, const int32_t z)
{
    const int32_t dn = imf_sub_sat32(mn, n);
    const int32_t tn = imf_scale32_s(n, k->knorm, 15, 15);
    const int32_t dd = imf_mul16(zn, imf_qn_to_q15s(h, 30)) - imf_mul16(hn, imf_qn_to_q15s(z, 30));
    return dn < tn && imf_sub_sat32(0, dn) < tn && dd < k->kdip && -dd < k->kdip;
}

/* B4's field me (q15 counts, earth frame): its unit vector u, its norm mn = m . u (q15
 * counts) and the horizontal direction ch; returns 0 for no usable reading, else 1, horiz
 * 0 where the field is vertical (ch then undefined) */
static int robust_q_mag_field(const int p8, int32_t me[3], int16_t u[3], int16_t ch[3],
                              int32_t *const mn, int *const horiz)
{
    int i;
    *mn = 0;
#if IMF_Q_HAS_P8
    if (p8) {
        /* 8-bit profile: u from me's 15 leading bits w (exponent e; robust_q_unit16_p8),
           |m| = w . u 2^(e - 15) (|w . u| <= |w| < 2^31); the horizontal direction from
           u's (robust_q_unit16_p8: the half angle of the heading below needs the norm of
           the 32-bit profile's too) */
        int16_t w[3];
        const int e = robust_q_exponent_p8(me, 3);
        robust_q_narrow_p8(me, 3, e, w);
        if (!robust_q_unit16_p8(w, u)) {
            return 0; /* no usable reading: gyro and accelerometer only */
        }
        *mn = robust_q_shift_p8(
            imf_mul16(w[0], u[0]) + imf_mul16(w[1], u[1]) + imf_mul16(w[2], u[2]), 15 - e);
        w[0] = u[0];
        w[1] = u[1];
        w[2] = 0;
        *horiz = robust_q_unit16_p8(w, ch);
        return 1;
    }
#endif
#if IMF_Q_HAS_P32
    if (!robust_q_unit(me, u)) {
        return 0; /* no usable reading: gyro and accelerometer only */
    }
    for (i = 0; i < 3; ++i) {
        *mn = imf_add_sat32(*mn, imf_q_mul_hq_p32(me[i], u[i]));
    }
    me[2] = 0;
    *horiz = robust_q_unit(me, ch);
#endif
    (void)p8;
    (void)i;
    return 1;
}

/* the field (mn, hn, zn) tested against the reference, the first reading taken as it;
 * returns 1 where it is used: matching for mag_hold */
static int robust_q_mag_match(const imf_robust_ahrs_q_consts_t *const k,
                              imf_robust_ahrs_q_state_t *const xm, const int32_t mn,
                              const int16_t hn, const int16_t zn)
{
    int match;
    if (xm->rn == 0) {
        /* first reading: it is the reference */
        xm->rn = xm->cn = mn;
        xm->rh = xm->ch = imf_x32768(hn);
        xm->rz = xm->cz = imf_x32768(zn);
        xm->n_ok = k->n_hold;
    }
    match = robust_q_mag_test(k, mn, hn, zn, xm->rn, xm->rh, xm->rz);
    if (!match) {
        xm->n_ok = 0;
    } else if (xm->n_ok < k->n_hold) {
        xm->n_ok++;
    }
    return match && xm->n_ok >= k->n_hold;
}

/* an undisturbed field (mn, hn, zn): the reference learnt from it, the candidate it */
static void robust_q_mag_reference(const imf_robust_ahrs_q_consts_t *const k,
                                   imf_robust_ahrs_q_state_t *const xm, const int32_t mn,
                                   const int16_t hn, const int16_t zn)
{
    const imf_qscale_t kk = robust_q_gain(ROBUST_Q_IS_P8(&k->imu), xm->imu.n, k->n_ref, k->k_ref);
    xm->n_dist = 0;
    xm->n_cand = 0;
    xm->rn = imf_add_sat32(xm->rn, imf_scale32_s(imf_sub_sat32(mn, xm->rn), kk, 15, 15));
    xm->rh = robust_q_lowpass(xm->rh, hn, kk);
    xm->rz = robust_q_lowpass(xm->rz, zn, kk);
    xm->cn = mn;
    xm->ch = imf_x32768(hn);
    xm->cz = imf_x32768(zn);
}

/* disturbed (or not yet matching for mag_hold): no heading correction; a new field (mn, hn,
 * zn) that stays the same for mag_new_time of motion becomes the reference */
static void robust_q_mag_candidate(const imf_robust_ahrs_q_consts_t *const k,
                                   imf_robust_ahrs_q_state_t *const xm, const int32_t mn,
                                   const int16_t hn, const int16_t zn)
{
    imf_robust_imu_q_state_t *const x = &xm->imu;
    if (xm->n_dist < 1073741824L) {
        xm->n_dist++;
    }
    if (robust_q_mag_test(k, mn, hn, zn, xm->cn, xm->ch, xm->cz)) {
        const imf_qscale_t kr = k->imu.k_rest;
        xm->cn = imf_add_sat32(xm->cn, imf_scale32_s(imf_sub_sat32(mn, xm->cn), kr, 15, 15));
        xm->ch = robust_q_lowpass(xm->ch, hn, kr);
        xm->cz = robust_q_lowpass(xm->cz, zn, kr);
        if (x->n_rest < k->imu.n_rest && xm->n_cand < k->n_new) {
            /* only motion counts: at rest an attached magnet's field is steady too */
            xm->n_cand++;
        }
        if (xm->n_cand >= k->n_new) {
            xm->rn = xm->cn;
            xm->rh = xm->ch;
            xm->rz = xm->cz;
            xm->n_cand = 0;
        }
    } else {
        xm->cn = mn;
        xm->ch = imf_x32768(hn);
        xm->cz = imf_x32768(zn);
        xm->n_cand = 0;
    }
}

/* B4: the disturbance detector. The field (mn, hn, zn) is used (returns 1) when it has
 * matched the reference for mag_hold, and the reference learns it; otherwise (disturbed) a
 * new field that stays the same for mag_new_time of motion becomes the reference */
static int robust_q_field_used(const imf_robust_ahrs_q_consts_t *const k,
                               imf_robust_ahrs_q_state_t *const xm, const int32_t mn,
                               const int16_t hn, const int16_t zn)
{
    if (robust_q_mag_match(k, xm, mn, hn, zn)) {
        robust_q_mag_reference(k, xm, mn, hn, zn);
        return 1;
    }
    robust_q_mag_candidate(k, xm, mn, hn, zn);
    return 0;
}

/* heading: the rotation about earth z that turns the horizontal field ch onto north (+x),
 * (1 + cos, 0, 0, -sin) normalised, taken by the fraction k: (1 + k (f_w - 1), k f_z),
 * normalised with c and q */
static void robust_q_heading(const imf_robust_ahrs_q_consts_t *const k,
                             imf_robust_imu_q_state_t *const x, const int16_t ch[3])
{
    int16_t f[3];
    const int p8 = ROBUST_Q_IS_P8(&k->imu);
    const imf_qscale_t kk = robust_q_gain(p8, x->n, k->n_mag, k->k_mag);
#if IMF_Q_HAS_P8
    if (p8) {
        /* 8-bit profile: (1 + cos, -sin) / 2 normalised by imf_q_unit3_p8 (within 1.2e-3:
           the turn's gain); (0, 1) where it is 0, as robust_q_half */
        int16_t w[3];
        w[0] = (int16_t)((32768L + ch[0]) >> 1);
        w[1] = (int16_t)(-(int32_t)ch[1] >> 1);
        w[2] = 0;
        if (!imf_q_unit3_p8(w, f)) {
            f[0] = 0;
            f[1] = 32767;
        }
    }
#endif
#if IMF_Q_HAS_P32
    if (!p8) {
        robust_q_half(ch[0], (int16_t)-ch[1], 0, f);
    }
#endif
#if IMF_Q_HAS_P8
    if (p8) {
        /* 8-bit profile: (dw, dz) = z 2^(15 - kk.s) in q30, z = kk.m (f_w - 1, f_z) 2^-15
           rounded (|z| < 2^15); c and q turned, neither normalised here (the next update
           normalises c and takes q = c (x) s again) */
        int16_t z16[2];
        z16[0] = (int16_t)imf_rshr32(imf_mul16((int16_t)(f[0] - 32768L), kk.m), 15);
        z16[1] = (int16_t)imf_rshr32(imf_mul16(f[1], kk.m), 15);
        robust_q_turn_z_p8(x->c, z16, kk.s - 15);
        robust_q_turn_z_p8(x->q, z16, kk.s - 15);
    }
#endif
#if IMF_Q_HAS_P32
    if (!p8) {
        int32_t dz[2];
        dz[0] = imf_scale32_s((int32_t)f[0] - 32768L, kk, 15, 30);
        dz[1] = imf_scale32_s(f[1], kk, 15, 30);
        robust_q_turn_z(x->c, dz[0], dz[1]);
        robust_q_turn_z(x->q, dz[0], dz[1]);
    }
#endif
}

/* B4: heading from the magnetometer (counts, less the stored offset); rm: R(q), q15. The
 * field's unit vector u, norm mn, the dip's cosine hn = u . ch and sine u_z. Out of line
 * (robust_q_step says why) */
static IMF_Q_NOINLINE void robust_q_magnetometer(const imf_robust_ahrs_q_consts_t *const k,
                                                 imf_robust_ahrs_q_state_t *const xm,
                                                 const int16_t mag[3], const int16_t rm[9])
{
    int16_t m[3], u[3], ch[3], hn;
    int32_t me[3], mn;
    int horiz = 0, i;
    if (mag[0] == 0 && mag[1] == 0 && mag[2] == 0) {
        return; /* no reading: gyro and accelerometer only */
    }
    for (i = 0; i < 3; ++i) {
        /* the reading less the offset in use, counts within +-32767, in the earth frame */
        m[i] = imf_sat_q15s(imf_sub_sat32(mag[i], xm->u[i]));
    }
    robust_q_rotate16(rm, 0, m, me); /* q15 counts */
    if (!robust_q_mag_field(ROBUST_Q_IS_P8(&k->imu), me, u, ch, &mn, &horiz)) {
        return; /* no usable reading: gyro and accelerometer only */
    }
    hn = horiz ? imf_qn_to_q15s(imf_mul16(u[0], ch[0]) + imf_mul16(u[1], ch[1]), 30) : 0;
    if (!robust_q_field_used(k, xm, mn, hn, u[2])) {
        return; /* B4: disturbed */
    }
    if (!horiz) {
        return; /* field vertical: no heading information */
    }
    robust_q_heading(k, &xm->imu, ch);
}

#endif /* IMF_ROBUST_Q_MAG_H */
