"""Madgwick's gradient-descent filter (article chapter 5, Appendix "IMU
Implementations"): pure-Python twin of csrc/madgwick.c, line for line.

beta (rad/s) is the published beta (default 0.1). delta_s="full" is the
appendix step 4 with the published intermediates and order; "simplified" is
the article's simplified corrective step for a unit quaternion.
"""
import dataclasses

from ..shared import checks as _checks
from . import _gate, _math
from ._base import QUAT_NORM2_TOL, ReferenceFilter, isfinite
from ._settings import FIXED, REQUIRED, SettingsRecord, choice, dt, fixed, real, setting

DELTA_S = {"full": 0, "simplified": 1}
DS_FULL, DS_SIMPLIFIED = 0, 1


# Step 3: dq = 1/2 q (x) omega
def rate(R, q, gx, gy, gz):
    q0, q1, q2, q3 = q
    return [R(0.5) * (-q1 * gx - q2 * gy - q3 * gz),
            R(0.5) * (q0 * gx + q2 * gz - q3 * gy),
            R(0.5) * (q0 * gy - q1 * gz + q3 * gx),
            R(0.5) * (q0 * gz + q1 * gy - q2 * gx)]


def ds_full(R, q, ax, ay, az):
    """Step 4, full form: ds = J^T f for the gravity objective, valid for any q,
    term by term as in the article's appendix and the published code."""
    q0, q1, q2, q3 = q
    two_q0 = R(2.0) * q0
    two_q1 = R(2.0) * q1
    two_q2 = R(2.0) * q2
    two_q3 = R(2.0) * q3
    four_q0 = R(4.0) * q0
    four_q1 = R(4.0) * q1
    four_q2 = R(4.0) * q2
    eight_q1 = R(8.0) * q1
    eight_q2 = R(8.0) * q2
    q0q0 = q0 * q0
    q1q1 = q1 * q1
    q2q2 = q2 * q2
    q3q3 = q3 * q3
    s0 = four_q0 * q2q2 + two_q2 * ax + four_q0 * q1q1 - two_q1 * ay
    s1 = (four_q1 * q3q3 - two_q3 * ax + R(4.0) * q0q0 * q1 - two_q0 * ay - four_q1
          + eight_q1 * q1q1 + eight_q1 * q2q2 + four_q1 * az)
    s2 = (R(4.0) * q0q0 * q2 + two_q0 * ax + four_q2 * q3q3 - two_q3 * ay - four_q2
          + eight_q2 * q1q1 + eight_q2 * q2q2 + four_q2 * az)
    s3 = R(4.0) * q1q1 * q3 - two_q1 * ax + R(4.0) * q2q2 * q3 - two_q2 * ay
    return [s0, s1, s2, s3]


def ds_simplified(R, q, ax, ay, az):
    """Step 4, simplified form (article, note below the appendix): for a unit q
    ds = 4 (q1^2 + q2^2) q + 2 (q2 ax - q1 ay, -q3 ax - q0 ay + 2 q1 az,
                                q0 ax - q3 ay + 2 q2 az, -q1 ax - q2 ay)."""
    q0, q1, q2, q3 = q
    c = R(4.0) * (q1 * q1 + q2 * q2)
    s0 = c * q0 + R(2.0) * (q2 * ax - q1 * ay)
    s1 = c * q1 + R(2.0) * (-q3 * ax - q0 * ay + R(2.0) * q1 * az)
    s2 = c * q2 + R(2.0) * (q0 * ax - q3 * ay + R(2.0) * q2 * az)
    s3 = c * q3 + R(2.0) * (-q1 * ax - q2 * ay)
    return [s0, s1, s2, s3]


