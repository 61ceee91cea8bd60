"""RobustAHRS on an uncalibrated magnetometer: the seven BROAD development trials with a
known distortion applied to the magnetometer, m' = S m + o (S symmetric: scale errors of
+-10 %, a few degrees of skew; o tens of uT), against the undistorted recording. Heading
and tilt RMSE (BROAD metrics) over the movement samples after the learning phase (the
first ``--learn`` s of movement), each trial, and the means.

    python research/soft_iron_study.py [--dir ../shared/data/broad] [--learn 60]
                                       [-p NAME=VALUE ...] [--backend c|reference]
"""
import argparse

import numpy as np

from imufuse import catalogue, evaluation
from broad_compare import DEFAULT_DIR, trials

#: the distortions (S, o): S symmetric near the identity, o in uT
DISTORTIONS = {
    "A": (np.array([[1.10, 0.04, -0.03], [0.04, 0.90, 0.05], [-0.03, 0.05, 1.02]]),
          np.array([25.0, -40.0, 10.0])),
    "B": (np.array([[0.92, -0.05, 0.02], [-0.05, 1.08, -0.04], [0.02, -0.04, 0.95]]),
          np.array([-30.0, 15.0, -35.0])),
    "O": (np.eye(3), np.array([25.0, -40.0, 10.0])),    # hard iron only
    "P": (np.eye(3), np.array([-12.0, 8.0, -15.0])),
}


def distort(mag, which):
    if which is None:
        return mag
    S, o = DISTORTIONS[which]
    return mag @ S.T + o


def run(d, params, which, backend="c"):
    e = catalogue.entry("RobustAHRS")
    dt = 1.0 / float(d["rate"])
    f = catalogue.make_filter("RobustAHRS", backend, "float64", dict(e.defaults, dt=dt, **params))
    q = catalogue.estimate(f, f.run(d["gyr"], d["acc"], distort(d["mag"], which),
                                    outputs="q")).q
    return q, f


def score(d, q, learn):
    rate = float(d["rate"])
    mv = np.asarray(d["movement"], bool).copy()
    k0 = int(np.argmax(mv))
    mv[:k0 + int(learn * rate)] = False
    e = evaluation.evaluate(q, d["quat_ref"], est_frame="NWU", ref_frame="ENU", movement=mv,
                            per_sample=False)
    return e.inclination, e.heading


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=DEFAULT_DIR)
    ap.add_argument("--learn", type=float, default=60.0)
    ap.add_argument("--backend", default="c")
    ap.add_argument("-p", action="append", default=[], help="RobustAHRS NAME=VALUE")
    a = ap.parse_args(argv)
    params = {k: (float(v) if v not in ("True", "False") else v == "True")
              for k, v in (s.split("=", 1) for s in a.p)}
    data = trials(a.dir)
    rows = {w: [] for w in (None, *DISTORTIONS)}
    for name, d in data:
        line = [name[:6]]
        for w in rows:
            q, f = run(d, params, w, a.backend)
            t, h = score(d, q, a.learn)
            rows[w].append((t, h))
            extra = ""
            if hasattr(f, "get_mag_soft"):
                extra = f" sd {f.get_mag_soft()[1]:.4f}"
            line.append(f"{w or '-'}: {t:.3f}/{h:.2f}{extra}")
        print("  ".join(line), flush=True)
    for w, r in rows.items():
        r = np.asarray(r)
        print(f"{w or 'undistorted'}: mean tilt {r[:, 0].mean():.3f} heading {r[:, 1].mean():.3f}"
              f" (worst heading {r[:, 1].max():.2f})")


if __name__ == "__main__":
    main()
