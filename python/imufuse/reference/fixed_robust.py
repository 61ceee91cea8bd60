"""Fixed-point RobustIMU and RobustAHRS (B6 included): pure-Python twin of
csrc/fixed/robust_q.c, line for line (Q formats and ranges in robust_q.h): the settings, the
constants, init and the updates, which compose the blocks of fixed_robust_blocks.py and
fixed_robust_mag.py and fixed_robust_b6.py (their helpers in fixed_robust_ops.py and
fixed_robust_p8.py), as robust_q.c composes those of robust_q_blocks.h, robust_q_mag.h and
robust_q_b6.h.
"""
from __future__ import annotations

import math

from . import _cint as ci
from . import fixed_quat as fq
from .fixed_base import FixedFilter, check_profile, check_scale, qconst
from .fixed_robust_blocks import (acc_reading, bias, gravity, level, output, rest,
                                  strapdown)
from .fixed_robust_b6 import offset
from .fixed_robust_mag import magnetometer
from .robust import RobustAHRS, RobustIMU


def _ceil(v):
    c = math.ceil(v)
    return int(c) if 0.0 <= c <= 1073741824.0 else -1


#: the state words in imf_robust_imu_q_state_t's order: (member, the suffixes of the names
#: of its words; "" for a scalar member)
IMU_LAYOUT = (("q", "0123"), ("s", "0123"), ("c", "0123"), ("f", "xyz"), ("v", "xyz"),
              ("p", ("vv", "vg", "gg")), ("b", "xyz"), ("lw", "xyz"), ("la", "xyz"),
              ("n", ""), ("n_rest", ""))
#: RobustAHRSQ's words after the IMU's (imf_robust_ahrs_q_state_t)
MAG_LAYOUT = (("u", "xyz"), ("rn", ""), ("rh", ""), ("rz", ""), ("cn", ""), ("ch", ""),
              ("cz", ""), ("n_ok", ""), ("n_dist", ""), ("n_cand", ""),
              # B6 (constant while mag_learn is off)
              ("hi", ("hx", "hy", "hz", "ox", "oy", "oz")),
              ("P", tuple(f"{i}{j}" for i in range(6) for j in range(i, 6))),
              ("so", "xyz"), ("m_n2", ""), ("m_im", ""), ("m_is", ""), ("m_nm", ""),
              ("m_ns", ""), ("m_ew", ""), ("m_d2", ""), ("m_var", ""),
              ("mn", ("_nu", "_vu", "_ne", "_ve")), ("m_qo", ""),
              ("m_axis", ""), ("m_bad", ""))


def _names(layout):
    """The state names of a layout: a member's name and each suffix, or the name alone."""
    return tuple(n for m, parts in layout for n in ([m + p for p in parts] if parts else [m]))


def _words(x, layout):
    """The state words of x in the layout's order (imf_*_state_t's)."""
    out = []
    for m, parts in layout:
        out += getattr(x, m) if parts else [getattr(x, m)]
    return out


def _set_words(x, layout, v):
    """x's members from the words v in the layout's order; the words left over."""
    v = list(v)
    for m, parts in layout:
        if parts:
            setattr(x, m, v[:len(parts)])
            v = v[len(parts):]
        else:
            setattr(x, m, v.pop(0))
    return v


def step(k, x, gyr, acc, rq):
    """robust_q_step: B1, B2, B3 and B5 of one sample; False when the sample is not taken
    (no start without an accelerometer reading), then nothing else runs. rq: None, or a
    list that takes the rotation matrix of the new q (for B4)."""
    first = x.n == 0
    has_acc = acc_reading(x, acc, first)
    if first and not has_acc:
        return False                     # no start without an accelerometer reading
    at_rest, w2 = rest(k, x, gyr, acc, has_acc)          # B1
    sn = strapdown(k, x, gyr)
    gravity(k, x, acc, sn, first, has_acc, w2)            # B2
    r = level(k, x, sn)
    bias(k, x, at_rest, r, rq)                            # B3
    return True


