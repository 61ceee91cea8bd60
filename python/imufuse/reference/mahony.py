"""Mahony's filter in quaternion form as implemented by Madgwick (article 4.1,
Eq. 4.1, Appendix "IMU Implementations" steps 1-9): pure-Python twin of
csrc/mahony.c, line for line.

Gains: kp (1/s) and ki (1/s^2) are Kp and Ki of Eq. 4.1 with e = a x d. The
published C (x-io MahonyAHRS.c) stores twoKp = 2 Kp and twoKi = 2 Ki and
multiplies them with half the error vector: kp = twoKp / 2, ki = twoKi / 2.
Its defaults twoKp = 2 * 0.5, twoKi = 2 * 0 are kp = 0.5, ki = 0 (our
defaults).
"""
import dataclasses

from ..shared import checks as _checks
from . import _gate, _math
from ._base import QUAT_NORM2_TOL, ReferenceFilter, integral_problem, isfinite
from ._settings import REQUIRED, SettingsRecord, choice, dt, real, setting


def check_mahony_gains(dt, kp, ki):
    """Stable range (docs/robustness.md). Near the attitude the accelerometer
    (and magnetometer) give, the error is e = a x d = sin(theta) ~ theta per
    axis and the update (steps 5-8) is the single-axis loop of Eq. 3.6:
    I_n = I + Ki dt e, theta_n = theta - (Kp e + I_n) dt, update matrix
    [[1 - kp dt - ki dt^2, -dt], [ki dt, 1]] (Mahony1DBias). Jury test:
    0 < kp dt < 2 and ki dt^2 < 4 - 2 kp dt. kp = ki = 0 (gyro integration
    only) is admitted."""
    if kp == 0.0 and ki == 0.0:
        return
    kpdt, kidt2 = kp * dt, ki * dt * dt
    if not (0.0 < kpdt < 2.0 and kidt2 < 4.0 - 2.0 * kpdt):
        raise ValueError(f"kp, ki: outside the stable range (0 < kp*dt < 2 and "
                         f"ki*dt^2 < 4 - 2 kp*dt needed, or kp = ki = 0; "
                         f"kp*dt={kpdt!r}, ki*dt^2={kidt2!r})")


def _ki(name, value, prior):
    ki = _checks.check_real(name, value, lo=0.0)
    check_mahony_gains(prior["dt"], prior["kp"], ki)
    return ki


@dataclasses.dataclass(frozen=True)
class MahonySettings(SettingsRecord):
    """imf_mahony_settings_t, member for member, in the C's units: the keywords of
    MahonyIMU and MahonyAHRS (the user's default and unit), checked and converted once."""
    #                  default   unit        check                 to C
    dt: float = setting(REQUIRED, "s", dt())
    kp: float = setting(0.5, "1/s", real(lo=0.0))
    ki: float = setting(0.0, "1/s^2", _ki)
    invsqrt: int = setting("exact", "", choice(*_math.INVSQRT), to_c=_math.INVSQRT.__getitem__,
                           kw_only=True)
    acc_gate_lo: float = setting(None, "acc_1g", _gate.lo, keyword="acc_gate", kw_only=True)
    acc_gate_hi: float = setting(None, "acc_1g", _gate.hi, keyword="acc_gate", kw_only=True)
    acc_1g: float = setting(1.0, "acc unit", real(lo=0.0, lo_open=True), kw_only=True)


