"""The Fusion suite of Longbin's walkthrough (x-io Fusion as shipped in imufusion 1.2.3):
pure-Python twin of csrc/fusion_math.h, fusion_ahrs.c, fusion_offset.c and
fusion_calibration.c, line for line.

Longer than 500 lines because: it is the twin of four C files that are one library
(Fusion's), kept in one module as the C keeps them in one suite; csrc/fusion_*.c and this
file are compared line by line.

UNITS ARE FUSION'S: gyroscope in degrees per second, accelerometer in g,
magnetometer in any unit, dt in seconds per update, angles in degrees.

Arithmetic on R (float, or numpy.float32 for float32). The transcendentals
are the C library's own functions in the precision of the build: float64
uses Python's math (the same libm sin, cos, atan2, asin); float32 calls libm's
sinf, cosf, atan2f and asinf through ctypes, the functions the float32 C build
and Fusion itself call.
"""
import ctypes
import ctypes.util
import math
import struct

import numpy as np

from ..shared import checks as _checks
from . import _fusion

NWU, ENU, NED = 0, 1, 2
INVSQRT_EXACT, INVSQRT_FAST = 0, 1

# the C library math functions (None: those already linked into the interpreter)
_libm = ctypes.CDLL(ctypes.util.find_library("m") or None)
for _name, _nargs in (("sinf", 1), ("cosf", 1), ("atan2f", 2), ("asinf", 1)):
    _fn = getattr(_libm, _name)
    _fn.restype = ctypes.c_float
    _fn.argtypes = [ctypes.c_float] * _nargs

_F32 = struct.Struct("<f")
_U32 = struct.Struct("<I")
_F64 = struct.Struct("<d")
_U64 = struct.Struct("<Q")
F32_MAX = float(np.finfo(np.float32).max)
F64_MAX = float(np.finfo(np.float64).max)


class _Ops:
    """fusion_math.h for one precision: R, the transcendentals, pi."""

    def __reduce__(self):
        # the libm wrappers are rebuilt for the precision (they cannot be pickled)
        return (_Ops, (self._dtype,))

    def __init__(self, dtype):
        self._dtype = dtype
        if dtype == "float32":
            R = np.float32
            self.sin = lambda x: R(_libm.sinf(float(x)))
            self.cos = lambda x: R(_libm.cosf(float(x)))
            self.atan2 = lambda y, x: R(_libm.atan2f(float(y), float(x)))
            self.asin = lambda x: R(_libm.asinf(float(x)))
            self.real_max = R(F32_MAX)
        else:
            R = float
            self.sin, self.cos, self.atan2, self.asin = math.sin, math.cos, math.atan2, math.asin
            self.real_max = F64_MAX
        self.R = R
        self.pi = R(math.pi)
        # imf_fusion_fabs: x < 0 ? -x : x (used in threshold comparisons only)
        self.fabs = lambda x: -x if x < R(0.0) else x


# ---- fusion_math.h ------------------------------------------------------------

def deg2rad(o, degrees):
    return degrees * (o.pi / o.R(180.0))


def rad2deg(o, radians):
    return radians * (o.R(180.0) / o.pi)


def safe_asin(o, value):
    if value <= o.R(-1.0):
        return o.pi / o.R(-2.0)
    if value >= o.R(1.0):
        return o.pi / o.R(2.0)
    return o.asin(value)


def invsqrt_fast(o, x):
    """Fusion's 0x5F1F1412 estimate and modified Newton step; float64: the
    same guess lifted to the double exponents (0x5FE3E28240000000)."""
    R = o.R
    if R is float:
        i = _U64.unpack(_F64.pack(x))[0]
        i = (0x5FE3E28240000000 - (i >> 1)) & 0xFFFFFFFFFFFFFFFF
        y = _F64.unpack(_U64.pack(i))[0]
    else:
        i = _U32.unpack(_F32.pack(x))[0]
        i = (0x5F1F1412 - (i >> 1)) & 0xFFFFFFFF
        y = R(_F32.unpack(_U32.pack(i))[0])
    return y * (R(1.69000231) - R(0.714158168) * x * y * y)


def vec_is_zero(o, v):
    return v[0] == o.R(0.0) and v[1] == o.R(0.0) and v[2] == o.R(0.0)


def vec_add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def vec_sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def vec_scale(v, s):
    return (v[0] * s, v[1] * s, v[2] * s)


def vec_hadamard(a, b):
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


def vec_cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def vec_dot(a, b):
    h = vec_hadamard(a, b)
    return h[0] + h[1] + h[2]


def vec_norm2(v):
    return vec_dot(v, v)



def error_degrees(o, v):
    """imf_fusion_error_degrees: the error angle (degrees) of a halved feedback or residual v,
    asin(2 |v|) (both releases)."""
    return rad2deg(o, safe_asin(o, o.R(2.0) * _sqrt(o, vec_norm2(v))))


