"""The Robust filters' cost per update once started, on the emulated ATmega328P.

    python bench/mcu/robust_steady.py

measure.py's median covers the stored samples from power-up: for the Robust filters at
dt = 1/512 that is their start-up (B5's running means, each a reciprocal, until tau_rest), and
never B3 (from tau_acc on) nor the bias at rest (after rest_time). Here the filter takes its
first sample as usual, then its start-up clock is set to its end (n = n_max in fixed point,
t = t_max in float); of the 40 samples, the median of the last 37:
  motion  gyro within +-400 counts (+-24 deg/s), accelerometer 1 g +-300 counts: B3 on;
  rest    within +-3 counts, the rest clock at rest_time: B1's bias at rest on.
Float32 (RobustIMU, RobustAHRS without B6; gyr_bias_max=0, as fixed point) and both
fixed-point profiles, side by side in one run; the ratios fixed / float32 are printed.
"""
from __future__ import annotations

import numpy as np

from imufuse import mcu, reference
from imufuse.mcu.filters import FilterSpec

DT = 1 / 512
GS = 1.0642e-3            # rad/s per count
# float32 with gyr_bias_max=0: the fixed-point filters' B1 and B3 are those of a calibrated gyro
CASES = [("RobustIMU", dict(dt=DT, gyr_bias_max=0.0), "float32"),
         ("RobustIMUQ", dict(dt=DT, gyr_scale=GS), "p32"),
         ("RobustIMUQ", dict(dt=DT, gyr_scale=GS), "p8"),
         ("RobustAHRS", dict(dt=DT, mag_learn=False, gyr_bias_max=0.0), "float32"),
         ("RobustAHRSQ", dict(dt=DT, gyr_scale=GS), "p32"),
         ("RobustAHRSQ", dict(dt=DT, gyr_scale=GS), "p8")]


def _inputs(name, prec, mode, n=40):
    rng = np.random.default_rng(2)
    w = 400 if mode == "motion" else 3
    a = 300 if mode == "motion" else 3
    g = rng.integers(-w, w, (n, 3))
    acc = rng.integers(-a, a, (n, 3)) + [0, 0, 4096]
    mag = rng.integers(-10, 10, (n, 3)) + [200, 0, -300]
    if prec.startswith("p"):
        ins = {"gyr": g.astype(np.int16), "acc": acc.astype(np.int16), "mag": mag.astype(np.int16)}
    else:
        ins = {"gyr": (g * GS).astype(np.float32), "acc": (acc / 4096 * 9.81).astype(np.float32),
               "mag": (mag * 0.15).astype(np.float32)}
    if "AHRS" not in name:
        del ins["mag"]
    return ins


def _clock(name, prec, mode):
    """C statements that end the start-up (and, at rest, start the rest)."""
    if not prec.startswith("p"):
        return "f.x.t = f.set.t_max;" + (" f.x.t_rest = 10.0f;" if mode == "rest" else "")
    x, k = ("f.x", "f.k") if name == "RobustIMUQ" else ("f.x.imu", "f.k.imu")
    return f"{x}.n = {k}.n_max;" + (f" {x}.n_rest = {k}.n_rest;" if mode == "rest" else "")


def measure(name, params, prec, mode):
    s = FilterSpec.make(getattr(reference, name), params, prec)
    decl, init, step, _ = s.c_parts("f")
    fixed = prec.startswith("p")
    q = ("f.x.q" if name == "RobustIMUQ" else "f.x.imu.q") if fixed else None
    out = (f"{{ int i; for (i = 0; i < 3; ++i) o3[i] = {q}[i]; }}" if q
           else "o3[0] = f.x.q[0]; o3[1] = f.x.q[1]; o3[2] = f.x.q[2];")
    drv = mcu.Driver(prelude=decl + f"\nstatic {'int32_t' if fixed else 'float'} o3[3];\n",
                     init=init,
                     step=(step + " { static int started; if (!started) { started = 1; "
                           + _clock(name, prec, mode) + " } } " + out),
                     state=mcu.state_words("o3", "i32" if fixed else "f32", 3))
    r = mcu.run("avr", sources=[str(s.c.source)], include_dirs=[s.csrc, s.csrc / "fixed"],
                defines=s.defines, driver=drv, inputs=_inputs(name, prec, mode), count=True)
    return int(np.median(np.asarray(r.counts)[3:]))


def main():
    rows = {}
    for name, params, prec in CASES:
        for mode in ("motion", "rest"):
            rows[(name, prec, mode)] = measure(name, params, prec, mode)
    print("| filter | profile | motion (cycles) | ratio | rest (cycles) | ratio |")
    print("|---|---|---:|---:|---:|---:|")
    for name, _, prec in CASES:
        twin = name.rstrip("Q")
        m, r = rows[(name, prec, "motion")], rows[(name, prec, "rest")]
        fm, fr = rows[(twin, "float32", "motion")], rows[(twin, "float32", "rest")]
        print(f"| {name} | {prec} | {m} | {m / fm:.3f} | {r} | {r / fr:.3f} |")


if __name__ == "__main__":
    main()
