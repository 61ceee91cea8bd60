"""Plausibility instead of silence: the usual mistakes (deg/s read as rad/s, m/s^2 read as g,
time in ms, a --rate that contradicts the time column) give a one-line note naming the option
that fixes them, and none fires on logs read correctly: the shipped example, the seven BROAD
development trials, x-io's layout with its units."""
import glob
import math
import os
import re

import numpy as np
import pytest

from broad_data import BROAD, SKIP_REASON
from imufuse import sim
from imufuse.io import example_log, read_log
from imufuse.plausible import gyro_scale
from cli_here import imf_here

XIO = ["Time (s)", "Gyroscope X (deg/s)", "Gyroscope Y (deg/s)", "Gyroscope Z (deg/s)",
       "Accelerometer X (g)", "Accelerometer Y (g)", "Accelerometer Z (g)"]


def _csv(path, header, rows):
    with open(path, "w") as f:
        f.write(",".join(header) + "\n")
        for r in rows:
            f.write(",".join(repr(float(v)) for v in r) + "\n")
    return path


@pytest.fixture(scope="module")
def motion():
    # a lively motion: rates beyond 35 deg/s (so that deg/s read as rad/s shows)
    return sim.imu("fast", rate=200.0, duration=10.0, seed=3)


def test_silent_on_the_shipped_example():
    assert read_log(example_log()).warnings == []


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_silent_on_the_broad_trials():
    files = sorted(glob.glob(os.path.join(BROAD, "*.npz")))
    assert len(files) == 7
    for f in files:
        assert read_log(f).warnings == [], f


def test_silent_on_xio_layout(tmp_path, motion):
    t = np.arange(len(motion.gyr)) * motion.dt
    rows = np.column_stack([t, np.degrees(motion.gyr), motion.acc])
    assert read_log(_csv(tmp_path / "x.csv", XIO, rows)).warnings == []


def test_deg_per_s_without_a_unit(tmp_path, motion):
    t = np.arange(len(motion.gyr)) * motion.dt
    rows = np.column_stack([t, np.degrees(motion.gyr), motion.acc])
    log = read_log(_csv(tmp_path / "d.csv", ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y",
                                             "acc_z"], rows))
    assert any("--gyr-unit deg/s" in w for w in log.warnings), log.warnings


def test_m_per_s2_read_as_g(tmp_path, motion):
    t = np.arange(len(motion.gyr)) * motion.dt
    rows = np.column_stack([t, motion.gyr, motion.acc * 9.80665])
    log = read_log(_csv(tmp_path / "a.csv", ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y",
                                             "acc_z"], rows))
    assert any("--acc-unit m/s2" in w for w in log.warnings), log.warnings
    # and g read as m/s^2
    rows = np.column_stack([t, motion.gyr, motion.acc])
    log = read_log(_csv(tmp_path / "b.csv", ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y",
                                             "acc_z"], rows), acc_unit="m/s2")
    assert any("--acc-unit g" in w for w in log.warnings), log.warnings


@pytest.mark.parametrize("counts_per_g,unit", [(16384, None), (2048, None), (4096, "m/s2")])
def test_accelerometer_counts_are_named(tmp_path, motion, counts_per_g, unit):
    """Raw counts (16384 per g at +-2 g, 2048 at +-16 g; read as g or as m/s^2) were taken
    without a word, though MultiWii's window and the acceleration gates never use them."""
    t = np.arange(len(motion.gyr)) * motion.dt
    rows = np.column_stack([t, motion.gyr, motion.acc * counts_per_g])
    log = read_log(_csv(tmp_path / "c.csv", ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y",
                                             "acc_z"], rows), acc_unit=unit)
    notes = [w for w in log.warnings if "raw sensor counts?" in w]
    assert len(notes) == 1 and "scale them to g or m/s^2" in notes[0], log.warnings
    # +-16 g of real motion (median far below) stays silent: the test is on the median
    rows = np.column_stack([t, motion.gyr, np.clip(motion.acc * 8.0, -16, 16)])
    log = read_log(_csv(tmp_path / "m.csv", ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y",
                                             "acc_z"], rows))
    assert not any("raw sensor counts?" in w for w in log.warnings), log.warnings


