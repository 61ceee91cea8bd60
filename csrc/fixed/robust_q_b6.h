/* B6 of the fixed-point RobustAHRS (robust_q.h, RobustAHRSQ): the magnetometer's offset
 * (hard iron) learnt while the sensor turns, csrc/robust_mag.h's estimator in integers: a
 * Kalman filter of the field h in the inertial frame and the offset o in the sensor frame,
 * m = R(s)^T h + o in units of the first field's norm n0, one axis per sample in turn; the
 * offset in use u (counts) the stored offset until the estimate is trusted and differs from
 * it by more than mag_offset_min, or until the reading's norm shows the stored offset
 * wrong (csrc/robust_mag.h's early use; mn: the norms' low-passes, q26). The same code in both profiles (int32 values times int16
 * factors, imf_mul_32x16). Formats (robust_q.h): h, o q26; P q30; the gains q24; P H^T q29;
 * the innovation's variance q28; the normalised innovation and its mean q16. Private to
 * csrc/fixed/robust_q.c, which includes this file once. Mirrored line for line by
 * python/imufuse/reference/fixed_robust_b6.py. */
#ifndef IMF_ROBUST_Q_B6_H
#define IMF_ROBUST_Q_B6_H

#include "robust_q.h"
#include "robust_q_ops.h"

/* B6's fixed model, csrc/robust_mag.h's in these formats: the prior variance 1 (q30), the
 * offset's variance added after an innovation beyond the gate (0.05, q30), the gate 19 and
 * the mean 8 of the normalised innovation (q16), the weight of its running mean
 * (0.02 = 20972 2^-20), the trusted variance (0.01^2, q30) */
#define ROBUST_Q6_P0 1073741824L
#define ROBUST_Q6_JUMP 53687091L
#define ROBUST_Q6_GATE 1245184L
#define ROBUST_Q6_MEAN 524288L
#define ROBUST_Q6_EW 20972
#define ROBUST_Q6_TRUST 107374L
/* csrc/robust_mag.h's early use of a large offset: the estimate's variance below 0.05^2
 * (q30), the reading's norm through the stored offset moving by more than 0.001 (squared,
 * q26) and four times (squared) more than through the estimate; a switch between the stored
 * offset and the estimate that differ by more than 0.05 of the field (squared, q30) starts
 * B4's reference again */
#define ROBUST_Q6_EARLY 2684355L
#define ROBUST_Q6_NORM2 67109L
#define ROBUST_Q6_RESET2 2684355L

/* B6's rarely run helpers (the norms every third sample, the offset in use) optimised for
 * size on AVR: the program of the 8-bit profile with its inputs fits the ATmega328P's flash
 * at -O2 beside them (the same integer operations, the same values at any level) */
#if defined(__AVR__) && defined(__GNUC__) && !defined(__clang__)
#define ROBUST_Q6_SMALL __attribute__((optimize("Os")))
#else
#define ROBUST_Q6_SMALL
#endif

/* index of P[i][j] in P[21], the covariance's upper triangle by rows */
static const unsigned char robust_q6_pi[6][6] = {
    { 0, 1, 2, 3, 4, 5 },     { 1, 6, 7, 8, 9, 10 },    { 2, 7, 11, 12, 13, 14 },
    { 3, 8, 12, 15, 16, 17 }, { 4, 9, 13, 16, 18, 19 }, { 5, 10, 14, 17, 19, 20 }
};

/* the q-scale of 1 / sqrt(n2) for n2 > 0 (imf_invsqrt_u32's 16 bits rounded to 15) */
static imf_qscale_t robust_q6_invsqrt(const uint32_t n2)
{
    imf_qscale_t r;
    int sh;
    const uint16_t y = imf_invsqrt_u32(n2, &sh); /* in [2^15, 2^16) */
    uint16_t m = (uint16_t)((y >> 1) + (y & 1u));
    if (m >= 32768u) {
        m = 16384u;
        sh--;
    }
    r.m = (int16_t)m;
    r.s = (int16_t)(sh - 1);
    return r;
}

/* a state word pair (mantissa, shift) as a q-scale */
static inline imf_qscale_t robust_q6_scale(const int32_t m, const int32_t s)
{
    imf_qscale_t r;
    r.m = (int16_t)m;
    r.s = (int16_t)s;
    return r;
}

