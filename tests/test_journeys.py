"""A user's journey: every subcommand on three real inputs as users have them, each result
checked against a computation made here from the raw arrays (not through imufuse.session).

  - a BROAD trial as published: the real HDF5 file of trial 03 (../shared/data/broad/published;
    imu_gyr rad/s, imu_acc m/s^2, imu_mag uT, opt_quat ENU, movement, attribute sampling_rate),
    or without it one written with every key and attribute of that layout (trial 09, 60 s);
  - an x-io-layout CSV (x-io Fusion's headers and units: deg/s, g, uT, seconds) of a real
    recording (BROAD trial 11, 20 s), as a logger writes it;
  - the shipped example (45 s of BROAD trial 03, NPZ).
"""
import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import imufuse_c
from broad_data import BROAD, SKIP_REASON
from imufuse.calibration import fit as calibrate
from imufuse.evaluation import estimate_latency, evaluate
from imufuse.io import example_log

h5py = pytest.importorskip("h5py", reason="h5py is in the test extra (pip install 'imufuse[test]')")
pytestmark = pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)

G = 9.80665
XIO = (["Time (s)"] + [f"Gyroscope {a} (deg/s)" for a in "XYZ"]
       + [f"Accelerometer {a} (g)" for a in "XYZ"] + [f"Magnetometer {a} (uT)" for a in "XYZ"])


