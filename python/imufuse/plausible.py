"""Plausibility of a log against physics: the usual unit and rate mistakes, named with the
option that fixes them (one line each; imufuse.io.read_log adds them to Log.warnings).

  accelerometer  |acc| at rest is 1 g: a median near 9.8 read as g is m/s^2 (--acc-unit m/s2);
                 a median near 0.1 read as m/s^2 is g (--acc-unit g)
  gyroscope      no MEMS gyro measures beyond 2000 deg/s = 35 rad/s: rates read as rad/s whose
                 99th percentile passes 35 rad/s are deg/s (--gyr-unit deg/s)
  gyro vs. acc   the rotation the gyroscope gives over windows of 0.2 s against the turn of the
                 accelerometer's (and magnetometer's) direction over the same windows: deg/s
                 read as rad/s turns 57.3 times too far, on slow logs too (gyro_scale); rad/s
                 read as deg/s 57.3 times too little (judged on the windows where the
                 directions turn, since the gyro's own turns are then too small to count)
  gyro samples   a rate beyond GYRO_ABSURD_RAD_S (1e4 rad/s: beyond 2000 deg/s read as rad/s
                 too) comes from no gyroscope in any unit: corrupt samples, which the filters
                 take as they are (one of 1e30 rad/s turns the attitude anywhere)
  time           a time column whose median interval is 1 to 100 "s" (10 mHz to 1 Hz) is
                 milliseconds (--time-unit ms); 100 s and beyond, microseconds (--time-unit us);
                 below 20 us (50 kHz, faster than any IMU samples) a unit too small
  rate           a --rate that disagrees with the time column by more than 1 %

Only what the user did not state is questioned: a unit from the header or the command line
is the user's word (the checks then still name a contradiction, as a warning). None of them
fires on the shipped example, the BROAD trials or the x-io example log read correctly (the
tests check the shipped example and logs in those layouts).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from .shared.runs import longest

__all__ = ["check_log", "gyro_scale", "gyro_axes", "gyro_axes_note", "still_gyro", "GyroScale"]

G = 9.80665
MAX_GYRO_RAD_S = 35.0          # 2000 deg/s, the largest range of common MEMS gyros
GYRO_ABSURD_RAD_S = 1e4        # beyond 2000 deg/s read as rad/s (3464 on three axes)
MIN_INTERVAL_S = 2e-5          # 50 kHz: IMUs sample at 32 kHz at most
# the unit 1000 times larger than each time unit
_TIME_LARGER = {"ns": "us", "us": "ms", "ms": "s"}

# the gyroscope against the directions of gravity and the magnetic field (gyro_scale)
TURN_WINDOW = 0.2              # s: each window's length
TURN_MIN = 0.05                # rad (2.9 deg): the turn the gyro gives a direction, to count
TURN_MIN_WINDOWS = 8           # windows that count, per sensor, for a verdict
TURN_RATIO = 10.0              # a ratio beyond this is deg/s read as rad/s (57.3)
TURN_AGREE = 0.5               # median cosine between the turns given and measured
TURN_MAX_SAMPLES = 200_000     # a longer log: 40 stretches of 5000 samples spread over it
# the gyroscope's axes (gyro_axes): a signed permutation of them agrees with every sensor's
# turns to this median cosine, and by this much more than the axes as read (a simulated
# sensor 0.999 or more; on the BROAD trials no other mapping reaches 0.96, and the shipped
# excerpt of trial 03 with its gyro's z negated reads 0.90 as read, 0.986 mapped)
AXES_AGREE = 0.98
AXES_GAIN = 0.05


def _median_norm(a: np.ndarray) -> float:
    with np.errstate(all="ignore"):
        n = np.linalg.norm(a, axis=1)
    n = n[np.isfinite(n)]
    return float(np.median(n)) if n.size else float("nan")


@dataclass(frozen=True)
class GyroScale:
    """What gyro_scale found: ratio, the rotation the gyroscope gives over the turn the
    directions measured (about 1 with the right unit, 57.3 for deg/s read as rad/s; NaN
    when no sensor gives a verdict); windows, how many windows it is the median of;
    sensors, {"acc" / "mag": (windows, median ratio, median cosine)} for each sensor with
    enough windows, and used, the sensors the ratio comes from."""
    ratio: float
    windows: int
    sensors: Dict[str, Tuple[int, float, float]] = field(default_factory=dict)
    used: Tuple[str, ...] = ()


def _unit(v: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):
        return v / np.linalg.norm(v, axis=1, keepdims=True)


def _turns(gyr, vec, dts, ok, w, step, h):
    """(given, measured, cosine) per window: the change of the direction of vec that the
    gyro's rates give (the sum of u x w dt over the window: exact to first order, so a
    scaled gyro scales it without wrapping at 180 deg), and the change measured (the
    direction averaged over 2h+1 samples at each end), for the windows whose samples (and
    ends) are all valid."""
    n = len(vec)
    u = _unit(vec)
    ok = ok & np.isfinite(u).all(axis=1)
    u = np.where(ok[:, None], u, 0.0)
    c = np.cross(u, np.where(ok[:, None], gyr, 0.0)) * np.where(ok, dts, 0.0)[:, None]
    zero = np.zeros((1, 3))
    csum = np.concatenate([zero, np.cumsum(c, axis=0)])
    usum = np.concatenate([zero, np.cumsum(u, axis=0)])
    bad = np.concatenate([[0], np.cumsum(~ok)])
    i = np.arange(h, n - w - h, step)
    if i.size == 0:
        return np.empty(0), np.empty(0), np.empty(0)
    j = i + w
    clean = bad[j + h + 1] == bad[i - h]
    i, j = i[clean], j[clean]
    given = csum[j + 1] - csum[i + 1]
    measured = _unit(usum[j + h + 1] - usum[j - h]) - _unit(usum[i + h + 1] - usum[i - h])
    p = np.linalg.norm(given, axis=1)
    m = np.linalg.norm(measured, axis=1)
    with np.errstate(all="ignore"):
        cos = np.einsum("ij,ij->i", given, measured) / (p * m)
    return p, m, np.nan_to_num(cos)


def _signed_permutations() -> List[np.ndarray]:
    """The 48 matrices that permute and negate three axes, the identity first."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            P = np.zeros((3, 3))
            P[np.arange(3), perm] = signs
            out.append(P)
    return out


