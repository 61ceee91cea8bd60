"""2D Mahony filter of the article's chapter 4.2 (Eq. 4.3 / 4.4): pure-Python
twin of csrc/mahony2d.c, line for line.

Also the output helpers shared by the gravity-vector family (multiwii, kk,
dcm): tilt_angles() (csrc/imf_math.h imf_tilt_angles) and sqrt_r().
"""
import dataclasses
import math

import numpy as np

from ..shared import checks as _checks
from . import _math
from ._base import ReferenceFilter, isfinite
from ._settings import REQUIRED, SettingsRecord, choice, dt, real, setting


def sqrt_r(R, x):
    """imf_sqrt on type R: sqrt (double) or sqrtf (float32; the double square
    root rounded once to float32 is the correctly rounded float32 result)."""
    if R is float:
        return math.sqrt(x)
    return np.float32(math.sqrt(float(x)))


def tilt_angles(dx, dy, dz):
    """(roll, pitch) in rad, ZYX (imufuse.rotations), of the attitude whose body
    up vector R^T e_z is (dx, dy, dz); evaluated in double with libm, the twin
    of imf_tilt_angles in csrc/imf_math.h. An output, never state."""
    dx, dy, dz = float(dx), float(dy), float(dz)
    return math.atan2(dy, dz), math.atan2(-dx, math.sqrt(dy * dy + dz * dz))


def _check_gains(dt, kp, ki):
    kp = _checks.check_real("kp", kp, lo=0.0)
    ki = _checks.check_real("ki", ki, lo=0.0)
    # per axis near convergence the loop is the single-axis filter of Eq. 3.6
    # (Mahony1DBias; with Eq. 4.3 too, since d is kept at unit length there),
    # update matrix [[1 - kp dt - ki dt^2, dt], [-ki dt, 1]]:
    # Jury test |det| < 1, 1 - tr + det = ki dt^2 >= 0, 1 + tr + det > 0,
    # written out so that ki = 0 (1 - tr + det = 0 exactly) is not lost to rounding
    kpdt, kidt2 = kp * dt, ki * dt * dt
    if not (0.0 < kpdt < 2.0 and kidt2 < 4.0 - 2.0 * kpdt):
        raise ValueError(f"kp, ki: outside the stable range (0 < kp*dt < 2 and "
                         f"ki*dt^2 < 4 - 2 kp*dt needed; kp*dt={kpdt!r}, ki*dt^2={kidt2!r})")
    return kp, ki


def gain_ki(name, value, prior):
    """Settings record: ki, with kp (checked before it) in the stable range."""
    return _check_gains(prior["dt"], prior["kp"], value)[1]


@dataclasses.dataclass(frozen=True)
class Mahony2DSettings(SettingsRecord):
    """imf_mahony2d_settings_t, member for member (Mahony2D's keywords, in the C's units)."""
    #                  default   unit     check                      to C
    dt: float = setting(REQUIRED, "s", dt())
    kp: float = setting(REQUIRED, "1/s", real(lo=0.0))
    ki: float = setting(REQUIRED, "1/s^2", gain_ki)
    exact: int = setting("approx", "", choice("approx", "exact"),
                         to_c=lambda v: int(v == "exact"), keyword="error")


