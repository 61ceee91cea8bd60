"""Three journeys of one issue ("reads what motion-capture tools export, compares many
recordings at once"), each against today's refusals:

  - a recording in the layout motion-capture and logging tools export (a group row whose
    names span empty cells, then an axis or unit row, ';' and decimal commas) is read by
    every command, with its units from the file, exactly as the same numbers under imufuse's
    own header; a missing column is suggested on its own axis;
  - `imufuse compare LOG...` (files, a folder, a glob) prints each recording's table, equal
    to compare on that recording alone, and the mean over the recordings that
    imufuse.evaluation.mean_over_trials gives (imufuse.comparison.compare_logs from Python);
  - the command line's texts: FusionAHRS among the valid and suggested filters, a --plot
    that cannot be written is exit 3, tune's notes only about what was asked, no carriage
    returns into a file, one "imufuse:" prefix.
"""
import contextlib
import io as _io
import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import imufuse
import imufuse_c
from imufuse import cli, io, sim
from imufuse.cli import common
from imufuse.comparison import compare_logs, log_paths
from imufuse.evaluation import mean_over_trials
from imufuse.session import ReadOptions, RunOptions, Session

pytestmark = pytest.mark.slow

PATHS = [os.path.dirname(os.path.dirname(imufuse.__file__)),
         os.path.dirname(os.path.dirname(imufuse_c.__file__))]
HAVE_MPL = __import__("importlib").util.find_spec("matplotlib") is not None
G = 9.80665

GROUPS = ("Time;Vicon Orientation;;;;IMU Acceleration;;;IMU Gyroscope;;;IMU Magnetometer;;")
AXES = "s;W;X;Y;Z;X;Y;Z;X;Y;Z;X;Y;Z"


def imf(*args, env=None, timeout=300):
    e = dict(os.environ, PYTHONPATH=os.pathsep.join(PATHS + [os.environ.get("PYTHONPATH", "")]),
             MPLBACKEND="Agg", **(env or {}))
    return subprocess.run([sys.executable, "-m", "imufuse", *map(str, args)], env=e,
                          capture_output=True, text=True, timeout=timeout)


def main(*args):
    """The command line in this process: (exit code, stdout, stderr)."""
    out, errs = _io.StringIO(), _io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(errs):
        rc = cli.main([str(a) for a in args])
    return rc, out.getvalue(), errs.getvalue()


def _values(d):
    """The recording as text, 9 significant digits: time s, reference W X Y Z, acc m/s^2,
    gyro deg/s, mag uT (a magnetometer of 50 uT)."""
    rows = np.column_stack([d.t, d.q_true, d.acc * G, np.degrees(d.gyr), d.mag * 50.0])
    return [[f"{v:.9g}" for v in r] for r in rows]


def write_exported(path, d, groups=GROUPS, axes=AXES, units=None):
    """The tools' layout: ';', decimal commas, a group row and an axis row (and a unit row)."""
    with open(path, "w", newline="") as fh:
        fh.write(groups + "\n" + axes + "\n" + (units + "\n" if units else ""))
        for r in _values(d):
            fh.write(";".join(v.replace(".", ",") for v in r) + "\n")
    return path


def write_plain(path, d):
    """The same numbers under imufuse's own one-row header, with the units in it."""
    head = (["time (s)", "q_w", "q_x", "q_y", "q_z"] + [f"acc_{a} (m/s^2)" for a in "xyz"]
            + [f"gyr_{a} (deg/s)" for a in "xyz"] + [f"mag_{a} (uT)" for a in "xyz"])
    with open(path, "w", newline="") as fh:
        fh.write(",".join(head) + "\n")
        for r in _values(d):
            fh.write(",".join(r) + "\n")
    return path


@pytest.fixture(scope="module")
def motion():
    return sim.imu("slow", rate=100.0, duration=8.0, seed=3)


@pytest.fixture(scope="module")
def still():
    return sim.imu("static", rate=100.0, duration=3.0, seed=3)


# ---------------------------------------------------------------------------
# 1. the layout tools export

