""""KK" linear small-angle filter of the article's appendix (Eq. 4.5 with a
P controller): pure-Python twin of csrc/kk.c, line for line."""
import dataclasses
import math

from ._base import ReferenceFilter, isfinite
from ._settings import REQUIRED, SettingsRecord, dt, real, setting
from .mahony2d import sqrt_r


@dataclasses.dataclass(frozen=True)
class KKSettings(SettingsRecord):
    """imf_kk_settings_t, member for member (KK's keywords, in the C's units)."""
    #                  default   unit   check
    dt: float = setting(REQUIRED, "s", dt())
    kp: float = setting(REQUIRED, "1", real(
        lo=0.0, hi=2.0, hi_open=True,
        why="the P loop theta_n = (1 - kp) theta + ... needs |1 - kp| <= 1"))


class KK(ReferenceFilter):
    """Linear small-angle filter, appendix "KK" / Eq. 4.5 with a P controller:

        pitch_n = pitch + (w_y - roll w_z) dt + Kp (a_pitch - pitch)
        roll_n  = roll  + (w_x + pitch w_z) dt + Kp (a_roll - roll)

    with a_pitch = -a_x/|a|, a_roll = a_y/|a| (small-angle accelerometer
    angles) and Kp a dimensionless gain per sample. The appendix writes
    (w_pitch + theta_roll w_yaw) and (w_roll - theta_pitch w_yaw): the same
    equations with w_yaw = -w_z; taken with w_yaw = +w_z they contradict
    Eq. 4.2 (see csrc/kk.h). Valid within about +-30 deg of level.
    """
    kind = "imu"
    c_name = "imf_kk"
    state_names = ("pitch", "roll")

    settings_type = KKSettings
    _params = KKSettings.keywords()

    def _init(self, s):
        R = self._R
        self._set_dt(R(s.dt))
        self.kp = R(s.kp)
        self.pitch = R(0.0)
        self.roll = R(0.0)

    def _set_dt(self, dt):
        # imf_kk_set_dt
        self.dt = dt

    def _set_attitude(self, att):
        # imf_kk_set_attitude: pitch = -up_x, roll = up_y (small-angle terms)
        self.pitch = -att.r[6]
        self.roll = att.r[7]

    def _update(self, gx, gy, gz, ax, ay, az):
        R = self._R
        if not isfinite(gx, gy, gz, ax, ay, az):
            self._skip()
            return
        # Eq. 4.5, gyro path: (w_pitch + theta_roll w_yaw) dt with w_yaw = -w_z
        pitch = self.pitch + (gy - self.roll * gz) * self.dt
        roll = self.roll + (gx + self.pitch * gz) * self.dt
        n2 = ax * ax + ay * ay + az * az
        if n2 > R(0.0) and math.isfinite(n2):
            # small-angle accelerometer angles, a_pitch = -a_x/|a|, a_roll = a_y/|a|;
            # P controller Kp (a - theta_{n-1})
            norm = sqrt_r(R, n2)
            pitch = pitch + self.kp * (-ax / norm - self.pitch)
            roll = roll + self.kp * (ay / norm - self.roll)
        if not isfinite(pitch, roll):
            self._skip()
            return
        self.pitch = pitch
        self.roll = roll

    def angles(self):
        """(roll, pitch) in rad: the state itself, as double."""
        return float(self.roll), float(self.pitch)