class _Mahony(ReferenceFilter):
    state_names = ("q0", "q1", "q2", "q3", "ix", "iy", "iz")

    @classmethod
    def _valid_state(cls, args, R, state):
        n2 = float(sum(float(v) * float(v) for v in state[:4]))
        if not abs(n2 - 1.0) <= QUAT_NORM2_TOL:
            return f"|q|^2 = {n2!r}, must be within 1 +- {QUAT_NORM2_TOL}"
        return integral_problem(cls.state_names, state, args[0])

    settings_type = MahonySettings
    _params = MahonySettings.keywords()

    def _init(self, s):
        R = self._R
        self._set_acc_gate(s.acc_gate_lo, s.acc_gate_hi, s.acc_1g)
        self._set_dt(R(s.dt))
        self.two_kp = R(2.0) * R(s.kp)
        self.two_ki = R(2.0) * R(s.ki)
        self.invsqrt = s.invsqrt
        self.q0 = R(1.0)
        self.q1 = R(0.0)
        self.q2 = R(0.0)
        self.q3 = R(0.0)
        self.ix = R(0.0)
        self.iy = R(0.0)
        self.iz = R(0.0)

    # mahony_set_dt: the settings that depend on the sample period dt (s)
    def _set_dt(self, dt):
        self.dt = dt
        self.half_dt = self._R(0.5) * dt

    # mahony_set_attitude: q = att.q (imf_attitude.h); I is kept
    def _set_attitude(self, att):
        self.q0, self.q1, self.q2, self.q3 = att.q

    # imf_mahony_set_acc_gate: Nair's accelerometer gate (imf_gate.h)
    def _set_acc_gate(self, acc_gate_lo, acc_gate_hi, acc_1g):
        self.acc_gate = _gate.set(self._R, acc_gate_lo, acc_gate_hi, acc_1g)

    # Steps 5 and 6: the PI controller on the half error (ex, ey, ez) = e/2,
    # added to the rate in the published order w + I + Kp e.
    def _feedback(self, i, g, ex, ey, ez):
        R = self._R
        ix, iy, iz = i
        gx, gy, gz = g
        if self.two_ki > R(0.0):
            # Step 5: I_n = I_{n-1} + Ki dt e = I_{n-1} + (2 Ki)(e/2) dt
            ix = ix + self.two_ki * ex * self.dt
            iy = iy + self.two_ki * ey * self.dt
            iz = iz + self.two_ki * ez * self.dt
            gx = gx + ix
            gy = gy + iy
            gz = gz + iz
        else:
            # Ki = 0: no integral action, and none wound up for later
            ix = R(0.0)
            iy = R(0.0)
            iz = R(0.0)
        # Step 6: omega' = omega + I_n + Kp e
        gx = gx + self.two_kp * ex
        gy = gy + self.two_kp * ey
        gz = gz + self.two_kp * ez
        return (ix, iy, iz), (gx, gy, gz)

    # Steps 7 and 8: q_n = q_{n-1} + 1/2 q_{n-1} (x) omega' dt, then normalise.
    # Returns None when q cannot be normalised (the sample is rejected).
    def _integrate(self, q, g):
        q0, q1, q2, q3 = q
        gx, gy, gz = g
        gx = gx * self.half_dt
        gy = gy * self.half_dt
        gz = gz * self.half_dt
        n0 = q0 + (-q1 * gx - q2 * gy - q3 * gz)
        n1 = q1 + (q0 * gx + q2 * gz - q3 * gy)
        n2 = q2 + (q0 * gy - q1 * gz + q3 * gx)
        n3 = q3 + (q0 * gz + q1 * gy - q2 * gx)
        rc, q = _math.normalise4(self._R, n0, n1, n2, n3, self.invsqrt)
        return q if rc == _math.NORM_OK else None

    # One update; returns None if a normalisation failed (the sample is rejected).
    def _imu_step(self, q, i, gx, gy, gz, ax, ay, az):
        R = self._R
        if not _math.is_zero3(R, ax, ay, az) and _gate.passes(R, self.acc_gate, ax, ay, az):
            q0, q1, q2, q3 = q
            # Step 2: normalise a
            rc, (ax, ay, az) = _math.normalise3(R, ax, ay, az, self.invsqrt)
            if rc != _math.NORM_OK:
                return None
            # Step 3: d/2, half the earth's up axis seen in the sensor frame
            vx = q1 * q3 - q0 * q2
            vy = q0 * q1 + q2 * q3
            vz = q0 * q0 - R(0.5) + q3 * q3
            # Step 4: e/2 = a x (d/2)
            ex = ay * vz - az * vy
            ey = az * vx - ax * vz
            ez = ax * vy - ay * vx
            i, (gx, gy, gz) = self._feedback(i, (gx, gy, gz), ex, ey, ez)
        q = self._integrate(q, (gx, gy, gz))
        return None if q is None else (q, i)

    def _ahrs_step(self, q, i, gx, gy, gz, ax, ay, az, mx, my, mz):
        R = self._R
        if _math.is_zero3(R, mx, my, mz):
            # no magnetometer reading: the IMU update
            return self._imu_step(q, i, gx, gy, gz, ax, ay, az)
        if not _math.is_zero3(R, ax, ay, az) and _gate.passes(R, self.acc_gate, ax, ay, az):
            q0, q1, q2, q3 = q
            # Step 2: normalise a and m
            rc, (ax, ay, az) = _math.normalise3(R, ax, ay, az, self.invsqrt)
            if rc != _math.NORM_OK:
                return None
            rc, (mx, my, mz) = _math.normalise3(R, mx, my, mz, self.invsqrt)
            if rc != _math.NORM_OK:
                return None
            q0q0 = q0 * q0
            q0q1 = q0 * q1
            q0q2 = q0 * q2
            q0q3 = q0 * q3
            q1q1 = q1 * q1
            q1q2 = q1 * q2
            q1q3 = q1 * q3
            q2q2 = q2 * q2
            q2q3 = q2 * q3
            q3q3 = q3 * q3
            # the field in the earth frame, h = R m; the reference field keeps its
            # vertical part bz and puts the horizontal part bx along earth x
            hx = R(2.0) * (mx * (R(0.5) - q2q2 - q3q3) + my * (q1q2 - q0q3)
                           + mz * (q1q3 + q0q2))
            hy = R(2.0) * (mx * (q1q2 + q0q3) + my * (R(0.5) - q1q1 - q3q3)
                           + mz * (q2q3 - q0q1))
            bx = _math.sqrt(R, hx * hx + hy * hy)
            bz = R(2.0) * (mx * (q1q3 - q0q2) + my * (q2q3 + q0q1)
                           + mz * (R(0.5) - q1q1 - q2q2))
            # Step 3: d/2 and w/2, the estimated up axis and field direction seen
            # in the sensor frame (halved)
            vx = q1q3 - q0q2
            vy = q0q1 + q2q3
            vz = q0q0 - R(0.5) + q3q3
            wx = bx * (R(0.5) - q2q2 - q3q3) + bz * (q1q3 - q0q2)
            wy = bx * (q1q2 - q0q3) + bz * (q0q1 + q2q3)
            wz = bx * (q0q2 + q1q3) + bz * (R(0.5) - q1q1 - q2q2)
            # Step 4: e/2 = a x (d/2) + m x (w/2)
            ex = (ay * vz - az * vy) + (my * wz - mz * wy)
            ey = (az * vx - ax * vz) + (mz * wx - mx * wz)
            ez = (ax * vy - ay * vx) + (mx * wy - my * wx)
            i, (gx, gy, gz) = self._feedback(i, (gx, gy, gz), ex, ey, ez)
        q = self._integrate(q, (gx, gy, gz))
        return None if q is None else (q, i)

    # Keep the new state only if the update succeeded (not None) and left it
    # finite (valid-attitude policy, imf_math.h).
    def _commit(self, new):
        if new is None or not isfinite(*new[0], *new[1]):
            self._skip()
            return
        q, i = new
        self.q0, self.q1, self.q2, self.q3 = q
        self.ix, self.iy, self.iz = i

    def _state(self):
        return (self.q0, self.q1, self.q2, self.q3), (self.ix, self.iy, self.iz)


