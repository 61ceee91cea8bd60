"""imufuse's recommended AHRS (docs/recommended-ahrs.md): pure-Python twin of
csrc/robust.c, line for line.

Longer than 500 lines because: it is the twin of robust.c (also one file), read side by
side with it, block by block.

Building blocks (article chapters 3 and 4 applied to real sensors):
  B1 gyro bias at rest: rest detected from gyro and accelerometer statistics,
     the bias is the low-passed gyro (chapter 3: the bias as a state);
  B2 gravity from the accelerometer in a quasi-inertial frame: a Kalman filter
     of (velocity, gravity) under "the velocity stays bounded", whose gravity
     uncertainty grows with the rotation rate; the attitude is aligned to it
     every sample;
  B3 gyro bias in motion: the integral of the inclination correction (chapter
     3.2/4.1: the I term of Mahony's PI), with tau_bias >= 4 tau_acc (Eq. 3.12);
  B4 magnetometer confined to heading, with a disturbance detector (field
     norm and dip against learned references) that rejects, then re-learns;
  B5 start from the first samples: every low-pass starts as a running mean;
  B6 the magnetometer's offset (hard iron) learnt while the sensor turns: a Kalman
     filter of the field in the inertial frame and the offset in the sensor frame.
"""
import math

from .. import _checks
from ._base import QUAT_NORM2_TOL, ReferenceFilter, isfinite
from ._math import qmul, qrotate

#: the largest finite number of each precision (IMF_REAL_MAX)
_REAL_MAX = {"float32": 3.4028234663852886e38, "float64": 1.7976931348623157e308}

# smallest normal and largest finite value of each precision (C: FLT_MIN, ...)
_LIMITS = {"float32": (1.1754943508222875e-38, 3.4028234663852886e+38),
           "float64": (2.2250738585072014e-308, 1.7976931348623157e+308)}

_DEG = math.pi / 180.0

#: B6's covariance, the upper triangle of the 6x6 (h, o) by rows (C: mp[21])
_PNAMES = tuple(f"p{i}{j}" for i in range(6) for j in range(i, 6))
#: index of P[i][j] in that triangle (C: robust_pi)
_PI = [[_PNAMES.index(f"p{min(i, j)}{max(i, j)}") for j in range(6)] for i in range(6)]
# B6's fixed model (C: ROBUST_MAG_*): walks of the field and of the offset per s, the
# offset's prior variance, the one-axis innovation gate, the offset's jump, the weight of
# the innovation's running mean and its consistent bound, the trusted standard deviation
_MAG_QH, _MAG_QO, _MAG_P0, _MAG_GATE, _MAG_JUMP, _MAG_EW, _MAG_MEAN, _MAG_TRUST = (
    1.0e-3, 1.0e-7, 1.0, 19.0, 0.05, 0.02, 8.0, 0.01)
# a reading beyond 8 times the field unit or below 1/8 of it is not used; after 1 s of them
# the estimator starts again (C: ROBUST_MAG_RANGE2, ROBUST_MAG_RESTART)
_MAG_RANGE2, _MAG_RESTART = 64.0, 1.0


