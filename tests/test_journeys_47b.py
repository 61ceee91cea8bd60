"""The findings of one issue ("reads what motion-capture tools export, compares many recordings
at once, and shows plots that do not mislead"), each as written, shown fixed; with
tests/test_journeys_47.py, which shows the multi-row headers, `compare LOG...` on simulated
trials and the command line's texts (FusionAHRS suggested, --plot without matplotlib exit 3,
tune's notes, no carriage returns, one "imufuse:" prefix):

  - deg/s without a unit in the header, on a gentle stretch of a real log (the first 14 s of
    x-io's example recording, tests/data): read as rad/s, MadgwickAHRS ends at a pitch of
    -21.2 deg instead of -0.28 deg and nothing said so, even with --strict. The gyroscope is
    now weighed against the turn of the accelerometer's and magnetometer's directions
    (imufuse.plausible.gyro_scale): a note naming --gyr-unit deg/s, an error with --strict
    (exit 4); never on the shipped example, the seven BROAD trials, x-io's log read with its
    units, or a glider's coordinated turns (where the accelerometer keeps its direction). The
    multi-row layout of test_journeys_47 without units, holding a gentle recording, now has
    its deg/s named beside its m/s^2;
  - `compare` over three of BROAD's real recordings (the trial as published, HDF5, and two
    converted ones): each recording's table and the mean over them;
  - the plots: one error quantity per axis (inclination for every filter, heading and total
    in their own panels for the AHRS filters), FusionAHRS's angles from its own start (not a
    jump from the identity it starts at), angle axes scaled to the data (the full +-180 only
    where an angle wraps, said in the panel), every coinciding line named (RobustIMU under
    RobustAHRS), nothing clipped (the demo's heading panel).
"""
import contextlib
import hashlib
import io as _io
import os

import numpy as np
import pytest

from broad_data import BROAD, SKIP_REASON
from imufuse import cli, io, plots
from imufuse.tools import demo
from imufuse.comparison import compare_logs
from imufuse.evaluation import mean_over_trials
from imufuse.plausible import TURN_RATIO, gyro_scale
from imufuse.session import FUSION, RunOptions, Session
from imufuse.sim import flight as glider
from imufuse.sim import imu as simulate
from test_journeys_47 import write_exported, write_plain

HERE = os.path.dirname(os.path.abspath(__file__))
XIO = os.path.join(HERE, "data", "xio_sensor_data_14s.csv")
XIO_SHA256 = "85a45c385d6dfec5c9743a575f4805fc0e14410998efb5bcfc042d9ac46b0740"
HAVE_MPL = plots.available()
needs_mpl = pytest.mark.skipif(not HAVE_MPL, reason="matplotlib (the plot extra)")


def main(*args):
    """The command line in this process: (exit code, stdout, stderr)."""
    out, errs = _io.StringIO(), _io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(errs):
        rc = cli.main([str(a) for a in args])
    return rc, out.getvalue(), errs.getvalue()


def final_pitch(path):
    return float(np.genfromtxt(path, delimiter=",", names=True)["pitch_deg"][-1])


@pytest.fixture(scope="module")
def xio(tmp_path_factory):
    """(the excerpt as x-io wrote it, the same without the '(deg/s)' of the gyro's headers:
    a user's log whose header carries no unit)."""
    with open(XIO, "rb") as fh:
        raw = fh.read()
    assert hashlib.sha256(raw).hexdigest() == XIO_SHA256, "tests/data excerpt changed"
    d = tmp_path_factory.mktemp("xio")
    bare = d / "sensor_data.csv"
    bare.write_bytes(raw.replace(b" (deg/s)", b""))
    assert b"deg/s" not in bare.read_bytes().split(b"\n")[0]
    return XIO, str(bare)


# ---------------------------------------------------------------------------
# 1. deg/s read as rad/s on a gentle stretch of a real log

