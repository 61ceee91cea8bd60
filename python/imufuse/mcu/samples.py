"""The inputs of the MCU filter runs: motion from imufuse.sim, then the corner cases.

``float_inputs(group)`` (float64: "1d" rate/angle, "3d" gyr/acc/mag, "vario"
accel/baro_alt/dt), ``fixed_inputs(group)`` (int16 counts of the same motion, scales
``FIXED_COUNTS``, with full-scale extremes) and ``inputs_for(precision, group)`` (in the dtype
the builds of that precision take).
"""

from __future__ import annotations

import math
from typing import Dict

import numpy as np

from .. import sim
from ..sim import flight as sim_flight

__all__ = ["FIXED_COUNTS", "float_inputs", "fixed_inputs", "inputs_for"]


def _rows(n_rows, fill):
    return np.tile(np.asarray(fill, dtype=np.float64), (n_rows, 1))


def float_inputs(group: str, n_motion: int = 300, seed: int = 5) -> Dict[str, np.ndarray]:
    """Float64 inputs of a group ("1d" or "3d"): realistic motion from imufuse.sim, then the
    corners (zero accelerometer/magnetometer, all zero, NaN/Inf in each input, overflow,
    tiny and subnormal values), then motion again. Cast to float32 for the float32 builds."""
    tail = 20
    if group == "1d":
        d = sim.axis1d("fast", rate=100.0, duration=(n_motion + tail) / 100.0, seed=seed,
                       disturbance=0.05)
        rate, angle = np.asarray(d.gyr, float), np.asarray(d.acc_angle, float)
        head_r, head_a = rate[:n_motion], angle[:n_motion]
        tail_r, tail_a = rate[n_motion:], angle[n_motion:]
        cr = [0.0] * 6 + [np.nan, 0.3, -np.inf, np.inf, np.nan, 0.2, 0.1, -0.1] \
            + [3e38, -3e38, 1e30, 1.0] + [1e-40, -3e-42, 1e-30, 0.0] + [1e5, -1e5]
        ca = [0.0] * 6 + [0.1, np.inf, 0.2, -0.3, np.nan, -np.inf, np.nan, 0.05] \
            + [-3e38, 3e38, -1e30, 3e38] + [-1e-40, 1e-45, -1e-30, 1e-38] + [3.0, -3.0]
        return {"rate": np.concatenate([head_r, cr, tail_r]),
                "angle": np.concatenate([head_a, ca, tail_a])}
    if group == "vario":
        return _vario_inputs(n_motion, seed, tail)
    if group != "3d":
        raise ValueError(f"group must be '1d', 'vario' or '3d', got {group!r}")
    d = sim.imu("fast", rate=100.0, duration=(n_motion + tail) / 100.0, seed=seed, lin_acc=1.0,
                amplitude=3.0)
    gyr, acc, mag = (np.asarray(a, float) for a in (d.gyr, d.acc, d.mag))
    g0, a0, m0 = gyr[n_motion - 1], acc[n_motion - 1], mag[n_motion - 1]
    cg, ca, cm = [], [], []

    def add(k, g=None, a=None, m=None):
        cg.append(_rows(k, g0 if g is None else g))
        ca.append(_rows(k, a0 if a is None else a))
        cm.append(_rows(k, m0 if m is None else m))

    add(6, a=[0, 0, 0])                      # zero accelerometer: the guard
    add(6, m=[0, 0, 0])                      # zero magnetometer
    add(3, g=[0, 0, 0], a=[0, 0, 0], m=[0, 0, 0])
    add(1, g=[np.nan, 0.1, 0.2])
    add(1, a=[0.1, np.inf, 1.0])
    add(1, m=[0.3, 0.1, -np.inf])
    add(1, a=[np.nan, 0.0, 1.0])
    add(1, g=[np.inf, -np.inf, 0.0], m=[np.nan, 0, 0])
    add(2, a=[3e38, -3e38, 3e38], m=[-3e38, 3e38, 3e38])   # overflow in the norms
    add(2, g=[1e30, -1e30, 1e30])
    add(2, a=[1e-20, -1e-20, 1e-20], m=[1e-20, 1e-20, -1e-20])  # squares underflow
    add(2, a=[1e-40, 0, 3e-41], m=[0, -1e-40, 0])             # subnormal components
    add(2, g=[25.0, -30.0, 35.0])                             # fast spin
    add(3, a=[1.0, 0.0, 1e-3])                                # nearly vertical
    return {"gyr": np.concatenate([gyr[:n_motion], *cg, gyr[n_motion:]]),
            "acc": np.concatenate([acc[:n_motion], *ca, acc[n_motion:]]),
            "mag": np.concatenate([mag[:n_motion], *cm, mag[n_motion:]])}