/* counts (int32, within int16) times 1 / n0, q26 */
static IMF_Q_NOINLINE int32_t robust_q6_rel(const int32_t v, const imf_qscale_t inv)
{
    return imf_scale32_s(imf_x32768(imf_sat_q15s(v)), inv, 15, 26);
}

/* start: n0 = |m - u| (n2 its square, counts^2), h = R(s) (m - u) / n0 (c: the rotated
 * reading, q15 counts), o = u / n0, both with the prior variance */
static void robust_q6_start(imf_robust_ahrs_q_state_t *const xm, const int32_t c[3],
                            const uint32_t n2)
{
    const imf_qscale_t inv = robust_q6_invsqrt(n2);
    int sign, k;
    /* n0 = n2 / sqrt(n2), q15 counts (< 2^31: n2 < 2^32; inv.s >= 17: n2 >= 64) */
    const imf_qscale_t n0 =
        robust_q_scale_of(imf_mul_32x16_s((int32_t)(n2 >> 1), inv.m, inv.s - 16), 15, &sign);
    xm->m_n2 = n2 > 2147483647u ? 2147483647L : (int32_t)n2;
    xm->m_im = inv.m;
    xm->m_is = inv.s;
    xm->m_nm = n0.m;
    xm->m_ns = n0.s;
    for (k = 0; k < 3; ++k) {
        xm->hi[k] = imf_scale32_s(c[k], inv, 15, 26);
        xm->hi[3 + k] = robust_q6_rel(xm->u[k], inv);
    }
    for (k = 0; k < 21; ++k) {
        xm->P[k] = 0;
    }
    for (k = 0; k < 6; ++k) {
        xm->P[robust_q6_pi[k][k]] = ROBUST_Q6_P0;
    }
    xm->m_ew = 65536L;
    xm->m_d2 = 0;
    xm->mn[0] = 67108864L; /* 1, q26 */
    xm->mn[1] = 0;
    xm->mn[2] = 67108864L;
    xm->mn[3] = 0;
}

/* the exponent e >= 0 that brings every v[k] (rounded, shifted by e) within +-32767
 * (|v| >> e at most 32766) */
static int robust_q6_exponent(const int32_t v[6])
{
    int32_t mx = 0;
    int e = 0, k;
    for (k = 0; k < 6; ++k) {
        const int32_t a = v[k] < 0 ? imf_sub_sat32(0, v[k]) : v[k];
        mx = a > mx ? a : mx;
    }
    while (mx > 32766L) {
        mx >>= 1;
        e++;
    }
    return e;
}

/* imf_mul_32x16(a, b, n), n in [0, 47]: round(a b 2^-n), saturated to int32; the same value
 * on every target. Outside AVR imf_mul_32x16 (inline for its callers' constant n). On AVR
 * through imf_mul_32x16_hi (eight 8x8 products on call-clobbered registers, then the
 * rounding shift by n - 16), which takes n > 16 only: a smaller n with
 * -2^(14+n) <= a < 2^(14+n) as a 2^(17-n) (within int32) times b over 2^17, the same exact
 * product rounded once (|a b 2^-n| <= 2^29: no saturation either way); the rest (a larger a)
 * imf_mul_32x16 itself. Its n <= 16 code is the slow one (imf_mul_32x16_lo for a run-time n:
 * the high part doubled bit by bit, the low part shifted by a loop, ten registers saved;
 * inline for n = 16 a loop of 15 bit steps on the low part). */
static inline int32_t robust_q6_mul(const int32_t a, const int16_t b, const int n)
{
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
    if (n > 16 && n <= 47) {
        return imf_mul_32x16_hi(a, b, n);
    }
    if (n >= 0 && n <= 16) {
        const int32_t lim = (int32_t)imf_lsl32(1u, 14 + n);
        if (a >= -lim && a < lim) {
            return imf_mul_32x16_hi((int32_t)imf_lsl32((uint32_t)a, 17 - n), b, 17);
        }
    }
    return imf_mul_32x16_v(a, b, n);
#else
    return imf_mul_32x16(a, b, n);
#endif
}

