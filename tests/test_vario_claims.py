"""Nair's claims, measured on simulated flights (research/vario_study.py;
the numbers are tabled in docs/vario.md), and `imufuse vario` end to end."""
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import imufuse
import imufuse_c
from imufuse.sim import flight as sf
import vario_study as study

PATHS = [os.path.dirname(os.path.dirname(imufuse.__file__)),
         os.path.dirname(os.path.dirname(imufuse_c.__file__))]


@pytest.fixture(scope="module")
def lag():
    return {name: (l90, steady, rms) for name, l90, steady, rms in study.study_lag()}


def test_fusion_removes_the_lag(lag):
    """Thermal entry: the fused filter follows the true climb rate (90 % as
    soon as the truth, within 0.1 s); the barometer-only filter lags by more
    than 0.35 s at every tuning, and by 2.6 s at Nair's noise settings."""
    truth = lag["truth"][0]
    fused, fused_steady, fused_rms = lag["VarioKF (Nair's defaults, MadgwickIMU)"]
    assert abs(fused - truth) <= 0.1
    baro = {k: v for k, v in lag.items() if k.startswith("barometer only")}
    assert len(baro) == 4
    for name, (l90, _steady, rms) in baro.items():
        assert l90 > fused + 0.35, name
        assert rms > 4 * fused_rms, name
    assert baro["barometer only, var_acc 200"][0] > fused + 2.5
    # at equal (or lower) steady noise the barometer-only filter is slower still
    quiet = [l90 for l90, steady, _ in baro.values() if steady <= 1.5 * fused_steady]
    assert quiet and min(quiet) > fused + 0.6


@pytest.mark.parametrize("bank", [40.0, 60.0])
def test_earth_frame_beats_norm_in_turns_with_a_good_attitude(bank):
    rows = {r[0]: r[1:] for r in study.study_turns(bank)}
    true_rms, true_max, _ = rows["true attitude"]
    norm_rms, norm_max, _ = rows["‖a‖ − 1"]
    assert true_rms < 0.8 * norm_rms
    assert true_max < norm_max
    # ... but not with the default Madgwick: in a coordinated turn the
    # accelerometer points along the body z axis and pulls the attitude level
    assert rows["MadgwickIMU beta 0.1"][0] > 2 * norm_rms
    # a slow filter with a tight gate comes close to the true attitude
    assert rows["MadgwickIMU beta 0.01, gate 0.9-1.1"][0] < 1.3 * norm_rms


def test_gate_in_high_g_turns():
    """60 deg bank (2 g): Nair's gate 0.6-1.4 g cuts the attitude error
    of the ungated filter; at 30 deg (1.15 g, inside the gate) it changes
    nothing of substance."""
    hi = {r[0]: r[1:] for r in study.study_turns(60.0)}
    for beta in ("0.1", "0.01"):
        gated = hi[f"MadgwickIMU beta {beta}, gate 0.6-1.4"]
        free = hi[f"MadgwickIMU beta {beta}"]
        assert gated[2] < 0.75 * free[2], beta      # tilt error
        assert gated[0] < 0.75 * free[0], beta      # climb-rate error
    lo = {r[0]: r[1:] for r in study.study_turns(30.0)}
    assert abs(lo["MadgwickIMU beta 0.1, gate 0.6-1.4"][2]
               - lo["MadgwickIMU beta 0.1"][2]) < 0.5


def test_bias_converges():
    rows, true_bias = study.study_bias(var_bias=(1.0, 0.01))
    assert 0.15 < true_bias < 0.25                   # the simulated 0.02 g, vertical
    (vb1, t1, mean1, rms1, _), (vb2, t2, mean2, rms2, climb2) = rows
    # seed default var_bias 1: unbiased after 30 s, but wandering (RMS 0.03 m/s^2)
    assert abs(mean1) < 0.01 and rms1 < 0.05
    # var_bias 0.01: within 0.05 m/s^2 for good after less than 15 s
    assert t2 < 15.0 and abs(mean2) < 0.01 and rms2 < 0.015
    assert rms2 < rms1 / 2


def test_model_prediction_is_better():
    rows = {(hz, p): (c, a) for hz, p, c, a in study.study_predict(seeds=range(3))}
    for hz in (50.0, 10.0, 4.0):
        assert rows[hz, "model"][0] <= rows[hz, "seed"][0]
        assert rows[hz, "model"][1] <= rows[hz, "seed"][1]
    assert rows[4.0, "model"][0] < 0.8 * rows[4.0, "seed"][0]


# ---- imufuse vario end to end -----------------------------------------------------

def imf(*args):
    e = dict(os.environ, PYTHONPATH=os.pathsep.join(PATHS + [os.environ.get("PYTHONPATH", "")]),
             MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-m", "imufuse", *map(str, args)], env=e,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("column", ["pressure", "baro_alt"])
def test_cli_vario(tmp_path, column):
    fl = sf.flight(sf.thermal_entry(before=15.0, after=15.0), seed=2)
    log = tmp_path / "flight.csv"
    fl.write_log(log, baro=column)
    out = tmp_path / "v.csv"
    r = imf("vario", log, "-o", out, "--plot", tmp_path / "v.png", "--kf", "predict='model'",
            "-p", "beta=0.05", "--acc-gate", "0.6", "1.4")
    assert r.returncode == 0, r.stderr
    data = np.genfromtxt(out, delimiter=",", names=True)
    assert data.dtype.names == ("time", "baro_alt", "altitude", "climb", "bias")
    assert len(data) == len(fl.baro_idx)
    np.testing.assert_allclose(data["time"], fl.baro_t, atol=1e-9)
    err = data["climb"] - fl.climb[fl.baro_idx]
    assert math.sqrt(np.mean(err[data["time"] > 5] ** 2)) < 0.15
    assert np.sqrt(np.mean((data["altitude"] - fl.alt[fl.baro_idx]) ** 2)) < 0.2
    if __import__("importlib").util.find_spec("matplotlib"):
        assert (tmp_path / "v.png").stat().st_size > 1000


def test_cli_vario_errors(tmp_path):
    assert imf("vario", tmp_path / "none.csv").returncode == 3
    bad = tmp_path / "nobaro.csv"
    bad.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,1\n0.01,0,0,0,0,0,1\n")
    r = imf("vario", bad)
    assert r.returncode == 4 and "pressure" in r.stderr
    fl = sf.flight(duration=2, seed=1)
    log = tmp_path / "f.csv"
    fl.write_log(log)
    r = imf("vario", log, "--filter", "Kalman1D", "--no-plot")
    assert r.returncode == 2 and "filter" in r.stderr
