"""Nair's variometer pipeline over arrays: barometric altitude from pressure (the ISA
troposphere), the gravity-compensated vertical acceleration and its ``|a| - 1`` alternative,
the down-sampling to the barometer rate, the barometer-only Kalman filter of Nair's
starting point, VarioResult and `run` (the whole pipeline over one recording)."""
from dataclasses import dataclass, field

import numpy as np

import imufuse_c

from .. import reference
from ..shared import checks as _checks

GRAVITY = 9.80665
#: ISA sea-level pressure, Pa
P_REF = 101325.0
# standard atmosphere (troposphere): T0 = 288.15 K, lapse L = 0.0065 K/m,
# exponent R L / (g M) with R = 8.3144598 J/(mol K), M = 0.0289644 kg/mol
_T0_L = 288.15 / 0.0065
_EXP = 8.3144598 * 0.0065 / (GRAVITY * 0.0289644)


def pressure_to_altitude(p, p_ref=P_REF):
    """Altitude (m) above the level of p_ref (Pa) for pressure p (Pa):
    h = T0/L (1 - (p/p_ref)^(R L / g M)), the ISA troposphere."""
    p_ref = _checks.check_real("p_ref", p_ref, lo=0.0, lo_open=True)
    p = np.asarray(p, dtype=float)
    with np.errstate(invalid="ignore"):
        return _T0_L * (1.0 - (p / p_ref) ** _EXP)


def altitude_to_pressure(h, p_ref=P_REF):
    """Inverse of :func:`pressure_to_altitude`: pressure (Pa) at altitude h (m)."""
    p_ref = _checks.check_real("p_ref", p_ref, lo=0.0, lo_open=True)
    h = np.asarray(h, dtype=float)
    return p_ref * (1.0 - h / _T0_L) ** (1.0 / _EXP)


def _modules(backend):
    _checks.check_choice("backend", backend, ("c", "reference"))
    return imufuse_c if backend == "c" else reference


def vertical_acceleration(q, acc, convention="nwu", one_g=1.0, scale=100.0 * GRAVITY,
                          backend="c", dtype="float64"):
    """Nair's gravity-compensated vertical acceleration, up positive, of
    every sample (default: acc in g, result in cm/s^2). See
    imufuse.reference.vertical_accel for the conventions."""
    return _modules(backend).vertical_accel(q, acc, convention, one_g, scale, dtype=dtype)


def norm_accel(acc, one_g=1.0, scale=100.0 * GRAVITY):
    """Nair's first idea, (|a| - 1 g) scale: right only when the
    acceleration is vertical (fails in banked turns)."""
    acc = np.asarray(acc, dtype=float)
    return (np.linalg.norm(acc, axis=1) - one_g) * scale


def decimate(x, idx):
    """Low-pass and down-sample: for each index idx[j], the mean of
    x[idx[j-1]+1 .. idx[j]] (the samples since the previous one; x[idx[0]]
    for the first)."""
    x = np.asarray(x, dtype=float)
    idx = np.asarray(idx)
    c = np.concatenate([[0.0], np.cumsum(x)])
    lo = np.concatenate([[idx[0]], idx[:-1] + 1])
    return (c[idx + 1] - c[lo]) / (idx + 1 - lo)


def baro_kf(alt, dt, var_z=300.0, var_acc=200.0, p0=(1.0, 1.0)):
    """Barometer-only two-state Kalman filter (z, v), Nair's starting
    point (Wikipedia's example: F = [[1, dt], [0, 1]], Q = G G^T var_acc with
    G = (dt^2/2, dt), H = [1 0], R = var_z). alt (M,) cm, dt scalar or (M,)
    s; returns (M, 2): z (cm), v (cm/s). z0 = the first altitude."""
    alt = np.asarray(alt, dtype=float)
    dt = np.broadcast_to(np.asarray(dt, dtype=float), alt.shape)
    x = np.array([alt[0], 0.0])
    P = np.diag(np.asarray(p0, dtype=float))
    out = np.empty((alt.size, 2))
    out[0] = x
    for k in range(1, alt.size):
        d = dt[k]
        F = np.array([[1.0, d], [0.0, 1.0]])
        G = np.array([0.5 * d * d, d])
        x = F @ x
        P = F @ P @ F.T + np.outer(G, G) * var_acc
        s = P[0, 0] + var_z
        K = P[:, 0] / s
        x = x + K * (alt[k] - x[0])
        P = P - np.outer(K, P[0])
        out[k] = x
    return out


