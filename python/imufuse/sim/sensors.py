"""Simulated sensor readings with their ground truth: the IMU samples along a trajectory
(`imu`: gyro, accelerometer with linear acceleration, magnetometer in the field of
`mag_earth`), and the single-axis data of the 1D filters (`axis1d`: rate, accelerometer
angle, disturbance)."""
import math
from dataclasses import dataclass, field

import numpy as np

from ..rotations import quat_rotate_inv
from .common import (ACC_NOISE, ANGLE_NOISE, GRAVITY, GYR_BIAS, GYR_NOISE, MAG_DIP, MAG_NOISE,
                     _eval_sines, _finite, _max_freq, _samples, _seeds, _sines, _sines_params,
                     _step_schedule, _vec3)
from .motion import Trajectory, trajectory

_DEFAULTS_1D = {
    "slow": (math.radians(30.0), 0.2),      # rad
    "tilt_steps": (math.radians(30.0), None),  # rad
    "fast": (math.radians(45.0), 2.0),      # rad
}


@dataclass(frozen=True)
class ImuData:
    """Simulated IMU samples and their ground truth.

    t: (N,) s. gyr: (N, 3) rad/s, body. acc: (N, 3) g (or m/s^2, see ``params["acc_unit"]``).
    mag: (N, 3) field units. q_true: (N, 4) orientation after each sample. dt: s.
    omega_true: (N, 3) rad/s, the noise- and bias-free body rate.
    lin_acc: (N, 3) m/s^2, the earth-frame linear acceleration at each sample (zeros if none).
    q0: (4,) orientation at t = 0. params: every parameter used, including the seed.
    """
    t: np.ndarray
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    q_true: np.ndarray
    dt: float
    omega_true: np.ndarray
    lin_acc: np.ndarray
    q0: np.ndarray
    params: dict = field(default_factory=dict)

    def __len__(self):
        return len(self.t)


@dataclass(frozen=True)
class Axis1D:
    """Single-axis data for the 1D filters of the article's chapters 2 and 3.

    t: (N,) s. angle: (N,) rad, true angle after each sample, exactly
    ``angle[k] = angle[k-1] + omega_true[k] * dt`` (``angle[-1] = angle0``).
    omega_true: (N,) rad/s, true rate. gyr: (N,) rad/s, measured rate (+ bias + noise).
    acc_angle: (N,) rad, accelerometer angle (true angle + noise + disturbance).
    disturbance: (N,) rad, the disturbance part of ``acc_angle``. dt: s. angle0: rad.
    params: every parameter used, including the seed.
    """
    t: np.ndarray
    angle: np.ndarray
    omega_true: np.ndarray
    gyr: np.ndarray
    acc_angle: np.ndarray
    disturbance: np.ndarray
    dt: float
    angle0: float
    params: dict = field(default_factory=dict)

    def __len__(self):
        return len(self.t)


def mag_earth(dip=MAG_DIP, strength=1.0):
    """Earth magnetic field in NWU: ``strength * (cos(dip), 0, -sin(dip))``.

    dip: rad, positive below the horizon. strength: any unit (the magnetometer's).
    """
    dip = _finite(dip, "dip", -0.5 * math.pi, 0.5 * math.pi)
    strength = _finite(strength, "strength", 0.0, lo_open=True)
    return strength * np.array([math.cos(dip), 0.0, -math.sin(dip)])


