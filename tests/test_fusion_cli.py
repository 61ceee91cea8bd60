"""`imufuse run --filter FusionAHRS`, the calibration file format and the
preprocessing options (--calibration, --align, --offset) in front of any filter."""
import json

import numpy as np
import pytest

import imufuse_c
from imufuse.preprocess import calibration as cm
from imufuse import cli, io
from imufuse import reference as ref

from bits import assert_same_bits
from fusion_sim import simulated_log


@pytest.fixture(scope="module")
def log_path(tmp_path_factory):
    d = tmp_path_factory.mktemp("fusion_cli")
    log = simulated_log(seed=21, n=1500)
    t = np.cumsum(log.dt.astype(np.float64))
    t -= t[0]
    path = d / "log.csv"
    io.write_log(str(path), t, np.radians(log.gyr.astype(np.float64)),
                 log.acc.astype(np.float64), log.mag.astype(np.float64))
    return path


def _read(path):
    import csv
    with open(path) as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], dtype=np.float64)


def test_run_fusion_ahrs_matches_the_class(log_path, tmp_path):
    out = tmp_path / "out.csv"
    rc = cli.main(["run", str(log_path), "--filter", "FusionAHRS", "-p", "gain=0.7",
                   "-p", "convention='ENU'", "-p", "recovery_trigger_period=300",
                   "-p", "acceleration_rejection=10", "--dtype", "float32", "--frame", "ENU",
                   "-o", str(out)])
    assert rc == 0
    header, data = _read(out)
    log = io.read_log(str(log_path))
    assert "each sample's own interval" in " ".join(log.warnings)
    t = log.columns["time"]
    dt = np.diff(t, prepend=t[0] - log.dt)
    f = imufuse_c.FusionAHRS(gain=0.7, convention="ENU", recovery_trigger_period=300,
                             acceleration_rejection=10, dtype="float32")
    S = f.run(np.degrees(log.gyr), log.acc, log.mag, dt=dt)
    got = data[:, [header.index(n) for n in f.state_names]].astype(np.float32)
    assert_same_bits(got, S, f.state_names)
    euler = f.outputs_batch(S)["euler"]
    for j, ax in enumerate(("roll", "pitch", "yaw")):
        # Fusion's own Euler angles (its float32 arithmetic), bit for bit
        assert_same_bits(data[:, header.index(f"fusion_{ax}_deg")].astype(np.float32),
                         euler[:, j], None)
    # the output frame's angles (--frame ENU, Fusion's convention here), computed by imufuse
    # from the quaternion in float64: the same angles to float32's precision
    d = (data[:, header.index("yaw_deg")] - euler[:, 2] + 180.0) % 360.0 - 180.0
    assert np.max(np.abs(d)) < 1e-3


@pytest.mark.parametrize("how", [["--fixed-rate"], ["--rate", "50"]])
def test_run_fusion_ahrs_fixed_rate(log_path, tmp_path, capsys, how):
    """--fixed-rate and --rate run FusionAHRS at one period, as every filter,
    and what the loader's note says is what it did (the log's intervals vary
    from 7.6 to 30 ms)."""
    out = tmp_path / "out.csv"
    rc = cli.main(["run", str(log_path), "--filter", "FusionAHRS", *how, "-o", str(out)])
    assert rc == 0
    err = capsys.readouterr().err
    header, data = _read(out)
    log = io.read_log(str(log_path), fixed_rate=True,
                      rate=float(how[1]) if how[0] == "--rate" else None)
    f = imufuse_c.FusionAHRS()
    S = f.run(np.degrees(log.gyr), log.acc, log.mag, dt=log.dt)
    assert_same_bits(data[:, [header.index(n) for n in f.state_names]], S, f.state_names)
    assert f"dt={log.dt:.6g} s" in err and "dt per sample" not in err
    if how[0] == "--fixed-rate":
        assert f"the filters use the median {log.dt:.6g} s" in err


@pytest.mark.parametrize("filt", ["FusionAHRS", "MadgwickAHRS", "MahonyIMU"])
def test_preprocessing_in_front_of_any_filter(log_path, tmp_path, filt):
    cal = tmp_path / "cal.json"
    cm.save_calibration(cal, {"gyroscope": {"b": [0.01, -0.007, 0.005], "s": [1.01, 1, 0.99]},
                              "accelerometer": {"M": np.eye(3).tolist()},
                              "magnetometer": {"S": (1.1 * np.eye(3)).tolist(), "h": [1, 2, 3]}})
    base, pre = tmp_path / "base.csv", tmp_path / "pre.csv"
    assert cli.main(["run", str(log_path), "--filter", filt, "-o", str(base)]) == 0
    assert cli.main(["run", str(log_path), "--filter", filt, "--calibration", str(cal),
                     "--align", "+Y+X-Z", "--offset", "-o", str(pre)]) == 0
    h0, d0 = _read(base)
    h1, d1 = _read(pre)
    assert h0 == h1 and not np.array_equal(d0, d1)