@dataclass(frozen=True)
class VarioResult:
    """Per barometer sample: t (s), baro_alt (m, the measurement), altitude
    (m), climb (m/s), bias (m/s^2: the accelerometer's vertical bias), vacc
    (m/s^2: the down-sampled vertical acceleration fed to the filter), and
    the IMU-rate quaternions q (N, 4) and vertical acceleration vacc_imu
    (m/s^2); state (M, 9): the Kalman filter state in its own units; imu_skipped,
    kf_skipped: the samples the attitude filter and the Kalman filter rejected (non-finite
    input: their state was kept through them)."""
    t: np.ndarray
    baro_alt: np.ndarray
    altitude: np.ndarray
    climb: np.ndarray
    bias: np.ndarray
    vacc: np.ndarray
    q: np.ndarray
    vacc_imu: np.ndarray
    state: np.ndarray
    imu_skipped: int = 0
    kf_skipped: int = 0
    notes: list = field(default_factory=list)   # run_log: what reading the log said


def run(gyr, acc, baro_alt, *, rate=None, t=None, mag=None, filter="MadgwickIMU",
        filter_params=None, convention="nwu", acc_unit_g=1.0, kf_params=None,
        backend="c", dtype="float64", vertical="earth"):
    """Nair's pipeline over one recording.

    gyr, acc (N, 3) (rad/s; acc in units where 1 g = acc_unit_g), mag (N, 3)
    for AHRS filters; baro_alt (N,) barometer altitude in m on the rows where
    the barometer sampled and NaN elsewhere. rate (Hz) or t (N,) s.
    filter: an imufuse quaternion filter (kind imu or ahrs) constructed with
    dt = 1/rate and filter_params (e.g. {"beta": 0.1, "acc_gate": (0.6, 1.4)}).
    kf_params: VarioKF keywords. vertical="earth" is Nair's earth-frame
    vertical acceleration, "norm" the |a| - 1 alternative (for comparison).
    """
    mod = _modules(backend)
    gyr = np.asarray(gyr, dtype=float)
    acc = np.asarray(acc, dtype=float)
    baro_alt = np.asarray(baro_alt, dtype=float)
    n = gyr.shape[0]
    if baro_alt.shape != (n,):
        raise ValueError(f"baro_alt: expected shape ({n},) like gyr, got {baro_alt.shape}")
    if t is None:
        if rate is None:
            raise ValueError("rate, t: give the IMU rate (Hz) or the sample times")
        rate = _checks.check_real("rate", rate, lo=0.0, lo_open=True)
        t = np.arange(n) / rate
    else:
        t = np.asarray(t, dtype=float)
        if t.shape != (n,) or not np.all(np.diff(t) > 0):
            raise ValueError("t: must be (N,) strictly increasing sample times")
        if rate is None:
            rate = 1.0 / float(np.median(np.diff(t)))
    idx = np.flatnonzero(np.isfinite(baro_alt))
    if idx.size < 2:
        raise ValueError(f"baro_alt: need at least two barometer samples (finite "
                         f"altitudes), got {idx.size}")
    _checks.check_choice("vertical", vertical, ("earth", "norm"))
    cls = getattr(mod, filter, None)
    if cls is None or getattr(cls, "kind", None) not in ("imu", "ahrs") \
            or tuple(cls.state_names[:4]) != ("q0", "q1", "q2", "q3"):
        raise ValueError(f"filter: must be an imufuse quaternion filter (kind imu or ahrs), "
                         f"got {filter!r}")
    f = cls(dt=1.0 / rate, **(filter_params or {}), dtype=dtype)
    if cls.kind == "ahrs":
        if mag is None:
            raise ValueError(f"mag: {filter} needs magnetometer samples")
        S = f.run(gyr, acc, np.asarray(mag, dtype=float))
    else:
        S = f.run(gyr, acc)
    q = np.asarray(S[:, :4], dtype=float)
    scale = 100.0 * GRAVITY / acc_unit_g     # cm/s^2 per accelerometer unit
    if vertical == "earth":
        va = np.asarray(mod.vertical_accel(q, acc, convention, acc_unit_g, scale,
                                           dtype=dtype), dtype=float)
    else:
        va = norm_accel(acc, acc_unit_g, scale)
    a_b = decimate(va, idx)
    tb = t[idx]
    dt = np.diff(tb, prepend=tb[0] - (tb[1] - tb[0]))
    kf = mod.VarioKF(**(kf_params or {}), dtype=dtype)
    X = np.asarray(kf.run(a_b, baro_alt[idx] * 100.0, dt), dtype=float)
    return VarioResult(t=tb, baro_alt=baro_alt[idx], altitude=X[:, 0] / 100.0,
                       climb=X[:, 1] / 100.0, bias=X[:, 2] / 100.0, vacc=a_b / 100.0,
                       q=q, vacc_imu=va / 100.0, state=X, imu_skipped=int(f.skipped),
                       kf_skipped=int(kf.skipped))