def trigger_ratio(o, trigger, period):
    """imf_fusion_trigger_ratio: a recovery trigger as the fraction of its period (1.2.3) or
    timeout (1.3); 0 without one."""
    R = o.R
    return R(0.0) if period == 0 else R(trigger) / R(period)

def _sqrt(o, x):
    return o.R(math.sqrt(x)) if x >= 0 else o.R(math.nan)


def vec_normalise(o, v, invsqrt):
    """v / |v|; exact mode returns a zero-norm vector unchanged."""
    n2 = vec_norm2(v)
    if invsqrt == INVSQRT_FAST:
        r = invsqrt_fast(o, n2)
    else:
        if n2 == o.R(0.0):
            return v
        r = o.R(1.0) / _sqrt(o, n2)
    return vec_scale(v, r)


def quat_add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3])


def quat_mul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def quat_mul_vec(q, v):
    qw, qx, qy, qz = q
    return (-qx * v[0] - qy * v[1] - qz * v[2],
            qw * v[0] + qy * v[2] - qz * v[1],
            qw * v[1] - qx * v[2] + qz * v[0],
            qw * v[2] + qx * v[1] - qy * v[0])


def quat_normalise(o, q, invsqrt):
    n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
    if invsqrt == INVSQRT_FAST:
        r = invsqrt_fast(o, n2)
    else:
        if n2 == o.R(0.0):
            return q
        r = o.R(1.0) / _sqrt(o, n2)
    return (q[0] * r, q[1] * r, q[2] * r, q[3] * r)


def mat_mul_vec(m, v):
    return (m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
            m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
            m[6] * v[0] + m[7] * v[1] + m[8] * v[2])


def _finite(*values):
    return all(math.isfinite(v) for v in values)


# ---- fusion_ahrs.c ------------------------------------------------------------

INITIAL_GAIN = 10.0
INITIALISATION_PERIOD = 3.0


