"""Files a user owns and repeated options (issue 44, round three): concurrent writers of one
calibration file keep every section (the merge holds a lock), the Arduino zip is never
overwritten; a bad calibration file or column map is one line naming the file with exit 4
(never 2 or 6), the Python API raising CalibrationError / LogError; an option's name given
twice is a usage error (exit 2) naming the option and the name. docs/robustness.md."""
import errno
import json
import multiprocessing
import os
import time

import numpy as np
import pytest

import imufuse
from imufuse import cli, io, sim
from imufuse.tools.arduino import export_arduino
from imufuse.calibration import CalibrationError, load_calibration, mag_offset, save_calibration
from imufuse.calibration.fit import Calibration as Fitted
from imufuse.calibration import log as callog
from imufuse.calibration.log import save, save_mag_offset
from imufuse.io import LogError, parse_column_map, read_column_map

# the exit codes documented in imufuse.cli
OK, USAGE, FILE, DATA = 0, 2, 3, 4


def one_line(capsys, rc, code, *words):
    """Exit `code`, one "imufuse: error:" line on stderr holding every word, no traceback."""
    err = capsys.readouterr().err
    assert rc == code, (rc, err[-2000:])
    lines = [ln for ln in err.splitlines() if ln.startswith(("imufuse: error:",
                                                             "imufuse: internal error"))]
    assert len(lines) == 1 and "Traceback" not in err, err
    for w in words:
        assert str(w) in lines[0], (w, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """An IMU log with a reference orientation, and a still gyroscope log (deg/s)."""
    d = tmp_path_factory.mktemp("logs")
    data = sim.imu("slow", rate=100.0, duration=4.0, seed=4)
    imu = d / "imu.csv"
    io.write_log(imu, data.t, data.gyr, data.acc, data.mag, data.q_true)
    g = np.random.default_rng(0).normal(0, 0.1, (300, 3)) + np.array([0.5, -1.2, 0.3])
    gyr = d / "gyr.csv"
    gyr.write_text("gyr_x,gyr_y,gyr_z\n" + "".join(",".join(map(repr, r.tolist())) + "\n" for r in g))
    return {"imu": imu, "gyr": gyr}


# ---- 1. writers never lose data ------------------------------------------------------------

ROUNDS = 20
H = (12.5, -3.25, 40.0)


def _writer(which, folder, barrier):
    """One of two processes: each round, both start together on a new file, one saving the
    gyroscope section, the other the magnetometer offset. The check of the merged data
    between the read and the write takes 20 ms here (a slow disk, a busy machine), so that
    without the lock both processes read before either writes in every round."""
    real = callog.from_dict

    def slow(data, source=""):
        time.sleep(0.02)
        return real(data, source)
    callog.from_dict = slow
    gyro = Fitted("gyro", dict(M=np.eye(3), s=np.ones(3), b=np.array([0.01, -0.02, 0.03])))
    for k in range(ROUNDS):
        path = os.path.join(folder, f"calib{k}.json")
        barrier.wait(timeout=60)
        if which == "gyro":
            save(path, gyro)
        else:
            save_mag_offset(path, H)


def test_concurrent_writers_keep_every_section(tmp_path):
    """2 processes x 20 rounds merge different sections into one file at the same moment:
    every section is there after every round (without the lock, one was lost in every
    round)."""
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(2)
    procs = [ctx.Process(target=_writer, args=(w, str(tmp_path), barrier))
             for w in ("gyro", "mag")]
    for p in procs:
        p.start()
    for p in procs:
        p.join(300)
    assert [p.exitcode for p in procs] == [0, 0]
    lost = []
    for k in range(ROUNDS):
        data = json.loads((tmp_path / f"calib{k}.json").read_text())
        if set(data) != {"gyroscope", "magnetometer"}:
            lost.append((k, sorted(data)))
    assert not lost, lost
    assert mag_offset(tmp_path / f"calib{ROUNDS - 1}.json") == H


def test_save_calibration_is_whole_or_nothing(tmp_path, monkeypatch):
    """A write that fails half way (a full disk) leaves the previous calibration file as it
    was: save_calibration writes beside it and renames."""
    p = tmp_path / "c.json"
    save_calibration(p, {"magnetometer": {"h": [1, 2, 3]}})
    before = p.read_bytes()

    def full_disk(obj, fh, **kw):
        fh.write("{\n  \"gyr")
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(json, "dump", full_disk)
    with pytest.raises(OSError, match="No space"):
        save_calibration(p, {"gyroscope": {"b": [0.1, 0.2, 0.3]}})
    monkeypatch.undo()
    assert p.read_bytes() == before
    assert [f.name for f in tmp_path.iterdir() if not f.name.endswith(".lock")] == ["c.json"]
    assert load_calibration(p).magnetometer["h"].tolist() == [1, 2, 3]


def test_export_refuses_an_existing_zip(tmp_path):
    """An existing DIR/imufuse-VERSION.zip is refused like an existing DIR/imufuse, before
    anything is written: the zip keeps its bytes, no library directory is made."""
    z = tmp_path / f"imufuse-{imufuse.__version__}.zip"
    z.write_bytes(b"my own zip")
    with pytest.raises(FileExistsError, match="zip exists"):
        export_arduino(tmp_path, make_zip=True)
    assert z.read_bytes() == b"my own zip" and not (tmp_path / "imufuse").exists()


def test_export_cli_refuses_an_existing_zip_or_directory(tmp_path, capsys):
    """`imufuse export arduino DIR --zip`: an existing zip is exit 3 naming it, as an existing
    directory is; with the directory there, no zip is written either."""
    z = tmp_path / f"imufuse-{imufuse.__version__}.zip"
    z.write_bytes(b"mine")
    one_line(capsys, cli.main(["export", "arduino", str(tmp_path), "--zip"]), FILE, z.name,
             "exists")
    assert z.read_bytes() == b"mine" and not (tmp_path / "imufuse").exists()
    other = tmp_path / "other"
    (other / "imufuse").mkdir(parents=True)
    one_line(capsys, cli.main(["export", "arduino", str(other), "--zip"]), FILE, "exists")
    assert os.listdir(other) == ["imufuse"]


def test_export_cli_refuses_a_file_as_its_directory(tmp_path, capsys):
    """`imufuse export arduino FILE`: exit 3 saying FILE is a file; it read
    "FILE/imufuse/src/fixed: Not a directory"."""
    f = tmp_path / "log.csv"
    f.write_text("time\n")
    one_line(capsys, cli.main(["export", "arduino", str(f)]), FILE,
             f"{f}: is a file, not a directory")
    assert f.read_text() == "time\n"


# ---- 2. bad files: one line naming the file, exit 4 -------------------------------------------

GOOD = b'{"magnetometer": {"S": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "h": [1, 2, 3]}}'
#: name -> (contents, words of the message)
BAD = {
    "latin1": (b'{"magn\xe9tometer": {"h": [1, 2, 3]}}', ["not UTF-8", "0xe9", "offset 6"]),
    "deep": (b"[" * 100000, ["nested deeper than"]),
    "huge": (GOOD + b" " * (2 << 20), ["too large", "1 MiB"]),
    "syntax": (b'{"magnetometer": {"h": [1, 2, 3]},\n}', ["not valid JSON", "line 2"]),
    "array": (b"[[1, 0, 0], [0, 1, 0]]", ["JSON object", "array"]),
    "repeated": (b'{"magnetometer": {"h": [1, 2, 3]}, "magnetometer": {"h": [0, 0, 0]}}',
                 ["'magnetometer' given twice"]),
    "long_int": (b'{"magnetometer": {"h": [1' + b"0" * 5000 + b", 0, 0]}}", ["digits"]),
    # another sensor's section: the one being saved would be replaced
    "overflow": (b'{"accelerometer": {"b": [1' + b"0" * 400 + b", 0, 0]}}",
                 ["accelerometer.b", "expected numbers"]),
}


@pytest.fixture
def bad(tmp_path, request):
    contents, words = BAD[request.param]
    p = tmp_path / f"{request.param}.json"
    p.write_bytes(contents)
    return p, words


@pytest.mark.parametrize("bad", sorted(BAD), indirect=True)
def test_run_with_a_bad_calibration_file(logs, tmp_path, capsys, bad):
    p, words = bad
    rc = cli.main(["run", str(logs["imu"]), "-f", "MadgwickIMU", "--calibration", str(p),
                   "-o", str(tmp_path / "out.csv")])
    one_line(capsys, rc, DATA, p, *words)
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("bad", sorted(BAD), indirect=True)
def test_compare_with_a_bad_calibration_file(logs, capsys, bad):
    p, words = bad
    rc = cli.main(["compare", str(logs["imu"]), "-f", "MadgwickIMU", "--calibration", str(p)])
    one_line(capsys, rc, DATA, p, *words)


@pytest.mark.parametrize("bad", sorted(BAD), indirect=True)
def test_calibrate_into_a_bad_file(logs, capsys, bad):
    """-o into an existing bad file: refused naming it, the file left as it was."""
    p, words = bad
    before = p.read_bytes()
    rc = cli.main(["calibrate", "gyro", str(logs["gyr"]), "-o", str(p), "--gyr-unit", "deg/s"])
    one_line(capsys, rc, DATA, p, *words)
    assert p.read_bytes() == before


@pytest.mark.parametrize("bad", sorted(BAD), indirect=True)
def test_the_api_raises_calibration_error(bad):
    """load_calibration, mag_offset(path) and save (the merge) raise CalibrationError naming
    the file; save writes nothing."""
    p, words = bad
    before = p.read_bytes()
    for call in (lambda: load_calibration(p), lambda: mag_offset(p),
                 lambda: save_mag_offset(p, (1.0, 2.0, 3.0))):
        with pytest.raises(CalibrationError) as e:
            call()
        assert str(p) in str(e.value) and e.value.kind == "data", str(e.value)
        for w in words:
            assert w in str(e.value), (w, str(e.value))
    assert p.read_bytes() == before


def test_a_missing_calibration_file_is_exit_3(logs, tmp_path, capsys):
    missing = tmp_path / "nowhere.json"
    rc = cli.main(["run", str(logs["imu"]), "-f", "MadgwickIMU", "--calibration", str(missing),
                   "-o", str(tmp_path / "out.csv")])
    one_line(capsys, rc, FILE, missing, "No such file")
    with pytest.raises(CalibrationError) as e:
        load_calibration(missing)
    assert e.value.kind == "file"


def test_a_calibration_file_with_a_byte_order_mark_is_read(tmp_path):
    p = tmp_path / "bom.json"
    p.write_bytes(b"\xef\xbb\xbf" + GOOD)
    assert mag_offset(p) == (1.0, 2.0, 3.0)


#: the column map's faults (JSON form): name -> (contents, words)
BAD_MAP = {
    "latin1": (b'{"gyr_x": "Gyro X (\xb0/s)"}', ["not UTF-8", "0xb0", "offset 19"]),
    "deep": (b'{"gyr_x": ' + b"[" * 100000, ["nested deeper than"]),
    "huge": (b'{"gyr_x": "gyr_x"}' + b" " * (2 << 20), ["too large", "1 MiB"]),
    "syntax": (b'{"gyr_x": "gyr_x",\n "gyr_y": }', ["not valid JSON", "line 2"]),
    "array": (b'{"gyr_x": ["gyr_x"]}', ["name: header strings"]),
}


@pytest.mark.parametrize("name", sorted(BAD_MAP))
def test_bad_column_map_file(logs, tmp_path, capsys, name):
    contents, words = BAD_MAP[name]
    p = tmp_path / f"{name}.json"
    p.write_bytes(contents)
    rc = cli.main(["run", str(logs["imu"]), "-f", "MadgwickIMU", "--column-map", str(p),
                   "-o", str(tmp_path / "out.csv")])
    one_line(capsys, rc, DATA, p, *words)
    rc = cli.main(["calibrate", "gyro", str(logs["gyr"]), "-o", str(tmp_path / "c.json"),
                   "--column-map", str(p)])
    one_line(capsys, rc, DATA, p, *words)
    with pytest.raises(LogError) as e:
        read_column_map(p)
    assert e.value.kind == "data" and str(p) in str(e.value)


def test_a_line_column_map_not_utf8_names_the_byte(logs, tmp_path, capsys):
    p = tmp_path / "map.txt"
    p.write_bytes(b"gyr_x = gyr_x\n# \xff\n")
    rc = cli.main(["run", str(logs["imu"]), "-f", "MadgwickIMU", "--column-map", str(p),
                   "-o", str(tmp_path / "out.csv")])
    one_line(capsys, rc, DATA, p, "not UTF-8", "0xff", "offset 16", "line 2")


# ---- 3. repeated options: exit 2 naming the option and the name --------------------------------

def _files(tmp_path):
    (tmp_path / "map.txt").write_text("gyr_x = gyr_x\ngyr_y = gyr_y\ngyr_x = gyr_z\n")
    (tmp_path / "map.json").write_text('{"gyr_x": "gyr_x", "gyr_x": "gyr_y"}')
    (tmp_path / "one.txt").write_text("gyr_x = gyr_x\n")
    (tmp_path / "fw.c").write_text("void upd(float *s, float r, float a) { *s = r + a; }\n")
    (tmp_path / "fw.h").write_text("void upd(float *s, float r, float a);\n")


RUN = ["run", "{imu}", "-f", "MadgwickIMU", "-o", "{tmp}/out.csv"]
COMPARE = ["compare", "{imu}", "-f", "MadgwickIMU,MahonyIMU"]
TUNE = ["tune", "{imu}", "-f", "MadgwickIMU", "--refine", "0", "-q"]
VALIDATE = ["validate", "{tmp}/fw.c", "-f", "Kalman1D", "--update", "upd"]
REPEATED = [
    (TUNE + ["--grid", "beta=0.01", "--grid", "beta=0.05"], ["--grid beta", "twice"]),
    (TUNE + ["--grid", "beta=0.01:1:3", "-g", "beta=0.2"], ["--grid beta", "twice"]),
    (TUNE + ["--grid", "beta=0.01,0.05", "--param", "beta=0.1"], ["--grid beta", "--param"]),
    (TUNE + ["-p", "beta=0.1", "-p", "beta=0.2"], ["--param beta", "twice"]),
    (RUN + ["--param", "beta=0.1", "--param", "beta=0.2"], ["--param beta", "twice"]),
    (RUN + ["-p", "beta=0.1", "-p", " beta =0.1"], ["--param beta", "twice"]),
    (COMPARE + ["-p", "MadgwickIMU.beta=0.1", "-p", "MadgwickIMU.beta=0.2"],
     ["--param MadgwickIMU.beta", "twice"]),
    (COMPARE + ["-p", "madgwickimu.beta=0.1", "-p", "MadgwickIMU.beta=0.2"],
     ["beta of MadgwickIMU"]),
    (COMPARE + ["-p", "beta=0.1", "-p", "MadgwickIMU.beta=0.2"], ["beta of MadgwickIMU"]),
    (COMPARE + ["-p", "kp=1", "-p", "MahonyIMU.kp=2"], ["kp of MahonyIMU"]),
    (COMPARE + ["-f", "MadgwickIMU"], ["--filter MadgwickIMU", "twice"]),
    (["compare", "{imu}", "-f", "MadgwickIMU,madgwickimu"], ["--filter MadgwickIMU"]),
    (RUN + ["--columns", "gyr_x=gyr_x", "--columns", "gyr_x=gyr_y"], ["--columns", "'gyr_x'"]),
    (RUN + ["-c", "gyr_x=gyr_x,acc_x=acc_x,gyr_x=gyr_y"], ["--columns", "'gyr_x' named twice"]),
    (RUN + ["--column-map", "{tmp}/one.txt", "-c", "gyr_x=gyr_y"],
     ["--columns gyr_x", "--column-map", "one.txt"]),
    (RUN + ["--column-map", "{tmp}/map.txt"], ["--column-map", "map.txt:3", "'gyr_x'"]),
    (RUN + ["--column-map", "{tmp}/map.json"], ["--column-map", "map.json", "'gyr_x'"]),
    (["calibrate", "gyro", "{imu}", "-o", "{tmp}/c.json", "-c", "gyr_y=gyr_x",
      "-c", "gyr_y=gyr_z"], ["--columns", "'gyr_y'"]),
    (["vario", "{imu}", "-o", "{tmp}/v.csv", "--no-plot", "--kf", "var_z=1", "--kf",
      "var_z=2"], ["--kf var_z", "twice"]),
    (["vario", "{imu}", "-o", "{tmp}/v.csv", "--no-plot", "-p", "beta=0.1", "-p", "beta=0.2"],
     ["--param beta"]),
    (["vario", "{imu}", "-o", "{tmp}/v.csv", "--no-plot", "--acc-gate", "0.6", "1.4",
      "-p", "acc_gate=(0.5,1.5)"], ["--acc-gate", "acc_gate"]),
    (VALIDATE + ["--state", "theta=x", "--state", "theta=y"], ["--state theta", "twice"]),
    (VALIDATE + ["--init-arg", "k0=1", "--init-arg", "k0=2"], ["--init-arg k0", "twice"]),
    (VALIDATE + ["-p", "k0=0.1", "-p", "k0=0.2"], ["--param k0", "twice"]),
    (VALIDATE + ["-D", "N=1", "-D", "N=2"], ["-D N", "twice"]),
    (VALIDATE + ["-I", "{tmp}", "-I", "{tmp}"], ["-I", "twice"]),
    (VALIDATE + ["--header", "fw.h", "-I", "{tmp}", "--header", "fw.h"],
     ["--header fw.h", "twice"]),
    (["demo", "--filter", "MadgwickIMU", "--filter", "madgwickimu", "--no-plot", "--no-real",
      "--duration", "1", "--out", "{tmp}/demo"], ["--filter MadgwickIMU", "twice"]),
    (["bench", "-f", "MadgwickIMU,MadgwickIMU", "--samples", "1000", "--ref-samples", "10",
      "--repeat", "1"], ["--filter MadgwickIMU", "twice"]),
]


@pytest.mark.parametrize("argv,words", REPEATED, ids=[f"{k}-{a[0]}" for k, (a, _) in enumerate(REPEATED)])
def test_a_name_given_twice_is_a_usage_error(logs, tmp_path, capsys, argv, words):
    _files(tmp_path)
    argv = [a.format(imu=logs["imu"], tmp=tmp_path) for a in argv]
    one_line(capsys, cli.main(argv), USAGE, *(w.format(tmp=tmp_path) for w in words))
    assert not (tmp_path / "out.csv").exists() and not (tmp_path / "c.json").exists()


def test_the_api_refuses_a_column_named_twice(tmp_path):
    with pytest.raises(LogError, match="'gyr_x' named twice") as e:
        parse_column_map('gyr_x="Gyro X",gyr_y=gy,gyr_x=gx')
    assert e.value.kind == "usage"
    _files(tmp_path)
    for name, where in (("map.txt", "map.txt:3"), ("map.json", "map.json")):
        with pytest.raises(LogError, match="'gyr_x'") as e:
            read_column_map(tmp_path / name)
        assert e.value.kind == "usage" and where in str(e.value)