# where the units are written: the group names, the axis cells, a third row of units
LAYOUTS = {
    "group": ("Time;Vicon Orientation;;;;IMU Acceleration (m/s^2);;;IMU Gyroscope (deg/s);;;"
              "IMU Magnetometer (uT);;", AXES, None),
    "axis": (GROUPS, "s;W;X;Y;Z;X [m/s^2];Y [m/s^2];Z [m/s^2];X (deg/s);Y (deg/s);Z (deg/s);"
             "X (uT);Y (uT);Z (uT)", None),
    "unit row": (GROUPS, AXES, "s;;;;;m/s^2;m/s^2;m/s^2;deg/s;deg/s;deg/s;uT;uT;uT"),
}


@pytest.mark.parametrize("layout", list(LAYOUTS))
def test_the_exported_layout_is_read_with_its_units(tmp_path, motion, layout):
    """Today: "column time: not a number: 's'". Every column is recognised, the units come
    from the file, and the values are those of the same numbers under imufuse's header."""
    p = write_exported(tmp_path / "vicon.csv", motion, *LAYOUTS[layout])
    log = io.read_log(p)
    plain = io.read_log(write_plain(tmp_path / "plain.csv", motion))
    assert log.units["gyr"] == ("deg/s", "header") and log.units["acc"] == ("m/s^2", "header")
    assert log.units["time"] == ("s", "header") and log.units["mag"][0] == "uT"
    assert any("decimal commas" in w for w in log.warnings)
    assert not log.suspicions, log.suspicions
    for a in ("gyr", "acc", "mag", "q_ref", "t"):
        assert np.array_equal(getattr(log, a), getattr(plain, a)), a
    assert np.allclose(log.gyr, motion.gyr, rtol=1e-7, atol=1e-9)
    assert np.allclose(log.acc, motion.acc, rtol=1e-7, atol=1e-9)
    assert np.allclose(log.q_ref, motion.q_true, rtol=1e-7, atol=1e-9)
    assert log.sources["q_w"] == "Vicon Orientation W"
    assert log.sources["gyr_x"].startswith("IMU Gyroscope X")
    assert len(log) == len(motion.t)


def test_the_exact_layout_without_units_takes_them_from_options(tmp_path, motion):
    """The group and axis rows as the issue shows them (no unit but the time's 's'): read,
    the m/s^2 read as g named by the plausibility check, the options give the units."""
    p = write_exported(tmp_path / "vicon.csv", motion)
    log = io.read_log(p)
    assert log.units["time"] == ("s", "header")
    assert any("--acc-unit m/s2" in w for w in log.suspicions), log.suspicions
    given = io.read_log(p, gyr_unit="deg/s", acc_unit="m/s2")
    plain = io.read_log(write_plain(tmp_path / "plain.csv", motion))
    assert np.array_equal(given.gyr, plain.gyr) and np.array_equal(given.acc, plain.acc)


def _same(a, b, pa, pb):
    return a.replace(str(pa), "LOG").replace(os.path.basename(str(pa)), "LOG") == \
        b.replace(str(pb), "LOG").replace(os.path.basename(str(pb)), "LOG")


@pytest.mark.parametrize("command", [
    ["run", "-f", "MadgwickAHRS"],
    ["compare", "-f", "MadgwickAHRS,RobustIMU,FusionAHRS"],
    ["tune", "-f", "MadgwickAHRS", "-g", "beta=0.03,0.1", "--refine", "0", "-j", "1"],
    ["latency"],
    ["validate", "--csrc", "-f", "MadgwickAHRS", "--dtype", "float32", "--log"],
])
def test_every_command_reads_the_exported_layout(tmp_path, motion, command):
    """Each command prints on the exported file what it prints on the same numbers under
    imufuse's header (the file's name aside)."""
    ex = write_exported(tmp_path / "vicon.csv", motion, *LAYOUTS["group"])
    pl = write_plain(tmp_path / "plain.csv", motion)
    name, rest = command[0], command[1:]
    a = imf(name, *rest, ex) if name != "run" else imf(name, ex, *rest)
    b = imf(name, *rest, pl) if name != "run" else imf(name, pl, *rest)
    assert a.returncode == b.returncode == 0, a.stderr + b.stderr
    drop = re.compile(r"samples/s|decimal commas|\d\.\d+e\+\d\d|\(\d+(\.\d+)? s\)")
    if name == "compare":        # samples/s differ from run to run
        a_out = [ln.rsplit(None, 3)[0] for ln in a.stdout.splitlines()[3:]]
        b_out = [ln.rsplit(None, 3)[0] for ln in b.stdout.splitlines()[3:]]
        assert a_out == b_out and len(a_out) == 3
    elif name == "validate":
        assert "bit-exact" in a.stdout and "bit-exact" in b.stdout
    else:
        assert _same(a.stdout, b.stdout, ex, pl), (a.stdout, b.stdout)
    ea = [ln for ln in a.stderr.splitlines() if not drop.search(ln)]
    eb = [ln for ln in b.stderr.splitlines() if not drop.search(ln)]
    assert _same("\n".join(ea), "\n".join(eb), ex, pl), (ea, eb)
    if name == "run":
        assert "against the log's reference q (NWU): total" in a.stderr


