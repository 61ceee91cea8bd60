"""x-io Fusion's current release (1.3, as in imufusion 1.3.3): pure-Python twin of
csrc/fusion13.c and fusion13_bias.c, line for line, with the vector helpers of the 1.2.3
twin (fusion.py, the twin of csrc/fusion_math.h, which both releases share).

Longer than 500 lines because: it is the twin of Fusion 1.3's AHRS and bias algorithm, one
library, kept in one module as the 1.2.3 twin keeps its suite; compared with the C line by
line.

UNITS ARE FUSION'S: gyroscope in degrees per second, accelerometer in g, magnetometer in any
unit, sample rate in Hz, sample period and timeouts in seconds, angles in degrees.
"""
import math

import numpy as np

from ..shared import checks as _checks
from . import _fusion, _fusion13
from .fusion import (ENU, NED, _finite, _Ops, deg2rad, error_degrees, mat_mul_vec,
                     quat_add, quat_mul, quat_mul_vec, quat_normalise, rad2deg, safe_asin,
                     trigger_ratio, vec_add, vec_cross, vec_dot, vec_hadamard, vec_is_zero,
                     vec_norm2, vec_normalise, vec_scale, vec_sub)

INITIAL_GAIN = 10.0
STARTUP_PERIOD = 3.0
BIAS_CUTOFF = 0.02


def _clamp(value, lo, hi):
    if value < lo:
        return lo
    if value > hi:
        return hi
    return value


