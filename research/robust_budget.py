"""Where the recommended filter's tilt error comes from, on the BROAD development trials.

    python research/robust_budget.py [--dir ../shared/data/broad] [--sensitivity]

Runs RobustIMU (C, float64, catalogue defaults) and prints markdown tables for
docs/recommended-ahrs.md:

1. the error budget per trial: the default's inclination RMS, its split into a slow part
   (the error vector averaged over 1 s: what a better gravity or bias estimate could
   remove) and a fast remainder, the error by rotation rate, the error at the end of the
   rest phases, the bias estimate during the movements against the bias measured offline
   from the rest phases, and bounds from oracles that a causal
   filter cannot have:
   - "2 ms": the output predicted by 2 ms (`latency=0.002`, the delay between BROAD's
     IMU and its optical reference);
   - "oracle bias": the gyro corrected by the mean of its rest phases (the whole
     recording, future included), the filter's own bias estimation off;
   - "oracle gyro cal.": the gyro corrected by a scale/misalignment matrix and bias
     fitted by least squares to the reference's rates (the reference used as a
     calibration rig; not applied when the fit is ill-conditioned, trial 11);
   - "best tuning": the best of a grid of tau_acc x rate_ref x tau_bias chosen per trial
     (what a perfectly adaptive gravity filter and bias gain could reach);
2. with --sensitivity, each default of RobustIMU times 0.5 and 1.5 (RobustAHRS
   for the heading).

Metrics: imufuse.evaluation (the BROAD paper's), RMS over the movement samples with a
finite reference, averaged over trials. A development tool: nothing here is used by the
filter.
"""
import argparse
import glob
import inspect
import math
import os
import sys

import numpy as np

from imufuse import catalogue, evaluation
from imufuse.reference.robust import _Robust
from imufuse.rotations import quat_mul

DEFAULT_DIR = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "broad")
NWU_TO_ENU = np.array([math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])
CONJ = np.array([1.0, -1.0, -1.0, -1.0])
RATE_BINS = (0.0, 100.0, 300.0, 1.0e4)  # deg/s


def load(path):
    files = sorted(glob.glob(os.path.join(path, "*.npz")))
    if not files:
        sys.exit(f"no BROAD trials (*.npz) in {path}")
    return [(os.path.basename(f)[:2], dict(np.load(f))) for f in files]


def run(name, d, **params):
    e = catalogue.entry(name)
    f = catalogue.make_filter(name, "c", "float64",
                              dict(e.defaults, dt=1.0 / float(d["rate"]), **params))
    args = (d["gyr"], d["acc"]) + ((d["mag"],) if e.kind == "ahrs" else ())
    return f.run(*args)


def counted(d):
    return d["movement"] & np.all(np.isfinite(d["quat_ref"]), axis=1)


def tilt_vector(q_nwu, ref):
    """Inclination error as a vector (deg, earth x and y) per sample: e = q r^-1 with the
    heading part (rotation about earth z) taken off."""
    e = quat_mul(quat_mul(NWU_TO_ENU, q_nwu), ref * CONJ)
    e = e * np.where(e[:, :1] < 0, -1.0, 1.0)
    n = np.sqrt(e[:, 0] ** 2 + e[:, 3] ** 2)
    h = np.stack([e[:, 0] / n, 0 * n, 0 * n, -e[:, 3] / n], axis=1)
    t = quat_mul(e, h)
    return np.degrees(2.0 * t[:, 1:3])


def rms(x):
    """RMS of scalars, or of the norms of vectors (rows)."""
    sq = np.sum(x ** 2, axis=1) if x.ndim > 1 else x ** 2
    return math.sqrt(float(np.mean(sq)))


def tilt(d, S):
    ev = evaluation.evaluate(S[:, :4], d["quat_ref"], est_frame="NWU", ref_frame="ENU",
                             movement=d["movement"])
    return ev.inclination, ev.heading


def oracle_bias(d):
    d = dict(d)
    d["gyr"] = d["gyr"] - d["gyr"][~d["movement"]].mean(axis=0)
    return d


def oracle_gyro_cal(d):
    """gyr = (I + M) w_ref + b, fitted on the reference's rates (central differences, the
    gyro one sample later: BROAD's IMU lags its reference); gyr <- (I + M)^-1 (gyr - b)."""
    ref, dt = d["quat_ref"], 1.0 / float(d["rate"])
    dq = quat_mul(ref[:-2] * CONJ, ref[2:])
    dq = dq * np.where(dq[:, :1] < 0, -1.0, 1.0)
    wr = dq[:, 1:] / dt
    g = d["gyr"][2:]
    ok = np.all(np.isfinite(wr), axis=1) & (np.linalg.norm(wr, axis=1) < 15.0)
    X = np.hstack([wr[ok], np.ones((int(ok.sum()), 1))])
    A = np.linalg.lstsq(X, g[ok], rcond=None)[0]
    M = A[:3].T - np.eye(3)
    if np.abs(M).max() > 0.05:  # ill-conditioned (little rotation): no correction
        return d, M
    d = dict(d)
    d["gyr"] = (d["gyr"] - A[3]) @ np.linalg.inv(np.eye(3) + M).T
    return d, M


def slow_fast(d, S):
    """RMS of the 1-s mean of the tilt error vector and of the rest (deg)."""
    ok = counted(d)
    ev = np.nan_to_num(tilt_vector(S[:, :4], d["quat_ref"]))
    n = int(round(float(d["rate"])))
    k = np.ones(n) / n
    lp = np.stack([np.convolve(ev[:, i], k, mode="same") for i in range(2)], axis=1)
    return rms(lp[ok]), rms((ev - lp)[ok])


