"""The magnetometer blocks of RobustAHRS (B6 the offset learnt while turning, B4 the heading
with its disturbance detector): the twin of csrc/robust_mag.h, the same functions in the same
order with the same comments, mixed into reference/robust.py's filter class."""
import math

from ._math import qmul, qrotate

#: B6's covariance, the upper triangle of the 6x6 (h, o) by rows (C: P[21])
_PNAMES = tuple(f"p{i}{j}" for i in range(6) for j in range(i, 6))
#: index of P[i][j] in that triangle (C: robust_pi)
_PI = [[_PNAMES.index(f"p{min(i, j)}{max(i, j)}") for j in range(6)] for i in range(6)]

# B6's fixed model (C: ROBUST_MAG_*): walks of the field and of the offset per s, the
# offset's prior variance, the one-axis innovation gate, the offset's jump, the weight of
# the innovation's running mean and its consistent bound, the trusted standard deviation
_MAG_QH, _MAG_QO, _MAG_P0, _MAG_GATE, _MAG_JUMP, _MAG_EW, _MAG_MEAN, _MAG_TRUST = (
    1.0e-3, 1.0e-7, 1.0, 19.0, 0.05, 0.02, 8.0, 0.01)
# before it is trusted, while the offset in use is the stored one, an estimate below
# _MAG_EARLY replaces it when the reading's norm moves by more than _MAG_NORM2 (squared, of
# the field) with the stored one and _MAG_BETTER2 (squared) times more than with the
# estimate; a change of the offset in use beyond _MAG_RESET2 (squared) starts B4's reference
# again (C: ROBUST_MAG_EARLY, _NORM2, _BETTER2, _RESET2)
_MAG_EARLY, _MAG_NORM2, _MAG_BETTER2, _MAG_RESET2 = 0.05, 0.001, 4.0, 0.0025
# a reading beyond 8 times the field unit or below 1/8 of it is not used; after 1 s of them
# the estimator starts again (C: ROBUST_MAG_RANGE2, ROBUST_MAG_RESTART)
_MAG_RANGE2, _MAG_RESTART = 64.0, 1.0