def test_deg_per_s_on_a_gentle_real_log_is_named(xio, tmp_path):
    """Today: a pitch of -21.2 deg, exit 0, not a word (the 35 rad/s check needs fast motion;
    here the gyro passes 35 "rad/s" in 4 samples of 1400). Now: a note naming the option,
    exit 4 under --strict, and the option gives x-io's own result."""
    given, bare = xio
    log = io.read_log(bare)
    assert log.units["gyr"] == ("rad/s", "default")
    assert np.percentile(np.linalg.norm(log.gyr, axis=1), 99) < 35.0
    g = gyro_scale(log.gyr, log.acc, log.mag, dts=log.dts, dt=log.dt)
    assert 25.0 < g.ratio < 80.0 and g.windows >= 8, g          # 57.3 read as 1: deg/s
    assert set(g.used) == {"acc", "mag"} and all(g.sensors[k][1] > TURN_RATIO for k in g.used)
    (note,) = log.suspicions
    assert note.startswith("the gyroscope, read as rad/s (assumed), turns ") and \
        note.endswith("these look like deg/s; give --gyr-unit deg/s"), note

    rc, _, errs = main("run", bare, "-f", "MadgwickAHRS", "-o", tmp_path / "wrong.csv")
    assert rc == 0 and f"imufuse: note: {note}" in errs, errs
    assert final_pitch(tmp_path / "wrong.csv") == pytest.approx(-21.2, abs=0.05)
    rc, _, errs = main("run", bare, "-f", "MadgwickAHRS", "-o", tmp_path / "s.csv", "--strict")
    assert rc == 4 and f"imufuse: error: {bare}: {note} (--strict)" in errs, errs
    assert not (tmp_path / "s.csv").exists()
    for path, extra in ((bare, ["--gyr-unit", "deg/s", "--strict"]), (given, ["--strict"])):
        out = tmp_path / f"right{len(extra)}.csv"
        rc, _, errs = main("run", path, "-f", "MadgwickAHRS", "-o", out, *extra)
        assert rc == 0 and "gyroscope" not in errs, errs
        assert final_pitch(out) == pytest.approx(-0.28, abs=0.05)


def test_the_exported_layout_without_units_names_both(tmp_path):
    """The layout of test_journeys_47 as the issue shows it (a group row over an axis row, no
    unit but the time's) holding a gentle recording (rates up to 20 deg/s, nowhere near 35):
    read, its m/s^2 named as before, and now its deg/s too; the options give the values of
    the same numbers under imufuse's header with units."""
    m = simulate("slow", rate=100.0, duration=8.0, seed=3, amplitude=0.2)
    p = write_exported(tmp_path / "vicon.csv", m)
    log = io.read_log(p)
    acc, gyr = log.suspicions
    assert "--acc-unit m/s2" in acc and "--gyr-unit deg/s" in gyr, log.suspicions
    assert np.percentile(np.linalg.norm(log.gyr, axis=1), 99) < 35.0
    given = io.read_log(p, gyr_unit="deg/s", acc_unit="m/s2")
    plain = io.read_log(write_plain(tmp_path / "plain.csv", m))
    assert given.suspicions == [] and np.array_equal(given.gyr, plain.gyr)


def test_x_io_read_with_its_units_is_silent(xio):
    given, _ = xio
    log = io.read_log(given)
    assert log.units["gyr"] == ("deg/s", "header") and log.suspicions == []
    g = gyro_scale(log.gyr, log.acc, log.mag, dts=log.dts, dt=log.dt)
    # 12.8 s at rest and one second of motion: too few windows turn far enough for a verdict
    # (and those that do are below the limit)
    assert not g.ratio > TURN_RATIO
    assert all(r < TURN_RATIO for _, r, _ in g.sensors.values())