def ds_ahrs(R, q, ax, ay, az, mx, my, mz):
    """ds = J^T f for the gravity and the magnetic objective (AHRS), with the
    published intermediates and order. f1..f3: predicted minus measured
    gravity direction; f4..f6: the same for the field, the reference field
    being (bx, 0, bz) in the earth frame (two_bx = 2 bx, two_bz = 2 bz)."""
    q0, q1, q2, q3 = q
    two_q0 = R(2.0) * q0
    two_q1 = R(2.0) * q1
    two_q2 = R(2.0) * q2
    two_q3 = R(2.0) * q3
    two_q0mx = two_q0 * mx
    two_q0my = two_q0 * my
    two_q0mz = two_q0 * mz
    two_q1mx = two_q1 * mx
    two_q0q2 = two_q0 * q2
    two_q2q3 = two_q2 * q3
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
    # the field in the earth frame, h = R m (expanded)
    hx = (mx * q0q0 - two_q0my * q3 + two_q0mz * q2 + mx * q1q1 + two_q1 * my * q2
          + two_q1 * mz * q3 - mx * q2q2 - mx * q3q3)
    hy = (two_q0mx * q3 + my * q0q0 - two_q0mz * q1 + two_q1mx * q2 - my * q1q1 + my * q2q2
          + two_q2 * mz * q3 - my * q3q3)
    two_bx = _math.sqrt(R, hx * hx + hy * hy)
    two_bz = (-two_q0mx * q2 + two_q0my * q1 + mz * q0q0 + two_q1mx * q3 - mz * q1q1
              + two_q2 * my * q3 - mz * q2q2 + mz * q3q3)
    four_bx = R(2.0) * two_bx
    four_bz = R(2.0) * two_bz
    # objective function f
    f1 = R(2.0) * q1q3 - two_q0q2 - ax
    f2 = R(2.0) * q0q1 + two_q2q3 - ay
    f3 = R(1.0) - R(2.0) * q1q1 - R(2.0) * q2q2 - az
    f4 = two_bx * (R(0.5) - q2q2 - q3q3) + two_bz * (q1q3 - q0q2) - mx
    f5 = two_bx * (q1q2 - q0q3) + two_bz * (q0q1 + q2q3) - my
    f6 = two_bx * (q0q2 + q1q3) + two_bz * (R(0.5) - q1q1 - q2q2) - mz
    # gradient J^T f
    s0 = (-two_q2 * f1 + two_q1 * f2 - two_bz * q2 * f4 + (-two_bx * q3 + two_bz * q1) * f5
          + two_bx * q2 * f6)
    s1 = (two_q3 * f1 + two_q0 * f2 - R(4.0) * q1 * f3 + two_bz * q3 * f4
          + (two_bx * q2 + two_bz * q0) * f5 + (two_bx * q3 - four_bz * q1) * f6)
    s2 = (-two_q0 * f1 + two_q3 * f2 - R(4.0) * q2 * f3
          + (-four_bx * q2 - two_bz * q0) * f4 + (two_bx * q1 + two_bz * q3) * f5
          + (two_bx * q0 - four_bz * q2) * f6)
    s3 = (two_q1 * f1 + two_q2 * f2 + (-four_bx * q3 + two_bz * q1) * f4
          + (-two_bx * q0 + two_bz * q2) * f5 + two_bx * q1 * f6)
    return [s0, s1, s2, s3]


#: largest beta*dt (docs/robustness.md)
BETA_DT_MAX = 0.1


def check_beta(dt, beta):
    """Stable range (docs/robustness.md). The corrective step moves q by
    beta dt along the unit gradient whatever the error (steps 5-7): it is not
    proportional, so near the optimum q settles into a limit cycle of up to
    2 beta dt rad around it (the step overshoots by up to its own length; one
    quaternion unit is two radians of attitude). beta dt <= 0.1 keeps that
    below 0.2 rad (11.5 deg) and the first-order step small; beyond it the
    estimate can be as far off as the step (beta = 150 at 100 Hz: 180 deg)."""
    if not beta * dt <= BETA_DT_MAX:
        raise ValueError(f"beta: outside the stable range (beta*dt <= {BETA_DT_MAX} needed; "
                         f"beta*dt={beta * dt!r})")


def _beta(name, value, prior):
    beta = _checks.check_real(name, value, lo=0.0)
    check_beta(prior["dt"], beta)
    return beta