class _RobustMag:
    """B6 and B4 of the Robust filters (reference/robust.py's _Robust mixes them in)."""

    def _offset_axis(self, mp, xs, i, h0, h1, h2, y, rr):
        """B6: the scalar update of axis i, measurement y with noise rr, H = (h0, h1, h2,
        e_i): state xs[6], covariance mp[21] (both updated); returns nu^2 / s."""
        R = self._R
        ph = [mp[_PI[j][0]] * h0 + mp[_PI[j][1]] * h1 + mp[_PI[j][2]] * h2
              + mp[_PI[j][3 + i]] for j in range(6)]
        sv = h0 * ph[0] + h1 * ph[1] + h2 * ph[2] + ph[3 + i] + rr
        nu = y - (h0 * xs[0] + h1 * xs[1] + h2 * xs[2] + xs[3 + i])
        ri = R(1.0) / sv
        kk = [R(0.0)] * 6
        for j in range(6):
            kk[j] = ph[j] * ri
            xs[j] = xs[j] + kk[j] * nu
        for j in range(6):
            for k in range(j, 6):
                mp[_PI[j][k]] = mp[_PI[j][k]] - ph[j] * kk[k]
        return nu * nu * ri

    def _offset_start(self, x, c, o2):
        # B6 start: field unit n0 = |m - u| (o2 = its square), h = R(s) (m - u) / n0 (c: the
        # rotated reading), o = u / n0, both with the prior variance; returns 1 / n0
        R = self._R
        x.m_n0 = R(math.sqrt(o2))
        inv = R(1.0) / x.m_n0
        for k in range(3):
            x.hi[k] = c[k] * inv
            x.hi[3 + k] = x.u[k] * inv
        x.P = [R(0.0)] * 21
        for k in range(6):
            x.P[_PI[k][k]] = R(_MAG_P0)
        x.m_ew = R(1.0)
        x.m_d2 = R(0.0)
        x.mn = [R(1.0), R(0.0), R(1.0), R(0.0)]
        return inv

    def _offset_update(self, x, i, c, y, g2):
        # B6 step: predict (the field and the offset walk; after an innovation beyond the gate
        # the offset may have jumped: a magnet attached or removed), then the measurement y
        # of axis i (c: column i of R(s)), its noise growing with the rate (timing mismatch)
        R = self._R
        for k in range(6):
            pb = x.P[_PI[k][k]] + R(_MAG_QH if k < 3 else _MAG_QO) * self.s.dt
            if k >= 3 and x.m_d2 > R(_MAG_GATE) and pb < R(_MAG_P0):
                pb = pb + R(_MAG_JUMP)
            x.P[_PI[k][k]] = pb
        rr = g2 * self.mag_lag2
        if not (rr <= R(1.0)):
            rr = R(1.0)
        rr = self.mag_noise2 + rr
        x.m_d2 = self._offset_axis(x.P, x.hi, i, c[0], c[1], c[2], y, rr)
        x.m_ew = x.m_ew + R(_MAG_EW) * (x.m_d2 - x.m_ew)
        x.m_axis = R(0.0) if i == 2 else x.m_axis + R(1.0)

    def _norm_lp(self, w, i, m, c, s, inv, k):
        # B6: the norm of the reading less an offset c s, in field units (inv = 1 / n0), into
        # a low-pass w[i] and the square of its deviation from that low-pass into a low-pass
        # w[i + 1] (gain k)
        n2 = self._R(0.0)
        for j in range(3):
            d = m[j] - c[j] * s
            n2 = n2 + d * d
        d = self._R(math.sqrt(n2)) * inv - w[i]
        w[i] = w[i] + k * d
        w[i + 1] = w[i + 1] + k * (d * d - w[i + 1])

    def _offset_norms(self, x, m, inv):
        # B6: how well the offset in use and the estimate each explain the reading's norm
        # (mn: with u, then with the estimate o n0), every third sample (the axis cycle) with
        # the gain of three samples of k_mag (over tau_mag): an offset wrong by d moves the
        # norm by up to d as the sensor turns, a right one leaves it still, whatever the
        # attitude
        R = self._R
        e = R(1.0) - self.k_mag
        k3 = R(1.0) - e * e * e
        self._norm_lp(x.mn, 0, m, x.u, R(1.0), inv, k3)
        self._norm_lp(x.mn, 2, m, x.hi[3:6], x.m_n0, inv, k3)

    def _offset_use(self, x, inv):
        # B6: the offset's standard deviation (its largest variance, never below 0). The
        # offset in use u: trusted and consistent, the stored offset while the estimate
        # agrees with it within mag_offset_min, else the estimate; consistent but not yet
        # trusted, the estimate when it is below MAG_EARLY and the reading's norm says the
        # stored offset, still in use, is wrong (MAG_NORM, MAG_BETTER) and the estimate
        # differs from it by more than mag_offset_min. A change beyond MAG_RESET starts B4's
        # reference again. inv: 1 / m_n0.
        R = self._R
        pb = R(0.0)
        for k in range(3, 6):
            if x.P[_PI[k][k]] > pb:
                pb = x.P[_PI[k][k]]
        x.m_std = R(math.sqrt(pb))
        if not (x.m_ew < R(_MAG_MEAN)):
            return
        trust = x.m_std < R(_MAG_TRUST)
        if not (trust or (x.m_std < R(_MAG_EARLY) and x.u[0] == x.so[0] and x.u[1] == x.so[1]
                          and x.u[2] == x.so[2] and x.t_dist == R(0.0)
                          and x.mn[1] > R(_MAG_NORM2) and R(_MAG_BETTER2) * x.mn[3] < x.mn[1])):
            return
        o2 = R(0.0)
        u = [R(0.0)] * 3
        for k in range(3):
            e = x.hi[3 + k] - x.so[k] * inv
            o2 = o2 + e * e
            u[k] = x.hi[3 + k] * x.m_n0
        if o2 < self.mag_min2:
            if not trust:
                return   # early: only an estimate that differs from the stored offset
            u = list(x.so)
        o2 = R(0.0)
        for k in range(3):
            d = u[k] - x.u[k]
            o2 = o2 + d * d
        if o2 * (inv * inv) > R(_MAG_RESET2):
            x.ref[0] = R(0.0)   # B4: a new reference from the next reading
        x.u = u

    def _offset(self, x, m, g2):
        """B6: one reading (m, not all zero) into the estimator of (h, o), m = R(s)^T h + o
        in units of m_n0, one axis per sample in turn; then the offset in use u. g2: |w|^2
        of this sample."""
        R = self._R
        i = 1 if x.m_axis == R(1.0) else 2 if x.m_axis == R(2.0) else 0
        start = x.m_n0 == R(0.0)
        if not self.s.mag_learn:
            return
        inv = R(0.0)
        if not start:
            # the reading against the field unit: absurd readings are not used
            inv = R(1.0) / x.m_n0
            o2 = R(0.0)
            for k in range(3):
                o2 = o2 + (m[k] * inv) * (m[k] * inv)
            if not (o2 <= R(_MAG_RANGE2) and o2 * R(_MAG_RANGE2) >= R(1.0)):
                x.m_bad = x.m_bad + self.s.dt
                if x.m_bad >= R(_MAG_RESTART):
                    x.m_n0 = R(0.0)
                    x.m_bad = R(0.0)
                return
            x.m_bad = R(0.0)
        e = [R(0.0)] * 3
        o2 = R(0.0)
        for k in range(3):
            if start:
                e[k] = m[k] - x.u[k]
                o2 = o2 + e[k] * e[k]
            else:
                e[k] = R(1.0) if k == i else R(0.0)
        if start and not (o2 >= self._min and o2 <= self._max):
            return
        # start: the field in I, R(s) (m - u); else column i of R(s), the row of axis i in
        # m = R^T h + o
        c = qrotate(R, x.s[0], x.s[1], x.s[2], x.s[3], e[0], e[1], e[2])
        if start:
            inv = self._offset_start(x, c, o2)
        else:
            self._offset_update(x, i, c, m[i] * inv, g2)
            if i == 2:
                self._offset_norms(x, m, inv)   # with the axis cycle: every third sample
        self._offset_use(x, inv)

    def _mag_test(self, fn, rf):
        # B4: the field (mn, hn, zn) in fn matches the reference (n, h, z) in rf: norm within
        # mag_norm n and dip within mag_dip (sine of the dip difference = zn h - hn z)
        dn = fn[0] - rf[0]
        dd = fn[2] * rf[1] - fn[1] * rf[2]
        tn = self.s.mag_norm * rf[0]
        return dn < tn and -dn < tn and dd < self.s.mag_dip and -dd < self.s.mag_dip

    def _field_used(self, x, fn):
        """B4: the disturbance detector. The field fn = (norm, cos dip, vertical part) is
        used (returns True) when it has matched the reference for mag_hold, and the
        reference learns it; otherwise (disturbed) a new field that stays the same for
        mag_new_time of motion becomes the reference."""
        R = self._R
        if x.ref[0] == R(0.0):
            # first reading: it is the reference
            x.ref = list(fn)
            x.cand = list(fn)
            x.t_ok = self.s.mag_hold
        match = self._mag_test(fn, x.ref)
        if match:
            x.t_ok = x.t_ok + self.s.dt
            if x.t_ok > self.s.mag_hold:
                x.t_ok = self.s.mag_hold
        else:
            x.t_ok = R(0.0)
        if match and x.t_ok >= self.s.mag_hold:
            x.t_dist = R(0.0)
            x.t_cand = R(0.0)
            k = self._gain(x.t, self.s.tau_mag_ref, self.k_ref)
            x.ref[0] = x.ref[0] + k * (fn[0] - x.ref[0])
            x.ref[1] = x.ref[1] + k * (fn[1] - x.ref[1])
            x.ref[2] = x.ref[2] + k * (fn[2] - x.ref[2])
            x.cand = list(fn)
            return True
        # disturbed (or not yet matching for mag_hold): no heading correction
        x.t_dist = x.t_dist + self.s.dt
        if self._mag_test(fn, x.cand):
            x.cand[0] = x.cand[0] + self.k_rest * (fn[0] - x.cand[0])
            x.cand[1] = x.cand[1] + self.k_rest * (fn[1] - x.cand[1])
            x.cand[2] = x.cand[2] + self.k_rest * (fn[2] - x.cand[2])
            if x.t_rest < self.s.rest_time:
                # only motion counts: at rest an attached magnet's field is steady too
                x.t_cand = x.t_cand + self.s.dt
            if x.t_cand >= self.s.mag_new_time:
                x.ref = list(x.cand)
                x.t_cand = R(0.0)
        else:
            x.cand = list(fn)
            x.t_cand = R(0.0)
        return False

    def _heading(self, x, me, mh):
        """B4: heading, the rotation about earth z that turns the horizontal field me (its
        norm mh) onto north (+x), (1 + cos, 0, 0, -sin) normalised, taken by the fraction k
        into c, and q = c (x) s; False rejects the sample."""
        R = self._R
        ih = R(1.0) / mh
        fw = R(1.0) + me[0] * ih
        fz = -(me[1] * ih)
        f2 = fw * fw + fz * fz
        if f2 >= self._min:
            fr = R(1.0) / R(math.sqrt(f2))
            fw = fw * fr
            fz = fz * fr
        else:
            fw = R(0.0)
            fz = R(1.0)
        k = self._gain(x.t, self.s.tau_mag, self.k_mag)
        zw = R(1.0) - k + k * fw
        zz = k * fz
        z2 = zw * zw + zz * zz
        if not (z2 >= self._min):
            return False
        zr = R(1.0) / R(math.sqrt(z2))
        zw = zw * zr
        zz = zz * zr
        # B3 from the heading: in motion, once the heading has started (tau_mag) and the
        # offset in use is trusted (B6: a heading through an unknown offset is no measure of
        # the bias); not for a calibrated gyro (gyr_bias_max 0: the fixed-point filters' B3)
        if (x.t >= self.s.tau_mag and self.inv_tau_bias > R(0.0)
                and self.s.gyr_bias_max > R(0.0) and not (x.t_rest >= self.s.rest_time)
                and (not self.s.mag_learn
                     or (x.m_std < R(_MAG_TRUST) and x.m_ew < R(_MAG_MEAN)))):
            self._bias_from(x, R(0.0), R(0.0), R(2.0) * zz, self._bias_gain(x, self.tau_h0))
        c = [zw * x.c[0] - zz * x.c[3],
             zw * x.c[1] - zz * x.c[2],
             zw * x.c[2] + zz * x.c[1],
             zw * x.c[3] + zz * x.c[0]]
        # z and c are unit quaternions: so are c and q = c (x) s, within a few roundings
        # (no normalisation: the levelling normalises c every sample; a non-finite c or q
        # fails the commit's check)
        x.c = c
        x.q = list(qmul(c[0], c[1], c[2], c[3], x.s[0], x.s[1], x.s[2], x.s[3]))
        return True

    def _magnetometer(self, x, m, g2):
        """B6 and B4: the magnetometer m (all zero: none); False rejects the sample.
        g2: |w|^2."""
        R = self._R
        if m[0] == R(0.0) and m[1] == R(0.0) and m[2] == R(0.0):
            return True   # no reading: gyro and accelerometer only
        self._offset(x, m, g2)   # B6, then the reading less the offset in use
        me = qrotate(R, x.q[0], x.q[1], x.q[2], x.q[3], m[0] - x.u[0], m[1] - x.u[1],
                     m[2] - x.u[2])
        h2 = me[0] * me[0] + me[1] * me[1]
        n2 = h2 + me[2] * me[2]
        if not (n2 >= self._min and n2 <= self._max):
            return True   # no usable reading: gyro and accelerometer only
        fn = [R(math.sqrt(n2)), R(0.0), R(0.0)]
        mh = R(math.sqrt(h2))
        inv = R(1.0) / fn[0]
        fn[1] = mh * inv
        fn[2] = me[2] * inv
        if not self._field_used(x, fn):
            return True   # B4: disturbed
        if not (h2 >= self._min):
            return True   # field vertical: no heading information
        return self._heading(x, me, mh)

    # ---- the output, the clock, the update --------------------------------------------