def test_calibrate_reads_the_exported_layout(tmp_path, still):
    ex = write_exported(tmp_path / "still.csv", still, *LAYOUTS["unit row"])
    pl = write_plain(tmp_path / "plain.csv", still)
    for p, out in ((ex, "a.json"), (pl, "b.json")):
        r = imf("calibrate", "gyro", p, "-o", tmp_path / out)
        assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "a.json").read_text()) == \
        json.loads((tmp_path / "b.json").read_text())


def test_a_header_row_is_not_taken_from_data(tmp_path):
    """A bad first data row stays a bad row (with its line), a one-row header with units
    under it is read, and what is not the sensor is not taken for it."""
    head = "time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n"
    rows = "".join(f"{k / 100},0,0,0,0,0,1\n" for k in range(1, 50))
    (tmp_path / "bad.csv").write_text(head + "abc,0,0,0,0,0,1\n" + rows)
    with pytest.raises(io.LogError, match=r"bad.csv:2: column time: not a number: 'abc'"):
        io.read_log(tmp_path / "bad.csv")
    (tmp_path / "units.csv").write_text(head + "ms,dps,dps,dps,g,g,g\n"
                                        + "".join(f"{k * 10},57.3,0,0,0,0,1\n" for k in range(50)))
    log = io.read_log(tmp_path / "units.csv")
    assert log.units["time"] == ("ms", "header") and log.units["gyr"] == ("deg/s", "header")
    assert log.dt == pytest.approx(0.01) and log.gyr[0, 0] == pytest.approx(1.0, rel=1e-3)
    # x-io's outputs and two IMUs: never a silent choice
    assert io.recognise(["Earth Acceleration X", "Linear Acceleration Y"]) == {}
    assert io.recognise(["Orientation X", "Orientation Y", "Orientation Z"]) == {}
    two = ["Time (s)", "IMU1 Gyroscope X", "IMU2 Gyroscope X"]
    assert io.duplicate_columns(two) == {"gyr_x": [1, 2]}
    (tmp_path / "two.csv").write_text("Time;IMU1 Gyroscope;;;IMU2 Gyroscope;;\ns;X;Y;Z;X;Y;Z\n"
                                      + "".join(f"{k / 100};0;0;0;0;0;0\n" for k in range(9)))
    with pytest.raises(io.LogError, match="are both gyr_x"):
        io.read_log(tmp_path / "two.csv")


@pytest.mark.parametrize("names,unit", [
    (["AccX_g", "AccY_g", "AccZ_g"], "g"),
    (["acc_x_mps2", "acc_y_mps2", "acc_z_mps2"], "m/s^2"),
    (["Accel-X m/s2", "Accel-Y m/s2", "Accel-Z m/s2"], "m/s^2"),
])
def test_a_unit_after_the_name_is_read(tmp_path, names, unit):
    """'AccX_g' was "missing columns acc_x (did you mean 'AccY_g' or 'AccZ_g'?)": it is
    acc_x, in g."""
    p = tmp_path / "x.csv"
    p.write_text("time,gx,gy,gz," + ",".join(names) + "\n"
                 + "".join(f"{k / 100},0,0,0,0,0,9.80665\n" for k in range(20)))
    log = io.read_log(p)
    io.require(log, io.ACC)
    assert log.units["acc"] == (unit, "header")
    assert log.acc[0, 2] == pytest.approx(9.80665 if unit == "g" else 1.0)


