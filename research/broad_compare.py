"""BROAD development trials: every imufuse 3-D filter (catalogue defaults) beside the
recommended AHRS and, when installed, VQF and Fusion (imufusion); plus the ablation of the
recommended filter's blocks. Prints the markdown tables of docs/recommended-ahrs.md.

    python research/broad_compare.py [--dir ../shared/data/broad] [--no-peers] [--ablation-only]

Metrics: imufuse.evaluation (BROAD paper): inclination RMS over the movement samples with
a finite reference (6-D filters: inclination only; 9-D: inclination and heading), each
trial's RMS averaged over the trials. One parameter set for all trials, causal, started
from the first samples.
"""
import argparse
import glob
import math
import os
import sys

import numpy as np

from imufuse import catalogue, evaluation

DEFAULT_DIR = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "broad")


def trials(path):
    files = sorted(glob.glob(os.path.join(path, "*.npz")))
    if not files:
        sys.exit(f"no BROAD trials (*.npz) in {path}")
    return [(os.path.basename(f)[:2], np.load(f)) for f in files]


def score(data, estimator, nine):
    """Mean inclination (and heading) RMS over the trials; estimator -> NWU q or ENU q."""
    ev = []
    for _, d in data:
        dt = 1.0 / float(d["rate"])
        q, frame = estimator(d, dt)
        ev.append(evaluation.evaluate(q, d["quat_ref"], est_frame=frame, ref_frame="ENU",
                                      movement=d["movement"]))
    m = evaluation.mean_over_trials(ev)
    per = [e.inclination for e in ev]
    return m["inclination"], (m["heading"] if nine else math.nan), per, \
        [e.heading for e in ev] if nine else None


def imufuse_estimator(name, **params):
    e = catalogue.entry(name)

    def est(d, dt):
        f = catalogue.make_filter(name, "c", "float64", dict(e.defaults, dt=dt, **params))
        # BROAD's accelerometer is in m/s^2; a filter that compares it with acc_1g (MultiWii's
        # window, an acc_gate) gets it in acc_1g's unit, g, as imufuse compare gives it
        acc = d["acc"] / 9.80665 if "acc_1g" in e.params else d["acc"]
        args = (d["gyr"], acc) + ((d["mag"],) if e.kind == "ahrs" else ())
        return catalogue.estimate(f, f.run(*args)).q, "NWU"
    return est


def vqf_estimator(nine, latency=0.0):
    """VQF at its defaults; latency > 0: its output predicted forward as RobustAHRS does
    (q (x) exp(1/2 (w - b) latency), with VQF's own bias), for a like-for-like comparison."""
    def est(d, dt):
        from vqf import VQF
        from imufuse.rotations import quat_from_rotvec, quat_mul
        v = VQF(dt)
        g = np.ascontiguousarray(d["gyr"], dtype=float)
        a = np.ascontiguousarray(d["acc"], dtype=float)
        if nine:
            out = v.updateBatch(g, a, np.ascontiguousarray(d["mag"], dtype=float))
            q = out["quat9D"]
        else:
            out = v.updateBatch(g, a)
            q = out["quat6D"]
        if latency > 0:
            q = quat_mul(q, quat_from_rotvec((g - out["bias"]) * latency))
        return q, "ENU"
    return est


def fusion_estimator(nine):
    def est(d, dt):
        import imufusion
        ahrs = imufusion.Ahrs()
        ahrs.set_sample_period(dt)
        gyr = np.degrees(d["gyr"])
        acc = d["acc"] / 9.81
        mag = d["mag"]
        q = np.empty((len(gyr), 4))
        for k in range(len(gyr)):
            if nine:
                ahrs.update(gyr[k], acc[k], mag[k])
            else:
                ahrs.update_no_magnetometer(gyr[k], acc[k])
            q[k] = ahrs.get_quaternion()
        # Fusion's default convention is NWU
        return q, "NWU"
    return est


