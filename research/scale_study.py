"""Prototype (float64, not bit for bit): B3 extended by a per-axis gyro scale error s, the
gyro read as w = (1 + s) omega + b. The strapdown's error rate is b_err + s_err omega; B2's
model of it runs B2's recursion on R(s) b_eff (the turn by the whole estimate) and on
R(s) e_i omega_i (the regressor of s_i, the analogue of dr/vr for the bias), and one Kalman
filter of (b, s) takes the levelling's two rows. Measured on tests/test_robust_bias.py's
scale scenario and on the BROAD development trials.

    python research/scale_study.py [--broad]
"""
import sys

import numpy as np

from imufuse import reference

SCALE_SD = 0.03        # the scale error's prior, per axis (a datasheet's +-3 %)


class ScaledAHRS(reference.RobustAHRS):
    """RobustAHRS (float64 twin) with B3 extended by the gyro's scale error."""

    def __init__(self, dt, *a, scale_q=0.0, scale_max=0.1, turn_scale=True, adapt=False,
                 **kw):
        super().__init__(dt, *a, **kw)
        self._adapt = adapt
        self._la2 = self.s.rest_acc ** 2
        self._ratio = 1.0
        n = (self.s.rest_acc ** 2) / self.s.tau_acc    # B3's unit of noise density
        self._sc = np.zeros(3)
        self._ds = [0.0] * 9
        self._vs = [0.0] * 9
        self._hs = [0.0] * 9
        self._P = np.zeros((6, 6))
        self._P[3:, 3:] = np.eye(3) * SCALE_SD ** 2 / n
        self._scale_q = scale_q / n
        self._scale_max = scale_max
        self._turn_scale = turn_scale
        self._g = (0.0, 0.0, 0.0)
        self._P_init = False

    def _beff(self, x, g):
        # the whole estimated error rate: b + s (w - b)
        b = x.b
        return [b[i] + self._sc[i] * (g[i] - b[i]) for i in range(3)]

    def _strapdown(self, x, g):
        s = [0.0] * 4
        if not self._turn_by(s, x.s, g, self._beff(x, g), self.s.dt):
            return False
        x.s = s
        return True

    def _gravity(self, x, a, first, has_acc, w2, hb, hr):
        # as B2, with hb the low-pass of the turn by b_eff and hs of R(s) e_i omega_i
        saved_b = x.b
        g = self._g
        if self._adapt and has_acc and not first:
            # the linear acceleration B2 sees, low-passed over tau_acc (relative to gravity)
            ai = self._rotate(x.s, a)
            f2 = x.f[0] ** 2 + x.f[1] ** 2 + x.f[2] ** 2
            dev2 = sum((ai[i] - x.f[i]) ** 2 for i in range(3)) / f2
            k = self.s.dt / (self.s.tau_acc + self.s.dt)
            self._la2 = self._la2 + k * (dev2 - self._la2)
            self._ratio = min(self._la2 / self.s.rest_acc ** 2, 1.0)
        x.b = self._beff(x, g)
        try:
            super()._gravity(x, a, first, has_acc, w2, hb, hr)
        finally:
            x.b = saved_b
        self._hs = [0.0] * 9
        if first:
            self._ds = [0.0] * 9
            self._vs = [0.0] * 9
            return
        if not has_acc:
            return
        kg, kv = self._kgkv
        ri = []
        for j in range(3):
            wj = g[j] - x.b[j]
            e = [wj if i == j else 0.0 for i in range(3)]
            ri.extend(self._rotate(x.s, e))
        self._turn_lp(self._ds, self._vs, ri, self._hs, kg, kv)

    def _turn_lp(self, d, v, u, o, kg, kv):
        self._kgkv = (kg, kv)
        super()._turn_lp(d, v, u, o, kg, kv)

    def _turn_div(self, x):
        if self._turn_scale:
            return super()._turn_div(x)
        return 1.0

    def _bias(self, x, r, rest, hb, hr):
        if not self._P_init:
            self._P[:3, :3] = np.array([[x.bp[0], x.bp[1], x.bp[2]], [x.bp[1], x.bp[3], x.bp[4]],
                                        [x.bp[2], x.bp[4], x.bp[5]]])
            self._P_init = True
        # B1 (rest) divides bp by its information gain: take it over, and divide the cross
        # covariance of (b, s) alike (P stays positive: the scale is not seen at rest)
        if self._P[0, 0] > 0.0 and x.bp[0] != self._P[0, 0]:
            self._P[:3, 3:] *= x.bp[0] / self._P[0, 0]
            self._P[3:, :3] = self._P[:3, 3:].T
        self._P[:3, :3] = np.array([[x.bp[0], x.bp[1], x.bp[2]], [x.bp[1], x.bp[3], x.bp[4]],
                                    [x.bp[2], x.bp[4], x.bp[5]]])
        if not (not rest and x.t >= self.s.tau_acc and self.inv_tau_bias > 0.0):
            return
        if x.bu > 0.0:
            x.bu = x.bu - self.ku_motion / super()._turn_div(x)
            if x.bu < 0.0:
                x.bu = 0.0
        y = self._rotate(x.c, hb)
        h = []
        for i in range(0, 9, 3):
            h.extend(self._rotate(x.c, hr[i:i + 3]))
        hs = []
        for i in range(0, 9, 3):
            hs.extend(self._rotate(x.c, self._hs[i:i + 3]))
        P = self._P
        P[0, 0] += self.qb * self.s.dt
        P[1, 1] += self.qb * self.s.dt
        P[2, 2] += self.qb * self.s.dt
        for i in range(3, 6):
            P[i, i] += self._scale_q * self.s.dt
        w = self._turn_div(x) * self.r_d * self._ratio
        th = np.concatenate([np.asarray(x.b), self._sc])
        for row, yy in ((0, y[0] - 2.0 * r[1] * self.r_d), (1, y[1] - 2.0 * r[2] * self.r_d)):
            H = np.array([h[row], h[row + 3], h[row + 6], hs[row], hs[row + 3], hs[row + 6]])
            ph = P @ H
            sv = H @ ph + w
            # y measures the true (b, s); the model's own estimate is in hb already:
            # y = H_b b_true + H_s s_true -> innovation y - H th
            e = (yy - H @ th) / sv
            th = th + ph * e
            P -= np.outer(ph, ph) / sv
        th[3:] = np.clip(th[3:], -self._scale_max, self._scale_max)
        x.b = [float(v) for v in th[:3]]
        self._sc = th[3:].copy()
        self._bias_clip(x.b)
        x.bp[0], x.bp[1], x.bp[2] = P[0, 0], P[0, 1], P[0, 2]
        x.bp[3], x.bp[4], x.bp[5] = P[1, 1], P[1, 2], P[2, 2]

    def _step(self, x, g, a, m):
        self._g = g
        return super()._step(x, g, a, m)


