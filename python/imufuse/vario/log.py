"""`imufuse vario` over a log file: reading a vario log (the IMU columns as every command
reads them, through imufuse.session, and a barometer column, pressure or baro_alt),
running the pipeline over it, writing its CSV and plotting it."""
import math
import os
from dataclasses import replace

import numpy as np

from ..shared import checks as _checks
from .. import io as _io
from ..shared.atomic import replacing
from ..io import LogError as _LogError
from ..io import read_csv_rows as _read_csv_rows
from ..plots import _plt, _save
from ..session import ReadOptions, Session
from .pipeline import P_REF, pressure_to_altitude, run


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
