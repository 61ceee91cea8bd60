"""The flight simulator of Nair (2016) (imufuse.sim.flight) and the standard
atmosphere: the ground truth is self-consistent and the sensors have the
stated errors."""
import math

import numpy as np
import pytest

from imufuse.sim import flight as sf
from imufuse import vario
from imufuse.rotations import quat_from_rotvec, quat_mul, quat_rotate, quat_angle_error


def test_atmosphere():
    # ISA: 1000 m is 89874.6 Pa; 0 m is the reference pressure
    assert vario.altitude_to_pressure(1000.0) == pytest.approx(89874.6, abs=0.5)
    assert vario.pressure_to_altitude(vario.P_REF) == 0.0
    h = np.linspace(-300, 5000, 50)
    for p_ref in (101325.0, 98000.0):
        np.testing.assert_allclose(
            vario.pressure_to_altitude(vario.altitude_to_pressure(h, p_ref), p_ref), h,
            atol=1e-8)
    with pytest.raises(ValueError, match="p_ref"):
        vario.pressure_to_altitude(1e5, p_ref=0.0)


def test_deterministic_and_seeded():
    a, b = sf.flight(duration=30, seed=4), sf.flight(duration=30, seed=4)
    c = sf.flight(duration=30, seed=5)
    for name in ("q", "gyr", "acc", "mag", "alt", "pressure"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.acc, c.acc)


def test_truth_is_consistent():
    fl = sf.flight(sf.turning_thermal(), seed=2, gyr_noise=0, gyr_bias=(0, 0, 0),
                   acc_noise=0, acc_bias=(0, 0, 0))
    dt = 1 / fl.rate
    # the gyro integrates exactly to the true attitude
    q = quat_mul(fl.q[:-1], quat_from_rotvec(fl.gyr[1:] * dt))
    assert quat_angle_error(q, fl.q[1:]).max() < 1e-9
    # the accelerometer, rotated to earth, is gravity plus the kinematic acceleration
    f = quat_rotate(fl.q, fl.acc) * sf.GRAVITY
    np.testing.assert_allclose(f[:, 2] - sf.GRAVITY, fl.vacc, atol=1e-9)
    # altitude integrates the climb rate; the climb rate the vertical acceleration
    np.testing.assert_allclose(np.diff(fl.alt), 0.5 * (fl.climb[1:] + fl.climb[:-1]) * dt,
                               atol=1e-12)
    w = fl.climb[0] + np.concatenate([[0], np.cumsum(0.5 * (fl.vacc[1:] + fl.vacc[:-1]) * dt)])
    np.testing.assert_allclose(w, fl.climb, atol=1e-4)


def test_banked_turn_loads_the_accelerometer():
    """Coordinated 40 deg turn: |a| = 1/cos(40 deg) g while the vertical
    acceleration is zero (the case that defeats |a| - 1)."""
    fl = sf.flight([sf.Phase(60.0, 0.0, 40.0)], seed=1, turbulence=0, pilot_motion=0,
                   acc_noise=0, acc_bias=(0, 0, 0))
    steady = slice(int(10 * fl.rate), None)
    norm = np.linalg.norm(fl.acc[steady], axis=1)
    np.testing.assert_allclose(norm, 1 / math.cos(math.radians(40)), rtol=1e-9)
    assert np.abs(fl.vacc[steady]).max() < 1e-12


def test_barometer_noise_and_quantisation():
    fl = sf.flight(duration=60, seed=3)
    err = fl.baro_alt - fl.alt[fl.baro_idx]
    rms = float(np.sqrt(np.mean(err ** 2)))
    assert 0.10 < rms < 0.20                       # MS5611: 10-20 cm RMS
    np.testing.assert_array_equal(fl.pressure, np.round(fl.pressure))   # 1 Pa steps
    assert np.all(np.diff(fl.baro_idx) == 4) and fl.baro_rate == 50.0
    np.testing.assert_allclose(np.diff(fl.baro_t), 0.02)


def test_sensor_errors_as_stated():
    fl = sf.flight([sf.Phase(60.0, 0.0, 0.0)], seed=6, turbulence=0, pilot_motion=0)
    ideal = sf.flight([sf.Phase(60.0, 0.0, 0.0)], seed=6, turbulence=0, pilot_motion=0,
                      acc_noise=0, acc_bias=(0, 0, 0), gyr_noise=0, gyr_bias=(0, 0, 0))
    e = fl.acc - ideal.acc
    np.testing.assert_allclose(e.mean(axis=0), sf.ACC_BIAS, atol=2e-4)
    np.testing.assert_allclose(e.std(axis=0), sf.ACC_NOISE, rtol=0.05)
    g = fl.gyr - ideal.gyr
    np.testing.assert_allclose(g.mean(axis=0), sf.GYR_BIAS, atol=1e-4)


def test_thermal_entry_profile():
    fl = sf.flight(sf.thermal_entry(climb=3.0, sink=-1.0), seed=0, turbulence=0)
    t = fl.t
    assert np.allclose(fl.climb[t < 20], -1.0) and np.allclose(fl.climb[t > 21], 3.0)
    assert fl.vacc.max() == pytest.approx(4.0 * math.pi / 2, rel=1e-3)   # cosine step, 1 s


@pytest.mark.parametrize("kwargs,name", [
    (dict(rate=0), "rate"), (dict(baro_rate=33), "baro_rate"),
    (dict(phases=[sf.Phase(-1, 0)]), r"phases\[0\].duration"),
    (dict(phases=[sf.Phase(10, 0, 85)]), r"phases\[0\].bank"),
    (dict(baro_noise=-1), "baro_noise"), (dict(phases=[]), "phases")])
def test_bad_arguments(kwargs, name):
    with pytest.raises(ValueError, match=f"^{name}:"):
        sf.flight(**kwargs)


def test_log_round_trip(tmp_path):
    fl = sf.flight(duration=5, seed=1)
    for col in ("pressure", "baro_alt"):
        p = tmp_path / f"{col}.csv"
        fl.write_log(p, baro=col)
        log = vario.read_vario_log(str(p))
        assert log["baro_column"] == col
        np.testing.assert_array_equal(np.flatnonzero(np.isfinite(log["baro_alt"])),
                                      fl.baro_idx)
        np.testing.assert_allclose(log["baro_alt"][fl.baro_idx], fl.baro_alt, atol=1e-9)
        np.testing.assert_array_equal(log["acc"], fl.acc)