ABLATION = [
    ("all blocks (defaults)", {}),
    ("latency=0.002: output predicted by the 2 ms delay of BROAD's IMU", dict(latency=0.002)),
    ("B1 off: no bias at rest (rest_gyr=0)", dict(rest_gyr=0.0)),
    ("B2 short: gravity filter tau_acc=0.5 s", dict(tau_acc=0.5, tau_bias=0.0)),
    ("B2 without the rotation-rate term (rate_ref=0)", dict(rate_ref=0.0)),
    ("B3 off: no bias in motion (tau_bias=0)", dict(tau_bias=0.0)),
    ("B1 and B3 off: no bias estimation", dict(rest_gyr=0.0, tau_bias=0.0)),
    ("B4 no rejection (mag_norm=1e6, mag_dip=90)", dict(mag_norm=1e6, mag_dip=90.0)),
    ("B4 no hold after a disturbance (mag_hold=0)", dict(mag_hold=0.0)),
    ("B6 off: no offset learnt (mag_learn=False)", dict(mag_learn=False)),
    ("B6 estimate always used once trusted (mag_offset_min=0)", dict(mag_offset_min=0.0)),
    ("B6 without the rate term of its noise (mag_lag=0)", dict(mag_lag=0.0)),
]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dir", default=os.environ.get("IMUFUSE_BROAD", DEFAULT_DIR))
    p.add_argument("--no-peers", action="store_true")
    p.add_argument("--ablation-only", action="store_true")
    a = p.parse_args(argv)
    data = trials(a.dir)
    ids = " ".join(t for t, _ in data)
    if not a.ablation_only:
        print("| filter | 6D tilt | 9D tilt | 9D heading |\n|---|---|---|---|")
        rows = []
        pairs = [("RobustIMU", "RobustAHRS"), ("MadgwickIMU", "MadgwickAHRS"),
                 ("MahonyIMU", "MahonyAHRS"), ("DCM", None), ("Mahony2D", None),
                 ("MultiWii", None), ("KK", None)]
        for six, nine in pairs:
            t6 = score(data, imufuse_estimator(six), False)[0]
            if nine:
                t9, h9, _, _ = score(data, imufuse_estimator(nine), True)
            else:
                t9 = h9 = math.nan
            label = f"imufuse {six}" + (f" / {nine}" if nine else "")
            rows.append((label, t6, t9, h9))
        if not a.no_peers:
            for label, mk in (("VQF 2 (vqf, defaults)", vqf_estimator),
                              ("VQF 2 + the same 2 ms output prediction",
                               lambda nine: vqf_estimator(nine, 0.002)),
                              ("Fusion (imufusion, defaults)", fusion_estimator)):
                try:
                    t6 = score(data, mk(False), False)[0]
                    t9, h9, _, _ = score(data, mk(True), True)
                except ImportError:
                    continue
                rows.append((label, t6, t9, h9))
        for label, t6, t9, h9 in rows:
            cells = [("%.2f" % v) if not math.isnan(v) else "" for v in (t6, t9, h9)]
            print(f"| {label} | " + " | ".join(cells) + " |")
        print()
        # per trial, the recommended filter and VQF
        t6, _, per6, _ = score(data, imufuse_estimator("RobustIMU"), False)
        t9, h9, per9, perh = score(data, imufuse_estimator("RobustAHRS"), True)
        print("| trial | " + " | ".join(t for t, _ in data) + " | mean |")
        print("|---" * (len(data) + 2) + "|")
        print("| RobustIMU tilt | " + " | ".join("%.2f" % v for v in per6) + f" | {t6:.2f} |")
        print("| RobustAHRS tilt | " + " | ".join("%.2f" % v for v in per9) + f" | {t9:.2f} |")
        print("| RobustAHRS heading | " + " | ".join("%.2f" % v for v in perh) + f" | {h9:.2f} |")
        print()
    print(f"| RobustIMU / RobustAHRS variant (trials {ids}) | 6D tilt | 9D tilt | 9D heading |")
    print("|---|---|---|---|")
    for label, kw in ABLATION:
        imu_kw = {k: v for k, v in kw.items() if not k.startswith("mag")}
        t6 = score(data, imufuse_estimator("RobustIMU", **imu_kw), False)[0]
        t9, h9, _, _ = score(data, imufuse_estimator("RobustAHRS", **kw), True)
        print(f"| {label} | {t6:.3f} | {t9:.3f} | {h9:.3f} |")


if __name__ == "__main__":
    main()
