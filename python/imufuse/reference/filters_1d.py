"""Single-axis filters of the article, chapters 2 and 3: pure-Python twins
of csrc/filters_1d.c, line for line.

Per sample: rate = gyro rate (rad/s), angle = accelerometer angle (rad).
"""
import dataclasses
import math

from ..shared import checks as _checks
from ._base import ReferenceFilter, isfinite
from ._settings import REQUIRED, USER, SettingsRecord, dt, real, setting


def _stable_gain_dt(name, k, dt):
    """P gain of Eq. 2.9: alpha = 1 - k dt must satisfy |alpha| < 1 (k = 0: pure gyro)."""
    _checks.check_real(name, k, lo=0.0)
    _checks.check_real(f"{name}*dt", k * dt, lo=0.0, hi=2.0, hi_open=True,
                       why="alpha = 1 - kp dt of Eq. 2.9 must satisfy |alpha| < 1")
    return float(k)


def _alpha(name, alpha, prior):
    # alpha, or the time constant T (an extra keyword): alpha = (T/dt) / (1 + T/dt)
    T = prior["T"]
    if (alpha is None) == (T is None):
        raise ValueError("alpha, T: give exactly one of alpha or the time constant T")
    if T is not None:
        T = _checks.check_real("T", T, lo=0.0)
        alpha = (T / prior["dt"]) / (1.0 + T / prior["dt"])
    return _checks.check_real("alpha", alpha, lo=0.0, hi=1.0)


@dataclasses.dataclass(frozen=True)
class Complementary1DSettings(SettingsRecord):
    """imf_complementary1d_settings_t, member for member (C units)."""
    extra = (("T", None, True),)
    dt: float = setting(REQUIRED, "s", dt())
    alpha: float = setting(None, "1", _alpha)


@dataclasses.dataclass(frozen=True)
class Kalman1DSettings(SettingsRecord):
    """imf_kalman1d_settings_t, member for member (C units)."""
    dt: float = setting(REQUIRED, "s", dt())
    k0: float = setting(REQUIRED, "1", real(lo=0.0, hi=1.0))


@dataclasses.dataclass(frozen=True)
class Mahony1DSettings(SettingsRecord):
    """imf_mahony1d_settings_t, member for member (C units)."""
    dt: float = setting(REQUIRED, "s", dt())
    kp: float = setting(REQUIRED, "1/s", lambda name, v, prior: _stable_gain_dt(name, v, prior["dt"]))


def _bias_sign(name, bias_sign, prior):
    # a bool is no sign (a complex one never gets here: SettingsRecord.from_user)
    if isinstance(bias_sign, bool) or bias_sign not in (-1, 1):
        raise ValueError(f"bias_sign: must be -1 or +1, got {bias_sign!r}")
    if not prior["allow_unstable"]:
        s = bias_sign * prior["k1"] * prior["dt"]
        if not (0.0 <= s < 4.0 - 2.0 * prior["k0"]):
            raise ValueError(
                f"k1: bias_sign*k1*dt = {s!r} is outside the stable range "
                f"[0, 4 - 2 k0) (Corollary #2: with bias_sign=-1, k1 must be <= 0)")
    return int(bias_sign)


@dataclasses.dataclass(frozen=True)
class Kalman1DBiasSettings(SettingsRecord):
    """imf_kalman1d_bias_settings_t, member for member (C units)."""
    extra = (("allow_unstable", False, True),)
    dt: float = setting(REQUIRED, "s", dt())
    k0: float = setting(REQUIRED, "1", real(lo=0.0, hi=1.0, lo_open=True))
    k1: float = setting(REQUIRED, "1/s", real())
    bias_sign: int = setting(-1, "", _bias_sign)


def _integrate_first(name, value, prior):
    if not isinstance(value, bool):
        raise ValueError(f"integrate_first: must be True or False, got {value!r}")
    kpdt, kidt2 = prior["kp"] * prior["dt"], prior["ki"] * prior["dt"] * prior["dt"]
    # homogeneous update matrix: p(1) = Ki dt^2 for both orders
    if value:
        det, p_plus = 1.0 - kpdt + kidt2, 4.0 - 2.0 * kpdt + kidt2
    else:
        det, p_plus = 1.0 - kpdt, 4.0 - 2.0 * kpdt - kidt2
    _checks.check_stable2("kp, ki", det, kidt2, p_plus, f"kp*dt={kpdt!r}, ki*dt^2={kidt2!r}")
    return value


