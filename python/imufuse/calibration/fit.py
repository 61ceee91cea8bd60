"""Sensor calibration from recordings (Nair 2016, host side, numpy).

The results feed the calibration models of the Fusion suite:

    gyroscope, accelerometer:  i_c = M s (i_u - b)
    magnetometer:              m_c = S (m_u - h)

- :func:`gyro_offset`: Nair's power-up procedure, the mean at rest, with
  its motion check: a reading farther than `threshold` from the median shows
  motion; the call refuses (ValueError naming the sample range) or, with
  ``restart=True``, takes the longest still stretch (Nair's "wait and
  repeat").
- :func:`accel_six_position`: Nair's six-position procedure. Per axis,
  from the mean readings with that axis pointing down (+1 g) and up (-1 g):
  sensitivity (a+ - a-)/2 and offset (a+ + a-)/2. The still phases are given
  as index ranges or found (:func:`still_phases`). With ``cross_axis=True``
  the off-axis readings of the six positions give the full matrix too (M,
  close to the identity, carries the cross-axis terms).
- :func:`mag_minmax`: Nair's hard-iron method, offset (max + min)/2 and
  per-axis scale (max - min)/2.
- :func:`mag_ellipsoid`: least-squares ellipsoid fit, soft-iron S (symmetric)
  and hard-iron h, with the residual and field-strength figures.

Every function returns a :class:`Calibration` (``as_json()`` gives the
object of the calibration file, written by imufuse.calibration.log) and
rejects degenerate data with a ValueError that says what is missing.
"""
from dataclasses import dataclass, field

import numpy as np

from ..shared.runs import runs

__all__ = ["Calibration", "gyro_offset", "still_phases", "accel_six_position", "mag_minmax",
           "mag_ellipsoid"]

_AXES = ("+x", "-x", "+y", "-y", "+z", "-z")


@dataclass(frozen=True)
class Calibration:
    """sensor "gyro" | "accel" | "mag"; params: the model's arrays (M, s, b or
    S, h); figures: numbers to judge the result (not written to the file)."""
    sensor: str
    params: dict
    figures: dict = field(default_factory=dict)
    notes: tuple = ()        # run_log: what reading the log said

    def as_json(self):
        return {k: np.asarray(v, dtype=float).tolist() for k, v in self.params.items()}

    def apply(self, x):
        """The calibrated samples of raw x (N, 3)."""
        x = np.asarray(x, dtype=float)
        p = self.params
        if self.sensor == "mag":
            return (x - p["h"]) @ np.asarray(p["S"]).T
        return ((x - p["b"]) * p["s"]) @ np.asarray(p["M"]).T


def _nx3(name, x, min_rows):
    a = np.asarray(x, dtype=float)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name}: expected an (N, 3) array, got shape {a.shape}")
    if a.shape[0] < min_rows:
        raise ValueError(f"{name}: need at least {min_rows} samples, got {a.shape[0]}")
    if not np.all(np.isfinite(a)):
        k = int(np.argmax(~np.all(np.isfinite(a), axis=1)))
        raise ValueError(f"{name}: sample {k} is not finite")
    return a


# ---- gyroscope ---------------------------------------------------------------------------

#: the largest gyro offset taken, in the gyro's unit: above any MEMS gyro's whole range in
#: rad/s (about 70) or deg/s (4000), and above any int16 count
GYRO_OFFSET_MAX = 1e5


#: a median gyro reading beyond this (rad/s, 20 deg/s) at rest is no offset of a MEMS part: with
#: the readings still when read as deg/s, the note names that unit
DEG_S_HINT = 0.35