class _Robust(ReferenceFilter):
    #: q0 is refused: the filter takes its tilt from the first sample's gravity and (AHRS)
    #: its heading from the first field, so a start attitude would be overwritten
    own_start = ("this filter starts from its first sample (its tilt from gravity; RobustAHRS "
                 "its heading from the field), which would overwrite a start attitude; leave "
                 "q0 out, or resume a saved filter with state= (its full state)")
    state_names = ("q0", "q1", "q2", "q3",      # estimate, sensor -> earth
                   "s0", "s1", "s2", "s3",      # strapdown: sensor -> inertial frame
                   "c0", "c1", "c2", "c3",      # correction: inertial -> earth frame
                   "fx", "fy", "fz",            # gravity (specific force) in the inertial frame
                   "vx", "vy", "vz",            # velocity-like state of B2, acc unit * s
                   "pvv", "pvg", "pgg",         # its covariance (shared by the three axes)
                   "bx", "by", "bz",            # gyro bias, rad/s
                   "lwx", "lwy", "lwz",         # low-passed gyro (rest detection), rad/s
                   "lax", "lay", "laz",         # low-passed accelerometer (rest detection)
                   "t", "t_rest",               # time since start (saturating), at rest, s
                   "rn", "rh", "rz",            # magnetic reference: norm, cos dip, -sin dip
                   "cn", "ch", "cz",            # candidate reference (a changed field)
                   "t_cand", "t_dist", "t_ok",  # candidate stable for, disturbed for,
                                                #   field matching the reference for, s
                   "hx", "hy", "hz",            # B6: field in the inertial frame, relative
                   "ix", "iy", "iz",            # offset estimate in the sensor frame, relative
                   *_PNAMES,                    # their covariance, upper triangle by rows
                   "ux", "uy", "uz",            # offset in use, field unit (B4 reads m - u)
                   "sx", "sy", "sz",            # stored offset (set_mag_offset), field unit
                   "m_n0",                      # the estimator's field unit (0: not started)
                   "m_ew", "m_d2",              # mean and last normalised innovation
                   "m_std",                     # the offset estimate's standard deviation
                   "m_axis",                    # the axis the next reading updates: 0, 1, 2
                   "m_bad")                     # absurd readings for, s (restart after 1 s)

    @staticmethod
    def _imu_params(tau_acc=2.5, rate_ref=100.0, tau_bias=100.0, tau_bias_rest=3.0,
                    rest_gyr=2.0, rest_acc=0.05, rest_time=1.5, tau_rest=0.5, latency=0.0):
        tau_acc = _checks.check_real("tau_acc", tau_acc, lo=0.0, lo_open=True)
        rate_ref = _checks.check_real("rate_ref", rate_ref, lo=0.0)
        tau_bias = _checks.check_real("tau_bias", tau_bias, lo=0.0)
        if 0.0 < tau_bias < 4.0 * tau_acc:
            raise ValueError("tau_bias: must be 0 (off) or >= 4 tau_acc (Eq. 3.12: "
                             f"a damped bias loop), got {tau_bias!r}")
        tau_bias_rest = _checks.check_real("tau_bias_rest", tau_bias_rest, lo=0.0, lo_open=True)
        rest_gyr = _checks.check_real("rest_gyr", rest_gyr, lo=0.0)
        rest_acc = _checks.check_real("rest_acc", rest_acc, lo=0.0)
        rest_time = _checks.check_real("rest_time", rest_time, lo=0.0)
        tau_rest = _checks.check_real("tau_rest", tau_rest, lo=0.0, lo_open=True)
        latency = _checks.check_real("latency", latency, lo=0.0, hi=0.1)
        # deg/s -> rad/s here, in double, for both backends
        return (tau_acc, rate_ref * _DEG, tau_bias, tau_bias_rest, rest_gyr * _DEG, rest_acc,
                rest_time, tau_rest, latency)

    @classmethod
    def _valid_state(cls, args, R, state):
        # state writes: the three quaternions unit, variances and times not negative
        names = cls.state_names
        for k in (0, 4, 8):
            n2 = float(sum(float(v) * float(v) for v in state[k:k + 4]))
            if not abs(n2 - 1.0) <= QUAT_NORM2_TOL:
                return (f"|{names[k][0]}|^2 = {n2!r}, must be within 1 +- "
                        f"{QUAT_NORM2_TOL}")
        for n in ("pvv", "pgg", "t", "t_rest", "rn", "cn", "t_cand", "t_dist", "t_ok",
                  "p00", "p11", "p22", "p33", "p44", "p55", "m_n0", "m_ew", "m_d2", "m_std",
                  "m_bad"):
            if float(state[names.index(n)]) < 0.0:
                return f"{n} = {float(state[names.index(n)])!r}, must not be negative"
        if float(state[names.index("m_axis")]) not in (0.0, 1.0, 2.0):
            return f"m_axis = {float(state[names.index('m_axis')])!r}, must be 0, 1 or 2"
        return None

    # imf_robust_init (shared settings of both filters)
    def _init_common(self, dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc,
                     rest_time, tau_rest, latency, tau_mag, mag_norm, mag_dip, tau_mag_ref,
                     mag_new_time, mag_hold, mag_learn, mag_noise, mag_lag, mag_offset_min):
        R = self._R
        lo, hi = _LIMITS[self.dtype]
        self._min, self._max = R(lo), R(hi)
        self._real_max = R(_REAL_MAX[self.dtype])
        self.tau_acc = R(tau_acc)
        self.tau_bias = R(tau_bias)
        self.tau_bias_rest = R(tau_bias_rest)
        self.tau_rest = R(tau_rest)
        self.latency = R(latency)
        self.tau_mag = R(tau_mag)
        self.tau_mag_ref = R(tau_mag_ref)
        # B2: gravity process noise q_g = (1 + |w|^2 / rate_ref^2) / tau_acc^4 per s, with the
        # velocity measurement noise 1 (any acc unit): the steady state is a second-order
        # low-pass with omega_0 = 1 / tau_acc and damping 1/sqrt(2) at rest
        ta2 = self.tau_acc * self.tau_acc
        self.qg0 = R(1.0) / (ta2 * ta2)
        self.pgg0 = R(1.0) / (ta2 * self.tau_acc)
        rr = R(rate_ref)
        self.inv_rate_ref2 = R(1.0) / (rr * rr) if rr > R(0.0) else R(0.0)
        self.inv_tau_bias = R(1.0) / self.tau_bias if self.tau_bias > R(0.0) else R(0.0)
        rg = R(rest_gyr)
        self.rest_gyr2 = rg * rg
        ra = R(rest_acc)
        self.rest_acc2 = ra * ra
        self.rest_time = R(rest_time)
        self.mag_norm = R(mag_norm)
        self.mag_dip = R(mag_dip)
        self.mag_new_time = R(mag_new_time)
        self.mag_hold = R(mag_hold)
        self.c48 = R(1.0) / R(48.0)
        self.mag_learn = int(mag_learn)
        self.mag_noise2 = R(mag_noise) * R(mag_noise)
        self.mag_lag2 = R(mag_lag) * R(mag_lag)
        self.mag_offset_min2 = R(mag_offset_min) * R(mag_offset_min)
        # t saturates at the longest start-up horizon
        tmax = self.tau_acc
        for v in (self.tau_rest, self.tau_mag, self.tau_mag_ref):
            if v > tmax:
                tmax = v
        self.t_max = tmax
        self._set_dt(R(dt))
        self.q0, self.q1, self.q2, self.q3 = R(1.0), R(0.0), R(0.0), R(0.0)
        self.s0, self.s1, self.s2, self.s3 = R(1.0), R(0.0), R(0.0), R(0.0)
        self.c0, self.c1, self.c2, self.c3 = R(1.0), R(0.0), R(0.0), R(0.0)
        self.fx, self.fy, self.fz = R(0.0), R(0.0), R(0.0)
        self.vx, self.vy, self.vz = R(0.0), R(0.0), R(0.0)
        self.pvv, self.pvg, self.pgg = R(0.0), R(0.0), R(0.0)
        self.bx, self.by, self.bz = R(0.0), R(0.0), R(0.0)
        self.lwx, self.lwy, self.lwz = R(0.0), R(0.0), R(0.0)
        self.lax, self.lay, self.laz = R(0.0), R(0.0), R(0.0)
        self.t, self.t_rest = R(0.0), R(0.0)
        self.rn, self.rh, self.rz = R(0.0), R(0.0), R(0.0)
        self.cn, self.ch, self.cz = R(0.0), R(0.0), R(0.0)
        self.t_cand, self.t_dist, self.t_ok = R(0.0), R(0.0), R(0.0)
        self._offset_clear()

    # B6 at init (robust_offset_clear): no offset stored, the estimator starts at the
    # first reading
    def _offset_clear(self):
        R = self._R
        self.hx, self.hy, self.hz = R(0.0), R(0.0), R(0.0)
        self.ix, self.iy, self.iz = R(0.0), R(0.0), R(0.0)
        for n in _PNAMES:
            setattr(self, n, R(0.0))
        self.ux, self.uy, self.uz = R(0.0), R(0.0), R(0.0)
        self.sx, self.sy, self.sz = R(0.0), R(0.0), R(0.0)
        self.m_n0 = R(0.0)
        self.m_ew = R(0.0)
        self.m_d2 = R(0.0)
        self.m_std = R(1.0)
        self.m_axis = R(0.0)
        self.m_bad = R(0.0)

    # imf_robust_*_set_dt: every dt-dependent constant, as init computes it
    def _set_dt(self, dt):
        R = self._R
        self.dt = dt
        self.two_dt = R(2.0) * dt
        self.dt2 = dt * dt
        self.r_d = R(1.0) / dt
        self.qg_dt = self.qg0 * dt
        self.k_rest = dt / (self.tau_rest + dt)
        self.kb_rest = dt / (self.tau_bias_rest + dt)
        self.k_mag = dt / (self.tau_mag + dt)
        self.k_ref = dt / (self.tau_mag_ref + dt)

    # imf_robust_*_set_attitude: start again from att (the next sample is the first)
    def _set_attitude(self, att):
        R = self._R
        self.q0, self.q1, self.q2, self.q3 = att.q
        self.s0, self.s1, self.s2, self.s3 = att.q
        self.c0, self.c1, self.c2, self.c3 = R(1.0), R(0.0), R(0.0), R(0.0)
        self.t = R(0.0)
        self.rn = R(0.0)
        self.m_n0 = R(0.0)

    # ---- helpers ------------------------------------------------------------

    def _norm4(self, w, x, y, z):
        # unit quaternion, or None when the normalisation fails (valid-attitude policy)
        R = self._R
        n2 = w * w + x * x + y * y + z * z
        if not (n2 >= self._min and n2 <= self._max):
            return None
        r = R(1.0) / R(math.sqrt(n2))
        return w * r, x * r, y * r, z * r

    def _gain(self, t, tau, k):
        # B5: a running mean until tau, then the low-pass gain k = dt / (tau + dt)
        if t < tau:
            return self.dt / (t + self.dt)
        return k

    # ---- the update ---------------------------------------------------------

    def _step(self, x, gx, gy, gz, ax, ay, az):
        """Gyro + accelerometer part. x: the working state (_State). Returns the
        inclination correction r (for the bias) or None to reject the sample."""
        R = self._R
        dt = self.dt
        first = x.t == R(0.0)
        # an all-zero accelerometer is no reading: gyro only (and no start without one)
        has_acc = not (ax == R(0.0) and ay == R(0.0) and az == R(0.0))
        if first and not has_acc:
            return None
        if has_acc and not first:
            # a reading beyond 100 times the gravity estimate (100 g) is a shock or a
            # hostile value: it says nothing about gravity, and is no reading
            f2 = x.fx * x.fx + x.fy * x.fy + x.fz * x.fz
            if not (ax * ax + ay * ay + az * az <= R(1.0e4) * f2):
                has_acc = False
        # B1: rest detection, low-passes of gyro and accelerometer in the sensor frame
        k = self._gain(x.t, self.tau_rest, self.k_rest)
        x.lwx = x.lwx + k * (gx - x.lwx)
        x.lwy = x.lwy + k * (gy - x.lwy)
        x.lwz = x.lwz + k * (gz - x.lwz)
        if has_acc:
            x.lax = x.lax + k * (ax - x.lax)
            x.lay = x.lay + k * (ay - x.lay)
            x.laz = x.laz + k * (az - x.laz)
        w2 = x.lwx * x.lwx + x.lwy * x.lwy + x.lwz * x.lwz
        g2 = gx * gx + gy * gy + gz * gz
        dx = ax - x.lax
        dy = ay - x.lay
        dz = az - x.laz
        d2 = dx * dx + dy * dy + dz * dz
        a2 = x.lax * x.lax + x.lay * x.lay + x.laz * x.laz
        if has_acc and w2 < self.rest_gyr2 and g2 < self.rest_gyr2 and d2 < self.rest_acc2 * a2:
            x.t_rest = x.t_rest + dt
            if x.t_rest > self.rest_time:
                x.t_rest = self.rest_time
        else:
            x.t_rest = R(0.0)
        rest = x.t_rest >= self.rest_time
        if rest:
            # Eq. 3.1: b_k = b_{k-1}, observed directly at rest
            x.bx = x.bx + self.kb_rest * (gx - x.bx)
            x.by = x.by + self.kb_rest * (gy - x.by)
            x.bz = x.bz + self.kb_rest * (gz - x.bz)
        # strapdown: s = s (x) exp(1/2 (w - b) dt), series to 4th order (no sin/cos)
        ox = (gx - x.bx) * dt
        oy = (gy - x.by) * dt
        oz = (gz - x.bz) * dt
        th2 = ox * ox + oy * oy + oz * oz
        cw = R(1.0) - th2 * R(0.125)
        sv = R(0.5) - th2 * self.c48
        s = qmul(x.s0, x.s1, x.s2, x.s3, cw, sv * ox, sv * oy, sv * oz)
        s = self._norm4(*s)
        if s is None:
            return None
        x.s0, x.s1, x.s2, x.s3 = s
        # B2: the accelerometer in the inertial frame
        aix, aiy, aiz = qrotate(R, *s, ax, ay, az)
        if first:
            # B5: gravity from the first sample
            x.fx, x.fy, x.fz = aix, aiy, aiz
            x.vx, x.vy, x.vz = R(0.0), R(0.0), R(0.0)
            x.pvv, x.pvg, x.pgg = R(0.0), R(0.0), self.pgg0
        elif has_acc:
            # predict: v' = a - g, g' = 0 (+ process noise growing with the rotation rate)
            x.vx = x.vx + dt * (aix - x.fx)
            x.vy = x.vy + dt * (aiy - x.fy)
            x.vz = x.vz + dt * (aiz - x.fz)
            # (w / rate_ref)^2 capped at 10^4 (100 rate_ref: beyond any gyro's range), so
            # that hostile rates cannot blow the covariance up
            rr = w2 * self.inv_rate_ref2
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
            x.fx = x.fx - kg * x.vx
            x.fy = x.fy - kg * x.vy
            x.fz = x.fz - kg * x.vz
            x.vx = x.vx - kv * x.vx
            x.vy = x.vy - kv * x.vy
            x.vz = x.vz - kv * x.vz
            x.pgg = pgg - kg * pvg
            x.pvg = pvg - kv * pvg
            x.pvv = pvv - kv * pvv
        # inclination: the smallest rotation r that turns the gravity estimate onto earth z
        gex, gey, gez = qrotate(R, x.c0, x.c1, x.c2, x.c3,
                                x.fx, x.fy, x.fz)
        gn = R(math.sqrt(gex * gex + gey * gey + gez * gez))
        r = self._norm4(gn + gez, gey, -gex, R(0.0))
        if r is None:
            # gravity straight down (upside down, r = 0): any half turn about a horizontal
            # axis is a smallest rotation; about x. Otherwise (not finite) reject.
            if not (gn > R(0.0) and gn <= self._real_max):
                return None
            r = (R(0.0), R(1.0), R(0.0), R(0.0))
        r0, r1, r2, _ = r
        c0, c1, c2, c3 = x.c0, x.c1, x.c2, x.c3
        c = self._norm4(r0 * c0 - r1 * c1 - r2 * c2,
                        r0 * c1 + r1 * c0 + r2 * c3,
                        r0 * c2 - r1 * c3 + r2 * c0,
                        r0 * c3 + r1 * c2 - r2 * c1)
        if c is None:
            return None
        x.c0, x.c1, x.c2, x.c3 = c
        q = self._norm4(*qmul(*c, *s))
        if q is None:
            return None
        x.q0, x.q1, x.q2, x.q3 = q
        # B3: the correction rate seen in the sensor frame is minus the bias error
        # (Eq. 3.6, I_k = I_{k-1} + Ki dt e_k, with Ki dt = 1 / tau_bias)
        if not rest and x.t >= self.tau_acc and self.inv_tau_bias > R(0.0):
            ex, ey, ez = qrotate(R, q[0], -q[1], -q[2], -q[3], R(2.0) * r1, R(2.0) * r2, R(0.0))
            x.bx = x.bx - ex * self.inv_tau_bias
            x.by = x.by - ey * self.inv_tau_bias
            x.bz = x.bz - ez * self.inv_tau_bias
        return True

    def _predict(self, x, gx, gy, gz):
        """The output: q = c (x) s, then predicted by the sensor's latency with the
        bias-corrected rate (q (x) exp(1/2 (w - b) latency), series as the strapdown).
        Returns False to reject the sample."""
        R = self._R
        if not (self.latency > R(0.0)):
            return True
        ox = (gx - x.bx) * self.latency
        oy = (gy - x.by) * self.latency
        oz = (gz - x.bz) * self.latency
        th2 = ox * ox + oy * oy + oz * oz
        cw = R(1.0) - th2 * R(0.125)
        sv = R(0.5) - th2 * self.c48
        q = self._norm4(*qmul(x.q0, x.q1, x.q2, x.q3,
                               cw, sv * ox, sv * oy, sv * oz))
        if q is None:
            return False
        x.q0, x.q1, x.q2, x.q3 = q
        return True

    def _mag_test(self, mn, hn, zn, n, h, z):
        # the field matches the reference (n, h, z): norm within mag_norm n and dip
        # within mag_dip (sin of the dip difference = zn h - hn z)
        dn = mn - n
        dd = zn * h - hn * z
        tn = self.mag_norm * n
        return dn < tn and -dn < tn and dd < self.mag_dip and -dd < self.mag_dip

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

    def _offset(self, x, mx, my, mz, g2):
        """B6: one reading (m, not all zero) into the estimator of (h, o), m = R(s)^T h + o
        in units of m_n0, one axis per sample in turn; then the offset in use u. g2: |w|^2
        of this sample."""
        R = self._R
        m = (mx, my, mz)
        i = 1 if x.m_axis == R(1.0) else 2 if x.m_axis == R(2.0) else 0
        start = x.m_n0 == R(0.0)
        if not self.mag_learn:
            return
        inv = R(0.0)
        if not start:
            # the reading against the field unit: absurd readings are not used
            inv = R(1.0) / x.m_n0
            o2 = R(0.0)
            for k in range(3):
                o2 = o2 + (m[k] * inv) * (m[k] * inv)
            if not (o2 <= R(_MAG_RANGE2) and o2 * R(_MAG_RANGE2) >= R(1.0)):
                x.m_bad = x.m_bad + self.dt
                if x.m_bad >= R(_MAG_RESTART):
                    x.m_n0 = R(0.0)
                    x.m_bad = R(0.0)
                return
            x.m_bad = R(0.0)
        u = [x.ux, x.uy, x.uz]
        e = [R(0.0)] * 3
        o2 = R(0.0)
        for k in range(3):
            if start:
                e[k] = m[k] - u[k]
                o2 = o2 + e[k] * e[k]
            else:
                e[k] = R(1.0) if k == i else R(0.0)
        if start and not (o2 >= self._min and o2 <= self._max):
            return
        # start: the field in I, R(s) (m - u); else column i of R(s), the row of axis i in
        # m = R^T h + o
        c = qrotate(R, x.s0, x.s1, x.s2, x.s3, e[0], e[1], e[2])
        if start:
            # field unit n0 = |m - u|: h = R(s) (m - u) / n0, o = u / n0, both with the
            # prior variance
            x.m_n0 = R(math.sqrt(o2))
            inv = R(1.0) / x.m_n0
            xs = [R(0.0)] * 6
            for k in range(3):
                xs[k] = c[k] * inv
                xs[3 + k] = u[k] * inv
            mp = [R(_MAG_P0) if n[1] == n[2] else R(0.0) for n in _PNAMES]
            x.m_ew = R(1.0)
            x.m_d2 = R(0.0)
        else:
            xs = [x.hx, x.hy, x.hz, x.ix, x.iy, x.iz]
            mp = [getattr(x, n) for n in _PNAMES]
            # predict: the field and the offset walk; after an innovation beyond the gate
            # the offset may have jumped (a magnet attached or removed)
            for k in range(6):
                pb = mp[_PI[k][k]] + R(_MAG_QH if k < 3 else _MAG_QO) * self.dt
                if k >= 3 and x.m_d2 > R(_MAG_GATE) and pb < R(_MAG_P0):
                    pb = pb + R(_MAG_JUMP)
                mp[_PI[k][k]] = pb
            # the measurement of axis i, relative; its noise grows with the rate (timing
            # mismatch)
            rr = g2 * self.mag_lag2
            if not (rr <= R(1.0)):
                rr = R(1.0)
            rr = self.mag_noise2 + rr
            x.m_d2 = self._offset_axis(mp, xs, i, c[0], c[1], c[2], m[i] * inv, rr)
            x.m_ew = x.m_ew + R(_MAG_EW) * (x.m_d2 - x.m_ew)
            x.m_axis = R(0.0) if i == 2 else x.m_axis + R(1.0)
        x.hx, x.hy, x.hz, x.ix, x.iy, x.iz = xs
        for n, v in zip(_PNAMES, mp):
            setattr(x, n, v)
        # the offset's standard deviation: its largest variance (never below 0)
        pb = R(0.0)
        for i in range(3, 6):
            if mp[_PI[i][i]] > pb:
                pb = mp[_PI[i][i]]
        x.m_std = R(math.sqrt(pb))
        # trusted and consistent: the stored offset while the estimate agrees with it
        # within mag_offset_min, else the estimate
        if x.m_std < R(_MAG_TRUST) and x.m_ew < R(_MAG_MEAN):
            st = (x.sx, x.sy, x.sz)
            o2 = R(0.0)
            for k in range(3):
                e[k] = xs[3 + k] - st[k] * inv
                o2 = o2 + e[k] * e[k]
                u[k] = xs[3 + k] * x.m_n0
            if o2 < self.mag_offset_min2:
                u = list(st)
            x.ux, x.uy, x.uz = u

    def _mag(self, x, mx, my, mz, g2):
        """B4: heading from the magnetometer. Returns False to reject the sample."""
        R = self._R
        dt = self.dt
        if mx == R(0.0) and my == R(0.0) and mz == R(0.0):
            return True   # no reading: gyro and accelerometer only
        # B6, then the reading less the offset in use
        self._offset(x, mx, my, mz, g2)
        mex, mey, mez = qrotate(R, x.q0, x.q1, x.q2, x.q3, mx - x.ux, my - x.uy, mz - x.uz)
        h2 = mex * mex + mey * mey
        n2 = h2 + mez * mez
        if not (n2 >= self._min and n2 <= self._max):
            return True   # no usable reading: gyro and accelerometer only
        mn = R(math.sqrt(n2))
        mh = R(math.sqrt(h2))
        inv = R(1.0) / mn
        hn = mh * inv
        zn = mez * inv
        if x.rn == R(0.0):
            # first reading: it is the reference
            x.rn, x.rh, x.rz = mn, hn, zn
            x.cn, x.ch, x.cz = mn, hn, zn
            x.t_ok = self.mag_hold
        match = self._mag_test(mn, hn, zn, x.rn, x.rh, x.rz)
        if match:
            x.t_ok = x.t_ok + dt
            if x.t_ok > self.mag_hold:
                x.t_ok = self.mag_hold
        else:
            x.t_ok = R(0.0)
        if match and x.t_ok >= self.mag_hold:
            x.t_dist = R(0.0)
            x.t_cand = R(0.0)
            k = self._gain(x.t, self.tau_mag_ref, self.k_ref)
            x.rn = x.rn + k * (mn - x.rn)
            x.rh = x.rh + k * (hn - x.rh)
            x.rz = x.rz + k * (zn - x.rz)
            x.cn, x.ch, x.cz = mn, hn, zn
            if not (h2 >= self._min):
                return True   # field vertical: no heading information
            # heading: the rotation about earth z that turns the horizontal field onto
            # north (+x), (1 + cos, 0, 0, -sin) normalised, taken by the fraction k
            ih = R(1.0) / mh
            fw = R(1.0) + mex * ih
            fz = -(mey * ih)
            f2 = fw * fw + fz * fz
            if f2 >= self._min:
                fr = R(1.0) / R(math.sqrt(f2))
                fw = fw * fr
                fz = fz * fr
            else:
                fw = R(0.0)
                fz = R(1.0)
            k = self._gain(x.t, self.tau_mag, self.k_mag)
            zw = R(1.0) - k + k * fw
            zz = k * fz
            z2 = zw * zw + zz * zz
            if not (z2 >= self._min):
                return False
            zr = R(1.0) / R(math.sqrt(z2))
            zw = zw * zr
            zz = zz * zr
            c0, c1, c2, c3 = x.c0, x.c1, x.c2, x.c3
            c = self._norm4(zw * c0 - zz * c3, zw * c1 - zz * c2,
                            zw * c2 + zz * c1, zw * c3 + zz * c0)
            if c is None:
                return False
            x.c0, x.c1, x.c2, x.c3 = c
            q = self._norm4(*qmul(*c, x.s0, x.s1, x.s2, x.s3))
            if q is None:
                return False
            x.q0, x.q1, x.q2, x.q3 = q
        else:
            # disturbed (or not yet matching for mag_hold): no heading correction; a new
            # field that stays the same for mag_new_time of motion becomes the reference
            x.t_dist = x.t_dist + dt
            if self._mag_test(mn, hn, zn, x.cn, x.ch, x.cz):
                x.cn = x.cn + self.k_rest * (mn - x.cn)
                x.ch = x.ch + self.k_rest * (hn - x.ch)
                x.cz = x.cz + self.k_rest * (zn - x.cz)
                if x.t_rest < self.rest_time:
                    # only motion counts: at rest an attached magnet's field is steady too
                    x.t_cand = x.t_cand + dt
                if x.t_cand >= self.mag_new_time:
                    x.rn, x.rh, x.rz = x.cn, x.ch, x.cz
                    x.t_cand = R(0.0)
            else:
                x.cn, x.ch, x.cz = mn, hn, zn
                x.t_cand = R(0.0)
        return True

    def _finish(self, x, gx, gy, gz):
        # the end of every update: the output prediction, then the clock
        if not self._predict(x, gx, gy, gz):
            return False
        self._advance(x)
        return True

    def _commit(self, x, ok, words):
        # keep the new state (its first `words`) only if every block accepted the sample
        # and left it finite (valid-attitude policy); the IMU, and the AHRS with B6 off,
        # never change B6's members (C: ROBUST_IMU_BYTES): only those before them
        names = self.state_names[:words]
        if not (ok and isfinite(*(getattr(x, n) for n in names))):
            self._skip()
            return
        for n in names:
            setattr(self, n, getattr(x, n))

    def _advance(self, x):
        # the clock of the start-up (saturating: no growth once every start is over)
        x.t = x.t + self.dt
        if x.t > self.t_max:
            x.t = self.t_max

    def _work(self):
        return _State(self)


