/*
 * Mahony DCM filter with Premerlani & Bizard re-orthogonalisation, article
 * 4.1 and 4.3. See dcm.h. The pure-Python twin is
 * python/imufuse/reference/dcm.py.
 */
#include "dcm.h"
#include "imf_math.h"

/* |v| <= tol, without fabs (avr-libc's fabsf is the double fabs) */
static int dcm_small(const imf_real v)
{
    return v >= -IMF_DCM_ORTHO_TOL && v <= IMF_DCM_ORTHO_TOL;
}

/* R orthonormal within IMF_DCM_ORTHO_TOL (and therefore finite). */
static int dcm_orthonormal(const imf_dcm_state_t *const r)
{
    const imf_real nx = r->r00 * r->r00 + r->r01 * r->r01 + r->r02 * r->r02;
    const imf_real ny = r->r10 * r->r10 + r->r11 * r->r11 + r->r12 * r->r12;
    const imf_real nz = r->r20 * r->r20 + r->r21 * r->r21 + r->r22 * r->r22;
    const imf_real xy = r->r00 * r->r10 + r->r01 * r->r11 + r->r02 * r->r12;
    const imf_real xz = r->r00 * r->r20 + r->r01 * r->r21 + r->r02 * r->r22;
    const imf_real yz = r->r10 * r->r20 + r->r11 * r->r21 + r->r12 * r->r22;
    return dcm_small(nx - IMF_R(1.0)) && dcm_small(ny - IMF_R(1.0)) && dcm_small(nz - IMF_R(1.0))
           && dcm_small(xy) && dcm_small(xz) && dcm_small(yz);
}

void imf_dcm_default_settings(imf_dcm_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->kp = IMF_R(0.5);
    settings->ki = IMF_R(0.0);
}

void imf_dcm_init(imf_dcm_t *const self, const imf_dcm_settings_t *const s)
{
    self->kp = s->kp;
    self->ki = s->ki;
    imf_dcm_set_dt(self, s->dt);
    self->skipped = 0;
    self->x.r00 = IMF_R(1.0);
    self->x.r01 = IMF_R(0.0);
    self->x.r02 = IMF_R(0.0);
    self->x.r10 = IMF_R(0.0);
    self->x.r11 = IMF_R(1.0);
    self->x.r12 = IMF_R(0.0);
    self->x.r20 = IMF_R(0.0);
    self->x.r21 = IMF_R(0.0);
    self->x.r22 = IMF_R(1.0);
    self->x.ix = IMF_R(0.0);
    self->x.iy = IMF_R(0.0);
    self->x.iz = IMF_R(0.0);
}

void imf_dcm_set_dt(imf_dcm_t *const self, const imf_real dt)
{
    self->dt = dt;
    self->ki_dt = self->ki * dt;
}

void imf_dcm_set_attitude(imf_dcm_t *const self, const imf_attitude_t *const att)
{
    self->x.r00 = att->r[0];
    self->x.r01 = att->r[1];
    self->x.r02 = att->r[2];
    self->x.r10 = att->r[3];
    self->x.r11 = att->r[4];
    self->x.r12 = att->r[5];
    self->x.r20 = att->r[6];
    self->x.r21 = att->r[7];
    self->x.r22 = att->r[8];
}

