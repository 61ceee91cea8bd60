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
    assert note.endswith("give --gyr-unit deg/s [Python: ReadOptions(gyr_unit='deg/s')]"), note
    # the field it names is the fix: the note is gone
    assert not [n for n in Session(deg_log, ReadOptions(gyr_unit="deg/s")).notes
                if "deg/s" in n]


def test_the_command_line_names_its_options_only(deg_log, tmp_path):
    p = imf_here("run", deg_log, "-f", "MadgwickIMU", "-o", str(tmp_path / "o.npz"))
    assert p.returncode == 0, p.stderr
    assert "give --gyr-unit deg/s" in p.stderr and "[Python:" not in p.stderr, p.stderr


def test_a_python_sessions_errors_name_the_fields(deg_log, tmp_path):
    with pytest.raises(StrictError, match=r"\[Python: ReadOptions\(gyr_unit='deg/s', "
                                          r"strict=True\)\]$"):
        Session(deg_log, ReadOptions(strict=True))
    bare = _csv(tmp_path / "n.csv", IMU, np.tile([0.0, 0.0, 0.0, 0.0, 0.0, 1.0], (50, 1)))
    with pytest.raises(LogError, match=r"\[Python: ReadOptions\(rate=HZ, "
                                       r"columns=\{'time': 'HEADER'\}\)\]$"):
        Session(bare)


@pytest.mark.parametrize("message, said", [
    ("hint: with --ref-frame ENU --ref-direction earth-to-sensor it would be 1.2 deg",
     "ScoreOptions(ref_frame='ENU', ref_direction='earth-to-sensor')"),
    ("an offset beyond gyr_bias_max; give -p gyr_bias_max=30, or calibrate the gyroscope "
     "(imufuse calibrate gyro, --calibration)",
     "ReadOptions(calibration=FILE); run(name, params={'gyr_bias_max': 30}); "
     "imufuse.calibration.log.run_log('gyro', ...)"),
    ("--rate 100 Hz, but the file says 285.714 Hz: the filters use --rate",
     "ReadOptions(rate=100)"),
    ("x.csv: --skip 3 s leaves no sample", "ScoreOptions(skip=3)"),
    ("the median interval (--fixed-rate); is it --time-unit ms?",
     "ReadOptions(fixed_rate=True, time_unit='ms')"),
    ("which --align turns, docs/logs.md", "ReadOptions(align=ALIGNMENT)"),
])
def test_each_option_is_said_as_its_field(message, said):
    assert as_python(message) == f"{message} [Python: {said}]"


def test_a_message_without_options_is_left_alone():
    for m in ("fixed dt 0.01 s (this build has no per-sample dt)", "the --rate-like word",
              "gyr--rate"):
        assert as_python(m) == m