@dataclasses.dataclass(frozen=True)
class MadgwickIMUSettings(SettingsRecord):
    """imf_madgwick_settings_t, member for member, in the C's units: MadgwickIMU's
    keywords (the user's default and unit), checked and converted once."""
    #                  default   unit        check                 to C
    dt: float = setting(REQUIRED, "s", dt())
    beta: float = setting(0.1, "rad/s", _beta)
    delta_s: int = setting("full", "", choice(*DELTA_S), to_c=DELTA_S.__getitem__)
    invsqrt: int = setting("exact", "", choice(*_math.INVSQRT), to_c=_math.INVSQRT.__getitem__,
                           kw_only=True)
    acc_gate_lo: float = setting(None, "acc_1g", _gate.lo, keyword="acc_gate", kw_only=True)
    acc_gate_hi: float = setting(None, "acc_1g", _gate.hi, keyword="acc_gate", kw_only=True)
    acc_1g: float = setting(1.0, "acc unit", real(lo=0.0, lo_open=True), kw_only=True)


@dataclasses.dataclass(frozen=True)
class MadgwickAHRSSettings(MadgwickIMUSettings):
    """imf_madgwick_settings_t for MadgwickAHRS: its keywords are MadgwickIMU's without
    delta_s (imf_madgwick_update always takes the full corrective step; delta_s is that of
    the update without magnetometer, run when it reads zero: the full one here too)."""
    delta_s: int = setting("full", "", fixed, to_c=DELTA_S.__getitem__, keyword=FIXED)


class _Madgwick(ReferenceFilter):
    state_names = ("q0", "q1", "q2", "q3")

    @classmethod
    def _valid_state(cls, args, R, state):
        n2 = float(sum(float(v) * float(v) for v in state[:4]))
        if not abs(n2 - 1.0) <= QUAT_NORM2_TOL:
            return f"|q|^2 = {n2!r}, must be within 1 +- {QUAT_NORM2_TOL}"
        return None

    def _init(self, s):
        R = self._R
        self._set_acc_gate(s.acc_gate_lo, s.acc_gate_hi, s.acc_1g)
        self._set_dt(R(s.dt))
        self.beta = R(s.beta)
        self.delta_s = DS_SIMPLIFIED if s.delta_s == DS_SIMPLIFIED else DS_FULL
        self.invsqrt = s.invsqrt
        self.q0 = R(1.0)
        self.q1 = R(0.0)
        self.q2 = R(0.0)
        self.q3 = R(0.0)

    # madgwick_set_dt: the settings that depend on the sample period dt (s)
    def _set_dt(self, dt):
        self.dt = dt

    # imf_madgwick_set_acc_gate: Nair's accelerometer gate (imf_gate.h)
    def _set_acc_gate(self, acc_gate_lo, acc_gate_hi, acc_1g):
        self.acc_gate = _gate.set(self._R, acc_gate_lo, acc_gate_hi, acc_1g)

    # madgwick_set_attitude: q = att.q (imf_attitude.h)
    def _set_attitude(self, att):
        self.q0, self.q1, self.q2, self.q3 = att.q

    # Steps 5 and 6: normalise ds, dq' = dq - beta ds. A zero (or subnormal)
    # ds is the exact optimum: it has no direction and is left as it is (no
    # correction). Returns None if ds overflowed (the sample is rejected).
    def _feedback(self, s, dq):
        rc, s = _math.normalise4(self._R, *s, self.invsqrt)
        if rc == _math.NORM_HUGE:
            return None
        return [dq[0] - self.beta * s[0],
                dq[1] - self.beta * s[1],
                dq[2] - self.beta * s[2],
                dq[3] - self.beta * s[3]]

    # Steps 7 and 8: q_n = q_{n-1} + dq' dt, then normalise. Returns None when
    # q cannot be normalised (the sample is rejected).
    def _integrate(self, q, dq):
        rc, q = _math.normalise4(self._R, q[0] + dq[0] * self.dt, q[1] + dq[1] * self.dt,
                                 q[2] + dq[2] * self.dt, q[3] + dq[3] * self.dt, self.invsqrt)
        return q if rc == _math.NORM_OK else None

    # One update; returns None if a normalisation failed (the sample is rejected).
    def _imu_step(self, q, gx, gy, gz, ax, ay, az):
        R = self._R
        dq = rate(R, q, gx, gy, gz)
        if not _math.is_zero3(R, ax, ay, az) and _gate.passes(R, self.acc_gate, ax, ay, az):
            # Step 2: normalise a
            rc, (ax, ay, az) = _math.normalise3(R, ax, ay, az, self.invsqrt)
            if rc != _math.NORM_OK:
                return None
            if self.delta_s == DS_SIMPLIFIED:
                s = ds_simplified(R, q, ax, ay, az)
            else:
                s = ds_full(R, q, ax, ay, az)
            dq = self._feedback(s, dq)
            if dq is None:
                return None
        return self._integrate(q, dq)

    def _ahrs_step(self, q, gx, gy, gz, ax, ay, az, mx, my, mz):
        R = self._R
        if _math.is_zero3(R, mx, my, mz):
            # no magnetometer reading: the IMU update
            return self._imu_step(q, gx, gy, gz, ax, ay, az)
        dq = rate(R, q, gx, gy, gz)
        if not _math.is_zero3(R, ax, ay, az) and _gate.passes(R, self.acc_gate, ax, ay, az):
            rc, (ax, ay, az) = _math.normalise3(R, ax, ay, az, self.invsqrt)
            if rc != _math.NORM_OK:
                return None
            rc, (mx, my, mz) = _math.normalise3(R, mx, my, mz, self.invsqrt)
            if rc != _math.NORM_OK:
                return None
            s = ds_ahrs(R, q, ax, ay, az, mx, my, mz)
            dq = self._feedback(s, dq)
            if dq is None:
                return None
        return self._integrate(q, dq)

    # Keep the new state only if the update succeeded (not None) and left it
    # finite (valid-attitude policy, imf_math.h).
    def _commit(self, q):
        if q is None or not isfinite(*q):
            self._skip()
            return
        self.q0, self.q1, self.q2, self.q3 = q