@pytest.mark.parametrize("counts_per_dps", [131.0, 65.5])
def test_gyroscope_counts_are_named(tmp_path, motion, counts_per_dps):
    """Raw gyro counts (131 per deg/s at +-250 deg/s, 65.5 at +-500) with --gyr-unit deg/s
    given: the note said "read as rad/s (given): these look like deg/s; give --gyr-unit
    deg/s", the option the user had given."""
    t = np.arange(len(motion.gyr)) * motion.dt
    rows = np.column_stack([t, np.degrees(motion.gyr) * counts_per_dps, motion.acc])
    log = read_log(_csv(tmp_path / "c.csv", ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y",
                                             "acc_z"], rows), gyr_unit="deg/s")
    notes = [w for w in log.warnings if "gyroscope passes" in w]
    assert len(notes) == 1 and "after converting from deg/s (given): raw sensor counts? scale " \
        "them to deg/s or rad/s first" in notes[0] and "--gyr-unit" not in notes[0], notes


def test_a_real_gyro_with_its_z_negated_is_named(tmp_path):
    """The shipped BROAD excerpt with its gyroscope's z negated: 54 deg of tilt and no note
    (the axes as read agree to 0.90 with the turns, the mapping to 0.986: less than the 0.1
    the note asked for)."""
    d = dict(np.load(example_log()))
    d["gyr"] = d["gyr"] * [1.0, 1.0, -1.0]
    np.savez(tmp_path / "z.npz", **d)
    notes = [w for w in read_log(str(tmp_path / "z.npz")).warnings if "axes disagree" in w]
    assert len(notes) == 1 and "read as (x, y, -z) they agree" in notes[0], notes


@pytest.mark.parametrize("P,name", [
    ([[1, 0, 0], [0, 1, 0], [0, 0, -1]], "x, y, -z"),     # z negated
    ([[0, 1, 0], [1, 0, 0], [0, 0, 1]], "y, x, z"),       # x and y swapped
    ([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], "z, -x, -y")])  # a turned gyro chip
def test_gyroscope_axes_that_disagree_are_named(tmp_path, motion, P, name):
    """A gyro wired or declared with other axes than the accelerometer's (48 deg of tilt for z
    negated on RobustAHRS) said nothing: gyro_scale gives no verdict on turns that point
    elsewhere. The note names the mapping that agrees and the calibration that applies it;
    with that file, or with a wrong one corrected as the second note says, the gyro agrees
    (no note, --strict passes) and the filter's tilt is the unmapped log's."""
    import json
    from imufuse.session import ReadOptions, Session
    P = np.asarray(P, float)
    head = ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z", "mag_x", "mag_y",
            "mag_z", "q_w", "q_x", "q_y", "q_z"]
    t = np.arange(len(motion.gyr)) * motion.dt
    # the log's gyro g' = P^T g, so that P g' = g
    rows = np.column_stack([t, motion.gyr @ P, motion.acc, motion.mag, motion.q_true])
    path = _csv(tmp_path / "axes.csv", head, rows)
    notes = [w for w in read_log(path).warnings if "axes disagree" in w]
    assert len(notes) == 1 and re.search(rf"read as \({name}\) they agree \((0\.9[89]\d|1\.000)\)",
                                         notes[0]) and \
        f"gyroscope.M is {P.astype(int).tolist()}" in notes[0], notes
    right = tmp_path / "right.json"
    right.write_text(json.dumps({"gyroscope": {"M": P.tolist()}}))
    swap = tmp_path / "wrong.json"
    swap.write_text(json.dumps({"gyroscope": {"M": [[-1, 0, 0], [0, 1, 0], [0, 0, 1]]}}))
    s = Session(str(path), ReadOptions(calibration=str(swap)))
    m = [n for n in s.notes if "axes disagree" in n]
    assert len(m) == 1 and "set the calibration file's gyroscope.M to " in m[0], s.notes
    composed = json.loads(m[0].split("gyroscope.M to ")[1].split(" (its M")[0])
    np.testing.assert_array_equal(composed, P)      # the file's M, then the mapping: P
    clean = _csv(tmp_path / "clean.csv", head, np.column_stack(
        [t, motion.gyr, motion.acc, motion.mag, motion.q_true]))
    want = Session(str(clean)).run("RobustAHRS").estimate.q
    for cal in (right, composed):
        if not isinstance(cal, type(right)):
            cal = tmp_path / "composed.json"
            cal.write_text(json.dumps({"gyroscope": {"M": composed}}))
        s = Session(str(path), ReadOptions(calibration=str(cal), strict=True))
        assert not [n for n in s.notes if "axes disagree" in n], s.notes
        np.testing.assert_array_equal(s.run("RobustAHRS").estimate.q, want)   # exact: a permutation


