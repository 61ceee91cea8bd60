"""`imufuse tune`: the best parameter it reports is the best of a dense scan
computed independently (imufuse_c + imufuse.evaluation called directly), on
the shipped BROAD excerpt and on the BROAD development trials when present."""
import glob
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import imufuse
import imufuse_c
from imufuse import io
from imufuse.evaluation import evaluate
from broad_data import BROAD, SKIP_REASON

PATHS = [os.path.dirname(os.path.dirname(imufuse.__file__)),
         os.path.dirname(os.path.dirname(imufuse_c.__file__))]



def imf(*args, timeout=600):
    e = dict(os.environ)
    e["PYTHONPATH"] = os.pathsep.join(PATHS + [e.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-m", "imufuse", *map(str, args)], env=e,
                          capture_output=True, text=True, timeout=timeout)


def objective(paths, beta):
    """Mean over the logs of the inclination RMS of MadgwickIMU(beta), started
    from the first sample, as the BROAD paper scores it."""
    out = []
    for p in paths:
        z = np.load(p)
        f = imufuse_c.MadgwickIMU(dt=1.0 / float(z["rate"]), beta=beta, init="first")
        q = f.run(z["gyr"], z["acc"] / io.GRAVITY)
        out.append(evaluate(q, z["quat_ref"], est_frame="NWU", ref_frame="ENU",
                            movement=z["movement"]).inclination)
    return float(np.mean(out))


def best_of(stdout):
    m = re.search(r"best: beta=([0-9.e+-]+) \(inclination ([0-9.]+) deg\)", stdout)
    assert m, stdout
    return float(m.group(1)), float(m.group(2))


def check(paths, extra=()):
    r = imf("tune", *paths, "-f", "MadgwickIMU", "--grid", "beta=0.005:1:12", "--quiet", *extra)
    assert r.returncode == 0, r.stderr
    beta, score = best_of(r.stdout)
    assert score == pytest.approx(objective(paths, beta), abs=6e-4)
    # an independent dense scan finds nothing clearly better
    scan = np.geomspace(0.005, 1, 30)
    vals = [objective(paths, b) for b in scan]
    assert score <= min(vals) + 0.01, (beta, score, scan[int(np.argmin(vals))], min(vals))
    return r


def test_tune_finds_the_best_beta_on_the_excerpt():
    r = check([io.example_log()])
    # the table lists the evaluated sets; threads give the same answer
    one = imf("tune", io.example_log(), "-f", "MadgwickIMU", "--grid", "beta=0.005:1:12",
              "--quiet", "-j", "1")
    assert best_of(one.stdout) == best_of(r.stdout)


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_tune_finds_the_best_beta_on_the_broad_development_trials():
    paths = sorted(glob.glob(os.path.join(BROAD, "*.npz")))
    assert len(paths) == 7
    check(paths)


def test_tune_errors(tmp_path):
    from imufuse import sim
    d = sim.imu("static", rate=100.0, duration=1.0, seed=1)
    p = tmp_path / "noref.csv"
    io.write_log(p, d.t, d.gyr, d.acc)
    r = imf("tune", p, "-f", "MadgwickIMU")
    assert r.returncode == 4 and "no reference orientation" in r.stderr
    r = imf("tune", io.example_log(), "-f", "MadgwickIMU", "--metric", "heading")
    assert r.returncode == 2 and "inclination" in r.stderr


def test_tune_fusion13_scores_its_gain_as_an_independent_run():
    """x-io Fusion 1.3 (FusionAHRS13) is tuned like the others: each gain's total error is
    the one of the class run directly (Fusion's units, the log's rate and intervals, the
    BROAD errors), and the best is the best of the grid."""
    path = io.example_log()
    r = imf("tune", path, "-f", "FusionAHRS13", "--grid", "gain=0.1,0.5,2", "--refine", "0",
            "--quiet")
    assert r.returncode == 0, r.stderr
    rows = {float(ln.split()[0]): float(ln.split()[1]) for ln in r.stdout.splitlines()
            if re.match(r"\s*[0-9.]+\s+[0-9.]+", ln)}
    log = io.read_log(path)
    want = {}
    for gain in (0.1, 0.5, 2.0):
        f = imufuse_c.FusionAHRS13(sample_rate=1.0 / log.dt, gain=gain)
        dts = log.dts if log.dts is not None else log.dt
        S = f.run(np.degrees(log.gyr), log.acc, log.mag, dt=dts)
        q = S[:, :4] / np.linalg.norm(S[:, :4], axis=1, keepdims=True)
        want[gain] = evaluate(q, log.q_ref, est_frame="NWU", ref_frame="ENU",
                              movement=log.movement).total
    assert set(rows) == set(want)
    for g, s in rows.items():
        assert s == pytest.approx(want[g], abs=6e-4), (g, s, want[g])
    assert min(rows, key=rows.get) == min(want, key=want.get)
