"""Mahony's filter in DCM form with Premerlani & Bizard's re-orthogonalisation
(article 4.1 and 4.3): pure-Python twin of csrc/dcm.c, line for line."""
import dataclasses
import math

from ._base import ReferenceFilter, integral_problem, isfinite
from ._settings import REQUIRED, SettingsRecord, dt, real, setting
from .mahony2d import gain_ki, sqrt_r, tilt_angles


@dataclasses.dataclass(frozen=True)
class DCMSettings(SettingsRecord):
    """imf_dcm_settings_t, member for member (DCM's keywords, in the C's units)."""
    #                  default   unit     check
    dt: float = setting(REQUIRED, "s", dt())
    kp: float = setting(REQUIRED, "1/s", real(lo=0.0))
    ki: float = setting(REQUIRED, "1/s^2", gain_ki)

_NAMES = ("r00", "r01", "r02", "r10", "r11", "r12", "r20", "r21", "r22", "ix", "iy", "iz")


#: IMF_DCM_ORTHO_TOL (csrc/dcm.h): rows of R of squared length 1 +- tol, pairwise
#: dot products within +-tol; an update that leaves this is rejected.
ORTHO_TOL = 0.01


def _orthonormal(R, r):
    """dcm_orthonormal: R orthonormal within ORTHO_TOL (and therefore finite)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
    nx = r00 * r00 + r01 * r01 + r02 * r02
    ny = r10 * r10 + r11 * r11 + r12 * r12
    nz = r20 * r20 + r21 * r21 + r22 * r22
    xy = r00 * r10 + r01 * r11 + r02 * r12
    xz = r00 * r20 + r01 * r21 + r02 * r22
    yz = r10 * r20 + r11 * r21 + r12 * r22
    tol = R(ORTHO_TOL)
    return (abs(nx - R(1.0)) <= tol and abs(ny - R(1.0)) <= tol and abs(nz - R(1.0)) <= tol
            and abs(xy) <= tol and abs(xz) <= tol and abs(yz) <= tol)


class DCM(ReferenceFilter):
    """Mahony DCM filter, article 4.1, with P&B re-orthogonalisation, 4.3.

    DCM(dt, kp, ki): e = a x d (d = R^T e_z, the third row of R);
    I_n = I_{n-1} + Ki dt e; w' = w + Kp e + I_n; R_n = R + R (w' dt)_x; then
    dr = 1/2 r_x.r_y, r_x' = r_x - dr r_y, r_y' = r_y - dr r_x,
    r'' = 1/2 (3 - |r'|^2) r', r_z'' = r_x'' x r_y'' (r_i: rows of R).
    R (row-major r00..r22) rotates body to earth; I converges to minus the
    gyro bias. angles() gives (roll, pitch) in rad (ZYX).
    """
    kind = "imu"
    c_name = "imf_dcm"
    state_names = _NAMES

    settings_type = DCMSettings
    _params = DCMSettings.keywords()

    @classmethod
    def _valid_state(cls, args, R, state):
        if not _orthonormal(R, [R(v) for v in state[:9]]):
            return f"R (r00..r22) must be orthonormal within {ORTHO_TOL}"
        return integral_problem(cls.state_names, state, args[0])

    def _init(self, s):
        R = self._R
        self.kp = R(s.kp)
        self.ki = R(s.ki)
        self._set_dt(R(s.dt))
        self.r00 = R(1.0)
        self.r01 = R(0.0)
        self.r02 = R(0.0)
        self.r10 = R(0.0)
        self.r11 = R(1.0)
        self.r12 = R(0.0)
        self.r20 = R(0.0)
        self.r21 = R(0.0)
        self.r22 = R(1.0)
        self.ix = R(0.0)
        self.iy = R(0.0)
        self.iz = R(0.0)

    def _set_dt(self, dt):
        # imf_dcm_set_dt
        self.dt = dt
        self.ki_dt = self.ki * dt

    def _set_attitude(self, att):
        # imf_dcm_set_attitude: R = att.r; I is kept
        (self.r00, self.r01, self.r02, self.r10, self.r11, self.r12,
         self.r20, self.r21, self.r22) = att.r

    def _update(self, gx, gy, gz, ax, ay, az):
        R = self._R
        ex = ey = ez = R(0.0)
        ix, iy, iz = self.ix, self.iy, self.iz
        if not isfinite(gx, gy, gz, ax, ay, az):
            self._skip()
            return
        n2 = ax * ax + ay * ay + az * az
        if n2 > R(0.0) and math.isfinite(n2):
            norm = sqrt_r(R, n2)
            nx = ax / norm
            ny = ay / norm
            nz = az / norm
            # 4.1 steps 2-3: e = a x d with d = r_z
            ex = ny * self.r22 - nz * self.r21
            ey = nz * self.r20 - nx * self.r22
            ez = nx * self.r21 - ny * self.r20
            # step 4: I_n = I_{n-1} + Ki dt e
            ix = ix + self.ki_dt * ex
            iy = iy + self.ki_dt * ey
            iz = iz + self.ki_dt * ez
        # step 5: w' = w + Kp e + I_n
        wx = gx + (self.kp * ex + ix)
        wy = gy + (self.kp * ey + iy)
        wz = gz + (self.kp * ez + iz)
        # step 6: R_n = R_{n-1} + R_{n-1} (w' dt)_x; row by row r + r x (w' dt)
        hx = wx * self.dt
        hy = wy * self.dt
        hz = wz * self.dt
        x0 = self.r00 + (self.r01 * hz - self.r02 * hy)
        x1 = self.r01 + (self.r02 * hx - self.r00 * hz)
        x2 = self.r02 + (self.r00 * hy - self.r01 * hx)
        y0 = self.r10 + (self.r11 * hz - self.r12 * hy)
        y1 = self.r11 + (self.r12 * hx - self.r10 * hz)
        y2 = self.r12 + (self.r10 * hy - self.r11 * hx)
        # 4.3 step 1: dr = 1/2 r_x . r_y
        dr = R(0.5) * (x0 * y0 + x1 * y1 + x2 * y2)
        # step 2: r_x' = r_x - dr r_y, r_y' = r_y - dr r_x (both from the old pair)
        r00 = x0 - dr * y0
        r01 = x1 - dr * y1
        r02 = x2 - dr * y2
        r10 = y0 - dr * x0
        r11 = y1 - dr * x1
        r12 = y2 - dr * x2
        # step 3: Taylor normalisation r'' = 1/2 (3 - |r'|^2) r'
        sx = R(0.5) * (R(3.0) - (r00 * r00 + r01 * r01 + r02 * r02))
        sy = R(0.5) * (R(3.0) - (r10 * r10 + r11 * r11 + r12 * r12))
        r00 = sx * r00
        r01 = sx * r01
        r02 = sx * r02
        r10 = sy * r10
        r11 = sy * r11
        r12 = sy * r12
        # step 4: r_z'' = r_x'' x r_y'' (the integrated r_z is discarded)
        r20 = r01 * r12 - r02 * r11
        r21 = r02 * r10 - r00 * r12
        r22 = r00 * r11 - r01 * r10
        # valid-attitude policy (imf_math.h): R stays orthonormal, I finite
        if not (_orthonormal(R, (r00, r01, r02, r10, r11, r12, r20, r21, r22))
                and isfinite(ix, iy, iz)):
            self._skip()
            return
        (self.r00, self.r01, self.r02, self.r10, self.r11, self.r12,
         self.r20, self.r21, self.r22, self.ix, self.iy, self.iz) = (
            r00, r01, r02, r10, r11, r12, r20, r21, r22, ix, iy, iz)

    def angles(self):
        """(roll, pitch) in rad (ZYX) of r_z, in double: an output, not state."""
        return tilt_angles(self.r20, self.r21, self.r22)
