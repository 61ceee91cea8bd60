"""Oracle: how much of RobustIMU's tilt error on the BROAD development trials is the
accelerometer's own bias (and scale) error?

    python research/acc_bias_oracle.py [--dir ../shared/data/broad]      (about 30 s)

Per trial a constant accelerometer correction is fitted offline against the optical
reference (sensor -> ENU, taken 2 ms earlier: BROAD's IMU lags it), subtracted from the
accelerometer, and RobustIMU (C, float64, catalogue defaults) is run again. Rows:

- "rest": the bias that makes the accelerometer agree with the reference's gravity in the
  rest phases, b = mean(a - g R^T e_z), g = 9.8128 m/s^2 (Berlin); the rest phases of
  BROAD are all z-up, so b_z is the rest norm's excess over g;
- "rest + closure": a multi-position calibration that also uses the movements: over each
  movement phase (rest to rest, so the velocity is 0 at both ends) the specific force in
  the earth frame integrates to g T, sum(R a) - g e_z T = sum(R) b, and in each rest phase
  mean(R a) - g e_z = mean(R) b; least squares in b and |g|.  (Three scale factors as
  well are not identifiable from these recordings: condition numbers 100-40000, fitted
  scales of 1-300 %.);
- "best b_xy", "best b": the constant correction (b_z from the rest norm and b_x, b_y
  free; or all three) that minimises the filter's own tilt RMSE (Nelder-Mead): not a
  physical estimate but an upper bound of what any constant sensor-frame offset gives;
- "offset removed": the RMS of the tilt error vector about its mean over the movement
  (each trial's constant earth-frame offset removed), which "best b" approaches;
and, to check the biases against the rest residual: the mean tilt error vector of the
filter in the rest phases and in the movement (earth x, y, deg), and the fitted biases (mg).

A development tool: nothing here is used by the filter.
"""
import argparse
import math
import os
import sys

import numpy as np

from robust_budget import DEFAULT_DIR, at_rest, load, run, tilt, tilt_vector  # beside this script

from imufuse.rotations import quat_to_matrix

G_BERLIN = 9.8128  # m/s^2
ENU_UP = np.array([0.0, 0.0, 1.0])


def corrected(d, f):
    d = dict(d)
    d["acc"] = (d["acc"] - f["b"]) / (1.0 + f["s"])
    return d


def best_offset(d, scale=False):
    """Upper bound: the constant accelerometer correction (bias, optionally scale factors)
    that minimises the filter's own tilt RMSE against the reference (Nelder-Mead from 0).
    It absorbs whatever a constant sensor-frame offset can explain (reference misalignment
    included), so it bounds any accelerometer-bias estimator from above."""
    from scipy.optimize import minimize

    def f(x):
        dd = dict(d)
        s = x[3:6] * 1e-2 if scale else 0.0
        dd["acc"] = (d["acc"] - x[:3]) / (1.0 + s)
        return tilt(dd, run("RobustIMU", dd))[0]
    x0 = np.zeros(6 if scale else 3)
    simplex = np.vstack([x0] + [x0 + 0.05 * e for e in np.eye(len(x0))])  # 0.05 m/s^2, %
    r = minimize(f, x0, method="Nelder-Mead",
                 options=dict(initial_simplex=simplex, xatol=1e-3, fatol=1e-4, maxfev=400))
    return r.x, r.fun


def ref_lagged(d, lag_s):
    """The reference at t - lag_s (nlerp between neighbouring samples)."""
    q = d["quat_ref"]
    x = lag_s * float(d["rate"])
    k, f = int(math.floor(x)), x - math.floor(x)
    sh = lambda n: np.vstack([np.full((n, 4), np.nan), q[:len(q) - n]]) if n else q  # noqa: E731
    a, b = sh(k), sh(k + 1)
    b = b * np.where(np.sum(a * b, axis=1, keepdims=True) < 0, -1.0, 1.0)
    r = (1.0 - f) * a + f * b
    return r / np.linalg.norm(r, axis=1, keepdims=True)


def fit_closure(d, lag_s=0.002, rest_weight=1.0, scale=False):
    """Multi-position calibration with velocity closure: over each movement phase (rest to
    rest, velocity 0 at both ends) the specific force in the earth frame integrates to g T:
        sum_seg (R a) - g e_z T = (sum_seg R) b;
    and in each rest phase  mean(R a) - g e_z = mean(R) b.  Unknowns b (3) and |g|; with
    `scale`, three scale factors s (a = (1 + s) f + b, to first order: + mean(R diag(a)) s;
    |g| is then fixed at Berlin's, a common scale being |g|)."""
    q = ref_lagged(d, lag_s)
    ok = np.all(np.isfinite(q), axis=1)
    R = np.full((len(q), 3, 3), np.nan)
    R[ok] = quat_to_matrix(q[ok])
    a = d["acc"]
    mv = d["movement"]
    rows, rhs = [], []
    e = np.flatnonzero(np.diff(np.r_[0, mv.astype(int), 0]))
    for s0, s1 in zip(e[::2], e[1::2]):  # movement phases; pad 0.5 s into the rests
        pad = int(0.5 * float(d["rate"]))
        sl = slice(max(s0 - pad, 0), min(s1 + pad, len(q)))
        okk = ok[sl]
        if okk.mean() < 0.99:
            continue
        Rw, aw = R[sl][okk], a[sl][okk]
        n = len(Rw)
        y = np.einsum("nij,nj->i", Rw, aw) / n  # m/s^2: the mean over the phase
        A = np.hstack([Rw.mean(axis=0), np.array([[0.0], [0.0], [1.0]])])
        if scale:
            A = np.hstack([A[:, :3], (Rw * aw[:, None, :]).mean(axis=0)])
            y = y - np.array([0.0, 0.0, G_BERLIN])
        rows.append(A)
        rhs.append(y)
    e = np.flatnonzero(np.diff(np.r_[0, (~mv).astype(int), 0]))
    for s0, s1 in zip(e[::2], e[1::2]):
        okk = ok[s0:s1]
        if okk.sum() < 100:
            continue
        Rw, aw = R[s0:s1][okk], a[s0:s1][okk]
        y = np.einsum("nij,nj->i", Rw, aw) / len(Rw)
        A = np.hstack([Rw.mean(axis=0), np.array([[0.0], [0.0], [1.0]])])
        if scale:
            A = np.hstack([A[:, :3], (Rw * aw[:, None, :]).mean(axis=0)])
            y = y - np.array([0.0, 0.0, G_BERLIN])
        rows.append(rest_weight * A)
        rhs.append(rest_weight * y)
    A, y = np.vstack(rows), np.concatenate(rhs)
    x, *_ = np.linalg.lstsq(A, y, rcond=None)
    if scale:
        return dict(b=x[:3], s=x[3:6], g=G_BERLIN, res=y - A @ x, cond=np.linalg.cond(A))
    return dict(b=x[:3], s=np.zeros(3), g=x[3], res=y - A @ x, cond=np.linalg.cond(A))


