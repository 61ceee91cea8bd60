"""Real logs end to end: what sensors write (x-io's header with units, BOM,
semicolons, tabs, decimal commas), column maps, NPZ in the BROAD layout, the
shipped BROAD excerpt through `compare --ref-frame ENU` against an independent
implementation of the metrics, per-sample dt and init="first" in the CLI, and
the plots' colours."""
import codecs
import json
import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import imufuse
import imufuse_c
from imufuse import io, sim
from imufuse.io import LogError, read_log

PATHS = [os.path.dirname(os.path.dirname(imufuse.__file__)),
         os.path.dirname(os.path.dirname(imufuse_c.__file__))]
HAVE_MPL = __import__("importlib").util.find_spec("matplotlib") is not None
XIO = ["Time (s)", "Gyroscope X (deg/s)", "Gyroscope Y (deg/s)", "Gyroscope Z (deg/s)",
       "Accelerometer X (g)", "Accelerometer Y (g)", "Accelerometer Z (g)",
       "Magnetometer X (uT)", "Magnetometer Y (uT)", "Magnetometer Z (uT)"]


def imf(*args, cwd=None, timeout=300):
    e = dict(os.environ, MPLBACKEND="Agg")
    e["PYTHONPATH"] = os.pathsep.join(PATHS + [e.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-m", "imufuse", *map(str, args)], cwd=cwd, env=e,
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def data():
    d = sim.imu("slow", rate=100.0, duration=3.0, seed=7)
    # x-io's log has jitter: intervals of 7.6 to 30.2 ms
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.0076, 0.0302, len(d.t)))
    return d, t


def write_xio(path, d, t, delim=",", bom=b"", decimal_comma=False, quote=True):
    rows = np.column_stack([t, np.degrees(d.gyr), d.acc, 50 * d.mag])
    q = '"' if quote else ""
    head = delim.join(f"{q}{h}{q}" for h in XIO)
    with open(path, "wb") as fh:
        fh.write(bom + head.encode() + b"\n")
        for r in rows:
            s = delim.join(repr(float(v)) for v in r)
            fh.write((s.replace(".", ",") if decimal_comma else s).encode() + b"\n")


@pytest.mark.parametrize("delim,bom,dc", [(",", b"", False), (";", codecs.BOM_UTF8, True),
                                          ("\t", b"", True), ("|", codecs.BOM_UTF8, False)])
def test_xio_headers_units_and_formats(tmp_path, data, delim, bom, dc):
    d, t = data
    p = tmp_path / "sensor_data.csv"
    write_xio(p, d, t, delim, bom, dc)
    log = read_log(p)
    assert log.sources["gyr_x"] == "Gyroscope X (deg/s)"
    assert log.units["gyr"] == ("deg/s", "header") and log.units["acc"] == ("g", "header")
    assert log.units["mag"][0] == "uT"
    assert np.allclose(log.gyr, d.gyr, rtol=1e-12, atol=1e-15)      # deg/s -> rad/s
    assert np.array_equal(log.acc, d.acc) and np.array_equal(log.columns["time"], t)
    assert not log.fixed_rate and np.array_equal(log.dts[1:], np.diff(t))
    if dc:
        assert any("decimal commas" in w for w in log.warnings)


@pytest.mark.parametrize("delim", [";", "\t", " "])
def test_decimal_commas_after_a_first_row_of_integers(tmp_path, delim):
    """A log whose first row holds only integers ("0;0;0;0;0;0;1", a logger's start): its
    decimal commas were looked for in that row alone, and the second row failed with
    "column time: not a number: '0,01'"."""
    p = tmp_path / "dc.csv"
    rows = [["0", "0", "0", "0", "0", "0", "1"]] + [
        [f"{k / 100:.2f}", "0,125", "-0,25", "0", "0,01", "0", "0,99"] for k in range(1, 20)]
    p.write_text(delim.join(["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z"])
                 + "\n" + "".join(delim.join(c.replace(".", ",") for c in r) + "\n"
                                   for r in rows))
    log = read_log(p)
    assert any("decimal commas ('0,01') read as decimal points" in w for w in log.warnings), \
        log.warnings
    assert log.columns["time"][1] == 0.01 and log.gyr[1, 1] == -0.25 and log.acc[5, 2] == 0.99