def scenario_scale(**kw):
    from imufuse.sim import disturb as sd

    def rms(v):
        return float(np.sqrt(np.mean(np.square(v))))

    def errs(S, s, since):
        tilt, head = sd.errors(S[:, :4], s.q_true)
        m = s.moving & (np.arange(len(S)) * s.dt >= since)
        return rms(tilt[m]), rms(head[m])
    s = sd.scenario("bias_walk", rate=100.0, duration=120.0, rest=0.0, seed=8,
                    bias_deg=(4.0, -3.0, 5.0))
    c = sd.scenario("bias_walk", rate=100.0, duration=120.0, rest=0.0, seed=8)
    omega = s.gyr - s.bias
    out = []
    for cls, name in ((reference.RobustAHRS, "RobustAHRS"), (ScaledAHRS, "scaled")):
        k = kw if cls is ScaledAHRS else {}
        C = cls(c.dt, latency=0.0, **k).run(c.gyr, c.acc, c.mag)
        t0 = errs(C, c, 60.0)
        row = [name, "clean %.3f / %.3f" % t0]
        for scale in ((1.03, 0.97, 1.03), (0.97, 1.03, 0.97)):
            f = cls(s.dt, latency=0.0, **k)
            S = f.run(omega * np.asarray(scale) + s.bias, s.acc, s.mag)
            row.append("%s %.3f / %.3f" % (scale, *errs(S, s, 60.0)))
            if cls is ScaledAHRS:
                row.append("s=" + np.array2string(f._sc, precision=4))
        out.append(row)
        print(*row, flush=True)
    return out


if __name__ == "__main__":
    kw = {}
    for a in sys.argv[1:]:
        if "=" in a:
            k, v = a.split("=")
            kw[k] = v == "True" if v in ("True", "False") else float(v)
    scenario_scale(**kw)
