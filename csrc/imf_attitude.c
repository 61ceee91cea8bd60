/*
 * Initial attitude shared by every 3-D filter. See imf_attitude.h. The
 * pure-Python twin is python/imufuse/reference/attitude.py.
 */
#include "imf_attitude.h"
#include "imf_math.h"

static imf_real attitude_abs(const imf_real x)
{
    return x < IMF_R(0.0) ? -x : x;
}

/* Scale (x, y, z) to unit length, first by its largest magnitude (so that
   neither huge nor subnormal components overflow or underflow the squared
   norm), then by 1/sqrt of the squared norm (1 <= n2 <= 3). Returns 0, the
   vector unchanged, when it is zero or not finite. */
static int attitude_unit3(imf_real *const x, imf_real *const y, imf_real *const z)
{
    imf_real m, n2, r;
    if (!imf_finite3(*x, *y, *z)) {
        return 0;
    }
    m = attitude_abs(*x);
    if (attitude_abs(*y) > m) {
        m = attitude_abs(*y);
    }
    if (attitude_abs(*z) > m) {
        m = attitude_abs(*z);
    }
    if (m == IMF_R(0.0)) {
        return 0;
    }
    *x = *x / m;
    *y = *y / m;
    *z = *z / m;
    n2 = *x * *x + *y * *y + *z * *z;
    r = IMF_R(1.0) / imf_sqrt(n2);
    *x = *x * r;
    *y = *y * r;
    *z = *z * r;
    return 1;
}

/* The same for a quaternion (w, x, y, z). */
static int attitude_unit4(imf_real q[4])
{
    imf_real m, n2, r;
    int i;
    if (!imf_finite4(q[0], q[1], q[2], q[3])) {
        return 0;
    }
    m = IMF_R(0.0);
    for (i = 0; i < 4; i++) {
        if (attitude_abs(q[i]) > m) {
            m = attitude_abs(q[i]);
        }
    }
    if (m == IMF_R(0.0)) {
        return 0;
    }
    for (i = 0; i < 4; i++) {
        q[i] = q[i] / m;
    }
    n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    r = IMF_R(1.0) / imf_sqrt(n2);
    for (i = 0; i < 4; i++) {
        q[i] = q[i] * r;
    }
    return 1;
}

/* Quaternion of the rotation matrix r (Shepperd: from the largest of w^2,
   x^2, y^2, z^2, so that the divisor s is never small), w >= 0, normalised. */
static void attitude_quat_of_matrix(imf_attitude_t *const att)
{
    const imf_real *const r = att->r;
    imf_real *const q = att->q;
    const imf_real t = r[0] + r[4] + r[8];
    imf_real s;
    int i;
    if (t > IMF_R(0.0)) {
        /* s = 4 w */
        s = IMF_R(2.0) * imf_sqrt(IMF_R(1.0) + t);
        q[0] = IMF_R(0.25) * s;
        q[1] = (r[7] - r[5]) / s;
        q[2] = (r[2] - r[6]) / s;
        q[3] = (r[3] - r[1]) / s;
    } else if (r[0] > r[4] && r[0] > r[8]) {
        /* s = 4 x */
        s = IMF_R(2.0) * imf_sqrt(IMF_R(1.0) + r[0] - r[4] - r[8]);
        q[0] = (r[7] - r[5]) / s;
        q[1] = IMF_R(0.25) * s;
        q[2] = (r[1] + r[3]) / s;
        q[3] = (r[2] + r[6]) / s;
    } else if (r[4] > r[8]) {
        /* s = 4 y */
        s = IMF_R(2.0) * imf_sqrt(IMF_R(1.0) + r[4] - r[0] - r[8]);
        q[0] = (r[2] - r[6]) / s;
        q[1] = (r[1] + r[3]) / s;
        q[2] = IMF_R(0.25) * s;
        q[3] = (r[5] + r[7]) / s;
    } else {
        /* s = 4 z */
        s = IMF_R(2.0) * imf_sqrt(IMF_R(1.0) + r[8] - r[0] - r[4]);
        q[0] = (r[3] - r[1]) / s;
        q[1] = (r[2] + r[6]) / s;
        q[2] = (r[5] + r[7]) / s;
        q[3] = IMF_R(0.25) * s;
    }
    if (q[0] < IMF_R(0.0)) {
        for (i = 0; i < 4; i++) {
            q[i] = -q[i];
        }
    }
    (void)attitude_unit4(q);
}

