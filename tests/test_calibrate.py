"""Calibration from recordings (Nair 2016): raw logs simulated from known
parameters, the parameters recovered within stated tolerances, degenerate
data refused with a clear error, and `imufuse calibrate` end to end."""
import json
import re
import os

import numpy as np
import pytest

import imufuse
import imufuse_c
from imufuse.calibration import fit as cal
from imufuse import sim
from imufuse.rotations import euler_to_quat, quat_rotate_inv
from cli_here import imf_here

PATHS = [os.path.dirname(os.path.dirname(imufuse.__file__)),
         os.path.dirname(os.path.dirname(imufuse_c.__file__))]


# ---- gyroscope -------------------------------------------------------------------------------

def test_gyro_offset_recovered():
    b = np.array([0.021, -0.013, 0.0071])
    g = np.random.default_rng(0).normal(0, 0.004, (500, 3)) + b
    c = cal.gyro_offset(g)
    # tolerance: 4 standard errors of the mean
    np.testing.assert_allclose(c.params["b"], b, atol=4 * 0.004 / np.sqrt(500))
    np.testing.assert_allclose(c.apply(g).mean(axis=0), 0.0, atol=1e-12)
    assert c.as_json() == {"M": np.eye(3).tolist(), "s": [1.0, 1.0, 1.0],
                           "b": np.asarray(c.params["b"]).tolist()}


def test_gyro_motion_is_refused_or_restarted():
    b = np.array([0.02, 0.0, -0.01])
    g = np.random.default_rng(1).normal(0, 0.003, (1000, 3)) + b
    g[300:420, 1] += 0.4                     # someone picks the unit up
    with pytest.raises(ValueError, match=r"moved .* samples 300\.\.419 .* axis y"):
        cal.gyro_offset(g)
    c = cal.gyro_offset(g, restart=True)
    assert c.figures["samples"] == (420, 1000)
    np.testing.assert_allclose(c.params["b"], b, atol=4 * 0.003 / np.sqrt(580))
    g[::150, 0] += 1.0                       # no still stretch of 100 samples left
    with pytest.raises(ValueError, match="no still stretch"):
        cal.gyro_offset(g, restart=True, min_samples=200)


def test_a_still_gyro_in_deg_s_read_as_rad_s_is_named():
    """A still log in deg/s without a unit (an offset of 3 deg/s read as 3 rad/s, noise 0.3
    deg/s read as rad/s) was called motion ("the unit moved ... keep it still and record
    again"); the message names the unit. A log that moved, in either unit, is still motion."""
    b = np.array([3.0, -2.0, 3.0])                                 # deg/s
    g = np.random.default_rng(2).normal(0, 0.3, (1000, 3)) + b
    with pytest.raises(ValueError, match=r"these look like deg/s read as rad/s: the median "
                       r"reading, \(3\.0\d, -2(\.0\d)?, 2\.9\d\), is no gyro's offset in rad/s "
                       r"\(17\d deg/s\), .* give --gyr-unit deg/s"):
        cal.gyro_offset(g)
    np.testing.assert_allclose(cal.gyro_offset(np.radians(g)).params["b"], np.radians(b),
                               atol=4 * np.radians(0.3) / np.sqrt(1000))
    g[300:420, 1] += 300.0                   # picked up, in deg/s: motion in any unit
    with pytest.raises(ValueError, match=r"the unit moved during the offset calibration"):
        cal.gyro_offset(g)


# ---- accelerometer: six positions ----------------------------------------------------------

# each axis down (+1 g read on it) and up, as (roll, pitch) in NWU: a level sensor reads +z
POSES = {"+z": (0, 0), "-z": (np.pi, 0), "+x": (0, -np.pi / 2), "-x": (0, np.pi / 2),
         "+y": (np.pi / 2, 0), "-y": (-np.pi / 2, 0)}
A_TRUE = np.array([[4100.0, 12.0, -20.0], [-8.0, 4050.0, 15.0], [25.0, -5.0, 4200.0]])
B_TRUE = np.array([60.0, -110.0, 35.0])