def test_time_in_ms(tmp_path, motion):
    t = np.arange(len(motion.gyr)) * motion.dt * 1000.0
    rows = np.column_stack([t, motion.gyr, motion.acc])
    log = read_log(_csv(tmp_path / "t.csv", ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y",
                                             "acc_z"], rows))
    assert any("--time-unit ms" in w for w in log.warnings), log.warnings
    assert read_log(str(tmp_path / "t.csv"), time_unit="ms").warnings == []


@pytest.mark.parametrize("unit,fix", [("ms", "--time-unit s"), ("us", "--time-unit ms")])
def test_time_in_seconds_read_as_a_smaller_unit(tmp_path, motion, unit, fix):
    """Seconds read as ms (a header's "(ms)" on seconds, or --time-unit ms): 200 Hz became
    200 kHz, and the filters integrated each sample over 5 us without a word."""
    t = np.arange(len(motion.gyr)) * motion.dt * (1.0 if unit == "ms" else 1e3)
    rows = np.column_stack([t, motion.gyr, motion.acc])
    path = _csv(tmp_path / "t.csv", ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y",
                                     "acc_z"], rows)
    log = read_log(path, time_unit=unit)
    assert any(f"faster than any IMU samples; a log in {fix[-2:].strip()} read as {unit}? give "
               f"{fix}" in w for w in log.warnings), log.warnings
    p = imf_here("run", path, "-f", "MadgwickIMU", "--time-unit", unit, "--strict", "-o",
                 tmp_path / "o.csv")
    assert p.returncode == 4 and fix in p.stderr, p.stderr


def test_a_corrupt_gyro_sample_is_named(tmp_path, motion):
    """One gyro sample of 1e30 rad/s (finite, so the filters take it) turned MadgwickIMU's
    attitude anywhere with no word; every sample corrupt from one on was also called deg/s."""
    t = np.arange(len(motion.gyr)) * motion.dt
    head = ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z"]
    for first, last, count in ((300, 301, "1 sample "), (300, None, f"{len(t) - 300} samples ")):
        gyr = motion.gyr.copy()
        gyr[first:last, 1] = 1e30
        log = read_log(_csv(tmp_path / "g.csv", head, np.column_stack([t, gyr, motion.acc])))
        assert log.warnings == [f"the gyroscope reads beyond 10000 rad/s in {count}(the largest "
                                f"1e+30 rad/s at {tmp_path / 'g.csv'}:302), more than any "
                                "gyroscope measures in any unit: corrupt samples? the filters "
                                "take them as they are"], log.warnings


def test_rate_that_contradicts_the_time_column(tmp_path):
    p = imf_here("run", example_log(), "-f", "MadgwickIMU",
                 "--rate", "100", "-o", str(tmp_path / "o.npz"))
    assert p.returncode == 0, p.stderr
    assert "--rate 100 Hz, but the file says 285.714 Hz" in p.stderr


def test_tune_varies_what_acts_sorted_by_score():
    """MadgwickIMU's acc_1g does nothing with the gate off: not varied (9 sets, not 81), and
    not a note either (nobody asked to vary it); the table is sorted by the score, best
    first, with the log's full name."""
    p = imf_here("tune", example_log(), "-f",
                 "MadgwickIMU", "--refine", "0", "-j", "2", "--quiet")
    assert p.returncode == 0, p.stderr
    assert "acc_1g" not in p.stderr and "note" not in p.stderr, p.stderr
    assert "9 parameter sets" in p.stdout
    lines = p.stdout.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("-"))
    rows = [ln for ln in lines[head + 1:] if ln and not ln.startswith("best")]
    scores = [float(r.split()[1]) for r in rows]
    assert scores == sorted(scores) and rows[0].endswith("<- best")
    assert os.path.basename(example_log()) in lines[head - 1]