def _broad_files():
    return sorted(os.path.join(BROAD, f) for f in os.listdir(BROAD) if f.endswith(".npz"))


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_the_check_is_silent_on_the_real_logs_read_right():
    """The shipped example and the seven BROAD trials (fast rotations up to 1400 deg/s,
    translations, tapping, magnets): the ratio is 0.5 to 1.0, no note; the same gyros in
    deg/s read as rad/s are named."""
    paths = [io.example_log()] + _broad_files()
    assert len(paths) == 8
    for p in paths:
        log = io.read_log(p)
        assert log.suspicions == [], (p, log.suspicions)
        g = gyro_scale(log.gyr, log.acc, log.mag, dt=log.dt)
        assert 0.4 < g.ratio < 1.5 and g.windows > 500, (p, g)
        w = gyro_scale(np.degrees(log.gyr), log.acc, log.mag, dt=log.dt)
        assert w.ratio > 3 * TURN_RATIO, (p, w)


def test_coordinated_turns_without_a_magnetometer_say_nothing():
    """A glider's coordinated turn keeps the accelerometer's direction while the gyro turns:
    a ratio of about 45 whose turns point nowhere in particular (no verdict), 2.6 with the
    pilot swinging by 3 deg (below the limit); with the magnetometer, 1."""
    for swing in (0.0, 1.0, 3.0):
        f = glider.flight(glider.turning_thermal(), rate=100.0, seed=1, pilot_motion=swing)
        g = gyro_scale(f.gyr, f.acc, None, dt=0.01)
        assert not g.ratio > TURN_RATIO, (swing, g)
        assert gyro_scale(f.gyr, f.acc, f.mag, dt=0.01).ratio == pytest.approx(1.0, abs=0.05)
        assert gyro_scale(np.degrees(f.gyr), f.acc, f.mag, dt=0.01).ratio > 3 * TURN_RATIO


# ---------------------------------------------------------------------------
# 2. compare over three of BROAD's real recordings

@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_compare_three_broad_recordings(tmp_path):
    """The trial as published (HDF5) and two trials converted to NPZ by the dataset's
    authors: each one's table, then the mean over the three of each filter's RMS."""
    pytest.importorskip("h5py", reason="h5py (the hdf5 extra) reads the published trial")
    logs = [os.path.join(BROAD, "published", "03_undisturbed_slow_rotation_C.hdf5"),
            os.path.join(BROAD, "11_undisturbed_slow_translation_B.npz"),
            os.path.join(BROAD, "25_disturbed_tapping_B.npz")]
    filters = "MadgwickAHRS,RobustIMU"
    rc, out, errs = main("compare", *logs, "-f", filters)
    assert rc == 0, errs
    for p in logs:
        assert f"{p}: " in out
    assert out.count("MadgwickAHRS ") == 4 and "mean over 3 logs" in out, out
    c = compare_logs(logs, filters.split(","))
    means = c.means()
    mean_rows = out.split("mean over 3 logs")[1]
    for name, metric, col in (("MadgwickAHRS", "total", 3), ("RobustIMU", "inclination", 1)):
        assert means[name] == mean_over_trials(c.evaluations(name))
        row = next(ln.split()[1:6] for ln in mean_rows.splitlines() if ln.startswith(name))
        assert float(row[col]) == pytest.approx(means[name][metric], abs=5e-4), row
    # the published trial is the converted trial 03, number for number
    s = Session(os.path.join(BROAD, "03_undisturbed_slow_rotation_C.npz"))
    ev = s.score(s.run("RobustIMU", {}, RunOptions()))
    assert c.logs[0].results["RobustIMU"].evaluation.inclination == \
        pytest.approx(ev.inclination, rel=1e-12)


# ---------------------------------------------------------------------------
# 3. plots that do not mislead

@pytest.fixture
def captured(monkeypatch):
    """The figures the command line and the demo draw, by plot function."""
    figs = {}
    for name in ("plot_euler", "plot_3d_errors"):
        real = getattr(plots, name)

        def keep(*a, _real=real, _name=name, **k):
            figs[_name] = _real(*a, **k)
            return figs[_name]
        monkeypatch.setattr(plots, name, keep)
    return figs


def _legend(ax):
    leg = ax.get_legend()
    return [t.get_text() for t in leg.get_texts()] if leg else []


def _lines(ax):
    return {ln.get_label(): ln for ln in ax.get_lines() if not ln.get_label().startswith("_")}