def gyro_offset(gyr, threshold=0.05, restart=False, min_samples=100):
    """Gyroscope offset b: the mean of a recording at rest (M = I, s = 1).

    threshold: largest credible distance of a reading from the median, per
    axis, in the gyro's unit (default 0.05, rad/s: about 3 deg/s). Readings
    beyond it show motion: ValueError naming the sample ranges, or with
    restart=True the mean of the longest still stretch (at least min_samples;
    Nair averages 100 samples)."""
    g = _nx3("gyr", gyr, min_samples)
    if not (np.isfinite(threshold) and threshold > 0):
        raise ValueError(f"threshold: must be finite and > 0, got {threshold!r}")
    med = np.median(g, axis=0)
    if not np.all(np.abs(med) <= GYRO_OFFSET_MAX):
        raise ValueError(f"gyr: a median reading of {np.max(np.abs(med)):.3g} at rest is no "
                         f"gyro offset (MEMS gyros read up to about 70 rad/s or 4000 deg/s; an "
                         f"offset above {GYRO_OFFSET_MAX:g} in the gyro's unit is refused): check "
                         "the unit "
                         "(--gyr-unit) and the columns")
    moving = np.any(np.abs(g - med) > threshold, axis=1)
    lo, hi = 0, len(g)
    if moving.any():
        bad = runs(moving)
        where = ", ".join(f"{a}..{b - 1}" for a, b in bad[:5]) + (" ..." if len(bad) > 5 else "")
        gd = np.radians(g)                        # the same numbers, as deg/s
        if np.abs(med).max() > DEG_S_HINT and not np.any(
                np.abs(gd - np.median(gd, axis=0)) > threshold):
            raise ValueError(
                f"gyr: these look like deg/s read as rad/s: the median reading, "
                f"({', '.join(f'{v:.3g}' for v in med)}), is no gyro's offset in rad/s "
                f"({np.degrees(np.abs(med)).max():.0f} deg/s), and read as deg/s every sample "
                f"is within {threshold:g} rad/s of it (the unit was still); give --gyr-unit "
                "deg/s (read_log(..., gyr_unit='deg/s'))")
        if not restart:
            k = int(np.argmax(moving))
            ax = "xyz"[int(np.argmax(np.abs(g[k] - med)))]
            raise ValueError(
                f"gyr: the unit moved during the offset calibration: samples {where} are "
                f"more than {threshold:g} from the median (first: sample {k}, axis {ax}, "
                f"{g[k]['xyz'.index(ax)] - med['xyz'.index(ax)]:+.4g}); keep it still and "
                f"record again, or use the longest still stretch (imufuse calibrate gyro "
                f"--longest-still; restart=True from Python)")
        still = runs(~moving)
        lo, hi = max(still, key=lambda r: r[1] - r[0]) if still else (0, 0)
        if hi - lo < min_samples:
            raise ValueError(f"gyr: no still stretch of {min_samples} samples (motion at "
                             f"samples {where})")
    part = g[lo:hi]
    b = part.mean(axis=0)
    figures = dict(samples=(int(lo), int(hi)), noise=part.std(axis=0).tolist(),
                   moving_samples=int(moving.sum()))
    return Calibration("gyro", dict(M=np.eye(3), s=np.ones(3), b=b), figures)


# ---- accelerometer -------------------------------------------------------------------------

def still_phases(acc, window=50, threshold=None, min_len=None):
    """Index ranges (start, stop) where the accelerometer is still: the
    moving standard deviation over `window` samples stays below `threshold`
    (default: 1 % of the median magnitude) on every axis, for at least
    `min_len` samples (default 2 windows)."""
    a = _nx3("acc", acc, 2 * window)
    if threshold is None:
        threshold = 0.01 * float(np.median(np.linalg.norm(a, axis=1)))
    min_len = 2 * window if min_len is None else min_len
    c1 = np.cumsum(np.vstack([np.zeros(3), a]), axis=0)
    c2 = np.cumsum(np.vstack([np.zeros(3), a * a]), axis=0)
    n = len(a) - window + 1
    mean = (c1[window:] - c1[:n]) / window
    var = (c2[window:] - c2[:n]) / window - mean * mean
    quiet = np.all(np.sqrt(np.maximum(var, 0.0)) < threshold, axis=1)
    # a window that is quiet marks all its samples still
    still = np.zeros(len(a), bool)
    for s, e in runs(quiet):
        still[s:e + window - 1] = True
    return [(int(s), int(e)) for s, e in runs(still) if e - s >= min_len]


