"""Fixed-point Mahony IMU filter: pure-Python twin of csrc/fixed/mahony_q.c,
line for line (Q formats in mahony_q.h)."""
from __future__ import annotations

from ..shared import checks as _checks
from . import _cint as ci
from . import fixed_quat as fq
from .fixed_base import FixedFilter, check_profile, check_scale, qconst



def carry_i(t, c, i):
    """imf_mahony_imu_q_carry_i: t + c[i] in q46 -> q38 (floor), the low 8 bits kept in c[i]."""
    u = ci.add_sat32(t, c[i])
    c[i] = u & 0xFF
    return u >> 8


class MahonyIMUQ(FixedFilter):
    """Mahony's filter in quaternion form (appendix), fixed point.

    MahonyIMUQ(dt, kp, ki, gyr_scale=rad/s per count, profile="32" | "8").
    State q0..q3 (q30), ix, iy, iz (0.5 I dt in q38) and cx, cy, cz (the
    remainder carried to the next sample: profile "32", of Ki dt e below q38,
    in [0, 2^8); profile "8", of the rate h, in [0, 2^16));
    state_float gives the unit quaternion, I in rad/s and c / 2^16.
    """
    kind = "imu"
    c_name = "imf_mahony_imu_q"
    state_names = ("q0", "q1", "q2", "q3", "ix", "iy", "iz", "cx", "cy", "cz")

    @staticmethod
    def _params(dt, kp=1.0, ki=0.0, *, gyr_scale, profile="32"):
        dt = _checks.check_dt(dt)
        kp = _checks.check_real("kp", kp, lo=0.0)
        ki = _checks.check_real("ki", ki, lo=0.0)
        gyr_scale = check_scale("gyr_scale", gyr_scale)
        qconst("gyr_scale*dt", 0.5 * gyr_scale * dt, 31, 61, nonzero=True)
        qconst("0.5*kp*dt", 0.5 * kp * dt, 16, 47)
        qconst("ki*dt^2", 0.5 * ki * dt * dt, 8, 54)
        return (dt, kp, ki, gyr_scale, check_profile(profile))

    @staticmethod
    def _consts(dt, kp, ki, gyr_scale, profile):
        # imf_mahony_imu_q_init: the constants from the double parameters
        return dict(kg=ci.qscale(0.5 * gyr_scale * dt), kp=ci.qscale(0.5 * kp * dt),
                    ki=ci.qscale(0.5 * ki * dt * dt), profile=profile)

    def _init(self, dt, kp, ki, gyr_scale, profile):
        self.dt = dt
        self._init_consts(**self._consts(dt, kp, ki, gyr_scale, profile))

    def _init_p8(self):
        """imf_mahony_imu_q_init_p8: the 8-bit profile's constants from kg, kp, ki, hs."""
        kp = self.kp
        hs = self.hs
        self.kg8 = ci.gain8(self.kg, 15 + hs)
        self.kp8 = ci.gain8(kp, hs)
        self.ki8 = ci.gain8(self.ki, 38 - 15)
        # kp rounded to q38 for e in q15: gain8's mantissa for the shift
        # kp.s - 7 >= 15 (kp.m 2, or kp.m rounded by kp.s - 23)
        self.kpi = ci.gain8(kp, 7)[0] if kp.s >= 22 else 0
        self.fast8 = (kp.s >= 22 and self.ki8[1] == 16 and self.kg8[1] == 16 and hs <= 6)

    def _init_consts(self, kg, kp, ki, profile):
        self.kg = kg
        self.kp = kp
        self.ki = ki
        self.hs = fq.rate_exponent(self.kg)
        self.q = [fq.Q30_ONE, 0, 0, 0]
        self.i = [0, 0, 0]
        self.c = [0, 0, 0]
        self._init_p8()
        self._update = self._update_p8 if profile == 8 else self._update_p32

    def _get_state(self):
        return self.q + self.i + self.c

    def _set_state(self, v):
        self.q, self.i, self.c = list(v[:4]), list(v[4:7]), list(v[7:])

    def _state_float(self, s):
        return ([v * 2.0 ** -30 for v in s[:4]] + [v * 2.0 ** -38 * 2.0 / self.dt for v in s[4:7]]
                + [v * 2.0 ** -16 for v in s[7:]])

    def _feedback_p32(self, qs, acc, h):
        """imf_mahony_imu_q_feedback_p32: appendix steps 2-6, h = 0.5 w' dt (q30)."""
        # step 2: normalise a
        a = fq.normalise_acc(acc)
        if a is None:
            return
        # step 3: d = 2 (q1 q3 - q0 q2, q0 q1 + q2 q3, q0^2 + q3^2 - 1/2), q15
        d = [ci.qn_to_q15s(qs[1] * qs[3] - qs[0] * qs[2], 29),
             ci.qn_to_q15s(qs[0] * qs[1] + qs[2] * qs[3], 29),
             ci.qn_to_q15s(qs[0] * qs[0] + qs[3] * qs[3] - 536870912, 29)]
        # step 4: e = a x d, q30
        e = [a[1] * d[2] - a[2] * d[1],
             a[2] * d[0] - a[0] * d[2],
             a[0] * d[1] - a[1] * d[0]]
        for i in range(3):
            if self.ki.s >= 31:
                # Ki dt e in q46, its 8 bits below q38 carried (imf_mahony_imu_q_carry_i)
                ip = carry_i(ci.mul_32x16_s(e[i], self.ki.m, self.ki.s - 16), self.c, i)
            else:
                ip = ci.scale32_s(e[i], self.ki, 30, 38)
            pp = ci.scale32_s(e[i], self.kp, 30, 30)
            # step 5: I_n = I_{n-1} + Ki dt e (as 0.5 I dt, q38)
            self.i[i] = ci.add_sat32(self.i[i], ip)
            # step 6: w' = w + Kp e + I_n (as 0.5 w' dt, q30)
            h[i] = ci.add_sat32(ci.add_sat32(h[i], pp), ci.rshr32(self.i[i], 8))

    def _feedback_p8(self, qs, acc, h):
        """imf_mahony_imu_q_feedback_p8: the same, 8-bit profile."""
        # step 2: normalise a (block-scaled, short inverse sqrt)
        a = fq.unit3_p8(acc)
        if a is None:
            return
        # step 3: d, q15
        d = [ci.qn_to_q15s(qs[1] * qs[3] - qs[0] * qs[2], 29),
             ci.qn_to_q15s(qs[0] * qs[1] + qs[2] * qs[3], 29),
             ci.qn_to_q15s(qs[0] * qs[0] + qs[3] * qs[3] - 536870912, 29)]
        # step 4: e = a x d, rounded to q15
        e15 = [ci.qn_to_q15s(a[1] * d[2] - a[2] * d[1], 30),
               ci.qn_to_q15s(a[2] * d[0] - a[0] * d[2], 30),
               ci.qn_to_q15s(a[0] * d[1] - a[1] * d[0], 30)]
        for i in range(3):
            if self.fast8:
                # steps 5, 6: Kp e + I summed in q38, rounded once to q(31+hs)
                ii = ci.add_sat32(self.i[i], ci.rshr32(e15[i] * self.ki8[0], 16))
                v = ci.add_sat32(ii, e15[i] * self.kpi)
                self.i[i] = ii
                h[i] = ci.add_sat32(h[i], fq.rshr_hs_p8(v, 7 - self.hs))  # shift in [1, 7]
            else:
                self.i[i] = ci.add_sat32(self.i[i], ci.gain8_mul(e15[i], self.ki8))
                h[i] = ci.add_sat32(ci.add_sat32(h[i], ci.gain8_mul(e15[i], self.kp8)),
                                    ci.rshr32(self.i[i], 23 - self.hs))

    def _update_p32(self, gyr, acc):
        qs = fq.snapshot(self.q)
        # step 1: gyro counts -> half angle per sample, q30
        h = [ci.scale16(g, self.kg, 30) for g in gyr]
        self._feedback_p32(qs, acc, h)
        # step 7: q += 0.5 q (x) w' dt
        dq = fq.rate_p32(qs, h)
        # step 8
        self.q = fq.add_normalise(self.q, dq)

    def _update_p8(self, gyr, acc):
        self.q, qs, d16 = fq.snapshot_norm_p8(self.q)
        # step 1: kg8 has the shift 16 for every kg init accepts (kg.s in
        # [31, 61], hs = kg.s - 31 clamped to [0, 15], so kg.s - 15 - hs >= 16):
        # gyr m is h in q(31+hs)
        if self.fast8:
            # steps 2-6 on h in q(31+hs), then h to q(15+hs) with the remainder
            # carried
            h = [g * self.kg8[0] for g in gyr]
            self._feedback_p8(qs, acc, h)
            h = [fq.carry_p8(h[i], self.c, i) for i in range(3)]
        else:
            # h rounded to q(15+hs); steps 2-6 add Kp e and I rounded
            h = [ci.rshr32(g * self.kg8[0], 16) for g in gyr]
            self._feedback_p8(qs, acc, h)
        # step 7
        dq = fq.rate_p8(qs, h, self.hs)
        self.q = fq.add_step_p8(self.q, dq, qs, d16)
