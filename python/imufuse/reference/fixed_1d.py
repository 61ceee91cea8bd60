"""Fixed-point single-axis filters: pure-Python twins of
csrc/fixed/filters_1d_q.c, line for line (Q formats in filters_1d_q.h)."""
from __future__ import annotations

from . import _cint as ci
from . import fixed_scale as fs
from .filters_1d import Complementary1D, Mahony1DBias
from .fixed_base import FixedFilter, check_profile, check_scale, qconst


def _kr(dt, gyr_scale, angle_scale):
    # imf_1d_q_kr_ok: kr != 0, s in [-14, 46]
    return qconst("gyr_scale*dt/angle_scale", gyr_scale * dt / angle_scale, -14, 46, nonzero=True)


def _kp_ki(dt, kp, ki):
    """imf_mahony1d_bias_q_init's ranges: Kp dt < 1 (a correction faster than one sample
    overshoots the measured angle) and Ki dt^2 < 2^-8 (the I loop's natural frequency sqrt(Ki)
    below 1/16 rad per sample), the gains the 16-bit products cover (q-scale s >= 15, 23)."""
    if not kp * dt < 1.0:
        raise ValueError(f"kp: kp*dt must be below 1 (a correction faster than one sample), "
                         f"got kp*dt={kp * dt!r}")
    if not ki * dt * dt < 2.0 ** -8:
        raise ValueError(f"ki: ki*dt^2 must be below 2^-8 (sqrt(ki)*dt below 1/16), "
                         f"got ki*dt^2={ki * dt * dt!r}")
    qconst("kp*dt", kp * dt, 15, 47)
    if ki > 0.0:                     # Ki = 0: the q-scale 0 2^-16, the gain 0
        qconst("ki*dt^2", ki * dt * dt, 23, 55)


class Complementary1DQ(FixedFilter):
    """Complementary filter, Eq. 2.2, in fixed point.

    Complementary1DQ(dt, alpha | T=..., gyr_scale=rad/s per count,
    angle_scale=rad per count, profile="32" | "8"). theta is q15 angle counts.
    Both profiles run the same 16x16->32 update.
    """
    c_name = "imf_complementary1d_q"
    state_names = ("theta",)

    @staticmethod
    def _params(dt, alpha=None, *, T=None, gyr_scale, angle_scale, profile="32"):
        dt, alpha = Complementary1D._params(dt, alpha, T=T)
        gyr_scale = check_scale("gyr_scale", gyr_scale)
        angle_scale = check_scale("angle_scale", angle_scale)
        _kr(dt, gyr_scale, angle_scale)
        qconst("1-alpha", 1.0 - alpha, 14, 47)
        return (dt, alpha, gyr_scale, angle_scale, check_profile(profile))

    @staticmethod
    def _consts(dt, alpha, gyr_scale, angle_scale, profile):
        # imf_complementary1d_q_init: the constants from the double parameters
        ka16 = fs.gain16(ci.qscale(1.0 - alpha), 15, 15)
        return dict(kr=ci.qscale(gyr_scale * dt / angle_scale), ka16_m=ka16[0], ka16_j=ka16[1])

    def _init(self, dt, alpha, gyr_scale, angle_scale, profile):
        self.angle_scale = angle_scale
        self._init_consts(**self._consts(dt, alpha, gyr_scale, angle_scale, profile))

    def _init_consts(self, kr, ka16_m, ka16_j):
        self.kr = kr
        self.ka16 = (ka16_m, ka16_j)
        self.theta = 0

    def _get_state(self):
        return [self.theta]

    def _set_state(self, v):
        (self.theta,) = v

    def _state_float(self, s):
        return [s[0] * 2.0 ** -15 * self.angle_scale]

    def _update(self, rate, angle):
        # Eq. 2.2 as Eq. 2.12: theta^- = theta + w dt; theta = theta^- + (1 - alpha)(a - theta^-)
        tp = ci.add_sat32(self.theta, fs.mulk16(rate, self.kr, 15))
        e = ci.sub_sat32(fs.i16_to_q15(angle), tp)
        # (1 - alpha) e; 1 - alpha >= 1 (ka16.j < 0) is exactly 1 (alpha in [0, 1])
        self.theta = ci.add_sat32(tp, fs.gain16_mul(e, self.ka16) if self.ka16[1] >= 0 else e)