def imf(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "imufuse", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


class Raw:
    """The recording as this test reads it: gyr rad/s, acc g, mag uT, q_ref ENU, times."""

    def __init__(self, path, gyr, acc, mag, q=None, movement=None, t=None, rate=None):
        self.path, self.gyr, self.acc, self.mag = path, gyr, acc, mag
        self.q, self.movement, self.t, self.rate = q, movement, t, rate

    def dt(self):
        """The per-sample periods a log's time column gives (the first: the median), or the
        fixed period of its rate."""
        if self.t is None:
            return 1.0 / self.rate
        d = np.diff(self.t)
        dt0 = 1.0 / float(f"{1.0 / np.median(d):.9g}")
        return np.concatenate([[dt0], d])


def _trial(name, start, seconds):
    """The arrays of a trial from ``start`` s for ``seconds`` s."""
    z = np.load(os.path.join(BROAD, name))
    r = float(z["rate"])
    a, n = int(start * r), int(seconds * r)
    return {k: (z[k][a:a + n] if z[k].ndim else z[k]) for k in z.files}, n


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("journeys")
    out = {}
    published = os.path.join(BROAD, "published", "03_undisturbed_slow_rotation_C.hdf5")
    if os.path.isfile(published):
        # the real file as the dataset's authors publish it, read here with h5py
        with h5py.File(published, "r") as f:
            rate = float(f.attrs["sampling_rate"])
            out["hdf5"] = Raw(published, f["imu_gyr"][()], f["imu_acc"][()] * (1.0 / G),
                              f["imu_mag"][()], f["opt_quat"][()],
                              f["movement"][()].astype(bool), rate=rate)
    else:
        out["hdf5"] = _written_hdf5(d)
    _xio(d, out)
    # the shipped example (NPZ, BROAD layout)
    e = np.load(example_log())
    out["example"] = Raw(example_log(), e["gyr"], e["acc"] * (1.0 / G), e["mag"], e["quat_ref"],
                         e["movement"], rate=float(e["rate"]))
    return out


def _written_hdf5(d):
    """Without the published file beside the checkout: one written with every key and
    attribute of the published layout (trial 09: rest, fast rotation, rest, rotation)."""
    z, n = _trial("09_undisturbed_fast_rotation_with_breaks_B.npz", 20.0, 60.0)
    h5 = d / "09_undisturbed_fast_rotation_with_breaks_B.hdf5"
    with h5py.File(h5, "w") as f:
        f.attrs["sampling_rate"] = float(z["rate"])
        f.attrs["info"] = "BROAD trial 09 (20 s to 80 s)"
        f["imu_gyr"], f["imu_acc"], f["imu_mag"] = z["gyr"][:n], z["acc"][:n], z["mag"][:n]
        f["opt_quat"] = z["quat_ref"][:n]
        f["opt_pos"] = np.zeros((n, 3))
        f["movement"] = z["movement"][:n]
    # m/s^2 -> g as the reader converts: times 1/9.80665
    return Raw(h5, z["gyr"][:n], z["acc"][:n] * (1.0 / G), z["mag"][:n],
               z["quat_ref"][:n], z["movement"][:n], rate=float(z["rate"]))


def _xio(d, out):
    """An x-io-layout sensor_data.csv of a real recording (deg/s, g, uT, time in s, written as
    a logger writes decimals)."""
    z, n = _trial("11_undisturbed_slow_translation_B.npz", 25.0, 30.0)
    t = np.round(np.arange(n) / float(z["rate"]), 6)
    gyr = np.round(np.degrees(z["gyr"][:n]), 6)
    acc = np.round(z["acc"][:n] / G, 7)
    mag = np.round(z["mag"][:n], 4)
    csv = d / "sensor_data.csv"
    with open(csv, "w") as fh:
        fh.write(",".join(XIO) + "\n")
        for k in range(n):
            fh.write(",".join(f"{v:.10g}" for v in (t[k], *gyr[k], *acc[k], *mag[k])) + "\n")
    out["xio"] = Raw(csv, np.radians(gyr), acc, mag, t=t)


KINDS = ["hdf5", "xio", "example"]


def _madgwick(raw):
    f = imufuse_c.MadgwickAHRS(dt=raw.dt() if raw.t is None else raw.dt()[0], beta=0.1,
                               init="first")
    dts = raw.dt()
    return f.run(raw.gyr, raw.acc, raw.mag, **({} if np.ndim(dts) == 0 else {"dt": dts}))


@pytest.mark.parametrize("kind", KINDS)
def test_run(inputs, kind, tmp_path):
    raw = inputs[kind]
    out = tmp_path / "out.npz"
    r = imf("run", raw.path, "-f", "MadgwickAHRS", "-o", out)
    assert r.returncode == 0, r.stderr
    assert "note" not in r.stderr, r.stderr          # read correctly: nothing to question
    z = np.load(out)
    S = _madgwick(raw)
    for j, n in enumerate(("q0", "q1", "q2", "q3")):
        assert np.array_equal(z[n], S[:, j]), n      # bit for bit
    if raw.q is not None:
        e = evaluate(S, raw.q, est_frame="NWU", ref_frame="ENU", movement=raw.movement)
        assert f"inclination {e.inclination:.3f}" in r.stderr, r.stderr
        assert e.inclination < 5.0


@pytest.mark.parametrize("kind", KINDS)
def test_compare(inputs, kind):
    raw = inputs[kind]
    r = imf("compare", raw.path, "-f", "MadgwickAHRS,FusionAHRS,RobustAHRS")
    assert r.returncode == 0, r.stderr
    rows = {ln.split()[0]: ln.split() for ln in r.stdout.splitlines()[2:] if ln[:1].isalpha()}
    assert set(rows) >= {"MadgwickAHRS", "FusionAHRS", "RobustAHRS"}, r.stdout
    S = _madgwick(raw)
    if raw.q is None:
        q = S[-1:] / np.linalg.norm(S[-1:])
        from imufuse.rotations import quat_to_euler
        want = [f"{v:.2f}" for v in np.degrees(quat_to_euler(q)[0])]
        assert rows["MadgwickAHRS"][2:5] == want
        return
    e = evaluate(S, raw.q, est_frame="NWU", ref_frame="ENU", movement=raw.movement)
    assert rows["MadgwickAHRS"][2:5] == [f"{e.inclination:.3f}", f"{e.heading:.3f}",
                                         f"{e.total:.3f}"]
    # FusionAHRS, Fusion's units (deg/s, dt with every sample), scored as every filter
    F = imufuse_c.FusionAHRS().run(np.degrees(raw.gyr), raw.acc, raw.mag, dt=raw.dt())
    qf = F[:, :4] / np.linalg.norm(F[:, :4], axis=1, keepdims=True)
    ef = evaluate(qf, raw.q, est_frame="NWU", ref_frame="ENU", movement=raw.movement)
    assert rows["FusionAHRS"][2:5] == [f"{ef.inclination:.3f}", f"{ef.heading:.3f}",
                                       f"{ef.total:.3f}"]
    assert ef.heading < 20.0      # not the 88 deg of NWU read against ENU


@pytest.mark.parametrize("kind", KINDS)
def test_tune(inputs, kind):
    raw = inputs[kind]
    betas = [0.01, 0.03, 0.1]
    r = imf("tune", raw.path, "-f", "MadgwickIMU", "--grid", "beta=" + ",".join(map(str, betas)),
            "--refine", "0", "-q")
    if raw.q is None:
        assert r.returncode == 4 and "no reference orientation" in r.stderr, r.stderr
        return
    assert r.returncode == 0, r.stderr
    scores = []
    for b in betas:
        f = imufuse_c.MadgwickIMU(dt=raw.dt(), beta=b, init="first")
        scores.append(evaluate(f.run(raw.gyr, raw.acc), raw.q, est_frame="NWU", ref_frame="ENU",
                               movement=raw.movement).inclination)
    best = betas[int(np.argmin(scores))]
    assert f"best: beta={best:.4g} (inclination {min(scores):.3f} deg)" in r.stdout, r.stdout
    table = [ln.split() for ln in r.stdout.splitlines() if re.match(r"\s+[0-9.]+\s+[0-9.]+", ln)]
    assert [float(row[1]) for row in table] == sorted(float(row[1]) for row in table)


@pytest.mark.parametrize("kind", KINDS)
def test_latency(inputs, kind):
    raw = inputs[kind]
    r = imf("latency", raw.path)
    if raw.q is None:
        assert r.returncode == 4 and "no reference orientation" in r.stderr, r.stderr
        return
    assert r.returncode == 0, r.stderr
    d = estimate_latency(raw.gyr, raw.q, 1.0 / raw.rate)
    assert f"by {abs(d) * 1e3:.2f} ms" in r.stdout, r.stdout


@pytest.mark.parametrize("kind", KINDS)
def test_calibrate(inputs, kind, tmp_path):
    raw = inputs[kind]
    out = tmp_path / "cal.json"
    r = imf("calibrate", "mag", raw.path, "-o", out)
    try:
        want = calibrate.mag_ellipsoid(raw.mag)
    except ValueError as e:
        # a recording that does not turn enough: the same reason, exit 4, nothing written
        assert r.returncode == 4 and str(e) in r.stderr and not out.exists(), r.stderr
    else:
        assert r.returncode == 0, r.stderr
        got = json.loads(out.read_text())["magnetometer"]
        assert np.allclose(got["h"], want.params["h"], rtol=0, atol=1e-9)
    r = imf("calibrate", "gyro", raw.path, "-o", out, "--longest-still", "--threshold", "0.05")
    want = None
    try:
        want = calibrate.gyro_offset(raw.gyr, threshold=0.05, restart=True)
    except ValueError as e:
        assert r.returncode == 4 and str(e) in r.stderr, r.stderr
        return
    assert r.returncode == 0, r.stderr
    got = json.loads(out.read_text())["gyroscope"]
    assert np.allclose(got["b"], want.params["b"], rtol=0, atol=1e-12)
    assert "rad/s (" in r.stdout and "deg/s)" in r.stdout


@pytest.mark.parametrize("kind", KINDS)
def test_vario_names_the_missing_barometer(inputs, kind, tmp_path):
    """None of the three has a barometer: exit 4 saying what the vario needs and how to name
    it (the IMU columns themselves are recognised, in every layout)."""
    raw = inputs[kind]
    r = imf("vario", raw.path, "-o", tmp_path / "v.csv")
    assert r.returncode == 4, r.stderr
    if str(raw.path).endswith(".csv"):
        assert "need exactly one barometer column" in r.stderr and "--columns" in r.stderr
    else:
        assert "no barometer: the vario reads CSV logs with a barometer column" in r.stderr, \
            r.stderr


@pytest.mark.parametrize("kind", KINDS)
def test_validate_log(inputs, kind):
    raw = inputs[kind]
    r = imf("validate", "--csrc", "--filter", "MadgwickAHRS", "--dtype", "float32", "--log",
            raw.path, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "bit-exact" in r.stdout
    assert f"{len(raw.gyr)} samples" in r.stdout, r.stdout


@pytest.mark.parametrize("header,need_columns", [("Baro (hPa)", False),
                                                 ("Static port (hPa)", True)])
def test_the_x_io_log_in_vario_with_a_barometer(inputs, tmp_path, header, need_columns):
    """vario reads x-io's headers and units as run does; a barometer column is found by its
    name with its unit from the header (hPa here), and one under a name of its own is named
    with --columns. The altitude is that of the pressures written (an independent ISA
    computation), so the unit was applied."""
    raw = inputs["xio"]
    lines = open(raw.path).read().splitlines()
    p = tmp_path / "with_baro.csv"
    hpa = 1013.25 - 0.012 * np.arange(len(lines) - 1) / 285.7      # a slow climb, ~0.1 m/s
    with open(p, "w") as fh:
        fh.write(lines[0] + f",{header}\n")
        for k, ln in enumerate(lines[1:]):
            fh.write(ln + ("," + f"{hpa[k]:.4f}" if k % 8 == 0 else ",") + "\n")
    args = ["vario", p, "-o", tmp_path / "v.csv", "--no-plot"]
    r = imf(*args)
    if need_columns:
        assert r.returncode == 4 and "--columns" in r.stderr, r.stderr
        r = imf(*args, "--columns", f'pressure="{header}"')
    assert r.returncode == 0, r.stderr
    v = np.loadtxt(tmp_path / "v.csv", delimiter=",", skiprows=1)
    p_pa = np.round(hpa[::8], 4) * 100.0
    want = 44330.8 * (1.0 - (p_pa / 101325.0) ** 0.190263)
    assert np.allclose(v[:, 1], want, rtol=0, atol=1e-3)


README = open(os.path.join(os.path.dirname(__file__), "..", "README.md")).read()
SH = re.findall(r"```sh\n(.*?)```", README, re.S)


def _bash(block, cwd):
    """A README shell block run as written, `imufuse` and `python3` being this Python's."""
    bin_dir = cwd / "bin"
    bin_dir.mkdir(exist_ok=True)
    for name, cmd in (("imufuse", f'exec "{sys.executable}" -m imufuse "$@"'),
                      ("python3", f'exec "{sys.executable}" "$@"')):
        (bin_dir / name).write_text(f"#!/bin/sh\n{cmd}\n")
        (bin_dir / name).chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}:{os.environ['PATH']}", MPLBACKEND="Agg")
    return subprocess.run(["bash", "-e", "-c", block], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


def test_readme_commands_on_the_x_io_log(inputs, tmp_path):
    """'Your own data': the two commands as written, on an x-io-layout sensor_data.csv."""
    block = next(b for b in SH if "sensor_data.csv" in b)
    (tmp_path / "sensor_data.csv").write_bytes(open(inputs["xio"].path, "rb").read())
    r = _bash(block, tmp_path)
    assert r.returncode == 0, r.stderr
    header = (tmp_path / "out.csv").read_text().splitlines()[0].split(",")
    assert header[:5] == ["time", "q0", "q1", "q2", "q3"] and "yaw_deg" in header
    rows = {ln.split()[0] for ln in r.stdout.splitlines() if ln[:1].isalpha()}
    # x-io Fusion's current release is among compare's default filters
    assert {"MadgwickAHRS", "RobustAHRS", "FusionAHRS13", "MahonyIMU"} <= rows, r.stdout
    assert (tmp_path / "cmp.png").stat().st_size > 10_000
    assert "note:" not in r.stderr, r.stderr        # headers and units as the file says


def test_readme_commands_on_the_shipped_example(tmp_path):
    """The shipped example's block as written: compare with a plot, tune, latency (the
    README's 2.06 ms, computed here from the rates)."""
    block = next(b for b in SH if b.startswith("LOG="))
    r = _bash(block, tmp_path)
    assert r.returncode == 0, r.stderr
    e = np.load(example_log())
    d = estimate_latency(e["gyr"], e["quat_ref"], 1.0 / float(e["rate"]))
    said = re.search(r"lags the reference by ([0-9.]+) ms", block).group(1)
    assert f"{d * 1e3:.2f}" == said and f"by {said} ms" in r.stdout, r.stdout
    assert re.search(r"^best: beta=[0-9.]+ \(inclination [0-9.]+ deg\)$", r.stdout, re.M)
    assert (tmp_path / "real.png").stat().st_size > 10_000
