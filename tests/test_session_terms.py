"""A log's notes and errors in the user's terms: the command line names its options
(--gyr-unit deg/s); a Python user of imufuse.session.Session gets the same words and the
ReadOptions / ScoreOptions fields, run()'s params, the calibration function they are
(imufuse.shared.flags)."""
import numpy as np
import pytest

from imufuse import sim
from imufuse.io import LogError
from imufuse.session import ReadOptions, Session, StrictError
from imufuse.shared.flags import as_python
from cli_here import imf_here

IMU = ["gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z"]


def _csv(path, header, rows):
    with open(path, "w") as f:
        f.write(",".join(header) + "\n")
        for r in rows:
            f.write(",".join(repr(float(v)) for v in r) + "\n")
    return str(path)


@pytest.fixture(scope="module")
def deg_log(tmp_path_factory):
    """A lively motion whose gyroscope is in deg/s, its header without a unit."""
    m = sim.imu("fast", rate=200.0, duration=10.0, seed=3)
    t = np.arange(len(m.gyr)) * m.dt
    return _csv(tmp_path_factory.mktemp("terms") / "d.csv", ["time", *IMU],
                np.column_stack([t, np.degrees(m.gyr), m.acc]))


def test_a_python_session_names_the_field(deg_log):
    (note,) = [n for n in Session(deg_log).notes if "deg/s" in n]
    assert note.endswith("give --gyr-unit deg/s [Python: --gyr-unit deg/s is "
                         "ReadOptions(gyr_unit='deg/s')]"), note
    # the field it names is the fix: the note is gone
    assert not [n for n in Session(deg_log, ReadOptions(gyr_unit="deg/s")).notes
                if "deg/s" in n]


def test_the_command_line_names_its_options_only(deg_log, tmp_path):
    p = imf_here("run", deg_log, "-f", "MadgwickIMU", "-o", str(tmp_path / "o.npz"))
    assert p.returncode == 0, p.stderr
    assert "give --gyr-unit deg/s" in p.stderr and "[Python:" not in p.stderr, p.stderr


def test_a_python_sessions_errors_name_the_fields(deg_log, tmp_path):
    with pytest.raises(StrictError, match=r"\[Python: --gyr-unit deg/s is ReadOptions\("
                                          r"gyr_unit='deg/s'\); --strict is "
                                          r"ReadOptions\(strict=True\)\]$"):
        Session(deg_log, ReadOptions(strict=True))
    bare = _csv(tmp_path / "n.csv", IMU, np.tile([0.0, 0.0, 0.0, 0.0, 0.0, 1.0], (50, 1)))
    with pytest.raises(LogError, match=r"\[Python: --rate HZ is ReadOptions\(rate=HZ\); "
                                       r"--columns time=\"HEADER\" is ReadOptions\("
                                       r"columns=\{'time': 'HEADER'\}\)\]$"):
        Session(bare)


def test_errors_of_a_run_and_a_search_are_said_too(tmp_path):
    """Errors raised by Session.run (a missing column, a parameter the log sets) and by
    Tuner (a metric, a grid too large) in a Python user's terms as well; the command line's
    Tuner says its options only."""
    from imufuse.io import example_log
    from imufuse.tune import Tuner
    m = sim.imu("fast", rate=200.0, duration=2.0, seed=3)
    t = np.arange(len(m.gyr)) * m.dt
    s = Session(_csv(tmp_path / "imu.csv", ["time", *IMU], np.column_stack([t, m.gyr, m.acc])))
    with pytest.raises(LogError, match=r"--columns NAME=\"HEADER\" is ReadOptions\(columns="
                                       r"\{'NAME': 'HEADER'\}\)\]$"):
        s.run("RobustAHRS")
    with pytest.raises(ValueError, match=r"\[Python: --rate HZ is ReadOptions\(rate=HZ\)\]$"):
        s.run("MadgwickIMU", {"dt": 0.01})
    ex = Session(example_log())
    with pytest.raises(ValueError, match=r"\[Python: --metric heading is "
                                         r"Tuner\(metric='heading'\)\]$"):
        Tuner([ex], "MadgwickIMU", metric="heading")
    with pytest.raises(ValueError, match=r"\[Python: --grid GRID is Tuner.search\(grid=GRID\)\]$"):
        Tuner([ex], "MadgwickIMU").search([("beta", list(np.linspace(0.01, 1, 100_001)))])
    with pytest.raises(ValueError) as e:
        Tuner([ex], "MadgwickIMU", metric="heading", read=ReadOptions(command_line=True))
    assert "[Python:" not in str(e.value)


@pytest.mark.parametrize("message, said", [
    ("hint: with --ref-frame ENU --ref-direction earth-to-sensor it would be 1.2 deg",
     "--ref-frame ENU is ScoreOptions(ref_frame='ENU'); --ref-direction earth-to-sensor is "
     "ScoreOptions(ref_direction='earth-to-sensor')"),
    ("an offset beyond gyr_bias_max; give -p gyr_bias_max=30, or calibrate the gyroscope "
     "(imufuse calibrate gyro, --calibration)",
     "--calibration FILE is ReadOptions(calibration=FILE); -p gyr_bias_max=30 is "
     "Session.run(name, params={'gyr_bias_max': 30}); imufuse calibrate gyro is "
     "run_log('gyro', LOG, OUTPUT) of imufuse.calibration.log"),
    # a glossary: the message says to leave the setting out
    ("--rate 100 Hz, but the file says 285.714 Hz: the filters use --rate; leave it out",
     "--rate 100 is ReadOptions(rate=100)"),
    ("x.csv: --skip 3 s leaves no sample", "--skip 3 is ScoreOptions(skip=3)"),
    ("the median interval (--fixed-rate); is it --time-unit ms?",
     "--fixed-rate is ReadOptions(fixed_rate=True); --time-unit ms is ReadOptions(time_unit='ms')"),
    ("which --align turns, docs/logs.md", "--align ALIGNMENT is ReadOptions(align=ALIGNMENT)"),
    # alternatives stay apart
    ('no time column; give the sample rate (--rate HZ), or name the time column '
     '(--columns time="HEADER")',
     "--rate HZ is ReadOptions(rate=HZ); --columns time=\"HEADER\" is "
     "ReadOptions(columns={'time': 'HEADER'})"),
    ("--metric heading: MadgwickIMU has no heading reference; use inclination",
     "--metric heading is Tuner(metric='heading')"),
    ("at most 100000: give --grid for the parameters to tune (fewer values), or --refine 0",
     "--grid GRID is Tuner.search(grid=GRID); --refine 0 is Tuner.search(refine=0)"),
])
def test_each_option_is_said_as_its_field(message, said):
    assert as_python(message) == f"{message} [Python: {said}]"
    assert as_python(as_python(message)) == as_python(message)   # said once


def test_a_message_without_options_is_left_alone():
    for m in ("fixed dt 0.01 s (this build has no per-sample dt)", "the --rate-like word",
              "gyr--rate"):
        assert as_python(m) == m