void imf_dcm_update(imf_dcm_t *const self, const imf_real gx, const imf_real gy, const imf_real gz,
                    const imf_real ax, const imf_real ay, const imf_real az)
{
    const imf_dcm_state_t *const r = &self->x;
    imf_real n2, norm, nx, ny, nz, wx, wy, wz, hx, hy, hz;
    imf_real ex = IMF_R(0.0), ey = IMF_R(0.0), ez = IMF_R(0.0);
    imf_real ix = r->ix, iy = r->iy, iz = r->iz;
    imf_real x0, x1, x2, y0, y1, y2, z0, z1, z2, dr, sx, sy;
    imf_dcm_state_t out;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az))) {
        self->skipped++;
        return;
    }
    n2 = ax * ax + ay * ay + az * az;
    if (n2 > IMF_R(0.0) && isfinite(n2)) {
        norm = imf_sqrt(n2);
        nx = ax / norm;
        ny = ay / norm;
        nz = az / norm;
        /* 4.1 steps 2-3: e = a x d with d = r_z */
        ex = ny * r->r22 - nz * r->r21;
        ey = nz * r->r20 - nx * r->r22;
        ez = nx * r->r21 - ny * r->r20;
        /* step 4: I_n = I_{n-1} + Ki dt e */
        ix = ix + self->ki_dt * ex;
        iy = iy + self->ki_dt * ey;
        iz = iz + self->ki_dt * ez;
    }
    /* step 5: w' = w + Kp e + I_n */
    wx = gx + (self->kp * ex + ix);
    wy = gy + (self->kp * ey + iy);
    wz = gz + (self->kp * ez + iz);
    /* step 6: R_n = R_{n-1} + R_{n-1} (w' dt)_x; row by row r + r x (w' dt) */
    hx = wx * self->dt;
    hy = wy * self->dt;
    hz = wz * self->dt;
    x0 = r->r00 + (r->r01 * hz - r->r02 * hy);
    x1 = r->r01 + (r->r02 * hx - r->r00 * hz);
    x2 = r->r02 + (r->r00 * hy - r->r01 * hx);
    y0 = r->r10 + (r->r11 * hz - r->r12 * hy);
    y1 = r->r11 + (r->r12 * hx - r->r10 * hz);
    y2 = r->r12 + (r->r10 * hy - r->r11 * hx);
    /* 4.3 step 1: dr = 1/2 r_x . r_y */
    dr = IMF_R(0.5) * (x0 * y0 + x1 * y1 + x2 * y2);
    /* step 2: r_x' = r_x - dr r_y, r_y' = r_y - dr r_x (both from the old pair) */
    out.r00 = x0 - dr * y0;
    out.r01 = x1 - dr * y1;
    out.r02 = x2 - dr * y2;
    out.r10 = y0 - dr * x0;
    out.r11 = y1 - dr * x1;
    out.r12 = y2 - dr * x2;
    /* step 3: Taylor normalisation r'' = 1/2 (3 - |r'|^2) r' */
    sx = IMF_R(0.5) * (IMF_R(3.0) - (out.r00 * out.r00 + out.r01 * out.r01 + out.r02 * out.r02));
    sy = IMF_R(0.5) * (IMF_R(3.0) - (out.r10 * out.r10 + out.r11 * out.r11 + out.r12 * out.r12));
    out.r00 = sx * out.r00;
    out.r01 = sx * out.r01;
    out.r02 = sx * out.r02;
    out.r10 = sy * out.r10;
    out.r11 = sy * out.r11;
    out.r12 = sy * out.r12;
    /* step 4: r_z'' = r_x'' x r_y'' (the integrated r_z is discarded) */
    z0 = out.r01 * out.r12 - out.r02 * out.r11;
    z1 = out.r02 * out.r10 - out.r00 * out.r12;
    z2 = out.r00 * out.r11 - out.r01 * out.r10;
    out.r20 = z0;
    out.r21 = z1;
    out.r22 = z2;
    out.ix = ix;
    out.iy = iy;
    out.iz = iz;
    /* valid-attitude policy (imf_math.h): R stays orthonormal, I finite */
    if (!(dcm_orthonormal(&out) && imf_finite3(ix, iy, iz))) {
        self->skipped++;
        return;
    }
    self->x = out;
}

void imf_dcm_angles(const imf_dcm_t *const self, double *const roll, double *const pitch)
{
    imf_tilt_angles((double)self->x.r20, (double)self->x.r21, (double)self->x.r22, roll, pitch);
}