class RobustIMUQ(FixedFilter):
    """imufuse's recommended attitude filter (RobustIMU, docs/recommended-ahrs.md) in
    fixed point: B1, B2, B3, B5 and the output latency, int32 with 16x16 multiplies.

    RobustIMUQ(dt, <RobustIMU's keywords, the same units>, gyr_scale=rad/s per count,
    profile="32"). Two profiles: "32" (q30 times q15 products) and "8" (the same state
    and blocks, every quaternion product and rotation in 16x16 products: for 8-bit MCUs).
    State: q, s, c (q30), gravity f and B2's v (q15 acc counts), B2's scaled covariance
    (q30), bias b, low-passes lw, la (q15 counts), the sample counters n, n_rest;
    state_float gives the quaternions, f and la in counts, b and lw in rad/s.
    """
    kind = "imu"
    c_name = "imf_robust_imu_q"
    state_names: tuple = _names(IMU_LAYOUT)

    @staticmethod
    def _params(dt, tau_acc=2.5, rate_ref=100.0, tau_bias=100.0, tau_bias_rest=3.0,
                rest_gyr=2.0, rest_acc=0.05, rest_time=1.5, tau_rest=0.5, latency=0.0, *,
                gyr_scale, profile="32"):
        s = RobustIMU._params(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr,
                              rest_acc, rest_time, tau_rest, latency)
        dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc, rest_time, \
            tau_rest, latency = (s.dt, s.tau_acc, s.rate_ref, s.tau_bias, s.tau_bias_rest,
                                 s.rest_gyr, s.rest_acc, s.rest_time, s.tau_rest, s.latency)
        profile = check_profile(profile)
        gyr_scale = check_scale("gyr_scale", gyr_scale)
        if not 200.0 * dt <= tau_acc <= 8192.0 * dt:
            hint = (f"; dt is in seconds (dt={dt!r} looks like milliseconds)" if dt >= 1.0
                    else "")
            raise ValueError(f"tau_acc: must be within [200 dt, 8192 dt] = [{200.0 * dt:.4g}, "
                             f"{8192.0 * dt:.4g}] s in fixed point (B2's covariance in q30), "
                             f"got {tau_acc!r}{hint}; give tau_acc in that range, or sample "
                             f"{'faster' if tau_acc < 200.0 * dt else 'slower'}")
        if not gyr_scale * dt < 2.0 ** -15:
            raise ValueError(f"gyr_scale: {gyr_scale!r} rad/s per count turns the gyro's full "
                             f"scale by more than half a radian per sample at dt={dt!r} s "
                             f"(gyr_scale dt must be below 2^-15 = {2.0 ** -15:.4g}); gyr_scale "
                             "is in rad/s per count (2000 deg/s on 16 bits: 1.0642e-3; a deg/s "
                             "scale is 57 times larger)")
        if rest_acc > 1.0:
            raise ValueError(f"rest_acc: must be <= 1 in fixed point, got {rest_acc!r}")
        if rest_acc > 0.0:
            qconst("rest_acc^2", rest_acc * rest_acc, 14, 47, nonzero=True)
        qconst("gyr_scale*dt", 0.5 * gyr_scale * dt, 31, 62, nonzero=True)
        if latency > 0.0:
            qconst("gyr_scale*latency", 0.5 * gyr_scale * latency, 15, 62, nonzero=True)
        if rate_ref > 0.0:
            e = dt / tau_acc
            qconst("(dt/tau_acc)^2 (gyr_scale/rate_ref)^2",
                   4.0 * e * e * (gyr_scale / rate_ref) * (gyr_scale / rate_ref), 30, 62,
                   nonzero=True)
        if tau_bias > 0.0:
            qconst("1/(tau_bias*gyr_scale)", 1.0 / (tau_bias * gyr_scale), -15, 32, nonzero=True)
        for name, v in (("rest_time", rest_time), ("tau_rest", tau_rest)):
            if _ceil(v / dt) < 0:
                raise ValueError(f"{name}: must be at most 2^30 samples, got {v!r}")
        qconst("dt/(tau_rest+dt)", dt / (tau_rest + dt), 0, 47, nonzero=True)
        qconst("dt/(tau_bias_rest+dt)", dt / (tau_bias_rest + dt), 0, 47, nonzero=True)
        return (dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc, rest_time,
                tau_rest, latency, gyr_scale, profile)

    @staticmethod
    def _consts(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc, rest_time,
                tau_rest, latency, gyr_scale, profile):
        # imf_robust_imu_q_init: the constants from the double parameters
        gs = gyr_scale
        e = dt / tau_acc
        g2 = rest_gyr / gs
        n_tau, n_acc = _ceil(tau_rest / dt), _ceil(tau_acc / dt)
        return dict(kg=ci.qscale(0.5 * gs * dt), klat=ci.qscale(0.5 * gs * latency),
                    eps=ci.qscale(e),
                    kq=ci.qscale(4.0 * e * e * (gs / rate_ref) * (gs / rate_ref)
                                 if rate_ref > 0.0 else 0.0),
                    k_rest=ci.qscale(dt / (tau_rest + dt)),
                    kb_rest=ci.qscale(dt / (tau_bias_rest + dt)),
                    kbias=ci.qscale(1.0 / (tau_bias * gs) if tau_bias > 0.0 else 0.0),
                    kacc2=ci.qscale(rest_acc * rest_acc),
                    qg0=math.floor(e * e * 1073741824.0 + 0.5),
                    qcap=math.floor(1e4 * e * e * 1073741824.0 + 0.5),
                    pg0=math.floor(e * 1073741824.0 + 0.5),
                    rest_g2=0xFFFFFFFF if g2 * g2 >= 4294967295.0 else math.ceil(g2 * g2),
                    n_tau=n_tau, n_acc=n_acc, n_rest=_ceil(rest_time / dt),
                    n_max=max(n_tau, n_acc), profile=int(profile))

    def _init(self, dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc,
              rest_time, tau_rest, latency, gyr_scale, profile):
        self.dt = dt
        self.gyr_scale = gyr_scale
        self.tau_acc = tau_acc
        self._init_consts(**self._consts(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest,
                                         rest_gyr, rest_acc, rest_time, tau_rest, latency,
                                         gyr_scale, profile))

    def _init_consts(self, **k):
        # imf_robust_imu_q_init_consts (the ranges were checked by _params)
        self.k = k
        self.kg = k["kg"]                                  # the rate scale integrated
        self.q = [fq.Q30_ONE, 0, 0, 0]
        self.s = [fq.Q30_ONE, 0, 0, 0]
        self.c = [fq.Q30_ONE, 0, 0, 0]
        self.f, self.v, self.p = [0, 0, 0], [0, 0, 0], [0, 0, 0]
        self.b, self.lw, self.la = [0, 0, 0], [0, 0, 0], [0, 0, 0]
        self.n = self.n_rest = 0

    def _get_state(self):
        return _words(self, IMU_LAYOUT)

    def _set_state(self, v):
        _set_words(self, IMU_LAYOUT, v)

    def _state_float(self, s):
        q30, q15 = 2.0 ** -30, 2.0 ** -15
        w = self.gyr_scale * q15
        return ([v * q30 for v in s[:12]] + [v * q15 for v in s[12:15]]
                + [v * q15 * self.tau_acc for v in s[15:18]] + [v * q30 for v in s[18:21]]
                + [v * w for v in s[21:27]] + [v * q15 for v in s[27:30]] + list(s[30:]))

    def _update(self, gyr, acc):
        # imf_robust_imu_q_update
        if step(self.k, self, gyr, acc, None):
            output(self.k, self, gyr)