class Mahony2D(ReferenceFilter):
    """2D Mahony filter, article 4.2: only the gravity direction d is estimated.

    Mahony2D(dt, kp, ki, error="approx"): error="approx" is Eq. 4.4 (E = a - d),
    error="exact" Eq. 4.3 (E = d x (a x d)). Per sample, per axis (Eq. 3.6):
    I_n = I_{n-1} + Ki dt E_n; d_n = d_{n-1} + (Kp E_n + I_n + d_{n-1} x w) dt.
    d is the body up vector R^T e_z (level: (0, 0, 1)). With Eq. 4.4 it is never
    renormalised (the controller pulls |d| to 1); with Eq. 4.3, which does not
    control |d| at all, it is scaled back to unit length after every update
    (task T2, csrc/mahony2d.h).
    angles() gives (roll, pitch). At equilibrium I = -d x b for a gyro bias b:
    the bias seen is d x I (rad/s), its part perpendicular to gravity.
    """
    kind = "imu"
    c_name = "imf_mahony2d"
    state_names = ("dx", "dy", "dz", "ix", "iy", "iz")

    settings_type = Mahony2DSettings
    _params = Mahony2DSettings.keywords()

    @classmethod
    def _valid_state(cls, args, R, state):
        if not _math.gravity_ok(R, *[R(v) for v in state[:3]], R(4.0)):
            return "d (dx, dy, dz) must have 0 < |d|^2 <= 4.0"
        return None

    def _init(self, s):
        R = self._R
        self.kp = R(s.kp)
        self.ki = R(s.ki)
        self._set_dt(R(s.dt))
        self.exact = s.exact != 0
        self.d2_max = R(4.0)
        self.dx = R(0.0)
        self.dy = R(0.0)
        self.dz = R(1.0)
        self.ix = R(0.0)
        self.iy = R(0.0)
        self.iz = R(0.0)

    def _set_dt(self, dt):
        # imf_mahony2d_set_dt
        self.dt = dt
        self.ki_dt = self.ki * dt

    def _set_attitude(self, att):
        # imf_mahony2d_set_attitude: d = up; I is kept
        self.dx, self.dy, self.dz = att.r[6], att.r[7], att.r[8]

    def _update(self, gx, gy, gz, ax, ay, az):
        R = self._R
        dx, dy, dz = self.dx, self.dy, self.dz
        ex = ey = ez = R(0.0)
        ix, iy, iz = self.ix, self.iy, self.iz
        if not isfinite(gx, gy, gz, ax, ay, az):
            self._skip()
            return
        # Eq. 4.2: rate of change of d from the gyro, d x w
        cx = dy * gz - dz * gy
        cy = dz * gx - dx * gz
        cz = dx * gy - dy * gx
        n2 = ax * ax + ay * ay + az * az
        if n2 > R(0.0) and math.isfinite(n2):
            norm = sqrt_r(R, n2)
            nx = ax / norm
            ny = ay / norm
            nz = az / norm
            if self.exact:
                # Eq. 4.3: E = d x (a x d)
                wx = ny * dz - nz * dy
                wy = nz * dx - nx * dz
                wz = nx * dy - ny * dx
                ex = dy * wz - dz * wy
                ey = dz * wx - dx * wz
                ez = dx * wy - dy * wx
            else:
                # Eq. 4.4: E = a - d
                ex = nx - dx
                ey = ny - dy
                ez = nz - dz
            # Eq. 3.6 per axis: I_n = I_{n-1} + Ki dt E_n
            ix = ix + self.ki_dt * ex
            iy = iy + self.ki_dt * ey
            iz = iz + self.ki_dt * ez
        # Eq. 3.6 per axis: d_n = d_{n-1} + (Kp E_n + I_n + d x w) dt
        dxn = dx + (self.kp * ex + ix + cx) * self.dt
        dyn = dy + (self.kp * ey + iy + cy) * self.dt
        dzn = dz + (self.kp * ez + iz + cz) * self.dt
        # Eq. 4.3 only (task T2, see mahony2d.h): E and d x w are perpendicular to
        # d, so d keeps its meaning only as a direction; scale it back to unit
        # length, where Eq. 4.3's loop gain Kp |d|^2 is Kp. A normalisation that
        # fails rejects the sample (imf_math.h).
        if self.exact:
            rc, (dxn, dyn, dzn) = _math.normalise3(R, dxn, dyn, dzn, _math.INVSQRT_EXACT)
            if rc != _math.NORM_OK:
                self._skip()
                return
        # valid-attitude policy (imf_math.h): d of plausible length, I finite
        if not (_math.gravity_ok(R, dxn, dyn, dzn, self.d2_max) and isfinite(ix, iy, iz)):
            self._skip()
            return
        self.dx = dxn
        self.dy = dyn
        self.dz = dzn
        self.ix = ix
        self.iy = iy
        self.iz = iz

    def angles(self):
        """(roll, pitch) in rad (ZYX) of d, in double: an output, not state."""
        return tilt_angles(self.dx, self.dy, self.dz)