class FusionAHRS:
    """x-io Fusion's AHRS in FUSION'S UNITS: gyroscope deg/s (not rad/s), accelerometer g, dt per update.

    Longbin's walkthrough / imufusion 1.2.3, bit-exact with it in float32. Units in full:
    gyroscope in degrees per second, accelerometer in g, magnetometer in any
    unit, dt in seconds given with every update, angles (rejection thresholds,
    heading, Euler) in degrees.

    Settings (Fusion's defaults): convention "NWU" | "ENU" | "NED" ("NWU"),
    gain (0.5), gyroscope_range in deg/s (0: no overrange detection),
    acceleration_rejection and magnetic_rejection in degrees (90; 0 disables),
    recovery_trigger_period in samples (0: rejection disabled),
    invsqrt "exact" (imufusion's FUSION_USE_NORMAL_SQRT) | "fast" (Fusion's
    fast inverse square root).

    update(gyr, acc, mag, dt), update_no_magnetometer(gyr, acc, dt),
    update_external_heading(gyr, acc, heading, dt), set_heading(heading),
    reset(), quaternion (settable), state (settable), outputs() (gravity,
    linear and earth acceleration, Euler, internal states, flags);
    run(gyr, acc, mag=None, *, dt, heading=None) returns the full state after
    every sample, outputs_batch(states) the outputs of all of them.
    """
    kind = "fusion"
    c_name = "imf_fusion_ahrs"
    state_names = _fusion.AHRS_STATE_NAMES

    def __init__(self, *args, dtype="float64", **kwargs):
        self.dtype = _checks.check_dtype(dtype)
        self._o = _Ops(self.dtype)
        self._args = self._params(*args, dtype=self.dtype, **kwargs)
        self._invsqrt = self._args[6]
        self.skipped = 0
        self._init()

    @staticmethod
    def _params(convention="NWU", gain=0.5, gyroscope_range=0.0, acceleration_rejection=90.0,
                magnetic_rejection=90.0, recovery_trigger_period=0, invsqrt="exact",
                dtype="float64"):
        return _fusion.ahrs_params(dtype, convention, gain, gyroscope_range,
                                   acceleration_rejection, magnetic_rejection,
                                   recovery_trigger_period, invsqrt)

    # -- init, settings, reset (imf_fusion_ahrs_init, _set_settings, _reset)

    def _init(self):
        self.skipped = 0
        self.initialising = 1
        self._set_settings(*self._args[:6])
        self._reset()

    def _rejection_threshold(self, degrees):
        o = self._o
        if degrees == o.R(0.0):
            return o.real_max
        v = o.R(0.5) * o.sin(deg2rad(o, degrees))
        return v * v

    def _set_settings(self, convention, gain, gyroscope_range, acceleration_rejection,
                      magnetic_rejection, recovery_trigger_period):
        o = self._o
        R = o.R
        gain, gyroscope_range = R(gain), R(gyroscope_range)
        self.convention = convention
        self.gain = gain
        # overrange is declared at 98 % of the range
        self.gyroscope_range = o.real_max if gyroscope_range == R(0.0) else R(0.98) * gyroscope_range
        self.acceleration_rejection = self._rejection_threshold(R(acceleration_rejection))
        self.magnetic_rejection = self._rejection_threshold(R(magnetic_rejection))
        self.recovery_trigger_period = recovery_trigger_period
        self.acceleration_recovery_timeout = recovery_trigger_period
        self.magnetic_recovery_timeout = recovery_trigger_period
        # without feedback or without recovery, rejection is disabled
        if gain == R(0.0) or recovery_trigger_period == 0:
            self.acceleration_rejection = o.real_max
            self.magnetic_rejection = o.real_max
        if self.initialising == 0:
            self.ramped_gain = self.gain
        self.ramped_gain_step = (R(INITIAL_GAIN) - self.gain) / R(INITIALISATION_PERIOD)

    def set_settings(self, **settings):
        """New settings at any time, Fusion's FusionAhrsSetSettings: the state
        is kept (a finished ramp jumps to the new gain)."""
        _fusion.check_settings(settings)
        cur = dict(zip(("convention", "gain", "gyroscope_range", "acceleration_rejection",
                        "magnetic_rejection", "recovery_trigger_period"), self._user))
        cur.update(settings)
        args = self._params(**cur, invsqrt=[k for k, v in _fusion.INVSQRT.items()
                                            if v == self._invsqrt][0], dtype=self.dtype)
        self._args = args
        with np.errstate(all="ignore"):
            self._set_settings(*args[:6])

    @property
    def _user(self):
        a = self._args
        return ([k for k, v in _fusion.CONVENTIONS.items() if v == a[0]][0], *a[1:6])

    def _reset(self):
        R = self._o.R
        self.q0, self.q1, self.q2, self.q3 = R(1.0), R(0.0), R(0.0), R(0.0)
        self.acc_x, self.acc_y, self.acc_z = R(0.0), R(0.0), R(0.0)
        self.initialising = 1
        self.ramped_gain = R(INITIAL_GAIN)
        self.angular_rate_recovery = 0
        self.half_acc_fb_x, self.half_acc_fb_y, self.half_acc_fb_z = R(0.0), R(0.0), R(0.0)
        self.half_mag_fb_x, self.half_mag_fb_y, self.half_mag_fb_z = R(0.0), R(0.0), R(0.0)
        self.accelerometer_ignored = 0
        self.acceleration_recovery_trigger = 0
        self.acceleration_recovery_timeout = self.recovery_trigger_period
        self.magnetometer_ignored = 0
        self.magnetic_recovery_trigger = 0
        self.magnetic_recovery_timeout = self.recovery_trigger_period

    def reset(self):
        """Back to the initial state, keeping the settings (FusionAhrsReset)."""
        self._reset()

    # -- the update

    def _half_gravity(self):
        R = self._o.R
        q0, q1, q2, q3 = self.q0, self.q1, self.q2, self.q3
        if self.convention == NED:
            return (q0 * q2 - q1 * q3, R(-1.0) * (q2 * q3 + q0 * q1), R(0.5) - q0 * q0 - q3 * q3)
        return (q1 * q3 - q0 * q2, q2 * q3 + q0 * q1, q0 * q0 - R(0.5) + q3 * q3)

    def _half_magnetic(self):
        R = self._o.R
        q0, q1, q2, q3 = self.q0, self.q1, self.q2, self.q3
        if self.convention == ENU:
            return (R(0.5) - q0 * q0 - q1 * q1, q0 * q3 - q1 * q2, R(-1.0) * (q1 * q3 + q0 * q2))
        if self.convention == NED:
            return (R(-1.0) * (q1 * q2 + q0 * q3), R(0.5) - q0 * q0 - q2 * q2, q0 * q1 - q2 * q3)
        return (q1 * q2 + q0 * q3, q0 * q0 - R(0.5) + q2 * q2, q2 * q3 - q0 * q1)

    def _feedback(self, sensor, reference):
        if vec_dot(sensor, reference) < self._o.R(0.0):
            return vec_normalise(self._o, vec_cross(sensor, reference), self._invsqrt)
        return vec_cross(sensor, reference)

    @staticmethod
    def _clamp(value, lo, hi):
        if value < lo:
            return lo
        if value > hi:
            return hi
        return value

    def _ahrs_update(self, gyr, acc, mag, dt):
        o = self._o
        R = o.R
        invsqrt = self._invsqrt
        period = self.recovery_trigger_period

        # keep the accelerometer for the acceleration outputs
        self.acc_x, self.acc_y, self.acc_z = acc

        # gyroscope overrange: start again from the current attitude
        rng = self.gyroscope_range
        if o.fabs(gyr[0]) > rng or o.fabs(gyr[1]) > rng or o.fabs(gyr[2]) > rng:
            q = (self.q0, self.q1, self.q2, self.q3)
            self._reset()
            self.q0, self.q1, self.q2, self.q3 = q
            self.angular_rate_recovery = 1

        # startup: ramp the gain down from 10 to gain
        if self.initialising != 0:
            self.ramped_gain = self.ramped_gain - self.ramped_gain_step * dt
            if self.ramped_gain < self.gain or self.gain == R(0.0):
                self.ramped_gain = self.gain
                self.initialising = 0
                self.angular_rate_recovery = 0

        half_grav = self._half_gravity()

        # accelerometer feedback, with rejection and recovery
        half_acc_fb = (R(0.0), R(0.0), R(0.0))
        self.accelerometer_ignored = 1
        if not vec_is_zero(o, acc):
            fb = self._feedback(vec_normalise(o, acc, invsqrt), half_grav)
            self.half_acc_fb_x, self.half_acc_fb_y, self.half_acc_fb_z = fb
            if self.initialising != 0 or vec_norm2(fb) <= self.acceleration_rejection:
                self.accelerometer_ignored = 0
                self.acceleration_recovery_trigger -= 9
            else:
                self.acceleration_recovery_trigger += 1
            if self.acceleration_recovery_trigger > self.acceleration_recovery_timeout:
                self.acceleration_recovery_timeout = 0
                self.accelerometer_ignored = 0
            else:
                self.acceleration_recovery_timeout = period
            self.acceleration_recovery_trigger = self._clamp(self.acceleration_recovery_trigger,
                                                             0, period)
            if self.accelerometer_ignored == 0:
                half_acc_fb = fb

        # magnetometer feedback: the horizontal field direction, gravity x m
        half_mag_fb = (R(0.0), R(0.0), R(0.0))
        self.magnetometer_ignored = 1
        if not vec_is_zero(o, mag):
            half_mag = self._half_magnetic()
            fb = self._feedback(vec_normalise(o, vec_cross(half_grav, mag), invsqrt), half_mag)
            self.half_mag_fb_x, self.half_mag_fb_y, self.half_mag_fb_z = fb
            if self.initialising != 0 or vec_norm2(fb) <= self.magnetic_rejection:
                self.magnetometer_ignored = 0
                self.magnetic_recovery_trigger -= 9
            else:
                self.magnetic_recovery_trigger += 1
            if self.magnetic_recovery_trigger > self.magnetic_recovery_timeout:
                self.magnetic_recovery_timeout = 0
                self.magnetometer_ignored = 0
            else:
                self.magnetic_recovery_timeout = period
            self.magnetic_recovery_trigger = self._clamp(self.magnetic_recovery_trigger, 0, period)
            if self.magnetometer_ignored == 0:
                half_mag_fb = fb

        # gyroscope in rad/s, halved, plus the gained feedback
        half_gyr = vec_scale(gyr, deg2rad(o, R(0.5)))
        adjusted = vec_add(half_gyr, vec_scale(vec_add(half_acc_fb, half_mag_fb), self.ramped_gain))

        # q <- normalise(q + q (x) (0, adjusted dt))
        q = (self.q0, self.q1, self.q2, self.q3)
        q = quat_add(q, quat_mul_vec(q, vec_scale(adjusted, dt)))
        self.q0, self.q1, self.q2, self.q3 = quat_normalise(o, q, invsqrt)

    def _ahrs_set_heading(self, heading):
        o = self._o
        R = o.R
        q0, q1, q2, q3 = self.q0, self.q1, self.q2, self.q3
        yaw = o.atan2(q0 * q3 + q1 * q2, R(0.5) - q2 * q2 - q3 * q3)
        half_yaw_minus_heading = R(0.5) * (yaw - deg2rad(o, heading))
        rotation = (o.cos(half_yaw_minus_heading), R(0.0), R(0.0),
                    R(-1.0) * o.sin(half_yaw_minus_heading))
        self.q0, self.q1, self.q2, self.q3 = quat_mul(rotation, (q0, q1, q2, q3))

    def _state_finite(self):
        return (_finite(self.q0, self.q1, self.q2, self.q3)
                and _finite(self.ramped_gain, self.half_acc_fb_x, self.half_acc_fb_y,
                            self.half_acc_fb_z)
                and _finite(self.half_mag_fb_x, self.half_mag_fb_y, self.half_mag_fb_z)
                and (self.q0 != 0 or self.q1 != 0 or self.q2 != 0 or self.q3 != 0))

    @staticmethod
    def _inputs_ok(gyr, acc, dt):
        return _finite(*gyr) and _finite(*acc) and math.isfinite(dt) and dt >= 0

    def _commit_or_restore(self, saved):
        if not self._state_finite():
            self._set_raw(saved)
            self.skipped = (self.skipped + 1) & 0xFFFFFFFF

    def _raw(self):
        return [getattr(self, n) for n in self.state_names]

    def _set_raw(self, values):
        for n, v in zip(self.state_names, values):
            setattr(self, n, v)

    def _skip(self):
        self.skipped = (self.skipped + 1) & 0xFFFFFFFF

    def _update(self, gyr, acc, mag, dt):
        saved = self._raw()
        if not self._inputs_ok(gyr, acc, dt) or not _finite(*mag):
            self._skip()
            return
        self._ahrs_update(gyr, acc, mag, dt)
        self._commit_or_restore(saved)

    def _update_no_magnetometer(self, gyr, acc, dt):
        R = self._o.R
        saved = self._raw()
        if not self._inputs_ok(gyr, acc, dt):
            self._skip()
            return
        self._ahrs_update(gyr, acc, (R(0.0), R(0.0), R(0.0)), dt)
        # without a heading reference, hold the heading at 0 while initialising
        if self.initialising != 0:
            self._ahrs_set_heading(R(0.0))
        self._commit_or_restore(saved)

    def _update_external_heading(self, gyr, acc, heading, dt):
        o = self._o
        R = o.R
        saved = self._raw()
        if not self._inputs_ok(gyr, acc, dt) or not math.isfinite(heading):
            self._skip()
            return
        # a magnetometer reading pointing along the given heading, at the current roll
        q0, q1, q2, q3 = self.q0, self.q1, self.q2, self.q3
        roll = o.atan2(q0 * q1 + q2 * q3, R(0.5) - q2 * q2 - q1 * q1)
        heading_rad = deg2rad(o, heading)
        sin_heading = o.sin(heading_rad)
        mag = (o.cos(heading_rad), R(-1.0) * o.cos(roll) * sin_heading, sin_heading * o.sin(roll))
        self._ahrs_update(gyr, acc, mag, dt)
        self._commit_or_restore(saved)

    def _set_heading(self, heading):
        saved = self._raw()
        if not math.isfinite(heading):
            self._skip()
            return
        self._ahrs_set_heading(heading)
        self._commit_or_restore(saved)

    # -- public per-sample API

    def _vec(self, name, v):
        R = self._o.R
        return tuple(_fusion.to_real(R, c) for c in _checks.as_vec3(name, v))

    def update(self, gyr, acc, mag, dt):
        """One sample: gyr (deg/s), acc (g), mag (any unit; all-zero: no
        magnetometer feedback this sample), dt (s)."""
        g, a, m = self._vec("gyr", gyr), self._vec("acc", acc), self._vec("mag", mag)
        d = _fusion.to_real(self._o.R, _fusion.check_dt_value(dt))
        with np.errstate(all="ignore"):
            self._update(g, a, m, d)

    def update_no_magnetometer(self, gyr, acc, dt):
        """One sample without magnetometer; heading held at 0 while initialising."""
        g, a = self._vec("gyr", gyr), self._vec("acc", acc)
        d = _fusion.to_real(self._o.R, _fusion.check_dt_value(dt))
        with np.errstate(all="ignore"):
            self._update_no_magnetometer(g, a, d)

    def update_external_heading(self, gyr, acc, heading, dt):
        """One sample with a heading (degrees) from another source."""
        g, a = self._vec("gyr", gyr), self._vec("acc", acc)
        h = _fusion.to_real(self._o.R, _fusion.check_scalar("heading", heading))
        d = _fusion.to_real(self._o.R, _fusion.check_dt_value(dt))
        with np.errstate(all="ignore"):
            self._update_external_heading(g, a, h, d)

    def set_heading(self, heading):
        """Rotate about the earth vertical so that the yaw is heading (degrees)."""
        h = _fusion.check_scalar("heading", heading)
        if not math.isfinite(h):
            raise ValueError(f"heading: must be finite, got {heading!r}")
        with np.errstate(all="ignore"):
            self._set_heading(self._o.R(h))

    @property
    def quaternion(self):
        return np.array([self.q0, self.q1, self.q2, self.q3], dtype=self.dtype)

    @quaternion.setter
    def quaternion(self, value):
        q = _fusion.quaternion(value, self.dtype)
        R = self._o.R
        self.q0, self.q1, self.q2, self.q3 = (R(v) for v in q)

    @property
    def state(self):
        return np.array(self._raw(), dtype=self.dtype)

    @state.setter
    def state(self, value):
        arr = _fusion.ahrs_state(value, self.dtype, self.recovery_trigger_period)
        problem = _checks.dead_state(self, arr, "fusion")
        if problem:
            raise ValueError(problem)
        R = self._o.R
        vals = [R(v) for v in arr[:_fusion.N_REAL]] + [int(v) for v in arr[_fusion.N_REAL:]]
        self._set_raw(vals)

    # -- outputs (imf_fusion_ahrs_outputs, imf_fusion_ahrs_flags)

    def _outputs(self):
        o = self._o
        R = o.R
        qw, qx, qy, qz = self.q0, self.q1, self.q2, self.q3
        ax, ay, az = self.acc_x, self.acc_y, self.acc_z
        out = [R(0.0)] * _fusion.N_OUT
        # gravity in the sensor frame: third column of R^T (up)
        gx = R(2.0) * (qx * qz - qw * qy)
        gy = R(2.0) * (qy * qz + qw * qx)
        gz = R(2.0) * (qw * qw - R(0.5) + qz * qz)
        # R a: the accelerometer in the earth frame, common products first
        qwqw, qwqx, qwqy, qwqz = qw * qw, qw * qx, qw * qy, qw * qz
        qxqy, qxqz, qyqz = qx * qy, qx * qz, qy * qz
        half_minus_qyqy = R(0.5) - qy * qy
        out[6] = R(2.0) * ((qwqw - R(0.5) + qx * qx) * ax + (qxqy - qwqz) * ay + (qxqz + qwqy) * az)
        out[7] = R(2.0) * ((qxqy + qwqz) * ax + (qwqw - R(0.5) + qy * qy) * ay + (qyqz - qwqx) * az)
        out[8] = R(2.0) * ((qxqz - qwqy) * ax + (qyqz + qwqx) * ay + (qwqw - R(0.5) + qz * qz) * az)
        if self.convention == NED:
            # earth z down: the accelerometer reads -up at rest
            out[0:3] = [-gx, -gy, -gz]
            out[3:6] = [ax + gx, ay + gy, az + gz]
            out[8] = out[8] + R(1.0)
        else:
            out[0:3] = [gx, gy, gz]
            out[3:6] = [ax - gx, ay - gy, az - gz]
            out[8] = out[8] - R(1.0)
        # Euler angles (ZYX), degrees
        out[9] = rad2deg(o, o.atan2(qw * qx + qy * qz, half_minus_qyqy - qx * qx))
        out[10] = rad2deg(o, safe_asin(o, R(2.0) * (qw * qy - qz * qx)))
        out[11] = rad2deg(o, o.atan2(qw * qz + qx * qy, half_minus_qyqy - qz * qz))
        period = self.recovery_trigger_period
        out[12] = error_degrees(o, (self.half_acc_fb_x, self.half_acc_fb_y, self.half_acc_fb_z))
        out[13] = trigger_ratio(o, self.acceleration_recovery_trigger, period)
        out[14] = error_degrees(o, (self.half_mag_fb_x, self.half_mag_fb_y, self.half_mag_fb_z))
        out[15] = trigger_ratio(o, self.magnetic_recovery_trigger, period)
        return out

    def _flags(self):
        flags = 0
        if self.initialising != 0:
            flags |= 1
        if self.angular_rate_recovery != 0:
            flags |= 2
        if self.acceleration_recovery_trigger > self.acceleration_recovery_timeout:
            flags |= 4
        if self.magnetic_recovery_trigger > self.magnetic_recovery_timeout:
            flags |= 8
        if self.accelerometer_ignored != 0:
            flags |= 16
        if self.magnetometer_ignored != 0:
            flags |= 32
        return flags

    def outputs(self):
        """The outputs now: dict of gravity, linear_acceleration,
        earth_acceleration (g), euler (roll, pitch, yaw; degrees),
        acceleration_error, magnetic_error (degrees), the recovery triggers
        (0..1) and the flags (bool)."""
        with np.errstate(all="ignore"):
            out = np.array(self._outputs(), dtype=self.dtype)
        return _fusion.pack_one(out, self._flags())

    def outputs_batch(self, states):
        """outputs() for every row of a run() result, as (N, ...) arrays
        (with this filter's convention and recovery period)."""
        arr = _fusion.states_array(states, self.dtype)
        saved = self._raw()
        out = np.empty((arr.shape[0], _fusion.N_OUT), dtype=self.dtype)
        flags = np.empty(arr.shape[0], dtype=np.uint32)
        R = self._o.R
        rows = arr.tolist() if self.dtype == "float64" else arr
        try:
            with np.errstate(all="ignore"):
                for k, row in enumerate(rows):
                    self._set_raw([R(v) for v in row[:_fusion.N_REAL]]
                                  + [int(v) for v in row[_fusion.N_REAL:]])
                    out[k] = self._outputs()
                    flags[k] = self._flags()
        finally:
            self._set_raw(saved)
        return _fusion.pack_outputs(out, flags)

    # -- batch

    def run(self, gyr, acc, mag=None, *, dt, heading=None):
        """All samples: gyr, acc (N, 3); mag (N, 3) for update(), or heading
        (N,) for update_external_heading(), or neither for
        update_no_magnetometer(); dt scalar or (N,) seconds. Returns the
        (N, 22) state after every sample."""
        g, a, m, h, d = _fusion.run_arrays(self.dtype, gyr, acc, mag, heading, dt)
        n = g.shape[0]
        out = np.empty((n, len(self.state_names)), dtype=self.dtype)
        conv = (lambda x: x.tolist()) if self.dtype == "float64" else (lambda x: [tuple(r) for r in x])
        gl, al = conv(g), conv(a)
        dl = d.tolist() if self.dtype == "float64" else list(d)
        ml = conv(m) if m is not None else None
        hl = (h.tolist() if self.dtype == "float64" else list(h)) if h is not None else None
        with np.errstate(all="ignore"):
            for k in range(n):
                if ml is not None:
                    self._update(tuple(gl[k]), tuple(al[k]), tuple(ml[k]), dl[k])
                elif hl is not None:
                    self._update_external_heading(tuple(gl[k]), tuple(al[k]), hl[k], dl[k])
                else:
                    self._update_no_magnetometer(tuple(gl[k]), tuple(al[k]), dl[k])
                out[k] = self._raw()
        return out

    def __repr__(self):
        return f"<imufuse.reference FusionAHRS dtype={self.dtype}>"


