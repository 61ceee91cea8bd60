"""The command line end to end: `python -m imufuse ...` in a subprocess, on
CSV logs the tests write, every subcommand and every error with its exit code (the
argument and file errors through main() in this process: imf_here)."""
import csv
import io as _io
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import imufuse
import imufuse_c
import imufuse.reference as reference
from imufuse import cli, io, sim
from imufuse.tools import demo
from cli_here import imf_here

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PATHS = [os.path.dirname(os.path.dirname(imufuse.__file__)),
         os.path.dirname(os.path.dirname(imufuse_c.__file__))]
HAVE_MPL = __import__("importlib").util.find_spec("matplotlib") is not None
FILTERS_1D = reference.FILTERS_1D
AHRS = [n for n in reference.FILTERS if getattr(reference, n).kind == "ahrs"]
assert AHRS, "the AHRS filters are missing from imufuse.reference"



def imf(*args, cwd=None, env=None, timeout=120):
    e = dict(os.environ)
    e["PYTHONPATH"] = os.pathsep.join(PATHS + [e.get("PYTHONPATH", "")])
    e["MPLBACKEND"] = "Agg"
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "imufuse", *map(str, args)], cwd=cwd, env=e,
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def data():
    return sim.imu("slow", rate=200.0, duration=5.0, seed=4)


@pytest.fixture(scope="module")
def logs(tmp_path_factory, data):
    d = tmp_path_factory.mktemp("logs")
    p = {}
    p["full"] = d / "full.csv"
    io.write_log(p["full"], data.t, data.gyr, data.acc, data.mag, data.q_true)
    p["noq"] = d / "noq.csv"
    io.write_log(p["noq"], data.t, data.gyr, data.acc)
    # deg/s and m/s^2, columns shuffled, an extra column, no time (needs --rate)
    p["units"] = d / "units.csv"
    with open(p["units"], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["acc_z", "gyr_y", "note", "gyr_x", "acc_x", "gyr_z", "acc_y"])
        for k in range(len(data.t)):
            g = np.degrees(data.gyr[k])
            a = data.acc[k] * io.GRAVITY
            w.writerow([repr(float(v)) if not isinstance(v, str) else v
                        for v in (a[2], g[1], "x", g[0], a[0], g[2], a[1])])
    p["axis"] = d / "axis.csv"
    a1 = sim.axis1d("slow", rate=100.0, duration=5.0, seed=2)
    io.write_csv(p["axis"], {"time": a1.t, "rate": a1.gyr, "angle": a1.acc_angle})
    lines = open(p["full"]).read().splitlines(keepends=True)
    p["misnamed"] = d / "misnamed.csv"
    p["misnamed"].write_text(lines[0].replace("gyr_x", "gyro_xx").replace("acc_z", "Acc_ZZ")
                             + "".join(lines[1:]))
    p["text"] = d / "text.csv"
    bad = lines[:]
    bad[6] = bad[6].split(",", 2)[0] + ",abc," + bad[6].split(",", 2)[2]
    p["text"].write_text("".join(bad))
    p["time"] = d / "time.csv"
    bad = lines[:]
    bad[9] = "0.001," + bad[9].split(",", 1)[1]
    p["time"].write_text("".join(bad))
    return p


def _read(path_or_text):
    fh = _io.StringIO(path_or_text) if "\n" in str(path_or_text) else open(path_or_text)
    rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], dtype=np.float64)


# ---------------------------------------------------------------------------
# demo

def test_demo(tmp_path):
    r = imf("demo", "--out", tmp_path / "out", "--duration", 5)
    assert r.returncode == 0, r.stdout + r.stderr
    for name in reference.FILTERS:
        line = next(ln for ln in r.stdout.splitlines() if ln.startswith(name + " "))
        assert line.split()[2:4] == ["ok", "ok"], line
    assert "0 of" in r.stdout
    # then every 3D filter on the shipped real recording, against optical truth
    real = r.stdout[r.stdout.index("real data:"):]
    assert "CC BY 4.0" in real and "(ENU, sensor-to-earth)" in real
    for name in demo.filter_names({"imu", "ahrs"}):
        line = next(ln for ln in real.splitlines() if ln.startswith(name + " "))
        assert 0 <= float(line.split()[2]) < 90, line
    if HAVE_MPL:
        assert (tmp_path / "out" / "demo_real.png").stat().st_size > 10000
        assert (tmp_path / "out" / "demo_1d.png").stat().st_size > 10000
        if demo.filter_names({"imu", "ahrs"}):
            assert (tmp_path / "out" / "demo_3d.png").stat().st_size > 10000


