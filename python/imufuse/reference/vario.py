"""Variometer of Hari Nair (2016): pure-Python twin of csrc/vario.c,
line for line.

VarioKF is the three-state Kalman filter that fuses vertical acceleration
with barometric altitude: z altitude (cm), v climb rate (cm/s), b
accelerometer bias (cm/s^2), and the covariance P (upper triangle).
vertical_accel() is Nair's gravity-compensated vertical acceleration.
"""
import dataclasses
import functools

import numpy as np

from ..shared import checks as _checks
from ._base import ReferenceFilter, isfinite
from ._settings import SettingsRecord, real, setting

#: its own input kind (accel, baro_alt, dt): not in FILTERS, the IMU/1-D matrix
PREDICT = {"seed": 0, "model": 1}
PREDICT_SEED, PREDICT_MODEL = 0, 1

#: vertical_accel conventions: the sign of az_earth for which the
#: accelerometer reads +1 g at rest (see csrc/vario.h)
CONVENTIONS = {"nwu": 1.0, "enu": 1.0, "ned_seed": 1.0, "ned": -1.0}

#: Nair's defaults
VAR_Z, VAR_ACC, VAR_BIAS, P0 = 300.0, 200.0, 1.0, (1.0, 1.0, 1e5)

#: barometer periods the stability check of Nair's order covers (1 kHz to 1 Hz), s
SEED_DT = tuple(float(v) for v in np.logspace(-3.0, 0.0, 16))


@functools.lru_cache(maxsize=256)
def seed_radius(var_z, var_acc, var_bias, dt):
    """Spectral radius of the steady-state error dynamics of predict="seed": the Kalman
    gain K of the model (its F, Q, R, from the discrete Riccati equation, solved by the
    structured doubling algorithm) applied to Nair's state prediction F_s, whose z uses
    the new v (z += v dt + (a - b) dt^2, not the model's dt^2 / 2). Above 1 the estimate
    diverges whatever the data. predict="model" uses F itself: a Kalman filter of its own
    model, stable for every setting."""
    f = np.array([[1.0, dt, -0.5 * dt * dt], [0.0, 1.0, -dt], [0.0, 0.0, 1.0]])
    g = np.array([0.5 * dt * dt, dt, 0.0])
    q = np.outer(g, g) * var_acc
    q[2, 2] += var_bias
    a, gm, x, eye = f.T.copy(), np.zeros((3, 3)), q.copy(), np.eye(3)
    gm[0, 0] = 1.0 / var_z
    for _ in range(80):
        wi = np.linalg.inv(eye + gm @ x)
        a, gm, x_new = a @ wi @ a, gm + a @ wi @ gm @ a.T, x + a.T @ x @ wi @ a
        done = np.allclose(x_new, x, rtol=1e-13, atol=0.0)
        x = x_new
        if done:
            break
    k = x[:, 0] / (x[0, 0] + var_z)
    fs = np.array([[1.0, dt, -dt * dt], [0.0, 1.0, -dt], [0.0, 0.0, 1.0]])
    m = (eye - np.outer(k, [1.0, 0.0, 0.0])) @ fs
    return float(np.max(np.abs(np.linalg.eigvals(m))))


def check_seed_stable(var_z, var_acc, var_bias):
    """predict="seed" with these variances: ValueError naming the barometer periods at
    which it diverges (see seed_radius)."""
    bad = [(dt, seed_radius(var_z, var_acc, var_bias, dt)) for dt in SEED_DT]
    bad = [(dt, r) for dt, r in bad if r > 1.0 + 1e-9]
    if bad:
        worst = max(r for _, r in bad)
        raise ValueError(
            f"var_z: {var_z!r} cm^2 is too small for predict='seed' against var_acc={var_acc!r}"
            f" and var_bias={var_bias!r}: Nair's order of prediction then diverges at "
            f"barometer periods of {bad[0][0]:.3g} to {bad[-1][0]:.3g} s (the error grows by "
            f"up to {worst:.4f} per sample, whatever the data); use predict='model' (stable "
            f"for every setting) or a larger var_z")