# ---- fusion_offset.c ----------------------------------------------------------

class FusionOffset:
    """x-io Fusion's gyroscope offset estimator in FUSION'S UNITS: gyroscope deg/s, sample_rate Hz.

    Longbin's walkthrough / imufusion 1.2.3, bit-exact with it in float32; one update per
    sample. After 5 s with every corrected axis within
    3 deg/s the offset follows the gyroscope through a 0.02 Hz low-pass.
    update(gyr) returns the corrected gyroscope; run(gyr) returns
    (corrected (N, 3), state (N, 4)).
    """
    kind = "fusion_offset"
    c_name = "imf_fusion_offset"
    state_names = _fusion.OFFSET_STATE_NAMES

    def __init__(self, sample_rate, *, dtype="float64"):
        self.dtype = _checks.check_dtype(dtype)
        self._o = _Ops(self.dtype)
        self._args = self._params(sample_rate)
        self.reset()

    @staticmethod
    def _params(sample_rate):
        return _fusion.offset_params(sample_rate)

    def reset(self):
        R = self._o.R
        (sample_rate,) = self._args
        # 2 pi fc dt, dt = 1 / fs rounded once
        self.filter_coefficient = R(2.0) * self._o.pi * R(0.02) * (R(1.0) / R(sample_rate))
        self.timeout = 5 * sample_rate
        self.skipped = 0
        self.timer = 0
        self.offset_x, self.offset_y, self.offset_z = R(0.0), R(0.0), R(0.0)

    def _update(self, g):
        fabs = self._o.fabs
        # subtract the current offset estimate
        wx = g[0] - self.offset_x
        wy = g[1] - self.offset_y
        wz = g[2] - self.offset_z
        out = (wx, wy, wz)
        if not _finite(*g):
            self.skipped = (self.skipped + 1) & 0xFFFFFFFF
            return out
        # moving: start the rest timer again
        threshold = self._o.R(3.0)
        if fabs(wx) > threshold or fabs(wy) > threshold or fabs(wz) > threshold:
            self.timer = 0
            return out
        # at rest, but not yet for the timeout
        if self.timer < self.timeout:
            self.timer += 1
            return out
        # at rest long enough: low-pass the offset towards the measurement
        self.offset_x = self.offset_x + wx * self.filter_coefficient
        self.offset_y = self.offset_y + wy * self.filter_coefficient
        self.offset_z = self.offset_z + wz * self.filter_coefficient
        return out

    def update(self, gyr):
        R = self._o.R
        g = tuple(_fusion.to_real(R, c) for c in _checks.as_vec3("gyr", gyr))
        with np.errstate(all="ignore"):
            return np.array(self._update(g), dtype=self.dtype)

    def run(self, gyr):
        (g,) = _checks.as_nx3(self.dtype, gyr=gyr)
        n = g.shape[0]
        out = np.empty((n, 3), dtype=self.dtype)
        st = np.empty((n, 4), dtype=self.dtype)
        rows = g.tolist() if self.dtype == "float64" else [tuple(r) for r in g]
        with np.errstate(all="ignore"):
            for k in range(n):
                out[k] = self._update(tuple(rows[k]))
                st[k] = (self.offset_x, self.offset_y, self.offset_z, self.timer)
        return out, st

    @property
    def state(self):
        return np.array([self.offset_x, self.offset_y, self.offset_z, self.timer], dtype=self.dtype)

    @state.setter
    def state(self, value):
        arr = _checks.as_state(value, 4, self.dtype, self.state_names)
        if arr[3] != int(arr[3]) or not 0 <= arr[3] <= self.timeout:
            raise ValueError(f"state: timer must be an integer in [0, {self.timeout}]")
        R = self._o.R
        self.offset_x, self.offset_y, self.offset_z = R(arr[0]), R(arr[1]), R(arr[2])
        self.timer = int(arr[3])

    def __repr__(self):
        return f"<imufuse.reference FusionOffset dtype={self.dtype}>"