def test_demo_without_matplotlib(tmp_path):
    code = ("import sys; sys.modules['matplotlib'] = None; from imufuse.cli import main; "
            f"sys.exit(main(['demo', '--out', {str(tmp_path)!r}, '--duration', '3', "
            "'--filter', 'Kalman1D,Mahony1D']))")
    e = dict(os.environ, PYTHONPATH=os.pathsep.join(PATHS))
    r = subprocess.run([sys.executable, "-c", code], env=e, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "imufuse: plots unavailable" in r.stderr      # said once, the demo's plots not asked for
    assert r.stderr.count("plots unavailable") == 1
    assert not list(tmp_path.iterdir())


def test_demo_fails_on_a_bit_difference(monkeypatch):
    """One ulp changed in the C trajectory of one filter makes the demo fail
    and name the sample."""
    real = imufuse_c.Kalman1D

    class Off:
        def __init__(self, *a, **k):
            self.f = real(*a, **k)
            self.state_names = self.f.state_names

        def run(self, *inputs):
            S = self.f.run(*inputs)
            S[123, 0] = np.nextafter(S[123, 0], np.inf)
            return S

    monkeypatch.setattr(imufuse_c, "Kalman1D", Off)
    out = _io.StringIO()
    rc = demo.run_demo(plot=False, duration=3.0, stream=out, names=["Kalman1D", "Mahony1D"])
    assert rc == 1
    assert "DIFF@123:theta" in out.getvalue()
    assert "2 of 4 bit-exact checks failed" in out.getvalue()


# ---------------------------------------------------------------------------
# run

def test_run_matches_the_library_bit_for_bit(logs, tmp_path):
    out = tmp_path / "k.csv"
    r = imf("run", logs["full"], "--filter", "Kalman1DBias", "-o", out, "--dtype", "float32",
            "--param", "k0=0.02", "-p", "k1=-0.05")
    assert r.returncode == 0, r.stderr
    head, M = _read(out)
    assert head == ["time", "theta", "b", "angle_deg"]
    log = io.read_log(str(logs["full"]))
    # by default each sample runs with its own interval (the first with the median)
    t = log.columns["time"]
    dts = np.concatenate([[log.dt], np.diff(t)])
    inputs = (log.columns["gyr_x"], np.arctan2(log.columns["acc_y"], log.columns["acc_z"]))
    f = imufuse_c.Kalman1DBias(dt=log.dt, k0=0.02, k1=-0.05, dtype="float32")
    want = f.run(*inputs, dt=dts)
    assert np.array_equal(M[:, 1:3].astype(np.float32).view(np.uint32), want.view(np.uint32))
    assert "against the log's reference q" in r.stderr
    # --fixed-rate: the median period for every sample
    r = imf("run", logs["full"], "--filter", "Kalman1DBias", "-o", out, "--dtype", "float32",
            "--param", "k0=0.02", "-p", "k1=-0.05", "--fixed-rate")
    assert r.returncode == 0, r.stderr
    _, M = _read(out)
    f = imufuse_c.Kalman1DBias(dt=log.dt, k0=0.02, k1=-0.05, dtype="float32")
    want = f.run(*inputs)
    assert np.array_equal(M[:, 1:3].astype(np.float32).view(np.uint32), want.view(np.uint32))


def test_run_ref_backend_stdout_and_units(logs):
    """--backend ref equals c; deg/s and m/s^2 with --rate read the same data."""
    a = imf("run", logs["full"], "-f", "Mahony1DBias", "--backend", "ref")
    b = imf("run", logs["full"], "-f", "Mahony1DBias", "--backend", "c")
    assert a.returncode == b.returncode == 0, a.stderr
    assert a.stdout == b.stdout
    c = imf("run", logs["units"], "-f", "Mahony1DBias", "--gyr-unit", "deg/s",
            "--acc-unit", "m/s2", "--rate", 200)
    assert c.returncode == 0, c.stderr
    _, B = _read(b.stdout)
    _, C = _read(c.stdout)
    assert np.allclose(B[:, 1:], C[:, 1:], rtol=0, atol=1e-9)
    assert np.allclose(C[:, 0], np.arange(len(C)) / 200.0)


def test_run_long_log_reports_progress(tmp_path):
    """A long run reports progress on stderr; the chunked run is the same
    trajectory as one run(), bit for bit (the C backend does it in one go)."""
    from imufuse import session
    n = session.PROGRESS_MIN["ref"] + 5000
    d = sim.imu("static", rate=200.0, duration=n / 200.0, seed=5)
    log = tmp_path / "long.csv"
    io.write_log(log, d.t, d.gyr, d.acc)
    a = imf("run", log, "-f", "Kalman1D", "-p", "k0=0.02", "--backend", "ref", timeout=300)
    b = imf("run", log, "-f", "Kalman1D", "-p", "k0=0.02", "--backend", "c")
    assert a.returncode == b.returncode == 0, a.stderr
    assert f"Kalman1D: 100% ({n}/{n} samples)" in a.stderr
    assert a.stderr.count("% (") >= 10
    assert "% (" not in b.stderr
    assert a.stdout == b.stdout


def test_run_rate_and_angle_columns_and_axis(logs):
    r = imf("run", logs["axis"], "-f", "Complementary1D", "-p", "alpha=0.95", "--fixed-rate")
    assert r.returncode == 0, r.stderr
    _, M = _read(r.stdout)
    a1 = sim.axis1d("slow", rate=100.0, duration=5.0, seed=2)
    want = imufuse_c.Complementary1D(dt=0.01, alpha=0.95).run(a1.gyr, a1.acc_angle)
    assert np.array_equal(M[:, 1], want[:, 0])
    assert "columns rate, angle" in r.stderr
    y = imf("run", logs["full"], "-f", "Kalman1D", "--axis", "y")
    assert y.returncode == 0 and "gyr_y, atan2(-acc_x, acc_z)" in y.stderr


@pytest.mark.skipif(not HAVE_MPL, reason="matplotlib not installed")
def test_run_plot(logs, tmp_path):
    r = imf("run", logs["full"], "-f", "Kalman1D", "-o", tmp_path / "o.csv", "--plot",
            tmp_path / "p.png")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "p.png").stat().st_size > 10000