def _finite(ln):
    y = np.asarray(ln.get_ydata(), dtype=float)
    return y[np.isfinite(y)]


@needs_mpl
def test_compare_plot_one_quantity_per_axis_and_fusion_from_its_start(tmp_path, captured):
    """Today the bottom panel drew total errors for the AHRS filters and inclination errors
    for the IMU filters on one axis (the AHRS ones looked worse), and FusionAHRS's yaw started
    at 0 and jumped to -90 deg although the title says 'init first'."""
    names = ["MadgwickAHRS", "RobustIMU", "RobustAHRS", FUSION]
    rc, out, errs = main("compare", io.example_log(), "-f", ",".join(names),
                         "--plot", tmp_path / "c.png")
    assert rc == 0 and (tmp_path / "c.png").stat().st_size > 10000, errs
    fig = captured["plot_euler"]
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels[:3] == ["roll (deg, NWU)", "pitch (deg, NWU)", "yaw (deg, NWU)"]
    assert labels[3:] == ["inclination error (deg)", "heading error (deg)", "total error (deg)"]
    assert set(_lines(fig.axes[3])) == set(names)                  # every filter, one quantity
    for ax in fig.axes[4:]:
        assert set(_lines(ax)) == {"MadgwickAHRS", "RobustAHRS", FUSION}   # the AHRS filters
    # the panels hold what compare's table prints: its RMS over the drawn samples
    s = Session(io.example_log())
    for i, m in ((3, "inclination"), (4, "heading"), (5, "total")):
        e = _finite(_lines(fig.axes[i])["MadgwickAHRS"])
        rms = getattr(s.score(s.run("MadgwickAHRS", {}, RunOptions())), m)
        assert np.sqrt(np.mean(e ** 2)) == pytest.approx(rms, rel=1e-9)
        lo, hi = fig.axes[i].get_ylim()
        kept = [_finite(ln) for n, ln in _lines(fig.axes[i]).items()]
        assert lo <= min(k.min() for k in kept) and max(k.max() for k in kept) <= hi, m
    # FusionAHRS from the end of its start-up (initialising), said in the legend
    r = s.run(FUSION, {}, RunOptions())
    k = int(np.argmax(r.states[:, list(r.cls.state_names).index("initialising")] == 0))
    t = s.log.t
    yaw = np.asarray(_lines(fig.axes[2])[FUSION].get_ydata(), dtype=float)
    first = int(np.argmax(np.isfinite(yaw)))
    assert first == k and 2.9 < t[k] - t[0] < 3.1
    ref = _lines(fig.axes[2])["reference"]
    assert abs(yaw[first] - np.asarray(ref.get_ydata(), dtype=float)[first]) < 3.0  # no identity
    assert any(x.startswith(f"{FUSION} (from 3 s") for x in _legend(fig.axes[0])), \
        _legend(fig.axes[0])
    # RobustAHRS's roll and pitch are RobustIMU's: named
    assert "RobustAHRS (roll, pitch ≈ RobustIMU)" in _legend(fig.axes[0])
    # the shipped log's roll and yaw wrap at +-180: the full scale, said in the panel
    for i in (0, 2):
        assert fig.axes[i].get_ylim() == (-195, 195)
        assert "wraps at ±180°" in fig.axes[i].get_title(loc="right")
    assert fig.axes[1].get_title(loc="right") == ""


@needs_mpl
@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_angle_axes_scaled_to_the_data(tmp_path, captured):
    """Today roll and yaw were on a fixed +-180 deg scale: trial 11's roll, within +-12 deg,
    was a flat line."""
    rc, _, errs = main("compare", os.path.join(BROAD, "11_undisturbed_slow_translation_B.npz"),
                       "-f", "RobustAHRS", "--plot", tmp_path / "t.png")
    assert rc == 0, errs
    fig = captured["plot_euler"]
    for i, most in ((0, 40), (1, 50), (2, 120)):
        ax = fig.axes[i]
        lo, hi = ax.get_ylim()
        y = np.concatenate([_finite(ln) for ln in _lines(ax).values()])
        assert lo <= y.min() and y.max() <= hi and hi - lo < most, (ax.get_ylabel(), lo, hi)
        assert "wraps" not in ax.get_title(loc="right")