def imu(motion=None, *, rate=200.0, duration=10.0, seed=0,
        gyr_bias=GYR_BIAS, gyr_noise=GYR_NOISE,
        acc_noise=ACC_NOISE, acc_bias=0.0, lin_acc=None, acc_unit="g",
        mag_field=1.0, mag_dip=MAG_DIP, mag_noise=MAG_NOISE, **motion_options):
    """Seeded IMU samples along a trajectory.

    motion: a kind for :func:`trajectory` (default "slow"; ``motion_options`` go there:
        q0, amplitude, max_freq, hold, ramp, omega, frame), or a :class:`Trajectory` (then
        its rate and duration are used and ``rate``/``duration`` are ignored).
    gyr = omega_true + gyr_bias + N(0, gyr_noise^2):
        gyr_bias rad/s, scalar or 3-vector (default :data:`GYR_BIAS`);
        gyr_noise rad/s, std per sample and axis (default 0.005).
    acc = R^T (lin_acc + g e_z) / g + acc_bias + N(0, acc_noise^2), in g:
        acc_noise g (default 0.005); acc_bias g, scalar or 3-vector (default 0);
        lin_acc: earth-frame linear acceleration, m/s^2: None; a number = amplitude of a
        random sinusoidal translation (each earth axis a sum of 3 sinusoids, 0.1-0.5 Hz,
        bounded by the number); a callable ``lin_acc(t) -> (N, 3)`` called with the sample
        times; or an (N, 3) array.
        acc_unit: "g" (default) or "m/s^2" (the whole reading, noise and bias included, is
        multiplied by ``GRAVITY``).
    mag = R^T m_earth + N(0, mag_noise^2), m_earth = :func:`mag_earth` (mag_dip, mag_field):
        mag_field any unit > 0 (default 1); mag_dip rad (default 60 deg); mag_noise in the
        field's unit (default 0.005).
    seed: int >= 0 or None; the motion uses the same stream as ``trajectory(seed=seed)``, the
        noises their own streams (also when a Trajectory is passed).
    Returns an :class:`ImuData`.
    """
    used_seed, (_, rng_g, rng_a, rng_m, rng_l) = _seeds(seed, 5)
    if isinstance(motion, Trajectory):
        if motion_options:
            raise ValueError(f"motion options {sorted(motion_options)} given with a Trajectory")
        traj = motion
    else:
        traj = trajectory(motion, rate=rate, duration=duration, seed=used_seed,
                          **motion_options)
    n = len(traj.t)
    gyr_bias = _vec3(gyr_bias, "gyr_bias")
    gyr_noise = _finite(gyr_noise, "gyr_noise", 0.0)
    acc_bias = _vec3(acc_bias, "acc_bias")
    acc_noise = _finite(acc_noise, "acc_noise", 0.0)
    mag_noise = _finite(mag_noise, "mag_noise", 0.0)
    if acc_unit not in ("g", "m/s^2"):
        raise ValueError(f"acc_unit must be 'g' or 'm/s^2'; got {acc_unit!r}")
    mag_dip = _finite(mag_dip, "mag_dip", -0.5 * math.pi, 0.5 * math.pi)
    mag_field = _finite(mag_field, "mag_field", 0.0, lo_open=True)
    m_e = mag_earth(mag_dip, mag_field)
    rate = 1.0 / traj.dt
    params = {"seed": used_seed, "trajectory": traj.params, "gyr_bias": gyr_bias.tolist(),
              "gyr_noise": gyr_noise, "acc_noise": acc_noise, "acc_bias": acc_bias.tolist(),
              "acc_unit": acc_unit, "mag_field": float(mag_field), "mag_dip": float(mag_dip),
              "mag_noise": mag_noise, "mag_earth": m_e.tolist(), "gravity": GRAVITY}

    if lin_acc is None:
        la = np.zeros((n, 3))
        params["lin_acc"] = None
    elif callable(lin_acc):
        la = np.asarray(lin_acc(traj.t), dtype=np.float64)
        params["lin_acc"] = "callable"
    elif np.ndim(lin_acc) == 0:
        amp = _finite(lin_acc, "lin_acc", 0.0)
        s = _sines(rng_l, 3, amp, min(0.5, 0.25 * rate))
        la = _eval_sines(s, traj.t)
        params["lin_acc"] = {"amplitude": amp, "sines": _sines_params(s)}
    else:
        la = np.array(lin_acc, dtype=np.float64)
        params["lin_acc"] = "array"
    if la.shape != (n, 3) or not np.all(np.isfinite(la)):
        raise ValueError(f"lin_acc must give finite values of shape ({n}, 3); got {la.shape}")

    # draw order is fixed: each noise has its own stream
    gyr = traj.omega + gyr_bias + gyr_noise * rng_g.standard_normal((n, 3))
    e_z = np.array([0.0, 0.0, 1.0])
    acc = quat_rotate_inv(traj.q, la / GRAVITY + e_z) + acc_bias \
        + acc_noise * rng_a.standard_normal((n, 3))
    if acc_unit == "m/s^2":
        acc = acc * GRAVITY
    mag = quat_rotate_inv(traj.q, m_e) + mag_noise * rng_m.standard_normal((n, 3))
    return ImuData(t=traj.t, gyr=gyr, acc=acc, mag=mag, q_true=traj.q, dt=traj.dt,
                   omega_true=traj.omega, lin_acc=la, q0=traj.q0, params=params)


