/*
 * MultiWii 2.2 attitude estimate: the float part of the firmware's
 * getEstimatedAttitude() in its order of operations. See multiwii.h. The
 * pure-Python twin is python/imufuse/reference/multiwii.py.
 */
#include "multiwii.h"
#include "imf_math.h"

void imf_multiwii_default_settings(imf_multiwii_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->cmpf = IMF_R(600.0);
    settings->acc_lpf_shift = 4;
    settings->acc_1g = IMF_R(1.0);
    settings->window = IMF_R(0.15);
}

void imf_multiwii_init(imf_multiwii_t *const self, const imf_multiwii_settings_t *const settings)
{
    const imf_real dt = settings->dt, cmpf = settings->cmpf, acc_1g = settings->acc_1g;
    const imf_real window = settings->window;
    const int acc_lpf_shift = settings->acc_lpf_shift;
    imf_real lo, hi;
    int k;
    imf_multiwii_set_dt(self, dt);
    self->cmpf = cmpf;
    self->inv_cmpf1 = IMF_R(1.0) / (cmpf + IMF_R(1.0));
    /* powers of two: the scalings of the LPF are exact, like the firmware's shifts */
    self->lpf_n = IMF_R(1.0);
    for (k = 0; k < acc_lpf_shift; k++) {
        self->lpf_n = self->lpf_n * IMF_R(2.0);
    }
    self->lpf_inv = IMF_R(1.0) / self->lpf_n;
    /* the window test compares squared magnitudes, like the firmware's accMag */
    lo = (IMF_R(1.0) - window) * acc_1g;
    hi = (IMF_R(1.0) + window) * acc_1g;
    self->mag2_lo = lo * lo;
    self->mag2_hi = hi * hi;
    /* valid attitude: |d| <= 4 g (the filter pulls d towards |a| < 2 g) */
    self->d2_max = (IMF_R(4.0) * acc_1g) * (IMF_R(4.0) * acc_1g);
    self->acc_1g = acc_1g;
    self->skipped = 0;
    self->x.dx = IMF_R(0.0);
    self->x.dy = IMF_R(0.0);
    self->x.dz = acc_1g;
    self->x.ax = IMF_R(0.0);
    self->x.ay = IMF_R(0.0);
    self->x.az = acc_1g;
}

void imf_multiwii_set_dt(imf_multiwii_t *const self, const imf_real dt)
{
    self->dt = dt;
}

void imf_multiwii_set_attitude(imf_multiwii_t *const self, const imf_attitude_t *const att)
{
    self->x.dx = self->acc_1g * att->r[6];
    self->x.dy = self->acc_1g * att->r[7];
    self->x.dz = self->acc_1g * att->r[8];
    self->x.ax = self->x.dx;
    self->x.ay = self->x.dy;
    self->x.az = self->x.dz;
}

void imf_multiwii_update(imf_multiwii_t *const self, const imf_real gx, const imf_real gy,
                         const imf_real gz, const imf_real ax, const imf_real ay, const imf_real az)
{
    imf_real deltax, deltay, deltaz, sx, sy, sz, mag2, dx, dy, dz;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az))) {
        self->skipped++;
        return;
    }
    /* deltaGyroAngle = gyro * scale: the rotation increment first */
    deltax = gx * self->dt;
    deltay = gy * self->dt;
    deltaz = gz * self->dt;
    /* accelerometer LPF: accLPF32 -= accLPF32 >> k; accLPF32 += acc;
       accSmooth = accLPF32 >> k, with accLPF32 = accSmooth 2^k (exact) */
    sx = ((self->x.ax * self->lpf_n - self->x.ax) + ax) * self->lpf_inv;
    sy = ((self->x.ay * self->lpf_n - self->x.ay) + ay) * self->lpf_inv;
    sz = ((self->x.az * self->lpf_n - self->x.az) + az) * self->lpf_inv;
    /* accMag: squared magnitude of the smoothed acceleration, axis 0, 1, 2 */
    mag2 = sx * sx + sy * sy + sz * sz;
    /* rotateV (appendix step 3): d_n = d_{n-1} + d_{n-1} x delta, every
       component from the old d, no renormalisation (task T2 left out) */
    dx = self->x.dx + (self->x.dy * deltaz - self->x.dz * deltay);
    dy = self->x.dy + (self->x.dz * deltax - self->x.dx * deltaz);
    dz = self->x.dz + (self->x.dx * deltay - self->x.dy * deltax);
    /* step 4: complementary filter (d F + a) / (F + 1), only while
       (1 - window) g < |a| < (1 + window) g */
    if (self->mag2_lo < mag2 && mag2 < self->mag2_hi) {
        dx = (dx * self->cmpf + sx) * self->inv_cmpf1;
        dy = (dy * self->cmpf + sy) * self->inv_cmpf1;
        dz = (dz * self->cmpf + sz) * self->inv_cmpf1;
    }
    /* valid-attitude policy (imf_math.h): d of plausible length, LPF finite */
    if (!(imf_gravity_ok(dx, dy, dz, self->d2_max) && imf_finite3(sx, sy, sz))) {
        self->skipped++;
        return;
    }
    self->x.dx = dx;
    self->x.dy = dy;
    self->x.dz = dz;
    self->x.ax = sx;
    self->x.ay = sy;
    self->x.az = sz;
}

void imf_multiwii_angles(const imf_multiwii_t *const self, double *const roll, double *const pitch)
{
    /* step 5, outside the state update */
    imf_tilt_angles((double)self->x.dx, (double)self->x.dy, (double)self->x.dz, roll, pitch);
}