@dataclasses.dataclass(frozen=True)
class Mahony1DBiasSettings(SettingsRecord):
    """imf_mahony1d_bias_settings_t, member for member (C units)."""
    dt: float = setting(REQUIRED, "s", dt())
    kp: float = setting(REQUIRED, "1/s", real(lo=0.0))
    ki: float = setting(REQUIRED, "1/s^2", real(lo=0.0))
    integrate_first: int = setting(False, "bool", _integrate_first, to_c=int)


def _pi_gains(prior):
    # kp and ki, or omega0 and xi (extra keywords): kp = 2 xi omega0, ki = omega0^2
    u = prior[USER]
    kp, ki, omega0, xi = u["kp"], u["ki"], u["omega0"], u["xi"]
    if omega0 is not None or xi is not None:
        if kp is not None or ki is not None or omega0 is None or xi is None:
            raise ValueError("kp, ki, omega0, xi: give either kp and ki, or omega0 and xi")
        omega0 = _checks.check_real("omega0", omega0, lo=0.0, lo_open=True)
        xi = _checks.check_real("xi", xi, lo=0.0, lo_open=True)
        kp, ki = 2.0 * xi * omega0, omega0 * omega0
    elif kp is None or ki is None:
        raise ValueError("kp, ki: both are required (or omega0 and xi)")
    # backward difference maps every stable continuous filter (kp > 0, ki >= 0)
    # to a stable discrete one
    return _checks.check_real("kp", kp, lo=0.0, lo_open=True), _checks.check_real("ki", ki, lo=0.0)


@dataclasses.dataclass(frozen=True)
class Complementary1DBiasSettings(SettingsRecord):
    """imf_complementary1d_bias_settings_t, member for member (C units)."""
    extra = (("omega0", None, True), ("xi", None, True))
    dt: float = setting(REQUIRED, "s", dt())
    kp: float = setting(None, "1/s", lambda name, v, prior: _pi_gains(prior)[0])
    ki: float = setting(None, "1/s^2", lambda name, v, prior: _pi_gains(prior)[1])


class Complementary1D(ReferenceFilter):
    """Complementary filter, Eq. 2.2: theta_k = alpha (theta_{k-1} + w_k dt) + (1 - alpha) a_k.

    Complementary1D(dt, alpha) or Complementary1D(dt, T=time_constant), with
    alpha = (T/dt) / (1 + T/dt). Example (the ROSE course blog, Telecom ParisTech, 2012): t = 10/11 at 60 Hz is
    Complementary1D(1/60, alpha=10/11), i.e. T = 10/60 s.
    """
    c_name = "imf_complementary1d"
    state_names = ("theta",)

    settings_type = Complementary1DSettings
    _params = Complementary1DSettings.keywords()

    def _init(self, s):
        R = self._R
        self._set_dt(R(s.dt))
        self.alpha = R(s.alpha)
        self.one_minus_alpha = R(1.0) - self.alpha
        self.theta = R(0.0)

    def _set_dt(self, dt):
        # imf_complementary1d_set_dt: dt (s) of type R
        self.dt = dt

    def _update(self, rate, angle):
        if not isfinite(rate, angle):
            self._skip()
            return
        # Eq. 2.2: theta_k = alpha (theta_{k-1} + w_k dt) + (1 - alpha) a_k
        theta = self.alpha * (self.theta + rate * self.dt) + self.one_minus_alpha * angle
        if not isfinite(theta):
            self._skip()
            return
        self.theta = theta


class Kalman1D(ReferenceFilter):
    """Kalman filter with constant gain K0, Eq. 2.5 (same as Eq. 2.2 with alpha = 1 - K0)."""
    c_name = "imf_kalman1d"
    state_names = ("theta",)

    settings_type = Kalman1DSettings
    _params = Kalman1DSettings.keywords()

    def _init(self, s):
        R = self._R
        self._set_dt(R(s.dt))
        self.k0 = R(s.k0)
        self.one_minus_k0 = R(1.0) - self.k0
        self.theta = R(0.0)

    def _set_dt(self, dt):
        # imf_kalman1d_set_dt: dt (s) of type R
        self.dt = dt

    def _update(self, rate, angle):
        if not isfinite(rate, angle):
            self._skip()
            return
        # Eq. 2.5: predict with the gyro, then correct with the accelerometer
        theta_pred = self.theta + rate * self.dt
        theta = self.one_minus_k0 * theta_pred + self.k0 * angle
        if not isfinite(theta):
            self._skip()
            return
        self.theta = theta