def inputs(dtype, accel, baro_alt, dt):
    """run() arguments of VarioKF: accel and baro_alt 1-D arrays, dt a scalar
    or an array of their length; returns three contiguous arrays of dtype. Real numbers
    only, as update() takes: None, strings, objects and complex values are refused (not
    converted to NaN or cut to their real part)."""
    if dt is None:
        raise ValueError("dt: give the sample period(s) in s, a scalar or an array (got None)")
    for name, v in (("accel", accel), ("baro_alt", baro_alt), ("dt", dt)):
        kind = np.asarray(v).dtype.kind
        if kind not in "biuf":
            raise ValueError(f"{name}: expected real numbers, got an array of "
                             f"{np.asarray(v).dtype}")
    accel = np.ascontiguousarray(accel, dtype=dtype)
    baro_alt = np.ascontiguousarray(baro_alt, dtype=dtype)
    dt_a = np.asarray(dt, dtype=dtype)
    if dt_a.ndim == 0:
        dt_a = np.full(accel.shape, dt_a, dtype=dtype) if accel.ndim == 1 else dt_a
    dt_a = np.ascontiguousarray(dt_a)
    shapes = {"accel": accel.shape, "baro_alt": baro_alt.shape, "dt": dt_a.shape}
    if accel.ndim != 1 or len(set(shapes.values())) != 1:
        seen = ", ".join(f"{k}{v}" for k, v in shapes.items())
        raise ValueError("run(): expected 1-D accel and baro_alt of equal length and dt a "
                         f"scalar or an array of that length, got shapes {seen}")
    return accel, baro_alt, dt_a


def check_start(kwargs):
    """VarioKF starts from z0 (or the first barometer sample) or state=; the
    attitude starts of the 3-D filters do not apply."""
    given = [k for k in ("init", "init_window", "q0") if k in kwargs]
    if given:
        raise ValueError(f"{', '.join(given)}: VarioKF has no attitude; it starts from z0 "
                         f"(None: the first barometer altitude) or state=")


def update_inputs(accel, baro_alt, dt):
    return tuple(_checks.check_scalar(n, v) for n, v in
                 (("accel", accel), ("baro_alt", baro_alt), ("dt", dt)))


def _p0(i):
    def check(name, p0, prior):
        try:
            p = tuple(p0)
            if len(p) != 3:
                raise ValueError
        except (TypeError, ValueError):
            raise ValueError(f"p0: must be three variances (z, v, b), got {p0!r}") from None
        return _checks.check_real(f"p0[{i}]", p[i], lo=0.0)
    return check


def _predict(name, predict, prior):
    _checks.check_choice("predict", predict, tuple(PREDICT))
    if predict == "seed":
        check_seed_stable(prior["var_z"], prior["var_acc"], prior["var_bias"])
    return predict


@dataclasses.dataclass(frozen=True)
class VarioSettings(SettingsRecord):
    """imf_vario_settings_t, member for member, in the C's units: VarioKF's keywords."""
    #                      default  unit         check                     to C
    var_z: float = setting(VAR_Z, "m^2", real(lo=0.0, lo_open=True))
    var_acc: float = setting(VAR_ACC, "(m/s^2)^2", real(lo=0.0))
    var_bias: float = setting(VAR_BIAS, "(m/s^2)^2", real(lo=0.0))
    p_z: float = setting(P0, "m^2", _p0(0), keyword="p0")
    p_v: float = setting(P0, "(m/s)^2", _p0(1), keyword="p0")
    p_b: float = setting(P0, "(m/s^2)^2", _p0(2), keyword="p0")
    z0: float = setting(None, "m", lambda name, v, prior: 0.0 if v is None
                        else _checks.check_real("z0", v), keyword="z0")
    v0: float = setting(0.0, "m/s", real())
    b0: float = setting(0.0, "m/s^2", real())
    z0_from_baro: int = setting(None, "", lambda name, v, prior: int(v is None), keyword="z0")
    predict: int = setting("seed", "", _predict, to_c=PREDICT.__getitem__, kw_only=True)