@needs_mpl
def test_the_demo_names_every_coinciding_line_and_clips_nothing(tmp_path, captured):
    """Today RobustIMU lay exactly under RobustAHRS in the demo's tilt panel with no tag, and
    the heading panel was cut at -20 deg (MahonyAHRS and MadgwickAHRS start at -27)."""
    rc = demo.run_demo(out_dir=str(tmp_path), names=["MahonyAHRS", "MadgwickAHRS", "RobustIMU",
                                                     "RobustAHRS"],
                       stream=_io.StringIO(), say=lambda m: None)
    assert rc == 0 and (tmp_path / "demo_3d.png").exists()
    fig = captured["plot_3d_errors"]
    tilt, heading = fig.axes[:2]
    assert tilt.get_ylabel() == "tilt error (deg)" and heading.get_ylabel() == "heading error (deg)"
    assert "RobustAHRS (tilt ≈ RobustIMU)" in _legend(tilt), _legend(tilt)
    for ax in (tilt, heading):
        lo, hi = ax.get_ylim()
        for name, ln in _lines(ax).items():
            y = _finite(ln)
            assert lo <= y.min() and y.max() <= hi, (ax.get_ylabel(), name, y.min(), lo)
    assert heading.get_ylim()[0] < -26


@needs_mpl
def test_plot_rules_on_made_up_angles(tmp_path):
    """The rules on their own: an angle within +-15 deg fills its panel; one that wraps gets
    the full scale, the note and a mark at both ends of each break; one error quantity per
    panel; filters coinciding where both have a value named with the parts they share."""
    t = np.linspace(0.0, 20.0, 2001)
    e = np.zeros((len(t), 3))
    e[:, 0] = np.radians(12 * np.sin(t))
    e[:, 2] = np.radians(170 + 20 * t)                   # wraps at +-180 several times
    imu = e.copy()
    imu[:, 2] = np.nan
    fusion = e + np.radians(1.0)
    errs = {"inclination": {"A": np.abs(np.sin(t)), "IMU": np.abs(np.sin(t)),
                            FUSION: 1 + np.cos(t)},
            "heading": {"A": -30 * np.exp(-t), FUSION: np.sin(t)}}
    fig = plots.plot_euler(tmp_path / "r.png", t, {"A": e, "IMU": imu, FUSION: fusion},
                           errors=errs, starts={FUSION: 300, "A": (0, "nothing")})
    roll, pitch, yaw, incl, head = fig.axes
    lo, hi = roll.get_ylim()
    assert -15 < lo <= -12 and 12 <= hi < 15 and roll.get_title(loc="right") == ""
    assert yaw.get_ylim() == (-195, 195) and "wraps at ±180°" in yaw.get_title(loc="right")
    marks = [ln for ln in yaw.get_lines() if ln.get_marker() == "D"]
    assert marks and all(np.all(np.abs(np.abs(_finite(m)) - 180) < 10) for m in marks)
    assert [a.get_ylabel() for a in (incl, head)] == ["inclination error (deg)",
                                                       "heading error (deg)"]
    assert set(_lines(head)) == {"A", FUSION} and head.get_ylim()[0] <= -30   # nothing clipped
    texts = _legend(roll)
    assert "IMU (roll, pitch = A)" in texts and f"{FUSION} (from 3 s: its start-up not drawn)" \
        in texts and "A" in texts, texts
    y = np.asarray(_lines(roll)[FUSION].get_ydata(), dtype=float)
    assert np.isnan(y[:300]).all() and np.isfinite(y[300:]).all()
    # the one-panel form of before still draws
    one = plots.plot_euler(tmp_path / "o.png", t, {"A": e}, errors={"A": np.abs(np.sin(t))},
                           error_label="error (deg)")
    assert [a.get_ylabel() for a in one.axes][3] == "error (deg)"
