"""`imufuse tune`: the best parameter it reports is the best of a dense scan
computed independently (imufuse_c + imufuse.evaluation called directly), on
the shipped BROAD excerpt and on the BROAD development trials when present;
grid mistakes are named, and the sets a filter refuses are said."""
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
from cli_here import imf_here

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


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """2 s of simulated motion at 100 Hz with its true orientation as the reference."""
    from imufuse import sim
    d = sim.imu("slow", rate=100.0, duration=2.0, seed=3)
    p = tmp_path_factory.mktemp("tune") / "good.csv"
    io.write_log(p, d.t, d.gyr, d.acc, d.mag, d.q_true)
    return p


@pytest.mark.parametrize("grid,word", [
    ("beta=0.01:1:0", "N, the number of values, must be 1 to 10000, got 0"),
    ("beta=0.01:1:20000", "N, the number of values, must be 1 to 10000, got 20000"),
    ("beta=nan:1:3", "of finite numbers"),
    ("beta=nan,0.1", "of finite numbers"),
    ("beta=0.1,inf", "of finite numbers"),
])
def test_tune_grid_mistakes_are_named(good, grid, word):
    """A grid of the right form with a count out of range was refused as if its form were
    wrong ("expected NAME=LO:HI:N[lin]"); NaN and Inf in a list of values were taken, their
    sets refused without a word, and NaN threw the refinement's neighbours off."""
    r = imf_here("tune", good, "-f", "MadgwickIMU", "-q", "--grid", grid)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and word in r.stderr, r.stderr


def test_tune_says_which_sets_it_refused(good):
    """beta=50 at 100 Hz is beyond MadgwickIMU's stable range: its set was left out of the
    table (and of --all) without a word, the heading counting it among the sets."""
    r = imf_here("tune", good, "-f", "MadgwickIMU", "-q", "--all", "--grid",
                 "beta=0.001,0.01,50")
    assert r.returncode == 0, r.stderr
    assert re.search(r"note: 1 of \d+ parameter sets refused by MadgwickIMU, not in the table "
                     r"\(e.g. beta=50: MadgwickIMU: beta: outside the stable range", r.stderr), \
        r.stderr
    rows = [float(ln.split()[0]) for ln in r.stdout.splitlines()
            if re.match(r"\s*[0-9.e+-]+\s+[0-9.]+\s", ln)]
    n = int(re.search(r"(\d+) parameter sets, best first", r.stdout).group(1))
    assert len(rows) == n - 1 and 50.0 not in rows, r.stdout


def test_tune_says_why_nothing_scored(tmp_path):
    """A reference of NaN only: every set scores NaN over 0 samples, and tune said only "no
    parameter set could be evaluated (9 tried)"; it names the reference, as compare does."""
    from imufuse import sim
    d = sim.imu("slow", rate=100.0, duration=2.0, seed=3)
    p = tmp_path / "nanref.csv"
    io.write_log(p, d.t, d.gyr, d.acc, d.mag, np.full_like(d.q_true, np.nan))
    r = imf_here("tune", p, "-f", "MadgwickIMU", "-q")
    assert r.returncode == 4 and r.stderr.strip() == (
        "imufuse: error: tune: no parameter set could be evaluated (9 tried): no sample has a "
        "finite reference inside the movement mask"), r.stderr


def test_tune_takes_folders_and_patterns_as_compare(good):
    """tune (and latency) name their logs as compare does: a folder of logs and a quoted
    glob pattern are its files (they were refused: "is a directory", "no such file")."""
    args = ("-f", "MadgwickIMU", "-q", "--grid", "beta=0.05,0.2")
    want = imf_here("tune", good, *args)
    assert want.returncode == 0, want.stderr
    for spec in (good.parent, good.parent / "*.csv"):
        r = imf_here("tune", spec, *args)
        assert (r.returncode, r.stdout) == (0, want.stdout), r.stderr
    r = imf_here("tune", good.parent / "none*.csv", *args)
    assert r.returncode == 3 and "no file matches" in r.stderr, r.stderr


