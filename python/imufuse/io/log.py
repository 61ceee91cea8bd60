"""What a log is once read: the names of its columns (GYR, ACC, MAG, QUAT, KNOWN), the
units imufuse reads them in (GYR_UNITS, ACC_UNITS, TIME_UNITS), the Log that holds the
columns, and LogError (a log that cannot be used)."""
import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

GRAVITY = 9.80665
GYR = ("gyr_x", "gyr_y", "gyr_z")
ACC = ("acc_x", "acc_y", "acc_z")
MAG = ("mag_x", "mag_y", "mag_z")
QUAT = ("q_w", "q_x", "q_y", "q_z")
KNOWN = ("time", *GYR, *ACC, *MAG, *QUAT, "movement", "rate", "angle")
GYR_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}
ACC_UNITS = {"g": 1.0, "m/s2": 1.0 / GRAVITY, "m/s^2": 1.0 / GRAVITY}
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_KIND_UNITS = {"gyr": GYR_UNITS, "acc": ACC_UNITS, "time": TIME_UNITS}


class LogError(ValueError):
    """A log that cannot be used; `kind` is "file" (missing, unreadable),
    "data" (columns, values, time) or "usage" (a bad column map)."""

    def __init__(self, message, kind="data"):
        super().__init__(message)
        self.kind = kind


@dataclass
class Log:
    path: str
    columns: dict                 # known column name -> (N,) float64, units converted
    header: list                  # every column of the file, in order
    dt: Optional[float] = None    # fixed sample period (median interval or 1/rate), s
    warnings: list = field(default_factory=list)
    sources: dict = field(default_factory=dict)   # known name -> header it came from
    units: dict = field(default_factory=dict)     # "gyr"/"acc"/"mag"/"time" -> (unit, where from)
    fixed_rate: bool = True       # True: every sample at dt; False: dts (the time column)
    ref_frame: Optional[str] = None  # frame of q_w..q_z when the format says (BROAD: "ENU")
    suspicions: list = field(default_factory=list)  # the plausibility warnings (also in warnings)

    def __len__(self):
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def has(self, *names):
        return all(n in self.columns for n in names)

    def vec(self, names):
        return np.column_stack([self.columns[n] for n in names])

    def _cached(self, key, names, make):
        """make() computed once while the columns it reads (the same array objects), dt and
        fixed_rate stay as they were; read-only, since every access shares it. A column
        replaced (imufuse.preprocess) or dt changed gives a new array."""
        cache = self.__dict__.get("_cache")
        if cache is None:
            cache = self.__dict__["_cache"] = {}
        hit = cache.get(key)
        cols = self.columns
        if hit is not None:
            (arrays, dt, fixed), value = hit
            if dt == self.dt and fixed == self.fixed_rate:
                for n, a in zip(names, arrays):
                    if cols.get(n) is not a:
                        break
                else:
                    return value
        token = (tuple(cols.get(n) for n in names), self.dt, self.fixed_rate)
        value = make()
        if isinstance(value, np.ndarray):
            value.flags.writeable = False
        cache[key] = (token, value)
        return value

    @property
    def t(self):
        """Sample times, s: the time column, else k * dt."""
        if "time" in self.columns:
            return self.columns["time"]
        return self._cached("t", (), lambda: np.arange(len(self)) * self.dt)

    @property
    def dts(self):
        """Per-sample periods (N,), s: None at a fixed rate, else the time
        column's intervals (the first sample: the median interval, dt)."""
        if self.fixed_rate or "time" not in self.columns:
            return None

        def make():
            d = np.empty(len(self))
            d[0] = self.dt
            np.subtract(self.columns["time"][1:], self.columns["time"][:-1], out=d[1:])
            return d
        return self._cached("dts", ("time",), make)

    @property
    def gyr(self):
        """(N, 3) gyroscope, rad/s (computed once; read-only)."""
        return self._cached("gyr", GYR, lambda: self.vec(GYR))

    @property
    def acc(self):
        """(N, 3) accelerometer, g (computed once; read-only)."""
        return self._cached("acc", ACC, lambda: self.vec(ACC))

    @property
    def mag(self):
        """(N, 3) magnetometer, or None (computed once; read-only)."""
        return self._cached("mag", MAG, lambda: self.vec(MAG) if self.has(*MAG) else None)

    @property
    def q_ref(self):
        """(N, 4) reference quaternion w, x, y, z, or None (computed once; read-only)."""
        return self._cached("q_ref", QUAT, lambda: self.vec(QUAT) if self.has(*QUAT) else None)

    @property
    def movement(self):
        m = self.columns.get("movement")
        return None if m is None else m != 0
