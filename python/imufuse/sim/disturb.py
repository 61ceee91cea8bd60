"""Simulated disturbance scenarios with ground truth, for robust attitude filters.

Each scenario is what real recordings throw at an AHRS (docs/recommended-ahrs.md):
linear accelerations from translation, vibration, a magnet passing by, a magnet attached
to the sensor, a gyro bias that walks, and rests. They follow the conventions of
:mod:`imufuse.sim`: earth frame NWU (z up), quaternions body -> earth, gyro in rad/s, the
accelerometer in m/s^2 (specific force, +g up at rest), the magnetometer in uT.

    s = scenario("translation", seed=1)
    f = imufuse_c.RobustIMU(s.dt)
    tilt, heading = errors(f.run(s.gyr, s.acc)[:, :4], s.q_true)     # degrees

Every scenario starts with ``rest`` seconds at rest (the sensor level, heading 30 deg),
then moves. The random parts (rotation rates, noise) come from ``numpy.random`` seeded
with ``seed``: the same seed gives the same arrays.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from ..rotations import quat_conj, quat_mul, quat_rotate, quat_rotate_inv
from .motion import integrate

__all__ = ["SCENARIOS", "Scenario", "scenario", "errors", "GRAVITY_MS2", "FIELD_UT",
           "DIP_DEG"]

GRAVITY_MS2 = 9.81
FIELD_UT = 49.0     # earth field strength, uT (Berlin: about 49 uT)
DIP_DEG = 67.0      # dip angle, deg (Berlin: about 67 deg)

SCENARIOS = ("rest", "rotation", "translation", "vibration", "magnet_passing",
             "magnet_attached", "bias_walk")


@dataclass
class Scenario:
    name: str
    dt: float
    gyr: np.ndarray        # (N, 3) rad/s, with bias and noise
    acc: np.ndarray        # (N, 3) m/s^2
    mag: np.ndarray        # (N, 3) uT
    q_true: np.ndarray     # (N, 4) body -> earth (NWU)
    bias: np.ndarray       # (N, 3) rad/s, the gyro bias in gyr
    moving: np.ndarray     # (N,) bool, the samples after the initial rest
    disturbed: np.ndarray  # (N,) bool, samples whose magnetometer is disturbed
    info: dict = field(default_factory=dict)


def errors(q_est, q_true):
    """BROAD's error definitions (degrees, per sample): e = q_est (x) q_true^-1 in the
    earth frame; tilt = 2 acos(sqrt(e_w^2 + e_z^2)), heading = 2 atan(|e_z / e_w|)."""
    e = quat_mul(np.asarray(q_est, dtype=np.float64), quat_conj(q_true))
    ew, ez = np.abs(e[:, 0]), e[:, 3]
    tilt = 2.0 * np.arccos(np.clip(np.sqrt(e[:, 0] ** 2 + ez ** 2), 0.0, 1.0))
    head = 2.0 * np.arctan(np.abs(ez) / np.maximum(ew, 1e-300))
    return np.degrees(tilt), np.degrees(head)


def _smooth_rates(rng, n, dt, amp, f_hi):
    """A smooth random body rate: a sum of sines per axis, amplitude amp (rad/s)."""
    t = np.arange(1, n + 1) * dt
    w = np.zeros((n, 3))
    for axis in range(3):
        for _ in range(4):
            f = rng.uniform(0.05, f_hi)
            w[:, axis] += amp / 2.0 * np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi))
    return w


def scenario(name, *, rate=285.714, duration=60.0, rest=10.0, seed=0, gyr_noise=0.0017,
             acc_noise=0.045, mag_noise=0.8, bias_deg=(0.5, -0.3, 0.2), q0=None):
    """Build one scenario (see SCENARIOS).

    rate: Hz; duration: s (including the initial rest); rest: s; gyr_noise: rad/s per
    sample; acc_noise: m/s^2 per sample; mag_noise: uT per sample; bias_deg: the constant
    gyro bias, deg/s (bias_walk adds a random walk to it); q0: the initial orientation
    (default: level, heading 30 deg). The defaults are the BROAD sensor's figures
    (0.1 deg/s, 0.045 m/s^2, about 1 uT).
    """
    if name not in SCENARIOS:
        raise ValueError(f"name: must be one of {', '.join(SCENARIOS)}, got {name!r}")
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate
    n = int(round(duration * rate))
    n_rest = int(round(rest * rate))
    moving = np.arange(n) >= n_rest
    k = np.arange(n)
    t = (k + 1) * dt
    omega = np.zeros((n, 3))
    a_lin = np.zeros((n, 3))          # earth frame, m/s^2
    field_dist = np.zeros((n, 3))     # earth frame, uT
    field_body = np.zeros((n, 3))     # body frame (attached magnet), uT
    disturbed = np.zeros(n, dtype=bool)
    bias = np.tile(np.radians(np.asarray(bias_deg, dtype=float)), (n, 1))
    info = {}
    m = n - n_rest
    if name == "rest":
        pass
    elif name == "rotation":
        omega[n_rest:] = _smooth_rates(rng, m, dt, math.radians(120.0), 0.5)
    elif name == "translation":
        # slow rotation plus a back-and-forth translation: velocity bounded (1 m/s),
        # accelerations up to about 0.6 g horizontally and 0.3 g vertically
        omega[n_rest:] = _smooth_rates(rng, m, dt, math.radians(20.0), 0.2)
        tm = t[n_rest:] - t[n_rest]
        for axis, (amp, f) in enumerate(((6.0, 1.0), (4.0, 0.7), (3.0, 1.3))):
            ramp = np.clip(tm / 2.0, 0.0, 1.0)
            a_lin[n_rest:, axis] = amp * ramp * np.sin(2 * math.pi * f * tm)
        info["a_max"] = float(np.abs(a_lin).max())
    elif name == "vibration":
        # slow rotation plus vibration: 2 g at 40-70 Hz along all axes
        omega[n_rest:] = _smooth_rates(rng, m, dt, math.radians(20.0), 0.2)
        tm = t[n_rest:]
        for axis in range(3):
            f = rng.uniform(40.0, 70.0)
            a_lin[n_rest:, axis] = 2.0 * GRAVITY_MS2 * np.sin(2 * math.pi * f * tm
                                                              + rng.uniform(0, 2 * math.pi))
    elif name == "magnet_passing":
        # rotation about all axes; a magnet passes by for 5 s in the middle: an extra
        # field of up to the earth field's strength, pointing east and up
        omega[n_rest:] = _smooth_rates(rng, m, dt, math.radians(60.0), 0.3)
        mid = n_rest + m // 2
        half = int(round(2.5 * rate))
        win = np.zeros(n)
        sl = slice(mid - half, mid + half)
        win[sl] = np.sin(np.linspace(0.0, math.pi, 2 * half)) ** 2
        field_dist[:] = FIELD_UT * np.outer(win, [0.0, -0.8, 0.6])
        disturbed[sl] = True
    elif name == "magnet_attached":
        # a magnet attached to the sensor from the middle on: a constant body-frame
        # field of half the earth field, while the sensor keeps rotating
        omega[n_rest:] = _smooth_rates(rng, m, dt, math.radians(60.0), 0.3)
        start = n_rest + m // 3
        field_body[start:] = 0.5 * FIELD_UT * np.array([0.6, -0.64, 0.48])
        disturbed[start:] = True
    elif name == "bias_walk":
        # rotation with pauses (2 s rest every 15 s) and a gyro bias that walks
        # (0.005 deg/s per sqrt(s): a poor MEMS gyro)
        w = _smooth_rates(rng, m, dt, math.radians(60.0), 0.3)
        tm = np.arange(m) * dt
        pause = (tm % 15.0) > 13.0
        w[pause] = 0.0
        omega[n_rest:] = w
        steps = rng.normal(0.0, math.radians(0.005) * math.sqrt(dt), size=(n, 3))
        bias = bias + np.cumsum(steps, axis=0)
    if q0 is None:
        q0 = np.array([math.cos(math.radians(15.0)), 0.0, 0.0, math.sin(math.radians(15.0))])
    q0 = np.asarray(q0, dtype=np.float64)
    q = integrate(q0, omega, dt)
    g = np.array([0.0, 0.0, GRAVITY_MS2])
    acc = quat_rotate_inv(q, a_lin + g) + rng.normal(0.0, acc_noise, size=(n, 3))
    dip = math.radians(DIP_DEG)
    m_earth = FIELD_UT * np.array([math.cos(dip), 0.0, -math.sin(dip)])
    mag = quat_rotate_inv(q, m_earth + field_dist) + field_body + \
        rng.normal(0.0, mag_noise, size=(n, 3))
    gyr = omega + bias + rng.normal(0.0, gyr_noise, size=(n, 3))
    return Scenario(name, dt, gyr, acc, mag, q, bias, moving, disturbed, info)


def field_heading_error(s):
    """The heading error (deg, per sample) of a compass that trusts the magnetometer:
    the disturbance's size as seen by a filter without rejection."""
    mE = quat_rotate(s.q_true, s.mag)
    return np.degrees(np.abs(np.arctan2(mE[:, 1], mE[:, 0])))
