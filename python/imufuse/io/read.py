"""`read_log`: one log of any format (CSV through imufuse.io.text, NPZ and HDF5 through
imufuse.io.arrays) into a Log with units converted, time checked, the sample period found
and the plausibility notes added; `describe` (what was read from where) and `axis_inputs`
(the inputs of the single-axis filters)."""
import math
import os

import numpy as np

from ..plausible import check_log
from .arrays import _read_arrays
from .columns import _units, require, split_unit
from .log import ACC, ACC_UNITS, GYR, GYR_UNITS, MAG, QUAT, TIME_UNITS, Log, LogError
from .text import _read_csv


def read_log(path, gyr_unit=None, acc_unit=None, rate=None, *, columns=None,
             fixed_rate=False, time_unit=None, need_time=True):
    """Read a log; return a Log with units converted (gyro rad/s, acc g, time s).

    gyr_unit, acc_unit, time_unit: None to take them from the header (else rad/s,
    g, s); rate: Hz, a fixed sample rate (the time column is then not needed);
    columns: {name: header} column map; fixed_rate: run at the median interval
    even when the time column is there; need_time=False: a log without a time column
    or rate is read with dt None (for calibration, which needs no time)."""
    user_rate = rate
    if gyr_unit is not None and gyr_unit not in GYR_UNITS:
        raise ValueError(f"gyr_unit: must be one of {', '.join(GYR_UNITS)}, got {gyr_unit!r}")
    if acc_unit is not None and acc_unit not in ACC_UNITS:
        raise ValueError(f"acc_unit: must be one of g, m/s2, got {acc_unit!r}")
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise ValueError(f"time_unit: must be one of {', '.join(TIME_UNITS)}, got {time_unit!r}")
    if rate is not None and not (isinstance(rate, (int, float)) and math.isfinite(rate)
                                 and 0 < rate <= 1e9 and 1.0 / rate > 0):
        raise ValueError(f"rate: must be a positive number of Hz (at most 1e9), got {rate!r}")
    path = os.fspath(path)
    if not os.path.exists(path):
        raise LogError(f"{path}: no such file", "file")
    if os.path.isdir(path):
        raise LogError(f"{path}: is a directory, not a log file", "file")
    ext = os.path.splitext(path)[1].lower()
    warnings, ref_frame, file_rate = [], None, None
    if ext in (".npz", ".h5", ".hdf5", ".hdf"):
        cols, header, sources, file_rate = _read_arrays(path)
        where = lambda k: f"{path}: sample {k}"  # noqa: E731
        ref_frame = "ENU" if "q_w" in cols else None
        default_acc = "m/s^2"
    else:
        cols, header, sources, notes, where = _read_csv(path, columns, time_unit)
        warnings += notes
        default_acc = "g"
    log = Log(path, cols, list(header), sources=sources, ref_frame=ref_frame)
    if len(log) == 0:
        raise LogError(f"{path}: no samples (every array of the log has 0 rows)")
    try:
        log.units["gyr"] = _units(cols, sources, "gyr", GYR, gyr_unit, GYR_UNITS, "rad/s", warnings)
        log.units["acc"] = _units(cols, sources, "acc", ACC, acc_unit, ACC_UNITS, default_acc,
                                  warnings)
        log.units["time"] = _units(cols, sources, "time", ("time",), time_unit, TIME_UNITS, "s",
                                   warnings)
    except LogError as e:
        raise LogError(f"{path}: {e}") from None
    mu = {split_unit(sources[n])[1] for n in MAG if n in sources} - {None}
    log.units["mag"] = (mu.pop() if len(mu) == 1 else ("uT" if ext == ".npz" else "any"), "header")
    if "movement" in cols:
        m = cols["movement"]
        if not np.all(np.isin(m, (0.0, 1.0))):
            k = int(np.argmax(~np.isin(m, (0.0, 1.0))))
            raise LogError(f"{where(k)}: movement must be 0 or 1, got {m[k]!r}")
    if "time" in cols:
        bad = _time_problem(cols["time"], where)
        if bad is not None and user_rate is None and need_time:
            raise LogError(f"{bad} (or give the sample rate, --rate HZ, to run without the "
                           "time column)")
        if bad is not None:
            # a rate given supersedes the column (the times become k / rate), and a reader
            # that needs no time does without it: said aloud, never silently
            warnings.append(f"{bad}; the time column is not used" + (
                f": --rate {user_rate:g} Hz gives every sample's time" if user_rate else ""))
            del cols["time"]
            log.sources.pop("time", None)
    time_cols = cols.get("time")      # the file's own times, before a rate generates any
    d = np.diff(time_cols) if time_cols is not None else np.empty(0)
    if rate is None and file_rate is not None and "time" not in cols:
        rate = file_rate
    if rate is not None:
        log.dt = 1.0 / rate
        log.fixed_rate = True
        if "time" not in cols:
            cols["time"] = np.arange(len(log)) * log.dt
            log.sources["time"] = f"k / {rate:g} Hz"
    elif "time" in cols and (d.size or need_time):   # one sample needs no rate to calibrate
        if d.size == 0:
            raise LogError(f"{path}: one sample: cannot derive the rate from time; give --rate")
        med = float(np.median(d))
        # decimal time stamps rarely difference to the exact period: the rate
        # is 1/median rounded to 9 significant digits (100 Hz, not 99.99999999999991)
        r = float(f"{1.0 / med:.9g}")
        if not (math.isfinite(r) and r > 0 and math.isfinite(1.0 / r) and 1.0 / r > 0):
            raise LogError(f"{path}: median sample interval {med!r} s gives no usable rate")
        log.dt = 1.0 / r
        log.fixed_rate = bool(fixed_rate)
        if np.max(np.abs(d - med)) > 0.2 * med:
            warnings.append(f"sample intervals vary from {d.min():.6g} to {d.max():.6g} s; "
                            + (f"the filters use the median {log.dt:.6g} s (--fixed-rate)"
                               if fixed_rate else "the filters use each sample's own interval"))
    elif not need_time:
        log.dt = None
    else:
        raise LogError(f"{path}: no time column (found {', '.join(map(repr, header[:12]))}); "
                       "give the sample rate (--rate HZ), or name the time column "
                       '(--columns time="HEADER")')
    # the usual unit and rate mistakes, named with the option that fixes them
    log.suspicions = check_log(log, user_rate, file_rate, time_cols, where)
    warnings += log.suspicions
    log.warnings = warnings
    return log


