"""Fixed-point KK and MultiWii filters: pure-Python twins of
csrc/fixed/gravity_q.c, line for line (Q formats in gravity_q.h)."""
from __future__ import annotations

import math

from .. import _checks
from . import _cint as ci
from .fixed_base import FixedFilter, check_profile, check_scale, qconst


def _acc_1g(v):
    return _checks.check_real("acc_1g", v, lo=1.0, hi=32767.0)


class KKQ(FixedFilter):
    """KK filter of the appendix (Eq. 4.5, small angles, P controller) in the
    integer arithmetic of 8-bit firmware. State tx, ty: q28 rad; the
    accelerometer angles are a_x = -acc_x/1g, a_y = acc_y/1g. kp is per sample."""
    kind = "imu"
    state_names = ("tx", "ty")

    @staticmethod
    def _params(dt, kp, *, gyr_scale, acc_1g, profile="32"):
        dt = _checks.check_dt(dt)
        kp = _checks.check_real("kp", kp, lo=0.0, hi=1.0)
        gyr_scale = check_scale("gyr_scale", gyr_scale)
        acc_1g = _acc_1g(acc_1g)
        qconst("gyr_scale*dt", gyr_scale * dt, 28, 59, nonzero=True)
        qconst("kp", kp, 14, 47)
        return (dt, kp, gyr_scale, acc_1g, check_profile(profile))

    def _init(self, dt, kp, gyr_scale, acc_1g, profile):
        self.kw = ci.qscale(gyr_scale * dt)
        self.ka = ci.qscale(1.0 / acc_1g if acc_1g > 0.0 else 0.0)
        self.kp = ci.qscale(kp)
        self.t = [0, 0]

    def _get_state(self):
        return list(self.t)

    def _set_state(self, v):
        self.t = list(v)

    def _state_float(self, s):
        return [s[0] * 2.0 ** -28, s[1] * 2.0 ** -28]

    def _update(self, gyr, acc):
        t = self.t
        tx15, ty15 = ci.qn_to_q15s(t[0], 28), ci.qn_to_q15s(t[1], 28)
        wx, wy = ci.scale16(gyr[0], self.kw, 28), ci.scale16(gyr[1], self.kw, 28)
        cx = ci.scale32(ty15 * gyr[2], self.kw, 15, 28)
        cy = ci.scale32(tx15 * gyr[2], self.kw, 15, 28)
        ax = ci.sub_sat32(0, ci.scale16(acc[0], self.ka, 28))
        ay = ci.scale16(acc[1], self.ka, 28)
        px = ci.scale32(ci.sub_sat32(ax, t[0]), self.kp, 28, 28)
        py = ci.scale32(ci.sub_sat32(ay, t[1]), self.kp, 28, 28)
        nx = ci.add_sat32(ci.add_sat32(ci.add_sat32(t[0], wy), cx), px)
        ny = ci.add_sat32(ci.add_sat32(ci.sub_sat32(t[1], cy), wx), py)
        self.t = [nx, ny]


class MultiWiiQ(FixedFilter):
    """MultiWii 2.2 gravity-vector filter (appendix) in integer arithmetic.
    d (q15 acc counts) follows the accelerometer: d += d x w dt, and while
    |a| is within 1 +- 0.15 g, d = (d F + a)/(F + 1). state_float is d in g."""
    kind = "imu"
    state_names = ("dx", "dy", "dz")

    @staticmethod
    def _params(dt, cmpf=600.0, *, gyr_scale, acc_1g, profile="32"):
        dt = _checks.check_dt(dt)
        cmpf = _checks.check_real("cmpf", cmpf, lo=0.0, hi=1e9)
        gyr_scale = check_scale("gyr_scale", gyr_scale)
        acc_1g = _acc_1g(acc_1g)
        qconst("gyr_scale*dt", gyr_scale * dt, 15, 62, nonzero=True)
        qconst("1/(cmpf+1)", 1.0 / (cmpf + 1.0), 14, 47)
        return (dt, cmpf, gyr_scale, acc_1g, check_profile(profile))

    def _init(self, dt, cmpf, gyr_scale, acc_1g, profile):
        lo, hi = 0.85 * acc_1g, 1.15 * acc_1g
        self.acc_1g = acc_1g
        self.kw = ci.qscale(gyr_scale * dt)
        self.kc = ci.qscale(1.0 / (cmpf + 1.0) if cmpf >= 0.0 else 0.0)
        self.lo2 = int(math.floor(lo * lo))
        self.hi2 = int(math.ceil(hi * hi))
        self.one_g = int(math.floor(acc_1g * 32768.0 + 0.5))
        self.d = [0, 0, self.one_g]

    def _get_state(self):
        return list(self.d)

    def _set_state(self, v):
        self.d = list(v)

    def _state_float(self, s):
        return [v * 2.0 ** -15 / self.acc_1g for v in s]

    def _update(self, gyr, acc):
        d = self.d
        m = ci.mul_32x16
        # step 3: d_n = d_{n-1} + d_{n-1} x w dt
        c = [ci.sub_sat32(m(d[1], gyr[2], 15), m(d[2], gyr[1], 15)),
             ci.sub_sat32(m(d[2], gyr[0], 15), m(d[0], gyr[2], 15)),
             ci.sub_sat32(m(d[0], gyr[1], 15), m(d[1], gyr[0], 15))]
        for i in range(3):
            d[i] = ci.add_sat32(d[i], ci.scale32(c[i], self.kw, 0, 15))
        # step 4: complementary weighting while |a| is within 1 +- 0.15 g
        n2 = acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2]
        if self.lo2 < n2 < self.hi2:
            for i in range(3):
                e = ci.sub_sat32(ci.q15_to_q30(acc[i]), d[i])
                d[i] = ci.add_sat32(d[i], ci.scale32(e, self.kc, 15, 15))