def _vario_inputs(n_motion, seed, tail):
    """Nair's variometer: a simulated flight at the barometer rate (vertical
    acceleration cm/s^2, barometer altitude cm, dt s), then the corners (NaN/Inf
    in each input, dt <= 0, overflow, tiny values), then the flight again."""
    fl = sim_flight.flight(duration=(n_motion + tail) / 50.0 + 1.0, seed=seed)
    idx = fl.baro_idx[:n_motion + tail]
    acc = np.diff(fl.climb, prepend=fl.climb[0])[idx] * fl.rate * 100.0 + 20.0
    alt = fl.baro_alt[:n_motion + tail] * 100.0
    dt = np.full(n_motion + tail, 0.02)
    ca = [np.nan, 1.0, 2.0, np.inf, 0.0, 0.0, 3e38, -3e38, 1e-40, 0.0, 5.0, -5.0]
    cz = [alt[n_motion - 1], np.nan, 1e5, 1e5, -np.inf, 1e5, 3e38, 1e5, 1e-40, 1e5, 1e5, 1e5]
    cd = [0.02, 0.02, -np.inf, 0.02, 0.02, 0.0, 0.02, 1e30, 1e-30, -0.02, 0.5, 0.001]
    return {"accel": np.concatenate([acc[:n_motion], ca, acc[n_motion:]]),
            "baro_alt": np.concatenate([alt[:n_motion], cz, alt[n_motion:]]),
            "dt": np.concatenate([dt[:n_motion], cd, dt[n_motion:]])}


#: int16 counts per unit of the fixed-point inputs (gyro +-2000 deg/s, acc +-8 g, angle +-pi)
FIXED_COUNTS = {"rate": 32768 / math.radians(2000.0), "gyr": 32768 / math.radians(2000.0),
                "angle": 32768 / math.pi, "acc": 4096.0, "mag": 1000.0}


def fixed_inputs(group: str, n_motion: int = 300, seed: int = 5) -> Dict[str, np.ndarray]:
    """int16 counts of the same motion (scales FIXED_COUNTS), with the corners: zero vectors,
    full-scale and minimum counts."""
    src = float_inputs(group, n_motion, seed)
    out = {}
    for name, a in src.items():
        a = a.copy()
        a[~np.isfinite(a)] = 0.0
        c = np.clip(np.rint(a * FIXED_COUNTS[name]), -32768, 32767)
        out[name] = c.astype(np.int16)
    k = n_motion
    for name, a in out.items():          # extremes right after the float corners' place
        ext = np.full((6,) + a.shape[1:], 32767, np.int16)
        ext[1::2] = -32768
        out[name] = np.concatenate([a[:k], ext, a[k:]])
    return out


def inputs_for(precision: str, group: str, n_motion: int = 300, seed: int = 5) -> Dict[str, np.ndarray]:
    """The inputs of a (precision, group) in the dtype the builds take."""
    if precision.startswith("p"):
        return fixed_inputs(group, n_motion, seed)
    dt = np.float32 if precision == "float32" else np.float64
    with np.errstate(over="ignore", under="ignore"):
        return {k: v.astype(dt) for k, v in float_inputs(group, n_motion, seed).items()}
