"""imufuse.latency.estimate_latency and `imufuse latency`: the delay of a gyroscope behind
a reference orientation, which RobustIMU's / RobustAHRS's `latency` compensates.

The simulated sensor (imufuse.sim.disturb) integrates exactly as the filters do, so its
delay is 0; delaying its gyro by a known amount must give that amount back. On the BROAD
development trials (when present) the delay is the one docs/recommended-ahrs.md states."""
import glob
import math
import os

import numpy as np
import pytest

import imufuse_c
from imufuse import cli
from imufuse.sim import disturb as sd
from imufuse.latency import estimate_latency
from imufuse.rotations import quat_conj, quat_mul
from broad_data import BROAD, SKIP_REASON

RATE = 500.0
DT = 1.0 / RATE


@pytest.fixture(scope="module")
def rot():
    return sd.scenario("rotation", rate=RATE, duration=40.0, rest=10.0, gyr_noise=0.0)


def delayed(gyr, samples):
    """gyr delayed by a (fractional) number of samples, linear interpolation"""
    k = np.arange(len(gyr)) - samples
    return np.column_stack([np.interp(k, np.arange(len(gyr)), gyr[:, i]) for i in range(3)])


def test_an_undelayed_sensor_has_no_latency(rot):
    # 0 to 1 % of a sample: the interval-midpoint convention of the filters' integration
    assert abs(estimate_latency(rot.gyr, rot.q_true, DT)) < 0.01 * DT


@pytest.mark.parametrize("samples", [1.0, 0.3, 2.5, -0.5])
def test_a_known_delay_is_found(rot, samples):
    d = estimate_latency(delayed(rot.gyr, samples), rot.q_true, DT)
    assert abs(d - samples * DT) < 0.02 * DT


def test_bias_noise_frames_directions_and_dropouts_do_not_change_it(rot):
    g = delayed(rot.gyr, 1.0)
    base = estimate_latency(g, rot.q_true, DT)
    rng = np.random.default_rng(0)
    noisy = g + np.radians([0.5, -0.3, 0.2]) + rng.normal(0, 0.0017, g.shape)
    assert abs(estimate_latency(noisy, rot.q_true, DT) - base) < 0.02 * DT
    # another earth frame (a constant rotation on the earth side): body rates are the same
    z = np.array([math.cos(0.6), 0.0, 0.0, math.sin(0.6)])
    q_other = quat_mul(np.tile(z, (len(g), 1)), rot.q_true)
    assert abs(estimate_latency(g, q_other, DT) - base) < 1e-3 * DT
    assert abs(estimate_latency(g, quat_conj(rot.q_true), DT, ref_direction="earth-to-sensor")
               - base) < 1e-3 * DT
    # a dropout of the reference: left out, not interpolated across
    q = rot.q_true.copy()
    q[5000:5600] = np.nan
    assert abs(estimate_latency(g, q, DT) - base) < 0.02 * DT
    # sample times instead of dt, and a gyro NaN row
    g2 = g.copy()
    g2[7000] = np.nan
    assert abs(estimate_latency(g2, rot.q_true, t=np.arange(len(g)) * DT) - base) < 0.02 * DT


@pytest.mark.parametrize("how", ["sign", "axes", "direction", "deg/s"])
def test_the_wrong_direction_axes_or_units_are_not_timed_silently(rot, how):
    # a gyro that does not follow the reference's rates: an error, never a delay
    g, q = delayed(rot.gyr, 1.0), rot.q_true
    if how == "sign":
        g = -g
    elif how == "axes":
        g = g[:, [1, 0, 2]]
    elif how == "direction":
        q = quat_conj(q)
    else:
        g = np.degrees(g)
    with pytest.raises(ValueError, match="does not follow|edge"):
        estimate_latency(g, q, DT)


def test_the_cli_names_its_options_when_the_gyro_does_not_follow(tmp_path, capsys, rot):
    """The command line said "check the axes, the units and ref_direction" (the Python
    keyword); it names its options, the Python function its keyword."""
    g = delayed(rot.gyr, 1.0)[:, [1, 0, 2]]          # x and y swapped
    with pytest.raises(ValueError, match=r"\(ref_direction='sensor-to-earth'\)$"):
        estimate_latency(g, rot.q_true, DT)
    path = tmp_path / "swapped.csv"
    np.savetxt(path, np.column_stack([np.arange(len(g)) * DT, g, rot.acc / 9.81, rot.q_true]),
               delimiter=",", comments="",
               header="time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,q_w,q_x,q_y,q_z")
    assert cli.main(["latency", str(path)]) == cli.EXIT_DATA
    err = capsys.readouterr().err
    assert "(--ref-direction sensor-to-earth) (--align turns the axes, --gyr-unit sets the " \
        "unit)" in err and "ref_direction" not in err, err


def test_latency_set_from_the_estimate_removes_the_delay_error(rot):
    g = delayed(rot.gyr, 1.0)
    d = estimate_latency(g, rot.q_true, DT)

    def tilt(lat):
        S = imufuse_c.RobustIMU(DT, latency=lat).run(g, rot.acc)
        return float(np.sqrt(np.mean(sd.errors(S[:, :4], rot.q_true)[0][rot.moving] ** 2)))
    assert tilt(d) < 0.5 * tilt(0.0)


