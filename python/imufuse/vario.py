"""The variometer pipeline of Hari Nair (2016), host side.

    IMU (200-250 Hz) -> quaternion filter (any imufuse IMU/AHRS filter, with
    the accelerometer gate) -> gravity-compensated vertical acceleration ->
    low-pass and down-sample to the barometer rate (the mean over the
    barometer interval) -> VarioKF once per barometer sample.

Barometric altitude comes from pressure by the standard atmosphere
(:func:`pressure_to_altitude`, reference pressure configurable). The Kalman
filter works in Nair's units (cm, cm/s, cm/s^2); results are given in
m, m/s and m/s^2.

Also here, for the measurements of docs/vario.md: the barometer-only
two-state Kalman filter of Nair's starting point (:func:`baro_kf`, the
Wikipedia constant-acceleration example) and Nair's rejected
alternative ``|a| - 1`` (:func:`norm_accel`).
"""
import math
import os
from dataclasses import dataclass, field, replace

import numpy as np

import imufuse_c

from . import _checks, reference
from ._atomic import replacing
from .plots import _plt, _save

__all__ = ["P_REF", "pressure_to_altitude", "altitude_to_pressure", "VarioResult",
           "vertical_acceleration", "norm_accel", "decimate", "baro_kf", "run",
           "read_vario_log", "run_log"]

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


# ---- logs ------------------------------------------------------------------------------

from .io import LogError as _LogError  # noqa: E402
from .io import read_csv_rows as _read_csv_rows  # noqa: E402
from . import io as _io  # noqa: E402
from .session import ReadOptions, Session  # noqa: E402


class VarioLogError(_LogError):
    """A vario log that cannot be used (kind "file" or "data", as io.LogError)."""


#: the barometer columns: name -> the headers taken for it (any case; a unit in brackets)
BARO_NAMES = {"pressure": ("pressure", "baro_pressure", "pressure_pa", "press"),
              "baro_alt": ("baro_alt", "baro_altitude", "altitude_baro", "baro")}
_PRESSURE_UNITS = {None: 1.0, "pa": 1.0, "hpa": 100.0, "mbar": 100.0, "kpa": 1000.0}


def _baro_column(path, header, given):
    """(header index, name, factor to Pa or m) of the barometer column."""
    hits = []
    for name in BARO_NAMES:
        if name in given:
            h = given[name]
            if h not in header:
                raise VarioLogError(f"{path}: --columns {name}={h!r}: no such column; columns "
                                    f"found: {', '.join(map(repr, header))}", "usage")
            hits.append((header.index(h), name))
            continue
        for i, h in enumerate(header):
            base, unit = _io.split_unit(h)
            if _io._norm(base) not in {s for names in BARO_NAMES.values() for s in names}:
                continue
            # the unit decides where the header says one: "Baro (hPa)" is a pressure
            kind = ("pressure" if unit is not None and unit.lower() in _PRESSURE_UNITS else
                    "baro_alt" if unit is not None and unit.lower() == "m" else
                    "pressure" if _io._norm(base) in BARO_NAMES["pressure"] else "baro_alt")
            if kind == name:
                hits.append((i, name))
    if len(hits) != 1:
        found = ", ".join(repr(header[i]) for i, _ in hits) or "none"
        raise VarioLogError(f"{path}: need exactly one barometer column, pressure (Pa, hPa, kPa) "
                            f"or baro_alt (m); found {found} (name it with --columns "
                            'pressure="HEADER" or baro_alt="HEADER")')
    i, name = hits[0]
    unit = _io.split_unit(header[i])[1]
    if name == "pressure":
        key = None if unit is None else unit.lower()
        if key not in _PRESSURE_UNITS:
            raise VarioLogError(f"{path}: column {header[i]!r}: unknown pressure unit {unit!r}; "
                                "expected Pa, hPa, mbar or kPa")
        return i, name, _PRESSURE_UNITS[key]
    if unit is not None and unit.lower() != "m":
        raise VarioLogError(f"{path}: column {header[i]!r}: the barometric altitude must be in m, "
                            f"got {unit!r}")
    return i, name, 1.0


