"""imufuse's recommended AHRS (docs/recommended-ahrs.md): pure-Python twin of
csrc/robust.c: the same functions, in the same order, with the same comments.

The blocks are in robust_b3.py (B3's noise), robust_blocks.py (B1-B3) and robust_mag.py
(B6, B4), the twins of csrc/robust_b3.h, csrc/robust_blocks.h and csrc/robust_mag.h, which
robust.c includes.

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

One sample: _step (B1 rest and the bias at rest, the strapdown, B2 gravity, the
levelling, B3 the bias in motion), then _magnetometer (B6 the offset, B4 the heading;
RobustAHRS only), then _output (the latency and B5's clock); the update keeps the new
state only if every block accepted the sample.
"""
import dataclasses
import math

from ..shared import checks as _checks
from ._base import QUAT_NORM2_TOL, ReferenceFilter, isfinite
from ._math import qmul
from .robust_b3 import _RobustB3
from .robust_blocks import _RobustBlocks, _vector3
from .robust_mag import _PNAMES, _RobustMag
from ._settings import FIXED, REQUIRED, SettingsRecord, choice, deg_to_rad, fixed, real, setting

# smallest normal and largest finite value of each precision (C: FLT_MIN, ..., IMF_REAL_MAX)
_LIMITS = {"float32": (1.1754943508222875e-38, 3.4028234663852886e+38),
           "float64": (2.2250738585072014e-308, 1.7976931348623157e+308)}


# ---- the settings (robust.h: imf_robust_settings_t) -----------------------------------

def _tau_bias(name, value, prior):
    # B3: 0 (off) or >= 4 tau_acc
    v = _checks.check_real(name, value, lo=0.0)
    if 0.0 < v < 4.0 * prior["tau_acc"]:
        raise ValueError("tau_bias: must be 0 (off) or >= 4 tau_acc (Eq. 3.12: "
                         f"a damped bias loop), got {value!r}")
    return v


def _dip_sine(v):
    # the dip test compares sines, in double for both backends; 90 deg or more: no dip test
    return math.sin(deg_to_rad(v)) if v < 90.0 else 2.0


@dataclasses.dataclass(frozen=True)
class RobustAHRSSettings(SettingsRecord):
    """imf_robust_settings_t, member for member, in the C's units: RobustAHRS's keywords (the
    user's default and unit), checked and converted once."""
    # member: setting(the user's default, the user's unit, the check, to_c=the conversion)
    dt: float = setting(REQUIRED, "s", real(lo=0.0, lo_open=True))
    tau_acc: float = setting(2.5, "s", real(lo=0.0, lo_open=True))                   # B2
    rate_ref: float = setting(100.0, "deg/s", real(lo=0.0), to_c=deg_to_rad)         # B2, rad/s
    tau_bias: float = setting(100.0, "s", _tau_bias)                                 # B3
    tau_bias_rest: float = setting(3.0, "s", real(lo=0.0, lo_open=True))             # B3
    rest_gyr: float = setting(2.0, "deg/s", real(lo=0.0), to_c=deg_to_rad)           # B1, rad/s
    rest_acc: float = setting(0.05, "g", real(lo=0.0))                               # B1
    rest_time: float = setting(1.5, "s", real(lo=0.0))                               # B1
    tau_rest: float = setting(0.5, "s", real(lo=0.0, lo_open=True))                  # B1
    latency: float = setting(0.0, "s", real(lo=0.0, hi=0.1))                         # output
    tau_mag: float = setting(10.0, "s", real(lo=0.0, lo_open=True))                  # B4
    mag_norm: float = setting(0.1, "relative", real(lo=0.0))                         # B4
    mag_dip: float = setting(10.0, "deg", real(lo=0.0, hi=180.0), to_c=_dip_sine)    # B4, sine
    tau_mag_ref: float = setting(20.0, "s", real(lo=0.0, lo_open=True))              # B4
    mag_new_time: float = setting(20.0, "s", real(lo=0.0))                           # B4
    mag_hold: float = setting(0.5, "s", real(lo=0.0))                                # B4
    mag_learn: int = setting(True, "bool", choice(True, False), to_c=int)            # B6, 0 or 1
    mag_noise: float = setting(0.02, "relative", real(lo=0.0, lo_open=True, hi=1.0))  # B6
    mag_lag: float = setting(0.003, "s", real(lo=0.0, hi=0.1))                       # B6
    mag_offset_min: float = setting(0.1, "relative", real(lo=0.0))                   # B6
    gyr_bias_max: float = setting(6.0, "deg/s", real(lo=0.0, hi=1000.0), to_c=deg_to_rad,  # B1/B3
                                  kw_only=True)                                    # rad/s


