"""Plausibility of a log against physics: the usual unit and rate mistakes, named with the
option that fixes them (one line each; imufuse.io.read_log adds them to Log.warnings).

  accelerometer  |acc| at rest is 1 g: a median near 9.8 read as g is m/s^2 (--acc-unit m/s2);
                 a median near 0.1 read as m/s^2 is g (--acc-unit g)
  gyroscope      no MEMS gyro measures beyond 2000 deg/s = 35 rad/s: rates read as rad/s whose
                 99th percentile passes 35 rad/s are deg/s (--gyr-unit deg/s)
  time           a time column whose median interval is 1 to 100 "s" (10 mHz to 1 Hz) is
                 milliseconds (--time-unit ms); 100 s and beyond, microseconds (--time-unit us)
  rate           a --rate that disagrees with the time column by more than 1 %

Only what the user did not state is questioned: a unit from the header or the command line
is the user's word (the checks then still name a contradiction, as a warning). None of them
fires on the shipped example, the BROAD trials or the x-io example log read correctly (the
tests check the shipped example and logs in those layouts).
"""
from __future__ import annotations

from typing import List, Optional

import numpy as np

__all__ = ["check_log"]

G = 9.80665
MAX_GYRO_RAD_S = 35.0          # 2000 deg/s, the largest range of common MEMS gyros


def _median_norm(a: np.ndarray) -> float:
    with np.errstate(all="ignore"):
        n = np.linalg.norm(a, axis=1)
    n = n[np.isfinite(n)]
    return float(np.median(n)) if n.size else float("nan")


def check_log(log, rate: Optional[float] = None, file_rate: Optional[float] = None,
              file_time: Optional[np.ndarray] = None) -> List[str]:
    """One-line warnings about the log's units, time and rate (see the module doc): rate is
    the user's --rate, file_rate the rate the file states, file_time its time column."""
    out: List[str] = []
    cols = log.columns
    acc_unit, acc_from = log.units.get("acc", (None, None))
    if all(n in cols for n in ("acc_x", "acc_y", "acc_z")) and len(log):
        m = _median_norm(np.column_stack([cols["acc_x"], cols["acc_y"], cols["acc_z"]]))
        if 7.0 < m < 13.0:
            out.append(f"the accelerometer's median magnitude is {m:.3g} {acc_unit} "
                       f"({'unit from the ' + acc_from if acc_from != 'default' else 'assumed'}): "
                       "1 g is 9.81 m/s^2, so these look like m/s^2 read as g; give "
                       "--acc-unit m/s2")
        elif 0.07 < m < 0.13:
            out.append(f"the accelerometer's median magnitude is {m:.3g} g after converting "
                       f"from {acc_unit}: these look like g read as m/s^2; give --acc-unit g")
    gyr_unit, gyr_from = log.units.get("gyr", (None, None))
    if all(n in cols for n in ("gyr_x", "gyr_y", "gyr_z")) and len(log):
        with np.errstate(all="ignore"):
            w = np.linalg.norm(np.column_stack([cols["gyr_x"], cols["gyr_y"], cols["gyr_z"]]),
                               axis=1)
        w = w[np.isfinite(w)]
        if w.size and float(np.percentile(w, 99)) > MAX_GYRO_RAD_S:
            out.append(f"the gyroscope passes {MAX_GYRO_RAD_S:g} rad/s (2000 deg/s, the largest "
                       f"MEMS range) in over 1 % of the samples, read as rad/s "
                       f"({'unit from the ' + gyr_from if gyr_from != 'default' else 'assumed'})"
                       ": these look like deg/s; give --gyr-unit deg/s")
    t = file_time
    if t is not None and len(t) > 1 and rate is None:
        med = float(np.median(np.diff(t)))
        if 1.0 <= med < 100.0:
            out.append(f"the median sample interval is {med:.4g} s ({1 / med:.3g} Hz): "
                       "an IMU log in milliseconds read as seconds? give --time-unit ms")
        elif med >= 100.0:
            out.append(f"the median sample interval is {med:.4g} s: an IMU log in microseconds "
                       "read as seconds? give --time-unit us")
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