class _State:
    """The working copy of the state (C: imf_robust_state_t x = self->x), its members
    named as in C: x.lwx is x->lwx."""
    __slots__ = _Robust.state_names

    def __init__(self, owner):
        for n in self.__slots__:
            setattr(self, n, getattr(owner, n))


class RobustIMU(_Robust):
    """imufuse's recommended attitude filter, gyroscope + accelerometer
    (docs/recommended-ahrs.md).

    RobustIMU(dt, tau_acc=2.5, rate_ref=100.0, tau_bias=100.0, tau_bias_rest=3.0,
    rest_gyr=2.0, rest_acc=0.05, rest_time=1.5, tau_rest=0.5, latency=0.0): dt in s;
    tau_acc (s)
    the gravity filter's time constant at rest; rate_ref (deg/s) the rotation rate at
    which its gravity uncertainty doubles (0: constant); tau_bias (s) the time
    constant of the bias estimation in motion (0: off, else >= 4 tau_acc);
    tau_bias_rest (s) that of the bias at rest; rest_gyr (deg/s) and rest_acc (g,
    relative to the accelerometer's mean magnitude) the rest thresholds, held for
    rest_time (s), with low-passes of tau_rest (s); latency (s) the delay of the
    sensor chain (the gyroscope's internal filter), compensated in the output q0..q3 by
    predicting it forward (0: none). Gyro in rad/s, accelerometer
    in any unit. State: see state_names; q0..q3 is the estimate (sensor -> earth, NWU).
    """
    kind = "imu"
    c_name = "imf_robust_imu"

    @staticmethod
    def _params(dt, tau_acc=2.5, rate_ref=100.0, tau_bias=100.0, tau_bias_rest=3.0,
                rest_gyr=2.0, rest_acc=0.05, rest_time=1.5, tau_rest=0.5, latency=0.0):
        dt = _checks.check_dt(dt)
        return (dt,) + _Robust._imu_params(tau_acc, rate_ref, tau_bias, tau_bias_rest,
                                           rest_gyr, rest_acc, rest_time, tau_rest, latency)

    def _init(self, dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc,
              rest_time, tau_rest, latency):
        self._init_common(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc,
                          rest_time, tau_rest, latency, tau_rest, 0.0, 0.0, tau_rest, 0.0, 0.0,
                          0, 0.0, 0.0, 0.0)

    def _update(self, gx, gy, gz, ax, ay, az):
        if not isfinite(gx, gy, gz, ax, ay, az):
            self._skip()
            return
        x = self._work()
        self._commit(x, self._step(x, gx, gy, gz, ax, ay, az) is not None
                     and self._finish(x, gx, gy, gz), self.state_names.index("hx"))