def test_preprocess_order_and_values(log_path):
    """calibration (sensor axes, deg/s), then alignment, then FusionOffset."""
    from imufuse import preprocess
    calib = {"gyroscope": {"M": [[1, 0.01, 0], [0, 1, 0], [0, 0, 1]], "s": [1, 1.02, 1],
                           "b": [0.009, 0, -0.009]}}
    import os
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        p = os.path.join(d, "c.json")
        cm.save_calibration(p, calib)
        log = io.read_log(str(log_path))
        raw = log.gyr.copy()
        notes = preprocess.apply(log, calibration=p, align="-Z+X-Y", offset=True)
    assert len(notes) == 3
    c = cm.from_dict(calib)
    want = c.apply("gyroscope", raw)          # the file is in rad/s, as the log is read
    want = imufuse_c.axes_apply(want, "-Z+X-Y")
    want, _ = imufuse_c.FusionOffset(int(round(1 / log.dt))).run(np.degrees(want))
    np.testing.assert_array_equal(log.gyr, np.radians(want))


@pytest.mark.parametrize("data,match", [
    ([1, 2], "JSON object"), ({"gyro": {}}, "unknown sensor"),
    ({"gyroscope": {"S": np.eye(3).tolist()}}, "unknown key"),
    ({"gyroscope": {"b": [1, 2]}}, r"gyroscope\.b: expected shape \(3,\)"),
    ({"magnetometer": {"S": [[1, 0], [0, 1]]}}, r"magnetometer\.S: expected shape"),
    ({"accelerometer": {"s": [1, "x", 1]}}, r"accelerometer\.s: expected numbers"),
    ({"accelerometer": {"b": [1, float("nan"), 1]}}, "finite"),
    # an offset written in deg/s (x-io's unit) was applied as rad/s: 63 deg of tilt
    ({"gyroscope": {"b": [3, -2, 3]}}, r"gyroscope\.b: \[3\.0, -2\.0, 3\.0\] rad/s is "
     r"\[171\.9, -114\.6, 171\.9\] deg/s, beyond .* they read \[0\.0524, -0\.0349, "
     r"0\.0524\] rad/s"),
])
def test_calibration_file_errors(tmp_path, data, match):
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(data))
    with pytest.raises(cm.CalibrationError, match=match):
        cm.load_calibration(p)
    with pytest.raises(cm.CalibrationError, match=match):
        cm.save_calibration(tmp_path / "not-written.json", data)
    assert not (tmp_path / "not-written.json").exists()


def test_calibration_file_roundtrip_and_cli_errors(tmp_path, log_path):
    p = tmp_path / "c.json"
    cm.save_calibration(p, {"magnetometer": {"h": [1, 2, 3]}})
    c = cm.load_calibration(p)
    assert c.gyroscope is None and c.magnetometer["h"].tolist() == [1, 2, 3]
    assert cm.is_identity(cm.from_dict({}))
    x = np.array([[1.0, 2.0, 3.0]])
    assert_same_bits(c.apply("magnetometer", x), ref.fusion.calibrate_magnetic(
        x, np.eye(3), [1, 2, 3]), None)
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(cm.CalibrationError, match="not valid JSON"):
        cm.load_calibration(tmp_path / "broken.json")
    # a calibration file that is not JSON: bad file contents (exit 4), not a bad command line
    assert cli.main(["run", str(log_path), "--filter", "FusionAHRS", "--calibration",
                     str(tmp_path / "broken.json"), "-o", str(tmp_path / "x.csv")]) == 4
    assert cli.main(["run", str(log_path), "--filter", "FusionAHRS", "-p", "gain=-1",
                     "-o", str(tmp_path / "x.csv")]) == 2
    assert cli.main(["run", str(log_path), "--filter", "FusionAHRS", "--align", "+X+X+Z",
                     "-o", str(tmp_path / "x.csv")]) == 2


def test_run_fusion_reports_errors_against_reference(tmp_path, capsys):
    """On a simulated log with a reference orientation (imufuse units, NWU),
    FusionAHRS through the command line tracks it."""
    from imufuse import sim
    d = sim.imu("slow", rate=100.0, duration=40.0, seed=2)
    path = tmp_path / "sim.csv"
    io.write_log(str(path), d.t, d.gyr, d.acc, d.mag, q=d.q_true)
    assert cli.main(["run", str(path), "--filter", "FusionAHRS", "-o", str(tmp_path / "o.csv")]) == 0
    err = capsys.readouterr().err
    import re
    # the BROAD metrics, as for every filter
    m = re.search(r"heading ([0-9.]+), inclination ([0-9.]+) deg RMS over 4000 of 4000", err)
    assert m, err
    # gain 0.5 leaves the simulated 0.7 deg/s gyroscope bias partly in the tilt
    assert float(m.group(2)) < 3.0 and float(m.group(1)) < 3.0