class Mahony1DBiasQ(FixedFilter):
    """Mahony&Madgwick PI filter, Eq. 3.6 (Eq. 3.9 with integrate_first), in
    fixed point. theta: q15 angle counts; j = I dt in q23 angle counts."""
    c_name = "imf_mahony1d_bias_q"
    state_names = ("theta", "j")

    @staticmethod
    def _params(dt, kp, ki, integrate_first=False, *, gyr_scale, angle_scale, profile="32"):
        dt, kp, ki, integrate_first = Mahony1DBias._params(dt, kp, ki, integrate_first)
        gyr_scale = check_scale("gyr_scale", gyr_scale)
        angle_scale = check_scale("angle_scale", angle_scale)
        _kr(dt, gyr_scale, angle_scale)
        _kp_ki(dt, kp, ki)
        return (dt, kp, ki, integrate_first, gyr_scale, angle_scale, check_profile(profile))

    @staticmethod
    def _consts(dt, kp, ki, integrate_first, gyr_scale, angle_scale, profile):
        # imf_mahony1d_bias_q_init: the constants from the double parameters
        kiq = ci.qscale(ki * dt * dt)
        kp16 = fs.gain16(ci.qscale(kp * dt), 15, 15)
        ki16 = fs.gain16(kiq, 15, 23)
        # Ki = 0: the gain 0 (gain16 gives j = -1 for its q-scale 0 2^-16)
        return dict(kr=ci.qscale(gyr_scale * dt / angle_scale), kp16_m=kp16[0], kp16_j=kp16[1],
                    ki16_m=ki16[0], ki16_j=0 if kiq.m == 0 else ki16[1],
                    integrate_first=int(integrate_first != 0))

    def _init(self, dt, kp, ki, integrate_first, gyr_scale, angle_scale, profile):
        self.dt, self.angle_scale = dt, angle_scale
        self._init_consts(**self._consts(dt, kp, ki, integrate_first, gyr_scale, angle_scale,
                                         profile))

    def _init_consts(self, kr, kp16_m, kp16_j, ki16_m, ki16_j, integrate_first):
        self.kr = kr
        self.kp16 = (kp16_m, kp16_j)
        self.ki16 = (ki16_m, ki16_j)
        self.integrate_first = integrate_first != 0
        self.theta = 0
        self.j = 0

    def _get_state(self):
        return [self.theta, self.j]

    def _set_state(self, v):
        self.theta, self.j = v

    def _state_float(self, s):
        return [s[0] * 2.0 ** -15 * self.angle_scale, s[1] * 2.0 ** -23 * self.angle_scale / self.dt]

    def _update(self, rate, angle):
        # e_k = a_k - theta_{k-1} (q15 counts)
        e = ci.sub_sat32(fs.i16_to_q15(angle), self.theta)
        w = fs.mulk16(rate, self.kr, 15)  # w dt, q15 counts
        p = fs.gain16_mul(e, self.kp16)  # Kp dt e, q15 counts
        di = fs.gain16_mul(e, self.ki16)  # Ki dt^2 e, q23 counts
        # I_k = I_{k-1} + Ki dt e_k
        j = ci.add_sat32(self.j, di)
        # Eq. 3.6: theta_k = theta_{k-1} + (Kp e_k + I_k + w_k) dt.
        # Eq. 3.9 (integrate_first): theta_k = theta_{k-1} + (w_k + I_{k-1}) dt + Kp' dt e_k
        # (one angle step for both: only the I term it adds differs)
        jt = self.j if self.integrate_first else j
        self.theta = ci.add_sat32(ci.add_sat32(ci.add_sat32(self.theta, p), ci.rshr32(jt, 8)), w)
        self.j = j
