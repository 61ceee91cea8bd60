"""Preprocessing of a log in front of any filter (seed 004), and the
`imufuse run --filter FusionAHRS` path.

Options (imufuse run / compare), applied in this order:
  --calibration FILE.json  the sensor models i_c = M s (i_u - b), m_c = S (m_u - h)
                           (imufuse.calibration_models, written by `imufuse calibrate`),
                           in the sensor's own axes and in the units imufuse reads the
                           log in: gyroscope b in rad/s, accelerometer b in g;
  --align ALIGNMENT        signed axis permutation, e.g. "+X-Z+Y": body x = +sensor x,
                           body y = -sensor z, body z = +sensor y; the 24 rotations of
                           Fusion's FusionAxesSwap and the 24 reflections;
  --offset                 FusionOffset, the gyroscope offset estimator, at the log's
                           sample rate (rounded to whole Hz).
FusionOffset runs on the gyroscope in deg/s (Fusion's unit, its 3 deg/s threshold).
"""
import numpy as np

import imufuse_c

from . import io, reference
from ._fusion import parse_alignment
from .calibration_models import load_calibration
from .catalogue import FILTERS_FUSION
from .demo import errors_3d
from .estimate import Estimate
from .reference import fusion



def add_arguments(parser):
    g = parser.add_argument_group("preprocessing (seed 004), in this order")
    g.add_argument("--calibration", metavar="FILE.json",
                   help="sensor calibration (M, s, b per inertial sensor; S, h for the "
                        "magnetometer; see imufuse.calibration_models)")
    g.add_argument("--align", metavar="ALIGNMENT",
                   help="axis alignment, a signed permutation such as +X-Z+Y "
                        "(body x = +sensor x, y = -sensor z, z = +sensor y)")
    g.add_argument("--offset", action="store_true",
                   help="gyroscope offset estimator (FusionOffset) at the log's rate")


def _sensor(log, names):
    return np.column_stack([log.columns[n] for n in names])


def _put(log, names, arr):
    for j, n in enumerate(names):
        log.columns[n] = np.asarray(arr[:, j], dtype=np.float64)


def apply(log, args, backend="c"):
    """Apply the options in `args` (missing attributes: not requested) to the
    log's columns in place; return notes describing what was done."""
    cal_path = getattr(args, "calibration", None)
    align = getattr(args, "align", None)
    offset = getattr(args, "offset", False)
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
        # imufuse.calibrate writes the file
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
        notes.append(f"gyroscope offset estimated (FusionOffset at {rate} Hz; final offset "
                     f"{', '.join(f'{v:.3f}' for v in st[-1, :3])} deg/s)")
    for sensor, arr in data.items():
        _put(log, cols[sensor], arr)
    return notes


def _backend(backend):
    if backend == "c":
        return imufuse_c
    return fusion


def is_fusion(name):
    """FusionAHRS: run by run_fusion (FusionOffset is the --offset option)."""
    return name in FILTERS_FUSION and name != "FusionOffset"


def run_fusion(args, log, params):
    """`imufuse run --filter FusionAHRS`: Fusion's units and dt per sample from
    the log's time column (Fusion integrates with the interval it is given),
    or, as for every filter, the fixed period with --fixed-rate or --rate.
    Returns (columns, summary)."""
    mod = imufuse_c if args.backend == "c" else reference
    f = mod.FusionAHRS(**params, dtype=args.dtype)
    io.require(log, io.GYR + io.ACC)
    gyr = np.degrees(log.gyr)
    if "time" in log.columns and not log.fixed_rate:
        dt = np.diff(log.columns["time"], prepend=log.columns["time"][0] - log.dt)
        when = "dt per sample"
    else:
        dt = log.dt
        when = f"dt={log.dt:.6g} s"
    if log.has(*io.MAG):
        S = f.run(gyr, log.acc, log.mag, dt=dt)
        src = "gyr, acc, mag (update)"
    else:
        S = f.run(gyr, log.acc, dt=dt)
        src = "gyr, acc (update_no_magnetometer)"
    out = f.outputs_batch(S)
    cols = {"time": log.t}
    for j, n in enumerate(f.state_names):
        cols[n] = S[:, j]
    for j, n in enumerate(io.QUAT):
        cols[n] = S[:, j]
    for j, n in enumerate(("roll_deg", "pitch_deg", "yaw_deg")):
        cols[n] = out["euler"][:, j]
    for name in ("earth_acceleration", "linear_acceleration"):
        for j, ax in enumerate("xyz"):
            cols[f"{name}_{ax}"] = out[name][:, j]
    for name in ("acceleration_error", "magnetic_error"):
        cols[name + "_deg"] = out[name]
    for name in ("initialising", "angular_rate_recovery", "acceleration_recovery",
                 "magnetic_recovery"):
        cols[name] = out[name].astype(np.float64)
    summary = (f"FusionAHRS ({args.backend}, {args.dtype}, "
               f"{', '.join(f'{k}={v}' for k, v in params.items()) or 'defaults'}): "
               f"{len(log)} samples from {src}, gyroscope in deg/s, {when}")
    if f.skipped:
        summary += f"; {f.skipped} samples skipped (non-finite)"
    if log.q_ref is not None and params.get("convention", "NWU").upper() == "NWU":
        # the log's reference is imufuse's NWU body -> earth quaternion, as FusionAHRS's
        q = np.asarray(S[:, :4], dtype=np.float64)
        est = Estimate(q=q, heading=log.has(*io.MAG), source="q0..q3")
        errs = errors_3d(est, log.q_ref, np.ones(len(log), dtype=bool))
        summary += "; against the log's reference q: " + ", ".join(
            f"{k} RMS {v[0]:.3f} max {v[1]:.3f} deg" for k, v in errs.items())
    return cols, summary, set(f.state_names) if args.dtype == "float32" else set()


def fusion_hint(name, command):
    """A usage message for a Fusion-suite name a command cannot take, else None."""
    if name == "FusionOffset":
        return "FusionOffset is the --offset option (in front of any filter), not a filter"
    if name == "FusionAHRS" and command != "run":
        return (f"FusionAHRS is not available in `imufuse {command}` (Fusion's units and dt "
                "per sample); use `imufuse run LOG --filter FusionAHRS`")
    return None
