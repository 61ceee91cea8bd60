"""Log files: reading IMU logs and writing filter outputs as CSV.

A log (DESIGN.md, "Log files") is CSV with a header row; columns by name, any
order, extra columns ignored:
  time                     s (optional when a sample rate is given)
  gyr_x gyr_y gyr_z        rad/s or deg/s (gyr_unit)
  acc_x acc_y acc_z        g or m/s^2 (acc_unit)
  mag_x mag_y mag_z        optional, any unit
  q_w q_x q_y q_z          optional reference orientation, body -> earth
  rate angle               optional single-axis inputs (rad/s, rad) for the 1D filters
Values must be numbers; "nan" and "inf" are numbers (the filters skip such
samples). Filters run at a fixed period: 1/rate when a rate is given, else
1/(1/median interval of `time`, rounded to 9 significant digits); time must
increase strictly.

Single-axis filters read `rate` and `angle` when both are present; otherwise
they are derived (axis "x": rate = gyr_x, angle = atan2(acc_y, acc_z), the
roll; axis "y": rate = gyr_y, angle = atan2(-acc_x, acc_z), the pitch; both
exact for rotation about that axis alone).
"""
import csv
import difflib
import math
import os
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

GRAVITY = 9.80665
GYR = ("gyr_x", "gyr_y", "gyr_z")
ACC = ("acc_x", "acc_y", "acc_z")
MAG = ("mag_x", "mag_y", "mag_z")
QUAT = ("q_w", "q_x", "q_y", "q_z")
KNOWN = ("time", *GYR, *ACC, *MAG, *QUAT, "rate", "angle")
GYR_UNITS = ("rad/s", "deg/s")
ACC_UNITS = ("g", "m/s2", "m/s^2")


class LogError(ValueError):
    """A log that cannot be used; `kind` is "file" (missing, unreadable) or
    "data" (columns, values, time)."""

    def __init__(self, message, kind="data"):
        super().__init__(message)
        self.kind = kind


@dataclass
class Log:
    path: str
    columns: dict                 # known column name -> (N,) float64, units converted
    header: list                  # every column of the file, in order
    dt: Optional[float] = None    # fixed sample period used by the filters, s
    warnings: list = field(default_factory=list)

    def __len__(self):
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def has(self, *names):
        return all(n in self.columns for n in names)

    def vec(self, names):
        return np.column_stack([self.columns[n] for n in names])

    @property
    def t(self):
        """Sample times, s: the time column, else k * dt."""
        if "time" in self.columns:
            return self.columns["time"]
        return np.arange(len(self)) * self.dt

    @property
    def gyr(self):
        return self.vec(GYR)

    @property
    def acc(self):
        return self.vec(ACC)

    @property
    def mag(self):
        return self.vec(MAG) if self.has(*MAG) else None

    @property
    def q_ref(self):
        return self.vec(QUAT) if self.has(*QUAT) else None


def _missing(names, header):
    msgs = []
    for n in names:
        unknown = [h for h in header if h not in KNOWN]
        close = difflib.get_close_matches(n, unknown, n=2, cutoff=0.6)
        lower = [h for h in unknown if h.strip().lower() == n]
        close = lower or close
        msgs.append(f"{n}" + (f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""))
    return msgs


def require(log, names, why=""):
    """LogError naming every missing column of `names`, with close matches."""
    miss = [n for n in names if n not in log.columns]
    if miss:
        raise LogError(f"{log.path}: missing column{'s' if len(miss) > 1 else ''} "
                       f"{', '.join(_missing(miss, log.header))}{' ' + why if why else ''}; "
                       f"columns found: {', '.join(log.header)}")