class Mahony1D(ReferenceFilter):
    """Mahony&Madgwick filter with a P controller, Eq. 2.8 (alpha = 1 - Kp dt, Eq. 2.9)."""
    c_name = "imf_mahony1d"
    state_names = ("theta",)

    settings_type = Mahony1DSettings
    _params = Mahony1DSettings.keywords()

    def _init(self, s):
        R = self._R
        self._set_dt(R(s.dt))
        self.kp = R(s.kp)
        self.theta = R(0.0)

    def _set_dt(self, dt):
        # imf_mahony1d_set_dt: dt (s) of type R
        self.dt = dt

    def _update(self, rate, angle):
        if not isfinite(rate, angle):
            self._skip()
            return
        # Eq. 2.8: the error uses the previous estimate theta_{k-1} (Eq. 2.12)
        e = angle - self.theta
        theta = self.theta + (self.kp * e + rate) * self.dt
        if not isfinite(theta):
            self._skip()
            return
        self.theta = theta


class Kalman1DBias(ReferenceFilter):
    """Kalman filter with a gyro-bias state, Eq. 3.3.

    bias_sign=-1 corrects the rate as w - b (the natural sign); bias_sign=+1 as
    w + b with the bias update law unchanged (Corollary #2). The filter is
    stable for 0 < k0 < 2 and 0 <= bias_sign*k1*dt < 4 - 2 k0: with the
    natural sign, k1 must be negative (or zero) and b converges to the gyro
    bias; with bias_sign=+1 and k1 > 0, b converges to minus the bias.
    allow_unstable=True skips the stability check (to study Corollary #2).
    """
    c_name = "imf_kalman1d_bias"
    state_names = ("theta", "b")

    settings_type = Kalman1DBiasSettings
    _params = Kalman1DBiasSettings.keywords()

    def _init(self, s):
        R = self._R
        self._set_dt(R(s.dt))
        self.k0 = R(s.k0)
        self.one_minus_k0 = R(1.0) - self.k0
        self.k1 = R(s.k1)
        self.bias_sign = R(-1.0) if s.bias_sign < 0 else R(1.0)
        self.theta = R(0.0)
        self.b = R(0.0)

    def _set_dt(self, dt):
        # imf_kalman1d_bias_set_dt: dt (s) of type R
        self.dt = dt

    def _update(self, rate, angle):
        if not isfinite(rate, angle):
            self._skip()
            return
        # Eq. 3.3: theta^-_k = theta_{k-1} + (w_k -+ b_{k-1}) dt; the sign only
        # enters here, the bias update law is the same for both (Corollary #2)
        theta_pred = self.theta + (rate + self.bias_sign * self.b) * self.dt
        theta = self.one_minus_k0 * theta_pred + self.k0 * angle
        b = self.b + self.k1 * (angle - theta_pred)
        if not isfinite(theta, b):
            self._skip()
            return
        self.theta = theta
        self.b = b


class Mahony1DBias(ReferenceFilter):
    """Mahony&Madgwick filter with a PI controller, Eq. 3.6.

    integrate_first=True runs the reversed order of Eq. 3.9 (Corollary #1); kp
    is then the K_p' of Eq. 3.9: Mahony1DBias(dt, kp + ki*dt, ki, True) has the
    transfer function of Mahony1DBias(dt, kp, ki). The integral I converges to
    minus the gyro bias.
    """
    c_name = "imf_mahony1d_bias"
    state_names = ("theta", "i")

    settings_type = Mahony1DBiasSettings
    _params = Mahony1DBiasSettings.keywords()

    def _init(self, s):
        R = self._R
        self.kp = R(s.kp)
        self.ki = R(s.ki)
        self._set_dt(R(s.dt))
        self.integrate_first = s.integrate_first != 0
        self.theta = R(0.0)
        self.i = R(0.0)

    def _set_dt(self, dt):
        # imf_mahony1d_bias_set_dt
        self.dt = dt
        self.ki_dt = self.ki * dt

    def _update(self, rate, angle):
        if not isfinite(rate, angle):
            self._skip()
            return
        e = angle - self.theta
        if not self.integrate_first:
            # Eq. 3.6: I_k = I_{k-1} + Ki dt e_k; theta_k = theta_{k-1} + (Kp e_k + I_k + w_k) dt
            i = self.i + self.ki_dt * e
            theta = self.theta + (self.kp * e + i + rate) * self.dt
        else:
            # Eq. 3.9: theta_k = theta_{k-1} + (w_k + I_{k-1}) dt + Kp' dt e_k; then I_k
            theta = self.theta + (rate + self.i) * self.dt
            theta = theta + self.kp * self.dt * e
            i = self.i + self.ki_dt * e
        if not isfinite(theta, i):
            self._skip()
            return
        self.theta = theta
        self.i = i