def test_run_xio_log_needs_no_renaming_and_honours_timestamps(tmp_path, data):
    """`imufuse run sensor_data.csv -f MadgwickAHRS -o out.csv`: columns and
    units from the header, each sample with its own interval, start from the
    first sample; equal bit for bit to the library called by hand."""
    d, t = data
    p = tmp_path / "sensor_data.csv"
    write_xio(p, d, t)
    out = tmp_path / "out.csv"
    r = imf("run", p, "-f", "MadgwickAHRS", "-o", out)
    assert r.returncode == 0, r.stderr
    assert "init=first" in r.stderr and "dt per sample" in r.stderr
    assert "beta=0.1" in r.stderr           # the parameters really used, never "()"
    head = open(out).readline().strip().split(",")
    assert head == ["time", "q0", "q1", "q2", "q3", "roll_deg", "pitch_deg", "yaw_deg"]
    M = np.loadtxt(out, delimiter=",", skiprows=1)
    log = read_log(p)
    dts = np.concatenate([[log.dt], np.diff(t)])
    f = imufuse_c.MadgwickAHRS(dt=log.dt, init="first")
    want = f.run(log.gyr, log.acc, log.mag, dt=dts)
    assert np.array_equal(M[:, 1:5], want)
    # --fixed-rate and --init identity reproduce the fixed-step, identity start
    r = imf("run", p, "-f", "MadgwickAHRS", "-o", out, "--fixed-rate", "--init", "identity")
    assert r.returncode == 0, r.stderr
    M = np.loadtxt(out, delimiter=",", skiprows=1)
    want = imufuse_c.MadgwickAHRS(dt=log.dt).run(log.gyr, log.acc, log.mag)
    assert np.array_equal(M[:, 1:5], want)


def test_init_first_starts_at_the_right_heading(tmp_path):
    """At rest, turned 120 deg in heading: started from the first sample the
    AHRS filter is right at once; from identity it is still far off."""
    from imufuse.rotations import quat_from_axis_angle, quat_rotate_inv
    n, rate = 500, 100.0
    q = quat_from_axis_angle([0, 0, 1], math.radians(120))
    acc = np.tile(quat_rotate_inv(q, [0, 0, 1.0]), (n, 1))
    mag = np.tile(quat_rotate_inv(q, [0.4, 0, -0.9]), (n, 1))
    p = tmp_path / "rest.csv"
    io.write_log(p, np.arange(n) / rate, np.zeros((n, 3)), acc, mag)
    yaws = {}
    for init in ("first", "identity"):
        r = imf("run", p, "-f", "MahonyAHRS", "--init", init)
        assert r.returncode == 0, r.stderr
        M = np.genfromtxt(r.stdout.splitlines(), delimiter=",", names=True)
        yaws[init] = M["yaw_deg"]
    assert abs(yaws["first"][0] - 120) < 0.5
    assert abs(yaws["identity"][-1] - 120) > 5