class FusionAHRS13:
    """x-io Fusion 1.3's AHRS in FUSION'S UNITS: gyroscope deg/s (not rad/s), accelerometer g.

    imufusion 1.3.3, bit-exact with it in float32. Settings (Fusion 1.3's defaults):
    sample_rate in Hz (100), convention "NWU" | "ENU" | "NED" ("NWU"), gain (0.5),
    gyroscope_range in deg/s (0: no overrange detection), acceleration_rejection and
    magnetic_rejection in degrees (0: disabled), rejection_timeout in seconds (0: rejection
    disabled), invsqrt "exact" (imufusion's FUSION_USE_NORMAL_SQRT) | "fast".

    The sample period is 1 / sample_rate until set_sample_period(dt) replaces it (Fusion's
    FusionAhrsSetSamplePeriod); every update form takes an optional dt that does so first.
    update(gyr, acc, mag, dt=None), update_no_magnetometer(gyr, acc, dt=None),
    update_external_heading(gyr, acc, heading, dt=None), set_heading(heading),
    set_sample_period(dt), skip_startup(), restart() (= reset()), set_settings(**settings),
    quaternion, state (settable), outputs(), outputs_batch(states);
    run(gyr, acc, mag=None, *, dt=None, heading=None) returns the full state after every
    sample (dt: None keeps the period, a scalar or (N,) sets it before every update).
    """
    kind = "fusion"
    c_name = "imf_fusion13_ahrs"
    state_names = _fusion13.AHRS_STATE_NAMES

    def __init__(self, *args, dtype="float64", **kwargs):
        self.dtype = _checks.check_dtype(dtype)
        self._o = _Ops(self.dtype)
        self._args = self._params(*args, dtype=self.dtype, **kwargs)
        self._invsqrt = self._args[7]
        self._init()

    @staticmethod
    def _params(sample_rate=100.0, convention="NWU", gain=0.5, gyroscope_range=0.0,
                acceleration_rejection=0.0, magnetic_rejection=0.0, rejection_timeout=0.0,
                invsqrt="exact", dtype="float64"):
        return _fusion13.ahrs_params(dtype, sample_rate, convention, gain, gyroscope_range,
                                     acceleration_rejection, magnetic_rejection,
                                     rejection_timeout, invsqrt)

    # -- init, settings, restart (imf_fusion13_ahrs_init, _set_settings, _restart, ...)

    def _init(self):
        self.skipped = 0
        self._set_settings(*self._args[:7])
        self._restart()

    def _rejection_threshold(self, degrees):
        o = self._o
        if degrees == o.R(0.0):
            return o.real_max
        v = o.R(0.5) * o.sin(deg2rad(o, degrees))
        return v * v

    def _set_settings(self, sample_rate, convention, gain, gyroscope_range,
                      acceleration_rejection, magnetic_rejection, rejection_timeout):
        o = self._o
        R = o.R
        sample_rate, rejection_timeout = R(sample_rate), R(rejection_timeout)
        self.sample_period = R(1.0) / sample_rate
        self.convention = convention
        self.gain = R(gain)
        # the ramp per update, at the settings' period
        self.startup_gain_rate = ((R(INITIAL_GAIN) - self.gain) / R(STARTUP_PERIOD)
                                  ) * self.sample_period
        self.overrange_enabled = R(gyroscope_range) > R(0.0)
        self.overrange_threshold = R(0.98) * R(gyroscope_range)
        self.acceleration_rejection = self._rejection_threshold(R(acceleration_rejection))
        self.magnetic_rejection = self._rejection_threshold(R(magnetic_rejection))
        self.rejection_timeout = int(sample_rate * rejection_timeout)
        self.acceleration_recovery_threshold = self.rejection_timeout
        self.magnetic_recovery_threshold = self.rejection_timeout
        # without feedback or without a timeout, rejection is disabled
        if self.gain == R(0.0) or rejection_timeout == R(0.0):
            self.acceleration_rejection = o.real_max
            self.magnetic_rejection = o.real_max

    def set_settings(self, **settings):
        """New settings at any time (FusionAhrsSetSettings): the period becomes
        1 / sample_rate; the state is kept."""
        _fusion13.check_settings(settings)
        cur = _fusion13.user_settings(self._args)
        cur.update(settings)
        self._args = self._params(**cur, invsqrt=_fusion13.invsqrt_name(self._invsqrt),
                                  dtype=self.dtype)
        with np.errstate(all="ignore"):
            self._set_settings(*self._args[:7])

    def _restart(self):
        R = self._o.R
        self.q0, self.q1, self.q2, self.q3 = R(1.0), R(0.0), R(0.0), R(0.0)
        self.acc_x, self.acc_y, self.acc_z = R(0.0), R(0.0), R(0.0)
        self.startup = 1
        self.startup_gain = R(INITIAL_GAIN)
        self.overrange_recovery = 0
        self.half_acc_res_x, self.half_acc_res_y, self.half_acc_res_z = R(0.0), R(0.0), R(0.0)
        self.acceleration_recovery_trigger = 0
        self.acceleration_recovery_threshold = self.rejection_timeout
        self.accelerometer_ignored = 0
        self.half_mag_res_x, self.half_mag_res_y, self.half_mag_res_z = R(0.0), R(0.0), R(0.0)
        self.magnetic_recovery_trigger = 0
        self.magnetic_recovery_threshold = self.rejection_timeout
        self.magnetometer_ignored = 0

    def restart(self):
        """Back to the initial state (identity, start-up), keeping the settings and the
        sample period (FusionAhrsRestart)."""
        self._restart()

    reset = restart

    def skip_startup(self):
        """End start-up now (FusionAhrsSkipStartup): the initial orientation is known."""
        self.startup = 0
        self.overrange_recovery = 0

    def _set_sample_period(self, dt):
        if not math.isfinite(dt) or dt < self._o.R(0.0):
            self.skipped = (self.skipped + 1) & 0xFFFFFFFF
            return
        self.sample_period = dt

    def set_sample_period(self, dt):
        """The measured sample period (s) of the next updates (FusionAhrsSetSamplePeriod)."""
        self._set_sample_period(_fusion.to_real(self._o.R, _fusion.check_dt_value(dt)))

    # -- the update

    def _overrange(self, gyr):
        o = self._o
        threshold = self.overrange_threshold
        if not self.overrange_enabled:
            return
        if (o.fabs(gyr[0]) <= threshold and o.fabs(gyr[1]) <= threshold
                and o.fabs(gyr[2]) <= threshold):
            return
        q = (self.q0, self.q1, self.q2, self.q3)
        acc = (self.acc_x, self.acc_y, self.acc_z)
        self._restart()
        self.q0, self.q1, self.q2, self.q3 = q
        self.acc_x, self.acc_y, self.acc_z = acc
        self.overrange_recovery = 1

    def _startup(self):
        if self.startup == 0:
            return self.gain
        self.startup_gain = self.startup_gain - self.startup_gain_rate
        if self.startup_gain > self.gain:
            return self.startup_gain
        self.startup = 0
        self.overrange_recovery = 0
        return self.gain

    def _half_gravity(self):
        R = self._o.R
        q0, q1, q2, q3 = self.q0, self.q1, self.q2, self.q3
        if self.convention == NED:
            return (q0 * q2 - q1 * q3, R(-1.0) * (q2 * q3 + q0 * q1), R(0.5) - q0 * q0 - q3 * q3)
        return (q1 * q3 - q0 * q2, q2 * q3 + q0 * q1, q0 * q0 - R(0.5) + q3 * q3)

    def _half_west(self):
        R = self._o.R
        q0, q1, q2, q3 = self.q0, self.q1, self.q2, self.q3
        if self.convention == ENU:
            return (R(0.5) - q0 * q0 - q1 * q1, q0 * q3 - q1 * q2, R(-1.0) * (q1 * q3 + q0 * q2))
        if self.convention == NED:
            return (R(-1.0) * (q1 * q2 + q0 * q3), R(0.5) - q0 * q0 - q2 * q2, q0 * q1 - q2 * q3)
        return (q1 * q2 + q0 * q3, q0 * q0 - R(0.5) + q2 * q2, q2 * q3 - q0 * q1)

    def _residual(self, sensor, reference):
        cross = vec_cross(sensor, reference)
        zero = (self._o.R(0.0), self._o.R(0.0), self._o.R(0.0))
        if vec_dot(sensor, reference) > self._o.R(0.0):
            return cross
        # +0 in every component (a zero cross product may hold -0)
        if vec_is_zero(self._o, cross):
            return zero
        return vec_normalise(self._o, cross, self._invsqrt)

    def _reject(self, half_res, rejection, trigger, threshold):
        """(ignored, trigger, threshold) after one residual (imf_fusion13 reject())."""
        timeout = self.rejection_timeout
        ignored = 1
        if self.startup != 0 or vec_norm2(half_res) <= rejection:
            ignored = 0
            trigger -= 9
        else:
            trigger += 1
        if trigger > threshold:
            threshold = 0
            ignored = 0
        else:
            threshold = timeout
        trigger = _clamp(trigger, 0, timeout)
        return ignored, trigger, threshold

    def _half_inclination_feedback(self, half_grav, acc):
        R = self._o.R
        zero = (R(0.0), R(0.0), R(0.0))
        self.accelerometer_ignored = 1
        if vec_is_zero(self._o, acc):
            return zero
        res = self._residual(vec_normalise(self._o, acc, self._invsqrt), half_grav)
        self.half_acc_res_x, self.half_acc_res_y, self.half_acc_res_z = res
        (self.accelerometer_ignored, self.acceleration_recovery_trigger,
         self.acceleration_recovery_threshold) = self._reject(
            res, self.acceleration_rejection, self.acceleration_recovery_trigger,
            self.acceleration_recovery_threshold)
        return res if self.accelerometer_ignored == 0 else zero

    def _half_heading_feedback(self, half_grav, mag):
        R = self._o.R
        zero = (R(0.0), R(0.0), R(0.0))
        self.magnetometer_ignored = 1
        if vec_is_zero(self._o, mag):
            return zero
        west = self._half_west()
        res = self._residual(vec_normalise(self._o, vec_cross(half_grav, mag), self._invsqrt),
                             west)
        self.half_mag_res_x, self.half_mag_res_y, self.half_mag_res_z = res
        (self.magnetometer_ignored, self.magnetic_recovery_trigger,
         self.magnetic_recovery_threshold) = self._reject(
            res, self.magnetic_rejection, self.magnetic_recovery_trigger,
            self.magnetic_recovery_threshold)
        return res if self.magnetometer_ignored == 0 else zero

    def _ahrs_update(self, gyr, acc, mag):
        o = self._o
        R = o.R
        self.acc_x, self.acc_y, self.acc_z = acc
        self._overrange(gyr)
        gain = self._startup()
        half_gyr = vec_scale(gyr, deg2rad(o, R(0.5)))
        half_grav = self._half_gravity()
        half_fb = self._half_inclination_feedback(half_grav, acc)
        half_fb = vec_add(half_fb, self._half_heading_feedback(half_grav, mag))
        half_rate = vec_add(half_gyr, vec_scale(half_fb, gain))
        # q <- normalise(q + q (x) (0, half_rate T))
        q = (self.q0, self.q1, self.q2, self.q3)
        q = quat_add(q, quat_mul_vec(q, vec_scale(half_rate, self.sample_period)))
        self.q0, self.q1, self.q2, self.q3 = quat_normalise(o, q, self._invsqrt)

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
                and _finite(self.startup_gain, self.half_acc_res_x, self.half_acc_res_y,
                            self.half_acc_res_z)
                and _finite(self.half_mag_res_x, self.half_mag_res_y, self.half_mag_res_z)
                and (self.q0 != 0 or self.q1 != 0 or self.q2 != 0 or self.q3 != 0))

    def _raw(self):
        return [getattr(self, n) for n in self.state_names]

    def _set_raw(self, values):
        for n, v in zip(self.state_names, values):
            setattr(self, n, v)

    def _commit_or_restore(self, saved):
        if not self._state_finite():
            self._set_raw(saved)
            self.skipped = (self.skipped + 1) & 0xFFFFFFFF

    def _skip(self):
        self.skipped = (self.skipped + 1) & 0xFFFFFFFF

    def _update(self, gyr, acc, mag):
        saved = self._raw()
        if not (_finite(*gyr) and _finite(*acc) and _finite(*mag)):
            self._skip()
            return
        self._ahrs_update(gyr, acc, mag)
        self._commit_or_restore(saved)

    def _update_no_magnetometer(self, gyr, acc):
        R = self._o.R
        saved = self._raw()
        if not (_finite(*gyr) and _finite(*acc)):
            self._skip()
            return
        self._ahrs_update(gyr, acc, (R(0.0), R(0.0), R(0.0)))
        # without a heading reference, hold the heading at 0 during start-up
        if self.startup != 0:
            self._ahrs_set_heading(R(0.0))
        self._commit_or_restore(saved)

    def _update_external_heading(self, gyr, acc, heading):
        o = self._o
        R = o.R
        saved = self._raw()
        if not (_finite(*gyr) and _finite(*acc)) or not math.isfinite(heading):
            self._skip()
            return
        # a magnetometer reading pointing along the given heading, at the current roll
        q0, q1, q2, q3 = self.q0, self.q1, self.q2, self.q3
        roll = o.atan2(q0 * q1 + q2 * q3, R(0.5) - q2 * q2 - q1 * q1)
        heading_rad = deg2rad(o, heading)
        sin_heading = o.sin(heading_rad)
        mag = (o.cos(heading_rad), R(-1.0) * o.cos(roll) * sin_heading, sin_heading * o.sin(roll))
        self._ahrs_update(gyr, acc, mag)
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

    def _period(self, dt):
        if dt is not None:
            self._set_sample_period(_fusion.to_real(self._o.R, _fusion.check_dt_value(dt)))

    def update(self, gyr, acc, mag, dt=None):
        """One sample: gyr (deg/s), acc (g), mag (any unit; all-zero: no magnetometer
        feedback this sample); dt (s): the measured period, set first if given."""
        g, a, m = self._vec("gyr", gyr), self._vec("acc", acc), self._vec("mag", mag)
        with np.errstate(all="ignore"):
            self._period(dt)
            self._update(g, a, m)

    def update_no_magnetometer(self, gyr, acc, dt=None):
        """One sample without magnetometer; heading held at 0 during start-up."""
        g, a = self._vec("gyr", gyr), self._vec("acc", acc)
        with np.errstate(all="ignore"):
            self._period(dt)
            self._update_no_magnetometer(g, a)

    def update_external_heading(self, gyr, acc, heading, dt=None):
        """One sample with a heading (degrees) from another source."""
        g, a = self._vec("gyr", gyr), self._vec("acc", acc)
        h = _fusion.to_real(self._o.R, _fusion.check_scalar("heading", heading))
        with np.errstate(all="ignore"):
            self._period(dt)
            self._update_external_heading(g, a, h)

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
        arr = _fusion13.ahrs_state(value, self.dtype, self.rejection_timeout)
        R = self._o.R
        n = _fusion13.N_REAL
        self._set_raw([R(v) for v in arr[:n]] + [int(v) for v in arr[n:]])

    # -- outputs (imf_fusion13_ahrs_outputs, imf_fusion13_ahrs_flags)

    def _outputs(self):
        o = self._o
        R = o.R
        qw, qx, qy, qz = self.q0, self.q1, self.q2, self.q3
        ax, ay, az = self.acc_x, self.acc_y, self.acc_z
        g = vec_scale(self._half_gravity(), R(2.0))
        out = [*g, ax - g[0], ay - g[1], az - g[2]]
        # R a: the accelerometer in the earth frame, minus gravity
        out.append(R(2.0) * ((qw * qw - R(0.5) + qx * qx) * ax + (qx * qy - qw * qz) * ay
                             + (qx * qz + qw * qy) * az))
        out.append(R(2.0) * ((qx * qy + qw * qz) * ax + (qw * qw - R(0.5) + qy * qy) * ay
                             + (qy * qz - qw * qx) * az))
        ez = R(2.0) * ((qx * qz - qw * qy) * ax + (qy * qz + qw * qx) * ay
                       + (qw * qw - R(0.5) + qz * qz) * az)
        out.append(ez + R(1.0) if self.convention == NED else ez - R(1.0))
        # Euler angles (ZYX), degrees, in 1.3's form
        out.append(rad2deg(o, o.atan2(qy * qz + qw * qx, qw * qw + qz * qz - R(0.5))))
        out.append(rad2deg(o, safe_asin(o, R(2.0) * (qw * qy - qx * qz))))
        out.append(rad2deg(o, o.atan2(qx * qy + qw * qz, qw * qw + qx * qx - R(0.5))))
        out.append(error_degrees(self._o, (self.half_acc_res_x, self.half_acc_res_y,
                                        self.half_acc_res_z)))
        out.append(trigger_ratio(self._o, self.acceleration_recovery_trigger,
                                 self.rejection_timeout))
        out.append(error_degrees(self._o, (self.half_mag_res_x, self.half_mag_res_y,
                                        self.half_mag_res_z)))
        out.append(trigger_ratio(self._o, self.magnetic_recovery_trigger,
                                 self.rejection_timeout))
        return out

    def _flags(self):
        flags = 1 if self.startup != 0 else 0
        flags |= 2 if self.overrange_recovery != 0 else 0
        flags |= 4 if self.acceleration_recovery_trigger > self.acceleration_recovery_threshold \
            else 0
        flags |= 8 if self.magnetic_recovery_trigger > self.magnetic_recovery_threshold else 0
        flags |= 16 if self.accelerometer_ignored != 0 else 0
        flags |= 32 if self.magnetometer_ignored != 0 else 0
        return flags

    def outputs(self):
        """The outputs now: dict of gravity, linear_acceleration, earth_acceleration (g),
        euler (roll, pitch, yaw; degrees), acceleration_error, magnetic_error (degrees), the
        recovery triggers (0..1) and the flags (bool; `initialising` is 1.3's start-up,
        `angular_rate_recovery` its overrange recovery)."""
        with np.errstate(all="ignore"):
            out = np.array(self._outputs(), dtype=self.dtype)
        return _fusion.pack_one(out, self._flags())

    def outputs_batch(self, states):
        """outputs() for every row of a run() result, as (N, ...) arrays (with this filter's
        convention and rejection timeout)."""
        arr = _fusion13.states_array(states, self.dtype)
        saved = self._raw()
        out = np.empty((arr.shape[0], _fusion.N_OUT), dtype=self.dtype)
        flags = np.empty(arr.shape[0], dtype=np.uint32)
        R = self._o.R
        n = _fusion13.N_REAL
        rows = arr.tolist() if self.dtype == "float64" else arr
        try:
            with np.errstate(all="ignore"):
                for k, row in enumerate(rows):
                    self._set_raw([R(v) for v in row[:n]] + [int(v) for v in row[n:]])
                    out[k] = self._outputs()
                    flags[k] = self._flags()
        finally:
            self._set_raw(saved)
        return _fusion.pack_outputs(out, flags)

    # -- batch

    def run(self, gyr, acc, mag=None, *, dt=None, heading=None):
        """All samples: gyr, acc (N, 3); mag (N, 3) for update(), or heading (N,) for
        update_external_heading(), or neither for update_no_magnetometer(); dt None (the
        current period), a scalar or (N,) seconds set before every update. Returns the
        (N, 23) state after every sample."""
        g, a, m, h, d = _fusion13.run_arrays(self.dtype, gyr, acc, mag, heading, dt)
        n = g.shape[0]
        out = np.empty((n, len(self.state_names)), dtype=self.dtype)
        f64 = self.dtype == "float64"
        conv = (lambda x: x.tolist()) if f64 else (lambda x: [tuple(r) for r in x])
        gl, al = conv(g), conv(a)
        dl = None if d is None else (d.tolist() if f64 else list(d))
        ml = conv(m) if m is not None else None
        hl = (h.tolist() if f64 else list(h)) if h is not None else None
        with np.errstate(all="ignore"):
            for k in range(n):
                if dl is not None:
                    self._set_sample_period(dl[k])
                if ml is not None:
                    self._update(tuple(gl[k]), tuple(al[k]), tuple(ml[k]))
                elif hl is not None:
                    self._update_external_heading(tuple(gl[k]), tuple(al[k]), hl[k])
                else:
                    self._update_no_magnetometer(tuple(gl[k]), tuple(al[k]))
                out[k] = self._raw()
        return out

    def __repr__(self):
        return f"<imufuse.reference FusionAHRS13 dtype={self.dtype}>"