class RobustAHRSQ(RobustIMUQ):
    """imufuse's recommended attitude filter with a magnetometer (RobustAHRS,
    docs/recommended-ahrs.md) in fixed point: RobustIMUQ's blocks, B4, the magnetometer
    confined to heading with its disturbance detector, and B6, its offset learnt while
    turning.

    RobustAHRSQ(dt, <RobustAHRS's keywords, the same units>, gyr_scale=rad/s per count,
    profile="32"); mag_learn (B6) is False by default in fixed point. The magnetometer in
    counts, any unit (B4 is relative to its learned reference); the stored offset (counts)
    is given with set_mag_offset. State: RobustIMUQ's, then the offset in use u, the
    reference (rn q15 counts, rh, rz q30) and the candidate (cn, ch, cz), the sample
    counters n_ok, n_dist, n_cand, then B6's (robust_q.h): h and o (q26 of the field unit),
    their covariance P (q30), the stored offset so, the field unit's words, the innovation's
    statistics, the offset's variance m_var, the norm statistics of the early use of a
    large offset mn_nu, mn_vu, mn_ne, mn_ve (q26), m_qo, m_axis, m_bad.
    """
    kind = "ahrs"
    c_name = "imf_robust_ahrs_q"
    state_names = _names(IMU_LAYOUT + MAG_LAYOUT)

    @staticmethod
    def _params(dt, tau_acc=2.5, rate_ref=100.0, tau_bias=100.0, tau_bias_rest=3.0,
                rest_gyr=2.0, rest_acc=0.05, rest_time=1.5, tau_rest=0.5, latency=0.0,
                tau_mag=10.0, mag_norm=0.1, mag_dip=10.0, tau_mag_ref=20.0, mag_new_time=20.0,
                mag_hold=0.5, mag_learn=False, mag_noise=0.02, mag_lag=0.003,
                mag_offset_min=0.1, *, gyr_scale, profile="32"):
        imu = RobustIMUQ._params(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr,
                                 rest_acc, rest_time, tau_rest, latency, gyr_scale=gyr_scale,
                                 profile=profile)
        m = RobustAHRS._params(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr,
                               rest_acc, rest_time, tau_rest, latency, tau_mag, mag_norm,
                               mag_dip, tau_mag_ref, mag_new_time, mag_hold, mag_learn,
                               mag_noise, mag_lag, mag_offset_min)
        dt = imu[0]
        mag = (m.tau_mag, m.mag_norm, m.mag_dip, m.tau_mag_ref, m.mag_new_time, m.mag_hold)
        tau_mag, mag_norm, _, tau_mag_ref, mag_new_time, mag_hold = mag
        if mag_norm > 1.0:
            raise ValueError(f"mag_norm: must be <= 1 in fixed point, got {mag_norm!r}")
        if mag_norm > 0.0:
            qconst("mag_norm", mag_norm, 14, 47, nonzero=True)
        for name, v in (("tau_mag", tau_mag), ("tau_mag_ref", tau_mag_ref),
                        ("mag_new_time", mag_new_time), ("mag_hold", mag_hold)):
            if _ceil(v / dt) < 0:
                raise ValueError(f"{name}: must be at most 2^30 samples, got {v!r}")
        qconst("dt/(tau_mag+dt)", dt / (tau_mag + dt), 0, 47, nonzero=True)
        qconst("dt/(tau_mag_ref+dt)", dt / (tau_mag_ref + dt), 0, 47, nonzero=True)
        # B6: the noise's square in q28 keeps the gains within q24; the lag's in its shifts
        if not 0.01 <= m.mag_noise <= 1.0:
            raise ValueError(f"mag_noise: must be within [0.01, 1] in fixed point (B6's gains "
                             f"in q24), got {m.mag_noise!r}")
        if m.mag_offset_min > 1.0:
            raise ValueError(f"mag_offset_min: must be <= 1 in fixed point, got "
                             f"{m.mag_offset_min!r}")
        if m.mag_lag > 0.0:
            qconst("(gyr_scale*mag_lag)^2", (imu[10] * m.mag_lag) ** 2, 29, 62, nonzero=True)
        b6 = (int(bool(m.mag_learn)), m.mag_noise, m.mag_lag, m.mag_offset_min)
        return imu[:10] + mag + b6 + imu[10:]

    @staticmethod
    def _consts(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc, rest_time,
                tau_rest, latency, tau_mag, mag_norm, mag_dip, tau_mag_ref, mag_new_time,
                mag_hold, mag_learn, mag_noise, mag_lag, mag_offset_min, gyr_scale, profile):
        # imf_robust_ahrs_q_init: RobustIMUQ's constants, B4's and B6's
        imu = RobustIMUQ._consts(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr,
                                 rest_acc, rest_time, tau_rest, latency, gyr_scale, profile)
        n_mag, n_ref = _ceil(tau_mag / dt), _ceil(tau_mag_ref / dt)
        imu["n_max"] = max(imu["n_max"], n_mag, n_ref)
        return dict(imu=imu, k_mag=ci.qscale(dt / (tau_mag + dt)),
                    k_ref=ci.qscale(dt / (tau_mag_ref + dt)), knorm=ci.qscale(mag_norm),
                    kdip=0x7FFFFFFF if mag_dip >= 2.0 else math.floor(mag_dip * 1073741824.0
                                                                       + 0.5),
                    n_mag=n_mag, n_ref=n_ref, n_hold=_ceil(mag_hold / dt),
                    n_new=_ceil(mag_new_time / dt), learn=int(mag_learn),
                    kqh=math.floor(1e-3 * dt * 1073741824.0 + 0.5),
                    kqo=math.floor(1e-7 * dt * 70368744177664.0 + 0.5),
                    knoise2=math.floor(mag_noise * mag_noise * 268435456.0 + 0.5),
                    klag2=ci.qscale((gyr_scale * mag_lag) * (gyr_scale * mag_lag)),
                    kmin2=math.floor(mag_offset_min * mag_offset_min * 1073741824.0 + 0.5),
                    n_bad=_ceil(1.0 / dt))

    def _init(self, dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc,
              rest_time, tau_rest, latency, tau_mag, mag_norm, mag_dip, tau_mag_ref,
              mag_new_time, mag_hold, mag_learn, mag_noise, mag_lag, mag_offset_min, gyr_scale,
              profile):
        self.dt = dt
        self.gyr_scale = gyr_scale
        self.tau_acc = tau_acc
        self._init_consts(**self._consts(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest,
                                         rest_gyr, rest_acc, rest_time, tau_rest, latency,
                                         tau_mag, mag_norm, mag_dip, tau_mag_ref,
                                         mag_new_time, mag_hold, mag_learn, mag_noise,
                                         mag_lag, mag_offset_min, gyr_scale, profile))

    def _init_consts(self, imu, **k):
        # imf_robust_ahrs_q_init_consts (the ranges were checked by _params)
        RobustIMUQ._init_consts(self, **imu)
        self.km = dict(k, imu=self.k)     # B4 reads the IMU's as k->imu
        self.u = [0, 0, 0]
        self.rn = self.rh = self.rz = self.cn = self.ch = self.cz = 0
        self.n_ok = self.n_dist = self.n_cand = 0
        self.hi, self.P, self.so = [0] * 6, [0] * 21, [0, 0, 0]
        self.m_n2 = self.m_im = self.m_is = self.m_nm = self.m_ns = 0
        self.m_ew = self.m_d2 = self.m_qo = self.m_axis = self.m_bad = 0
        self.m_var = fq.Q30_ONE
        self.mn = [0, 0, 0, 0]

    @staticmethod
    def _offset_counts(offset):
        # (x, y, z) int16 counts, or ValueError naming the component
        try:
            values = tuple(offset)
        except TypeError:
            raise ValueError(f"mag offset: expected (x, y, z) in counts, got {offset!r}") from None
        if len(values) != 3:
            raise ValueError(f"mag offset: expected 3 values (x, y, z), got {len(values)}")
        out = []
        for n, v in zip("xyz", values):
            try:
                ok = (not isinstance(v, (bool, str)) and float(v).is_integer()
                      and -32768 <= v <= 32767)
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(f"mag offset {n}: expected an int16 count (the offset in the "
                                 f"magnetometer's counts, as its readings), got {v!r}")
            out.append(int(v))
        return tuple(out)

    def set_mag_offset(self, offset):
        """imf_robust_ahrs_q_set_mag_offset: the stored offset (hard iron), magnetometer
        counts (x, y, z) in the sensor frame, used from the next sample (B6 starts again from
        it). reset() clears it (as the C init does): set it again after a reset."""
        self.u = list(self._offset_counts(offset))
        self.so = list(self.u)
        self.m_n2 = 0                       # B6 starts again from it
        self.m_var = fq.Q30_ONE
        self.mn = [0, 0, 0, 0]

    def _get_state(self):
        return _words(self, IMU_LAYOUT + MAG_LAYOUT)

    def _set_state(self, v):
        _set_words(self, IMU_LAYOUT + MAG_LAYOUT, v)

    def _state_float(self, s):
        q30, q15 = 2.0 ** -30, 2.0 ** -15
        q26, q16 = 2.0 ** -26, 2.0 ** -16
        return (super()._state_float(s[:32]) + list(s[32:35])
                + [s[35] * q15, s[36] * q30, s[37] * q30, s[38] * q15, s[39] * q30,
                   s[40] * q30] + list(s[41:44]) + [v * q26 for v in s[44:50]]
                + [v * q30 for v in s[50:71]] + list(s[71:79]) + [s[79] * q16, s[80] * q16,
                                                                   s[81] * q30]
                + [v * q26 for v in s[82:86]] + list(s[86:]))

    def _update(self, gyr, acc, mag):
        # imf_robust_ahrs_q_update
        rq = [0] * 9
        if step(self.k, self, gyr, acc, rq):
            offset(self.km, self, gyr, mag)                      # B6
            magnetometer(self.km, self, mag, rq)
            output(self.k, self, gyr)
