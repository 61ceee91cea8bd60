"""MultiWii 2.2 attitude estimate (article, Appendix "IMU Implementations"):
pure-Python twin of csrc/multiwii.c, line for line.

The float part of the firmware's getEstimatedAttitude() (IMU.cpp/IMU.ino of
MultiWii 2.2) in its order of operations: accelerometer LPF and squared
magnitude, rotateV of the gravity vector by the gyro increment, then the
complementary filter inside the 1 +- 0.15 g window.

Where imufuse departs from the firmware, and why:

1. Window test (follows the article, "apply complementary filter if
   |a| - 1 < 0.15", read as 1 - w < |a| < 1 + w): the firmware computes
   accMag = sum(accSmooth^2) * 100 / acc_1G^2 in integers (truncating) and
   tests 72 < accMag < 133, i.e. |a| in [0.854, 1.153) g; its float ports
   (|a|^2 in (0.72, 1.33)) give (0.849, 1.153) g. Both are the rounded
   squares of 0.85 and 1.15. imufuse compares |a|^2 with the exact
   ((1 -+ window) acc_1g)^2, precomputed once, so the window is the stated
   one and configurable.
2. Accelerometer LPF: the firmware keeps an int32 sum, accLPF32 -= accLPF32
   >> k; accLPF32 += acc; accSmooth = accLPF32 >> k (ACC_LPF_FACTOR k = 4, a
   16-sample LPF). imufuse runs the same recurrence in floating point on
   accSmooth (accLPF32 = accSmooth 2^k exactly), without the truncation of
   the shifts (and without the firmware's integer accSmooth).
3. Axes (follows the article): the firmware's rotateV works in its sensor
   channels, where the gyro roll/pitch/yaw channels enter with the signs of
   w = (delta_pitch, -delta_roll, -delta_yaw) / dt in the accelerometer's
   axes ("d_x defined negative"). imufuse takes a right-handed body-frame
   gyro and writes rotateV as the article's d + d x (w dt); with those
   signs substituted the firmware's three expressions are the same
   floating-point operations, component by component, from the old d.
   The increment w dt is formed first, as the firmware's deltaGyroAngle.
4. Angles (follows the article and the README's conventions): the firmware converts EstG to
   int32 and uses an approximate atan2 (Hastings, deci-degrees) and
   InvSqrt; the article writes pitch = atan2(d_x/d_z), roll =
   atan2(d_y/sqrt(...)). imufuse gives ZYX roll = atan2(d_y, d_z), pitch =
   atan2(-d_x, sqrt(d_y^2 + d_z^2)) in double with libm, from the state,
   outside the update (angles()).
5. Period: the firmware measures it every cycle with micros() and scales raw
   gyro counts by GYRO_SCALE; imufuse uses a fixed dt and rad/s.
6. Initial state: the firmware starts from EstG = 0 and accLPF32 = (0, 0, 1)
   and needs seconds to converge; imufuse starts level, d = accSmooth =
   (0, 0, acc_1g).
7. Normalisation (follows the firmware, not the article's step 2 "normalize
   a"): a and d stay in accelerometer units (the window needs |a|; the
   weighting is linear, so the direction of d is the same either way).
8. Not ported: the magnetometer vector EstM, SMALL_ANGLES_25, the int32
   copies EstG32. Non-finite samples are rejected (imufuse policy).
"""
import dataclasses

from . import _math
from ._base import ReferenceFilter, isfinite
from ._settings import REQUIRED, SettingsRecord, dt, real, setting
from .mahony2d import tilt_angles


def _shift(name, value, prior):
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 16:
        raise ValueError(f"acc_lpf_shift: must be an integer with 0 <= acc_lpf_shift <= 16, "
                         f"got {value!r}")
    return value


@dataclasses.dataclass(frozen=True)
class MultiWiiSettings(SettingsRecord):
    """imf_multiwii_settings_t, member for member (MultiWii's keywords, in the C's units)."""
    #                  default   unit        check
    dt: float = setting(REQUIRED, "s", dt())
    cmpf: float = setting(600.0, "1", real(lo=0.0))
    acc_lpf_shift: int = setting(4, "bits", _shift)
    acc_1g: float = setting(1.0, "acc unit", real(lo=0.0, lo_open=True))
    window: float = setting(0.15, "1", real(lo=0.0, hi=1.0, lo_open=True))