class FusionBias:
    """x-io Fusion 1.3's gyroscope bias algorithm in FUSION'S UNITS: gyroscope deg/s.

    imufusion 1.3.3's Bias, bit-exact with it in float32. Settings: sample_rate in Hz (100),
    stationary_threshold in deg/s (3), stationary_period in s (3). After stationary_period
    with every corrected axis within the threshold, the offset follows the corrected
    gyroscope through a 0.02 Hz first-order filter. update(gyr) returns the corrected
    gyroscope; run(gyr) returns (corrected (N, 3), state (N, 4)); `offset` (settable: keep
    it in non-volatile memory and give it back after a restart, FusionBiasGet/SetOffset).
    """
    kind = "fusion_bias"
    c_name = "imf_fusion13_bias"
    state_names = _fusion13.BIAS_STATE_NAMES

    def __init__(self, sample_rate=100.0, stationary_threshold=3.0, stationary_period=3.0, *,
                 dtype="float64"):
        self.dtype = _checks.check_dtype(dtype)
        self._o = _Ops(self.dtype)
        self._args = self._params(sample_rate, stationary_threshold, stationary_period,
                                  dtype=self.dtype)
        self.reset()

    @staticmethod
    def _params(sample_rate=100.0, stationary_threshold=3.0, stationary_period=3.0,
                dtype="float64"):
        return _fusion13.bias_params(dtype, sample_rate, stationary_threshold, stationary_period)

    def _set_settings(self, sample_rate, stationary_threshold, stationary_period):
        R = self._o.R
        self.stationary_threshold = R(stationary_threshold)
        # 2 pi fc T, left to right
        self.filter_coefficient = (R(2.0) * self._o.pi * R(BIAS_CUTOFF)
                                   * (R(1.0) / R(sample_rate)))
        self.timeout = int(R(stationary_period) * R(sample_rate))

    def reset(self):
        """Settings applied, timer and offset zero (FusionBiasInitialise)."""
        R = self._o.R
        self._set_settings(*self._args)
        self.skipped = 0
        self.timer = 0
        self.offset_x, self.offset_y, self.offset_z = R(0.0), R(0.0), R(0.0)

    def set_settings(self, **settings):
        """New settings (FusionBiasSetSettings): the timer and the offset are kept."""
        cur = dict(zip(("sample_rate", "stationary_threshold", "stationary_period"), self._args))
        for k in settings:
            if k not in cur:
                raise ValueError(f"{k}: not a setting of FusionBias; set_settings changes "
                                 f"{', '.join(cur)}")
        cur.update(settings)
        self._args = self._params(**cur, dtype=self.dtype)
        self._set_settings(*self._args)

    def _update(self, g):
        fabs = self._o.fabs
        threshold = self.stationary_threshold
        if not _finite(*g):
            self.skipped = (self.skipped + 1) & 0xFFFFFFFF
            return g
        # corrected gyroscope
        cx = g[0] - self.offset_x
        cy = g[1] - self.offset_y
        cz = g[2] - self.offset_z
        out = (cx, cy, cz)
        # moving: the stationary timer starts again
        if fabs(cx) > threshold or fabs(cy) > threshold or fabs(cz) > threshold:
            self.timer = 0
            return out
        if self.timer < self.timeout:
            self.timer += 1
            return out
        # stationary long enough: the offset follows the corrected gyroscope
        self.offset_x = self.offset_x + cx * self.filter_coefficient
        self.offset_y = self.offset_y + cy * self.filter_coefficient
        self.offset_z = self.offset_z + cz * self.filter_coefficient
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
    def offset(self):
        """The gyroscope offset (deg/s), FusionBiasGetOffset; settable (FusionBiasSetOffset)."""
        return np.array([self.offset_x, self.offset_y, self.offset_z], dtype=self.dtype)

    @offset.setter
    def offset(self, value):
        R = self._o.R
        v = _fusion.model_param("offset", value, (3,), self.dtype)
        self.offset_x, self.offset_y, self.offset_z = R(v[0]), R(v[1]), R(v[2])

    @property
    def state(self):
        return np.array([self.offset_x, self.offset_y, self.offset_z, self.timer],
                        dtype=self.dtype)

    @state.setter
    def state(self, value):
        arr = _checks.as_state(value, 4, self.dtype, self.state_names)
        if arr[3] != int(arr[3]) or not 0 <= arr[3] <= self.timeout:
            raise ValueError(f"state: timer must be an integer in [0, {self.timeout}]")
        R = self._o.R
        self.offset_x, self.offset_y, self.offset_z = R(arr[0]), R(arr[1]), R(arr[2])
        self.timer = int(arr[3])

    def __repr__(self):
        return f"<imufuse.reference FusionBias dtype={self.dtype}>"


