"""Initial attitude shared by every 3-D filter: pure-Python twin of
csrc/imf_attitude.c, line for line.

Earth frame NWU (x north, y west, z up); the attitude rotates sensor to
earth, so the rows of the matrix r are north, west and up seen in the sensor
frame. From a reading (TRIAD): up = a/|a|, west = (up x m)/|up x m|, north =
west x up; without a magnetometer (or with a vertical field) the heading of
ZYX yaw 0, west = (up x e_x)/|...|, and with the x axis vertical west = e_y.

R is the arithmetic type (float or numpy.float32). Functions return new
values instead of writing through pointers; None stands for C's return 0.
"""
import math

from ._math import sqrt


def isfinite(*values):
    return all(math.isfinite(v) for v in values)


class Attitude:
    """imf_attitude_t: q (w, x, y, z) and r (row-major north, west, up)."""
    __slots__ = ("q", "r")

    def __init__(self, q, r):
        self.q = q
        self.r = r


def _abs(R, x):
    return -x if x < R(0.0) else x


def unit3(R, x, y, z):
    """attitude_unit3: (x, y, z) / |(x, y, z)|, scaled by its largest magnitude
    first; None when zero or not finite."""
    if not isfinite(x, y, z):
        return None
    m = _abs(R, x)
    if _abs(R, y) > m:
        m = _abs(R, y)
    if _abs(R, z) > m:
        m = _abs(R, z)
    if m == R(0.0):
        return None
    x = x / m
    y = y / m
    z = z / m
    n2 = x * x + y * y + z * z
    r = R(1.0) / sqrt(R, n2)
    return x * r, y * r, z * r


def unit4(R, q):
    """attitude_unit4: the same for a quaternion."""
    if not isfinite(*q):
        return None
    m = R(0.0)
    for v in q:
        if _abs(R, v) > m:
            m = _abs(R, v)
    if m == R(0.0):
        return None
    q = [v / m for v in q]
    n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
    r = R(1.0) / sqrt(R, n2)
    return [v * r for v in q]


def quat_of_matrix(R, r):
    """attitude_quat_of_matrix: Shepperd, w >= 0, normalised."""
    t = r[0] + r[4] + r[8]
    if t > R(0.0):
        # s = 4 w
        s = R(2.0) * sqrt(R, R(1.0) + t)
        q = [R(0.25) * s, (r[7] - r[5]) / s, (r[2] - r[6]) / s, (r[3] - r[1]) / s]
    elif r[0] > r[4] and r[0] > r[8]:
        # s = 4 x
        s = R(2.0) * sqrt(R, R(1.0) + r[0] - r[4] - r[8])
        q = [(r[7] - r[5]) / s, R(0.25) * s, (r[1] + r[3]) / s, (r[2] + r[6]) / s]
    elif r[4] > r[8]:
        # s = 4 y
        s = R(2.0) * sqrt(R, R(1.0) + r[4] - r[0] - r[8])
        q = [(r[2] - r[6]) / s, (r[1] + r[3]) / s, R(0.25) * s, (r[5] + r[7]) / s]
    else:
        # s = 4 z
        s = R(2.0) * sqrt(R, R(1.0) + r[8] - r[0] - r[4])
        q = [(r[3] - r[1]) / s, (r[2] + r[6]) / s, (r[5] + r[7]) / s, R(0.25) * s]
    if q[0] < R(0.0):
        q = [-v for v in q]
    u = unit4(R, q)
    return q if u is None else u


def from_acc_mag(R, ax, ay, az, mx, my, mz):
    """imf_attitude_from_acc_mag: an Attitude, or None (acc zero or not finite)."""
    u = unit3(R, ax, ay, az)
    if u is None:
        return None
    ux, uy, uz = u
    # west = up x m, normalised
    w = unit3(R, uy * mz - uz * my, uz * mx - ux * mz, ux * my - uy * mx)
    if w is None:
        # no field, or a vertical one: ZYX yaw 0, west = up x e_x
        w = unit3(R, R(0.0), uz, -uy)
        if w is None:
            # the x axis vertical: ZYX roll 0, west = e_y
            w = (R(0.0), R(1.0), R(0.0))
    wx, wy, wz = w
    # north = west x up
    r = [wy * uz - wz * uy, wz * ux - wx * uz, wx * uy - wy * ux,
         wx, wy, wz,
         ux, uy, uz]
    return Attitude(quat_of_matrix(R, r), r)


def from_quat(R, q0, q1, q2, q3):
    """imf_attitude_from_quat: an Attitude, or None (zero or not finite)."""
    q = unit4(R, [q0, q1, q2, q3])
    if q is None:
        return None
    # R(q), sensor -> earth
    r = [R(1.0) - R(2.0) * (q[2] * q[2] + q[3] * q[3]),
         R(2.0) * (q[1] * q[2] - q[0] * q[3]),
         R(2.0) * (q[1] * q[3] + q[0] * q[2]),
         R(2.0) * (q[1] * q[2] + q[0] * q[3]),
         R(1.0) - R(2.0) * (q[1] * q[1] + q[3] * q[3]),
         R(2.0) * (q[2] * q[3] - q[0] * q[1]),
         R(2.0) * (q[1] * q[3] - q[0] * q[2]),
         R(2.0) * (q[2] * q[3] + q[0] * q[1]),
         R(1.0) - R(2.0) * (q[1] * q[1] + q[2] * q[2])]
    return Attitude(q, r)


class Window:
    """imf_attitude_window_t: sums of the unit directions of the first readings."""

    def __init__(self, R, window):
        # imf_attitude_window_init
        self.R = R
        self.ax = self.ay = self.az = R(0.0)
        self.mx = self.my = self.mz = R(0.0)
        self.n = 0
        self.window = window if window > 0 else 1

    def add(self, ax, ay, az, mx, my, mz):
        """imf_attitude_window_add: (1, Attitude), (0, None) or (-1, None)."""
        R = self.R
        if not isfinite(ax, ay, az, mx, my, mz):
            return -1, None
        u = unit3(R, ax, ay, az)
        if u is None:
            return 0, None
        sax = self.ax + u[0]
        say = self.ay + u[1]
        saz = self.az + u[2]
        smx, smy, smz = self.mx, self.my, self.mz
        v = unit3(R, mx, my, mz)
        if v is not None:
            smx = smx + v[0]
            smy = smy + v[1]
            smz = smz + v[2]
        att = from_acc_mag(R, sax, say, saz, smx, smy, smz)
        if att is None:
            return -1, None
        self.ax, self.ay, self.az = sax, say, saz
        self.mx, self.my, self.mz = smx, smy, smz
        self.n = (self.n + 1) & 0xFFFFFFFF
        return 1, att