def _tau_rest(name, value, prior):
    # RobustIMU: the magnetic time constants at tau_rest keep the start-up horizon t_max
    # that of the blocks it runs (B1-B3, B5)
    return prior["tau_rest"]


@dataclasses.dataclass(frozen=True)
class RobustIMUSettings(RobustAHRSSettings):
    """imf_robust_settings_t for RobustIMU (imf_robust_update_imu): RobustAHRS's settings
    without the magnetometer's, which are fixed: B6 off, tau_mag = tau_mag_ref = tau_rest,
    the others at their defaults (never read without a field)."""
    # member: setting(the value, the user's unit, how it is fixed, to_c=the conversion)
    tau_mag: float = setting(None, "s", _tau_rest, keyword=FIXED)                      # B4
    mag_norm: float = setting(0.1, "relative", fixed, keyword=FIXED)                   # B4
    mag_dip: float = setting(10.0, "deg", fixed, to_c=_dip_sine, keyword=FIXED)        # B4, sine
    tau_mag_ref: float = setting(None, "s", _tau_rest, keyword=FIXED)                  # B4
    mag_new_time: float = setting(20.0, "s", fixed, keyword=FIXED)                     # B4
    mag_hold: float = setting(0.5, "s", fixed, keyword=FIXED)                          # B4
    mag_learn: int = setting(False, "bool", fixed, to_c=int, keyword=FIXED)            # B6 off
    mag_noise: float = setting(0.02, "relative", fixed, keyword=FIXED)                 # B6
    mag_lag: float = setting(0.003, "s", fixed, keyword=FIXED)                         # B6
    mag_offset_min: float = setting(0.1, "relative", fixed, keyword=FIXED)             # B6


# ---- the state (robust.h: imf_robust_state_t) ----------------------------------------

#: imf_robust_state_t member by member: (member, the names of its words in state_names;
#: None: one word, named as the member)
_MEMBERS = (("q", ("q0", "q1", "q2", "q3")),          # estimate, sensor -> earth
            ("s", ("s0", "s1", "s2", "s3")),          # strapdown: sensor -> inertial frame
            ("c", ("c0", "c1", "c2", "c3")),          # correction: inertial -> earth frame
            ("f", ("fx", "fy", "fz")),                # B2: gravity in the inertial frame
            ("v", ("vx", "vy", "vz")),                # B2: velocity-like state, acc unit * s
            ("pvv", None), ("pvg", None), ("pgg", None),  # B2: covariance (three axes)
            ("b", ("bx", "by", "bz")),                # gyro bias, rad/s
            ("lw", ("lwx", "lwy", "lwz")),            # B1: low-passed gyro, rad/s
            ("la", ("lax", "lay", "laz")),            # B1: low-passed accelerometer
            ("t", None), ("t_rest", None),            # time since start (saturating), at rest
            ("bu", None),                             # B1/B3: how unknown the bias still is
            ("ref", ("rn", "rh", "rz")),              # B4: reference: norm, cos dip, vertical
            ("cand", ("cn", "ch", "cz")),             # B4: candidate reference (changed field)
            ("t_cand", None), ("t_dist", None),       # B4: candidate stable for, disturbed for
            ("t_ok", None),                           # B4: matching the reference for, s
            ("lm", ("lmx", "lmy", "lmz")),            # B1: low-passed magnetometer
            ("l0", ("l0x", "l0y", "l0z")),            # B1: lm where the rest window began
            ("w0", ("w0x", "w0y", "w0z")),            # B1: lw where the rest window began
            ("db", ("dbx", "dby", "dbz")),            # B3: the turn by b less B2's low-pass
            ("vb", ("vbx", "vby", "vbz")),            # B3: its velocity-like state
            ("dr", tuple(f"dr{i}{j}" for j in "xyz" for i in "xyz")),  # B3: the same for R(s)
            ("vr", tuple(f"vr{i}{j}" for j in "xyz" for i in "xyz")),  # B3: its velocity
            ("bp", ("bp00", "bp01", "bp02", "bp11", "bp12", "bp22")),  # B3: covariance of b
            ("an", None),                             # B3: its rows' noise (of its bound)
            ("hi", ("hx", "hy", "hz", "ix", "iy", "iz")),  # B6: field h, offset estimate
            ("P", _PNAMES),                           # B6: their covariance, upper triangle
            ("u", ("ux", "uy", "uz")),                # B6: offset in use (B4 reads m - u)
            ("so", ("sx", "sy", "sz")),               # B6: stored offset (set_mag_offset)
            ("m_n0", None),                           # B6: field unit (0: not started)
            ("m_ew", None), ("m_d2", None),           # B6: mean and last normalised innovation
            ("m_std", None),                          # B6: the offset's standard deviation
            ("mn", ("m_nu", "m_vu", "m_ne", "m_ve")),  # B6: the norm (deviation) with u, o
            ("m_axis", None),                         # B6: the axis the next reading updates
            ("m_bad", None))                          # B6: absurd readings for, s