class Complementary1DBias(ReferenceFilter):
    """Second-order complementary filter, Eq. 3.10.

    Complementary1DBias(dt, kp, ki) or Complementary1DBias(dt, omega0=..., xi=...)
    with Ki = omega0^2, Kp = 2 xi omega0 (Eq. 3.11). Discretised by backward
    difference (Eq. 1.2) and run in its PI form (theta' = w + Kp e + I,
    I' = Ki e), solved for theta_k; state: the angle theta and the integral
    term i (rad/s). See csrc/filters_1d.h for why not a direct-form section,
    and tuning() for Eq. 3.12 and the rule of thumb.
    """
    c_name = "imf_complementary1d_bias"
    state_names = ("theta", "i")

    settings_type = Complementary1DBiasSettings
    _params = Complementary1DBiasSettings.keywords()

    def _init(self, s):
        R = self._R
        self.kp = R(s.kp)
        self.ki = R(s.ki)
        self._set_dt(R(s.dt))
        self.theta = R(0.0)
        self.i = R(0.0)

    def _set_dt(self, dt):
        # imf_complementary1d_bias_set_dt:
        # a0 = 1 + Kp dt + Ki dt^2: the z^0 term of (1 - z^-1)^2 + Kp dt (1 - z^-1) + Ki dt^2
        R = self._R
        kp_dt = self.kp * dt
        ki_dt2 = self.ki * dt * dt
        a0 = R(1.0) + kp_dt + ki_dt2
        self.dt = dt
        self.b0a = (kp_dt + ki_dt2) / a0
        self.b0w = dt / a0
        self.ki_dt = self.ki * dt

    def _update(self, rate, angle):
        if not isfinite(rate, angle):
            self._skip()
            return
        # Eq. 3.10 by backward difference, solved for theta_k:
        # theta_k = theta_{k-1} + (dt (w_k + I_{k-1}) + (Kp dt + Ki dt^2)(a_k - theta_{k-1})) / a0
        theta = self.theta + (self.b0w * (rate + self.i) + self.b0a * (angle - self.theta))
        # I_k = I_{k-1} + Ki dt e_k, e_k = a_k - theta_k
        i = self.i + self.ki_dt * (angle - theta)
        if not isfinite(theta, i):
            self._skip()
            return
        self.theta = theta
        self.i = i


def tuning(kp, ki):
    """Eq. 3.11/3.12 for PI gains kp (1/s), ki (1/s^2): resonance omega0 (rad/s),
    damping xi, whether Eq. 3.12 (Ki <= Kp^2/4, no overshoot in the gyro
    channel) holds, and the rule-of-thumb range Ki = 0.05..0.1 Kp^2."""
    kp = _checks.check_real("kp", kp, lo=0.0, lo_open=True)
    ki = _checks.check_real("ki", ki, lo=0.0, lo_open=True)
    omega0 = math.sqrt(ki)
    return {
        "omega0": omega0,
        "xi": kp / (2.0 * omega0),
        "eq_3_12": ki <= 0.25 * kp * kp,
        "ki_rule_of_thumb": (0.05 * kp * kp, 0.1 * kp * kp),
        "in_rule_of_thumb": 0.05 * kp * kp <= ki <= 0.1 * kp * kp,
    }


Complementary1DBias.tuning = staticmethod(tuning)  # type: ignore[attr-defined]
Mahony1DBias.tuning = staticmethod(tuning)  # type: ignore[attr-defined]
