"""float64 twins of the fixed-point filters for the accuracy tests: the
appendix step lists in plain float arithmetic, fed with the same counts
converted to physical units.  (They stand in for imufuse's float classes
where those are not written yet; the equations are the same.)"""
from __future__ import annotations

import math

import numpy as np


def mahony_imu(gyr, acc, dt, kp, ki):
    q0, q1, q2, q3 = 1.0, 0.0, 0.0, 0.0
    ix = iy = iz = 0.0
    out = np.empty((len(gyr), 4))
    for k, ((gx, gy, gz), (ax, ay, az)) in enumerate(zip(gyr.tolist(), acc.tolist())):
        n = math.sqrt(ax * ax + ay * ay + az * az)
        if n > 0.0:
            ax, ay, az = ax / n, ay / n, az / n
            vx = 2.0 * (q1 * q3 - q0 * q2)
            vy = 2.0 * (q0 * q1 + q2 * q3)
            vz = 2.0 * (q0 * q0 + q3 * q3 - 0.5)
            ex, ey, ez = ay * vz - az * vy, az * vx - ax * vz, ax * vy - ay * vx
            ix += ki * dt * ex
            iy += ki * dt * ey
            iz += ki * dt * ez
            gx, gy, gz = gx + kp * ex + ix, gy + kp * ey + iy, gz + kp * ez + iz
        hx, hy, hz = 0.5 * gx * dt, 0.5 * gy * dt, 0.5 * gz * dt
        q0, q1, q2, q3 = (q0 - q1 * hx - q2 * hy - q3 * hz,
                          q1 + q0 * hx + q2 * hz - q3 * hy,
                          q2 + q0 * hy - q1 * hz + q3 * hx,
                          q3 + q0 * hz + q1 * hy - q2 * hx)
        n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 / n, q1 / n, q2 / n, q3 / n
        out[k] = q0, q1, q2, q3
    return out


def madgwick_imu(gyr, acc, dt, beta):
    q0, q1, q2, q3 = 1.0, 0.0, 0.0, 0.0
    out = np.empty((len(gyr), 4))
    for k, ((gx, gy, gz), (ax, ay, az)) in enumerate(zip(gyr.tolist(), acc.tolist())):
        d0 = 0.5 * (-q1 * gx - q2 * gy - q3 * gz)
        d1 = 0.5 * (q0 * gx + q2 * gz - q3 * gy)
        d2 = 0.5 * (q0 * gy - q1 * gz + q3 * gx)
        d3 = 0.5 * (q0 * gz + q1 * gy - q2 * gx)
        n = math.sqrt(ax * ax + ay * ay + az * az)
        if n > 0.0:
            ax, ay, az = ax / n, ay / n, az / n
            w = 4.0 * (q1 * q1 + q2 * q2)
            s0 = w * q0 + 2.0 * (q2 * ax - q1 * ay)
            s1 = w * q1 + 2.0 * (-q3 * ax - q0 * ay + 2.0 * q1 * az)
            s2 = w * q2 + 2.0 * (q0 * ax - q3 * ay + 2.0 * q2 * az)
            s3 = w * q3 + 2.0 * (-q1 * ax - q2 * ay)
            sn = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
            if sn > 0.0:
                d0 -= beta * s0 / sn
                d1 -= beta * s1 / sn
                d2 -= beta * s2 / sn
                d3 -= beta * s3 / sn
        q0, q1, q2, q3 = q0 + d0 * dt, q1 + d1 * dt, q2 + d2 * dt, q3 + d3 * dt
        n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 / n, q1 / n, q2 / n, q3 / n
        out[k] = q0, q1, q2, q3
    return out


def up_in_body(q):
    """Earth z seen in the body frame, R^T e_z, for (N, 4) quaternions body -> earth."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z])


def tilt_between(qa, qb):
    """Angle (deg) between the gravity directions of two quaternion trajectories."""
    a, b = up_in_body(qa), up_in_body(qb)
    c = np.clip(np.sum(a * b, axis=1), -1.0, 1.0)
    return np.degrees(np.arccos(c))


def quantise(imu, gyr_scale, acc_1g):
    g = np.clip(np.round(imu.gyr / gyr_scale), -32768, 32767).astype(np.int16)
    a = np.clip(np.round(imu.acc * acc_1g), -32768, 32767).astype(np.int16)
    return g, a
