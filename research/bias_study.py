"""RobustAHRS on an uncalibrated gyroscope: the seven BROAD development trials with a constant
gyro bias b = B (0.8, -0.6, 1.0) deg/s added, started at rest (as recorded) or in motion (the
first rest cut off: the trial starts at its first movement sample), beside VQF 2.1 in real
time. Prints the tables of docs/recommended-ahrs.md's uncalibrated-sensor section.

    python research/bias_study.py [--dir ../shared/data/broad] [--bias 0,1,2,3,5] [--no-vqf]
                                  [-p NAME=VALUE ...]

Metrics: imufuse.evaluation (BROAD paper), each trial's RMS averaged over the trials.
"""
import argparse

import numpy as np

from imufuse import catalogue, evaluation
from broad_compare import DEFAULT_DIR, trials

DIRECTION = np.radians([0.8, -0.6, 1.0])


def cut(d, motion):
    """The trial's arrays, from its first movement sample when ``motion``."""
    k = int(np.argmax(d["movement"])) if motion else 0
    return {n: d[n][k:] for n in ("gyr", "acc", "mag", "quat_ref", "movement")}, float(d["rate"])


def robust(d, dt, params):
    e = catalogue.entry("RobustAHRS")
    f = catalogue.make_filter("RobustAHRS", "c", "float64", dict(e.defaults, dt=dt, **params))
    return catalogue.estimate(f, f.run(d["gyr"], d["acc"], d["mag"], outputs="q")).q, "NWU"


def vqf(d, dt, params):
    from vqf import VQF
    out = VQF(dt).updateBatch(np.ascontiguousarray(d["gyr"]), np.ascontiguousarray(d["acc"]),
                              np.ascontiguousarray(d["mag"]))
    return out["quat9D"], "ENU"


def score(data, est, B, motion, params):
    ev, heads = [], []
    for _, raw in data:
        d, rate = cut(raw, motion)
        d = dict(d, gyr=d["gyr"] + B * DIRECTION)
        q, frame = est(d, 1.0 / rate, params)
        e = evaluation.evaluate(q, d["quat_ref"], est_frame=frame, ref_frame="ENU",
                                movement=d["movement"], per_sample=False)
        ev.append(e)
        heads.append(e.heading)
    m = evaluation.mean_over_trials(ev)
    return m["inclination"], m["heading"], max(heads), [e.inclination for e in ev], heads


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=DEFAULT_DIR)
    ap.add_argument("--bias", default="0,1,2,3,5")
    ap.add_argument("--no-vqf", action="store_true")
    ap.add_argument("--per-trial", action="store_true")
    ap.add_argument("-p", action="append", default=[], help="RobustAHRS NAME=VALUE")
    a = ap.parse_args(argv)
    params = {k: (float(v) if v not in ("True", "False") else v == "True")
              for k, v in (s.split("=", 1) for s in a.p)}
    data = trials(a.dir)
    Bs = [float(b) for b in a.bias.split(",")]
    for motion in (False, True):
        print(f"\n### started {'in motion (first rest cut off)' if motion else 'at rest'}\n")
        print("| bias B (deg/s) | RobustAHRS tilt / heading (worst) | VQF tilt / heading (worst) |")
        print("|---:|---|---|")
        for B in Bs:
            r = score(data, robust, B, motion, params)
            row = f"| {B:g} | {r[0]:.3f} / {r[1]:.2f} ({r[2]:.1f}) |"
            if not a.no_vqf:
                v = score(data, vqf, B, motion, {})
                row += f" {v[0]:.3f} / {v[1]:.2f} ({v[2]:.1f}) |"
            else:
                row += " - |"
            print(row, flush=True)
            if a.per_trial:
                print("|  | " + " ".join(f"{t:.2f}/{h:.1f}" for t, h in zip(r[3], r[4])) + " | |")


if __name__ == "__main__":
    main()
