"""Helpers of the fixed-point accuracy tests: quantising simulated samples to
int16 counts and comparing attitudes by tilt."""
from __future__ import annotations

import numpy as np


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
