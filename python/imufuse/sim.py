"""Deterministic, seeded simulation of orientation trajectories and IMU samples.

Frames and units
----------------
- Earth frame NWU: x north (magnetic), y west, z up. Gravity is ``-g e_z``; a sensor at rest
  measures the specific force ``+g e_z``, so a level sensor reads acc = (0, 0, +1 g).
- Quaternions ``[w, x, y, z]`` rotate body -> earth (``v_earth = R v_body``), see
  :mod:`imufuse.rotations`. A sensor reads earth vectors as ``R^T v_earth``.
- Gyro rad/s in the body frame; accelerometer in g (``acc_unit="m/s^2"`` for m/s^2, with
  ``g = GRAVITY``); magnetometer in the unit of ``mag_field`` (default 1: a unit field).
- Earth magnetic field ``m_earth = mag_field * (cos(dip), 0, -sin(dip))``: pointing north and,
  for positive dip (northern hemisphere), down.

Timing
------
Sample ``k`` (k = 0 .. N-1) covers the interval ``(k dt, (k+1) dt]``. The true body rate
``omega[k]`` is constant over that interval and the true orientation after it is, exactly,

    q_true[k] = q_true[k-1] (x) exp(omega[k] dt / 2)        (q_true[-1] = q0)

evaluated in float64 with :func:`imufuse.rotations.quat_from_rotvec` (no renormalisation).
``t[k] = (k+1) / rate`` is the time of ``q_true[k]``; the accelerometer and magnetometer of
sample ``k`` are read at that orientation. This matches a filter that integrates ``gyr[k]``
and then corrects with ``acc[k]``: with noise-free, bias-free data an exact integrator
reproduces ``q_true``.

Reproducibility
---------------
Every random draw comes from ``numpy.random.SeedSequence(seed)``: child 0 drives the motion,
the other children the sensor noises, so changing a noise level never changes the motion.
The same seed gives the same arrays bit for bit. ``seed=None`` draws fresh entropy and
records it in ``params["seed"]`` so the run can be repeated.

Default sensor figures (MPU-6050-class MEMS, after a rough bias calibration, 100-500 Hz)
----------------------------------------------------------------------------------------
- gyro white noise 0.005 rad/s (0.29 deg/s) per sample, residual bias about 0.01-0.02 rad/s
  per axis (:data:`GYR_BIAS`);
- accelerometer white noise 0.005 g per sample, no bias;
- magnetometer white noise 0.005 of the field strength per sample; dip 60 deg (mid-latitude
  Europe / North America).
Pass 0 for any of them to get noise-free or bias-free data.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from .rotations import (
    euler_to_quat, quat_conj, quat_from_rotvec, quat_mul, quat_normalize, quat_rotate_inv,
    quat_to_euler, quat_to_rotvec,
)

__all__ = [
    "GRAVITY", "GYR_NOISE", "GYR_BIAS", "ACC_NOISE", "MAG_NOISE", "MAG_DIP", "ANGLE_NOISE",
    "KINDS", "Trajectory", "ImuData", "Axis1D", "trajectory", "imu", "axis1d",
    "mag_earth", "integrate",
]

#: Standard gravity, m/s^2.
GRAVITY = 9.80665
#: Default gyro white noise, rad/s (standard deviation per sample, each axis).
GYR_NOISE = 0.005
#: Default constant gyro bias, rad/s (body x, y, z).
GYR_BIAS = (0.012, -0.017, 0.009)
#: Default accelerometer white noise, g (standard deviation per sample, each axis).
ACC_NOISE = 0.005
#: Default magnetometer white noise, in units of the field strength.
MAG_NOISE = 0.005
#: Default magnetic inclination (dip), rad; positive = field points below the horizon.
MAG_DIP = math.radians(60.0)
#: Default noise of the single-axis accelerometer angle, rad (0.005 g noise ~ 0.005 rad).
ANGLE_NOISE = 0.005

#: Motion kinds understood by :func:`trajectory` (and, without "yaw_spin", :func:`axis1d`).
KINDS = ("static", "slow", "tilt_steps", "yaw_spin", "fast", "custom")

# Per kind: default amplitude and max frequency (Hz) of the random sinusoids.
_DEFAULTS_3D = {
    "slow": (math.radians(30.0), 0.2),      # rad (max roll/pitch; yaw twice that)
    "tilt_steps": (math.radians(30.0), None),  # rad (max roll/pitch of each step)
    "yaw_spin": (1.0, None),                # rad/s about earth z
    "fast": (5.0, 2.0),                     # rad/s per body axis
}
_DEFAULTS_1D = {
    "slow": (math.radians(30.0), 0.2),      # rad
    "tilt_steps": (math.radians(30.0), None),  # rad
    "fast": (math.radians(45.0), 2.0),      # rad
}
_N_SINES = 3  # sinusoids per axis


# --------------------------------------------------------------------------------------------
# result types

@dataclass(frozen=True)
class Trajectory:
    """Ground-truth orientation trajectory (see the module doc for the timing).

    t: (N,) s, time of ``q[k]``, ``(k+1)/rate``.
    omega: (N, 3) rad/s, true body rate, constant over sample k's interval.
    q: (N, 4) unit quaternions [w, x, y, z] body -> earth after each sample.
    q0: (4,) orientation at t = 0.
    dt: s, ``1/rate``.
    params: the generator's arguments (seed included) and the drawn random parameters.
    """
    t: np.ndarray
    omega: np.ndarray
    q: np.ndarray
    q0: np.ndarray
    dt: float
    params: dict = field(default_factory=dict)

    def __len__(self):
        return len(self.t)


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


# --------------------------------------------------------------------------------------------
# argument checks

def _finite(x, name, lo=None, hi=None, lo_open=False):
    try:
        x = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number; got {x!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite; got {x}")
    if lo is not None and (x < lo or (lo_open and x == lo)):
        raise ValueError(f"{name} must be {'>' if lo_open else '>='} {lo}; got {x}")
    if hi is not None and x > hi:
        raise ValueError(f"{name} must be <= {hi}; got {x}")
    return x


def _vec3(v, name):
    a = np.asarray(v, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(3, float(a))
    if a.shape != (3,):
        raise ValueError(f"{name} must be a scalar or a 3-vector; got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite; got {a}")
    return a


def _samples(rate, duration):
    rate = _finite(rate, "rate", 0.0, lo_open=True)
    duration = _finite(duration, "duration", 0.0, lo_open=True)
    n = int(round(duration * rate))
    if n < 1:
        raise ValueError(f"duration * rate must give at least one sample; got {duration} s "
                         f"at {rate} Hz")
    return rate, duration, n


def _seeds(seed, n):
    """(seed actually used, n independent Generators)."""
    if seed is None:
        ss = np.random.SeedSequence()
    else:
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"seed must be a non-negative int or None; got {seed!r}")
        ss = np.random.SeedSequence(int(seed))
    return ss.entropy, [np.random.default_rng(c) for c in ss.spawn(n)]


def _max_freq(max_freq, default, rate):
    f = default if max_freq is None else _finite(max_freq, "max_freq", 0.0, lo_open=True)
    if f >= 0.5 * rate:
        raise ValueError(f"max_freq must be below the Nyquist frequency {0.5 * rate} Hz; got {f}")
    return f


# --------------------------------------------------------------------------------------------
# random signal pieces

def _sines(rng, n_axes, amplitude, f_hi, f_lo=None):
    """Draw ``_N_SINES`` sinusoids per axis: frequencies in [f_lo, f_hi] Hz (f_lo default
    f_hi/5), random phases, weights summing to ``amplitude`` per axis (|signal| <= amplitude)."""
    amplitude = np.broadcast_to(np.asarray(amplitude, dtype=np.float64), (n_axes,))
    f = rng.uniform(0.2 * f_hi if f_lo is None else f_lo, f_hi, (_N_SINES, n_axes))
    ph = rng.uniform(0.0, 2.0 * math.pi, (_N_SINES, n_axes))
    w = rng.uniform(0.5, 1.0, (_N_SINES, n_axes))
    a = w / w.sum(axis=0) * amplitude
    return {"freq": f, "phase": ph, "amp": a}


def _eval_sines(s, t):
    """(len(t), n_axes) sum of the sinusoids at times t (s)."""
    arg = 2.0 * math.pi * s["freq"][None] * t[:, None, None] + s["phase"][None]
    return np.sum(s["amp"][None] * np.sin(arg), axis=1)


def _sines_params(s):
    return {k: v.tolist() for k, v in s.items()}


# --------------------------------------------------------------------------------------------
# integration

def integrate(q0, omega, dt):
    """Exact quaternion integration of piecewise-constant body rates.

    ``q[k] = q[k-1] (x) quat_from_rotvec(omega[k] * dt)`` with ``q[-1] = q0``; float64, no
    renormalisation. ``q0`` (4,), ``omega`` (N, 3) rad/s, ``dt`` s. Returns (N, 4).
    """
    q0 = np.asarray(q0, dtype=np.float64)
    if q0.shape != (4,):
        raise ValueError(f"q0 must have shape (4,); got {q0.shape}")
    omega = np.asarray(omega, dtype=np.float64)
    if omega.ndim != 2 or omega.shape[1] != 3:
        raise ValueError(f"omega must have shape (N, 3); got {omega.shape}")
    dq = quat_from_rotvec(omega * dt)
    out = np.empty((len(omega), 4))
    pw, px, py, pz = (float(c) for c in q0)
    # same expression order as rotations.quat_mul, in Python floats (fast for a sequential loop)
    for k, (qw, qx, qy, qz) in enumerate(dq.tolist()):
        pw, px, py, pz = (pw * qw - px * qx - py * qy - pz * qz,
                          pw * qx + px * qw + py * qz - pz * qy,
                          pw * qy - px * qz + py * qw + pz * qx,
                          pw * qz + px * qy - py * qx + pz * qw)
        out[k] = (pw, px, py, pz)
    return out


def _integrate_earth(q0, omega_earth, dt):
    """Earth-frame piecewise-constant rates: the body rate of step k is R(q[k-1])^T omega_e[k]
    (a rotation about a fixed earth axis is one about a fixed body axis). Returns
    (omega_body (N, 3), q (N, 4))."""
    n = len(omega_earth)
    omega_b = np.empty((n, 3))
    q = np.empty((n, 4))
    prev = np.asarray(q0, dtype=np.float64)
    for k in range(n):
        omega_b[k] = quat_rotate_inv(prev, omega_earth[k])
        prev = quat_mul(prev, quat_from_rotvec(omega_b[k] * dt))
        q[k] = prev
    return omega_b, q


def _rates_from_path(p, dt):
    """Constant body rate per interval that moves p[k-1] exactly onto p[k]: (N+1, 4) -> (N, 3)."""
    return quat_to_rotvec(quat_mul(quat_conj(p[:-1]), p[1:])) / dt


def _step_schedule(n, hold_n, ramp_n):
    """Yield (start, stop, is_ramp) segments covering n samples: hold, ramp, hold, ramp, ..."""
    k, ramp = 0, False
    while k < n:
        m = ramp_n if ramp else hold_n
        yield k, min(k + m, n), ramp
        k += m
        ramp = not ramp


# --------------------------------------------------------------------------------------------
# public generators

def trajectory(kind=None, *, rate=200.0, duration=10.0, seed=0, q0=None, amplitude=None,
               max_freq=None, hold=2.0, ramp=0.5, omega=None, frame="body"):
    """Seeded ground-truth orientation trajectory.

    kind:
        ``"static"``: no rotation, at ``q0`` (default level, heading north).
        ``"slow"``: smooth random motion. roll and pitch are each a sum of 3 sinusoids with
        random phases and frequencies in [max_freq/5, max_freq] (default 0.2 Hz), bounded by
        ``amplitude`` (rad, default 30 deg); yaw likewise bounded by 2 * amplitude. The body
        rate of each interval is the constant rate joining consecutive points of that ZYX
        Euler path, so ``q`` follows the path to rounding. Default ``q0``: the path's start;
        another ``q0`` replays the same body motion from there.
        ``"tilt_steps"``: hold ``hold`` s, then rotate at constant body rate for ``ramp`` s to a
        new random tilt (roll, pitch uniform in +-amplitude rad, default 30 deg; yaw of
        ``q0``), hold, and so on.
        ``"yaw_spin"``: constant rotation about earth z at ``amplitude`` rad/s (default 1),
        keeping the tilt of ``q0``.
        ``"fast"``: each body rate axis a sum of 3 sinusoids bounded by ``amplitude`` rad/s
        (default 5), frequencies up to ``max_freq`` (default 2 Hz); tumbles freely. The rate
        of each interval is the sinusoid at its midpoint.
        ``"custom"``: ``omega`` gives the rates: a callable ``omega(t) -> (N, 3)`` rad/s,
        called once with the interval midpoints ``(k + 0.5) / rate`` (N,), or an (N, 3) array
        (then N = len(omega) and ``duration`` is ignored). ``frame="earth"`` reads them as
        earth-frame rates (converted to body rates step by step), ``"body"`` (default) as
        body rates.
        Default: ``"custom"`` if ``omega`` is given, else ``"slow"``.
    rate: Hz. duration: s. seed: int >= 0 or None (see module doc).
    q0: None, a (4,) quaternion (normalised here), or ``"random"`` (uniform, from the seed).
    Returns a :class:`Trajectory`.
    """
    if kind is None:
        kind = "slow" if omega is None else "custom"
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}; got {kind!r}")
    if (omega is not None) != (kind == "custom"):
        raise ValueError("omega is required for kind='custom' and only allowed with it")
    if frame not in ("body", "earth"):
        raise ValueError(f"frame must be 'body' or 'earth'; got {frame!r}")
    if frame == "earth" and kind != "custom":
        raise ValueError("frame='earth' applies to kind='custom' only")
    if kind == "custom" and not callable(omega):
        omega = np.asarray(omega, dtype=np.float64)
        if omega.ndim != 2 or omega.shape[1] != 3 or len(omega) < 1:
            raise ValueError(f"omega array must have shape (N, 3); got {omega.shape}")
        duration = len(omega) / _finite(rate, "rate", 0.0, lo_open=True)
    rate, duration, n = _samples(rate, duration)
    hold = _finite(hold, "hold", 0.0)
    ramp = _finite(ramp, "ramp", 0.0)
    dt = 1.0 / rate
    used_seed, (rng,) = _seeds(seed, 1)
    amp_default, f_default = _DEFAULTS_3D.get(kind, (None, None))
    amp = None if amp_default is None else (
        amp_default if amplitude is None else _finite(amplitude, "amplitude", 0.0))
    params = {"kind": kind, "rate": rate, "duration": duration, "n": n, "seed": used_seed,
              "amplitude": amp, "frame": frame}

    # q0 first (its draw, if any, precedes the motion's draws)
    q0_given = q0 is not None
    if isinstance(q0, str):
        if q0 != "random":
            raise ValueError(f"q0 must be None, a quaternion or 'random'; got {q0!r}")
        q0 = quat_normalize(rng.standard_normal(4))
    elif q0 is not None:
        q0 = np.asarray(q0, dtype=np.float64)
        if q0.shape != (4,) or not np.all(np.isfinite(q0)):
            raise ValueError(f"q0 must be a finite (4,) quaternion; got shape {q0.shape}")
        q0 = quat_normalize(q0)
    else:
        q0 = np.array([1.0, 0.0, 0.0, 0.0])

    t_mid = (np.arange(n) + 0.5) / rate
    q = None
    if kind == "static":
        om = np.zeros((n, 3))
    elif kind == "slow":
        f_hi = _max_freq(max_freq, f_default, rate)
        s = _sines(rng, 3, [amp, amp, 2.0 * amp], f_hi)
        params.update(max_freq=f_hi, sines=_sines_params(s))
        path = euler_to_quat(_eval_sines(s, np.arange(n + 1) / rate))
        om = _rates_from_path(path, dt)
        if not q0_given:
            q0 = path[0]
    elif kind == "tilt_steps":
        params.update(hold=hold, ramp=ramp)
        yaw0 = float(quat_to_euler(q0)[2])
        hold_n, ramp_n = max(1, int(round(hold * rate))), max(1, int(round(ramp * rate)))
        om = np.zeros((n, 3))
        cur, targets = q0, []
        for a, b, is_ramp in _step_schedule(n, hold_n, ramp_n):
            if is_ramp:
                rp = rng.uniform(-amp, amp, 2)
                tgt = euler_to_quat([rp[0], rp[1], yaw0])
                targets.append(rp.tolist())
                om[a:b] = quat_to_rotvec(quat_mul(quat_conj(cur), tgt)) / (ramp_n * dt)
                cur = tgt
        params["targets"] = targets
    elif kind == "yaw_spin":
        om = np.broadcast_to(quat_rotate_inv(q0, [0.0, 0.0, amp]), (n, 3)).copy()
    elif kind == "fast":
        f_hi = _max_freq(max_freq, f_default, rate)
        s = _sines(rng, 3, amp, f_hi)
        params.update(max_freq=f_hi, sines=_sines_params(s))
        om = _eval_sines(s, t_mid)
    else:  # custom
        if callable(omega):
            om = np.asarray(omega(t_mid), dtype=np.float64)
            if om.shape != (n, 3):
                raise ValueError(f"omega(t) must return shape ({n}, 3); got {om.shape}")
        else:
            om = omega.copy()
        if not np.all(np.isfinite(om)):
            raise ValueError("omega contains non-finite values")
        if frame == "earth":
            om, q = _integrate_earth(q0, om, dt)
    if q is None:
        q = integrate(q0, om, dt)
    params["q0"] = q0.tolist()
    t = np.arange(1, n + 1) / rate
    return Trajectory(t=t, omega=np.ascontiguousarray(om), q=q, q0=np.array(q0, dtype=float),
                      dt=dt, params=params)


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