def six_position_log(poses=POSES, hold=400, move=200, noise=0.003, seed=0):
    """Raw counts: still phases of `hold` samples, joined by `move` samples of
    rotation (changing readings). raw = A a_g + b + noise, a_g in g."""
    rng = np.random.default_rng(seed)
    rows, ranges, k = [], [], 0
    keys = list(poses)
    for i, key in enumerate(keys):
        q = euler_to_quat([*poses[key], 0.0])
        a = np.tile(quat_rotate_inv(q, [0, 0, 1.0]), (hold, 1))
        rows.append(a)
        ranges.append((k + 20, k + hold - 20))
        k += hold
        if i + 1 < len(keys):
            nxt = euler_to_quat([*poses[keys[i + 1]], 0.0])
            t = np.linspace(0, 1, move)[:, None]
            qs = (1 - t) * q + t * nxt
            qs /= np.linalg.norm(qs, axis=1, keepdims=True)
            rows.append(quat_rotate_inv(qs, np.tile([0, 0, 1.0], (move, 1)))
                        + rng.normal(0, 0.2, (move, 3)))     # handling shakes
            k += move
    a = np.vstack(rows) + rng.normal(0, noise, (k, 3))
    return a @ A_TRUE.T + B_TRUE, ranges


@pytest.mark.parametrize("given_ranges", [True, False], ids=["ranges", "found"])
def test_six_position_seed_formulas(given_ranges):
    raw, ranges = six_position_log()
    c = cal.accel_six_position(raw, ranges if given_ranges else None)
    # per-axis sensitivity and offset (Nair's formulas): the diagonal of A,
    # and the offset plus the cross-axis leakage (which Nair ignores)
    np.testing.assert_allclose(c.figures["sensitivity"], np.diag(A_TRUE), rtol=2e-4)
    np.testing.assert_allclose(c.params["b"], B_TRUE, atol=3.0)
    np.testing.assert_array_equal(c.params["M"], np.eye(3))
    assert sorted(c.figures["positions"]) == sorted(POSES)


def test_six_position_cross_axis():
    raw, ranges = six_position_log()
    c = cal.accel_six_position(raw, cross_axis=True)
    np.testing.assert_allclose(c.params["b"], B_TRUE, atol=1.0)    # counts (2.5e-4 g)
    # the calibrated readings of the whole log are unit vectors where still
    got = c.apply(raw)
    for s, e in ranges:
        np.testing.assert_allclose(np.linalg.norm(got[s:e].mean(axis=0)), 1.0, atol=2e-4)
    # M s = A^-1 within the noise
    Ms = np.asarray(c.params["M"]) @ np.diag(c.params["s"])
    np.testing.assert_allclose(Ms @ A_TRUE, np.eye(3), atol=2e-4)
    assert c.figures["magnitude_error"] < 3e-4


def test_six_position_degenerate():
    five = {k: v for k, v in POSES.items() if k != "-y"}
    raw, ranges = six_position_log(five)
    with pytest.raises(ValueError, match="six positions needed"):
        cal.accel_six_position(raw)
    doubled = dict(five, **{"+z2": (0.01, 0.0)})
    raw, ranges = six_position_log(doubled)
    with pytest.raises(ValueError, match=r"too few orientations: no still phase with axis -y"):
        cal.accel_six_position(raw)
    tilted = dict(POSES, **{"-y": (-np.pi / 4, 0)})       # between -y and +z
    raw, ranges = six_position_log(tilted)
    with pytest.raises(ValueError, match="not one axis up or down"):
        cal.accel_six_position(raw, ranges)
    with pytest.raises(ValueError, match="ranges"):
        cal.accel_six_position(raw, [(0, 10)] * 5 + [(10, 10**7)])


# ---- magnetometer ------------------------------------------------------------------------------

S_TRUE = np.array([[1.10, 0.06, -0.03], [0.06, 0.92, 0.04], [-0.03, 0.04, 1.02]])  # symmetric
H_TRUE = np.array([180.0, -75.0, 40.0])
FIELD = 480.0   # raw counts of the earth's field


def mag_log(motion="fast", S=S_TRUE, noise=0.002, seed=3, duration=60.0, **kw):
    """Raw magnetometer along a simulated motion: m_u = S^-1 m + h."""
    d = sim.imu(motion, rate=100.0, duration=duration, seed=seed, mag_noise=noise,
                mag_field=FIELD, **kw)
    return d.mag @ np.linalg.inv(S).T + H_TRUE