def _time_problem(t, where):
    """None if the times t are finite and increase strictly with finite intervals, else the
    message naming the first sample that breaks it."""
    if not np.all(np.isfinite(t)):
        k = int(np.argmax(~np.isfinite(t)))
        return f"{where(k)}: time is not finite: {float(t[k])!r}"
    with np.errstate(over="ignore", invalid="ignore"):
        d = np.diff(t)
    if np.any(~(d > 0)):
        k = int(np.argmax(~(d > 0))) + 1
        return (f"{where(k)}: time does not increase ({float(t[k - 1])!r} then "
                f"{float(t[k])!r}); times must increase strictly")
    if not np.all(np.isfinite(d)):
        k = int(np.argmax(~np.isfinite(d))) + 1
        return (f"{where(k)}: the interval from {float(t[k - 1])!r} to {float(t[k])!r} s is "
                "not a finite number")
    return None


def describe(log):
    """One line: what was read from where, with units."""
    parts = []
    for kind, names in (("gyr", GYR), ("acc", ACC), ("mag", MAG), ("q", QUAT)):
        if log.has(*names):
            src = [log.sources.get(n, n) for n in names]
            u = log.units.get(kind)
            unit = f" [{u[0]}, {u[1]}]" if u else ""
            same = all(s == n for s, n in zip(src, names))
            parts.append(f"{kind}{unit}" + ("" if same else f" from {src[0]!r}..."))
    return ", ".join(parts)


def axis_inputs(log, axis="x"):
    """(rate, angle, source) for the single-axis filters (see imufuse.io)."""
    if log.has("rate", "angle"):
        return log.columns["rate"], log.columns["angle"], "columns rate, angle"
    if axis == "x":
        need = ("gyr_x", "acc_y", "acc_z")
        require(log, need, "(single-axis filters need rate and angle, or gyr_x, acc_y, acc_z)")
        c = log.columns
        return c["gyr_x"], np.arctan2(c["acc_y"], c["acc_z"]), "gyr_x, atan2(acc_y, acc_z)"
    if axis == "y":
        need = ("gyr_y", "acc_x", "acc_z")
        require(log, need, "(single-axis filters need rate and angle, or gyr_y, acc_x, acc_z)")
        c = log.columns
        return c["gyr_y"], np.arctan2(-c["acc_x"], c["acc_z"]), "gyr_y, atan2(-acc_x, acc_z)"
    raise ValueError(f"axis: must be 'x' or 'y', got {axis!r}")
