"""Fixed-point Madgwick IMU filter: pure-Python twin of
csrc/fixed/madgwick_q.c, line for line (Q formats in madgwick_q.h)."""
from __future__ import annotations

from ..shared import checks as _checks
from . import _cint as ci
from . import fixed_quat as fq
from .fixed_base import FixedFilter, check_profile, check_scale, qconst


def _bitlen32(v):
    """imf_bitlen32: number of bits of v >= 0, byte steps first."""
    n = 0
    if v >= 65536:
        v >>= 16
        n = 16
    if v >= 256:
        v >>= 8
        n += 8
    while v:
        v >>= 1
        n += 1
    return n


class MadgwickIMUQ(FixedFilter):
    """Madgwick's 6DOF IMU filter (appendix, simplified delta-s), fixed point.

    MadgwickIMUQ(dt, beta, gyr_scale=rad/s per count, profile="32" | "8").
    State q0..q3 in q30 and cx, cy, cz (profile "8": the rate's remainder
    carried to the next sample, in [0, 2^16)); state_float gives the unit
    quaternion and c / 2^16.
    """
    kind = "imu"
    c_name = "imf_madgwick_imu_q"
    state_names = ("q0", "q1", "q2", "q3", "cx", "cy", "cz")

    @staticmethod
    def _params(dt, beta=0.1, *, gyr_scale, profile="32"):
        dt = _checks.check_dt(dt)
        beta = _checks.check_real("beta", beta, lo=0.0)
        gyr_scale = check_scale("gyr_scale", gyr_scale)
        qconst("gyr_scale*dt", 0.5 * gyr_scale * dt, 31, 61, nonzero=True)
        qconst("beta*dt", beta * dt, 16, 46)
        return (dt, beta, gyr_scale, check_profile(profile))

    @staticmethod
    def _consts(dt, beta, gyr_scale, profile):
        # imf_madgwick_imu_q_init: the constants from the double parameters
        return dict(kg=ci.qscale(0.5 * gyr_scale * dt), kb=ci.qscale(beta * dt), profile=profile)

    def _init(self, dt, beta, gyr_scale, profile):
        self._init_consts(**self._consts(dt, beta, gyr_scale, profile))

    def _init_consts(self, kg, kb, profile):
        self.kg = kg
        self.kb = kb
        self.hs = fq.rate_exponent(self.kg)
        self.kg8 = ci.gain8(kg, 15 + self.hs)
        self.kbf = 0 if kb.s < 16 else ((kb.s - 16) // 8) * 8
        self.q = [fq.Q30_ONE, 0, 0, 0]
        self.c = [0, 0, 0]
        self._update = self._update_p8 if profile == 8 else self._update_p32

    def _get_state(self):
        return self.q + self.c

    def _set_state(self, v):
        self.q, self.c = list(v[:4]), list(v[4:])

    def _state_float(self, s):
        return [v * 2.0 ** -30 for v in s[:4]] + [v * 2.0 ** -16 for v in s[4:]]

    def _correct_p32(self, qs, acc, dq):
        """imf_madgwick_imu_q_correct_p32: appendix steps 2, 4, 5, 6."""
        # step 2: normalise a
        a = fq.normalise_acc(acc)
        if a is None:
            return
        # step 4 (simplified): s = delta-s / 2, q28
        w = qs[1] * qs[1] + qs[2] * qs[2]
        w15 = ci.qn_to_q15s(w, 30)

        def P2(x, y):
            return ci.rshr32(x * y, 2)

        def P1(x, y):
            return ci.rshr32(x * y, 1)
        add = ci.add_sat32
        s = [add(P1(w15, qs[0]), P2(qs[2], a[0]) - P2(qs[1], a[1])),
             add(P1(w15, qs[1]), -P2(qs[3], a[0]) - P2(qs[0], a[1]) + P1(qs[1], a[2])),
             add(P1(w15, qs[2]), P2(qs[0], a[0]) - P2(qs[3], a[1]) + P1(qs[2], a[2])),
             add(P1(w15, qs[3]), -P2(qs[1], a[0]) - P2(qs[2], a[1]))]
        # step 5: normalise s (power-of-two prescale, then inverse sqrt)
        m = max(abs(v) for v in s)
        if m == 0:
            return
        k = _bitlen32(m) - 15
        s15 = [ci.sat_q15s(ci.rshift_sat32(v, k)) for v in s]
        n2 = sum(v * v for v in s15)
        y, sh = ci.invsqrt_u32(n2)
        for i in range(4):
            u = ci.sat_q15s(ci.rshr32(s15[i] * y, sh - 15))
            # step 6: dq' = dq - beta dt * unit delta-s
            dq[i] = ci.sub_sat32(dq[i], ci.scale16(u, self.kb, 30 - 15))

    def _correct_p8(self, qs, acc, dq):
        # imf_madgwick_imu_q_correct_p8: s in q29, block scaling by left
        # shifts, step s15 * yk / 2^kbf
        a = fq.unit3_p8(acc)
        if a is None:
            return
        r, add = ci.rshr32, ci.add_sat32
        w15 = ci.qn_to_q15s(qs[1] * qs[1] + qs[2] * qs[2], 30)
        s = [add(w15 * qs[0], r(qs[2] * a[0] - qs[1] * a[1], 1)),
             add(w15 * qs[1] + qs[1] * a[2], r(-qs[3] * a[0] - qs[0] * a[1], 1)),
             add(w15 * qs[2] + qs[2] * a[2], r(qs[0] * a[0] - qs[3] * a[1], 1)),
             add(w15 * qs[3], r(-qs[1] * a[0] - qs[2] * a[1], 1))]
        m = 0
        for v in s:
            m |= abs(v)
        if m == 0:
            return
        if m >= 1 << 31:
            s15 = [ci.sat_q15s(r(v, 17)) for v in s]
        else:
            while m < 1 << 22:
                m <<= 8
                s = [v * 256 for v in s]
            while m < 1 << 30:
                m <<= 1
                s = [v + v for v in s]
            s15 = [ci.qn_to_q15s(v, 31) for v in s]
        n2 = sum(v * v for v in s15)
        y, e = ci.invsqrt8_u32(n2)
        yk = r(y * self.kb.m, self.kb.s + 1 - e - self.kbf)
        for i in range(4):
            dq[i] = ci.sub_sat32(dq[i], r(s15[i] * yk, self.kbf))

    def _update_p32(self, gyr, acc):
        qs = fq.snapshot(self.q)
        # step 3: dq = 0.5 q (x) w dt
        h = [ci.scale16(g, self.kg, 30) for g in gyr]
        dq = fq.rate_p32(qs, h)
        self._correct_p32(qs, acc, dq)
        # steps 7, 8
        self.q = fq.add_normalise(self.q, dq)

    def _update_p8(self, gyr, acc):
        self.q, qs, d16 = fq.snapshot_norm_p8(self.q)
        # step 3: h = 0.5 w dt in q(15+hs), from the product in q(31+hs) with
        # the remainder carried: kg8 has the shift 16 for every kg init accepts
        # (kg.s in [31, 61], hs = kg.s - 31 clamped to [0, 15], so
        # kg.s - 15 - hs >= 16)
        h = [fq.carry_p8(gyr[i] * self.kg8[0], self.c, i) for i in range(3)]
        dq = fq.rate_p8(qs, h, self.hs)
        self._correct_p8(qs, acc, dq)
        self.q = fq.add_step_p8(self.q, dq, qs, d16)