class MultiWii(ReferenceFilter):
    """MultiWii 2.2 gravity-vector complementary filter (article appendix).

    MultiWii(dt, cmpf=600, acc_lpf_shift=4, acc_1g=1.0, window=0.15):
    cmpf is GYR_CMPF_FACTOR F (d = (d F + a) / (F + 1)); acc_lpf_shift is
    ACC_LPF_FACTOR (LPF length 2^shift samples, 0 = no LPF); acc_1g the
    accelerometer reading of 1 g; the complementary step runs only while
    (1 - window) acc_1g < |accSmooth| < (1 + window) acc_1g.
    State: d (EstG, body up, acc units) and the low-passed accelerometer.
    angles() gives (roll, pitch) in rad (ZYX).
    """
    kind = "imu"
    c_name = "imf_multiwii"
    state_names = ("dx", "dy", "dz", "ax", "ay", "az")

    settings_type = MultiWiiSettings
    _params = MultiWiiSettings.keywords()

    @classmethod
    def _valid_state(cls, args, R, state):
        acc_1g = R(args.acc_1g)
        if not _math.gravity_ok(R, *[R(v) for v in state[:3]],
                                (R(4.0) * acc_1g) * (R(4.0) * acc_1g)):
            return "d (dx, dy, dz) must have 0 < |d| <= 4 acc_1g"
        return None

    def _init(self, s):
        R = self._R
        self._set_dt(R(s.dt))
        self.cmpf = R(s.cmpf)
        self.inv_cmpf1 = R(1.0) / (self.cmpf + R(1.0))
        # powers of two: the scalings of the LPF are exact, like the firmware's shifts
        self.lpf_n = R(1.0)
        for _ in range(s.acc_lpf_shift):
            self.lpf_n = self.lpf_n * R(2.0)
        self.lpf_inv = R(1.0) / self.lpf_n
        # the window test compares squared magnitudes, like the firmware's accMag
        acc_1g = R(s.acc_1g)
        window = R(s.window)
        lo = (R(1.0) - window) * acc_1g
        hi = (R(1.0) + window) * acc_1g
        self.mag2_lo = lo * lo
        self.mag2_hi = hi * hi
        # valid attitude: |d| <= 4 g (the filter pulls d towards |a| < 2 g)
        self.d2_max = (R(4.0) * acc_1g) * (R(4.0) * acc_1g)
        self.acc_1g = acc_1g
        self.dx = R(0.0)
        self.dy = R(0.0)
        self.dz = acc_1g
        self.ax = R(0.0)
        self.ay = R(0.0)
        self.az = acc_1g

    def _set_dt(self, dt):
        # imf_multiwii_set_dt
        self.dt = dt

    def _set_attitude(self, att):
        # imf_multiwii_set_attitude: d = accSmooth = acc_1g up
        self.dx = self.acc_1g * att.r[6]
        self.dy = self.acc_1g * att.r[7]
        self.dz = self.acc_1g * att.r[8]
        self.ax = self.dx
        self.ay = self.dy
        self.az = self.dz

    def _update(self, gx, gy, gz, ax, ay, az):
        if not isfinite(gx, gy, gz, ax, ay, az):
            self._skip()
            return
        # deltaGyroAngle = gyro * scale: the rotation increment first
        deltax = gx * self.dt
        deltay = gy * self.dt
        deltaz = gz * self.dt
        # accelerometer LPF: accLPF32 -= accLPF32 >> k; accLPF32 += acc;
        # accSmooth = accLPF32 >> k, with accLPF32 = accSmooth 2^k (exact)
        sx = ((self.ax * self.lpf_n - self.ax) + ax) * self.lpf_inv
        sy = ((self.ay * self.lpf_n - self.ay) + ay) * self.lpf_inv
        sz = ((self.az * self.lpf_n - self.az) + az) * self.lpf_inv
        # accMag: squared magnitude of the smoothed acceleration, axis 0, 1, 2
        mag2 = sx * sx + sy * sy + sz * sz
        # rotateV (appendix step 3): d_n = d_{n-1} + d_{n-1} x delta, every
        # component from the old d, no renormalisation (task T2 left out)
        dx = self.dx + (self.dy * deltaz - self.dz * deltay)
        dy = self.dy + (self.dz * deltax - self.dx * deltaz)
        dz = self.dz + (self.dx * deltay - self.dy * deltax)
        # step 4: complementary filter (d F + a) / (F + 1), only while
        # (1 - window) g < |a| < (1 + window) g
        if self.mag2_lo < mag2 and mag2 < self.mag2_hi:
            dx = (dx * self.cmpf + sx) * self.inv_cmpf1
            dy = (dy * self.cmpf + sy) * self.inv_cmpf1
            dz = (dz * self.cmpf + sz) * self.inv_cmpf1
        # valid-attitude policy (imf_math.h): d of plausible length, LPF finite
        if not (_math.gravity_ok(self._R, dx, dy, dz, self.d2_max) and isfinite(sx, sy, sz)):
            self._skip()
            return
        self.dx = dx
        self.dy = dy
        self.dz = dz
        self.ax = sx
        self.ay = sy
        self.az = sz

    def angles(self):
        """(roll, pitch) in rad (ZYX) of d, in double (step 5): an output, not state."""
        return tilt_angles(self.dx, self.dy, self.dz)