def _axes_cosines(gyr, vec, dts, ok, w, step, h, perms) -> Optional[Tuple[np.ndarray, int]]:
    """(the median cosine of _turns for the gyro read as P w, each P of perms; the windows)
    over the windows where vec's direction turns by TURN_MIN or more; None with fewer than
    TURN_MIN_WINDOWS of them. u x (P w) = sum over k, a of P[k, a] w_a (u x e_k): the nine
    window sums of w_a (u x e_k) dt, once, give every P's."""
    n = len(vec)
    u = _unit(vec)
    ok = ok & np.isfinite(u).all(axis=1)
    u = np.where(ok[:, None], u, 0.0)
    wd = np.where(ok[:, None], gyr, 0.0) * np.where(ok, dts, 0.0)[:, None]
    zero = np.zeros((1, 3))
    usum = np.concatenate([zero, np.cumsum(u, axis=0)])
    bad = np.concatenate([[0], np.cumsum(~ok)])
    i = np.arange(h, n - w - h, step)
    j = i + w
    if i.size:
        clean = bad[j + h + 1] == bad[i - h]
        i, j = i[clean], j[clean]
    measured = _unit(usum[j + h + 1] - usum[j - h]) - _unit(usum[i + h + 1] - usum[i - h])
    m = np.linalg.norm(measured, axis=1)
    sel = m >= TURN_MIN
    if int(sel.sum()) < TURN_MIN_WINDOWS:
        return None
    i, j, measured, m = i[sel], j[sel], measured[sel], m[sel]
    part = {}
    for k in range(3):
        uk = np.cross(u, np.eye(3)[k])
        for a in range(3):
            cs = np.concatenate([zero, np.cumsum(uk * wd[:, a:a + 1], axis=0)])
            part[k, a] = cs[j + 1] - cs[i + 1]
    out = np.empty(len(perms))
    for q, P in enumerate(perms):
        given = sum(P[k, a] * part[k, a] for k in range(3) for a in range(3) if P[k, a] != 0)
        with np.errstate(all="ignore"):
            cos = np.einsum("ij,ij->i", given, measured) / (np.linalg.norm(given, axis=1) * m)
        out[q] = float(np.median(np.nan_to_num(cos)))
    return out, int(sel.sum())


