"""Sensor calibration files: the models of Longbin's walkthrough (x-io Fusion) in JSON.

Format (every key optional; a missing sensor or parameter means "identity"):

    {"gyroscope":     {"M": [[...], [...], [...]], "s": [sx, sy, sz], "b": [bx, by, bz]},
     "accelerometer": {"M": 3x3, "s": [3], "b": [3]},
     "magnetometer":  {"S": 3x3, "h": [3]}}

Inertial model  i_c = M s (i_u - b)   (M misalignment, s sensitivity, b offset)
Magnetic model  m_c = S (m_u - h)     (S soft-iron matrix, h hard-iron offset)

Units: those in which imufuse reads a log (imufuse.io, after --gyr-unit and
--acc-unit), as `imufuse calibrate` (imufuse.calibration.log) writes the file:
gyroscope b in rad/s (at most GYR_OFFSET_MAX, 1 rad/s, per axis: a larger one is a file
written in deg/s, refused), accelerometer b in g, magnetometer h in the
magnetometer's unit; M, s and S are dimensionless. (The models are linear: a
caller working in Fusion's deg/s converts b by 180/pi.) The models are
evaluated by imufuse_c.calibrate_inertial / calibrate_magnetic (C, in
Fusion's operation order; pure-Python twin in imufuse.reference.fusion).

A file is read by imufuse.shared.jsonfile (UTF-8, at most 1 MiB, nesting and repeated keys
bounded) and written whole (imufuse.shared.atomic.replacing) under the lock of a
read-merge-write (imufuse.shared.atomic.locked).
"""
import json
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

import imufuse_c

from ..shared.atomic import locked, replacing
from ..shared.checks import check_real_in
from ..shared.jsonfile import FileContentError, read_object
from ..reference import fusion

SENSORS = {"gyroscope": ("M", "s", "b"), "accelerometer": ("M", "s", "b"),
           "magnetometer": ("S", "h")}
SHAPES = {"M": (3, 3), "S": (3, 3), "s": (3,), "b": (3,), "h": (3,)}
#: the largest gyroscope offset a file may hold, rad/s (57 deg/s; MEMS parts' zero-rate
#: offsets are specified up to tens of deg/s): beyond it, the file was written in deg/s
GYR_OFFSET_MAX = 1.0
IDENTITY = {"M": np.eye(3), "S": np.eye(3), "s": np.ones(3), "b": np.zeros(3), "h": np.zeros(3)}


class CalibrationError(ValueError):
    """A calibration file or dict that does not follow the format; `kind` is "file" (a file
    missing or unreadable: exit 3 on the command line) or "data" (its contents: exit 4)."""

    def __init__(self, message, kind="data"):
        super().__init__(message)
        self.kind = kind


@dataclass
class Calibration:
    """Parameters per sensor (float64 arrays); absent sensors are None."""
    gyroscope: Optional[dict] = None
    accelerometer: Optional[dict] = None
    magnetometer: Optional[dict] = None
    source: str = ""
    extra: dict = field(default_factory=dict)

    def params(self, sensor):
        """The sensor's parameters with the identity filled in."""
        given = getattr(self, sensor) or {}
        return {k: given.get(k, IDENTITY[k]) for k in SENSORS[sensor]}

    def apply(self, sensor, x, dtype="float64", backend="c"):
        """Calibrate (N, 3) samples of one sensor; unchanged if it has no entry."""
        if getattr(self, sensor) is None:
            return np.asarray(x, dtype=dtype)
        mod = imufuse_c if backend == "c" else fusion
        p = self.params(sensor)
        if sensor == "magnetometer":
            return mod.calibrate_magnetic(x, p["S"], p["h"], dtype=dtype)
        return mod.calibrate_inertial(x, p["M"], p["s"], p["b"], dtype=dtype)

    def to_dict(self):
        out = {}
        for sensor in SENSORS:
            given = getattr(self, sensor)
            if given is not None:
                out[sensor] = {k: np.asarray(v).tolist() for k, v in given.items()}
        return out


def _where(src, path):
    return f"{src}: {path}" if src else path


def from_dict(data, source=""):
    """Validate a calibration dict; raise CalibrationError naming the key."""
    if not isinstance(data, dict):
        raise CalibrationError(_where(source, f"expected a JSON object, got {type(data).__name__}"))
    unknown = sorted(set(data) - set(SENSORS))
    if unknown:
        raise CalibrationError(_where(source, f"unknown sensor(s) {', '.join(map(repr, unknown))}; "
                                              f"expected {', '.join(SENSORS)}"))
    cal = Calibration(source=source)
    for sensor, keys in SENSORS.items():
        if sensor not in data:
            continue
        entry = data[sensor]
        if not isinstance(entry, dict):
            raise CalibrationError(_where(source, f"{sensor}: expected an object with "
                                                  f"{', '.join(keys)}"))
        bad = sorted(set(entry) - set(keys))
        if bad:
            raise CalibrationError(_where(source, f"{sensor}: unknown key(s) "
                                                  f"{', '.join(map(repr, bad))}; expected "
                                                  f"{', '.join(keys)}"))
        params = {}
        for k, v in entry.items():
            try:
                arr = np.asarray(v, dtype=np.float64)
            except (TypeError, ValueError, OverflowError):
                raise CalibrationError(_where(source, f"{sensor}.{k}: expected numbers, got {v!r}")) \
                    from None
            if arr.shape != SHAPES[k]:
                raise CalibrationError(_where(source, f"{sensor}.{k}: expected shape "
                                                      f"{SHAPES[k]}, got {arr.shape}"))
            if not np.all(np.isfinite(arr)):
                raise CalibrationError(_where(source, f"{sensor}.{k}: values must be finite"))
            if sensor == "gyroscope" and k == "b" and np.abs(arr).max() > GYR_OFFSET_MAX:
                raise CalibrationError(_where(source, (
                    f"gyroscope.b: {arr.tolist()} rad/s is "
                    f"{np.round(np.degrees(arr), 1).tolist()} deg/s, beyond any gyroscope's "
                    f"zero-rate offset (at most {GYR_OFFSET_MAX:g} rad/s here); the file's "
                    f"offsets are in rad/s: written in deg/s (as x-io's calibrations are), "
                    f"they read {np.round(np.radians(arr), 4).tolist()} rad/s")))
            params[k] = arr
        setattr(cal, sensor, params)
    return cal