def test_fusion_in_compare_as_any_filter(tmp_path, capsys):
    """compare takes FusionAHRS beside the other filters (its units applied by the session)
    and scores it against the reference as them: on a simulated NWU log its table row
    equals the errors of the class run by hand in Fusion's units."""
    from imufuse import sim
    from imufuse.evaluation import evaluate
    d = sim.imu("slow", rate=100.0, duration=40.0, seed=2)
    path = tmp_path / "sim.csv"
    io.write_log(str(path), d.t, d.gyr, d.acc, d.mag, q=d.q_true)
    assert cli.main(["compare", str(path), "-f", "FusionAHRS,MadgwickAHRS",
                     "-p", "FusionAHRS.gain=0.7", "--fixed-rate"]) == 0
    out = capsys.readouterr().out
    row = next(ln for ln in out.splitlines() if ln.startswith("FusionAHRS"))
    f = imufuse_c.FusionAHRS(gain=0.7)
    S = f.run(np.degrees(d.gyr), d.acc, d.mag, dt=d.dt)
    q = S[:, :4] / np.linalg.norm(S[:, :4], axis=1, keepdims=True)
    e = evaluate(q, d.q_true, est_frame="NWU", ref_frame="NWU")
    assert row.split()[2:5] == [f"{e.inclination:.3f}", f"{e.heading:.3f}", f"{e.total:.3f}"]
    assert any(ln.startswith("MadgwickAHRS") for ln in out.splitlines())


def test_fusion_names_in_other_commands(log_path, tmp_path, capsys):
    assert cli.main(["run", str(log_path), "--filter", "FusionOffset",
                     "-o", str(tmp_path / "x.csv")]) == 2
    assert "--offset" in capsys.readouterr().err



def test_calibration_file_from_imufuse_calibrate(tmp_path, log_path):
    """The file imufuse.calibration.log writes is the one --calibration reads, in the
    same units: a gyroscope offset estimated on a still log removes the bias."""
    from imufuse import preprocess
    from imufuse.calibration import log as calibrate
    n = 3000
    g = np.random.default_rng(5)
    bias = np.array([0.01, -0.02, 0.015])                       # rad/s
    gyr = bias + g.normal(0, 0.002, (n, 3))
    t = np.arange(n) * 0.01
    acc = np.tile([0.0, 0.0, 1.0], (n, 1)) + g.normal(0, 0.002, (n, 3))
    path = tmp_path / "still.csv"
    io.write_log(str(path), t, gyr, acc)
    cal_path = tmp_path / "cal.json"
    calibrate.run_log("gyro", str(path), str(cal_path))
    log = io.read_log(str(path))
    preprocess.apply(log, calibration=str(cal_path))
    assert np.abs(log.gyr.mean(axis=0)).max() < 1e-4


def test_offset_says_when_it_corrected_nothing(tmp_path):
    """--offset with a gyro offset beyond FusionOffset's 3 deg/s stillness threshold said
    "final offset 0.000, 0.000, 0.000 deg/s" and nothing more: the note says it never found
    the gyroscope still and what corrects such an offset; with 1 deg/s it corrects it."""
    from imufuse import sim
    from imufuse.session import ReadOptions, Session
    d = sim.imu("static", rate=100.0, duration=20.0, seed=1)
    for bias, corrected in ((4.0, False), (1.0, True)):
        p = tmp_path / f"b{bias:g}.csv"
        io.write_log(p, d.t, d.gyr + np.radians([bias, -bias, bias]), d.acc)
        note = [n for n in Session(str(p), ReadOptions(offset=True)).notes
                if n.startswith("gyroscope offset estimated")]
        assert len(note) == 1, note
        assert ("it never found the gyroscope still" in note[0]) != corrected, note
        if corrected:
            final = [float(v) for v in note[0].split("final offset ")[1].split(" deg/s")[0]
                     .split(", ")]
            # a static log: learning the gyro's mean (the simulated part's own offset and the
            # one added; FusionOffset's low-pass has a time constant of 8 s)
            mean = np.degrees(d.gyr.mean(axis=0)) + [1, -1, 1]
            assert np.all(np.abs(final) > 0.6 * np.abs(mean)) and np.all(
                np.sign(final) == np.sign(mean)), (final, mean)
