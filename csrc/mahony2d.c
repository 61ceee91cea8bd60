/*
 * 2D Mahony filter, article 4.2, Eq. 4.3 / 4.4. See mahony2d.h. The
 * pure-Python twin is python/imufuse/reference/mahony2d.py.
 */
#include "mahony2d.h"
#include "imf_math.h"

void imf_mahony2d_default_settings(imf_mahony2d_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->kp = IMF_R(0.5);
    settings->ki = IMF_R(0.0);
    settings->exact = 0;
}

void imf_mahony2d_init(imf_mahony2d_t *const self, const imf_mahony2d_settings_t *const s)
{
    self->kp = s->kp;
    self->ki = s->ki;
    imf_mahony2d_set_dt(self, s->dt);
    self->exact = s->exact != 0;
    self->d2_max = IMF_R(4.0);
    self->skipped = 0;
    self->x.dx = IMF_R(0.0);
    self->x.dy = IMF_R(0.0);
    self->x.dz = IMF_R(1.0);
    self->x.ix = IMF_R(0.0);
    self->x.iy = IMF_R(0.0);
    self->x.iz = IMF_R(0.0);
}

void imf_mahony2d_set_dt(imf_mahony2d_t *const self, const imf_real dt)
{
    self->dt = dt;
    self->ki_dt = self->ki * dt;
}

void imf_mahony2d_set_attitude(imf_mahony2d_t *const self, const imf_attitude_t *const att)
{
    self->x.dx = att->r[6];
    self->x.dy = att->r[7];
    self->x.dz = att->r[8];
}

void imf_mahony2d_update(imf_mahony2d_t *const self, const imf_real gx, const imf_real gy,
                         const imf_real gz, const imf_real ax, const imf_real ay, const imf_real az)
{
    const imf_real dx = self->x.dx, dy = self->x.dy, dz = self->x.dz;
    imf_real cx, cy, cz, n2, norm, nx, ny, nz, wx, wy, wz;
    imf_real ex = IMF_R(0.0), ey = IMF_R(0.0), ez = IMF_R(0.0);
    imf_real ix = self->x.ix, iy = self->x.iy, iz = self->x.iz;
    imf_real dxn, dyn, dzn;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az))) {
        self->skipped++;
        return;
    }
    /* Eq. 4.2: rate of change of d from the gyro, d x w */
    cx = dy * gz - dz * gy;
    cy = dz * gx - dx * gz;
    cz = dx * gy - dy * gx;
    n2 = ax * ax + ay * ay + az * az;
    if (n2 > IMF_R(0.0) && isfinite(n2)) {
        norm = imf_sqrt(n2);
        nx = ax / norm;
        ny = ay / norm;
        nz = az / norm;
        if (self->exact) {
            /* Eq. 4.3: E = d x (a x d) */
            wx = ny * dz - nz * dy;
            wy = nz * dx - nx * dz;
            wz = nx * dy - ny * dx;
            ex = dy * wz - dz * wy;
            ey = dz * wx - dx * wz;
            ez = dx * wy - dy * wx;
        } else {
            /* Eq. 4.4: E = a - d */
            ex = nx - dx;
            ey = ny - dy;
            ez = nz - dz;
        }
        /* Eq. 3.6 per axis: I_n = I_{n-1} + Ki dt E_n */
        ix = ix + self->ki_dt * ex;
        iy = iy + self->ki_dt * ey;
        iz = iz + self->ki_dt * ez;
    }
    /* Eq. 3.6 per axis: d_n = d_{n-1} + (Kp E_n + I_n + d x w) dt */
    dxn = dx + (self->kp * ex + ix + cx) * self->dt;
    dyn = dy + (self->kp * ey + iy + cy) * self->dt;
    dzn = dz + (self->kp * ez + iz + cz) * self->dt;
    /* Eq. 4.3 only (task T2, see mahony2d.h): E and d x w are perpendicular to
       d, so d keeps its meaning only as a direction; scale it back to unit
       length, where Eq. 4.3's loop gain Kp |d|^2 is Kp. A normalisation that
       fails rejects the sample (imf_math.h). */
    if (self->exact && imf_normalise3(&dxn, &dyn, &dzn, IMF_INVSQRT_EXACT) != IMF_NORM_OK) {
        self->skipped++;
        return;
    }
    /* valid-attitude policy (imf_math.h): d of plausible length, I finite */
    if (!(imf_gravity_ok(dxn, dyn, dzn, self->d2_max) && imf_finite3(ix, iy, iz))) {
        self->skipped++;
        return;
    }
    self->x.dx = dxn;
    self->x.dy = dyn;
    self->x.dz = dzn;
    self->x.ix = ix;
    self->x.iy = iy;
    self->x.iz = iz;
}

void imf_mahony2d_angles(const imf_mahony2d_t *const self, double *const roll, double *const pitch)
{
    imf_tilt_angles((double)self->x.dx, (double)self->x.dy, (double)self->x.dz, roll, pitch);
}