/* out[k] = robust_q6_mul(a[k], b, n), k < 6, n in [0, 47] (out may be a) */
static IMF_Q_NOINLINE void robust_q6_mul6(int32_t out[6], const int32_t a[6], const int16_t b,
                                          const int n)
{
    int k;
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
    if (n >= 0 && n <= 16) {
        const int32_t lim = (int32_t)imf_lsl32(1u, 14 + n);
        for (k = 0; k < 6; ++k) {
            out[k] = a[k] >= -lim && a[k] < lim
                         ? imf_mul_32x16_hi((int32_t)imf_lsl32((uint32_t)a[k], 17 - n), b, 17)
                         : imf_mul_32x16_v(a[k], b, n);
        }
        return;
    }
#endif
    for (k = 0; k < 6; ++k) {
        out[k] = imf_mul_32x16_s(a[k], b, n);
    }
}

/* P H^T (q29) for the row H = (c, e_i) into ph[0..5], then H P H^T = H (P H^T) (q28) into
 * ph[6]: each (P H^T)[j] = P[j][3 + i] / 2 + sum_k P[j][k] c[k] 2^-16, the products rounded,
 * the sums saturated in this order; one loop, out of line (inlined in robust_q6_axis,
 * avr-gcc spilled around every product) */
static IMF_Q_NOINLINE void robust_q6_ph(const int32_t P[21], const int i, const int16_t c[3],
                                        int32_t ph[7])
{
    int j, k;
    for (j = 0; j < 7; ++j) {
        const int32_t *const v = j < 6 ? P : ph;
        const unsigned char *const t = robust_q6_pi[j < 6 ? j : 0]; /* row 0: 0 to 5 */
        int32_t a = imf_rshr32(v[t[3 + i]], 1);
        for (k = 0; k < 3; ++k) {
            a = imf_add_sat32(a, robust_q6_mul(v[t[k]], c[k], 16));
        }
        ph[j] = a;
    }
}

/* P -= kk p16^T 2^-n, rounded, saturated, on the upper triangle (P[21] by rows: P[0] to
 * P[20] in turn); n in [0, 47]. On AVR, for n <= 16 and every kk[k] within +-2^(14+n),
 * kk 2^(17-n) with n = 17: the same values, each product through imf_mul_32x16_hi */
static IMF_Q_NOINLINE void robust_q6_cov(int32_t P[21], const int32_t kk[6], const int16_t p16[6],
                                         const int n)
{
    int32_t kx[6];
    int j, k, t = 0, nx = n;
    for (k = 0; k < 6; ++k) {
        kx[k] = kk[k];
    }
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
    if (n >= 0 && n <= 16) {
        const int32_t lim = (int32_t)imf_lsl32(1u, 14 + n);
        for (k = 0; k < 6 && kk[k] >= -lim && kk[k] < lim; ++k) {
        }
        if (k == 6) {
            for (k = 0; k < 6; ++k) {
                kx[k] = (int32_t)imf_lsl32((uint32_t)kk[k], 17 - n);
            }
            nx = 17;
        }
    }
#endif
    for (j = 0; j < 6; ++j) {
        for (k = j; k < 6; ++k) {
            P[t] = imf_sub_sat32(P[t], imf_mul_32x16_s(kx[k], p16[j], nx));
            t++;
        }
    }
}