@pytest.mark.parametrize("args,code,words", [
    (["missing.csv", "-f", "Kalman1D"], 3, ["no such file"]),
    (["@misnamed", "-f", "Kalman1D"], 4, ["missing column", "gyr_x", "'gyro_xx'", "acc_z", "'Acc_ZZ'"]),
    (["@text", "-f", "Kalman1D"], 4, [":7:", "gyr_x", "'abc'"]),
    (["@time", "-f", "Kalman1D"], 4, [":10:", "time does not increase"]),
    (["@units", "-f", "Kalman1D"], 4, ["no time column", "--rate"]),
    (["@full", "-f", "Kalman1X"], 2, ["unknown filter", "Kalman1D", *FILTERS_1D]),
    (["@full", "-f", "Kalman1D", "-p", "gain=1"], 2, ["unknown parameter 'gain'", "k0"]),
    (["@full", "-f", "Kalman1D", "-p", "k0=3"], 2, ["k0"]),
    (["@full", "-f", "Kalman1D", "-p", "k0"], 2, ["NAME=VALUE"]),
    (["@full", "-f", "Kalman1D", "-p", "dt=0.1"], 2, ["--rate"]),
    # options given as parameters: it read "unknown parameter 'dtype'"
    (["@full", "-f", "Kalman1D", "-p", "dtype=float32"], 2,
     ["Kalman1D: dtype is not a parameter but an option of the run: --dtype"]),
    (["@full", "-f", "MadgwickIMU", "-p", "init=identity"], 2,
     ["MadgwickIMU: init is not a parameter but an option of the run: --init"]),
    (["@full", "-f", "Kalman1D", "-p", "init=identity"], 2, ["unknown parameter 'init'"]),
    (["@full", "-f", "Kalman1D", "--rate", "-5"], 2, ["rate"]),
])
def test_run_errors(logs, args, code, words):
    args = [str(logs[a[1:]]) if a.startswith("@") else a for a in args]
    r = imf_here("run", *args, "-o", os.devnull)
    assert r.returncode == code, (r.returncode, r.stderr)
    for w in words:
        assert w in r.stderr, (w, r.stderr)
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize("name", AHRS)
def test_run_ahrs_without_mag(logs, name):
    r = imf_here("run", logs["noq"], "-f", name)
    assert r.returncode == 4 and "mag_x" in r.stderr