class VarioKF(ReferenceFilter):
    """Nair's variometer Kalman filter: altitude, climb rate and
    accelerometer bias from vertical acceleration and barometric altitude.

    VarioKF(var_z=300, var_acc=200, var_bias=1, p0=(1, 1, 1e5), z0=None,
    v0=0, b0=0, predict="seed"): var_z the barometer altitude variance (cm^2),
    var_acc the acceleration variance ((cm/s^2)^2), var_bias the bias
    variance added per step ((cm/s^2)^2), p0 the initial variances of z, v, b;
    z0 (cm) None takes the first barometer altitude; v0 (cm/s), b0 (cm/s^2).
    predict="seed" predicts the state as Nair writes it (v first, then z
    with the new v), "model" as its transition matrix F does.

    update(accel, baro_alt, dt): accel the net vertical acceleration (up
    positive, cm/s^2), baro_alt (cm), dt (s) since the previous sample.
    run(accel, baro_alt, dt): 1-D arrays, dt a scalar or an array. A sample
    with a non-finite input or a dt that is not > 0 is skipped (`skipped`).
    Setting `state` (or state=) keeps the start rule: with z0=None the first
    accepted sample still sets z; give z0 to continue from a set state.
    """
    kind = "vario"
    c_name = "imf_vario"
    state_names = ("z", "v", "b", "pzz", "pzv", "pzb", "pvv", "pvb", "pbb")

    @classmethod
    def _valid_state(cls, args, R, state):
        # state writes: the covariance's diagonal holds variances, which are not negative
        for n in ("pzz", "pvv", "pbb"):
            v = float(state[cls.state_names.index(n)])
            if v < 0.0:
                return f"{n} = {v!r}, a variance, must not be negative"
        return None

    def __init__(self, *args, dtype="float64", **kwargs):
        check_start(kwargs)
        super().__init__(*args, dtype=dtype, **kwargs)

    settings_type = VarioSettings
    _params = VarioSettings.keywords()

    def _init(self, s):
        R = self._R
        self.var_z = R(s.var_z)
        self.var_acc = R(s.var_acc)
        self.var_bias = R(s.var_bias)
        self.predict = PREDICT_MODEL if s.predict == PREDICT_MODEL else PREDICT_SEED
        self.started = 0 if s.z0_from_baro else 1
        self.z = R(s.z0)
        self.v = R(s.v0)
        self.b = R(s.b0)
        self.pzz = R(s.p_z)
        self.pzv = R(0.0)
        self.pzb = R(0.0)
        self.pvv = R(s.p_v)
        self.pvb = R(0.0)
        self.pbb = R(s.p_b)

    def _predict_covariance(self, x, dt):
        """Step 1: P = F P F^T + Q, with A = F P (rows 0 and 1; row 2 of F P is
        row 2 of P) and F's entries dt and h = -(-dt^2/2)."""
        R = self._R
        z, v, b, pzz, pzv, pzb, pvv, pvb, pbb = x
        dt2 = dt * dt
        dt3 = dt2 * dt
        dt4 = dt2 * dt2
        h = R(0.5) * dt2
        a00 = pzz + dt * pzv - h * pzb
        a01 = pzv + dt * pvv - h * pvb
        a02 = pzb + dt * pvb - h * pbb
        a11 = pvv - dt * pvb
        a12 = pvb - dt * pbb
        pzz = a00 + dt * a01 - h * a02 + R(0.25) * dt4 * self.var_acc
        pzv = a01 - dt * a02 + R(0.5) * dt3 * self.var_acc
        pzb = a02
        pvv = a11 - dt * a12 + dt2 * self.var_acc
        pvb = a12
        pbb = pbb + self.var_bias
        return [z, v, b, pzz, pzv, pzb, pvv, pvb, pbb]

    def _predict_state(self, x, accel, dt):
        # Step 2: a priori state, accel_real = accel_meas - b
        R = self._R
        acc = accel - x[2]
        if self.predict == PREDICT_MODEL:
            # the first row of F: z += v dt + (a - b) dt^2/2, with the old v
            x[0] = x[0] + x[1] * dt + R(0.5) * dt * dt * acc
            x[1] = x[1] + acc * dt
        else:
            # as Nair writes it: v first, then z with the new v
            x[1] = x[1] + acc * dt
            x[0] = x[0] + x[1] * dt
        return x

    def _correct(self, x, baro_alt):
        """Steps 3-7: innovation, its covariance, gain, a posteriori state and
        covariance P = (I - K H) P."""
        R = self._R
        z, v, b, pzz, pzv, pzb, pvv, pvb, pbb = x
        # Step 3: y = m - H x
        y = baro_alt - z
        # Step 4: s = pzz + sigma_z^2
        s = pzz + self.var_z
        # Step 5: K = P H^T / s
        inv_s = R(1.0) / s
        kz = pzz * inv_s
        kv = pzv * inv_s
        kb = pzb * inv_s
        # Step 6: x = x + K y
        z = z + kz * y
        v = v + kv * y
        b = b + kb * y
        # Step 7: P = P - K [pzz pzv pzb]
        return [z, v, b, pzz - kz * pzz, pzv - kz * pzv, pzb - kz * pzb,
                pvv - kv * pzv, pvb - kv * pzb, pbb - kb * pzb]

    def _update(self, accel, baro_alt, dt):
        R = self._R
        if not (isfinite(accel, baro_alt, dt) and dt > R(0.0)):
            self._skip()
            return
        if not self.started:
            # z0 = the first barometer altitude
            self.z = baro_alt
            self.started = 1
            return
        x = [getattr(self, n) for n in self.state_names]
        x = self._predict_covariance(x, dt)
        x = self._predict_state(x, accel, dt)
        x = self._correct(x, baro_alt)
        if not isfinite(*x):
            self._skip()
            return
        for n, val in zip(self.state_names, x):
            setattr(self, n, val)

    def update(self, accel, baro_alt, dt):
        """One barometer sample: accel (cm/s^2, up positive), baro_alt (cm), dt (s)."""
        vals = update_inputs(accel, baro_alt, dt)
        R = self._R
        with np.errstate(all="ignore"):
            self._update(*[R(v) for v in vals])

    def run(self, accel, baro_alt, dt):
        """All samples: accel, baro_alt 1-D arrays, dt scalar or array; returns
        the (N, 9) trajectory of the state."""
        cols = np.column_stack(inputs(self.dtype, accel, baro_alt, dt))
        out = np.empty((cols.shape[0], len(self.state_names)), dtype=self.dtype)
        rows = cols.tolist() if self.dtype == "float64" else cols
        names = self.state_names
        with np.errstate(all="ignore"):
            for k, row in enumerate(rows):
                self._update(*row)
                out[k] = [getattr(self, s) for s in names]
        return out