def test_column_map_option_and_file(tmp_path, data):
    d, t = data
    p = tmp_path / "odd.csv"
    io.write_csv(p, {"stamp": t, "G1": d.gyr[:, 0], "G2": d.gyr[:, 1], "G3": d.gyr[:, 2],
                     "A1": d.acc[:, 0], "A2": d.acc[:, 1], "A3": d.acc[:, 2]})
    with pytest.raises(LogError, match="no known column"):
        read_log(p)
    m = 'time=stamp,gyr_x=G1,gyr_y=G2,gyr_z=G3,acc_x="A1",acc_y=A2,acc_z=A3'
    a = read_log(p, columns=io.parse_column_map(m))
    mf = tmp_path / "map.txt"
    mf.write_text("# my logger\n" + "\n".join(f"{k} = {v}" for k, v in
                                             io.parse_column_map(m).items()) + "\n")
    b = read_log(p, columns=io.read_column_map(mf))
    jf = tmp_path / "map.json"
    jf.write_text(json.dumps(io.parse_column_map(m)))
    c = read_log(p, columns=io.read_column_map(jf))
    for lg in (a, b, c):
        assert np.array_equal(lg.gyr, d.gyr) and np.array_equal(lg.columns["time"], t)
    r = imf("run", p, "-f", "MadgwickIMU", "--column-map", mf)
    assert r.returncode == 0, r.stderr
    r = imf("run", p, "-f", "MadgwickIMU", "--columns", "time=stamp", "--columns",
            "gyr_x=G1,gyr_y=G2,gyr_z=G3,acc_x=A1,acc_y=A2,acc_z=A3")
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("text,words", [
    ("Time (s),Gyr-X raw,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,1\n0.01,0,0,0,0,0,1\n",
     ["missing column gyr_x", "did you mean 'Gyr-X raw'", "--columns"]),
    ("time,gyr_x (furlong/s),gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,1\n0.01,0,0,0,0,0,1\n",
     ["unknown gyr unit 'furlong/s'", "deg/s"]),
    ("time,gyr_x (deg/s),gyr_y (rad/s),gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,1\n",
     ["different units", "deg/s", "rad/s"]),
    ("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,1,5\n",
     ["decimal commas", "';' or tabs"]),
])
def test_errors_say_what_was_found_and_expected(tmp_path, text, words):
    p = tmp_path / "x.csv"
    p.write_text(text)
    with pytest.raises(LogError) as e:
        log = read_log(p)
        io.require(log, io.GYR + io.ACC)
    for w in words:
        assert w in str(e.value), str(e.value)


def test_binary_files_taken_for_a_csv_log_are_named(tmp_path):
    """A gzip-compressed CSV, a .npy array, an NPZ or HDF5 log under another extension: they
    read "it contains NUL bytes (expected a header row of column names)"; now what they are,
    with what to do."""
    import gzip
    text = b"time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,1\n0.01,0,0,0,0,0,1\n"
    (tmp_path / "a.csv.gz").write_bytes(gzip.compress(text))
    np.save(tmp_path / "b.npy", np.zeros((10, 3)))
    np.savez(tmp_path / "c.npz", gyr=np.zeros((3, 3)))
    os.replace(tmp_path / "c.npz", tmp_path / "c.csv")
    for name, words in (("a.csv.gz", "a gzip-compressed file; decompress it first"),
                        ("b.npy", "a NumPy .npy array; save the log as NPZ"),
                        ("c.csv", "a ZIP archive; an NPZ log needs the .npz extension")):
        with pytest.raises(LogError, match=re.escape(f"not a text (CSV) log: {words}")):
            read_log(tmp_path / name)


def test_units_given_win_over_the_header_with_a_warning(tmp_path, data):
    d, t = data
    p = tmp_path / "x.csv"
    write_xio(p, d, t)
    log = read_log(p, gyr_unit="rad/s")
    assert np.array_equal(log.columns["gyr_x"], np.degrees(d.gyr[:, 0])) or np.allclose(
        log.columns["gyr_x"], np.degrees(d.gyr[:, 0]))
    assert any("the header says deg/s" in w for w in log.warnings)


# ---------------------------------------------------------------------------
# BROAD: the shipped excerpt, NPZ and CSV, against an independent implementation

def test_example_excerpt_is_package_data_with_attribution():
    p = io.example_log()
    assert os.path.isfile(p)
    z = np.load(p)
    rate = float(z["rate"])
    assert len(z["gyr"]) / rate <= 60
    att = open(os.path.join(os.path.dirname(p), "BROAD-EXCERPT.md")).read()
    assert "CC BY 4.0" in att and "doi:10.3390/data6070072" in att and "Laidig" in att
    log = read_log(p)
    assert log.ref_frame == "ENU" and log.units["acc"][0] == "m/s^2"
    assert np.allclose(np.linalg.norm(log.acc[:100], axis=1), 1.0, atol=0.05)  # g after conversion


