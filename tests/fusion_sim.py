"""Simulated logs for the Fusion suite, in Fusion's units (deg/s, g, uT).

Rates and jitter as x-io's example recording (Fusion's sensor_data.csv:
~100 Hz, steps of 10.08 ms and 7.56 ms, dropped samples up to 30.2 ms),
which cannot be fetched here. Phases exercise every branch of FusionAHRS:
rest (with a gyroscope bias, long enough for FusionOffset's 5 s timeout),
slow and fast rotation, shaking with linear acceleration (acceleration
rejection and recovery), a magnetic disturbance (magnetic rejection and
recovery), gyroscope overrange spikes, and all-zero accelerometer and
magnetometer rows.
"""
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

DT_STEPS = (0.010079, 0.007559, 0.020158, 0.030238)   # s
DT_P = (0.85, 0.10, 0.035, 0.015)
M_EARTH = np.array([20.0, 0.0, -42.0])                 # uT, NWU: north and down


@dataclass
class Log:
    dt: np.ndarray       # (N,) s
    gyr: np.ndarray      # (N, 3) deg/s
    acc: np.ndarray      # (N, 3) g
    mag: np.ndarray      # (N, 3) uT
    yaw: np.ndarray      # (N,) true heading, degrees (NWU)
    phases: dict


def simulated_log(seed=0, n=6000, bias=(0.6, -0.4, 0.3), overrange=2100.0, zero_rows=True,
                  frame="NWU"):
    rng = np.random.default_rng(seed)
    dt = rng.choice(DT_STEPS, p=DT_P, size=n) + rng.normal(0.0, 2e-7, n)
    f = n / 6000.0
    ph = {name: (int(a * f), int(b * f)) for name, (a, b) in {
        "rest1": (0, 800), "slow": (800, 1500), "shake": (1500, 2600), "magdist": (2600, 3600),
        "rest2": (3600, 4300), "fast": (4300, 5100), "rest3": (5100, 6000)}.items()}
    w = np.zeros((n, 3))
    lin = np.zeros((n, 3))
    dist = np.zeros((n, 3))
    t = np.cumsum(dt)
    a, b = ph["slow"]
    w[a:b] = 40.0 * np.sin(np.outer(t[a:b], [0.7, 1.1, 0.5]))
    a, b = ph["shake"]
    w[a:b] = 90.0 * np.sin(np.outer(t[a:b], [5.0, 4.0, 3.0]))
    lin[a:b] = 1.5 * np.sin(np.outer(t[a:b], [7.0, 9.0, 5.0]))
    a, b = ph["magdist"]
    w[a:b] = 15.0 * np.sin(np.outer(t[a:b], [0.3, 0.2, 0.9]))
    dist[a:b] = [60.0, -45.0, 20.0]
    a, b = ph["fast"]
    w[a:b] = 300.0 * np.sin(np.outer(t[a:b], [2.0, 1.3, 2.7]))
    # integrate the true attitude (sensor -> earth)
    rot = [Rotation.identity()]
    for k in range(1, n):
        rot.append(rot[-1] * Rotation.from_rotvec(np.radians(w[k]) * dt[k]))
    R = Rotation.concatenate(rot)
    up = R.inv().apply([0.0, 0.0, 1.0])
    acc = up + lin + rng.normal(0.0, 0.01, (n, 3))
    mag = R.inv().apply(M_EARTH) + dist + rng.normal(0.0, 0.3, (n, 3))
    gyr = w + np.asarray(bias) + rng.normal(0.0, 0.05, (n, 3))
    # overrange spikes during the fast phase
    a, b = ph["fast"]
    spikes = rng.choice(np.arange(a, b), size=4, replace=False)
    gyr[spikes, rng.integers(0, 3, 4)] = overrange * rng.choice([-1.0, 1.0], 4)
    if zero_rows:
        acc[rng.random(n) < 0.01] = 0.0
        mag[rng.random(n) < 0.02] = 0.0
        mag[rng.random(n) < 0.005] = -0.0
    yaw = R.as_euler("ZYX", degrees=True)[:, 0]
    if frame == "FRD":   # the body rotated 180 deg about x: a down-looking z axis (NED mounting)
        flip = np.array([1.0, -1.0, -1.0])
        gyr, acc, mag = gyr * flip, acc * flip, mag * flip
    f32 = np.float32
    return Log(dt.astype(f32), gyr.astype(f32), acc.astype(f32), mag.astype(f32),
               yaw.astype(f32), ph)