# ---- fusion_calibration.c -----------------------------------------------------

def _rows(dtype, name, x):
    (arr,) = _checks.as_nx3(dtype, **{name: np.atleast_2d(x)})
    return arr


def calibrate_inertial(x, M, s, b, dtype="float64"):
    """i_c = M ((i_u - b) .* s) for each row of x (N, 3)."""
    dtype = _checks.check_dtype(dtype)
    R = _Ops(dtype).R
    m = [R(v) for v in _fusion.model_param("M", M, (3, 3), dtype)]
    sens = tuple(R(v) for v in _fusion.model_param("s", s, (3,), dtype))
    off = tuple(R(v) for v in _fusion.model_param("b", b, (3,), dtype))
    arr = _rows(dtype, "x", x)
    out = np.empty_like(arr)
    rows = arr.tolist() if dtype == "float64" else [tuple(r) for r in arr]
    with np.errstate(all="ignore"):
        for k, u in enumerate(rows):
            out[k] = mat_mul_vec(m, vec_hadamard(vec_sub(tuple(u), off), sens))
    return _checks.canonical_nan(out)


def calibrate_magnetic(x, S, h, dtype="float64"):
    """m_c = S (m_u - h) for each row of x (N, 3)."""
    dtype = _checks.check_dtype(dtype)
    R = _Ops(dtype).R
    m = [R(v) for v in _fusion.model_param("S", S, (3, 3), dtype)]
    hard = tuple(R(v) for v in _fusion.model_param("h", h, (3,), dtype))
    arr = _rows(dtype, "x", x)
    out = np.empty_like(arr)
    rows = arr.tolist() if dtype == "float64" else [tuple(r) for r in arr]
    with np.errstate(all="ignore"):
        for k, u in enumerate(rows):
            out[k] = mat_mul_vec(m, vec_sub(tuple(u), hard))
    return _checks.canonical_nan(out)


