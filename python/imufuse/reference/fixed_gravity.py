"""Fixed-point KK and MultiWii filters: pure-Python twins of
csrc/fixed/gravity_q.c, line for line (Q formats in gravity_q.h)."""
from __future__ import annotations

import math
import numbers

from ..shared import checks as _checks
from . import _cint as ci
from . import fixed_scale as fs
from .fixed_base import FixedFilter, check_profile, check_scale, qconst
from .kk import KK
from .multiwii import MultiWii


def _q15(t):
    """imf_kk_q_q15: the state rounded to q15, imf_qn_to_q15s(t, 28)."""
    return ci.qn_to_q15s(t, 28)


def _mul15(w, q):
    """imf_kk_q_mul15: round(w q / 2^15) for int32 w, int16 q (no saturation)."""
    return (ci.check32(w) * q + 16384) >> 15


class KKQ(FixedFilter):
    """KK filter of the appendix (Eq. 4.5 with a P controller), fixed point;
    twin of KK (same equations): pitch, roll in q28 rad, a_pitch = -a_x/|a|,
    a_roll = a_y/|a|; kp per sample, in [0, 1]. KKQ(dt, kp, gyr_scale=rad/s per count)."""
    kind = "imu"
    c_name = "imf_kk_q"
    state_names = ("pitch", "roll")

    @staticmethod
    def _params(dt, kp, *, gyr_scale, profile="32"):
        # the fixed-point range first (KK's own is [0, 2), which the message would name)
        if isinstance(kp, numbers.Real) and not isinstance(kp, bool) and kp > 1.0:
            # imf_kk_q_init_consts: kp in [0, 1]
            raise ValueError(f"kp: must be in [0, 1] in fixed point (kp > 1 corrects more than "
                             f"the whole error in one sample: an oscillating P loop), got {kp!r}")
        dt, kp = KK._params(dt, kp)
        gyr_scale = check_scale("gyr_scale", gyr_scale)
        qconst("gyr_scale*dt", gyr_scale * dt, 28, 59, nonzero=True)
        qconst("kp", kp, 14, 47)
        return (dt, kp, gyr_scale, check_profile(profile))

    @staticmethod
    def _consts(dt, kp, gyr_scale, profile):
        # imf_kk_q_init: the constants from the double parameters
        kp16 = fs.gain16(ci.qscale(kp), 15, 15)
        return dict(kw=ci.qscale(gyr_scale * dt), kp16_m=kp16[0], kp16_j=kp16[1])

    def _init(self, dt, kp, gyr_scale, profile):
        self._init_consts(**self._consts(dt, kp, gyr_scale, profile))

    def _init_consts(self, kw, kp16_m, kp16_j):
        self.kw = kw
        self.kp16 = (kp16_m, kp16_j)
        self.t = [0, 0]

    def _get_state(self):
        return list(self.t)

    def _set_state(self, v):
        self.t = list(v)

    def _state_float(self, s):
        return [s[0] * 2.0 ** -28, s[1] * 2.0 ** -28]

    def _angle(self, ti, tj, wj, wz, neg, ok, ai):
        # -+ theta_j w_z dt: the state rounded to q15 (imf_kk_q_q15), its sign
        # applied there (symmetric q15), times w_z dt in q28, / 2^15 rounded
        q = _q15(tj)
        x = ci.add_sat32(ti, wj)
        if neg:
            q = -q
        x = ci.add_sat32(x, _mul15(wz, q))
        if ok:
            # P controller Kp (a - theta_{n-1}), a in q28 (symmetric q15 -> q28
            # exactly); kp = 1 (kp16.j < 0): the whole error
            e = ci.sub_sat32(ai * 8192, ti)
            x = ci.add_sat32(x, fs.gain16_mul(e, self.kp16) if self.kp16[1] >= 0 else e)
        return x

    def _update(self, gyr, acc):
        t = self.t
        a = fs.unit_xy_k(acc)
        ok = a is not None
        a = a if ok else [0, 0]
        # w dt in q28 (imf_mulk16's value, its shift kw.s - 28 >= 0)
        w = [fs.rshrk(g * self.kw.m, self.kw.s - 28) for g in gyr]
        # pitch (theta_0 with roll, w_y dt, -a_x) and roll (theta_1 with pitch, w_x dt, a_y)
        self.t = [self._angle(t[0], t[1], w[1], w[2], True, ok, -a[0]),
                  self._angle(t[1], t[0], w[0], w[2], False, ok, a[1])]