# ---------------------------------------------------------------------------
# compare, bench

def test_compare_with_reference(logs, tmp_path):
    png = tmp_path / "c.png"
    r = imf("compare", logs["full"], "--plot", png)
    assert r.returncode == 0, r.stderr
    assert "errors against the log's q_w..q_z" in r.stdout
    expected = demo.filter_names({"imu", "ahrs"}) or FILTERS_1D
    for n in expected:
        line = next(ln for ln in r.stdout.splitlines() if ln.startswith(n + " "))
        incl, head, total = line.split()[2:5]
        assert 0 <= float(incl) < 90
        if getattr(reference, n).kind == "ahrs":       # total error >= each part
            assert float(total) >= max(float(incl), float(head))
        else:                                          # 6-DOF: inclination only
            assert head == total == "-"
    if HAVE_MPL:
        assert png.stat().st_size > 10000


def test_compare_errors_match_run(logs):
    """compare's error for a filter is run's error for it."""
    c = imf("compare", logs["full"], "-f", "Mahony1D,Kalman1D", "-p", "Kalman1D.k0=0.05",
            "-p", "kp=3")
    r = imf("run", logs["full"], "-f", "Mahony1D", "-o", os.devnull, "-p", "kp=3")
    assert c.returncode == r.returncode == 0
    line = next(ln for ln in c.stdout.splitlines() if ln.startswith("Mahony1D "))
    rms = line.split()[2]
    assert f"angle RMS {rms} max" in r.stderr
    assert len([ln for ln in c.stdout.splitlines() if ln.endswith("theta")]) == 2


def test_compare_without_reference_and_errors(logs):
    r = imf("compare", logs["noq"], "-f", "Kalman1D", "-f", "Mahony1D")
    assert r.returncode == 0 and "final attitude" in r.stdout
    bad = imf_here("compare", logs["noq"], "-f", "Kalman1D", "-p", "beta=1")
    assert bad.returncode == 2 and "no selected filter has a parameter 'beta'" in bad.stderr
    bad = imf_here("compare", logs["noq"], "-f", "Kalman1D,Nope")
    assert bad.returncode == 2 and "unknown filter 'Nope'" in bad.stderr


def test_bench():
    r = imf("bench", "--samples", 2000, "--ref-samples", 200, "--repeat", 1, "-f",
            "Kalman1D,Complementary1DBias")
    assert r.returncode == 0, r.stderr
    for n in ("Kalman1D", "Complementary1DBias"):
        line = next(ln for ln in r.stdout.splitlines() if ln.startswith(n + " "))
        assert all(float(x) > 0 for x in line.split()[1:5])


# ---------------------------------------------------------------------------
# validate

@pytest.fixture(scope="module")
def fw_cache(tmp_path_factory):
    return {"IMUFUSE_CACHE": str(tmp_path_factory.mktemp("fw-cache"))}


