"""What the simulators share: the default sensor figures (GYR_NOISE, GYR_BIAS, ACC_NOISE,
MAG_NOISE, MAG_DIP, ANGLE_NOISE), gravity, the motion kinds, the checks of their arguments,
the seeded random streams, the random sinusoids motions and disturbances are made of, and
the hold/ramp schedule of the tilt steps."""
import math

import numpy as np

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

_N_SINES = 3  # sinusoids per axis


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


def _step_schedule(n, hold_n, ramp_n):
    """Yield (start, stop, is_ramp) segments covering n samples: hold, ramp, hold, ramp, ..."""
    k, ramp = 0, False
    while k < n:
        m = ramp_n if ramp else hold_n
        yield k, min(k + m, n), ramp
        k += m
        ramp = not ramp