def read_json(path):
    """The JSON object of a calibration file, unvalidated; CalibrationError naming the file
    and the fault (not UTF-8, over 1 MiB, not JSON, nested too deep, a key given twice)."""
    try:
        return read_object(path, "calibration file")
    except FileContentError as e:
        raise CalibrationError(str(e), e.kind) from None


def load_calibration(path):
    """Read and validate a calibration JSON file."""
    return from_dict(read_json(path), source=str(path))


def save_calibration(path, calibration):
    """Write a Calibration (or a dict in the format) as JSON, validated first; whole or not
    at all, and under the lock that `imufuse calibrate`'s merge holds."""
    cal = calibration if isinstance(calibration, Calibration) else from_dict(calibration)
    with locked(path), replacing(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        json.dump(cal.to_dict(), fh, indent=2)
        fh.write("\n")
    return path


def mag_offset(calibration):
    """The magnetometer offset h (3 floats, the log's unit) of a calibration (a Calibration
    or a file) that is an offset only, S the identity: what RobustAHRS.set_mag_offset
    takes (`imufuse calibrate mag --method sphere` writes it; the learnt offset goes back
    with imufuse.calibration.log.save_mag_offset). A soft-iron matrix cannot be given to the
    filter: CalibrationError saying so (apply such a file to the readings instead,
    `imufuse run --calibration`)."""
    cal = calibration if isinstance(calibration, Calibration) else load_calibration(calibration)
    where = cal.source or "calibration"
    if cal.magnetometer is None:
        raise CalibrationError(f"{where}: no magnetometer section")
    p = cal.params("magnetometer")
    S = np.asarray(p["S"], dtype=float)
    if not np.allclose(S, np.eye(3), rtol=0.0, atol=1e-12):
        raise CalibrationError(
            f"{where}: magnetometer.S is not the identity ({S.tolist()}): a soft-iron "
            "calibration, which the filter's offset cannot hold; apply it to the readings "
            "(imufuse run --calibration) or fit an offset only (imufuse calibrate mag "
            "--method sphere)")
    return _vector_for_filter(where, "magnetometer.h", p["h"])


def _vector_for_filter(where, name, values):
    # (x, y, z) floats finite in float32 (the vector goes into a filter of either precision,
    # float32 on an MCU), or CalibrationError naming the file and the component
    v = tuple(float(c) for c in np.asarray(values, dtype=float))
    for axis, c in zip("xyz", v):
        try:
            check_real_in(f"{name} {axis}", c, "float32")
        except ValueError as e:
            raise CalibrationError(f"{where}: {e}") from None
    return v


def gyr_bias(calibration):
    """The gyroscope offset b (3 floats, rad/s) of a calibration (a Calibration or a file)
    whose gyroscope section is an offset only (M the identity, s ones): what
    RobustIMU/RobustAHRS.set_gyr_bias takes (`imufuse calibrate gyro` writes it; a filter's
    learnt bias goes back with imufuse.calibration.log.save_gyr_bias). A misalignment or
    scale cannot be given to the filter: CalibrationError saying so (apply such a file to
    the readings instead, `imufuse run --calibration`)."""
    cal = calibration if isinstance(calibration, Calibration) else load_calibration(calibration)
    where = cal.source or "calibration"
    if cal.gyroscope is None:
        raise CalibrationError(f"{where}: no gyroscope section")
    p = cal.params("gyroscope")
    if not (np.array_equal(np.asarray(p["M"], dtype=float), np.eye(3))
            and np.array_equal(np.asarray(p["s"], dtype=float), np.ones(3))):
        raise CalibrationError(
            f"{where}: gyroscope.M or gyroscope.s is not the identity: a misalignment or "
            "scale, which the filter's bias cannot hold; apply it to the readings (imufuse "
            "run --calibration)")
    return _vector_for_filter(where, "gyroscope.b", p["b"])


def is_identity(cal):
    return all(getattr(cal, s) is None or all(
        np.array_equal(v, IDENTITY[k]) for k, v in getattr(cal, s).items()) for s in SENSORS)


__all__ = ["Calibration", "CalibrationError", "from_dict", "read_json", "load_calibration",
           "save_calibration", "is_identity", "mag_offset", "gyr_bias"]