@pytest.mark.parametrize("names", [
    ["AccX_raw", "AccY_raw", "AccZ_raw"],
    ["AccelX_lsb", "AccelY_lsb", "AccelZ_lsb"],
    ["Acc Z counts", "Acc Y counts", "Acc X counts"],
])
def test_a_missing_column_is_suggested_on_its_axis(tmp_path, names):
    p = tmp_path / "x.csv"
    p.write_text("time,gx,gy,gz," + ",".join(names) + "\n"
                 + "".join(f"{k / 100},0,0,0,0,0,1\n" for k in range(20)))
    log = io.read_log(p)
    with pytest.raises(io.LogError) as e:
        io.require(log, io.ACC)
    msg = str(e.value)
    for axis in "xyz":
        want = next(n for n in names if re.search(axis, n, re.I))
        assert f"acc_{axis} (did you mean {want!r}?)" in msg, msg


# ---------------------------------------------------------------------------
# 2. compare over many recordings

@pytest.fixture(scope="module")
def trials(tmp_path_factory):
    d = tmp_path_factory.mktemp("trials")
    paths = []
    for seed in (1, 2, 3):
        m = sim.imu("slow", rate=100.0, duration=5.0, seed=seed)
        p = d / f"trial{seed}.csv"
        io.write_log(p, m.t, m.gyr, m.acc, m.mag, m.q_true)
        paths.append(p)
    return paths


FILTERS = "MadgwickAHRS,MahonyIMU,FusionAHRS,Kalman1D"


def _rows(text):
    """{(log, filter): the row's cells without samples/s and the note} of compare's tables;
    {filter: cells} of the mean table under the key (None, filter)."""
    out, log = {}, None
    for ln in text.splitlines():
        if ln.startswith("mean over"):
            log = None
        elif re.match(r"^\S+: \d+ samples", ln):
            log = ln.split(": ")[0]
        elif re.match(r"^[A-Z]\w+\s+(imu|ahrs|1d)\s", ln):
            cells = ln.split()
            out[(log, cells[0])] = cells[1:6] if log else cells[1:6]
    return out


def test_compare_many_logs_equals_each_alone_and_their_mean(trials):
    """Today: "unrecognized arguments". Each log's rows are compare's on that log alone;
    the means are mean_over_trials of the per-log evaluations."""
    rc, out, errs = main("compare", *trials, "-f", FILTERS)
    assert rc == 0, errs
    many = _rows(out)
    for p in trials:
        rc1, out1, _ = main("compare", p, "-f", FILTERS)
        assert rc1 == 0
        for k, v in _rows(out1).items():
            assert many[k] == v, (k, many[k], v)
    c = compare_logs(trials, FILTERS.split(","))
    assert [lg.path for lg in c.logs] == [str(p) for p in trials]
    means = c.means()
    for name in ("MadgwickAHRS", "MahonyIMU", "FusionAHRS"):
        evs = c.evaluations(name)
        assert len(evs) == 3 and means[name] == mean_over_trials(evs)
        shown = many[(None, name)]
        assert float(shown[1]) == pytest.approx(means[name]["inclination"], abs=5e-4)
        if name != "MahonyIMU":
            assert float(shown[3]) == pytest.approx(means[name]["total"], abs=5e-4)
    k = [lg.results["Kalman1D"].evaluation["angle"][0] for lg in c.logs]
    assert means["Kalman1D"]["angle"] == pytest.approx(np.mean(k), rel=1e-15)
    # a log's numbers are those of the session on that log alone
    s = Session(str(trials[1]))
    ev = s.score(s.run("MadgwickAHRS", {}, RunOptions()))
    assert c.logs[1].results["MadgwickAHRS"].evaluation.total == ev.total


def test_a_folder_and_a_glob_are_the_logs_in_them(trials, tmp_path):
    rc, want, _ = main("compare", *trials, "-f", "MadgwickIMU")
    folder = os.path.dirname(trials[0])
    for spec in ([folder], [os.path.join(folder, "trial*.csv")],
                 [trials[0], os.path.join(folder, "trial[23].csv")]):
        rc, out, errs = main("compare", *spec, "-f", "MadgwickIMU")
        assert rc == 0, errs
        assert _rows(out) == _rows(want) and out.count(" samples, ") == 3
    assert log_paths(folder) == [str(p) for p in trials]
    c = compare_logs(os.path.join(folder, "*.csv"), ["MadgwickIMU"],
                     read=ReadOptions(strict=True))
    assert len(c.logs) == 3