def _independent(q_nwu, ref_enu, use):
    from scipy.spatial.transform import Rotation as R
    rot = lambda q: R.from_quat(q[:, [1, 2, 3, 0]])  # noqa: E731
    E = (R.from_euler("z", 90, degrees=True) * rot(q_nwu[use])) * rot(ref_enu[use]).inv()
    z = np.array([0, 0, 1.0])
    incl = np.degrees(np.arccos(np.clip(E.apply(z) @ z, -1, 1)))
    total = np.degrees(E.magnitude())
    # heading: the twist about z left after removing the swing that tilts z
    Ez = E.apply(z)
    ax = np.cross(z, Ez)
    nrm = np.linalg.norm(ax, axis=1, keepdims=True)
    swing = R.from_rotvec(np.where(nrm > 0, ax / np.where(nrm > 0, nrm, 1), 0) * np.radians(incl)[:, None])
    head = np.degrees((swing.inv() * E).magnitude())
    rms = lambda x: math.sqrt(np.mean(x ** 2))  # noqa: E731
    return rms(total), rms(head), rms(incl)


def test_broad_csv_through_compare_equals_an_independent_implementation(tmp_path):
    """The excerpt converted to CSV (with NaN reference rows put in), through
    `imufuse compare --ref-frame ENU`: the printed metrics equal scipy-based ones."""
    z = dict(np.load(io.example_log()))
    z["quat_ref"] = z["quat_ref"].copy()
    z["quat_ref"][3000:3400] = np.nan               # an optical dropout
    npz = tmp_path / "trial.npz"
    np.savez(npz, **z)
    csv = tmp_path / "trial.csv"
    io.npz_to_csv(npz, csv)
    r = imf("compare", csv, "--ref-frame", "ENU", "-f", "MadgwickAHRS,MahonyIMU")
    assert r.returncode == 0, r.stderr
    assert "400 with a NaN reference" in r.stdout
    log = read_log(csv)
    use = log.movement & np.all(np.isfinite(log.q_ref), axis=1)
    for name in ("MadgwickAHRS", "MahonyIMU"):
        line = next(ln for ln in r.stdout.splitlines() if ln.startswith(name + " "))
        cols = line.split()
        from imufuse.catalogue import resolve_params
        f = getattr(imufuse_c, name)(**resolve_params(name, log.dt), init="first")
        ins = (log.gyr, log.acc, log.mag) if name.endswith("AHRS") else (log.gyr, log.acc)
        q = f.run(*ins, dt=log.dts)[:, :4]
        total, head, incl = _independent(q, log.q_ref, use)
        assert float(cols[2]) == pytest.approx(incl, abs=6e-4)
        assert int(cols[5]) == use.sum()
        if name.endswith("AHRS"):
            assert float(cols[3]) == pytest.approx(head, abs=6e-4)
            assert float(cols[4]) == pytest.approx(total, abs=6e-4)
    # the wrong frame is not silently accepted as right: NWU gives large heading errors
    r = imf("compare", csv, "--ref-frame", "NWU", "-f", "MadgwickAHRS")
    head_nwu = float(next(ln for ln in r.stdout.splitlines()
                          if ln.startswith("MadgwickAHRS ")).split()[3])
    assert head_nwu > 45
    # the user said NWU, and the errors point at the mistake: the hint names the frame that fits
    assert "against the reference as NWU (given)" in r.stderr and "--ref-frame ENU" in r.stderr
    # not said: a hint names the frame that fits
    r = imf("compare", csv, "-f", "MadgwickAHRS")
    assert r.returncode == 0 and "with --ref-frame ENU it would be" in r.stderr, r.stderr