def at_rest(d, S):
    """RMS tilt error over the last 0.5 s of each rest phase of 1 s or more (deg): what the
    next movement starts from."""
    ev = tilt_vector(S[:, :4], d["quat_ref"])
    rest = ~d["movement"]
    edges = np.flatnonzero(np.diff(np.r_[0, rest.astype(int), 0]))
    n = int(round(0.5 * float(d["rate"])))
    seg = [ev[b - n:b] for a, b in zip(edges[::2], edges[1::2]) if b - a >= 2 * n]
    seg = [s[np.all(np.isfinite(s), axis=1)] for s in seg]
    seg = [s for s in seg if len(s)]
    return rms(np.vstack(seg)) if seg else math.nan


def by_rate(d, S):
    ok = counted(d)
    q = quat_mul(quat_mul(NWU_TO_ENU, S[:, :4]), d["quat_ref"] * CONJ)
    inc = np.degrees(2.0 * np.arccos(np.minimum(np.sqrt(q[:, 0] ** 2 + q[:, 3] ** 2), 1.0)))
    w = np.degrees(np.linalg.norm(d["gyr"], axis=1))
    out = []
    for lo, hi in zip(RATE_BINS[:-1], RATE_BINS[1:]):
        m = ok & (w >= lo) & (w < hi)
        out.append((m.sum() / ok.sum(), rms(inc[m]) if m.any() else math.nan))
    return out


GRID = [dict(tau_acc=ta, rate_ref=rr, tau_bias=tb)
        for ta in (1.5, 2.0, 2.5, 3.5, 5.0) for rr in (0.0, 100.0, 300.0)
        for tb in (20.0, 50.0, 100.0, 200.0) if tb >= 4.0 * ta]


def budget(data):
    cols = ["default", "slow (1 s)", "fast", "<100 deg/s", "100-300", ">300", "at rest",
            "bias error, max in motion (deg/s)", "2 ms", "oracle bias", "oracle gyro cal.",
            "best tuning"]
    rows = {}
    for tid, d in data:
        S = run("RobustIMU", d)
        t0 = tilt(d, S)[0]
        sl, fa = slow_fast(d, S)
        br = by_rate(d, S)
        b_off = d["gyr"][~d["movement"]].mean(axis=0)
        ok = counted(d)
        berr = float(np.degrees(np.linalg.norm(S[ok, 21:24] - b_off, axis=1)).max())
        lat = tilt(d, run("RobustIMU", d, latency=0.002))[0]
        ob = oracle_bias(d)
        tob = tilt(ob, run("RobustIMU", ob, rest_gyr=0.0, tau_bias=0.0))[0]
        oc, _ = oracle_gyro_cal(d)
        toc = tilt(oc, run("RobustIMU", oc))[0]
        best = min(tilt(d, run("RobustIMU", d, **g))[0] for g in GRID)
        rows[tid] = [t0, sl, fa] + [r for _, r in br] + [at_rest(d, S), berr, lat, tob, toc,
                                                          best]
        print(f"trial {tid} done", file=sys.stderr, flush=True)
    print("| quantity | " + " | ".join(rows) + " | mean |")
    print("|---" * (len(rows) + 2) + "|")
    for i, c in enumerate(cols):
        v = [rows[t][i] for t in rows]
        print(f"| {c} | " + " | ".join("%.2f" % x if not math.isnan(x) else "" for x in v)
              + " | %.3f |" % np.nanmean(v))
    share = [[f for f, _ in by_rate(d, run("RobustIMU", d))] for _, d in data]
    print("\nshare of the counted samples per rate bin (<100, 100-300, >300 deg/s): "
          + "; ".join(f"{t} " + "/".join("%.2f" % f for f in s)
                      for (t, _), s in zip(data, share)))


SENS = ["tau_acc", "rate_ref", "tau_bias", "tau_bias_rest", "rest_gyr", "rest_acc",
        "rest_time", "tau_rest"]


def sensitivity(data):
    def mean_scores(**kw):
        t6 = np.mean([tilt(d, run("RobustIMU", d, **kw))[0] for _, d in data])
        th = [tilt(d, run("RobustAHRS", d, **kw)) for _, d in data]
        return t6, np.mean([a for a, _ in th]), np.mean([b for _, b in th])
    sig = inspect.signature(_Robust._imu_params).parameters
    dflt = {k: v.default for k, v in sig.items()}
    t6, t9, h9 = mean_scores()
    print("| parameter (default) | x0.5: 6D tilt / 9D tilt / heading | "
          "x1.5: 6D tilt / 9D tilt / heading |\n|---|---|---|")
    print(f"| all defaults | {t6:.3f} / {t9:.3f} / {h9:.3f} | |")
    for p in SENS:
        cells = []
        for f in (0.5, 1.5):
            kw = {p: dflt[p] * f}
            if p == "tau_acc" and dflt["tau_bias"] < 4.0 * kw[p]:
                kw["tau_bias"] = 4.0 * kw[p]  # the constructor's Eq. 3.12 bound
            cells.append("%.3f / %.3f / %.3f" % mean_scores(**kw))
        print(f"| `{p}` ({dflt[p]:g}) | " + " | ".join(cells) + " |")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dir", default=os.environ.get("IMUFUSE_BROAD", DEFAULT_DIR))
    p.add_argument("--sensitivity", action="store_true")
    a = p.parse_args(argv)
    data = load(a.dir)
    if a.sensitivity:
        sensitivity(data)
    else:
        budget(data)


if __name__ == "__main__":
    main()