def rest_bias(d, lag_s=0.002):
    q = ref_lagged(d, lag_s)
    m = ~d["movement"] & np.all(np.isfinite(q), axis=1)
    R = quat_to_matrix(q[m])
    return (d["acc"][m] - G_BERLIN * R[:, 2, :]).mean(axis=0)


def score(d, b, s=0.0):
    dd = corrected(d, dict(b=np.asarray(b, dtype=float), s=s))
    return tilt(dd, run("RobustIMU", dd))[0]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dir", default=os.environ.get("IMUFUSE_BROAD", DEFAULT_DIR))
    a = p.parse_args(argv)
    from scipy.optimize import minimize
    data = load(a.dir)
    rows = {k: [] for k in ("defaults", "b_z from the rest norm", "rest", "rest + closure",
                            "best b_xy (b_z from the rest norm)", "best b (3 axes)",
                            "offset removed", "at rest, defaults",
                            "at rest, rest bias subtracted")}
    info = []
    for tid, d in data:
        S = run("RobustIMU", d)
        rows["defaults"].append(tilt(d, S)[0])
        br = rest_bias(d)
        bz = np.array([0.0, 0.0, br[2]])
        rows["b_z from the rest norm"].append(score(d, bz))
        rows["rest"].append(score(d, br))
        rows["at rest, defaults"].append(at_rest(d, S))
        dr = corrected(d, dict(b=br, s=0.0))
        rows["at rest, rest bias subtracted"].append(at_rest(dr, run("RobustIMU", dr)))
        bc = fit_closure(d)["b"]
        rows["rest + closure"].append(score(d, bc))
        sim = np.array([[0.0, 0.0], [0.05, 0.0], [0.0, 0.05]])
        r2 = minimize(lambda x: score(d, [x[0], x[1], br[2]]), [0.0, 0.0], method="Nelder-Mead",
                      options=dict(initial_simplex=sim, xatol=1e-3, fatol=1e-4))
        rows["best b_xy (b_z from the rest norm)"].append(r2.fun)
        b3, f3 = best_offset(d)
        rows["best b (3 axes)"].append(f3)
        ev = tilt_vector(S[:, :4], d["quat_ref"])
        ok = np.all(np.isfinite(ev), axis=1)
        mv, rs = d["movement"] & ok, ~d["movement"] & ok
        mean_mv, mean_rs = ev[mv].mean(axis=0), ev[rs].mean(axis=0)
        rows["offset removed"].append(math.sqrt(float(np.mean(np.sum((ev[mv] - mean_mv) ** 2,
                                                                      axis=1)))))
        # the rest phases' biases one by one: a constant bias is the same in each
        q = ref_lagged(d, 0.002)
        e = np.flatnonzero(np.diff(np.r_[0, (~d["movement"]).astype(int), 0]))
        per = []
        for s0, s1 in zip(e[::2], e[1::2]):
            okk = np.all(np.isfinite(q[s0:s1]), axis=1)
            if okk.sum() >= 100:
                R = quat_to_matrix(q[s0:s1][okk])
                per.append((d["acc"][s0:s1][okk] - G_BERLIN * R[:, 2, :]).mean(axis=0)[:2])
        per = np.array(per) / 9.81e-3
        info.append((tid, br / 9.81e-3, per, bc / 9.81e-3, np.r_[r2.x, br[2]] / 9.81e-3,
                     b3 / 9.81e-3, mean_rs, mean_mv))
        print(f"trial {tid} done", file=sys.stderr, flush=True)
    tids = [t for t, _ in data]
    print("| accelerometer correction | " + " | ".join(tids) + " | mean |")
    print("|---" * (len(tids) + 2) + "|")
    for k, v in rows.items():
        print(f"| {k} | " + " | ".join("%.3f" % x for x in v) + " | %.3f |" % np.mean(v))
    print("\nfitted biases (mg; x y z) and the filter's mean tilt error vector (deg, earth x y)")
    for tid, br, per, bc, b2, b3, mr, mm in info:
        f = lambda v, fmt="%+.1f": "(" + " ".join(fmt % x for x in v) + ")"  # noqa: E731
        print(f"{tid}: rest {f(br)}, per rest phase (x y) " + " ".join(f(p) for p in per)
              + f"; rest + closure {f(bc)}; best b_xy {f(b2)}; best b {f(b3)}; "
              f"tilt error mean at rest {f(mr, '%+.2f')}, in motion {f(mm, '%+.2f')}")


if __name__ == "__main__":
    main()