def test_validate_csrc_and_a_planted_mistake(tmp_path, fw_cache):
    import shutil
    ok = imf("validate", "--csrc", os.path.join(ROOT, "csrc"), "-f", "Mahony1D", "--dtype",
             "float32", "--duration", 3, env=fw_cache)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "bit-exact: 600 samples" in ok.stdout
    d = tmp_path / "fw"
    shutil.copytree(os.path.join(ROOT, "csrc"), d)
    src = (d / "filters_1d.c").read_text()
    old = "theta = self->x.theta + (self->kp * e + rate) * self->dt;"
    assert src.count(old) == 1
    (d / "filters_1d.c").write_text(
        src.replace(old, "theta = self->x.theta + self->kp * e * self->dt + rate * self->dt;"))
    png = tmp_path / "div.png"
    bad = imf("validate", d / "filters_1d.c", "-I", d, "--header", "filters_1d.h", "-f", "Mahony1D",
              "--init", "imf_mahony1d_init",
              "--update", "void imf_mahony1d_update(imf_mahony1d_t *self, float w, float a)",
              "--state", "theta=x.theta", "--duration", 3, "--plot", png, env=fw_cache)
    assert bad.returncode == 1, bad.stdout + bad.stderr
    assert "NOT bit-exact (float32): first divergence at sample" in bad.stdout
    # the first divergence, found here by a mirror of the distributed product
    d1 = sim.axis1d("slow", rate=200.0, duration=3.0, seed=1)
    f32 = np.float32
    want = imufuse_c.Mahony1D(dt=0.005, kp=2.0, dtype="float32").run(d1.gyr, d1.acc_angle)[:, 0]
    th, k0 = f32(0), None
    kp, dt = f32(2.0), f32(0.005)
    for k, (w, a) in enumerate(zip(d1.gyr.astype(f32), d1.acc_angle.astype(f32))):
        e = a - th
        th = th + kp * e * dt + w * dt
        if th.view(np.uint32) != want[k].view(np.uint32):
            k0 = k
            break
    assert k0 is not None
    assert f"first divergence at sample {k0}, variable theta" in bad.stdout
    if HAVE_MPL:
        assert png.stat().st_size > 10000


def test_validate_errors(tmp_path, fw_cache):
    r = imf("validate", tmp_path / "none.c", "-f", "Kalman1D", "--update", "f")
    assert r.returncode == 3 and "no such file" in r.stderr
    src = tmp_path / "f.c"
    src.write_text("void f(float a, float b) { (void)a; (void)b; }\n")
    r = imf("validate", src, "-f", "Kalman1D", "--update", "f")
    assert r.returncode == 5 and "prototype of f not found" in r.stderr
    r = imf("validate", src, "-f", "Kalman1D", "--update", "void f(float a, float b)",
            "--state", "theta=not valid", env=fw_cache)
    assert r.returncode == 5 and "state expression" in r.stderr
    r = imf("validate", src, "-f", "Kalman1D")
    assert r.returncode == 2 and "--update" in r.stderr


def test_main_without_command():
    assert cli.main([]) == 2


def test_help_lists_subcommands():
    r = imf("--help")
    assert r.returncode == 0
    for c in ("demo", "run", "compare", "bench", "validate"):
        assert c in r.stdout


@pytest.mark.parametrize("name,heading", [("MadgwickIMU", False), ("MahonyIMU", False),
                                          ("MadgwickAHRS", True)])
def test_run_scores_heading_only_for_filters_that_estimate_it(tmp_path, name, heading):
    """`run` against the log's reference: a 6-D filter's yaw is unobserved, so its line
    gives the inclination only (as compare's table does), not a 'heading' of ~90 deg."""
    r = imf("run", io.example_log(), "-f", name, "-o", tmp_path / "out.npz")
    assert r.returncode == 0, r.stderr
    line = next(ln for ln in r.stderr.splitlines() if "against the log's reference" in ln)
    assert re.search(r"inclination \d", line), line
    assert bool(re.search(r"heading \d", line)) == bool(re.search(r"total \d", line)) == heading, line
    assert ("no heading" in line) != heading, line