# ---- remap, models, compass (fusion_calibration.c, fusion_ahrs.c) ---------------------

def remap(x, alignment, dtype="float64"):
    """FusionRemap for each row of x (N, 3): alignment one of the 24 names of
    imufuse.reference._fusion13.REMAP_ALIGNMENTS ('+X+Z-Y': x = +x, y = +z, z = -y) or its number."""
    dtype = _checks.check_dtype(dtype)
    perm, neg = _fusion13.remap_alignment(alignment)
    (arr,) = _checks.as_nx3(dtype, x=np.atleast_2d(x))
    out = np.empty_like(arr)
    for k in range(arr.shape[0]):
        u = arr[k]
        out[k] = [-u[perm[i]] if neg[i] else u[perm[i]] for i in range(3)]
    return out


def model_inertial(x, misalignment=None, sensitivity=None, offset=None, dtype="float64"):
    """FusionModelInertial: misalignment ((x - offset) .* sensitivity), row by row
    (defaults: identity, ones, zeros)."""
    dtype = _checks.check_dtype(dtype)
    R = _Ops(dtype).R
    m = [R(v) for v in _fusion.model_param(
        "misalignment", np.eye(3) if misalignment is None else misalignment, (3, 3), dtype)]
    sens = tuple(R(v) for v in _fusion.model_param(
        "sensitivity", np.ones(3) if sensitivity is None else sensitivity, (3,), dtype))
    off = tuple(R(v) for v in _fusion.model_param(
        "offset", np.zeros(3) if offset is None else offset, (3,), dtype))
    (arr,) = _checks.as_nx3(dtype, x=np.atleast_2d(x))
    out = np.empty_like(arr)
    rows = arr.tolist() if dtype == "float64" else [tuple(r) for r in arr]
    with np.errstate(all="ignore"):
        for k, u in enumerate(rows):
            out[k] = mat_mul_vec(m, vec_hadamard(vec_sub(tuple(u), off), sens))
    return _checks.canonical_nan(out)


def model_magnetic(x, soft_iron_matrix=None, hard_iron_offset=None, dtype="float64"):
    """FusionModelMagnetic: soft_iron_matrix (x - hard_iron_offset), row by row."""
    dtype = _checks.check_dtype(dtype)
    R = _Ops(dtype).R
    m = [R(v) for v in _fusion.model_param(
        "soft_iron_matrix", np.eye(3) if soft_iron_matrix is None else soft_iron_matrix,
        (3, 3), dtype)]
    hard = tuple(R(v) for v in _fusion.model_param(
        "hard_iron_offset", np.zeros(3) if hard_iron_offset is None else hard_iron_offset,
        (3,), dtype))
    (arr,) = _checks.as_nx3(dtype, x=np.atleast_2d(x))
    out = np.empty_like(arr)
    rows = arr.tolist() if dtype == "float64" else [tuple(r) for r in arr]
    with np.errstate(all="ignore"):
        for k, u in enumerate(rows):
            out[k] = mat_mul_vec(m, vec_sub(tuple(u), hard))
    return _checks.canonical_nan(out)