def convention_sign(convention):
    _checks.check_choice("convention", convention, tuple(CONVENTIONS))
    return CONVENTIONS[convention]


def vertical_accel_step(R, q0, q1, q2, q3, ax, ay, az, sign, one_g, scale):
    """Twin of imf_vertical_accel: (sign az_earth - one_g) scale with
    az_earth = (2q1q3 - 2q0q2) ax + (2q2q3 + 2q0q1) ay + (q0^2 - q1^2 - q2^2 + q3^2) az."""
    # Nair (2016): the third row of the rotation matrix of q, times a
    az_earth = ((R(2.0) * q1 * q3 - R(2.0) * q0 * q2) * ax
                + (R(2.0) * q2 * q3 + R(2.0) * q0 * q1) * ay
                + (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * az)
    return (sign * az_earth - one_g) * scale


def vertical_inputs(dtype, q, acc):
    q = np.ascontiguousarray(q, dtype=dtype)
    acc = np.ascontiguousarray(acc, dtype=dtype)
    if q.ndim != 2 or q.shape[1] != 4 or acc.ndim != 2 or acc.shape[1] != 3 \
            or q.shape[0] != acc.shape[0]:
        raise ValueError("vertical_accel(): expected q (N, 4) and acc (N, 3) with the same N, "
                         f"got shapes q{q.shape}, acc{acc.shape}")
    return q, acc


def vertical_params(convention, one_g, scale):
    sign = convention_sign(convention)
    one_g = _checks.check_real("one_g", one_g, lo=0.0, lo_open=True)
    scale = _checks.check_real("scale", scale)
    return sign, one_g, scale


def vertical_accel(q, acc, convention="nwu", one_g=1.0, scale=980.0, dtype="float64"):
    """Net vertical acceleration, up positive, for every sample: q (N, 4)
    sensor -> earth quaternions [w, x, y, z], acc (N, 3) accelerometer in the
    unit of one_g; the result is in that unit times scale (default: g in,
    cm/s^2 out with Nair's 980). convention: "nwu" or "enu" (imufuse:
    +1 g along earth z at rest), "ned_seed" (Nair's board: +1 g on D at
    rest), "ned" (specific force: -1 g on D at rest)."""
    dtype = _checks.check_dtype(dtype)
    sign, one_g, scale = vertical_params(convention, one_g, scale)
    q, acc = vertical_inputs(dtype, q, acc)
    R = np.float32 if dtype == "float32" else float
    out = np.empty(q.shape[0], dtype=dtype)
    qs = q.tolist() if R is float else q
    accs = acc.tolist() if R is float else acc
    s, g, c = R(sign), R(one_g), R(scale)
    with np.errstate(all="ignore"):
        for k in range(q.shape[0]):
            out[k] = vertical_accel_step(R, *qs[k], *accs[k], s, g, c)
    return _checks.canonical_nan(out)