/* the scalar update of axis i: measurement y (q26) with noise rr (q28), H = (c, e_i) */
static IMF_Q_NOINLINE void robust_q6_axis(imf_robust_ahrs_q_state_t *const xm, const int i,
                                          const int16_t c[3], const int32_t y, const int32_t rr)
{
    int32_t ph[7], kk[6], d[6], sv, hx, nu, nn;
    int16_t p16[6];
    imf_qscale_t ri, nq;
    int j, k, sign, e, n;
    robust_q6_ph(xm->P, i, c, ph); /* P H^T, q29; H P H^T, q28 */
    sv = ph[6];
    hx = xm->hi[3 + i]; /* H x, q26 */
    for (k = 0; k < 3; ++k) {
        hx = imf_add_sat32(hx, robust_q6_mul(xm->hi[k], c[k], 15));
    }
    /* + rr: at least rr (P's rounding may leave H P H^T a few LSB below 0) */
    sv = sv > 0 ? imf_add_sat32(sv, rr) : rr;
    nu = imf_sub_sat32(y, hx);
    ri = robust_q_recip((uint32_t)sv, 0); /* 1 / sv, sv >= mag_noise^2 >= 2^-14 */
    nq = robust_q_scale_of(nu, 26, &sign);
    robust_q6_mul6(kk, ph, ri.m, ri.s - 23); /* K, q24 */
    robust_q6_mul6(d, kk, nq.m, nq.s - 2);   /* K |nu|, q26 */
    for (j = 0; j < 6; ++j) {
        xm->hi[j] = imf_add_sat32(xm->hi[j], sign < 0 ? imf_sub_sat32(0, d[j]) : d[j]);
    }
    /* P -= P H^T K^T: P H^T narrowed to int16 with one exponent e, times K (q24) */
    e = robust_q6_exponent(ph);
    for (j = 0; j < 6; ++j) {
        p16[j] = (int16_t)imf_rshr32(ph[j], e);
    }
    robust_q6_cov(xm->P, kk, p16, 23 - e);
    /* the normalised innovation nu^2 / sv, q16 */
    nn = imf_mul16(nq.m, nq.m);
    n = ri.s + 2 * nq.s - 44;
    if (nq.m == 0) {
        xm->m_d2 = 0;
    } else if (n < 0) {
        xm->m_d2 = IMF_INT32_MAX;
    } else {
        xm->m_d2 = imf_mul_32x16_s(nn, ri.m, n > 47 ? 47 : n);
    }
    xm->m_ew =
        imf_add_sat32(xm->m_ew, imf_mul_32x16(imf_sub_sat32(xm->m_d2, xm->m_ew), ROBUST_Q6_EW, 20));
}

/* predict (the field and the offset walk; after an innovation beyond the gate the offset
 * may have jumped), then the measurement y of axis i (c: column i of R(s)), its noise
 * growing with the rate: w2 = |gyr|^2, counts^2 */
static void robust_q6_update(const imf_robust_ahrs_q_consts_t *const k,
                             imf_robust_ahrs_q_state_t *const xm, const int i, const int16_t c[3],
                             const int32_t y, const uint32_t w2)
{
    int32_t pb, rr, qo;
    int j;
    qo = (xm->m_qo & 65535L) + k->kqo; /* the offset's walk, q46: its whole q30 LSBs added */
    xm->m_qo = qo & 65535L;
    qo >>= 16;
    for (j = 0; j < 6; ++j) {
        pb = imf_add_sat32(xm->P[robust_q6_pi[j][j]], j < 3 ? k->kqh : qo);
        if (j >= 3 && xm->m_d2 > ROBUST_Q6_GATE && pb < ROBUST_Q6_P0) {
            pb = imf_add_sat32(pb, ROBUST_Q6_JUMP);
        }
        xm->P[robust_q6_pi[j][j]] = pb;
    }
    rr = 0;
    if (k->klag2.m != 0) {
        rr = imf_mul_32x16_s((int32_t)(w2 >> 1), k->klag2.m, k->klag2.s - 29); /* q28 */
        if (rr > 268435456L) {
            rr = 268435456L;
        }
    }
    robust_q6_axis(xm, i, c, y, imf_add_sat32(k->knoise2, rr));
    xm->m_axis = i == 2 ? 0 : i + 1;
}

/* d times 3 k (the gain of three samples of k, within k^2), saturated */
static IMF_Q_NOINLINE ROBUST_Q6_SMALL int32_t robust_q6_k3(const int32_t d, const imf_qscale_t k)
{
    const int32_t p = imf_mul_32x16_s(d, k.m, k.s);
    return imf_add_sat32(imf_add_sat32(p, p), p);
}

/* the norm of v - c (v, c: three words relative to n0, q26; through q12 components) into a
 * low-pass w[0] (q26) and the square of its deviation from that low-pass into a low-pass w[1]
 * (q26), the gain 3 k; a norm below 2^-9 counts as 0 */