def test_too_little_rotation_and_bad_arguments(rot):
    rest = sd.scenario("rest", rate=RATE, duration=5.0, rest=5.0)
    with pytest.raises(ValueError, match="too little rotation"):
        estimate_latency(rest.gyr, rest.q_true, DT)
    with pytest.raises(ValueError, match="edge"):
        estimate_latency(delayed(rot.gyr, 10.0), rot.q_true, DT, max_delay=0.01)
    g, q = rot.gyr, rot.q_true
    for kw, words in [(dict(gyr=g[:, :2]), "gyr"), (dict(q_ref=q[:-1]), "different lengths"),
                      (dict(dt=None), "one of dt"), (dict(t=np.arange(len(g)) * DT), "one of dt"),
                      (dict(dt=-1.0), "dt"), (dict(dt=math.nan), "dt"),
                      (dict(max_delay=0.0), "max_delay"), (dict(ref_direction="x"), "direction")]:
        args = dict(gyr=g, q_ref=q, dt=DT)
        args.update(kw)
        with pytest.raises(ValueError, match=words):
            estimate_latency(args.pop("gyr"), args.pop("q_ref"), args.pop("dt"), **args)
    with pytest.raises(ValueError, match="increasing"):
        estimate_latency(g, q, t=np.zeros(len(g)))
    absurd = g.copy()
    absurd[100, 1] = 1e200                      # finite, but no gyroscope's value
    with pytest.raises(ValueError, match="beyond 1e4 rad/s"):
        estimate_latency(absurd, q, DT)
    with pytest.raises(ValueError, match="usable rate"):
        estimate_latency(g, np.full_like(q, np.nan), DT)


def test_cli(tmp_path, capsys, rot):
    path = tmp_path / "log.csv"
    g = delayed(rot.gyr, 1.0)
    cols = np.column_stack([np.arange(len(g)) * DT, g, rot.acc / 9.81, rot.q_true])
    np.savetxt(path, cols, delimiter=",", comments="",
               header="time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,q_w,q_x,q_y,q_z")
    assert cli.main(["latency", str(path), str(path)]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert "lags the reference by 2.00 ms" in out and "latency=0.0020" in out
    assert "mean over" not in out            # a file named twice is timed once, as compare's
    # a folder and a glob pattern name their logs, as compare's (a file named twice: once)
    (tmp_path / "two").mkdir()
    for name in ("a.csv", "b.csv"):
        (tmp_path / "two" / name).write_bytes(path.read_bytes())
    assert cli.main(["latency", str(tmp_path / "two"), str(tmp_path / "lo*.csv")]) == cli.EXIT_OK
    assert "mean over 3 logs: 2.00 ms" in capsys.readouterr().out
    nref = tmp_path / "noref.csv"
    np.savetxt(nref, cols[:, :7], delimiter=",", comments="",
               header="time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z")
    assert cli.main(["latency", str(nref)]) == cli.EXIT_DATA
    assert "no reference orientation" in capsys.readouterr().err
    lead = tmp_path / "lead.csv"
    cols[:, 1:4] = delayed(rot.gyr, -1.0)
    np.savetxt(lead, cols, delimiter=",", comments="",
               header="time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,q_w,q_x,q_y,q_z")
    assert cli.main(["latency", str(lead)]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert "leads the reference by 2.00 ms" in out and "cannot compensate" in out
    assert "latency=" not in out
    assert cli.main(["latency", str(path), "--max-delay", "0.0005"]) == cli.EXIT_DATA
    assert cli.main(["latency", str(path), "--max-delay", "-1"]) == cli.EXIT_USAGE


def test_a_log_in_step_is_said_to_be(tmp_path, capsys, rot):
    """A log whose gyro and reference are in step was told "the gyroscope leads the reference
    by 0.04 ms ... latency cannot compensate that; check the logger's timestamps": a shift
    below 2 % of a sample (the estimate's accuracy, test_a_known_delay_is_found) is none."""
    path = tmp_path / "step.csv"
    cols = np.column_stack([np.arange(len(rot.gyr)) * DT, rot.gyr, rot.acc / 9.81, rot.q_true])
    np.savetxt(path, cols, delimiter=",", comments="",
               header="time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,q_w,q_x,q_y,q_z")
    assert cli.main(["latency", str(path)]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert "are in step" in out and "below 2% of a sample" in out, out
    assert "cannot compensate" not in out and "latency=" not in out, out


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_broad_delay_is_the_documented_two_milliseconds():
    # docs/recommended-ahrs.md: 1.8 to 2.1 ms on every development trial, mean 2.0
    d = []
    for p in sorted(glob.glob(os.path.join(BROAD, "*.npz"))):
        z = np.load(p)
        d.append(estimate_latency(z["gyr"], z["quat_ref"], 1.0 / float(z["rate"])))
    assert len(d) == 7
    assert all(1.7e-3 < x < 2.2e-3 for x in d) and abs(np.mean(d) - 1.99e-3) < 0.05e-3


def test_max_delay_is_bounded_by_the_data(rot):
    """The search grid grows with max_delay: one beyond half the log is refused at once, not
    a grid of 10^12 shifts (memory bounded by the data, not by the argument)."""
    with pytest.raises(ValueError, match="more than half the log"):
        estimate_latency(rot.gyr, rot.q_true, DT, max_delay=1e9)
    span = (len(rot.gyr) - 1) * DT
    assert abs(estimate_latency(rot.gyr, rot.q_true, DT, max_delay=0.1)) < 0.01 * DT
    with pytest.raises(ValueError, match="more than half the log"):
        estimate_latency(rot.gyr, rot.q_true, DT, max_delay=0.51 * span)