def _mistake_logs(tmp_path, motion):
    """{mistake: (log path, extra options, the fix the message names)}"""
    t = np.arange(len(motion.gyr)) * motion.dt
    plain = ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z"]
    return {
        "deg/s": (_csv(tmp_path / "d.csv", plain, np.column_stack([t, np.degrees(motion.gyr),
                                                                   motion.acc])), [],
                  "--gyr-unit deg/s"),
        "m/s2": (_csv(tmp_path / "a.csv", plain, np.column_stack([t, motion.gyr,
                                                                  motion.acc * 9.80665])), [],
                 "--acc-unit m/s2"),
        "ms": (_csv(tmp_path / "t.csv", plain, np.column_stack([t * 1000.0, motion.gyr,
                                                                motion.acc])), [],
               "--time-unit ms"),
        "rate": (example_log(), ["--rate", "100"], "leave it out to use the file's rate"),
    }


@pytest.mark.parametrize("command,mistake", [
    (c, m) for c in ("run", "compare", "vario", "calibrate") for m in ("deg/s", "m/s2", "ms", "rate")
    if not (c in ("vario", "calibrate") and m == "rate")])     # they take no --rate
def test_strict_makes_each_mistake_an_error(tmp_path, motion, mistake, command):
    """--strict: the note becomes an error (exit 4) naming the fix, in every command that
    reads a log; without it the same is said as a note."""
    path, extra, fix = _mistake_logs(tmp_path, motion)[mistake]
    argv = {"run": ["run", path, "-f", "MadgwickIMU", "-o", tmp_path / "o.npz"],
            "compare": ["compare", path, "-f", "MadgwickIMU"],
            "vario": ["vario", path, "-o", tmp_path / "v.csv", "--no-plot"],
            "calibrate": ["calibrate", "gyro", path, "-o",
                          tmp_path / "c.json", "--longest-still"]}[command] + extra
    argv = [str(a) for a in argv]
    p = imf_here(*argv, "--strict")
    assert p.returncode == 4, p.stderr
    assert "(--strict)" in p.stderr and fix in p.stderr, p.stderr
    assert p.stderr.count("\n") == 1, p.stderr      # one line
    if command == "run":
        p = imf_here(*argv)
        assert "note: " in p.stderr and fix in p.stderr.split("\n")[0], p.stderr


@pytest.mark.parametrize("given", ["NED", "NWU"])
def test_strict_makes_a_frame_mistake_an_error(tmp_path, given):
    p = imf_here("run", example_log(), "-f",
                 "MadgwickAHRS", "--ref-frame", given, "--strict", "-o",
                 str(tmp_path / "o.npz"))
    assert p.returncode == 4, p.stderr
    assert "with --ref-frame ENU it would be" in p.stderr and "(--strict)" in p.stderr, p.stderr


def test_strict_is_silent_on_logs_read_correctly(tmp_path, motion):
    t = np.arange(len(motion.gyr)) * motion.dt
    rows = np.column_stack([t, np.degrees(motion.gyr), motion.acc])
    for path in (example_log(), _csv(tmp_path / "x.csv", XIO, rows)):
        p = imf_here("compare", str(path), "--strict")
        assert p.returncode == 0 and "note:" not in p.stderr, p.stderr