static IMF_Q_NOINLINE ROBUST_Q6_SMALL void robust_q6_norm_lp(int32_t w[2], const int32_t v[3],
                                                             const int32_t c[3],
                                                             const imf_qscale_t k)
{
    uint32_t n2 = 0u;
    int32_t nrm = 0, d;
    int16_t a;
    int j;
    for (j = 0; j < 3; ++j) {
        a = imf_sat_q15s(imf_rshr32(imf_sub_sat32(v[j], c[j]), 14)); /* q12 */
        n2 += (uint32_t)imf_mul16(a, a);                             /* q24, below 3 2^30 */
    }
    if (n2 >= 64u) {
        const imf_qscale_t r = robust_q6_invsqrt(n2);             /* shift 17 .. 31 */
        nrm = imf_mul_32x16_s((int32_t)(n2 >> 1), r.m, r.s - 15); /* sqrt(n2) 2^14 */
    }
    d = imf_sub_sat32(nrm, w[0]);
    w[0] = imf_add_sat32(w[0], robust_q6_k3(d, k));
    a = imf_sat_q15s(imf_rshr32(d, 13)); /* q13 */
    w[1] = imf_add_sat32(w[1], robust_q6_k3(imf_sub_sat32(imf_mul16(a, a), w[1]), k));
}

/* the offset's largest variance. The offset in use u: trusted and consistent, the stored
 * offset while the estimate agrees with it within mag_offset_min, else the estimate;
 * consistent but not yet trusted, the estimate when its variance is below EARLY, the
 * reading's norm says the stored offset, still in use, is wrong (NORM2, four times) and the
 * estimate differs from it by more than mag_offset_min. A switch between the two beyond
 * RESET2 starts B4's reference again (rn 0; the float filter tests any change of u, also
 * from one estimate to another, which is rare: a magnet attached after one was learnt). */
static IMF_Q_NOINLINE ROBUST_Q6_SMALL void robust_q6_use(const imf_robust_ahrs_q_consts_t *const k,
                                                         imf_robust_ahrs_q_state_t *const xm)
{
    const imf_qscale_t inv = robust_q6_scale(xm->m_im, xm->m_is);
    const imf_qscale_t n0 = robust_q6_scale(xm->m_nm, xm->m_ns);
    int32_t pb = 0;
    uint32_t o2 = 0u;
    int j, same, trust;
    for (j = 3; j < 6; ++j) {
        pb = xm->P[robust_q6_pi[j][j]] > pb ? xm->P[robust_q6_pi[j][j]] : pb;
    }
    xm->m_var = pb;
    if (!(xm->m_ew < ROBUST_Q6_MEAN)) {
        return;
    }
    trust = pb < ROBUST_Q6_TRUST;
    for (j = 0; j < 3 && xm->u[j] == xm->so[j]; ++j) {
    }
    same = j == 3; /* the stored offset in use */
    if (!(trust
          || (pb < ROBUST_Q6_EARLY && same && xm->n_dist == 0 && xm->mn[1] > ROBUST_Q6_NORM2
              && xm->mn[3] < (xm->mn[1] >> 2)))) {
        return;
    }
    for (j = 0; j < 3; ++j) {
        const int16_t e =
            imf_qn_to_q15s(imf_sub_sat32(xm->hi[3 + j], robust_q6_rel(xm->so[j], inv)), 26);
        o2 += (uint32_t)imf_mul16(e, e);
    }
    if (o2 < (uint32_t)k->kmin2 && !trust) {
        return; /* early: only an estimate that differs from the stored offset */
    }
    for (j = 0; j < 3; ++j) {
        xm->u[j] = o2 < (uint32_t)k->kmin2 ? xm->so[j]
                                           : imf_sat_q15s(imf_scale32_s(xm->hi[3 + j], n0, 26, 0));
    }
    /* a switch between the stored offset and the estimate (o2 their difference, q30) beyond
       RESET2: B4's reference from the next reading */
    if (same != (o2 < (uint32_t)k->kmin2) && o2 > (uint32_t)ROBUST_Q6_RESET2) {
        xm->rn = 0;
    }
}

/* column i of R(s), the row of axis i in m = R^T h + o: robust_q_matrix's r[3 j + i]
 * (j = 0, 1, 2), the same values from 6 of its 10 products: the diagonal
 * 2 (w^2 + q_i^2) - 1, the others 2 (q_j q_i + w q_k) for j = i + 1 (mod 3), else
 * 2 (q_j q_i - w q_k), k = 3 - i - j the third axis; q29 -> q15 */
static IMF_Q_NOINLINE void robust_q6_column(const int16_t qs[4], const int i, int16_t c[3])
{
    int j;
    for (j = 0; j < 3; ++j) {
        const int32_t p = imf_mul16(qs[1 + j], qs[1 + i]);
        const int32_t t = imf_mul16(qs[0], qs[j == i ? 0 : 4 - i - j]); /* w^2, or w q_k */
        const int32_t v = j == i ? t + p - 536870912L : j - i == 1 || j - i == -2 ? p + t : p - t;
        c[j] = imf_qn_to_q15s(v, 29);
    }
}