_ARRAYS = frozenset(m for m, names in _MEMBERS if names is not None)   #: members of > 1 word
#: the members an IMU update can change (C: ROBUST_IMU_WORDS, the words before hi)
_IMU_MEMBERS = tuple(m for m, _ in _MEMBERS[:[m for m, _ in _MEMBERS].index("hi")])


class _State:
    """The state (C: imf_robust_state_t), its members named as in C: x.lw is x->lw."""
    __slots__ = tuple(m for m, _ in _MEMBERS)

    @classmethod
    def zero(cls, R):
        # every word 0
        x = cls()
        for m, names in _MEMBERS:
            setattr(x, m, R(0.0) if names is None else [R(0.0)] * len(names))
        return x

    def copy(self):
        # the working copy (C: imf_robust_state_t x = self->x)
        x = _State()
        for m in _STATE_MEMBERS:
            v = getattr(self, m)
            setattr(x, m, v[:] if m in _ARRAYS else v)
        return x

    def words(self, members):
        # the words of these members, in the struct's order
        out = []
        for m in members:
            v = getattr(self, m)
            out += v if m in _ARRAYS else (v,)
        return out


def _word(member, i):
    # state_names' word: member[i] of the state (i None: the member itself)
    if i is None:
        return property(lambda self: getattr(self.x, member),
                        lambda self, v: setattr(self.x, member, v))

    def get(self):
        return getattr(self.x, member)[i]

    def put(self, v):
        getattr(self.x, member)[i] = v
    return property(get, put)


