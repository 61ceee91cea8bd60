"""The hints at a frame mistake behind an error beyond 45 deg (Session.frame_hint): the
reference read in another earth frame or direction, or the sensor's axes turned against the
reference's body (mounted turned: the --align that turns it back), on the shipped example."""
import re

import numpy as np
import pytest

from imufuse.io import example_log
from imufuse.reference._fusion import alignment_matrix
from cli_here import imf_here


@pytest.mark.parametrize("given, want", [("NED", "ENU"), ("NWU", "ENU")])
def test_a_wrong_reference_frame_is_named(tmp_path, given, want):
    """The shipped example's reference is ENU: read as NED the inclination error is 179 deg,
    as NWU the heading error 88 deg; the note names the frame that fits."""
    p = imf_here("run", example_log(), "-f",
                 "MadgwickAHRS", "--ref-frame", given, "-o", str(tmp_path / "o.npz"))
    assert p.returncode == 0, p.stderr
    assert f"against the reference as {given} (given)" in p.stderr
    assert f"with --ref-frame {want} it would be" in p.stderr


def test_no_frame_note_when_the_frame_is_right(tmp_path):
    p = imf_here("run", example_log(), "-f",
                 "MadgwickAHRS", "-o", str(tmp_path / "o.npz"))
    assert p.returncode == 0 and "hint:" not in p.stderr and "note:" not in p.stderr, p.stderr


def _mounted_turned(tmp_path, alignment):
    """The shipped example as read by a sensor mounted turned: --align ``alignment`` (body =
    M sensor) is what turns its readings back (each reading M^T body)."""
    m = alignment_matrix(alignment)
    d = dict(np.load(example_log()))
    for k in ("gyr", "acc", "mag"):
        d[k] = d[k] @ m
    path = tmp_path / "turned.npz"
    np.savez(path, **d)
    return str(path)


@pytest.mark.parametrize("alignment, name", [("-Y+X+Z", "MadgwickAHRS"), ("-X-Y+Z", "MadgwickAHRS"),
                                             ("+X+Z-Y", "RobustIMU"), ("+Y+Z+X", "MahonyIMU")])
def test_a_sensor_mounted_turned_is_named(tmp_path, alignment, name):
    """A sensor turned 90 deg about z gave 67 deg of tilt and no hint (no reference frame
    halves it). Now the hint names the --align that turns it back, and the run with it gives
    the log's own result."""
    from imufuse.session import ReadOptions, Session
    path = _mounted_turned(tmp_path, alignment)
    s = Session(path)
    r = s.run(name, {})
    ev = s.score(r)
    assert max(ev.inclination, ev.heading if r.kind == "ahrs" else 0.0) > 45.0
    hint = s.frame_hint(r, ev)
    assert hint is not None and f"with --align {alignment} it would be about" in hint, hint
    assert hint.endswith(f"[Python: --align {alignment} is ReadOptions(align={alignment!r})]"), hint
    want = Session(example_log())
    ev0 = want.score(want.run(name, {}))
    s2 = Session(path, ReadOptions(align=alignment))
    ev2 = s2.score(s2.run(name, {}))
    assert abs(ev2.inclination - ev0.inclination) < 0.01, (ev2.inclination, ev0.inclination)
    said = float(re.search(r"it would be about ([0-9.]+) deg", hint).group(1))
    assert said < 5.0 and s2.frame_hint(s2.run(name, {}), ev2) is None


def test_the_command_line_names_the_turn(tmp_path):
    p = imf_here("run", _mounted_turned(tmp_path, "-Y+X+Z"), "-f", "MadgwickAHRS",
                 "-o", str(tmp_path / "o.npz"))
    assert p.returncode == 0, p.stderr
    assert "with --align -Y+X+Z it would be about" in p.stderr and "[Python:" not in p.stderr
    p = imf_here("run", _mounted_turned(tmp_path, "-Y+X+Z"), "-f", "MadgwickAHRS",
                 "-o", str(tmp_path / "s.npz"), "--strict")
    assert p.returncode == 4 and "--align -Y+X+Z" in p.stderr, p.stderr


def test_a_turned_sensor_with_the_reference_in_another_frame(tmp_path):
    """A CSV's reference is assumed NWU; the shipped example's is ENU. With the sensor turned
    90 deg about z as well, no frame alone halved the error (102 deg) and no hint came; now
    the turn and the frame are named together, and with both the run is the log's own."""
    from imufuse.session import ReadOptions, ScoreOptions, Session
    alignment = "-Y+X+Z"
    m = alignment_matrix(alignment)
    d = np.load(example_log())
    t = np.arange(len(d["gyr"])) / float(d["rate"])

    def csv(name, turn):
        with open(tmp_path / name, "w") as f:
            f.write("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z,q_w,q_x,q_y,"
                    "q_z\n")
            np.savetxt(f, np.column_stack([t, d["gyr"] @ turn, d["acc"] @ turn,
                                           d["mag"] @ turn, d["quat_ref"]]),
                       delimiter=",", fmt="%.17g")
        return str(tmp_path / name)
    path = csv("turned.csv", m)
    s = Session(path)
    r = s.run("MadgwickAHRS")
    ev = s.score(r)
    hint = s.frame_hint(r, ev)
    assert hint is not None and "against the reference as NWU (assumed)" in hint, hint
    assert f"with --align {alignment} --ref-frame ENU it would be about" in hint, hint
    s2 = Session(path, ReadOptions(align=alignment))
    ev2 = s2.score(s2.run("MadgwickAHRS"), ScoreOptions(ref_frame="ENU"))
    want = Session(csv("as_read.csv", np.eye(3)))
    ev0 = want.score(want.run("MadgwickAHRS"), ScoreOptions(ref_frame="ENU"))
    assert abs(ev2.inclination - ev0.inclination) < 0.01 and abs(ev2.heading - ev0.heading) < 0.01