@pytest.mark.parametrize("given,word", [
    (["MISSING.csv"], "MISSING.csv: no such file"),
    (["nothing*.csv"], "nothing*.csv: no file matches"),
    (["emptydir"], "emptydir: a folder without logs"),
])
def test_a_log_that_is_not_there_is_exit_3_naming_it(trials, tmp_path, given, word):
    (tmp_path / "emptydir").mkdir()
    args = [str(tmp_path / g) for g in given]
    rc, out, errs = main("compare", trials[0], *args, "-f", "MadgwickIMU")
    assert rc == 3 and word in errs and out == "", errs


def test_an_unreadable_log_among_several_is_exit_4_naming_it(trials, tmp_path):
    """The logs before it are shown; no mean over fewer logs than given."""
    bad = tmp_path / "bad.csv"
    bad.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,1\n0.01,0,x,0,0,0,1\n")
    rc, out, errs = main("compare", trials[0], bad, trials[1], "-f", "MadgwickIMU")
    assert rc == 4 and f"{bad}:3: column gyr_y: not a number" in errs, errs
    assert str(trials[0]) in out and str(trials[1]) not in out and "mean over" not in out


@pytest.mark.skipif(not HAVE_MPL, reason="matplotlib (the plot extra)")
def test_compare_many_plots_bars(trials, tmp_path):
    rc, out, errs = main("compare", *trials, "-f", "MadgwickAHRS,MahonyIMU",
                         "--plot", tmp_path / "bars.png")
    assert rc == 0, errs
    assert (tmp_path / "bars.png").stat().st_size > 10000
    assert f"imufuse: plot: {tmp_path / 'bars.png'}" in errs


# ---------------------------------------------------------------------------
# 3. the command line's texts

@pytest.mark.parametrize("command", ["run", "compare"])
@pytest.mark.parametrize("given,want", [
    ("Fusion", ["FusionAHRS"]), ("fusion", ["FusionAHRS"]),
    ("madgwick", ["MadgwickIMU", "MadgwickAHRS"]), ("Madgwik", ["MadgwickIMU"]),
])
def test_filter_names_suggest_fusion_ahrs(command, given, want):
    log = io.example_log()
    args = ["run", log, "-f", given, "-o", "-"] if command == "run" else \
        ["compare", log, "-f", given]
    rc, out, errs = main(*args)
    assert rc == 2, errs
    hinted = errs.split("did you mean ")[1].split("?")[0].split(", ")
    assert set(want) <= set(hinted), errs
    assert errs.rstrip().endswith("RobustAHRS, FusionAHRS, FusionAHRS13"), errs


def test_fixed_point_and_fusion_suite_names_list_fusion_ahrs():
    rc, _, errs = main("compare", io.example_log(), "-f", "MadgwickIMUQ")
    assert rc == 2 and "fixed-point" in errs and "FusionAHRS" in errs


HIDE_MPL = "import sys; sys.modules['matplotlib'] = None; from imufuse.cli import main; "


