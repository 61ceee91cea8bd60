"""Preprocessing of a log in front of any filter (x-io Fusion's calibration models, axis
alignment and gyroscope offset estimator, as Longbin's "IMU Fusion Algorithm -- Madgwick"
walks through them), applied by imufuse.session.

Options (imufuse run / compare), applied in this order:
  --calibration FILE.json  the sensor models i_c = M s (i_u - b), m_c = S (m_u - h)
                           (imufuse.preprocess.calibration, written by `imufuse calibrate`),
                           in the sensor's own axes and in the units imufuse reads the
                           log in: gyroscope b in rad/s, accelerometer b in g;
  --align ALIGNMENT        signed axis permutation, e.g. "+X-Z+Y": body x = +sensor x,
                           body y = -sensor z, body z = +sensor y; the 24 rotations of
                           Fusion's FusionAxesSwap and the 24 reflections;
  --offset                 FusionOffset, the gyroscope offset estimator, at the log's
                           sample rate (rounded to whole Hz).
FusionOffset runs on the gyroscope in deg/s (Fusion's unit, its 3 deg/s threshold).

Its module imufuse.preprocess.calibration holds the calibration file and its models (on this
floor, below imufuse.calibration, which fits them from logs and re-exports them).
"""
import numpy as np

import imufuse_c

from .. import io
from ..reference._fusion import parse_alignment
from ..reference import fusion
from .calibration import load_calibration



def _sensor(log, names):
    return np.column_stack([log.columns[n] for n in names])


def _put(log, names, arr):
    for j, n in enumerate(names):
        log.columns[n] = np.asarray(arr[:, j], dtype=np.float64)


def apply(log, *, calibration=None, align=None, offset=False, backend="c"):
    """Apply a calibration file, an axis alignment and the gyroscope offset estimator, in
    this order, to the log's columns in place; return notes describing what was done."""
    cal_path = calibration
    if not (cal_path or align or offset):
        return []
    notes = []
    mod = _backend(backend)
    have = {"gyroscope": log.has(*io.GYR), "accelerometer": log.has(*io.ACC),
            "magnetometer": log.has(*io.MAG)}
    cols = {"gyroscope": io.GYR, "accelerometer": io.ACC, "magnetometer": io.MAG}
    data = {s: _sensor(log, cols[s]) for s, ok in have.items() if ok}
    if cal_path:
        # in the units imufuse reads the log in (gyroscope rad/s, accelerometer g), as
        # imufuse.calibration.log writes the file
        cal = load_calibration(cal_path)
        for sensor in data:
            if getattr(cal, sensor) is not None:
                data[sensor] = cal.apply(sensor, data[sensor], backend=backend)
                notes.append(f"{sensor} calibrated ({cal_path})")
    if align:
        parse_alignment(align)
        for sensor in data:
            data[sensor] = mod.axes_apply(data[sensor], align)
        notes.append(f"axes aligned {align.upper()}")
    if offset:
        if "gyroscope" not in data:
            raise ValueError("--offset: the log has no gyroscope columns")
        rate = int(round(1.0 / log.dt))
        if rate < 1:
            raise ValueError(f"--offset: sample rate {1.0 / log.dt:.3g} Hz is below 1 Hz")
        # FusionOffset works in Fusion's unit, deg/s (its 3 deg/s rest threshold)
        corrected, st = mod.FusionOffset(rate).run(np.degrees(data["gyroscope"]))
        data["gyroscope"] = np.radians(corrected)
        note = (f"gyroscope offset estimated (FusionOffset at {rate} Hz; final offset "
                f"{', '.join(f'{v:.3f}' for v in st[-1, :3])} deg/s)")
        if not np.any(st[:, :3]):
            # its offset moves only once every axis, less the offset, has stayed within its
            # threshold for its timeout
            note += (": it never found the gyroscope still (every axis within 3 deg/s for 5 s), "
                     "so nothing was corrected; an offset beyond 3 deg/s needs `imufuse "
                     "calibrate gyro` on a still log (--calibration), or RobustIMU/RobustAHRS, "
                     "which learn it")
        notes.append(note)
    for sensor, arr in data.items():
        _put(log, cols[sensor], arr)
    return notes


def _backend(backend):
    if backend == "c":
        return imufuse_c
    return fusion
