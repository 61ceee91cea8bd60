"""`imufuse calibrate` over a log: read the log through imufuse.session (recognised
headers, units; no time column needed), fit one sensor (imufuse.calibration.fit), merge the
result into the calibration file (`save`) and describe it in one line (`describe`).

The file format (`imufuse calibrate ... -o calib.json`, read by `imufuse run
--calibration` through imufuse.preprocess.calibration):

    {"gyroscope": {"M": 3x3, "s": [3], "b": [3]},
     "accelerometer": {"M": 3x3, "s": [3], "b": [3]},
     "magnetometer": {"S": 3x3, "h": [3]}}        every key optional

`save` reads, merges and writes the file under an exclusive lock (imufuse.shared.atomic.locked):
two processes saving different sections of one file both keep theirs.
"""
import json
import os
from dataclasses import replace

import numpy as np

from ..shared.checks import check_real_in
from ..shared.atomic import locked, replacing
from ..io import LogError, require
from ..session import ReadOptions, Session
from .fit import Calibration, accel_six_position, gyro_offset, mag_ellipsoid, mag_minmax, mag_sphere
from ..preprocess.calibration import CalibrationError, from_dict, read_json

__all__ = ["save", "save_mag_offset", "save_gyr_bias", "run_log", "describe", "SECTIONS"]

#: JSON section of each sensor
SECTIONS = {"gyro": "gyroscope", "accel": "accelerometer", "mag": "magnetometer"}


def save(path, cal):
    """Write (or merge into an existing) calibration file, holding its lock from the read to
    the rename. The merged file must be one that `imufuse run --calibration` reads: an
    existing file that is not one, or a malformed section of another sensor, is refused
    (CalibrationError naming the file) and nothing is written (a malformed section of this
    sensor is replaced)."""
    section = cal.as_json()
    if not all(np.all(np.isfinite(np.asarray(v, dtype=float))) for v in cal.params.values()):
        raise ValueError(f"{path}: the {cal.sensor} calibration is not finite "
                         f"({cal.params}); nothing written")
    with locked(path):
        data = {}
        if os.path.exists(path):
            try:
                data = read_json(path)
            except CalibrationError as e:
                raise CalibrationError(f"{e} (not a calibration file; nothing written)",
                                       e.kind) from None
        data[SECTIONS[cal.sensor]] = section
        try:
            from_dict(data)
        except CalibrationError as e:
            raise CalibrationError(f"{path}: {e}; fix or remove that section (nothing "
                                   "written)") from None
        with replacing(path) as tmp, open(tmp, "w") as fh:
            json.dump(data, fh, indent=2)
            fh.write("\n")
    return data


def save_mag_offset(path, offset):
    """Write (or merge into an existing) calibration file the magnetometer offset of a
    filter (RobustAHRS.get_mag_offset()[0], the log's unit) as {"S": identity, "h": offset}:
    the file that `imufuse calibrate mag --method sphere` writes and that
    imufuse.calibration.mag_offset reads back at the next start."""
    h = np.asarray(offset, dtype=float)
    if h.shape != (3,):
        raise ValueError(f"offset: expected (x, y, z), got shape {h.shape}")
    # the file serves filters of either precision (the C library on an MCU is float32)
    for axis, v in zip("xyz", h):
        check_real_in(f"{path}: mag offset {axis}", float(v), "float32")
    return save(path, Calibration("mag", dict(S=np.eye(3), h=h)))


def save_gyr_bias(path, bias):
    """Write (or merge into an existing) calibration file the gyro bias of a filter
    (RobustIMU/RobustAHRS.get_gyr_bias()[0], rad/s) as {"M": identity, "s": ones, "b": bias}:
    the file that `imufuse calibrate gyro` writes and that imufuse.calibration.gyr_bias
    reads back at the next start."""
    b = np.asarray(bias, dtype=float)
    if b.shape != (3,):
        raise ValueError(f"bias: expected (x, y, z), got shape {b.shape}")
    for axis, v in zip("xyz", b):
        check_real_in(f"{path}: gyr bias {axis}", float(v), "float32")
    return save(path, Calibration("gyro", dict(M=np.eye(3), s=np.ones(3), b=b)))


def run_log(sensor, path, output, gyr_unit=None, ranges=None, threshold=None,
            method="ellipsoid", longest_still=False, *, acc_unit=None, columns=None,
            strict=False):
    """`imufuse calibrate gyro|accel|mag LOG -o calib.json`. The log is read as every
    imufuse command reads it (imufuse.session: recognised headers, units from the header or
    gyr_unit/acc_unit, `columns` {name: header}); no time column is needed. The file holds
    the gyroscope in rad/s and the accelerometer in g, the units imufuse reads logs in
    (imufuse.preprocess applies it to logs read the same way); the magnetometer in the
    log's unit."""
    if sensor not in SECTIONS:
        raise ValueError(f"sensor: must be one of {', '.join(SECTIONS)}, got {sensor!r}")
    prefix = {"gyro": "gyr", "accel": "acc", "mag": "mag"}[sensor]
    names = [f"{prefix}_{c}" for c in "xyz"]
    s = Session(path, ReadOptions(gyr_unit=gyr_unit, acc_unit=acc_unit,
                                  columns=dict(columns or {}), strict=strict, need_time=False))
    require(s.log, names)
    x = np.array(s.log.vec(names))
    notes = list(s.notes)
    rng = None
    if sensor == "accel" and ranges:
        try:
            rng = [tuple(int(v) for v in r.split(":")) for r in ranges.split(",")]
        except ValueError:
            raise ValueError(f"--ranges: expected A:B,C:D,..., got {ranges!r}") from None
    try:
        if sensor == "gyro":
            kw = {} if threshold is None else dict(threshold=threshold)
            cal = gyro_offset(x, restart=longest_still, **kw)
        elif sensor == "accel":
            cal = accel_six_position(x, rng, threshold=threshold)
        else:
            cal = {"ellipsoid": mag_ellipsoid, "minmax": mag_minmax, "sphere": mag_sphere}[method](x)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as e:
        # the recording cannot give a calibration: bad data (exit 4), not a bad command line
        raise LogError(f"{path}: {e}") from None
    cal = replace(cal, notes=tuple(notes))
    save(output, cal)
    return cal


def describe(sensor, cal):
    p, f = cal.params, cal.figures
    np.set_printoptions(precision=5, suppress=True)
    if sensor == "gyro":
        return (f"gyroscope offset b = {np.asarray(p['b'])} rad/s "
                f"({np.degrees(np.asarray(p['b']))} deg/s) from samples "
                f"{f['samples'][0]}..{f['samples'][1] - 1} (noise {np.asarray(f['noise'])} "
                f"rad/s)")
    if sensor == "accel":
        return (f"accelerometer: offset b = {np.asarray(p['b'])} (the log's unit), sensitivity "
                f"{np.asarray(f['sensitivity'])} per g; worst |a| error at the six "
                f"positions {f['magnitude_error']:.2g} g")
    return (f"magnetometer: hard iron h = {np.asarray(p['h'])} (the log's unit), soft iron S =\n"
            f"{np.asarray(p['S'])}\nfield strength {f['field']:.5g}, residual "
            f"{f['residual']:.3g} ({100 * f['residual'] / f['field']:.2f} % of the field)")