/* the field unit's words within the ranges start() gives them: n0^2 > 0, 1 / n0 and n0 as
 * q-scales with shifts in [16, 31] and [-2, 12] (n0 from 8 to 56756 counts) */
static int robust_q6_started(const imf_robust_ahrs_q_state_t *const xm)
{
    return xm->m_n2 > 0 && xm->m_im >= 16384L && xm->m_im <= 32767L && xm->m_is >= 16
           && xm->m_is <= 31 && xm->m_nm >= 16384L && xm->m_nm <= 32767L && xm->m_ns >= -2
           && xm->m_ns <= 12;
}

/* B6: one reading (mag; all zero: none) into the estimator, then the offset in use u. gyr:
 * this sample's rate (the measurement noise grows with it), counts */
static IMF_Q_NOINLINE void robust_q_offset(const imf_robust_ahrs_q_consts_t *const k,
                                           imf_robust_ahrs_q_state_t *const xm,
                                           const int16_t gyr[3], const int16_t mag[3])
{
    const int i = xm->m_axis == 1 ? 1 : xm->m_axis == 2 ? 2 : 0;
    int16_t qs[4], r[9], m[3], c[3];
    int32_t cr[3];
    uint32_t n2;
    int j;
    if (!IMF_ROBUST_Q_B6 || !k->learn || (mag[0] == 0 && mag[1] == 0 && mag[2] == 0)) {
        return; /* B6 off (or not compiled in), or no reading */
    }
    if (xm->m_n2 != 0 && !robust_q6_started(xm)) {
        xm->m_n2 = 0; /* a unit out of its ranges (a state written by hand): start again */
    }
    if (xm->m_n2 != 0) {
        /* the reading against the field unit: absurd readings are not used */
        n2 = robust_q_norm2(mag[0], mag[1], mag[2]);
        if (!((n2 >> 6) <= (uint32_t)xm->m_n2 && n2 >= ((uint32_t)xm->m_n2 >> 6))) {
            if (xm->m_bad < k->n_bad) {
                xm->m_bad++;
            }
            if (xm->m_bad >= k->n_bad) {
                xm->m_n2 = 0;
                xm->m_bad = 0;
            }
            return;
        }
        xm->m_bad = 0;
    }
    imf_q_snapshot(xm->imu.s, qs); /* R(s), sensor -> inertial frame */
    if (xm->m_n2 == 0) {
        for (j = 0; j < 3; ++j) {
            m[j] = imf_sat_q15s(imf_sub_sat32(mag[j], xm->u[j]));
        }
        n2 = robust_q_norm2(m[0], m[1], m[2]);
        if (n2 < 64u) {
            return; /* below 8 counts: no field to start from */
        }
        robust_q_matrix(qs, r, 3);
        robust_q_rotate16(r, 0, m, cr); /* the field in the inertial frame, q15 counts */
        robust_q6_start(xm, cr, n2);
    } else {
        robust_q6_column(qs, i, c);
        robust_q6_update(k, xm, i, c, robust_q6_rel(mag[i], robust_q6_scale(xm->m_im, xm->m_is)),
                         robust_q_norm2(gyr[0], gyr[1], gyr[2]));
        if (i == 2) {
            /* how well the offset in use and the estimate each explain the reading's norm
               (the reading, u and the estimate relative to n0), with the axis cycle: every
               third sample, the gain of three samples of k_mag */
            const imf_qscale_t inv = robust_q6_scale(xm->m_im, xm->m_is);
            int32_t rm[3], ru[3];
            for (j = 0; j < 3; ++j) {
                rm[j] = robust_q6_rel(mag[j], inv);
                ru[j] = robust_q6_rel(xm->u[j], inv);
            }
            robust_q6_norm_lp(xm->mn, rm, ru, k->k_mag);
            robust_q6_norm_lp(xm->mn + 2, rm, xm->hi + 3, k->k_mag);
        }
    }
    robust_q6_use(k, xm);
}

#endif /* IMF_ROBUST_Q_B6_H */