@pytest.mark.parametrize("command", [
    ["run", "LOG", "-f", "MadgwickIMU", "-o", "OUT/o.csv", "--plot", "OUT/p.png"],
    ["compare", "LOG", "-f", "MadgwickIMU", "--plot", "OUT/p.png"],
    ["compare", "LOG", "LOG2", "-f", "MadgwickIMU", "--plot", "OUT/p.png"],
    ["vario", "VARIO", "-o", "OUT/v.csv", "--plot", "OUT/p.png"],
    ["validate", "--csrc", "-f", "Kalman1D", "--duration", "1", "--plot", "OUT/p.png"],
])
def test_a_plot_without_matplotlib_is_exit_3(tmp_path, trials, command):
    """Today: a message, exit 0 and no file."""
    vario = tmp_path / "vario.csv"
    m = sim.imu("slow", rate=100.0, duration=2.0, seed=1)
    with open(vario, "w") as fh:
        fh.write("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,pressure\n")
        for k in range(len(m.t)):
            fh.write(",".join(repr(float(v)) for v in (m.t[k], *m.gyr[k], *m.acc[k]))
                     + (",101325\n" if k % 4 == 0 else ",\n"))
    out = tmp_path / "out"
    out.mkdir()
    subs = {"LOG": str(trials[0]), "LOG2": str(trials[1]), "VARIO": str(vario)}
    argv = [subs.get(a, a.replace("OUT", str(out))) for a in command]
    code = HIDE_MPL + f"sys.exit(main({argv!r}))"
    e = dict(os.environ, PYTHONPATH=os.pathsep.join(PATHS))
    r = subprocess.run([sys.executable, "-c", code], env=e, capture_output=True, text=True)
    assert r.returncode == 3, r.stderr
    assert f"imufuse: error: --plot {out / 'p.png'}: cannot write: matplotlib is not " \
           "installed" in r.stderr
    assert not (out / "p.png").exists()


def test_tune_notes_only_what_was_asked():
    """Today every tune printed "not varied (no effect with these settings): acc_1g"."""
    log = io.example_log()
    rc, out, errs = main("tune", log, "-f", "MadgwickIMU", "--refine", "0", "-j", "1")
    assert rc == 0 and "9 parameter sets" in out
    assert "note" not in errs and "acc_1g" not in errs, errs
    rc, out, errs = main("tune", log, "-f", "MadgwickIMU", "--refine", "0", "-j", "1",
                         "-g", "acc_1g=0.5,2", "-g", "beta=0.05,0.1")
    assert rc == 0 and "imufuse: note: --grid acc_1g: no effect" in errs, errs


def test_no_carriage_returns_into_a_file():
    """tune's bar only on a terminal; a long run's progress a line at each tenth."""
    r = imf("tune", io.example_log(), "-f", "MadgwickIMU", "--refine", "0", "-j", "1")
    assert r.returncode == 0 and "\r" not in r.stderr and "tune: [" not in r.stderr, r.stderr
    errs = _io.StringIO()
    with contextlib.redirect_stderr(errs):
        for k in range(1, 21):                 # about 20 reports, as a long run makes
            common.progress("X", k * 1250, 25000)
        for k in range(1, 21):                 # a second run of the same filter
            common.progress("X", k * 1250, 25000)
    lines = errs.getvalue().splitlines()
    assert "\r" not in errs.getvalue() and len(lines) == 20, lines
    assert lines[0] == "imufuse: X: 10% (2500/25000 samples)" and lines[9].startswith(
        "imufuse: X: 100%") and lines[10].startswith("imufuse: X: 10%")

    class Tty(_io.StringIO):
        def isatty(self):
            return True
    tty = Tty()
    with contextlib.redirect_stderr(tty):
        common.progress("X", 1250, 25000)
        common.progress("X", 25000, 25000)
    assert tty.getvalue() == ("\rimufuse: X: 5% (1250/25000 samples)"
                              "\rimufuse: X: 100% (25000/25000 samples)\n")


@pytest.mark.skipif(not HAVE_MPL, reason="matplotlib (the plot extra)")
def test_every_message_has_one_prefix(tmp_path):
    """Today the demo said `plot: ...` on stdout, then `imufuse: plot: ...`."""
    r = imf("demo", "--out", tmp_path, "--duration", "2", "--filter", "Kalman1D,MadgwickIMU")
    assert r.returncode == 0, r.stderr
    assert not re.search(r"^plot", r.stdout, re.M), r.stdout
    plots = [ln for ln in r.stderr.splitlines() if "plot: " in ln]
    assert len(plots) == 3 and all(ln.startswith("imufuse: plot: ") for ln in plots), plots
    assert all(ln.startswith("imufuse: ") for ln in r.stderr.splitlines()), r.stderr


def test_the_docs_example_of_many_recordings_runs():
    """docs/logs.md's compare_logs example, as written."""
    docs = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "logs.md")
    block = next(b for b in re.findall(r"```python\n(.*?)```", open(docs).read(), re.S)
                 if "compare_logs" in b)
    exec(compile(block, "docs/logs.md", "exec"), {})