def test_a_grid_too_large_is_refused_before_it_is_built(good):
    """RobustAHRS's default grid was every one of its 18 gains at 9 points: 1.5e17 sets,
    built as a list before the first ran (23 GB, then the kernel's OOM killer). A grid of
    more than MAX_SETS sets, or a refinement round of more, is a usage error naming its
    size, before any set runs."""
    from imufuse.tune import MAX_SETS, Tuner
    t = Tuner([str(good)], "RobustAHRS")
    names = ["tau_acc", "rate_ref", "tau_bias", "rest_acc", "tau_mag", "mag_noise", "mag_lag",
             "tau_rest"]
    with pytest.raises(ValueError, match=r"tune: 1\.68e\+07 parameter sets in the grid "
                       r"\(8 tau_acc x 8 rate_ref .* at most 100000"):
        t.search([(k, list(np.geomspace(0.5, 2.0, 8))) for k in names])
    # 4 values each are 65 536 sets, but each refinement round would be 5^8 = 390 625
    with pytest.raises(ValueError, match=r"3\.91e\+05 in each refinement round; .*, or "
                       r"--refine 0 \[Python: --grid GRID is Tuner\.search\(grid=GRID\); "
                       r"--refine 0 is Tuner\.search\(refine=0\)\]$"):
        t.search([(k, list(np.geomspace(0.5, 2.0, 4))) for k in names])
    assert MAX_SETS == 100_000


def test_the_default_grid_of_many_gains_varies_the_three_that_matter(good):
    """Without --grid, of RobustAHRS's gains the three whose /10 and x10 (one at a time) move
    the score most; a note names them and the ones left at their values. The three are the
    largest one-at-a-time score changes, computed here independently with Session."""
    from imufuse.session import Session
    from imufuse.tune import Tuner
    r = imf_here("tune", good, "-f", "RobustIMU", "--refine", "0", "--points", "3")
    assert r.returncode == 0, r.stderr
    m = re.search(r"note: the default grid varies the 3 parameters of RobustIMU whose /10 and "
                  r"x10 move the inclination most on the first log \(([a-z_, ]+)\); ([a-z_, ]+) "
                  r"keep their values: give --grid to choose", r.stderr)
    assert m, r.stderr
    kept, left = m.group(1).split(", "), m.group(2).split(", ")
    header = next(ln for ln in r.stdout.splitlines() if "inclination" in ln and "good" in ln)
    assert header.split()[:3] == kept
    # 3 values of 3 parameters: 27 sets, refined 0 times
    assert "27 parameter sets" in r.stdout, r.stdout
    s = Session(str(good))
    defaults = Tuner([s], "RobustIMU")._effective()

    def score(**kw):
        return s.score(s.run("RobustIMU", kw)).inclination

    base = score()
    moved = {k: max(abs(score(**{k: defaults[k] * f}) - base) for f in (0.1, 10.0))
             for k in kept + left}
    assert min(moved[k] for k in kept) >= max(moved[k] for k in left), moved


def test_a_best_value_at_the_end_of_its_grid_is_noted(good):
    """A best value at the lowest or highest value of its grid was printed as the best with
    no word, though the best may lie beyond: a note says so, and only then."""
    for grid in ("beta=0.3,1,3", "beta=0.0001:10:9"):
        r = imf_here("tune", good, "-f", "MadgwickIMU", "-q", "--grid", grid)
        assert r.returncode == 0, r.stderr
        beta = float(re.search(r"best: beta=([0-9.e+-]+)", r.stdout).group(1))
        lo, hi = (0.3, 3.0) if "," in grid else (0.0001, 10.0)
        edge = beta in (lo, hi)
        side = "lowest" if beta == lo else "highest"
        note = (f"note: the best beta={beta:.4g} is the {side} value of its grid: the best may "
                f"lie {'below' if side == 'lowest' else 'above'} it; extend --grid beta")
        assert (note in r.stderr) == edge and ("note" in r.stderr) == edge, (grid, r.stdout,
                                                                             r.stderr)
        assert edge == ("," in grid), (grid, r.stdout)     # one of each, as measured


def test_the_default_grid_reads_only_the_first_log(good, tmp_path):
    """Choosing the default grid's gains scores them on the first log only, as idle() does:
    with an executor the other logs are read where it runs (a path the driver cannot open
    is no error until then)."""
    from imufuse.tune import Tuner
    t = Tuner([str(good), str(tmp_path / "read-where-the-executor-runs.csv")], "RobustIMU")
    grid = t.default_grid(3)
    assert len(grid) == 3 and t.left_out and 0 in t._sessions and 1 not in t._sessions