@pytest.mark.parametrize("peak_deg_s, noticed", [(100.0, True), (1700.0, True)])
def test_the_gyro_limit_is_that_of_mems_parts(tmp_path, peak_deg_s, noticed):
    """A log in deg/s without a unit, its rates up to peak_deg_s (1/3 of the samples near the
    peak): read as rad/s they pass 35 rad/s (2000 deg/s, the largest MEMS range), and the note
    says so; the same rates in rad/s (converted) are not questioned."""
    n = 3000
    t = np.arange(n) / 200.0
    w = np.zeros((n, 3))
    w[: n // 3, 2] = peak_deg_s
    w[n // 3:, 0] = 0.1 * peak_deg_s * np.sin(t[n // 3:])
    acc = np.tile([0.0, 0.0, 1.0], (n, 1))
    head = ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z"]
    deg = read_log(_csv(tmp_path / "deg.csv", head, np.column_stack([t, w, acc])))
    assert any("--gyr-unit deg/s" in x for x in deg.warnings) == noticed, deg.warnings
    rad = read_log(_csv(tmp_path / "rad.csv", head, np.column_stack([t, np.radians(w), acc])))
    assert not any("--gyr-unit" in x for x in rad.warnings), rad.warnings


@pytest.mark.parametrize("with_mag", [True, False])
def test_deg_per_s_on_a_slow_log(tmp_path, with_mag):
    """Slow motion in deg/s without a unit never passes 35 rad/s; the gyroscope turning the
    accelerometer's (and magnetometer's) direction 57 times too far names it; the same log in
    rad/s is not questioned (imufuse.plausible.gyro_scale)."""
    m = sim.imu("slow", rate=100.0, duration=10.0, seed=4, amplitude=0.2)  # up to 20 deg/s
    head = ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z"]
    cols = [m.t, np.degrees(m.gyr), m.acc]
    if with_mag:
        head += ["mag_x", "mag_y", "mag_z"]
        cols.append(m.mag)
    log = read_log(_csv(tmp_path / "slow.csv", head, np.column_stack(cols)))
    assert np.max(np.abs(log.gyr)) < 35.0
    (note,) = log.suspicions
    assert "--gyr-unit deg/s" in note and "57.3 times" in note, note
    assert ("magnetometer's" in note) == with_mag, note
    g = gyro_scale(log.gyr, log.acc, log.mag, dt=log.dt)
    assert 45 < g.ratio < 70, g
    assert read_log(str(tmp_path / "slow.csv"), gyr_unit="deg/s").suspicions == []


def test_gyro_scale_on_a_long_log_reads_stretches(tmp_path):
    """Past 200 000 samples, 40 stretches of 5000 spread over the log: the same verdict, from
    gyro_scale and from read_log (which stacks only the stretches)."""
    m = sim.imu("slow", rate=100.0, duration=60.0, seed=5, amplitude=0.2)
    reps = 42
    gyr, acc = np.tile(m.gyr, (reps, 1)), np.tile(m.acc, (reps, 1))
    assert len(gyr) > 200_000
    for scale in (1.0, np.degrees(1.0)):
        g = gyro_scale(gyr * scale, acc, None, dt=m.dt)
        assert g.windows <= 40 * 5000 // 5, g
        # rates up to 20 deg/s: read right, few windows turn far enough for a verdict
        assert (45.0 < g.ratio < 70.0) if scale != 1.0 else not g.ratio > 10.0, g
        np.savez(tmp_path / "long.npz", gyr=gyr * scale, acc=acc * 9.80665,
                 rate=np.array(1 / m.dt))
        notes = read_log(str(tmp_path / "long.npz")).suspicions
        assert len(notes) == (scale != 1.0) and all("--gyr-unit deg/s" in n for n in notes)
    assert np.isnan(gyro_scale(gyr, acc, dt=None).ratio)


@pytest.mark.parametrize("with_mag", [True, False])
def test_rad_per_s_read_as_deg_per_s(tmp_path, motion, with_mag):
    """A gyro in rad/s under a header that says deg/s (or --gyr-unit deg/s): 57.3 times too
    slow, MadgwickIMU off by tens of degrees, and not a word (only the reverse mistake was
    checked). It turns the directions 0.0175 times as far as they turn: a note naming
    --gyr-unit rad/s, an error under --strict, silence when the unit is right."""
    t = np.arange(len(motion.gyr)) * motion.dt
    cols = [t, motion.gyr, motion.acc] + ([motion.mag] if with_mag else [])
    head = ["time", "gyr_x (deg/s)", "gyr_y (deg/s)", "gyr_z (deg/s)", "acc_x", "acc_y",
            "acc_z"] + (["mag_x", "mag_y", "mag_z"] if with_mag else [])
    log = read_log(_csv(tmp_path / "r.csv", head, np.column_stack(cols)))
    (note,) = log.suspicions
    assert note.startswith("the gyroscope, read as deg/s (unit from the header), turns 0.017")
    assert note.endswith("these look like rad/s; give --gyr-unit rad/s"), note
    assert ("magnetometer's" in note) == with_mag, note
    assert read_log(str(tmp_path / "r.csv"), gyr_unit="rad/s").suspicions == []
    bare = _csv(tmp_path / "b.csv", [h.replace(" (deg/s)", "") for h in head],
                np.column_stack(cols))
    (note,) = read_log(bare, gyr_unit="deg/s").suspicions
    assert "read as deg/s (given)" in note and "--gyr-unit rad/s" in note, note
    p = imf_here("run", bare, "-f", "MadgwickIMU", "--gyr-unit", "deg/s", "--strict", "-o",
                 tmp_path / "o.csv")
    assert p.returncode == 4 and "--gyr-unit rad/s (--strict)" in p.stderr, p.stderr
    right = np.column_stack([t, np.degrees(motion.gyr)] + cols[2:])
    assert read_log(_csv(tmp_path / "d.csv", head, right)).suspicions == []


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_rad_per_s_read_as_deg_per_s_keeps_its_margin_on_the_broad_trials():
    """Read right, no BROAD trial comes near the too-slow verdict (their lowest ratio is
    0.9, translations and tapping included); scaled by 1/57.3, every one gets it."""
    for f in sorted(glob.glob(os.path.join(BROAD, "*.npz"))):
        log = read_log(f)
        right = gyro_scale(log.gyr, log.acc, log.mag, dt=log.dt, too_small=True)
        slow = gyro_scale(log.gyr / np.degrees(1.0), log.acc, log.mag, dt=log.dt,
                          too_small=True)
        assert right.ratio > 0.5 and slow.ratio < 0.02, (f, right, slow)


def test_a_given_rate_runs_past_a_broken_time_column(tmp_path):
    """A time column that stops increasing (line 23) is refused with the way out named;
    with --rate the log runs at that rate, its times k / rate, and the column's defect is
    said; calibration, which needs no time, does without the column."""
    f = tmp_path / "time_repeat.csv"
    f.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n"
                 + "".join(f"{min(k, 20) / 100},0,0,0,0,0,1\n" for k in range(150)))
    r = imf_here("run", f, "-f", "MadgwickIMU", "-o", tmp_path / "o.csv")
    errs = [ln for ln in r.stderr.splitlines() if ln.startswith("imufuse: error:")]
    assert r.returncode == 4 and len(errs) == 1, r.stderr       # 4: a data error
    line = errs[0]
    assert ":23: time does not increase (0.2 then 0.2)" in line and "--rate HZ" in line, line
    r = imf_here("run", f, "-f", "MadgwickIMU", "--rate", 50, "-o", tmp_path / "o.csv")
    assert r.returncode == 0, r.stderr
    assert ":23: time does not increase" in r.stderr and "--rate 50 Hz gives" in r.stderr
    t = np.loadtxt(tmp_path / "o.csv", delimiter=",", skiprows=1, usecols=0)
    assert np.array_equal(t, np.arange(150) * (1 / 50.0))
    r = imf_here("calibrate", "gyro", f, "-o", tmp_path / "c.json")
    assert "time does not increase" in r.stderr and "the time column is not used" in r.stderr
    assert "--rate HZ" not in r.stderr, r.stderr


def test_a_gyro_offset_beyond_the_filters_range_is_named(tmp_path):
    """A gyro offset beyond RobustIMU/RobustAHRS's gyr_bias_max (20 deg/s against 6: 35 deg of
    tilt) gave no word although the log lies still for 30 s: the run's notes name what the
    gyroscope reads while the other sensors are still, and the setting that covers it. Not
    within the range, not with the setting given, not on a turntable (the magnetometer
    turns), and a log without a magnetometer says a turn about the vertical could be it."""
    from imufuse import io, sim
    from imufuse.session import Session
    d = sim.imu("static", rate=100.0, duration=30.0, seed=1)

    def notes(bias, mag=True, gyr=None, m=None, **params):
        p = tmp_path / f"b{len(list(tmp_path.iterdir()))}.csv"
        g = (d.gyr if gyr is None else gyr) + np.radians(bias)
        io.write_log(p, d.t, g, d.acc, (d.mag if m is None else m) if mag else None)
        name = "RobustAHRS" if mag else "RobustIMU"
        return [n for n in Session(str(p)).run(name, params, keep_states=False).notes
                if "gyr_bias_max" in n]
    mean = np.degrees(d.gyr.mean(axis=0))          # the simulated part's own small offset
    got = notes([20.0, -15.0, 10.0])
    want = mean + [20.0, -15.0, 10.0]
    assert len(got) == 1 and "the gyroscope reads (" in got[0] and \
        "deg/s while the accelerometer and the magnetometer stay still" in got[0] and \
        "beyond RobustAHRS's gyr_bias_max (6 deg/s)" in got[0] and \
        f"give -p gyr_bias_max={int(np.ceil(1.5 * np.abs(want).max()))}," in got[0], (got, want)
    reads = [float(v) for v in got[0].split("reads (")[1].split(")")[0].split(", ")]
    np.testing.assert_allclose(reads, want, rtol=5e-3)       # three significant digits
    assert notes([20.0, -15.0, 10.0], gyr_bias_max=32.0) == []
    assert notes([3.0, -2.0, 3.0]) == []
    imu = notes([20.0, -15.0, 10.0], mag=False)
    assert len(imu) == 1 and "(or a turn about the vertical at that rate)" in imu[0], imu
    # a turntable: 20 deg/s about the vertical, the field turning in the sensor frame
    th = np.radians(20.0) * d.t
    turned = np.column_stack([np.cos(th) * d.mag[:, 0] + np.sin(th) * d.mag[:, 1],
                              -np.sin(th) * d.mag[:, 0] + np.cos(th) * d.mag[:, 1], d.mag[:, 2]])
    assert notes([0.0, 0.0, 20.0], m=turned) == []


@pytest.mark.parametrize("turn_deg,left", [(0.0, False), (30.0, True)])
def test_a_frame_hint_that_leaves_a_large_error_names_the_sensor_axes(turn_deg, left):
    """A frame hint whose best frame still leaves a large error ("with --ref-frame NED it
    would be 48.3 deg: is the reference in NED?", for a sensor whose axes differ from the
    reference's) sent the user to a frame that does not fix it: beyond 10 deg left, the hint
    also names the sensor's axes and --align. The shipped example read as NED, its estimate
    as run and turned on the sensor side by 30 deg."""
    import dataclasses
    from imufuse.rotations import quat_mul
    from imufuse.session import ScoreOptions, Session
    s = Session(example_log())
    r = s.run("MadgwickAHRS")
    h = math.radians(turn_deg) / 2
    q = quat_mul(r.estimate.q, np.array([[math.cos(h), math.sin(h), 0.0, 0.0]]))
    r = dataclasses.replace(r, estimate=dataclasses.replace(r.estimate, q=q))
    sc = ScoreOptions(ref_frame="NED")
    hint = s.frame_hint(r, s.score(r, sc), sc)
    assert hint and "with --ref-frame ENU it would be" in hint, hint
    assert ("is still far off: the sensor's axes may differ from the reference's, which "
            "--align turns" in hint) == left, hint


def test_an_accelerometer_window_that_holds_no_reading_is_named():
    """MultiWii given acc_1g in m/s^2 (9.81) where it gets g: no reading falls in its window,
    it integrates the gyro alone (11.5 deg of tilt on the shipped excerpt against 2.1), and
    nothing said so. The run's notes now do, with the acc_1g the readings have."""
    from imufuse.session import Session
    s = Session(example_log())
    assert not [n for n in s.run("MultiWii").notes if "window" in n]
    (note,) = [n for n in s.run("MultiWii", {"acc_1g": 9.81}).notes if "window" in n]
    assert "no accelerometer reading falls in MultiWii's window of 1 g (acc_1g 9.81 +- 15%" in note
    assert "give -p acc_1g=1.005" in note, note