def read_log(path, gyr_unit="rad/s", acc_unit="g", rate=None):
    """Read a log; return a Log with units converted (gyro rad/s, acc g).

    rate: Hz; when None the period comes from the time column."""
    if gyr_unit not in GYR_UNITS:
        raise ValueError(f"gyr_unit: must be one of {', '.join(GYR_UNITS)}, got {gyr_unit!r}")
    if acc_unit not in ACC_UNITS:
        raise ValueError(f"acc_unit: must be one of g, m/s2, got {acc_unit!r}")
    if rate is not None and not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate: must be a positive number of Hz, got {rate!r}")
    if not os.path.exists(path):
        raise LogError(f"{path}: no such file", "file")
    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as e:
        raise LogError(f"{path}: cannot read: {e}", "file") from None
    if not rows:
        raise LogError(f"{path}: empty file (expected a header row)")
    header = [h.strip() for h in rows[0]]
    idx = {h: i for i, h in enumerate(header) if h in KNOWN}
    body = [(ln, r) for ln, r in enumerate(rows[1:], start=2) if any(c.strip() for c in r)]
    if not body:
        raise LogError(f"{path}: no data rows after the header")
    cols = {h: np.empty(len(body)) for h in idx}
    for k, (ln, r) in enumerate(body):
        if len(r) < len(header):
            raise LogError(f"{path}:{ln}: {len(r)} values, the header has {len(header)} columns")
        for h, i in idx.items():
            s = r[i].strip()
            try:
                cols[h][k] = float(s)
            except ValueError:
                raise LogError(f"{path}:{ln}: column {h}: not a number: {s!r}") from None
    if gyr_unit == "deg/s":
        for h in GYR:
            if h in cols:
                cols[h] = np.radians(cols[h])
    if acc_unit != "g":
        for h in ACC:
            if h in cols:
                cols[h] = cols[h] / GRAVITY
    log = Log(path, cols, header)
    if "time" in cols:
        t = cols["time"]
        if not np.all(np.isfinite(t)):
            k = int(np.argmax(~np.isfinite(t)))
            raise LogError(f"{path}:{body[k][0]}: time is not finite: {float(t[k])!r}")
        d = np.diff(t)
        if np.any(d <= 0):
            k = int(np.argmax(d <= 0)) + 1
            raise LogError(f"{path}:{body[k][0]}: time does not increase "
                           f"({float(t[k - 1])!r} then {float(t[k])!r}); times must increase strictly")
    if rate is not None:
        log.dt = 1.0 / rate
    elif "time" in cols:
        d = np.diff(cols["time"])
        if d.size == 0:
            raise LogError(f"{path}: one sample: cannot derive the rate from time; give --rate")
        med = float(np.median(d))
        # decimal time stamps rarely difference to the exact period: the rate
        # is 1/median rounded to 9 significant digits (100 Hz, not 99.99999999999991)
        log.dt = 1.0 / float(f"{1.0 / med:.9g}")
        if np.max(np.abs(d - med)) > 0.2 * med:
            log.warnings.append(f"sample intervals vary from {d.min():.6g} to {d.max():.6g} s; "
                                f"the filters use the median {log.dt:.6g} s")
    else:
        raise LogError(f"{path}: no time column; give the sample rate (--rate HZ)")
    return log


def axis_inputs(log, axis="x"):
    """(rate, angle, source) for the single-axis filters (see the module doc)."""
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


def write_csv(path, columns, float32=()):
    """Write {name: (N,) array} as CSV with a header; values round-trip
    exactly (9 significant digits for the names in float32, else 17)."""
    names = list(columns)
    M = np.column_stack([np.asarray(columns[n], dtype=np.float64) for n in names])
    fmt = ["%.9g" if n in float32 else "%.17g" for n in names]
    np.savetxt(path, M, fmt=fmt, delimiter=",", header=",".join(names), comments="")


def write_log(path, t, gyr, acc, mag=None, q=None, extra=None):
    """Write a log in the imufuse format (gyro rad/s, acc g)."""
    cols = {"time": t}
    for names, arr in ((GYR, gyr), (ACC, acc), (MAG, mag), (QUAT, q)):
        if arr is not None:
            for j, n in enumerate(names):
                cols[n] = np.asarray(arr)[:, j]
    cols.update(extra or {})
    write_csv(path, cols)
