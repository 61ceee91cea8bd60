/*
 * Sensor models and axis alignment (Longbin's Fusion walkthrough). See fusion_calibration.h.
 * Twin: python/imufuse/reference/fusion.py.
 */
#include "fusion_calibration.h"
#include "fusion_ahrs.h"

static imf_fusion_mat_t load_mat(const imf_real *const m)
{
    imf_fusion_mat_t r;
    int i;
    for (i = 0; i < 9; i++) {
        r.m[i] = m[i];
    }
    return r;
}

void imf_fusion_calibrate_inertial(const imf_real *const m, const imf_real *const s,
                                   const imf_real *const b, const imf_real *const in,
                                   imf_real *const out, const size_t n)
{
    const imf_fusion_mat_t mis = load_mat(m);
    const imf_fusion_vec_t sens = { s[0], s[1], s[2] }, off = { b[0], b[1], b[2] };
    size_t k;
    for (k = 0; k < n; k++) {
        const imf_fusion_vec_t u = { in[3 * k], in[3 * k + 1], in[3 * k + 2] };
        /* i_c = M ((i_u - b) .* s) */
        const imf_fusion_vec_t c =
            imf_fusion_mat_mul_vec(&mis, imf_fusion_vec_hadamard(imf_fusion_vec_sub(u, off), sens));
        out[3 * k] = c.x;
        out[3 * k + 1] = c.y;
        out[3 * k + 2] = c.z;
    }
}

void imf_fusion_calibrate_magnetic(const imf_real *const soft_iron, const imf_real *const hard_iron,
                                   const imf_real *const in, imf_real *const out, const size_t n)
{
    const imf_fusion_mat_t soft = load_mat(soft_iron);
    const imf_fusion_vec_t hard = { hard_iron[0], hard_iron[1], hard_iron[2] };
    size_t k;
    for (k = 0; k < n; k++) {
        const imf_fusion_vec_t u = { in[3 * k], in[3 * k + 1], in[3 * k + 2] };
        /* m_c = S (m_u - h) */
        const imf_fusion_vec_t c = imf_fusion_mat_mul_vec(&soft, imf_fusion_vec_sub(u, hard));
        out[3 * k] = c.x;
        out[3 * k + 1] = c.y;
        out[3 * k + 2] = c.z;
    }
}

void imf_fusion_axes_apply(const int *const perm, const int *const negate, const imf_real *const in,
                           imf_real *const out, const size_t n)
{
    size_t k, i;
    for (k = 0; k < n; k++) {
        const imf_real *const u = in + 3 * k;
        imf_real v[3];
        for (i = 0; i < 3; i++) { /* in place (out == in) is allowed */
            v[i] = negate[i] ? -u[perm[i]] : u[perm[i]];
        }
        for (i = 0; i < 3; i++) {
            out[3 * k + i] = v[i];
        }
    }
}

void imf_fusion_compass_headings(const int convention, const imf_real *const acc,
                                 const imf_real *const mag, imf_real *const out, const size_t n,
                                 const int invsqrt)
{
    size_t k;
    for (k = 0; k < n; k++) {
        const imf_fusion_vec_t a = { acc[3 * k], acc[3 * k + 1], acc[3 * k + 2] };
        const imf_fusion_vec_t m = { mag[3 * k], mag[3 * k + 1], mag[3 * k + 2] };
        out[k] = imf_fusion_compass_heading(convention, a, m, invsqrt);
    }
}