def gyro_axes(gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None,
              dts=None, breaks: Optional[np.ndarray] = None
              ) -> Optional[Tuple[np.ndarray, float, float, int]]:
    """(P, cosine with P, cosine as read, windows) when the gyroscope read through a signed
    permutation P of its axes (P w: a gyro wired, or declared, with other axes than the
    accelerometer's) turns the directions of the accelerometer and the magnetometer as
    they turn, the median cosine over the windows of gyro_scale where they turn by
    TURN_MIN at least AXES_AGREE for each sensor, and AXES_GAIN above the axes as read;
    else None. The cosine does not depend on the unit."""
    gyr, dts = np.asarray(gyr, float), np.asarray(dts, float)
    n = len(gyr)
    with np.errstate(all="ignore"):
        med = float(np.median(dts[np.isfinite(dts) & (dts > 0)])) if n else math.nan
    if not (med > 0 and math.isfinite(med)) or n < 8:
        return None
    w = max(2, int(round(TURN_WINDOW / med)))
    h = max(1, int(round(0.01 / med)))
    ok = np.isfinite(gyr).all(axis=1) & np.isfinite(dts) & (dts > 0) & (dts <= 3.0 * med)
    if breaks is not None:
        ok[np.asarray(breaks, dtype=np.int64)] = False
    perms = _signed_permutations()
    worst, windows = None, 0                     # per P, the smallest median over the sensors
    for vec in (acc, mag):
        if vec is None:
            continue
        got = _axes_cosines(gyr, np.asarray(vec, float), dts, ok, w, max(1, w // 4), h, perms)
        if got is None:
            continue                             # too few turns of this sensor
        worst = got[0] if worst is None else np.minimum(worst, got[0])
        windows = max(windows, got[1])
    if worst is None:
        return None
    best = int(np.argmax(worst))
    if best == 0 or worst[best] < AXES_AGREE or worst[best] - worst[0] < AXES_GAIN:
        return None
    return perms[best], float(worst[best]), float(worst[0]), windows


AXES_NOTE = "the gyroscope's axes disagree"


def _axes_note(gyr, acc, mag, dts, breaks, applied=None) -> Optional[str]:
    axes = gyro_axes(gyr, acc, mag, dts, breaks)
    if axes is None:
        return None
    P, good, bad, k = axes
    name = ", ".join(("-" if P[i].sum() < 0 else "") + "xyz"[int(np.abs(P[i]).argmax())]
                     for i in range(3))
    which = "the accelerometer" + ("" if mag is None else " and the magnetometer")
    if applied is None:
        fix = f"give a calibration file whose gyroscope.M is {P.astype(int).tolist()}"
    else:   # the gyro as calibrated (M s (w - b)): M becomes P M
        fix = (f"set the calibration file's gyroscope.M to "
               f"{(np.round(P @ np.asarray(applied, float), 6) + 0.0).tolist()} (its M, then "
               "that mapping)")
    return (f"{AXES_NOTE} with the turns of {which} (median cosine {bad:.2f} over {k} windows "
            f"of {TURN_WINDOW:g} s); read as ({name}) they agree ({good:.3f}): a gyro wired or "
            f"declared with other axes? {fix} (imufuse run --calibration)")


def gyro_axes_note(log, applied=None) -> Optional[str]:
    """The note of gyro_axes on the log's columns as they are now, or None; applied: the
    gyroscope.M of the calibration they were calibrated with (imufuse.session), which the
    note's fix composes with."""
    cols = log.columns
    if log.dt is None or not all(f"{k}_{a}" in cols for k in ("gyr", "acc") for a in "xyz"):
        return None
    dts = log.dts if log.dts is not None else np.full(len(log), float(log.dt))
    take, breaks = _stretches(len(log)) if len(log) > TURN_MAX_SAMPLES else (slice(None), None)

    def sensor(k):
        return np.column_stack([cols[f"{k}_{a}"][take] for a in "xyz"])
    mag = sensor("mag") if all(f"mag_{a}" in cols for a in "xyz") else None
    return _axes_note(sensor("gyr"), sensor("acc"), mag, np.asarray(dts)[take], breaks,
                      applied)


def _stretches(n: int, block: int = 5000) -> Tuple[np.ndarray, np.ndarray]:
    """(the samples taken, where each stretch starts among them): TURN_MAX_SAMPLES // block
    stretches of `block` samples spread over n."""
    first = np.linspace(0, n - block, TURN_MAX_SAMPLES // block).astype(np.int64)
    return (first[:, None] + np.arange(block)).ravel(), np.arange(len(first)) * block


def gyro_scale(gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None,
               dts=None, dt: Optional[float] = None,
               breaks: Optional[np.ndarray] = None, too_small: bool = False) -> GyroScale:
    """How far the gyroscope (rad/s, (N, 3)) turns the directions of the accelerometer and
    the magnetometer (when given), against how far they turn: over windows of TURN_WINDOW
    s where the gyro turns a direction by TURN_MIN or more, the median ratio of the turn
    it gives over the turn measured. With the right unit it is about 1 (0.5 to 1.2 on the
    BROAD trials: the accelerometer's direction also turns with linear acceleration);
    deg/s read as rad/s gives 57.3 (the gyro is 57.3 times too fast). A sensor whose turns
    point elsewhere than the gyro's (median cosine below TURN_AGREE: strong linear
    acceleration, a coordinated turn where the accelerometer keeps its direction, axes that
    do not match) gives no verdict; the ratio is the smallest over the sensors whose turns
    agree with the gyro's, NaN when none does. dts: each sample's interval (N,), else dt.
    A log of more than TURN_MAX_SAMPLES samples is judged on 40 stretches of 5000 samples
    spread over it (a tenth of a second for 10^6 samples); breaks: the samples where such
    stretches, taken by the caller, begin (no window across one). too_small: judge a gyro
    too slow (rad/s read as deg/s: 1/57.3) on the windows where the directions turn by
    TURN_MIN or more, the ratio the largest over the sensors that agree."""
    n = len(gyr)
    if dts is None:
        if dt is None or not dt > 0:
            return GyroScale(math.nan, 0)
        dts = np.full(n, float(dt))
    starts = None
    if n > TURN_MAX_SAMPLES:
        take, starts = _stretches(n)
        acc = np.asarray(acc)[take]
        mag = None if mag is None else np.asarray(mag)[take]
        gyr, dts = np.asarray(gyr)[take], np.asarray(dts)[take]
    gyr, dts = np.asarray(gyr, float), np.asarray(dts, float)
    n = len(gyr)
    with np.errstate(all="ignore"):
        med = float(np.median(dts[np.isfinite(dts) & (dts > 0)])) if n else math.nan
    if not (med > 0 and math.isfinite(med)) or n < 8:
        return GyroScale(math.nan, 0)
    w = max(2, int(round(TURN_WINDOW / med)))
    h = max(1, int(round(0.01 / med)))
    ok = np.isfinite(gyr).all(axis=1) & np.isfinite(dts) & (dts > 0) & (dts <= 3.0 * med)
    for b in (starts, breaks):
        if b is not None:
            ok[np.asarray(b, dtype=np.int64)] = False    # no window across two stretches
    sensors: Dict[str, Tuple[int, float, float]] = {}
    for name, vec in (("acc", acc), ("mag", mag)):
        if vec is None:
            continue
        p, m, cos = _turns(gyr, np.asarray(vec, float), dts, ok, w, max(1, w // 4), h)
        sel = (m if too_small else p) >= TURN_MIN
        if int(sel.sum()) >= TURN_MIN_WINDOWS:
            with np.errstate(all="ignore"):
                r = p[sel] / m[sel]
            sensors[name] = (int(sel.sum()), float(np.median(r)), float(np.median(cos[sel])))
    # a sensor that turns elsewhere than the gyro says nothing about its scale
    used = tuple(k for k, (_, _, c) in sensors.items() if c >= TURN_AGREE)
    if not used:
        return GyroScale(math.nan, 0, sensors)
    best = (max if too_small else min)(used, key=lambda k: sensors[k][1])
    return GyroScale(sensors[best][1], sensors[best][0], sensors, used)


def _unit_from(source) -> str:
    """Where a unit came from, as the notes say it: from the header, given (the command
    line's --*-unit or read_log's argument), or assumed (the default)."""
    return {None: "assumed", "default": "assumed", "given": "given"}.get(
        source, f"unit from the {source}")


def check_log(log, rate: Optional[float] = None, file_rate: Optional[float] = None,
              file_time: Optional[np.ndarray] = None, where=None) -> List[str]:
    """One-line warnings about the log's units, time and rate (see the module doc): rate is
    the user's --rate, file_rate the rate the file states, file_time its time column (in
    s); where(k): where sample k is in the file ("log.csv:12")."""
    out: List[str] = []
    where = where or (lambda k: f"sample {k}")
    cols = log.columns
    acc_unit, acc_from = log.units.get("acc", (None, None))
    if all(n in cols for n in ("acc_x", "acc_y", "acc_z")) and len(log):
        m = _median_norm(np.column_stack([cols["acc_x"], cols["acc_y"], cols["acc_z"]]))
        if 7.0 < m < 13.0:
            out.append(f"the accelerometer's median magnitude is {m:.3g} {acc_unit} "
                       f"({_unit_from(acc_from)}): "
                       "1 g is 9.81 m/s^2, so these look like m/s^2 read as g; give "
                       "--acc-unit m/s2")
        elif 0.07 < m < 0.13:
            out.append(f"the accelerometer's median magnitude is {m:.3g} g after converting "
                       f"from {acc_unit}: these look like g read as m/s^2; give --acc-unit g")
        elif m > 20.0:
            # no accelerometer range reaches this at rest or in motion: sensor counts
            conv = "" if acc_unit == "g" else f" after converting from {acc_unit}"
            out.append(f"the accelerometer's median magnitude is {m:.3g} g{conv}: raw sensor "
                       "counts? scale them to g or m/s^2 first (the datasheet's counts per g, "
                       "e.g. 16384 at +-2 g); a filter that compares it with 1 g (MultiWii's "
                       "window, acc_gate, Fusion's rejection) never uses it as it is, unless "
                       "its acc_1g is set to the counts per g")
    gyr_unit, gyr_from = log.units.get("gyr", (None, None))
    if all(n in cols for n in ("gyr_x", "gyr_y", "gyr_z")) and len(log):
        with np.errstate(all="ignore"):
            w = np.linalg.norm(np.column_stack([cols["gyr_x"], cols["gyr_y"], cols["gyr_z"]]),
                               axis=1)
        with np.errstate(invalid="ignore"):
            absurd = np.flatnonzero(w > GYRO_ABSURD_RAD_S)
        if absurd.size:
            k = int(absurd[np.argmax(w[absurd])])
            out.append(f"the gyroscope reads beyond {GYRO_ABSURD_RAD_S:g} rad/s in "
                       f"{absurd.size} sample{'s' if absurd.size > 1 else ''} (the largest "
                       f"{float(w[k]):.3g} rad/s at {where(k)}), more than any gyroscope "
                       "measures in any unit: corrupt samples? the filters take them as they "
                       "are")
        w = w[np.isfinite(w) & ~(w > GYRO_ABSURD_RAD_S)]    # corrupt samples said above
        if w.size and float(np.percentile(w, 99)) > MAX_GYRO_RAD_S and gyr_unit not in (
                None, "rad/s"):
            # already converted from deg/s: larger still than any range, so sensor counts
            out.append(f"the gyroscope passes {MAX_GYRO_RAD_S:g} rad/s (2000 deg/s, the largest "
                       f"MEMS range) in over 1 % of the samples after converting from "
                       f"{gyr_unit} ({_unit_from(gyr_from)}): raw sensor counts? scale them to "
                       "deg/s or rad/s first (the datasheet's counts per deg/s, e.g. 16.4 at "
                       "+-2000 deg/s)")
        elif w.size and float(np.percentile(w, 99)) > MAX_GYRO_RAD_S:
            out.append(f"the gyroscope passes {MAX_GYRO_RAD_S:g} rad/s (2000 deg/s, the largest "
                       f"MEMS range) in over 1 % of the samples, read as rad/s "
                       f"({_unit_from(gyr_from)})"
                       ": these look like deg/s; give --gyr-unit deg/s")
        else:
            out += _gyro_against_directions(log, gyr_unit, gyr_from, rate, file_time)
    t = file_time
    if t is not None and len(t) > 1 and rate is None:
        med = float(np.median(np.diff(t)))
        if 1.0 <= med < 100.0:
            out.append(f"the median sample interval is {med:.4g} s ({1 / med:.3g} Hz): "
                       "an IMU log in milliseconds read as seconds? give --time-unit ms")
        elif med >= 100.0:
            out.append(f"the median sample interval is {med:.4g} s: an IMU log in microseconds "
                       "read as seconds? give --time-unit us")
        elif 0 < med < MIN_INTERVAL_S:
            unit, source = log.units.get("time", ("s", "default"))
            larger = _TIME_LARGER.get(unit)
            out.append(f"the median sample interval is {med:.4g} s ({1 / med:.3g} Hz) with "
                       f"the time column in {unit} ({_unit_from(source)}): faster than any "
                       "IMU samples; "
                       + (f"a log in {larger} read as {unit}? give --time-unit {larger}"
                          if larger else "is the time column in seconds?"))
    if rate is not None and t is not None and len(t) > 1:
        med = float(np.median(np.diff(t)))
        if med > 0 and abs(rate * med - 1.0) > 0.01:
            out.append(f"--rate {rate:g} Hz, but the time column's median interval is "
                       f"{med:.6g} s ({1 / med:.6g} Hz): the filters use --rate; leave it out "
                       "to use the time column")
    elif rate is not None and file_rate is not None and abs(rate / file_rate - 1.0) > 0.01:
        out.append(f"--rate {rate:g} Hz, but the file says {file_rate:g} Hz: the filters use "
                   "--rate; leave it out to use the file's rate")
    return out


def _gyro_against_directions(log, unit, source, rate, file_time) -> List[str]:
    """The note of gyro_scale on a gyroscope read as rad/s (none when the time column looks
    like milliseconds: the intervals would be wrong, and that note comes first)."""
    cols = log.columns
    if unit not in (None, "rad/s", "deg/s") or not all(n in cols for n in
                                                       ("acc_x", "acc_y", "acc_z")):
        return []
    too_small = unit == "deg/s"
    dts = None
    if rate is None and file_time is not None and len(file_time) > 1:
        d = np.diff(np.asarray(file_time, float))
        if float(np.median(d)) >= 1.0:
            return []
        dts = np.concatenate([[float(np.median(d))], d])
    elif log.dt is not None:
        dts = np.full(len(log), float(log.dt))
    # a long log: only its stretches stacked (memory: the log's columns, not three copies)
    take, breaks = _stretches(len(log)) if len(log) > TURN_MAX_SAMPLES else (slice(None), None)

    def sensor(k):
        return np.column_stack([cols[f"{k}_{a}"][take] for a in "xyz"])
    mag = sensor("mag") if all(f"mag_{a}" in cols for a in "xyz") else None
    res = gyro_scale(sensor("gyr"), sensor("acc"), mag, dts=None if dts is None else dts[take],
                     breaks=breaks, too_small=too_small)
    if dts is not None and res.sensors and min(c for _, _, c in res.sensors.values()) < AXES_AGREE:
        note = _axes_note(sensor("gyr"), sensor("acc"), mag, dts[take], breaks)
        if note:
            return [note]
    if not (res.ratio < 1.0 / TURN_RATIO if too_small else res.ratio > TURN_RATIO):
        return []
    what = " and ".join({"acc": "the accelerometer's", "mag": "the magnetometer's"}[k]
                        for k in res.used)
    what += " direction turns" if len(res.used) == 1 else " directions turn"
    if too_small:
        return [f"the gyroscope, read as deg/s ({_unit_from(source)}), turns {res.ratio:.3g} "
                f"times as far as {what} (the median over {res.windows} windows of "
                f"{TURN_WINDOW:g} s): rad/s read as deg/s is 1/57.3 = 0.0175 times; these look "
                "like rad/s; give --gyr-unit rad/s"]
    return [f"the gyroscope, read as rad/s ("
            f"{_unit_from(source)}), "
            f"turns {res.ratio:.3g} times as far as {what} (the median over {res.windows} "
            f"windows of {TURN_WINDOW:g} s): deg/s read as rad/s is 57.3 times; these look "
            "like deg/s; give --gyr-unit deg/s"]


# the gyroscope while the other sensors are still (still_gyro)
STILL_WINDOW = 0.5         # s
STILL_ACC = 0.03           # g: each accelerometer axis's standard deviation over a window,
STILL_MAG = 0.03           # of the field: each magnetometer axis's (noise: 1-10 mg, 1 %),
STILL_STEP = 0.01          # and each one's mean from one window to the next (g, of the field)
STILL_GYR = 0.0175         # rad/s (1 deg/s): each gyro axis's standard deviation, noise only
STILL_MIN = 2.0            # s: the shortest stretch that counts


def still_gyro(log) -> Optional[Tuple[np.ndarray, float, float, bool]]:
    """(the median gyro reading, rad/s (3,); the stretch's start and end, s; whether the
    magnetometer was still too) over the longest stretch of STILL_MIN s or more where, in
    every window of STILL_WINDOW s, the accelerometer (g), the gyroscope and the magnetometer
    (when the log has one) each vary by less than their noise bound: what the gyroscope reads
    at rest, its offset. None without such a stretch, a time base or the sensors."""
    cols = log.columns
    if log.dt is None or not all(f"{k}_{a}" in cols for k in ("gyr", "acc") for a in "xyz"):
        return None
    w = max(2, int(round(STILL_WINDOW / float(log.dt))))
    n = len(log) // w
    if n * w * float(log.dt) < STILL_MIN:
        return None
    has_mag = all(f"mag_{a}" in cols for a in "xyz")

    def stats(k):
        # per window, each axis's mean and standard deviation (n, 3), from views of the
        # columns and one sum of squares (no copy of a column: memory, 10^6-row logs)
        mean, sd = np.empty((n, 3)), np.empty((n, 3))
        for i, a in enumerate("xyz"):
            x = np.asarray(cols[f"{k}_{a}"], dtype=np.float64)[:n * w].reshape(n, w)
            mean[:, i] = x.mean(axis=1)
            sd[:, i] = np.sqrt(np.maximum(np.einsum("ij,ij->i", x, x) / w - mean[:, i] ** 2, 0.0))
        return mean, sd

    def steady(mean, sd, spread, step):
        # each axis within spread over the window, its mean within step of the last window's
        moved = np.concatenate([[True], (np.abs(np.diff(mean, axis=0)) >= step[1:]).any(axis=1)])
        return (sd < spread).all(axis=1) & ~moved
    with np.errstate(all="ignore"):
        am, asd = stats("acc")
        still = steady(am, asd, STILL_ACC, np.full((n, 1), STILL_STEP)) & \
            (stats("gyr")[1] < STILL_GYR).all(axis=1)
        if has_mag:
            mm, ms = stats("mag")
            field = np.linalg.norm(mm, axis=1)[:, None]
            still &= steady(mm, ms, STILL_MAG * field, STILL_STEP * field)
    best = longest(still)
    if (best[1] - best[0]) * w * float(log.dt) < STILL_MIN:
        return None
    lo, hi = best[0] * w, best[1] * w
    step = max(1, (hi - lo) // 100_000)                  # at most 10^5 samples: memory
    med = np.array([np.median(np.asarray(cols[f"gyr_{a}"])[lo:hi:step]) for a in "xyz"])
    return med, float(log.t[lo]), float(log.t[hi - 1]), has_mag