def test_ellipsoid_fit_recovers_soft_and_hard_iron():
    raw = mag_log()
    c = cal.mag_ellipsoid(raw)
    S = np.asarray(c.params["S"])
    np.testing.assert_allclose(c.params["h"], H_TRUE, atol=0.01 * FIELD)   # 1 % of the field
    # S up to the overall scale (the field strength is a free choice)
    k = np.trace(S) / np.trace(S_TRUE)
    np.testing.assert_allclose(S / k, S_TRUE, atol=0.01)
    assert c.figures["residual"] < 0.005 * c.figures["field"]
    np.testing.assert_allclose(c.figures["field"], FIELD * k, rtol=0.01)
    # the calibrated field has one strength in every orientation
    r = np.linalg.norm(c.apply(raw), axis=1)
    assert r.std() / r.mean() < 0.005
    fixed = cal.mag_ellipsoid(raw, field=1.0)
    np.testing.assert_allclose(np.linalg.norm(fixed.apply(raw), axis=1), 1.0, atol=0.01)


def test_minmax_hard_iron_and_its_limit():
    diag = np.diag([1.1, 0.9, 1.0])
    # min/max needs every axis to have pointed along the field both ways: 60 s
    # of this motion leave x 19 counts short of its extreme, 240 s do not
    raw = mag_log(S=diag, duration=240.0)
    c = cal.mag_minmax(raw)
    np.testing.assert_allclose(c.params["h"], H_TRUE, atol=0.02 * FIELD)
    S = np.asarray(c.params["S"])
    np.testing.assert_allclose(S / S[2, 2], diag / diag[2, 2], atol=0.03)
    # with soft iron off the axes min/max leaves more residual than the fit
    raw = mag_log()
    assert cal.mag_minmax(raw).figures["residual"] > 3 * cal.mag_ellipsoid(raw).figures["residual"]


def test_flat_rotation_is_refused():
    # turning about the vertical only: the readings lie on a circle
    n = 2000
    yaw = np.linspace(0, 6 * np.pi, n)
    q = euler_to_quat(np.column_stack([np.zeros(n), np.zeros(n), yaw]))
    m = quat_rotate_inv(q, sim.mag_earth(strength=FIELD))
    raw = m @ np.linalg.inv(S_TRUE).T + H_TRUE
    for fit in (cal.mag_ellipsoid, cal.mag_minmax):
        with pytest.raises(ValueError, match="flat rotation"):
            fit(raw)
    with pytest.raises(ValueError, match=r"mag: expected an \(N, 3\) array"):
        cal.mag_ellipsoid(raw[:, :2])
    with pytest.raises(ValueError, match="at least 20 samples"):
        cal.mag_ellipsoid(raw[:5])


# ---- the command line -----------------------------------------------------------------------

def imf(*args):
    """The command line through main() in this process (its messages and exit codes)."""
    return imf_here(*args)


def _write(path, prefix, x):
    with open(path, "w") as fh:
        fh.write(",".join(["time"] + [f"{prefix}_{c}" for c in "xyz"]) + "\n")
        for k, row in enumerate(x):
            fh.write(",".join([repr(k * 0.01)] + [repr(float(v)) for v in row]) + "\n")


def test_cli_calibrate(tmp_path):
    out = tmp_path / "calib.json"
    b = np.array([0.5, -1.2, 0.3])                       # deg/s
    g = np.random.default_rng(0).normal(0, 0.1, (300, 3)) + b
    _write(tmp_path / "gyr.csv", "gyr", g)
    r = imf("calibrate", "gyro", tmp_path / "gyr.csv", "-o", out, "--gyr-unit", "deg/s")
    assert r.returncode == 0, r.stderr
    raw, _ = six_position_log()
    _write(tmp_path / "acc.csv", "acc", raw)
    assert imf("calibrate", "accel", tmp_path / "acc.csv", "-o", out).returncode == 0
    _write(tmp_path / "mag.csv", "mag", mag_log())
    r = imf("calibrate", "mag", tmp_path / "mag.csv", "-o", out)
    assert r.returncode == 0, r.stderr
    assert "residual" in r.stdout
    data = json.loads(out.read_text())
    assert set(data) == {"gyroscope", "accelerometer", "magnetometer"}
    assert set(data["gyroscope"]) == {"M", "s", "b"} == set(data["accelerometer"])
    assert set(data["magnetometer"]) == {"S", "h"}
    np.testing.assert_allclose(data["gyroscope"]["b"], np.radians(b), atol=4e-4)
    np.testing.assert_allclose(data["accelerometer"]["b"], B_TRUE, atol=3.0)
    np.testing.assert_allclose(data["magnetometer"]["h"], H_TRUE, atol=0.01 * FIELD)
    # refused data: exit code 4 (bad data, not a bad command line) with the reason and the
    # option that takes the longest still stretch instead
    g[100:150] += 5.0
    _write(tmp_path / "moved.csv", "gyr", g)
    r = imf("calibrate", "gyro", tmp_path / "moved.csv", "-o", tmp_path / "x.json",
            "--gyr-unit", "deg/s")
    assert r.returncode == 4 and "samples 100..149" in r.stderr and "--longest-still" in r.stderr
    assert not (tmp_path / "x.json").exists()
    r = imf("calibrate", "gyro", tmp_path / "moved.csv", "-o", tmp_path / "x.json",
            "--gyr-unit", "deg/s", "--longest-still")
    assert r.returncode == 0, r.stderr
    assert re.search(r"rad/s \(\[[-0-9. ]+\] deg/s\) from samples 150\.\.", r.stdout), r.stdout
    # a magnetometer that never turned: refused, the existing file untouched
    _write(tmp_path / "still.csv", "mag", np.tile(H_TRUE, (200, 1)))
    before = out.read_bytes()
    for method in ("minmax", "ellipsoid", "sphere"):
        r = imf("calibrate", "mag", tmp_path / "still.csv", "-o", out, "--method", method)
        assert r.returncode == 4 and "never turned" in r.stderr, r.stderr
        assert out.read_bytes() == before
    assert imf("calibrate", "mag", tmp_path / "none.csv", "-o", out).returncode == 3


