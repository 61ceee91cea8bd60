"""RobustAHRS on an uncalibrated magnetometer: the seven BROAD development trials with a
known distortion applied to the magnetometer, m' = S m + o (S symmetric: scale errors of
+-10 %, a few degrees of skew; o tens of uT), against the undistorted recording. Heading
and tilt RMSE (BROAD metrics) over the movement samples after the learning phase (the
first ``--learn`` s of movement), each trial, and the means.

    python research/soft_iron_study.py [--dir ../shared/data/broad] [--learn 60]
                                       [-p NAME=VALUE ...] [--backend c|reference]
    python research/soft_iron_study.py --oracle     # what the recordings pin the offset to
    python research/soft_iron_study.py --backend soft   # B6 with soft iron: soft_iron_kf.py

--oracle: per trial, the offset of the least-squares sphere through every reading of the
undistorted recording (an offline oracle: the whole trial, no attitude, no model of B6's),
the heading with that offset stored and B6 off against BROAD's own calibration (stored 0),
and B6's final estimate with its claimed standard deviation. Any learnt offset is scored
against a calibration the recording itself does not reproduce to better than about 1 uT.
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
    if backend == "soft":   # the prototype of B6 with soft iron (research/soft_iron_kf.py)
        from soft_iron_kf import SoftRobustAHRS
        f = SoftRobustAHRS(dt, **params)
    else:
        f = catalogue.make_filter("RobustAHRS", backend, "float64",
                                  dict(e.defaults, dt=dt, **params))
    kind = f if backend != "soft" else catalogue.entry("RobustAHRS").reference
    q = catalogue.estimate(kind, f.run(d["gyr"], d["acc"], distort(d["mag"], which),
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


def sphere(mag):
    """The least-squares sphere |m - o| = r through the readings: (o, r)."""
    m = np.asarray(mag, float)
    x = np.linalg.lstsq(np.c_[2.0 * m, np.ones(len(m))], (m * m).sum(1), rcond=None)[0]
    return x[:3], float(np.sqrt(x[3] + x[:3] @ x[:3]))


def oracle(data, learn):
    print("trial  sphere |o| uT (r)   heading: stored 0 / stored sphere   B6: |estimate| uT (sd)")
    for name, d in data:
        o, r = sphere(d["mag"])
        dt = 1.0 / float(d["rate"])
        heads = []
        for stored in ((0.0, 0.0, 0.0), tuple(o)):
            f = catalogue.make_filter("RobustAHRS", "c", "float64", dict(dt=dt, mag_learn=False))
            f.set_mag_offset(stored)
            q = catalogue.estimate(f, f.run(d["gyr"], d["acc"], d["mag"], outputs="q")).q
            heads.append(score(d, q, learn)[1])
        f = catalogue.make_filter("RobustAHRS", "c", "float64", dict(dt=dt))
        f.run(d["gyr"], d["acc"], d["mag"], outputs="q")
        est, sd = f.get_mag_offset()
        # the estimate, used or not: the state's ix, iy, iz in units of m_n0
        S = f.state
        names = f.state_names
        n0 = S[names.index("m_n0")]
        e = np.array([S[names.index(k)] for k in ("ix", "iy", "iz")]) * n0
        print(f"{name:5s}  {np.linalg.norm(o):6.2f} ({r:4.1f})        {heads[0]:5.2f} / {heads[1]:5.2f}"
              f"                  {np.linalg.norm(e):5.2f} ({sd * n0:.2f})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=DEFAULT_DIR)
    ap.add_argument("--learn", type=float, default=60.0)
    ap.add_argument("--backend", default="c", help="c, reference or soft (the prototype)")
    ap.add_argument("-p", action="append", default=[], help="RobustAHRS NAME=VALUE")
    ap.add_argument("--oracle", action="store_true",
                    help="the offset the recordings themselves pin (see the docstring)")
    a = ap.parse_args(argv)
    if a.oracle:
        return oracle(trials(a.dir), a.learn)
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