class RobustAHRS(_Robust):
    """imufuse's recommended attitude filter with a magnetometer
    (docs/recommended-ahrs.md).

    RobustAHRS(dt, ..., tau_mag=10.0, mag_norm=0.1, mag_dip=10.0, tau_mag_ref=20.0,
    mag_new_time=20.0, mag_hold=0.5): the parameters of RobustIMU, and tau_mag (s) the heading
    correction time constant; mag_norm (relative) and mag_dip (deg) the disturbance
    thresholds against the learned reference field, learnt with tau_mag_ref (s); a
    changed field that stays the same for mag_new_time (s) becomes the reference; after a
    disturbance the field must match the reference for mag_hold (s) before it is used.
    B6: mag_learn learns the magnetometer's offset (hard iron) while the sensor turns
    (False: the stored offset only, set_mag_offset); mag_noise (relative to the field) the
    magnetometer's noise, growing by |w| mag_lag (s, the timing mismatch of magnetometer
    and gyro); a trusted estimate is used once it differs from the stored offset by more
    than mag_offset_min (relative). Magnetometer in any unit; an all-zero reading means
    none.
    """
    kind = "ahrs"
    c_name = "imf_robust_ahrs"

    @staticmethod
    def _params(dt, tau_acc=2.5, rate_ref=100.0, tau_bias=100.0, tau_bias_rest=3.0,
                rest_gyr=2.0, rest_acc=0.05, rest_time=1.5, tau_rest=0.5, latency=0.0,
                tau_mag=10.0, mag_norm=0.1, mag_dip=10.0, tau_mag_ref=20.0, mag_new_time=20.0,
                mag_hold=0.5, mag_learn=True, mag_noise=0.02, mag_lag=0.003,
                mag_offset_min=0.1):
        dt = _checks.check_dt(dt)
        imu = _Robust._imu_params(tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr,
                                  rest_acc, rest_time, tau_rest, latency)
        tau_mag = _checks.check_real("tau_mag", tau_mag, lo=0.0, lo_open=True)
        mag_norm = _checks.check_real("mag_norm", mag_norm, lo=0.0)
        mag_dip = _checks.check_real("mag_dip", mag_dip, lo=0.0, hi=180.0)
        tau_mag_ref = _checks.check_real("tau_mag_ref", tau_mag_ref, lo=0.0, lo_open=True)
        mag_new_time = _checks.check_real("mag_new_time", mag_new_time, lo=0.0)
        mag_hold = _checks.check_real("mag_hold", mag_hold, lo=0.0)
        # the dip test compares sines: sin(mag_dip), in double, for both backends;
        # 90 deg or more: no dip test
        dip = math.sin(mag_dip * _DEG) if mag_dip < 90.0 else 2.0
        mag_learn = _checks.check_choice("mag_learn", mag_learn, (True, False))
        mag_noise = _checks.check_real("mag_noise", mag_noise, lo=0.0, lo_open=True, hi=1.0)
        mag_lag = _checks.check_real("mag_lag", mag_lag, lo=0.0, hi=0.1)
        mag_offset_min = _checks.check_real("mag_offset_min", mag_offset_min, lo=0.0)
        return (dt,) + imu + (tau_mag, mag_norm, dip, tau_mag_ref, mag_new_time, mag_hold,
                              int(mag_learn), mag_noise, mag_lag, mag_offset_min)

    def _init(self, dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc,
              rest_time, tau_rest, latency, tau_mag, mag_norm, mag_dip, tau_mag_ref,
              mag_new_time, mag_hold, mag_learn, mag_noise, mag_lag, mag_offset_min):
        self._init_common(dt, tau_acc, rate_ref, tau_bias, tau_bias_rest, rest_gyr, rest_acc,
                          rest_time, tau_rest, latency, tau_mag, mag_norm, mag_dip, tau_mag_ref,
                          mag_new_time, mag_hold, mag_learn, mag_noise, mag_lag, mag_offset_min)

    # imf_robust_ahrs_get_mag_offset / _set_mag_offset
    def get_mag_offset(self):
        """B6: ((x, y, z) the offset in use, magnetometer unit, sensor frame; the learnt
        estimate's standard deviation relative to the field, about 1 until the sensor has
        turned). Store it at power-down and give it back with set_mag_offset."""
        return (float(self.ux), float(self.uy), float(self.uz)), float(self.m_std)

    @staticmethod
    def _offset3(offset, dtype):
        # (x, y, z) numbers finite in the filter's precision, or ValueError naming the
        # component
        try:
            values = tuple(offset)
        except TypeError:
            raise ValueError(f"mag offset: expected (x, y, z), got {offset!r}") from None
        if len(values) != 3:
            raise ValueError(f"mag offset: expected 3 values (x, y, z), got {len(values)}")
        return tuple(_checks.check_real_in(f"mag offset {n}", v, dtype)
                     for n, v in zip("xyz", values))

    def set_mag_offset(self, offset):
        """B6: the stored offset (x, y, z; magnetometer unit, sensor frame, e.g. the "h"
        of a calibration file): used until a trusted estimate differs from it by more
        than mag_offset_min; the estimator starts again from it."""
        R = self._R
        ox, oy, oz = (R(v) for v in self._offset3(offset, self.dtype))
        self.sx, self.sy, self.sz = ox, oy, oz
        self.ux, self.uy, self.uz = ox, oy, oz
        self.m_n0 = R(0.0)
        self.m_std = R(1.0)

    def _update(self, gx, gy, gz, ax, ay, az, mx, my, mz):
        if not isfinite(gx, gy, gz, ax, ay, az, mx, my, mz):
            self._skip()
            return
        x = self._work()
        self._commit(x, self._step(x, gx, gy, gz, ax, ay, az) is not None
                     and self._mag(x, mx, my, mz, gx * gx + gy * gy + gz * gz)
                     and self._finish(x, gx, gy, gz),
                     len(self.state_names) if self.mag_learn else self.state_names.index("hx"))
