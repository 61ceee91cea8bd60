"""Evaluate the recommended-AHRS prototype on the BROAD development trials.

    python tools/robust_eval.py [key=value ...] [--vqf] [--6d-only]

Metrics as in ../shared/data/broad/README.md (BROAD paper): estimate sensor -> NWU mapped to
ENU (+90 deg about earth z), e = q (x) r^-1, tilt and heading RMS over movement samples with a
finite reference, averaged over trials.
"""
import glob
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
import robust_proto  # noqa: E402

DATA = os.environ.get("BROAD_DIR", "/work/shared/data/broad")
NWU_TO_ENU = np.array([math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)])


def qmul(p, q):
    p0, p1, p2, p3 = np.moveaxis(p, -1, 0)
    q0, q1, q2, q3 = np.moveaxis(q, -1, 0)
    return np.stack([p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
                     p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
                     p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
                     p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0], axis=-1)


def errors(q_enu, ref, mask):
    ok = mask & np.all(np.isfinite(ref), axis=1)
    rinv = ref[ok] * np.array([1, -1, -1, -1])
    e = qmul(q_enu[ok], rinv)
    ew = np.abs(e[:, 0])
    tilt = 2 * np.arccos(np.clip(np.sqrt(e[:, 0] ** 2 + e[:, 3] ** 2), 0, 1))
    head = 2 * np.arctan(np.abs(e[:, 3]) / np.maximum(ew, 1e-300))
    rms = lambda x: math.degrees(math.sqrt(np.mean(x ** 2)))  # noqa: E731
    return rms(tilt), rms(head)


def trials():
    return sorted(glob.glob(os.path.join(DATA, "*.npz")))


def evaluate(estimator, label, six=True, nine=True, verbose=True):
    """estimator(gyr, acc, mag_or_None, dt) -> (N,4) sensor->NWU quaternions."""
    rows = []
    for path in trials():
        d = np.load(path)
        dt = 1.0 / float(d["rate"])
        r = {"trial": os.path.basename(path)[:2]}
        if six:
            q = estimator(d["gyr"], d["acc"], None, dt)
            r["tilt6"], _ = errors(qmul(NWU_TO_ENU, q), d["quat_ref"], d["movement"])
        if nine:
            q = estimator(d["gyr"], d["acc"], d["mag"], dt)
            r["tilt9"], r["head9"] = errors(qmul(NWU_TO_ENU, q), d["quat_ref"], d["movement"])
        rows.append(r)
    keys = [k for k in ("tilt6", "tilt9", "head9") if k in rows[0]]
    mean = {k: float(np.mean([r[k] for r in rows])) for k in keys}
    if verbose:
        print(f"== {label}")
        print("trial " + " ".join(f"{k:>7}" for k in keys))
        for r in rows:
            print(f"{r['trial']:5} " + " ".join(f"{r[k]:7.3f}" for k in keys))
        print("mean  " + " ".join(f"{mean[k]:7.3f}" for k in keys), flush=True)
    return mean, rows


def proto_estimator(**kw):
    def est(gyr, acc, mag, dt):
        return robust_proto.run(gyr, acc, mag, dt=dt, **kw)
    return est


def vqf_estimator(gyr, acc, mag, dt):
    from vqf import VQF
    v = VQF(dt)
    g = np.ascontiguousarray(gyr, dtype=float)
    a = np.ascontiguousarray(acc, dtype=float)
    if mag is None:
        out = v.updateBatch(g, a)
        q = out["quat6D"]
    else:
        out = v.updateBatch(g, a, np.ascontiguousarray(mag, dtype=float))
        q = out["quat9D"]
    # VQF's earth frame is ENU; map back to NWU (the evaluation maps NWU -> ENU)
    return qmul(NWU_TO_ENU * np.array([1, -1, -1, -1]), q)


def reference_estimator(**kw):
    from imufuse import reference

    def est(gyr, acc, mag, dt):
        if mag is None:
            f = reference.RobustIMU(dt, **kw)
            return f.run(gyr, acc)[:, :4]
        f = reference.RobustAHRS(dt, **kw)
        return f.run(gyr, acc, mag)[:, :4]
    return est


def compiled_estimator(**kw):
    import imufuse_c

    def est(gyr, acc, mag, dt):
        if mag is None:
            return imufuse_c.RobustIMU(dt, **kw).run(gyr, acc)[:, :4]
        return imufuse_c.RobustAHRS(dt, **kw).run(gyr, acc, mag)[:, :4]
    return est


def parse(v):
    for t in (int, float):
        try:
            return t(v)
        except ValueError:
            pass
    return {"True": True, "False": False}.get(v, v)


if __name__ == "__main__":
    args = sys.argv[1:]
    kw = {}
    for a in args:
        if "=" in a:
            k, v = a.split("=", 1)
            kw[k] = parse(v)
    six = "--9d-only" not in args
    nine = "--6d-only" not in args
    if "--ref" in args:
        evaluate(reference_estimator(**kw), "reference", six, nine)
    elif "--c" in args:
        evaluate(compiled_estimator(**kw), "compiled", six, nine)
    elif "--vqf" in args:
        evaluate(vqf_estimator, "vqf", six, nine)
    else:
        evaluate(proto_estimator(**kw), "proto " + " ".join(f"{k}={v}" for k, v in kw.items()),
                 six, nine)
