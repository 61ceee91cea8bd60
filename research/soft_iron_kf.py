"""A prototype of B6 with soft iron (not in the filter): RobustAHRS's twin (float64) whose B6
estimates, beside the field h in I and the offset o, a trace-free symmetric E (5 numbers),
m = (I + E) R(s)^T h + o in units of the first field's norm (the trace is the field's norm, so
it is left to h). One extended Kalman filter of the 11 numbers, one axis per sample as B6,
with B6's noise, walks and gate; E's prior variance ``PE`` (a 10 % soft iron is 1 sigma) and
walk ``QE`` per s. B4 reads (I + E)^-1 (m - u) once E is trusted (its largest standard
deviation below ``E_TRUST``, the offset trusted and consistent) and some |E_ij| exceeds
``E_MIN``; a change of that starts B4's reference again, as B6's offset does. The state the
filter commits stays B6's: the soft-iron part lives beside it (a rejected sample does not
take it back), so this is a measurement, not a filter to ship.

    python research/soft_iron_study.py --backend soft [-p ...]

Measured (the seven development trials, mean heading RMSE after the first 60 s of movement,
B6 as it is -> this prototype; research/soft_iron_study.py's distortions): undistorted 0.91 ->
1.24 (trial 16 learns E of 0.09 with a standard deviation of 0.005: 0.29 -> 2.27 deg), A (10 %
soft iron, 47 uT) 17.1 -> 6.0, B (8 %, 48 uT) 9.1 -> 16.8, offsets alone O 2.9 -> 4.8 and P
5.4 -> 9.4: on the trials that turn about one axis (11, 25) E is never trusted, and the offset,
less certain beside it, is used later and worse. Not kept (docs/recommended-ahrs.md, Limits).
"""
import math

import numpy as np

from imufuse import reference
from imufuse.reference._math import qrotate

PE, QE, E_TRUST, E_MIN = 0.01, 1e-9, 0.01, 0.02


def _rot(q):
    """R(q), sensor -> I, of a unit quaternion [w x y z]."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def soft_matrix(e):
    """E of its five numbers (xx, yy, xy, xz, yz; zz = -xx - yy)."""
    return np.array([[e[0], e[2], e[3]], [e[2], e[1], e[4]], [e[3], e[4], -e[0] - e[1]]])


#: d(E v)_i / de: for each axis i, (index in e, component of v, sign)
_DE = (((0, 0, 1.0), (2, 1, 1.0), (3, 2, 1.0)),
       ((2, 0, 1.0), (1, 1, 1.0), (4, 2, 1.0)),
       ((3, 0, 1.0), (4, 1, 1.0), (0, 2, -1.0), (1, 2, -1.0)))


class SoftRobustAHRS(reference.RobustAHRS):
    """The twin with B6 extended by soft iron (the module's docstring)."""

    used = False
    esd = 1.0

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.xs = np.zeros(11)
        self.Pe = np.eye(11)

    def get_mag_soft(self):
        """(E, its largest standard deviation)."""
        return soft_matrix(self.xs[6:]), self.esd

    def _offset_start(self, x, c, o2):
        inv = super()._offset_start(x, c, o2)
        self.xs = np.r_[np.asarray(x.hi, float), np.zeros(5)]
        self.Pe = np.diag(np.r_[np.ones(6), np.full(5, PE)])
        return inv

    def _offset_update(self, x, i, c, y, g2):
        dt = float(self.s.dt)
        P = self.Pe
        P[np.diag_indices(11)] += np.r_[np.full(3, 1e-3), np.full(3, 1e-7), np.full(5, QE)] * dt
        if x.m_d2 > 19.0:
            for k in range(3, 6):
                if P[k, k] < 1.0:
                    P[k, k] += 0.05
        rr = min(g2 * self.mag_lag2, 1.0) + self.mag_noise2
        Rt = _rot(x.s).T
        v = Rt @ self.xs[:3]
        E = soft_matrix(self.xs[6:])
        H = np.zeros(11)
        H[:3] = (np.eye(3)[i] + E[i]) @ Rt
        H[3 + i] = 1.0
        for k, j, sgn in _DE[i]:
            H[6 + k] += sgn * v[j]
        PH = P @ H
        sv = H @ PH + rr
        nu = y - (v[i] + E[i] @ v + self.xs[3 + i])
        K = PH / sv
        self.xs = self.xs + K * nu
        self.Pe = P - np.outer(K, PH)
        x.hi = [float(v) for v in self.xs[:6]]
        x.P = [float(self.Pe[a, b]) for a in range(6) for b in range(a, 6)]
        x.m_d2 = nu * nu / sv
        x.m_ew = x.m_ew + 0.02 * (x.m_d2 - x.m_ew)
        x.m_axis = 0.0 if i == 2 else x.m_axis + 1.0
        self.esd = math.sqrt(max(float(np.max(np.diag(self.Pe)[6:])), 0.0))

    def _magnetometer(self, x, m, g2):
        if m[0] == 0.0 and m[1] == 0.0 and m[2] == 0.0:
            return True
        self._offset(x, m, g2)
        d = np.asarray(m, float) - np.asarray(x.u, float)
        use = bool(x.m_n0 != 0.0 and self.esd < E_TRUST and x.m_std < 0.01 and x.m_ew < 8.0
                   and np.abs(self.xs[6:]).max() > E_MIN)
        if use != self.used:
            x.ref[0] = 0.0   # B4: a new reference, as for a change of the offset in use
            self.used = use
        if use:
            d = np.linalg.solve(np.eye(3) + soft_matrix(self.xs[6:]), d)
        me = qrotate(self._R, x.q[0], x.q[1], x.q[2], x.q[3], float(d[0]), float(d[1]),
                     float(d[2]))
        h2 = me[0] * me[0] + me[1] * me[1]
        n2 = h2 + me[2] * me[2]
        if not (n2 >= self._min and n2 <= self._max):
            return True
        fn = [math.sqrt(n2), 0.0, 0.0]
        mh = math.sqrt(h2)
        fn[1] = mh / fn[0]
        fn[2] = me[2] / fn[0]
        if not self._field_used(x, fn) or not (h2 >= self._min):
            return True
        return self._heading(x, list(me), mh)