def accel_six_position(acc, ranges=None, cross_axis=False, window=50, threshold=None):
    """Nair's six-position calibration.

    acc (N, 3) raw readings; ranges: six or more (start, stop) index ranges
    of still phases (default: :func:`still_phases`), each with one axis
    pointing down or up. For each axis j: sensitivity (a+_j - a-_j)/2 (raw
    units per g), offset b_j = (a+_j + a-_j)/2, s_j = 1/sensitivity. With
    cross_axis=True, M = A^-1 diag(sensitivity) where column j of A is
    (a+ - a-)/2 (the off-axis readings included); otherwise M = I."""
    a = _nx3("acc", acc, 6)
    if ranges is None:
        ranges = still_phases(a, window, threshold)
    ranges = [(int(s), int(e)) for s, e in ranges]
    for s, e in ranges:
        if not 0 <= s < e <= len(a):
            raise ValueError(f"ranges: {s}:{e} is not a range of rows within 0..{len(a)}")
    if len(ranges) < 6:
        raise ValueError(f"acc: six positions needed (each axis down and up), found "
                         f"{len(ranges)} still phase(s) {ranges}")
    means = np.array([a[s:e].mean(axis=0) for s, e in ranges])
    found = {}
    for (s, e), m in zip(ranges, means):
        j = int(np.argmax(np.abs(m)))
        key = ("+" if m[j] > 0 else "-") + "xyz"[j]
        # the dominant axis must stand out: a position between two axes is no use
        rest = np.delete(np.abs(m), j)
        if rest.max() > 0.5 * abs(m[j]):
            raise ValueError(f"acc: rows {s}:{e} are not one axis up or down "
                             f"(mean {np.round(m, 4).tolist()})")
        if key not in found or (e - s) > found[key][1][1] - found[key][1][0]:
            found[key] = (m, (s, e))
    missing = [k for k in _AXES if k not in found]
    if missing:
        raise ValueError(f"acc: too few orientations: no still phase with axis "
                         f"{', '.join(missing)} (found {', '.join(sorted(found))}); "
                         f"the six positions are each axis pointing down and up")
    plus = np.array([found["+" + c][0] for c in "xyz"])   # rows: positions
    minus = np.array([found["-" + c][0] for c in "xyz"])
    A = (plus - minus).T / 2.0                            # column j: axis j's +1 g response
    sens = np.diag(A).copy()
    b = np.array([(plus[j, j] + minus[j, j]) / 2.0 for j in range(3)])
    if np.any(sens <= 0):
        raise ValueError(f"acc: the +1 g and -1 g readings are reversed on an axis "
                         f"(sensitivities {sens.tolist()})")
    if cross_axis:
        b = (plus + minus).mean(axis=0) / 2.0
        M = np.linalg.inv(A) @ np.diag(sens)
    else:
        M = np.eye(3)
    cal = Calibration("accel", dict(M=M, s=1.0 / sens, b=b))
    g = np.linalg.norm(cal.apply(np.vstack([plus, minus])), axis=1)
    figures = dict(sensitivity=sens.tolist(), positions={k: list(v[1]) for k, v in found.items()},
                   magnitude_error=float(np.abs(g - 1.0).max()))
    return Calibration("accel", cal.params, figures)


# ---- magnetometer ------------------------------------------------------------------------

def _check_spread(m, center):
    """Refuse data that do not turn the sensor in three dimensions."""
    d = m - center
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    ev = np.linalg.eigvalsh(np.cov(d.T))
    if ev[0] < 0.02 * ev[-1]:
        raise ValueError(f"mag: the readings span a plane, not a sphere (flat rotation: "
                         f"directions' spread ratio {ev[0] / ev[-1]:.2g} < 0.02); turn the "
                         f"unit about all three axes (a figure of 8 in three dimensions)")


def _check_turned(m, lo, hi):
    """Refuse readings that never change on an axis (a unit that never turned)."""
    span = hi - lo
    tiny = 1e-9 * max(float(np.abs(m).max()), 1e-300)
    flat = [("xyz"[j], float(span[j])) for j in range(3) if not span[j] > tiny]
    if flat:
        raise ValueError("mag: the readings do not change on axis " +
                         ", ".join(f"{a} (range {s:g})" for a, s in flat) +
                         ": the unit never turned; record while turning it about all three "
                         "axes (a figure of 8 in three dimensions)")


def _check_coverage(u, what):
    """u: calibrated readings in units of the field (unit sphere when the fit is right). A
    calibration needs each axis to have pointed along the field: at the reading where an axis
    is largest (and smallest), the two others must be small. Readings from a cap of directions
    (a unit that turned a little) put the extremes off the axes."""
    for j, ax in enumerate("xyz"):
        for k, sign in ((int(np.argmax(u[:, j])), "+"), (int(np.argmin(u[:, j])), "-")):
            others = float(np.hypot(*np.delete(u[k], j)))
            if not others < 0.75:
                raise ValueError(
                    f"mag: {what}: the readings do not cover the directions: where {sign}{ax} is "
                    f"{'largest' if sign == '+' else 'smallest'} (sample {k}) the other axes are "
                    f"{others:.2f} of the field (below 0.75 when {sign}{ax} points near it); "
                    "turn the unit about all three axes (a figure of 8 in three dimensions)")


def _turned(mag, min_rows):
    """The readings as (N, 3), refused unless the unit turned in three dimensions (above),
    with their mean c0 and largest deviation sc: the least-squares fits work on
    (m - c0) / sc, centred and scaled for conditioning."""
    m = _nx3("mag", mag, min_rows)
    lo, hi = m.min(axis=0), m.max(axis=0)
    _check_turned(m, lo, hi)
    _check_spread(m, (hi + lo) / 2.0)
    c0 = m.mean(axis=0)
    return m, c0, float(np.abs(m - c0).max())