int imf_attitude_from_acc_mag(imf_attitude_t *const att, const imf_real ax, const imf_real ay,
                              const imf_real az, const imf_real mx, const imf_real my,
                              const imf_real mz)
{
    imf_real *const r = att->r;
    imf_real ux = ax, uy = ay, uz = az, wx, wy, wz;
    if (!attitude_unit3(&ux, &uy, &uz)) {
        return 0;
    }
    /* west = up x m, normalised */
    wx = uy * mz - uz * my;
    wy = uz * mx - ux * mz;
    wz = ux * my - uy * mx;
    if (!attitude_unit3(&wx, &wy, &wz)) {
        /* no field, or a vertical one: ZYX yaw 0, west = up x e_x */
        wx = IMF_R(0.0);
        wy = uz;
        wz = -uy;
        if (!attitude_unit3(&wx, &wy, &wz)) {
            /* the x axis vertical: ZYX roll 0, west = e_y */
            wx = IMF_R(0.0);
            wy = IMF_R(1.0);
            wz = IMF_R(0.0);
        }
    }
    /* north = west x up */
    r[0] = wy * uz - wz * uy;
    r[1] = wz * ux - wx * uz;
    r[2] = wx * uy - wy * ux;
    r[3] = wx;
    r[4] = wy;
    r[5] = wz;
    r[6] = ux;
    r[7] = uy;
    r[8] = uz;
    attitude_quat_of_matrix(att);
    return 1;
}

int imf_attitude_from_quat(imf_attitude_t *const att, const imf_real q0, const imf_real q1,
                           const imf_real q2, const imf_real q3)
{
    imf_real q[4];
    imf_real *const r = att->r;
    q[0] = q0;
    q[1] = q1;
    q[2] = q2;
    q[3] = q3;
    if (!attitude_unit4(q)) {
        return 0;
    }
    att->q[0] = q[0];
    att->q[1] = q[1];
    att->q[2] = q[2];
    att->q[3] = q[3];
    /* R(q), sensor -> earth */
    r[0] = IMF_R(1.0) - IMF_R(2.0) * (q[2] * q[2] + q[3] * q[3]);
    r[1] = IMF_R(2.0) * (q[1] * q[2] - q[0] * q[3]);
    r[2] = IMF_R(2.0) * (q[1] * q[3] + q[0] * q[2]);
    r[3] = IMF_R(2.0) * (q[1] * q[2] + q[0] * q[3]);
    r[4] = IMF_R(1.0) - IMF_R(2.0) * (q[1] * q[1] + q[3] * q[3]);
    r[5] = IMF_R(2.0) * (q[2] * q[3] - q[0] * q[1]);
    r[6] = IMF_R(2.0) * (q[1] * q[3] - q[0] * q[2]);
    r[7] = IMF_R(2.0) * (q[2] * q[3] + q[0] * q[1]);
    r[8] = IMF_R(1.0) - IMF_R(2.0) * (q[1] * q[1] + q[2] * q[2]);
    return 1;
}

void imf_attitude_window_init(imf_attitude_window_t *const w, const uint32_t window)
{
    w->ax = IMF_R(0.0);
    w->ay = IMF_R(0.0);
    w->az = IMF_R(0.0);
    w->mx = IMF_R(0.0);
    w->my = IMF_R(0.0);
    w->mz = IMF_R(0.0);
    w->n = 0;
    w->window = window > 0 ? window : 1;
}

int imf_attitude_window_add(imf_attitude_window_t *const w, imf_attitude_t *const att,
                            const imf_real ax, const imf_real ay, const imf_real az,
                            const imf_real mx, const imf_real my, const imf_real mz)
{
    imf_real ux = ax, uy = ay, uz = az, vx = mx, vy = my, vz = mz;
    imf_real sax, say, saz, smx, smy, smz;
    if (!(imf_finite3(ax, ay, az) && imf_finite3(mx, my, mz))) {
        return -1;
    }
    if (!attitude_unit3(&ux, &uy, &uz)) {
        return 0;
    }
    sax = w->ax + ux;
    say = w->ay + uy;
    saz = w->az + uz;
    smx = w->mx;
    smy = w->my;
    smz = w->mz;
    if (attitude_unit3(&vx, &vy, &vz)) {
        smx = smx + vx;
        smy = smy + vy;
        smz = smz + vz;
    }
    if (!imf_attitude_from_acc_mag(att, sax, say, saz, smx, smy, smz)) {
        return -1;
    }
    w->ax = sax;
    w->ay = say;
    w->az = saz;
    w->mx = smx;
    w->my = smy;
    w->mz = smz;
    w->n++;
    return 1;
}
