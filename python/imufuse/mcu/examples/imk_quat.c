#include <math.h>
#include "imk_quat.h"

void imk_quat_init(imk_quat_t *const self, float dt, float kp)
{
    self->q[0] = 1.0f;
    self->q[1] = 0.0f;
    self->q[2] = 0.0f;
    self->q[3] = 0.0f;
    self->e[0] = 0.0f;
    self->e[1] = 0.0f;
    self->e[2] = 0.0f;
    self->anorm = 0.0f;
    self->dt = dt;
    self->kp = kp;
}

void imk_quat_update(imk_quat_t *const self, const float gyr[3], const float acc[3])
{
    float *const q = self->q;
    float ax = acc[0], ay = acc[1], az = acc[2];
    float gx = gyr[0], gy = gyr[1], gz = gyr[2];
    float n, vx, vy, vz, hdt, q0, q1, q2, q3, r;

    n = sqrtf(ax * ax + ay * ay + az * az);
    self->anorm = n;
    if (n > 0.0f) {
        ax = ax / n;
        ay = ay / n;
        az = az / n;
        /* gravity direction predicted by q (third row of the rotation matrix) */
        vx = 2.0f * (q[1] * q[3] - q[0] * q[2]);
        vy = 2.0f * (q[0] * q[1] + q[2] * q[3]);
        vz = q[0] * q[0] - q[1] * q[1] - q[2] * q[2] + q[3] * q[3];
        self->e[0] = ay * vz - az * vy;
        self->e[1] = az * vx - ax * vz;
        self->e[2] = ax * vy - ay * vx;
        gx += self->kp * self->e[0];
        gy += self->kp * self->e[1];
        gz += self->kp * self->e[2];
    }
    hdt = 0.5f * self->dt;
    q0 = q[0];
    q1 = q[1];
    q2 = q[2];
    q3 = q[3];
    q[0] = q0 + (-q1 * gx - q2 * gy - q3 * gz) * hdt;
    q[1] = q1 + (q0 * gx + q2 * gz - q3 * gy) * hdt;
    q[2] = q2 + (q0 * gy - q1 * gz + q3 * gx) * hdt;
    q[3] = q3 + (q0 * gz + q1 * gy - q2 * gx) * hdt;
    r = 1.0f / sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    q[0] *= r;
    q[1] *= r;
    q[2] *= r;
    q[3] *= r;
}