def test_coverage_is_checked_with_numbers():
    """Readings from a cap of directions (a unit turned a little) or a few noisy rows do not
    give a calibration: refused with the axis, the sample and how far off the axis it was."""
    rng = np.random.default_rng(0)
    v = rng.normal(size=(200000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    cap = v[v[:, 2] > np.cos(np.radians(18.0))] * FIELD + H_TRUE
    for fit in (cal.mag_minmax, cal.mag_ellipsoid):
        with pytest.raises(ValueError, match=r"do not cover the directions: where [+-][xyz] is "
                                             r"(largest|smallest) \(sample \d+\) the other axes "
                                             r"are 0\.\d\d of the field"):
            fit(cap)
    with pytest.raises(ValueError, match="do not cover the directions"):
        cal.mag_minmax(rng.normal(size=(12, 3)) + H_TRUE)


def test_absurd_gyro_readings_are_no_offset():
    """Readings of 1e307 at rest (finite, absurd): refused naming the unit, instead of an
    infinite offset blamed on the output file."""
    g = np.full((200, 3), 1e307)
    with pytest.raises(ValueError, match=r"^gyr: a median reading of 1e\+307 at rest is no gyro"):
        cal.gyro_offset(g)
    b = cal.gyro_offset(np.full((200, 3), 30000.0)).params["b"]     # int16 counts still fine
    assert np.all(b == 30000.0)


def test_calibrate_refuses_to_merge_into_a_malformed_file(tmp_path):
    """-o into an existing file: a malformed section of another sensor (a file `run
    --calibration` would refuse) is refused by name and the file is left as it was; a
    malformed section of the sensor being calibrated is replaced."""
    g = np.random.default_rng(1).normal(0, 0.1, (300, 3)) + np.array([0.5, -1.2, 0.3])
    _write(tmp_path / "gyr.csv", "gyr", g)
    out = tmp_path / "calib.json"
    bad = '{"accelerometer": {"M": [1, 2], "s": [1, 1, 1], "b": [0, 0, 0]}}\n'
    out.write_text(bad)
    r = imf("calibrate", "gyro", tmp_path / "gyr.csv", "-o", out, "--gyr-unit", "deg/s")
    # refused as an -o that is not a calibration file at all is: bad file contents (exit 4)
    assert r.returncode == 4 and "accelerometer.M" in r.stderr and "nothing written" in r.stderr, \
        (r.returncode, r.stderr)
    assert out.read_text() == bad
    out.write_text("[1, 2]\n")
    r2 = imf("calibrate", "gyro", tmp_path / "gyr.csv", "-o", out, "--gyr-unit", "deg/s")
    assert r2.returncode == r.returncode and "not a calibration file" in r2.stderr
    out.write_text('{"gyroscope": {"b": "zero"}}\n')
    r = imf("calibrate", "gyro", tmp_path / "gyr.csv", "-o", out, "--gyr-unit", "deg/s")
    assert r.returncode == 0, r.stderr
    assert set(json.loads(out.read_text())["gyroscope"]) == {"M", "s", "b"}