def read_vario_log(path, gyr_unit=None, acc_unit=None, p_ref=P_REF, *, columns=None,
                   time_unit=None, strict=False):
    """Read a CSV log for the vario: time, gyr_*, acc_*, optional mag_*, read as every
    imufuse command reads them (imufuse.session: headers such as 'Gyroscope X (deg/s)',
    units from the header, `columns` {name: header}, plausibility notes), and a barometer
    column `pressure` (Pa, hPa or kPa by its header) or `baro_alt` (m) filled on the rows
    where the barometer sampled and empty elsewhere. gyr_unit, acc_unit, time_unit: None =
    from the header, else rad/s, g, s. Returns a dict of arrays (gyro rad/s, acc g,
    baro_alt m with NaN on rows without a sample) and notes."""
    if gyr_unit is not None:
        _checks.check_choice("gyr_unit", gyr_unit, ("rad/s", "deg/s"))
    if acc_unit is not None:
        _checks.check_choice("acc_unit", acc_unit, ("g", "m/s2", "m/s^2"))
    given = dict(columns or {})
    baro_given = {k: given.pop(k) for k in BARO_NAMES if k in given}
    try:
        s = Session(path, ReadOptions(gyr_unit=gyr_unit, acc_unit=acc_unit,
                                      time_unit=time_unit, columns=given, strict=strict))
        _io.require(s.log, _io.GYR + _io.ACC)
        if "time" not in s.log.sources:
            raise VarioLogError(f"{path}: no time column; the vario needs the time of every "
                                'sample (name it with --columns time="HEADER")')
        rows = ([] if os.path.splitext(str(path))[1].lower() in (".npz", ".h5", ".hdf5", ".hdf")
                else [r for r in _read_csv_rows(path) if not r[0].lstrip().startswith("#")])
    except _LogError as e:
        raise VarioLogError(str(e), e.kind) from None
    log = s.log
    if not rows or os.path.splitext(str(path))[1].lower() in (".npz", ".h5", ".hdf5", ".hdf"):
        raise VarioLogError(f"{path}: no barometer: the vario reads CSV logs with a barometer "
                            "column (pressure or baro_alt) on the rows where it sampled")
    header = [h.strip() for h in rows[0]]
    col, name, factor = _baro_column(path, header, baro_given)
    if len(rows) - 1 != len(log):
        raise VarioLogError(f"{path}: {len(rows) - 1} rows of CSV, {len(log)} samples read; "
                            "the vario reads comma-separated logs")
    b = np.empty(len(log))
    for k, r in enumerate(rows[1:]):
        c = r[col].strip() if col < len(r) else ""
        if c == "":
            b[k] = np.nan
            continue
        try:
            b[k] = float(c)
        except ValueError:
            raise VarioLogError(f"{path}:{k + 2}: column {header[col]}: not a number: "
                                f"{c!r}") from None
    b = b * factor
    if name == "pressure":
        # a barometer reads 1 to 200 kPa (the atmosphere from 30 km up to a deep mine, with
        # margin); hPa or kPa logged as Pa would be 100 or 1000 times off
        ok = np.isfinite(b)
        v = b[ok]
        med = float(np.partition(v, v.size // 2)[v.size // 2]) if v.size else math.nan
        if ok.any() and not 1e4 <= med <= 2e5:
            unit = (" (it looks like hPa: write the header 'pressure (hPa)')"
                    if 100.0 <= med <= 2000.0 else
                    " (it looks like kPa: write the header 'pressure (kPa)')"
                    if 10.0 <= med <= 200.0 else "")
            raise VarioLogError(f"{path}: column {header[col]}: median {med:g} Pa is not an air "
                                f"pressure a barometer reads (10 kPa to 200 kPa){unit}")
        bad = np.flatnonzero(ok & ~((b >= 1e3) & (b <= 2e5)))
        if bad.size:
            k = int(bad[0])
            raise VarioLogError(f"{path}:{k + 2}: column pressure: {b[k]:g} Pa is outside a "
                                "barometer's range (1 kPa to 200 kPa)")
    alt = pressure_to_altitude(b, p_ref) if name == "pressure" else b
    return dict(t=np.asarray(log.t), gyr=np.array(log.gyr), acc=np.array(log.acc),
                mag=None if log.mag is None else np.array(log.mag), baro_alt=alt,
                baro_column=header[col], notes=list(s.notes))


def run_log(path, out_csv, *, plot=None, gyr_unit=None, acc_unit=None, p_ref=P_REF,
            filter="MadgwickIMU", filter_params=None, kf_params=None, convention="nwu",
            columns=None, time_unit=None, strict=False):
    """`imufuse vario`: run the pipeline over a log, write time, baro_alt,
    altitude (m), climb (m/s), bias (m/s^2) per barometer sample to out_csv,
    and a PNG plot when `plot` is a path. Returns the VarioResult."""
    log = read_vario_log(path, gyr_unit, acc_unit, p_ref, columns=columns, time_unit=time_unit,
                         strict=strict)
    n_baro = int(np.count_nonzero(np.isfinite(log["baro_alt"])))
    if n_baro < 2:
        raise VarioLogError(f"{path}: {n_baro} usable barometer samples in column "
                            f"{log['baro_column']} (finite values; a pressure must be > 0); "
                            "the vario needs at least two")
    res = run(log["gyr"], log["acc"], log["baro_alt"], t=log["t"], mag=log["mag"],
              filter=filter, filter_params=filter_params, kf_params=kf_params,
              convention=convention)
    if res.kf_skipped >= len(res.t):
        raise VarioLogError(f"{path}: the Kalman filter rejected every one of the "
                            f"{len(res.t)} barometer samples (a non-finite vertical "
                            "acceleration or altitude in each: check the accelerometer "
                            "columns): nothing was estimated")
    M = np.column_stack([res.t, res.baro_alt, res.altitude, res.climb, res.bias])
    with replacing(out_csv) as tmp:
        np.savetxt(tmp, M, fmt="%.9g", delimiter=",",
                   header="time,baro_alt,altitude,climb,bias", comments="")
    if plot:
        plot_vario(plot, res)
    return replace(res, notes=log["notes"])


def plot_vario(path, res, truth=None):
    """Altitude (barometer and filter) and climb rate over time, PNG."""
    plt = _plt()
    fig, ax = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    ax[0].plot(res.t, res.baro_alt, ".", ms=2, color="0.6", label="barometer")
    ax[0].plot(res.t, res.altitude, label="Kalman filter")
    ax[0].set_ylabel("altitude, m")
    ax[0].legend(loc="best")
    ax[1].plot(res.t, res.climb)
    if truth is not None:
        ax[1].plot(truth[0], truth[1], "--", label="truth")
        ax[1].legend(loc="best")
    ax[1].set_ylabel("climb, m/s")
    ax[2].plot(res.t, res.bias)
    ax[2].set_ylabel("acc bias, m/s^2")
    ax[2].set_xlabel("time, s")
    _save(fig, path)

