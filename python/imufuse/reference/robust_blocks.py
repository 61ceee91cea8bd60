"""The gyroscope and accelerometer blocks of RobustIMU and RobustAHRS (B1 rest and the bias
at rest with the bias's get/set pair, the strapdown, B2 gravity, the levelling, B3 the bias in motion): the twin of
csrc/robust_blocks.h, the same functions in the same order with the same comments, mixed into
reference/robust.py's filter class (with robust_b3.py's B3 noise, which B2 and B3 call)."""
import math

from ..shared import checks as _checks
from ._math import qmul, qrotate


def _vector3(what, values, dtype):
    # (x, y, z) numbers finite in the precision dtype, or ValueError naming the component
    try:
        v = tuple(values)
    except TypeError:
        raise ValueError(f"{what}: expected (x, y, z), got {values!r}") from None
    if len(v) != 3:
        raise ValueError(f"{what}: expected 3 values (x, y, z), got {len(v)}")
    return tuple(_checks.check_real_in(f"{what} {n}", c, dtype) for n, c in zip("xyz", v))


class _RobustBlocks:
    """B1-B3 of the Robust filters (reference/robust.py's _Robust mixes them in)."""

    def _acc_reading(self, x, a, first):
        # the accelerometer reading a is one: not all zero (no reading: gyro only), and
        # within 100 times the gravity estimate (beyond, a shock or a hostile value that
        # says nothing about gravity)
        R = self._R
        if a[0] == R(0.0) and a[1] == R(0.0) and a[2] == R(0.0):
            return False
        if first:
            return True
        f2 = x.f[0] * x.f[0] + x.f[1] * x.f[1] + x.f[2] * x.f[2]
        return a[0] * a[0] + a[1] * a[1] + a[2] * a[2] <= R(1.0e4) * f2

    def _bias_clip(self, b):
        # the bias within the part's range, per axis (gyr_bias_max; 0: no bound)
        m = self.s.gyr_bias_max
        if m > self._R(0.0):
            for i in range(3):
                if b[i] > m:
                    b[i] = m
                elif b[i] < -m:
                    b[i] = -m

    @staticmethod
    def _off2(v, b):
        # |v - b|^2 (robust.c's helpers)
        x, y, z = v[0] - b[0], v[1] - b[1], v[2] - b[2]
        return x * x + y * y + z * z

    def _rest_mag(self, x, m, k):
        """B1 with a magnetometer: at rest the field in the sensor frame is steady, and so is
        the rate (the bias alone). A turn about the vertical, which the accelerometer does not
        see and a gyro of unknown bias cannot tell from its bias, turns the field's horizontal
        part (across the low-passed gravity la): the low-passed field lm must not have turned
        since the rest window began (l0) by more than rest_gyr allows over the window
        (t_rest), beyond the noise of the two low-passes (3 sigma of mag_noise at the gain k,
        each: a turn accumulates, the noise averages). At the turning point of a swing the
        field is as steady for a moment, but the rate changes: the low-passed rate lw must not
        have changed since the window began (w0) by rest_gyr. Updates lm; passes without a
        reading (all zero: an IMU) and with a disturbed field (B4)."""
        R = self._R
        la = x.la
        if m[0] == R(0.0) and m[1] == R(0.0) and m[2] == R(0.0):
            return True
        if x.lm[0] == R(0.0) and x.lm[1] == R(0.0) and x.lm[2] == R(0.0):
            x.lm = list(m)  # the first reading
            x.l0 = list(m)
        else:
            # a reading beyond 8 times the low-passed field or below an eighth of it (a shock,
            # a finite but absurd value) is no rest and is not low-passed: it would hold rest
            # off for as long as the low-pass takes to forget it (minutes for 1e30)
            n2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2]
            l2 = x.lm[0] * x.lm[0] + x.lm[1] * x.lm[1] + x.lm[2] * x.lm[2]
            if not (n2 <= R(64.0) * l2 and n2 * R(64.0) >= l2):
                return False
            x.lm[0] = x.lm[0] + k * (m[0] - x.lm[0])
            x.lm[1] = x.lm[1] + k * (m[1] - x.lm[1])
            x.lm[2] = x.lm[2] + k * (m[2] - x.lm[2])
        if x.t_dist > R(0.0):
            return True
        d = [x.lm[0] - x.l0[0], x.lm[1] - x.l0[1], x.lm[2] - x.l0[2]]
        a2 = la[0] * la[0] + la[1] * la[1] + la[2] * la[2]
        da = d[0] * la[0] + d[1] * la[1] + d[2] * la[2]
        ma = x.lm[0] * la[0] + x.lm[1] * la[1] + x.lm[2] * la[2]
        m2 = x.lm[0] * x.lm[0] + x.lm[1] * x.lm[1] + x.lm[2] * x.lm[2]
        # horizontal parts times a2: |d_h|^2 a2 and |lm_h|^2 a2
        d2 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * a2 - da * da
        h2 = m2 * a2 - ma * ma
        r = self.s.rest_gyr * x.t_rest
        return (d2 <= r * r * h2 + R(18.0) * self.mag_noise2 * k * (m2 * a2)
                and self._off2(x.lw, x.w0) < self.rest_gyr2)

    def _rest(self, x, g, a, m, has_acc):
        """B1: rest detection from low-passes of gyro and accelerometer in the sensor frame,
        and the bias observed at rest (Eq. 3.1: b_k = b_{k-1}). The rates are compared after
        the bias estimate is taken off, within rest_gyr plus what is still unknown of the
        bias (bu: at the start any bias up to gyr_bias_max per axis passes). Returns (rest,
        w2: the low-passed rate squared, B2's process noise). m: the magnetometer (all zero:
        none), whose field must be steady too (_rest_mag)."""
        R = self._R
        k = self._gain(x.t, self.s.tau_rest, self.k_rest)
        win = self.rest_gyr2 + self.bias_var0 * (x.bu * x.bu)
        # the bias taken off; gyr_bias_max 0: the raw rates (the fixed-point filters' B1)
        bb = x.b if self.s.gyr_bias_max > R(0.0) else (R(0.0), R(0.0), R(0.0))
        x.lw[0] = x.lw[0] + k * (g[0] - x.lw[0])
        x.lw[1] = x.lw[1] + k * (g[1] - x.lw[1])
        x.lw[2] = x.lw[2] + k * (g[2] - x.lw[2])
        if has_acc:
            x.la[0] = x.la[0] + k * (a[0] - x.la[0])
            x.la[1] = x.la[1] + k * (a[1] - x.la[1])
            x.la[2] = x.la[2] + k * (a[2] - x.la[2])
        w2 = x.lw[0] * x.lw[0] + x.lw[1] * x.lw[1] + x.lw[2] * x.lw[2]
        dx = a[0] - x.la[0]
        dy = a[1] - x.la[1]
        dz = a[2] - x.la[2]
        d2 = dx * dx + dy * dy + dz * dz
        a2 = x.la[0] * x.la[0] + x.la[1] * x.la[1] + x.la[2] * x.la[2]
        # the field steady too; gyr_bias_max 0: the fixed-point filters' B1 (no field)
        steady = self._rest_mag(x, m, k) if self.s.gyr_bias_max > R(0.0) else True
        if (has_acc and self._off2(x.lw, bb) < win and self._off2(g, bb) < win
                and d2 < self.rest_acc2 * a2 and steady):
            x.t_rest = x.t_rest + self.s.dt
            if x.t_rest > self.s.rest_time:
                x.t_rest = self.s.rest_time
        else:
            x.t_rest = R(0.0)
        if x.t_rest == R(0.0) or x.t < self.s.tau_rest:
            x.l0 = list(x.lm)  # the next window begins here
            x.w0 = list(x.lw)
        if not (x.t_rest >= self.s.rest_time):
            return False, w2
        # the bias's low-pass: tau_bias_rest once known, tau_rest while unknown (bu)
        kb = self.kb_rest + x.bu * (self.k_rest - self.kb_rest)
        x.b[0] = x.b[0] + kb * (g[0] - x.b[0])
        x.b[1] = x.b[1] + kb * (g[1] - x.b[1])
        x.b[2] = x.b[2] + kb * (g[2] - x.b[2])
        self._bias_clip(x.b)
        # B3's covariance learns with it: a rest counts as (1 - bu) tau_bias of motion (as
        # _bias_gain), so its information 1 / P grows from tau_p + (1 - bu) tau_bias by
        # kb bu tau_bias (in units of 1 / tau_p)
        pr = kb * x.bu * self.s.tau_bias * self.inv_tau_p
        pr = R(1.0) + pr / (R(1.0) + (R(1.0) - x.bu) * self.s.tau_bias * self.inv_tau_p)
        for i in range(6):
            x.bp[i] = x.bp[i] / pr
        x.bu = x.bu - kb * x.bu
        # B2 at rest: the accelerometer is gravity, so B1's low-pass of it, in I, is B2's
        # gravity and the velocity is 0 (an uncalibrated gyro's drift before the rest taken
        # back at once); not for a calibrated gyro (gyr_bias_max 0)
        if self.s.gyr_bias_max > R(0.0):
            x.f = list(qrotate(R, x.s[0], x.s[1], x.s[2], x.s[3], x.la[0], x.la[1], x.la[2]))
            x.v = [R(0.0), R(0.0), R(0.0)]
        return True, w2

    # imf_robust_get_gyr_bias / _set_gyr_bias
    def get_gyr_bias(self):
        """B1/B3: ((x, y, z) the gyro bias in use, rad/s, sensor frame; how unknown it still
        is: 1 until learnt, at rest for a few tau_bias_rest or in motion for tau_bias, 0
        once learnt). Store it at power-down and give it back with set_gyr_bias."""
        return tuple(float(v) for v in self.x.b), float(self.x.bu)

    def set_gyr_bias(self, bias):
        """B1/B3: a known gyro bias (x, y, z; rad/s, sensor frame: one stored with
        get_gyr_bias, or the "b" of a calibration file, imufuse.calibration.gyr_bias): the
        bias starts from it as learnt (the rest test uses rest_gyr around it, B3 learns with
        tau_bias). Each component finite and within +-gyr_bias_max (when not 0)."""
        R = self._R
        self.x.b = [R(v) for v in self._gyr_bias3(bias, self.dtype, float(self.s.gyr_bias_max))]
        self.x.bu = R(0.0)
        # B3: as learnt at the bound of its noise (an = 1: steady state 1 / tau_bias; a smooth
        # motion's smaller an learns it tighter)
        self.x.bp = [self.inv_tau_bias, R(0.0), R(0.0), self.inv_tau_bias, R(0.0),
                     self.inv_tau_bias]

    @staticmethod
    def _gyr_bias3(bias, dtype, bias_max):
        # (x, y, z) finite in the precision dtype and within +-bias_max (rad/s; 0: any), or
        # ValueError naming the component
        b = _vector3("gyr bias", bias, dtype)
        for n, v in zip("xyz", b):
            if bias_max > 0.0 and not abs(float(v)) <= bias_max:
                raise ValueError(f"gyr bias {n}: {float(v)!r} rad/s is beyond gyr_bias_max "
                                 f"({math.degrees(bias_max):g} deg/s): check the unit (rad/s) "
                                 "or raise gyr_bias_max")
        return b

    def _strapdown(self, x, g):
        # strapdown: s = s (x) exp(1/2 (w - b) dt)
        s = [self._R(0.0)] * 4
        if not self._turn_by(s, x.s, g, x.b, self.s.dt):
            return False
        x.s = s
        return True

    def _axes(self, q):
        # R(q)'s columns (the sensor axes turned by q), from the products of q's components:
        # the matrix, not three rotations of the axes (robust.c's helpers)
        one, two = self._R(1.0), self._R(2.0)
        xx, yy, zz = q[1] * q[1], q[2] * q[2], q[3] * q[3]
        xy, xz, yz = q[1] * q[2], q[1] * q[3], q[2] * q[3]
        wx, wy, wz = q[0] * q[1], q[0] * q[2], q[0] * q[3]
        return [one - two * (yy + zz), two * (xy + wz), two * (xz - wy),
                two * (xy - wz), one - two * (xx + zz), two * (yz + wx),
                two * (xz + wy), two * (yz - wx), one - two * (xx + yy)]

    def _rotate(self, q, v):
        # R(q) v (the C out of line: B3 turns four vectors per sample, one copy of the
        # rotation; robust.c's helpers)
        return qrotate(self._R, q[0], q[1], q[2], q[3], v[0], v[1], v[2])

    def _turn_lp(self, d, v, u, o, kg, kv):
        # B2's model of the bias (for B3), len(u) values: the strapdown turns I through the
        # bias estimate by u dt per sample (u: R(s) b, or R(s) for its dependence on b),
        # gravity in I turns with it, and B2's gravity follows that turn through its
        # low-pass, whose rate the levelling corrects. d: the summed turn less its low-pass,
        # v: the velocity-like state, through the same Kalman gains as gravity (kg, kv); o:
        # the low-pass's rate this sample
        dt = self.s.dt
        for j in range(len(u)):
            du = u[j] * dt
            vp = v[j] + dt * (d[j] + du)
            o[j] = -(kg * vp) * self.r_d
            d[j] = d[j] + du + kg * vp
            v[j] = vp - kv * vp

    def _gravity(self, x, a, first, has_acc, w2, hb, hr):
        # B2: gravity in the inertial frame, a Kalman filter of (v, f) per axis fed with the
        # accelerometer in that frame; from the first sample (B5). With gyr_bias_max > 0
        # also B2's model of the bias (_turn_lp): hb, the rate of its low-pass of R(s) b,
        # and hr, of R(s) (columns), both in I; 0 when gravity is not updated.
        R = self._R
        dt = self.s.dt
        ai = qrotate(R, x.s[0], x.s[1], x.s[2], x.s[3], a[0], a[1], a[2])
        self._acc_noise(x, ai, first, has_acc)   # B3's noise, before the update
        if first or not has_acc or not self.s.gyr_bias_max > R(0.0):
            # no rate of B2's model this sample
            hr[:] = [R(0.0)] * 9
            hb[:] = [R(0.0)] * 3
        if first:
            # B3: no turn yet (gravity is the first sample's)
            x.dr = [R(0.0)] * 9
            x.vr = [R(0.0)] * 9
            x.db = [R(0.0)] * 3
            x.vb = [R(0.0)] * 3
            # B5: gravity from the first sample
            x.f = list(ai)
            x.v = [R(0.0), R(0.0), R(0.0)]
            x.pvv = R(0.0)
            x.pvg = R(0.0)
            x.pgg = self.pgg0
            return
        if not has_acc:
            return
        # predict: v' = a - g, g' = 0 (+ process noise growing with the rotation rate)
        x.v[0] = x.v[0] + dt * (ai[0] - x.f[0])
        x.v[1] = x.v[1] + dt * (ai[1] - x.f[1])
        x.v[2] = x.v[2] + dt * (ai[2] - x.f[2])
        # (w / rate_ref)^2 capped at 10^4 (100 rate_ref: beyond any gyro's range), so
        # that hostile rates cannot blow the covariance up. While the bias is still unknown,
        # its error sigma_b (the error of a running mean after (1 - bu) tau_bias of learning,
        # at most bu gyr_bias_max; the part's range gyr_bias_max at first) turns I as a
        # rotation 60 times faster does through a scale error of 1/60: it adds (60 sigma_b)^2
        # to w^2
        rr = w2
        if x.bu > R(0.0):
            ub = self.tau_b0 / (self.tau_b0 + (R(1.0) - x.bu) * self.s.tau_bias)
            if x.bu < ub:
                ub = x.bu   # learnt at rest (or B3 off): what is left of it
            rr = rr + self.bias_w2 * (ub * ub)
        rr = rr * self.inv_rate_ref2
        if not (rr <= R(1.0e4)):
            rr = R(1.0e4)
        qg = self.qg_dt + self.qg_dt * rr
        pvv = x.pvv - self.two_dt * x.pvg + self.dt2 * x.pgg
        pvg = x.pvg - dt * x.pgg
        pgg = x.pgg + qg
        # update with the pseudo-measurement v = 0 (noise 1 / dt per sample)
        inv = R(1.0) / (pvv + self.r_d)
        kv = pvv * inv
        kg = pvg * inv
        x.f[0] = x.f[0] - kg * x.v[0]
        x.f[1] = x.f[1] - kg * x.v[1]
        x.f[2] = x.f[2] - kg * x.v[2]
        x.v[0] = x.v[0] - kv * x.v[0]
        x.v[1] = x.v[1] - kv * x.v[1]
        x.v[2] = x.v[2] - kv * x.v[2]
        x.pgg = pgg - kg * pvg
        x.pvg = pvg - kv * pvg
        x.pvv = pvv - kv * pvv
        if self.s.gyr_bias_max > R(0.0):
            ri = self._axes(x.s)  # R(s), then R(s) b from its columns
            rb = [ri[j] * x.b[0] + ri[3 + j] * x.b[1] + ri[6 + j] * x.b[2] for j in range(3)]
            self._turn_lp(x.db, x.vb, rb, hb, kg, kv)
            self._turn_lp(x.dr, x.vr, ri, hr, kg, kv)

    def _level(self, x, r):
        # levelling: the smallest rotation r that turns the gravity estimate onto earth z,
        # into the correction c, and q = c (x) s; False rejects the sample
        R = self._R
        ge = qrotate(R, x.c[0], x.c[1], x.c[2], x.c[3], x.f[0], x.f[1], x.f[2])
        gn = R(math.sqrt(ge[0] * ge[0] + ge[1] * ge[1] + ge[2] * ge[2]))
        r[0] = gn + ge[2]
        r[1] = ge[1]
        r[2] = -ge[0]
        r[3] = R(0.0)
        if not self._norm4(r):
            # gravity straight down (upside down, r = 0): any half turn about a horizontal
            # axis is a smallest rotation; about x. Otherwise (not finite) reject.
            if not (gn > R(0.0) and gn <= self._real_max):
                return False
            r[0] = R(0.0)
            r[1] = R(1.0)
            r[2] = R(0.0)
        c = [r[0] * x.c[0] - r[1] * x.c[1] - r[2] * x.c[2],
             r[0] * x.c[1] + r[1] * x.c[0] + r[2] * x.c[3],
             r[0] * x.c[2] - r[1] * x.c[3] + r[2] * x.c[0],
             r[0] * x.c[3] + r[1] * x.c[2] - r[2] * x.c[1]]
        if not self._norm4(c):
            return False
        x.c = c
        # c and s are unit quaternions: so is their product, within a few roundings (no
        # normalisation; a non-finite q fails the commit's check)
        x.q = list(qmul(c[0], c[1], c[2], c[3], x.s[0], x.s[1], x.s[2], x.s[3]))
        return True

    def _turn_div(self, x):
        """How much less a correction says of the bias while the sensor turns at w - b: d^2,
        with d = 1 + (|w - b| / rate_ref)^2. Two errors grow alike with the rate: B2's gravity
        is less certain (its process noise grows by d), so the correction is noisier by d;
        and the gyro's scale and alignment errors add a false bias s |w - b| (s = 1/60, B2's
        scale error, as large as B2's own noise at rate_ref) that a running mean does not
        average away while a rotation lasts, so of the rest only 1 / d is bias."""
        d = self._R(1.0) + self._off2(x.lw, x.b) * self.inv_rate_ref2
        return d * d

    def _bias_gain(self, x, tau0):
        """B3's integral gain, 1/s: 1 / tau while the sensor turns slowly; while the bias is
        still unknown (bu > 0) tau is the time it has been learnt for, (1 - bu) tau_bias,
        from tau0 (the fastest damped loop, Eq. 3.12: 4 times the correction's time
        constant) up to tau_bias (a running mean), then tau_bias. Divided by _turn_div: while
        the sensor turns fast the corrections are mostly B2's noise and the gyro's scale and
        alignment errors, not its bias. gyr_bias_max 0 (a calibrated gyro): 1 / tau_bias."""
        R = self._R
        tau = self.s.tau_bias
        if not (self.s.gyr_bias_max > R(0.0)):
            return self.inv_tau_bias   # a calibrated gyro: 1 / tau_bias (the fixed-point B3)
        if x.bu > R(0.0):
            tm = (R(1.0) - x.bu) * self.s.tau_bias
            tau = tm if tm > tau0 else tau0
        return R(1.0) / (tau * self._turn_div(x))

    def _bias_from(self, x, cx, cy, cz, k):
        # the bias from a correction rotation (its rotation vector (cx, cy, cz) in the earth
        # frame, one sample) with the gain k: seen in the sensor frame it is minus the bias
        # error (Eq. 3.6)
        R = self._R
        e = qrotate(R, x.q[0], -x.q[1], -x.q[2], -x.q[3], cx, cy, cz)
        x.b[0] = x.b[0] - e[0] * k
        x.b[1] = x.b[1] - e[1] * k
        x.b[2] = x.b[2] - e[2] * k
        self._bias_clip(x.b)

    def _bias_row(self, x, h, y, w):
        # B3: one row of the bias's measurement, y = (h[0], h[3], h[6]) . b + noise of
        # variance w: the Kalman update of b and of its covariance bp
        p = x.bp
        ph0 = p[0] * h[0] + p[1] * h[3] + p[2] * h[6]
        ph1 = p[1] * h[0] + p[3] * h[3] + p[4] * h[6]
        ph2 = p[2] * h[0] + p[4] * h[3] + p[5] * h[6]
        ri = self._R(1.0) / (h[0] * ph0 + h[3] * ph1 + h[6] * ph2 + w)  # one division
        e = (y - (h[0] * x.b[0] + h[3] * x.b[1] + h[6] * x.b[2])) * ri
        x.b[0] = x.b[0] + ph0 * e
        x.b[1] = x.b[1] + ph1 * e
        x.b[2] = x.b[2] + ph2 * e
        k0 = ph0 * ri
        k1 = ph1 * ri
        k2 = ph2 * ri
        p[0] = p[0] - k0 * ph0
        p[1] = p[1] - k0 * ph1
        p[2] = p[2] - k0 * ph2
        p[3] = p[3] - k1 * ph1
        p[4] = p[4] - k1 * ph2
        p[5] = p[5] - k2 * ph2

    def _bias(self, x, r, rest, hb, hr):
        # B3: in motion, from the levelling. The correction is B2's low-pass of the
        # strapdown's turn by the bias error; B2's model of the bias (_gravity) low-passes
        # the turn by the estimate (hb) and by each sensor axis (hr) alike, so in the earth
        # frame (c) the low-pass of the turn by the true bias is y = c hb - 2 r / dt, and
        # y = H b_true with H the horizontal rows of c hr: a Kalman filter of b (covariance
        # bp: prior, random walk, _init_filter) with the noise d^2 an / dt per row (_turn_div,
        # _an), no loop to damp and no lag to wait for, and a bias turning with the sensor
        # faster than B2 follows is seen as small as it is. Each sample teaches bu by
        # dt / tau_bias, less while the sensor turns fast. gyr_bias_max 0: the integral of
        # the correction (Eq. 3.6, I_k = I_{k-1} + Ki dt e_k, Ki dt = 1 / tau_bias)
        R = self._R
        if not rest and x.t >= self.s.tau_acc and self.inv_tau_bias > R(0.0):
            if x.bu > R(0.0):
                # less learnt while the sensor turns fast (_bias_gain)
                x.bu = x.bu - self.ku_motion / self._turn_div(x)
                if x.bu < R(0.0):
                    x.bu = R(0.0)
            if not (self.s.gyr_bias_max > R(0.0)):
                self._bias_from(x, R(2.0) * r[1], R(2.0) * r[2], R(0.0),
                                self._bias_gain(x, self.tau_b0))
                return
            y = self._rotate(x.c, hb)
            h = []
            for i in range(0, 9, 3):
                h.extend(self._rotate(x.c, hr[i:i + 3]))
            k = self.qb * self.s.dt   # the random walk
            x.bp[0] = x.bp[0] + k
            x.bp[3] = x.bp[3] + k
            x.bp[5] = x.bp[5] + k
            k = self._turn_div(x) * self.r_d * self._an(x)
            self._bias_row(x, h, y[0] - R(2.0) * r[1] * self.r_d, k)
            self._bias_row(x, h[1:], y[1] - R(2.0) * r[2] * self.r_d, k)
            self._bias_clip(x.b)

    def _step(self, x, g, a, m):
        """Gyro (rad/s), accelerometer (and magnetometer m for B1's rest; all zero: none) of
        one sample through B1, the strapdown, B2, the levelling and B3, on the working state
        x; False rejects the sample."""
        first = x.t == self._R(0.0)
        has_acc = self._acc_reading(x, a, first)
        r = [self._R(0.0)] * 4
        hb = [self._R(0.0)] * 3
        hr = [self._R(0.0)] * 9
        if first and not has_acc:
            return False   # no start without an accelerometer reading
        rest, w2 = self._rest(x, g, a, m, has_acc)   # B1
        if not self._strapdown(x, g):
            return False
        self._gravity(x, a, first, has_acc, w2, hb, hr)   # B2
        if not self._level(x, r):
            return False
        self._bias(x, r, rest, hb, hr)   # B3
        return True

    # ---- magnetometer: B6, B4 ----------------------------------------------------------