def test_npz_and_csv_runs_agree(tmp_path):
    csv = tmp_path / "trial.csv"
    io.npz_to_csv(io.example_log(), csv)
    a = imf("compare", io.example_log(), "-f", "MahonyAHRS")
    b = imf("compare", csv, "--ref-frame", "ENU", "-f", "MahonyAHRS", "--fixed-rate")
    assert a.returncode == b.returncode == 0, a.stderr + b.stderr
    la = next(ln for ln in a.stdout.splitlines() if ln.startswith("MahonyAHRS "))
    lb = next(ln for ln in b.stdout.splitlines() if ln.startswith("MahonyAHRS "))
    assert [float(x) for x in la.split()[2:5]] == pytest.approx(
        [float(x) for x in lb.split()[2:5]], abs=2e-3)


def test_run_frame_option_converts_output(tmp_path):
    out = {}
    for fr in ("NWU", "ENU", "NED"):
        o = tmp_path / f"{fr}.csv"
        r = imf("run", io.example_log(), "-f", "MadgwickAHRS", "-o", o, "--frame", fr)
        assert r.returncode == 0, r.stderr
        out[fr] = np.genfromtxt(o, delimiter=",", names=True)
    from imufuse.evaluation import to_enu
    q = {fr: np.column_stack([out[fr][c] for c in ("q_w", "q_x", "q_y", "q_z")])
         for fr in ("ENU", "NED")}
    qn = np.column_stack([out["NWU"][c] for c in ("q0", "q1", "q2", "q3")])
    for fr in ("ENU", "NED"):
        assert np.allclose(to_enu(q[fr], fr), to_enu(qn, "NWU"), atol=1e-12)
    # ENU yaw = NWU yaw + 90 deg (modulo 360)
    d = (out["ENU"]["yaw_deg"] - out["NWU"]["yaw_deg"] - 90 + 180) % 360 - 180
    assert np.allclose(d, 0, atol=1e-9)


# ---------------------------------------------------------------------------
# plots

@pytest.mark.skipif(not HAVE_MPL, reason="matplotlib not installed")
def test_one_colour_per_filter_in_every_panel(tmp_path):
    """Every line of a filter has that filter's colour in every panel (the
    heading panel skipping IMU filters does not shift the colours)."""
    from imufuse import plots
    from imufuse.catalogue import estimate, reference_class
    from imufuse.shared.estimate import euler_of
    d = sim.imu("slow", rate=100.0, duration=8.0, seed=2)
    names = ["MahonyIMU", "MahonyAHRS", "MadgwickIMU", "DCM", "MadgwickAHRS"]
    ests = {}
    for n in names:
        cls = reference_class(n)
        ins = (d.gyr, d.acc, d.mag) if cls.kind == "ahrs" else (d.gyr, d.acc)
        from imufuse.catalogue import resolve_params
        ests[n] = estimate(cls, getattr(imufuse_c, n)(**resolve_params(n, d.dt)).run(*ins))
    want = plots.colours(names)
    assert len(set(want.values())) == len(names)
    figs = [plots.plot_3d_errors(tmp_path / "e.png", d.t, d.q_true, ests),
            plots.plot_euler(tmp_path / "u.png", d.t, {n: euler_of(e) for n, e in ests.items()},
                             None, errors={n: np.zeros(len(d.t)) for n in names})]
    seen = 0
    for fig in figs:
        for ax in fig.axes:
            for line in ax.get_lines():
                if line.get_label() in want:
                    assert line.get_color() == want[line.get_label()], (ax.get_ylabel(),
                                                                         line.get_label())
                    seen += 1
            leg = ax.get_legend()
            if leg is not None:
                for h, t in zip(leg.legend_handles, leg.get_texts()):
                    if t.get_text() in want:
                        assert h.get_color() == want[t.get_text()]
    assert seen >= 2 * len(names) + 2 * 2 + 3 * 2