class MultiWiiQ(FixedFilter):
    """MultiWii 2.2 gravity-vector filter (appendix) in integer arithmetic;
    twin of MultiWii (same keywords; acc_1g in counts, required). State d
    (q15 acc counts) and the accelerometer LPF l (accSmooth = accLPF32 / 2^k,
    q15 counts); state_float gives both in acc counts, like the float twin
    fed with counts."""
    kind = "imu"
    c_name = "imf_multiwii_q"
    state_names = ("dx", "dy", "dz", "ax", "ay", "az")

    @staticmethod
    def _params(dt, cmpf=600.0, acc_lpf_shift=4, *, acc_1g, window=0.15, gyr_scale, profile="32"):
        dt, cmpf, acc_lpf_shift, acc_1g, window = MultiWii._params(dt, cmpf, acc_lpf_shift,
                                                                   acc_1g, window)
        if acc_lpf_shift > 15:
            raise ValueError(f"acc_lpf_shift: must be <= 15 in fixed point, got {acc_lpf_shift!r}")
        acc_1g = _checks.check_real("acc_1g", acc_1g, lo=0.0, lo_open=True, hi=32767.0)
        if not math.floor(acc_1g * 32768.0 + 0.5) > 0:
            # its q15 form (csrc/fixed/gravity_q.c) must not round to zero
            raise ValueError(f"acc_1g: must be at least 2^-16 counts in fixed point, got {acc_1g!r}")
        cmpf = _checks.check_real("cmpf", cmpf, lo=0.0, hi=1e9)
        _checks.check_real("window", window, lo=0.0, hi=1.0)
        gyr_scale = check_scale("gyr_scale", gyr_scale)
        qconst("gyr_scale*dt", gyr_scale * dt, 16, 62, nonzero=True)
        qconst("1/(cmpf+1)", 1.0 / (cmpf + 1.0), 14, 47)
        return (dt, cmpf, acc_lpf_shift, acc_1g, window, gyr_scale, check_profile(profile))

    @staticmethod
    def _consts(dt, cmpf, acc_lpf_shift, acc_1g, window, gyr_scale, profile):
        # imf_multiwii_q_init: the constants from the double parameters
        lo, hi = (1.0 - window) * acc_1g, (1.0 + window) * acc_1g
        return dict(kw=ci.qscale(gyr_scale * dt),
                    kc=ci.qscale(1.0 / (cmpf + 1.0) if cmpf >= 0.0 else 0.0),
                    acc_lpf_shift=acc_lpf_shift,
                    lo2=int(math.floor(lo * lo)) if lo > 0.0 else 0,
                    hi2=0xFFFFFFFF if hi * hi >= 4294967295.0 else int(math.ceil(hi * hi)),
                    acc_1g_q15=int(math.floor(acc_1g * 32768.0 + 0.5)))

    def _init(self, dt, cmpf, acc_lpf_shift, acc_1g, window, gyr_scale, profile):
        self._init_consts(**self._consts(dt, cmpf, acc_lpf_shift, acc_1g, window, gyr_scale,
                                         profile))

    def _init_consts(self, kw, kc, acc_lpf_shift, lo2, hi2, acc_1g_q15):
        self.kw = kw
        self.kc = kc
        self.kw16 = fs.gain16(kw, 0, 16)
        self.kc16 = fs.gain16(kc, 15, 15)
        self.k = acc_lpf_shift
        self.lo2 = lo2
        self.hi2 = hi2
        # start level: d = accSmooth = (0, 0, acc_1g)
        self.d = [0, 0, acc_1g_q15]
        self.l = [0, 0, acc_1g_q15]

    def _get_state(self):
        return self.d + self.l

    def _set_state(self, v):
        self.d, self.l = list(v[:3]), list(v[3:])

    def _state_float(self, s):
        return [v * 2.0 ** -15 for v in s]

    def _update(self, gyr, acc):
        d, l, k = self.d, self.l, self.k
        n2 = 0
        # accelerometer LPF, MultiWii's accLPF32 -= accLPF32 >> k; += acc divided by
        # 2^k: accSmooth += (acc - accSmooth) / 2^k, in q15 counts (rounded)
        for i in range(3):
            l[i] = ci.add_sat32(l[i], fs.rshrk(ci.sub_sat32(fs.i16_to_q15(acc[i]), l[i]), k))
            sc = ci.sat_q15(ci.rshr32(l[i], 15))
            n2 += sc * sc
        # step 3: d_n = d_{n-1} + d_{n-1} x w dt; the cross product d x w first,
        # in half acc counts x gyro counts (d q15 x counts / 2^16, each component
        # rounded once), then x kw -> q15
        c = fs.cross3_16(d, gyr)
        for i in range(3):
            d[i] = ci.add_sat32(d[i], fs.gain16_or_mulk32(c[i], self.kw16, self.kw, 0, 16))
        # step 4: complementary weighting while |accSmooth| is within the window
        if self.lo2 < n2 < self.hi2:
            for i in range(3):
                d[i] = ci.add_sat32(d[i], fs.gain16_or_mulk32(ci.sub_sat32(l[i], d[i]), self.kc16, self.kc, 15, 15))