class _Robust(_RobustB3, _RobustBlocks, _RobustMag, ReferenceFilter):
    #: q0 is refused: the filter takes its tilt from the first sample's gravity and (AHRS)
    #: its heading from the first field, so a start attitude would be overwritten
    own_start = ("this filter starts from its first sample (its tilt from gravity; RobustAHRS "
                 "its heading from the field), which would overwrite a start attitude; leave "
                 "q0 out, or resume a saved filter with state= (its full state)")
    #: the state's words, in the order of imf_robust_state_t (_MEMBERS expanded)
    state_names = tuple(m if names is None else n for m, names in _MEMBERS
                        for n in (names or (m,)))
    #: each word's C expression in the state (the firmware harnesses read x.<expression>)
    c_state = {n: m if names is None else f"{m}[{i}]" for m, names in _MEMBERS
               for i, n in enumerate(names or (m,))}

    @classmethod
    def _valid_state(cls, args, R, state):
        # state writes: the three quaternions unit, variances and times not negative
        names = cls.state_names
        for k in (0, 4, 8):
            n2 = float(sum(float(v) * float(v) for v in state[k:k + 4]))
            if not abs(n2 - 1.0) <= QUAT_NORM2_TOL:
                return (f"|{names[k][0]}|^2 = {n2!r}, must be within 1 +- "
                        f"{QUAT_NORM2_TOL}")
        bu = float(state[names.index("bu")])
        if not 0.0 <= bu <= 1.0:
            return f"bu = {bu!r}, must be within 0 .. 1"
        for n in ("pvv", "pgg", "t", "t_rest", "rn", "cn", "t_cand", "t_dist", "t_ok", "bp00",
                  "bp11", "bp22", "an", "p00", "p11", "p22", "p33", "p44", "p55", "m_n0", "m_ew",
                  "m_d2", "m_std", "m_nu", "m_vu", "m_ne", "m_ve", "m_bad"):
            if float(state[names.index(n)]) < 0.0:
                return f"{n} = {float(state[names.index(n)])!r}, must not be negative"
        if float(state[names.index("m_axis")]) not in (0.0, 1.0, 2.0):
            return f"m_axis = {float(state[names.index('m_axis')])!r}, must be 0, 1 or 2"
        return None

    # ---- helpers (quaternion product and rotation: _math) ----------------------------

    def _norm4(self, q):
        # unit quaternion in place; False when the normalisation fails (squared norm zero,
        # subnormal, overflowed or NaN: valid-attitude policy)
        R = self._R
        n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
        if not (n2 >= self._min and n2 <= self._max):
            return False
        r = R(1.0) / R(math.sqrt(n2))
        q[0] = q[0] * r
        q[1] = q[1] * r
        q[2] = q[2] * r
        q[3] = q[3] * r
        return True

    def _gain(self, t, tau, k):
        # B5: a running mean until tau, then the low-pass gain k = dt / (tau + dt)
        if t < tau:
            return self.s.dt / (t + self.s.dt)
        return k

    def _turn_by(self, o, q, g, b, h):
        # q (x) exp(1/2 w h) into o, h = dt or the latency: the series to 4th order (no
        # sin/cos), w = g - b; False when the normalisation fails
        R = self._R
        ox = (g[0] - b[0]) * h
        oy = (g[1] - b[1]) * h
        oz = (g[2] - b[2]) * h
        th2 = ox * ox + oy * oy + oz * oz
        cw = R(1.0) - th2 * R(0.125)
        sv = R(0.5) - th2 * self.c48
        o[0], o[1], o[2], o[3] = qmul(q[0], q[1], q[2], q[3], cw, sv * ox, sv * oy, sv * oz)
        return self._norm4(o)

    # ---- init, dt, attitude -----------------------------------------------------------

    # imf_robust_*_set_dt: every dt-dependent constant, as init computes it
    def _set_dt(self, dt):
        R = self._R
        self.s.dt = dt
        self.two_dt = R(2.0) * dt
        self.dt2 = dt * dt
        self.r_d = R(1.0) / dt
        self.qg_dt = self.qg0 * dt
        # B5: the first accelerometer sample is one sample, not a settled estimate: gravity's
        # initial variance is what one velocity measurement (noise 1 / dt per sample) says of
        # an acceleration over dt, 1 / dt^3, where 1 / tau_acc^3 (the settled variance, worth
        # tau_acc of samples) would hold a moving start's first reading for tau_acc.
        # gyr_bias_max 0: 1 / tau_acc^3, as the fixed-point filters start
        if self.s.gyr_bias_max > R(0.0):
            self.pgg0 = self.r_d * (self.r_d * self.r_d)
        else:
            self.pgg0 = R(1.0) / (self.s.tau_acc * self.s.tau_acc * self.s.tau_acc)
        self.k_rest = dt / (self.s.tau_rest + dt)
        self.kb_rest = dt / (self.s.tau_bias_rest + dt)
        self.ku_motion = self.inv_tau_bias * dt
        self.k_mag = dt / (self.s.tau_mag + dt)
        self.k_ref = dt / (self.s.tau_mag_ref + dt)
        self.k_acc = dt / (self.s.tau_acc + dt)

    # robust_init: the settings s (a RobustAHRSSettings, C units) as the C keeps them
    # (imf_real), and the constants derived from them once; the state
    def _init_filter(self, s):
        R = self._R
        lo, hi = _LIMITS[self.dtype]
        self._min, self._max = R(lo), R(hi)
        self._real_max = R(hi)
        self.s = s = s.as_real(R)
        rate_ref, rest_gyr, rest_acc = s.rate_ref, s.rest_gyr, s.rest_acc
        # B2: gravity process noise q_g = (1 + |w|^2 / rate_ref^2) / tau_acc^4 per s, with the
        # velocity measurement noise 1 (any acc unit): the steady state is a second-order
        # low-pass with omega_0 = 1 / tau_acc and damping 1/sqrt(2) at rest
        ta2 = s.tau_acc * s.tau_acc
        self.qg0 = R(1.0) / (ta2 * ta2)
        self.inv_rate_ref2 = R(1.0) / (rate_ref * rate_ref) if rate_ref > R(0.0) else R(0.0)
        self.inv_tau_bias = R(1.0) / s.tau_bias if s.tau_bias > R(0.0) else R(0.0)
        self.tau_b0 = R(4.0) * s.tau_acc
        # B3's Kalman filter of the bias, relative to the noise of its measurement (the
        # correction rate; _bias): in motion the accelerometer differs from gravity by up to
        # rest_acc (what B1 calls motion), which B2 passes on as a tilt error changing over
        # tau_acc, noise of density rest_acc^2 / tau_acc in the rate; the prior, any bias in
        # the part's range in any direction, |b|^2 <= 3 gyr_bias_max^2: 1 / tau_p =
        # 3 gyr_bias_max^2 tau_acc / rest_acc^2 (no weaker than one sample's worth, 1 / dt);
        # its random walk makes the steady state 1 / tau_bias (learnt over tau_bias)
        p0 = R(3.0) * (s.gyr_bias_max * s.gyr_bias_max) * s.tau_acc
        if p0 * s.dt < s.rest_acc * s.rest_acc:
            self.inv_tau_p = p0 / (s.rest_acc * s.rest_acc)
        else:
            self.inv_tau_p = R(1.0) / s.dt
        self.qb = self.inv_tau_bias * self.inv_tau_bias
        self.tau_h0 = R(4.0) * s.tau_mag
        # rest_gyr 0: no rest (B1 off) at any bias
        self.bias_var0 = (R(3.0) * s.gyr_bias_max * s.gyr_bias_max if rest_gyr > R(0.0)
                          else R(0.0))
        self.bias_w2 = R(3600.0) * (s.gyr_bias_max * s.gyr_bias_max)
        self.rest_gyr2 = rest_gyr * rest_gyr
        self.rest_acc2 = rest_acc * rest_acc
        self.c48 = R(1.0) / R(48.0)
        self.mag_noise2 = s.mag_noise * s.mag_noise
        self._zero3 = (R(0.0), R(0.0), R(0.0))  # the IMU's magnetometer: none
        self.mag_lag2 = s.mag_lag * s.mag_lag
        self.mag_min2 = s.mag_offset_min * s.mag_offset_min
        # t saturates at the longest start-up horizon
        tmax = s.tau_acc
        for v in (s.tau_rest, s.tau_mag, s.tau_mag_ref):
            if v > tmax:
                tmax = v
        self.t_max = tmax
        self._set_dt(s.dt)
        # every word 0; the three quaternions the identity; B6: no offset stored, the
        # estimator starts at the first reading, its standard deviation 1
        self.x = _State.zero(R)
        self.x.q[0] = R(1.0)
        self.x.s[0] = R(1.0)
        self.x.c[0] = R(1.0)
        self.x.m_std = R(1.0)
        self.x.bu = R(1.0) if s.gyr_bias_max > R(0.0) else R(0.0)
        if s.gyr_bias_max > R(0.0):
            # B3: the bias's prior, worth tau_p of measurement
            self.x.bp[0] = self.x.bp[3] = self.x.bp[5] = self.inv_tau_p

    # imf_robust_*_set_attitude: start again from att (the next sample is the first)
    def _set_attitude(self, att):
        R = self._R
        x = self.x
        x.q = list(att.q)
        x.s = list(att.q)
        x.c = [R(1.0), R(0.0), R(0.0), R(0.0)]
        x.t = R(0.0)
        x.ref[0] = R(0.0)
        x.m_n0 = R(0.0)

    # ---- gyro and accelerometer: B1, strapdown, B2, levelling, B3 ----------------------

    def _output(self, x, g):
        """The end of every update: the output q = c (x) s predicted by the sensor's latency
        with the bias-corrected rate (q (x) exp(1/2 (w - b) latency)), then B5's clock of
        the start-up (saturating: no growth once every start is over); False rejects the
        sample."""
        if self.s.latency > self._R(0.0) and not self._turn_by(x.q, x.q, g, x.b, self.s.latency):
            return False
        x.t = x.t + self.s.dt
        if x.t > self.t_max:
            x.t = self.t_max
        return True

    def _words(self):
        return self.x.words(_STATE_MEMBERS)     # state_names: _MEMBERS expanded

    def _commit(self, x, ok, members):
        # keep the new state (its first members: the IMU and the AHRS with B6 off never change
        # B6's) only if every block accepted the sample and left it finite (valid attitude)
        if not (ok and isfinite(*x.words(members))):
            self._skip()
            return
        if members is _STATE_MEMBERS:
            self.x = x
            return
        for m in members:
            setattr(self.x, m, getattr(x, m))


