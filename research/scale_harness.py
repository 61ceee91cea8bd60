"""Harness of the scale-error study (research/scale_consider.py): test_scale_error's
scenario and the seven BROAD development trials (from rest; started in motion with an added
bias B as research/bias_study.py), per trial, for any RobustAHRS-like class."""
import os
import sys
import tempfile

import numpy as np

import imufuse_c
from imufuse import evaluation
from imufuse.sim import disturb as sd
from bias_study import DIRECTION, cut
from broad_compare import DEFAULT_DIR, trials

BIG = (4.0, -3.0, 5.0)
SCALES = ((1.03, 0.97, 1.03), (0.97, 1.03, 0.97))


def rms(v):
    return float(np.sqrt(np.mean(np.square(v))))


def errs(S, s, since=60.0):
    tilt, head = sd.errors(S[:, :4], s.q_true)
    m = s.moving & (np.arange(len(S)) * s.dt >= since)
    return rms(tilt[m]), rms(head[m])


def scale_test(make, scales=SCALES):
    """test_scale_error: [(scale, dt_tilt, dt_head)], bound 0.3 / 1.0 deg."""
    s = sd.scenario("bias_walk", rate=100.0, duration=120.0, rest=0.0, seed=8, bias_deg=BIG)
    c = sd.scenario("bias_walk", rate=100.0, duration=120.0, rest=0.0, seed=8)
    C = imufuse_c.RobustAHRS(c.dt, latency=0.0).run(c.gyr, c.acc, c.mag)
    t0, h0 = errs(C, c)
    omega = s.gyr - s.bias
    out = []
    for scale in scales:
        f = make(s.dt)
        S = f.run(omega * np.asarray(scale) + s.bias, s.acc, s.mag)
        t, h = errs(S, s)
        out.append((scale, t - t0, h - h0, getattr(f, "_sc", None)))
    return out


def broad(make, motion=False, B=0.0, data=None, names=None):
    """[(name, tilt, heading)] per trial."""
    data = data or trials(DEFAULT_DIR)
    out = []
    for name, raw in data:
        if names and name[:2] not in names:
            continue
        d, rate = cut(raw, motion)
        g = d["gyr"] + B * DIRECTION
        f = make(1.0 / rate)
        q = f.run(g, d["acc"], d["mag"])[:, :4]
        e = evaluation.evaluate(q, d["quat_ref"], est_frame="NWU", ref_frame="ENU",
                                movement=d["movement"], per_sample=False)
        out.append((name[:2], e.inclination, e.heading, getattr(f, "_peak", None)))
        sys.stdout.flush()
    return out


def baseline_path():
    """Today's per-trial numbers (written by this script): $SCALE_BASELINE, else
    <tempdir>/scale_baseline.json."""
    return os.environ.get("SCALE_BASELINE",
                          os.path.join(tempfile.gettempdir(), "scale_baseline.json"))


def c_make(dt):
    return imufuse_c.RobustAHRS(dt, latency=0.0)


if __name__ == "__main__":
    import json
    res = {}
    for motion, B in ((False, 0.0), (True, 0.0), (True, 2.0), (True, 5.0)):
        r = broad(c_make, motion, B)
        res[f"{int(motion)}_{B:g}"] = [(n, t, h) for n, t, h, _ in r]
        print(motion, B, "mean %.3f / %.2f" % (np.mean([x[1] for x in r]), np.mean([x[2] for x in r])),
              " ".join("%s %.3f/%.2f" % (n, t, h) for n, t, h, _ in r), flush=True)
    path = sys.argv[1] if len(sys.argv) > 1 else baseline_path()
    with open(path, "w") as f:
        json.dump(res, f)
    print(scale_test(lambda dt: imufuse_c.RobustAHRS(dt, latency=0.0)))