def axis1d(motion=None, *, rate=200.0, duration=10.0, seed=0, angle0=None, amplitude=None,
           max_freq=None, hold=2.0, ramp=0.5, omega=None,
           gyr_bias=0.015, gyr_noise=GYR_NOISE, angle_noise=ANGLE_NOISE, disturbance=None):
    """Seeded single-axis data: true angle, gyro rate, accelerometer angle.

    motion: ``"static"`` (angle0, default 0), ``"slow"`` (sum of 3 sinusoids bounded by
        ``amplitude`` rad, default 30 deg, frequencies up to ``max_freq``, default 0.2 Hz),
        ``"tilt_steps"`` (hold ``hold`` s, ramp ``ramp`` s at constant rate to a random angle
        in +-amplitude, default 30 deg, ...), ``"fast"`` (like slow, 45 deg, 2 Hz), or
        ``"custom"`` with ``omega``: callable ``omega(t) -> (N,)`` rad/s at the interval
        midpoints, or an (N,) array (then ``duration`` is ignored). Default: "custom" if
        ``omega`` is given, else "slow". For slow/fast the rate of each interval is the
        constant rate joining consecutive points of the sinusoid, so ``angle`` follows it.
    angle0: rad, angle at t = 0 (default 0; for slow/fast the sinusoid's start). The true
        angle is integrated exactly: ``angle[k] = angle[k-1] + omega_true[k] * dt``.
    gyr = omega_true + gyr_bias + N(0, gyr_noise^2): rad/s (default bias 0.015, noise 0.005).
    acc_angle = angle + N(0, angle_noise^2) + disturbance: rad (default noise 0.005).
    disturbance: None; a number = amplitude (rad) of a vibration-like sum of 3 sinusoids at
        1-5 Hz (capped at rate/4); a callable ``disturbance(t) -> (N,)``; or an (N,) array.
    Returns an :class:`Axis1D`.
    """
    if motion is None:
        motion = "slow" if omega is None else "custom"
    if motion not in ("static", "slow", "tilt_steps", "fast", "custom"):
        raise ValueError("motion must be one of ('static', 'slow', 'tilt_steps', 'fast', "
                         f"'custom'); got {motion!r}")
    if (omega is not None) != (motion == "custom"):
        raise ValueError("omega is required for motion='custom' and only allowed with it")
    if motion == "custom" and not callable(omega):
        omega = np.asarray(omega, dtype=np.float64)
        if omega.ndim != 1 or len(omega) < 1:
            raise ValueError(f"omega array must have shape (N,); got {omega.shape}")
        duration = len(omega) / _finite(rate, "rate", 0.0, lo_open=True)
    rate, duration, n = _samples(rate, duration)
    dt = 1.0 / rate
    hold = _finite(hold, "hold", 0.0)
    ramp = _finite(ramp, "ramp", 0.0)
    gyr_bias = _finite(gyr_bias, "gyr_bias")
    gyr_noise = _finite(gyr_noise, "gyr_noise", 0.0)
    angle_noise = _finite(angle_noise, "angle_noise", 0.0)
    if angle0 is not None:
        angle0 = _finite(angle0, "angle0")
    used_seed, (rng_mo, rng_g, rng_a, rng_d) = _seeds(seed, 4)
    amp_default, f_default = _DEFAULTS_1D.get(motion, (None, None))
    amp = None if amp_default is None else (
        amp_default if amplitude is None else _finite(amplitude, "amplitude", 0.0))
    params = {"motion": motion, "rate": rate, "duration": duration, "n": n, "seed": used_seed,
              "amplitude": amp, "gyr_bias": gyr_bias, "gyr_noise": gyr_noise,
              "angle_noise": angle_noise}
    t = np.arange(1, n + 1) / rate
    t_mid = (np.arange(n) + 0.5) / rate

    if motion == "static":
        om = np.zeros(n)
        a0 = 0.0 if angle0 is None else angle0
    elif motion in ("slow", "fast"):
        f_hi = _max_freq(max_freq, f_default, rate)
        s = _sines(rng_mo, 1, amp, f_hi)
        params.update(max_freq=f_hi, sines=_sines_params(s))
        path = _eval_sines(s, np.arange(n + 1) / rate)[:, 0]
        if angle0 is not None:
            path = path + (angle0 - path[0])
        a0 = float(path[0])
        om = np.diff(path) / dt
    elif motion == "tilt_steps":
        params.update(hold=hold, ramp=ramp)
        a0 = 0.0 if angle0 is None else angle0
        hold_n, ramp_n = max(1, int(round(hold * rate))), max(1, int(round(ramp * rate)))
        om = np.zeros(n)
        cur, targets = a0, []
        for a, b, is_ramp in _step_schedule(n, hold_n, ramp_n):
            if is_ramp:
                tgt = float(rng_mo.uniform(-amp, amp))
                targets.append(tgt)
                om[a:b] = (tgt - cur) / (ramp_n * dt)
                cur = tgt
        params["targets"] = targets
    else:
        om = np.asarray(omega(t_mid) if callable(omega) else omega, dtype=np.float64)
        if om.shape != (n,) or not np.all(np.isfinite(om)):
            raise ValueError(f"omega must give finite values of shape ({n},); got {om.shape}")
        om = om.copy()
        a0 = 0.0 if angle0 is None else angle0
    params["angle0"] = a0

    # angle[k] = angle[k-1] + om[k] * dt, summed left to right (numpy accumulate is sequential)
    angle = np.add.accumulate(np.concatenate([[a0], om * dt]))[1:]

    if disturbance is None:
        dist = np.zeros(n)
        params["disturbance"] = None
    elif callable(disturbance):
        dist = np.asarray(disturbance(t), dtype=np.float64)
        params["disturbance"] = "callable"
    elif np.ndim(disturbance) == 0:
        d_amp = _finite(disturbance, "disturbance", 0.0)
        f_hi = min(5.0, 0.25 * rate)
        s = _sines(rng_d, 1, d_amp, f_hi, min(1.0, f_hi))
        dist = _eval_sines(s, t)[:, 0]
        params["disturbance"] = {"amplitude": d_amp, "sines": _sines_params(s)}
    else:
        dist = np.array(disturbance, dtype=np.float64)
        params["disturbance"] = "array"
    if dist.shape != (n,) or not np.all(np.isfinite(dist)):
        raise ValueError(f"disturbance must give finite values of shape ({n},); got {dist.shape}")

    gyr = om + gyr_bias + gyr_noise * rng_g.standard_normal(n)
    acc_angle = angle + angle_noise * rng_a.standard_normal(n) + dist
    return Axis1D(t=t, angle=angle, omega_true=om, gyr=gyr, acc_angle=acc_angle,
                  disturbance=dist, dt=dt, angle0=a0, params=params)