class MahonyIMU(_Mahony):
    """Mahony's filter with gyro and accelerometer (article 4.1, appendix).

    MahonyIMU(dt, kp=0.5, ki=0.0, invsqrt="exact"): dt in s; kp in 1/s and ki
    in 1/s^2 are Kp, Ki of Eq. 4.1 (published twoKp = 2 kp, twoKi = 2 ki);
    invsqrt="fast" uses the published fast inverse square root. State: the
    quaternion q0..q3 (sensor -> earth) and the integral term ix, iy, iz
    (rad/s; it converges to minus the gyro bias).
    """
    kind = "imu"
    c_name = "imf_mahony"
    c_update = "imf_mahony_update_imu"

    def _update(self, gx, gy, gz, ax, ay, az):
        if not isfinite(gx, gy, gz, ax, ay, az):
            self._skip()
            return
        q, i = self._state()
        self._commit(self._imu_step(q, i, gx, gy, gz, ax, ay, az))


class MahonyAHRS(_Mahony):
    """Mahony's filter with gyro, accelerometer and magnetometer.

    Same parameters and state as MahonyIMU; an all-zero magnetometer sample
    runs the IMU update.
    """
    kind = "ahrs"
    c_name = "imf_mahony"

    def _update(self, gx, gy, gz, ax, ay, az, mx, my, mz):
        if not isfinite(gx, gy, gz, ax, ay, az, mx, my, mz):
            self._skip()
            return
        q, i = self._state()
        self._commit(self._ahrs_step(q, i, gx, gy, gz, ax, ay, az, mx, my, mz))