_STATE_MEMBERS = tuple(m for m, _ in _MEMBERS)
for _m, _names in _MEMBERS:
    for _i, _n in enumerate(_names or (_m,)):
        setattr(_Robust, _n, _word(_m, None if _names is None else _i))


class RobustIMU(_Robust):
    """imufuse's recommended attitude filter, gyroscope + accelerometer
    (docs/recommended-ahrs.md).

    RobustIMU(dt, tau_acc=2.5, rate_ref=100.0, tau_bias=100.0, tau_bias_rest=3.0,
    rest_gyr=2.0, rest_acc=0.05, rest_time=1.5, tau_rest=0.5, latency=0.0): dt in s;
    tau_acc (s) the gravity filter's time constant at rest; rate_ref (deg/s) the rotation
    rate at which its gravity uncertainty doubles (0: constant); tau_bias (s) the time
    constant of the bias estimation in motion at the bound of its noise (its random walk;
    smooth motion learns faster; 0: off, else >= 4 tau_acc); tau_bias_rest
    (s) that of the bias at rest; rest_gyr (deg/s) and rest_acc (g, relative to the
    accelerometer's mean magnitude) the rest thresholds, held for rest_time (s), with
    low-passes of tau_rest (s); latency (s) the delay of the sensor chain (the gyroscope's
    internal filter), compensated in the output q0..q3 by predicting it forward (0: none).
    Gyro in rad/s, accelerometer in any unit. State: see state_names; q0..q3 is the
    estimate (sensor -> earth, NWU).
    """
    kind = "imu"
    c_name = "imf_robust"
    c_update = "imf_robust_update_imu"
    settings_type = RobustIMUSettings
    _params = RobustIMUSettings.keywords()

    # imf_robust_init with RobustIMU's settings (the magnetometer's fixed, RobustIMUSettings)
    def _init(self, s):
        self._init_filter(s)

    # imf_robust_update_imu
    def _update(self, gx, gy, gz, ax, ay, az):
        if not isfinite(gx, gy, gz, ax, ay, az):
            self._skip()
            return
        g = (gx, gy, gz)
        x = self.x.copy()
        self._commit(x, self._step(x, g, (ax, ay, az), self._zero3) and self._output(x, g),
                     _IMU_MEMBERS)


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
    than mag_offset_min (relative), an untrusted one when the norm shows the stored one
    wrong. Magnetometer in any unit; an all-zero reading means none.
    """
    kind = "ahrs"
    c_name = "imf_robust"
    settings_type = RobustAHRSSettings
    _params = RobustAHRSSettings.keywords()

    # imf_robust_init
    def _init(self, s):
        self._init_filter(s)

    # imf_robust_get_mag_offset / _set_mag_offset
    def get_mag_offset(self):
        """B6: ((x, y, z) the offset in use, magnetometer unit, sensor frame; the learnt
        estimate's standard deviation relative to the field, about 1 until the sensor has
        turned). Store it at power-down and give it back with set_mag_offset."""
        return tuple(float(v) for v in self.x.u), float(self.x.m_std)

    @staticmethod
    def _offset3(offset, dtype):
        # (x, y, z) numbers finite in the filter's precision, or ValueError naming the
        # component
        return _vector3("mag offset", offset, dtype)

    def set_mag_offset(self, offset):
        """B6: the stored offset (x, y, z; magnetometer unit, sensor frame, e.g. the "h"
        of a calibration file): used until a trusted estimate differs from it by more
        than mag_offset_min; the estimator starts again from it."""
        R = self._R
        o = [R(v) for v in self._offset3(offset, self.dtype)]
        self.x.so = list(o)
        self.x.u = list(o)
        self.x.m_n0 = R(0.0)
        self.x.m_std = R(1.0)

    # imf_robust_update
    def _update(self, gx, gy, gz, ax, ay, az, mx, my, mz):
        if not isfinite(gx, gy, gz, ax, ay, az, mx, my, mz):
            self._skip()
            return
        g = (gx, gy, gz)
        g2 = gx * gx + gy * gy + gz * gz
        x = self.x.copy()
        self._commit(x, self._step(x, g, (ax, ay, az), (mx, my, mz))
                     and self._magnetometer(x, (mx, my, mz), g2)
                     and self._output(x, g), _STATE_MEMBERS if self.s.mag_learn else _IMU_MEMBERS)