def axes_apply(x, alignment, dtype="float64"):
    """out_i = sign_i x_{perm_i} for each row (alignment like '+X-Z+Y')."""
    dtype = _checks.check_dtype(dtype)
    perm, neg = _fusion.parse_alignment(alignment)
    arr = _rows(dtype, "x", x)
    out = np.empty_like(arr)
    for k in range(arr.shape[0]):
        u = arr[k]
        out[k] = [-u[perm[i]] if neg[i] else u[perm[i]] for i in range(3)]
    return out


def compass_heading(convention, acc, mag, invsqrt="exact", dtype="float64"):
    """Tilt-compensated heading (degrees) for each row of acc, mag (N, 3)."""
    dtype = _checks.check_dtype(dtype)
    o = _Ops(dtype)
    R = o.R
    conv = _fusion.ahrs_params(dtype, convention)[0]
    mode = _fusion.INVSQRT[_checks.check_choice("invsqrt", invsqrt, tuple(_fusion.INVSQRT))]
    a, m = _checks.as_nx3(dtype, acc=np.atleast_2d(acc), mag=np.atleast_2d(mag))
    out = np.empty(a.shape[0], dtype=dtype)
    with np.errstate(all="ignore"):
        for k in range(a.shape[0]):
            acc_k = tuple(R(v) for v in a[k])
            mag_k = tuple(R(v) for v in m[k])
            # NED: gravity "up" is -acc; NWU and ENU: acc
            up = vec_scale(acc_k, R(-1.0)) if conv == NED else acc_k
            w = vec_cross(up, mag_k)
            # up x m = 0 (no accelerometer, no field, or a field along gravity): no heading
            if vec_norm2(w) == R(0.0):
                out[k] = R(np.nan)
                continue
            west = vec_normalise(o, w, mode)
            north = vec_normalise(o, vec_cross(west, up), mode)
            if conv == ENU:
                east = vec_scale(west, R(-1.0))
                out[k] = rad2deg(o, o.atan2(north[0], east[0]))
            else:
                out[k] = rad2deg(o, o.atan2(west[0], north[0]))
    _checks.canonical_nan(out)
    return out