def _mag_result(cal, m, f, what, u=None, **figures):
    """The fit's calibration after the coverage check (u: the readings it checks, in units of
    the field; default the calibrated readings / f), with its figures: field f, residual
    (RMS of |m_c| - f), field_spread (std of |m_c|) and the fit's own."""
    mc = cal.apply(m)
    _check_coverage(mc / f if u is None else u, what)
    r = np.linalg.norm(mc, axis=1)
    return Calibration("mag", cal.params, dict(field=f, **figures,
                                               residual=float(np.sqrt(np.mean((r - f) ** 2))),
                                               field_spread=float(r.std())))


def mag_minmax(mag, field=None):
    """Nair's hard-iron calibration: h = (max + min)/2 per axis and a
    per-axis scale (max - min)/2; S = diag(field / scale) with field the
    mean of the three scales unless given (keeps the sensor's unit)."""
    m = _nx3("mag", mag, 10)
    lo, hi = m.min(axis=0), m.max(axis=0)
    _check_turned(m, lo, hi)
    h = (hi + lo) / 2.0
    _check_spread(m, h)
    scale = (hi - lo) / 2.0
    f = float(scale.mean()) if field is None else float(field)
    S = np.diag(f / scale)
    return _mag_result(Calibration("mag", dict(S=S, h=h)), m, f, "min/max",
                       u=(m - h) / scale, scale=scale.tolist())


def mag_sphere(mag):
    """Hard iron only: the least-squares sphere |m - h| = r, written as
    |m|^2 = 2 m.h + (r^2 - |h|^2), linear in (h, r^2 - |h|^2). S is the identity (the
    log's unit kept): the offset that RobustAHRS holds and learns (set_mag_offset;
    imufuse.calibration.mag_offset reads it from the file). Figures: field (r),
    residual (RMS of |m - h| - r), field_spread (std of |m - h|)."""
    m, c0, sc = _turned(mag, 10)
    x = (m - c0) / sc
    A = np.column_stack([2.0 * x, np.ones(len(x))])
    v, *_ = np.linalg.lstsq(A, np.einsum("ij,ij->i", x, x), rcond=None)
    r2 = v[3] + v[:3] @ v[:3]
    if not r2 > 0.0:
        raise ValueError("mag: the readings do not determine a sphere (the fit's radius^2 is "
                         f"{r2:.3g}); record while turning the unit about all three axes")
    h = c0 + sc * v[:3]
    return _mag_result(Calibration("mag", dict(S=np.eye(3), h=h)), m, sc * float(np.sqrt(r2)),
                       "sphere")


def mag_ellipsoid(mag, field=None):
    """Least-squares ellipsoid fit: m_u lies on (m - h)^T Q (m - h) = 1. h is
    the hard iron, S = field Q^(1/2) (symmetric) the soft iron, so that
    |S (m_u - h)| = field. field: default the geometric mean radius of the
    ellipsoid (keeps the sensor's unit). Figures: field, the ellipsoid's
    radii, residual (RMS of |m_c| - field), field_spread (std of |m_c|)."""
    m, c0, sc = _turned(mag, 20)
    x, y, z = ((m - c0) / sc).T
    D = np.column_stack([x * x, y * y, z * z, 2 * y * z, 2 * x * z, 2 * x * y,
                         2 * x, 2 * y, 2 * z])
    v, *_ = np.linalg.lstsq(D, np.ones(len(m)), rcond=None)
    Q = np.array([[v[0], v[5], v[4]], [v[5], v[1], v[3]], [v[4], v[3], v[2]]])
    try:
        center = -np.linalg.solve(Q, v[6:9])
    except np.linalg.LinAlgError:
        raise ValueError("mag: the readings do not determine an ellipsoid (singular fit)") \
            from None
    k = 1.0 + center @ Q @ center
    Qn = Q / k
    w, V = np.linalg.eigh(Qn)
    if not (k > 0 and np.all(w > 0)):
        raise ValueError(f"mag: the best-fitting quadric is not an ellipsoid (eigenvalues "
                         f"{w.tolist()}); the readings are too noisy or too few orientations")
    radii = sc / np.sqrt(w)
    h = c0 + sc * center
    f = float(np.prod(radii) ** (1.0 / 3.0)) if field is None else float(field)
    S = f / sc * (V @ np.diag(np.sqrt(w)) @ V.T)
    return _mag_result(Calibration("mag", dict(S=S, h=h)), m, f, "ellipsoid",
                       radii=sorted(radii.tolist()))


# ---- files and the command line ----------------------------------------------------------
