"""Seeded paraglider flights with ground truth, for the variometer of Nair (2016).

A flight is a list of phases (:class:`Phase`): glides in sinking air and
thermals, each with its air-mass climb rate and the bank angle the pilot
flies. The pilot's vertical speed moves from one phase's climb rate to the
next over ``entry_time`` (a smooth cosine step: a thermal entry), and the
bank over ``roll_time``. Turns are coordinated: the heading turns at
``g tan(bank) / airspeed`` and the pilot hangs along the specific force, so
the centripetal acceleration appears in the body frame (the accelerometer
magnitude is ``g / cos(bank)``, not 1 g). On top: vertical gusts
(``turbulence``) and the pilot swinging under the wing (``pilot_motion``).

Frames and units are those of :mod:`imufuse.sim`: earth NWU (z up), body
x forward, y left, z up; quaternions ``[w, x, y, z]`` body -> earth; gyro
rad/s; accelerometer in g (+1 g on body z when level at rest); magnetometer
in units of the field. Sample ``k`` is at ``t[k] = k / rate``; ``gyr[k]`` is
the rate over ``(t[k-1], t[k]]`` (exact: ``q[k] = q[k-1] (x) exp(gyr dt / 2)``
without noise and bias).

Sensors:
  IMU at ``rate`` (default 200 Hz) with white noise and constant biases
  (``acc_bias`` in g, body frame: the bias the vario Kalman filter estimates
  is its vertical component);
  barometer (MS5611-like) every ``rate / baro_rate`` IMU samples: pressure
  from the standard atmosphere at the true altitude, white noise of
  ``baro_noise`` metres of altitude, quantised to ``baro_quantum`` Pa (the
  MS5611 reports 0.01 mbar = 1 Pa), then back to altitude with
  :func:`imufuse.vario.pressure_to_altitude`.

Every random draw comes from ``numpy.random.SeedSequence(seed)``: the same
seed gives the same arrays bit for bit.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from ..rotations import euler_to_quat, matrix_to_quat, quat_conj, quat_mul, quat_rotate_inv, \
    quat_to_rotvec
from ..vario import P_REF, altitude_to_pressure, pressure_to_altitude
from .common import GRAVITY
from .sensors import mag_earth

__all__ = ["Phase", "Flight", "flight", "random_phases", "thermal_entry", "turning_thermal"]

#: defaults: IMU after a rough calibration (MPU-class), MS5611 barometer
GYR_NOISE = 0.003          # rad/s per sample
GYR_BIAS = (0.002, -0.001, 0.0015)   # rad/s
ACC_NOISE = 0.004          # g per sample
ACC_BIAS = (0.01, -0.015, 0.02)      # g, body frame
BARO_NOISE = 0.15          # m of altitude, RMS (before quantisation)
BARO_QUANTUM = 1.0         # Pa
AIRSPEED = 10.0            # m/s


@dataclass(frozen=True)
class Phase:
    """duration (s); climb: the vertical speed the pilot settles at (m/s, up
    positive: a thermal 0..5, sinking air < 0); bank (deg, positive = left
    turn, counter-clockwise seen from above in NWU)."""
    duration: float
    climb: float
    bank: float = 0.0


@dataclass(frozen=True)
class Flight:
    """A simulated flight (see the module doc).

    t (N,) s; q (N, 4) true attitude; gyr, acc, mag (N, 3) sensor samples;
    alt (N,) true altitude m; climb (N,) true vertical speed m/s; vacc (N,)
    true vertical acceleration m/s^2 (up); bank (N,) rad (commanded bank);
    baro_idx (M,) indices of the IMU samples at which the barometer sampled;
    pressure (M,) Pa, baro_alt (M,) m; acc_bias (3,) g; p_ref Pa.
    """
    t: np.ndarray
    q: np.ndarray
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    alt: np.ndarray
    climb: np.ndarray
    vacc: np.ndarray
    bank: np.ndarray
    baro_idx: np.ndarray
    pressure: np.ndarray
    baro_alt: np.ndarray
    acc_bias: np.ndarray
    rate: float
    baro_rate: float
    p_ref: float
    phases: tuple
    params: dict = field(default_factory=dict)

    def __len__(self):
        return len(self.t)

    @property
    def baro_t(self):
        return self.t[self.baro_idx]

    def baro_column(self, name="pressure"):
        """(N,) column for a log: the barometer value on its rows, NaN elsewhere."""
        col = np.full(len(self.t), np.nan)
        col[self.baro_idx] = self.pressure if name == "pressure" else self.baro_alt
        return col

    def write_log(self, path, baro="pressure"):
        """CSV log for `imufuse vario`: time, gyr_*, acc_* (g), mag_*, q_* and
        the barometer column `pressure` (Pa) or `baro_alt` (m), empty on the
        rows without a barometer sample; plus the truth (true_alt, true_climb)."""
        if baro not in ("pressure", "baro_alt"):
            raise ValueError(f"baro: must be 'pressure' or 'baro_alt', got {baro!r}")
        names = ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z",
                 "mag_x", "mag_y", "mag_z", "q_w", "q_x", "q_y", "q_z", baro,
                 "true_alt", "true_climb"]
        cols = np.column_stack([self.t, self.gyr, self.acc, self.mag, self.q,
                                self.baro_column(baro), self.alt, self.climb])
        with open(path, "w") as fh:
            fh.write(",".join(names) + "\n")
            for row in cols:
                fh.write(",".join("" if math.isnan(v) else repr(float(v)) for v in row) + "\n")


def _check(name, v, lo=None, lo_open=False):
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a real number, got {v!r}") from None
    if not math.isfinite(x) or (lo is not None and (x <= lo if lo_open else x < lo)):
        raise ValueError(f"{name}: must be finite{f' and > {lo}' if lo_open else ''}"
                         f"{f' and >= {lo}' if lo is not None and not lo_open else ''}, got {v!r}")
    return x


def random_phases(duration, seed=0):
    """Alternating glides (sinking air, straight) and thermals (climb 0.5..5
    m/s, banked 25..45 deg, either direction) filling `duration` seconds."""
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
    phases, t, thermal = [], 0.0, False
    while t < duration:
        if thermal:
            p = Phase(float(rng.uniform(20, 50)), float(rng.uniform(0.5, 5.0)),
                      float(rng.choice([-1, 1]) * rng.uniform(25, 45)))
        else:
            p = Phase(float(rng.uniform(10, 25)), float(-rng.uniform(0.8, 2.0)), 0.0)
        phases.append(p)
        t += p.duration
        thermal = not thermal
    return phases


def thermal_entry(climb=3.0, sink=-1.0, before=20.0, after=30.0, bank=0.0):
    """A straight glide in sinking air, then a thermal: the climb-rate step."""
    return [Phase(before, sink, 0.0), Phase(after, climb, bank)]


def turning_thermal(climb=2.0, bank=40.0, turns_for=60.0, sink=-1.0):
    """A glide, then a thermal worked in steady turns at `bank` degrees."""
    return [Phase(15.0, sink, 0.0), Phase(turns_for, climb, bank), Phase(15.0, sink, 0.0)]


def _smooth_profile(t, phases, attr, ramp):
    """Value of `attr` over time, moving between phases with a cosine step of
    length `ramp` starting at each boundary; returns (value, d value / dt)."""
    val = np.full(t.shape, float(getattr(phases[0], attr)))
    der = np.zeros(t.shape)
    start = 0.0
    for prev, nxt in zip(phases[:-1], phases[1:]):
        start += prev.duration
        dv = float(getattr(nxt, attr)) - float(getattr(prev, attr))
        u = np.clip((t - start) / ramp, 0.0, 1.0)
        val += dv * 0.5 * (1.0 - np.cos(math.pi * u))
        inside = (t > start) & (t < start + ramp)
        der += np.where(inside, dv * 0.5 * math.pi / ramp * np.sin(math.pi * u), 0.0)
    return val, der


def _sines(rng, t, amp, f_lo, f_hi, n=3):
    """Sum of n random sinusoids of total amplitude about `amp`; value and derivative."""
    f = rng.uniform(f_lo, f_hi, n)
    ph = rng.uniform(0, 2 * math.pi, n)
    a = amp / math.sqrt(n) * rng.uniform(0.5, 1.5, n)
    w = 2 * math.pi * f
    val = (a * np.sin(np.outer(t, w) + ph)).sum(axis=1)
    der = (a * w * np.cos(np.outer(t, w) + ph)).sum(axis=1)
    return val, der


def flight(phases=None, *, duration=None, rate=200.0, baro_rate=50.0, seed=0, alt0=1000.0,
           airspeed=AIRSPEED, entry_time=1.0, roll_time=3.0, turbulence=0.2,
           pilot_motion=3.0, gyr_noise=GYR_NOISE, gyr_bias=GYR_BIAS, acc_noise=ACC_NOISE,
           acc_bias=ACC_BIAS, mag_noise=0.005, baro_noise=BARO_NOISE,
           baro_quantum=BARO_QUANTUM, p_ref=P_REF):
    """Simulate a flight (see the module doc). phases: list of Phase (default
    :func:`random_phases` over `duration`, default 120 s); duration, when
    given with phases, cuts or extends (last phase held) the flight.
    turbulence: vertical gust amplitude, m/s; pilot_motion: swing amplitude,
    deg (roll and pitch). Pass 0 for any noise, bias or disturbance to turn
    it off."""
    rate = _check("rate", rate, 0.0, True)
    baro_rate = _check("baro_rate", baro_rate, 0.0, True)
    decim = int(round(rate / baro_rate))
    if decim < 1 or abs(decim * baro_rate - rate) > 1e-9 * rate:
        raise ValueError(f"baro_rate: rate / baro_rate must be a whole number, got "
                         f"{rate} / {baro_rate}")
    for name, v in (("alt0", alt0), ("entry_time", entry_time), ("roll_time", roll_time),
                    ("airspeed", airspeed)):
        _check(name, v, 0.0, name != "alt0")
    for name, v in (("turbulence", turbulence), ("pilot_motion", pilot_motion),
                    ("gyr_noise", gyr_noise), ("acc_noise", acc_noise),
                    ("mag_noise", mag_noise), ("baro_noise", baro_noise),
                    ("baro_quantum", baro_quantum)):
        _check(name, v, 0.0)
    p_ref = _check("p_ref", p_ref, 0.0, True)
    if phases is None:
        phases = random_phases(120.0 if duration is None else duration, seed)
    phases = [p if isinstance(p, Phase) else Phase(*p) for p in phases]
    if not phases:
        raise ValueError("phases: need at least one phase")
    for i, p in enumerate(phases):
        _check(f"phases[{i}].duration", p.duration, 0.0, True)
        _check(f"phases[{i}].climb", p.climb)
        b = _check(f"phases[{i}].bank", p.bank)
        if abs(b) >= 80.0:
            raise ValueError(f"phases[{i}].bank: must be within +-80 deg, got {b}")
    total = sum(p.duration for p in phases) if duration is None else _check(
        "duration", duration, 0.0, True)
    n = int(round(total * rate)) + 1
    dt = 1.0 / rate
    t = np.arange(n) * dt
    ss = np.random.SeedSequence(seed).spawn(6)
    rng_motion, rng_gyr, rng_acc, rng_mag, rng_baro = (np.random.default_rng(s) for s in ss[1:])

    # vertical: the phases' climb rates with smooth entries, plus gusts
    w, wdot = _smooth_profile(t, phases, "climb", entry_time)
    gust, gust_dot = _sines(rng_motion, t, turbulence, 0.05, 0.5)
    w, wdot = w + gust, wdot + gust_dot
    alt = alt0 + np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * dt)])

    # horizontal: coordinated turns at the commanded bank
    bank_deg, _ = _smooth_profile(t, phases, "bank", roll_time)
    bank = np.radians(bank_deg)
    psi_dot = GRAVITY * np.tan(bank) / airspeed
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (psi_dot[1:] + psi_dot[:-1]) * dt)])
    fwd = np.column_stack([np.cos(psi), np.sin(psi), np.zeros(n)])
    left = np.column_stack([-np.sin(psi), np.cos(psi), np.zeros(n)])
    # kinematic acceleration: centripetal (toward the turn's centre) + vertical
    a_kin = (airspeed * psi_dot)[:, None] * left + np.outer(wdot, [0.0, 0.0, 1.0])
    f_earth = a_kin + np.array([0.0, 0.0, GRAVITY])            # specific force, NWU
    z_b = f_earth / np.linalg.norm(f_earth, axis=1, keepdims=True)
    x_b = fwd - np.sum(fwd * z_b, axis=1, keepdims=True) * z_b
    x_b /= np.linalg.norm(x_b, axis=1, keepdims=True)
    y_b = np.cross(z_b, x_b)
    q = matrix_to_quat(np.stack([x_b, y_b, z_b], axis=-1))
    # the pilot swinging under the wing (body roll and pitch)
    roll_w, _ = _sines(rng_motion, t, math.radians(pilot_motion), 0.3, 1.0)
    pitch_w, _ = _sines(rng_motion, t, math.radians(pilot_motion), 0.3, 1.0)
    q = quat_mul(q, euler_to_quat(np.column_stack([roll_w, pitch_w, np.zeros(n)])))
    q[q[:, 0] < 0] *= -1.0
    # continuity of sign (q and -q are one attitude; keep neighbours close)
    flip = np.cumsum(np.r_[0, (np.sum(q[1:] * q[:-1], axis=1) < 0)]) % 2 == 1
    q[flip] *= -1.0

    # sensors
    dq = quat_mul(quat_conj(q[:-1]), q[1:])
    omega = quat_to_rotvec(dq) / dt
    omega = np.vstack([omega[:1], omega])
    gyr = omega + np.asarray(gyr_bias, float) + rng_gyr.normal(0, gyr_noise, (n, 3))
    acc_bias = np.asarray(acc_bias, float) * np.ones(3)
    acc = quat_rotate_inv(q, f_earth) / GRAVITY + acc_bias + rng_acc.normal(0, acc_noise, (n, 3))
    mag = quat_rotate_inv(q, mag_earth()) + rng_mag.normal(0, mag_noise, (n, 3))
    baro_idx = np.arange(0, n, decim)
    h = alt[baro_idx]
    p_true = altitude_to_pressure(h, p_ref)
    # altitude noise as pressure noise at the local gradient
    dpdh = altitude_to_pressure(h + 1.0, p_ref) - p_true
    pressure = p_true + dpdh * rng_baro.normal(0, baro_noise, h.size)
    if baro_quantum > 0:
        pressure = np.round(pressure / baro_quantum) * baro_quantum
    baro_alt = pressure_to_altitude(pressure, p_ref)
    params = dict(seed=seed, rate=rate, baro_rate=baro_rate, alt0=alt0, airspeed=airspeed,
                  entry_time=entry_time, roll_time=roll_time, turbulence=turbulence,
                  pilot_motion=pilot_motion, gyr_noise=gyr_noise, gyr_bias=list(gyr_bias),
                  acc_noise=acc_noise, acc_bias=acc_bias.tolist(), baro_noise=baro_noise,
                  baro_quantum=baro_quantum, p_ref=p_ref)
    return Flight(t=t, q=q, gyr=gyr, acc=acc, mag=mag, alt=alt, climb=w, vacc=wdot,
                  bank=bank, baro_idx=baro_idx, pressure=pressure, baro_alt=baro_alt,
                  acc_bias=acc_bias, rate=rate, baro_rate=baro_rate, p_ref=p_ref,
                  phases=tuple(phases), params=params)