def test_unwrap_and_steady_limits():
    from imufuse import plots
    yaw = np.radians(np.arange(0, 720, 10.0)) % (2 * np.pi) - np.pi
    u = plots.unwrap_deg(yaw)
    assert np.all(np.abs(np.diff(u)) < 11)
    t = np.linspace(0, 10, 1001)
    e = np.where(t < 0.5, -5.0, 0.4 * np.sin(t))      # a start-up transient, then 0.4 deg
    lo, hi = plots.steady_limits(t, [e])
    assert -1 < lo <= -0.39 and 0.39 <= hi < 1


def test_hdf5_in_the_broad_layout(tmp_path):
    """BROAD's HDF5 names (imu_gyr, opt_quat, sampling_rate, ...) read like the NPZ."""
    h5py = pytest.importorskip("h5py", reason="h5py (test extra) not installed")
    z = np.load(io.example_log())
    p = tmp_path / "trial.hdf5"
    with h5py.File(p, "w") as f:
        for k, v in (("imu_gyr", z["gyr"]), ("imu_acc", z["acc"]), ("imu_mag", z["mag"]),
                     ("opt_quat", z["quat_ref"]), ("movement", z["movement"]),
                     ("sampling_rate", z["rate"])):
            f[k] = v
    a, b = read_log(p), read_log(io.example_log())
    for n in ("gyr", "acc", "mag", "q_ref", "movement"):
        assert np.array_equal(getattr(a, n), getattr(b, n), equal_nan=True)
    assert a.dt == b.dt and a.ref_frame == "ENU"
    p2 = tmp_path / "bad.h5"
    p2.write_bytes(b"not hdf5")
    with pytest.raises(LogError, match="not a readable HDF5"):
        read_log(p2)


def test_init_window_through_the_cli(tmp_path):
    """--init first --init-window N is the library's init="first", init_window=N."""
    from imufuse.catalogue import resolve_params
    out = tmp_path / "o.csv"
    r = imf("run", io.example_log(), "-f", "MahonyAHRS", "--init-window", 50, "-o", out)
    assert r.returncode == 0 and "mean of 50 samples" in r.stderr, r.stderr
    log = read_log(io.example_log())
    want = imufuse_c.MahonyAHRS(**resolve_params("MahonyAHRS", log.dt), init="first",
                                init_window=50).run(log.gyr, log.acc, log.mag)
    M = np.genfromtxt(out, delimiter=",", names=True)
    got = np.column_stack([M[c] for c in ("q0", "q1", "q2", "q3")])
    assert np.array_equal(got, want[:, :4])
    one = imufuse_c.MahonyAHRS(**resolve_params("MahonyAHRS", log.dt), init="first").run(
        log.gyr, log.acc, log.mag)
    assert not np.array_equal(one[:, :4], want[:, :4])      # the window matters


def test_recognition_prefers_close_names_and_checks_time_units():
    h = ["T (degC)", "t", "Time (s)", "gx", "gyr_x", "ax"]
    got = io.recognise(h)
    assert got["time"] == 2 and got["gyr_x"] == 4 and got["acc_x"] == 5
    assert io.recognise(["T (degC)", "gx"]) == {"gyr_x": 1}


def test_frame_hint_on_a_long_log_ranks_on_a_sample_and_scores_on_all(monkeypatch):
    """frame_hint ranks the other frames on every k-th sample of a long log (session.HINT_SAMPLES)
    and says the best one's error on the whole log: the same hint, with the same figure, as
    when every frame is scored on every sample."""
    from imufuse import session as ses
    s = ses.Session(io.example_log())
    opts = ses.ScoreOptions(ref_frame="NWU")
    run = s.run("MadgwickAHRS")
    ev = s.score(run, opts)
    full = s.frame_hint(run, ev, opts)
    assert full is not None and "--ref-frame ENU" in full, full
    assert len(s.log.q_ref) > 3000
    monkeypatch.setattr(ses, "HINT_SAMPLES", 1000)
    assert s.frame_hint(run, ev, opts) == full