class MadgwickIMU(_Madgwick):
    """Madgwick's gradient-descent filter with gyro and accelerometer (article
    chapter 5, appendix steps 1-9).

    MadgwickIMU(dt, beta=0.1, delta_s="full", invsqrt="exact"): dt in s, beta
    in rad/s (the published beta); delta_s "full" (appendix step 4, published
    order) or "simplified" (the article's form for a unit quaternion);
    invsqrt="fast" uses the published fast inverse square root. State: the
    quaternion q0..q3 (sensor -> earth).
    """
    kind = "imu"
    c_name = "imf_madgwick"
    c_update = "imf_madgwick_update_imu"

    settings_type = MadgwickIMUSettings
    _params = MadgwickIMUSettings.keywords()

    def _update(self, gx, gy, gz, ax, ay, az):
        if not isfinite(gx, gy, gz, ax, ay, az):
            self._skip()
            return
        q = (self.q0, self.q1, self.q2, self.q3)
        self._commit(self._imu_step(q, gx, gy, gz, ax, ay, az))


class MadgwickAHRS(_Madgwick):
    """Madgwick's gradient-descent filter with gyro, accelerometer and
    magnetometer (published AHRS form; the corrective step is always the full
    form). MadgwickAHRS(dt, beta=0.1, invsqrt="exact"); an all-zero
    magnetometer sample runs the IMU update.
    """
    kind = "ahrs"
    c_name = "imf_madgwick"

    settings_type = MadgwickAHRSSettings
    _params = MadgwickAHRSSettings.keywords()

    def _update(self, gx, gy, gz, ax, ay, az, mx, my, mz):
        if not isfinite(gx, gy, gz, ax, ay, az, mx, my, mz):
            self._skip()
            return
        q = (self.q0, self.q1, self.q2, self.q3)
        self._commit(self._ahrs_step(q, gx, gy, gz, ax, ay, az, mx, my, mz))
