"""Fixed-point filters against their float64 twins on simulated motion
(imufuse.sim), on the same int16 counts: tilt RMS difference within the
budget of each profile, and no drift over 10^6 samples."""
from __future__ import annotations


import numpy as np
import pytest

import twins  # noqa: E402

import imufuse.reference as reference  # noqa: E402
from imufuse import sim  # noqa: E402

GYR_SCALE = 1.0642e-3   # 2000 deg/s full scale, rad/s per count
ACC_1G = 4096           # +-8 g full scale, counts per g
RATE = 512.0
BUDGET = {"32": 0.5, "8": 1.5}   # deg, tilt RMS difference to the float64 twin


def _backend():
    try:
        import imufuse_c
        if hasattr(imufuse_c, "FILTERS_FIXED"):
            return imufuse_c
    except ImportError:
        pass
    return reference


def _data(motion, duration, seed=1, **kw):
    imu = sim.imu(motion, rate=RATE, duration=duration, seed=seed, **kw)
    g, a = twins.quantise(imu, GYR_SCALE, ACC_1G)
    return imu, g, a


def _float_twin(name, **kw):
    """The float64 filter the fixed-point one ports, fed the same counts in
    physical units."""
    import imufuse_c

    def run(g, a, dt):
        return getattr(imufuse_c, name)(dt, **kw).run(g * GYR_SCALE, a.astype(float))[:, :4]
    return run


QUAT = {
    "MahonyIMUQ": (dict(kp=1.0, ki=0.05), _float_twin("MahonyIMU", kp=1.0, ki=0.05)),
    "MadgwickIMUQ": (dict(beta=0.1), _float_twin("MadgwickIMU", beta=0.1, delta_s="simplified")),
}


@pytest.mark.parametrize("profile", ["32", "8"])
@pytest.mark.parametrize("name", list(QUAT))
@pytest.mark.parametrize("motion", ["slow", "fast", "tilt_steps"])
def test_tilt_rms_vs_float64_twin(name, profile, motion):
    imu, g, a = _data(motion, duration=20.0)
    kw, twin = QUAT[name]
    f = getattr(_backend(), name)(imu.dt, **kw, gyr_scale=GYR_SCALE, profile=profile)
    q = f.run(g, a)[:, :4].astype(float)
    ref = twin(g, a, imu.dt)
    d = twins.tilt_between(q, ref)
    rms = float(np.sqrt(np.mean(d ** 2)))
    print(f"{name} p{profile} {motion}: tilt RMS diff {rms:.4f} deg, max {d.max():.4f} deg")
    assert rms <= BUDGET[profile]
    # the twin itself tracks the truth (the comparison is meaningful)
    assert np.sqrt(np.mean(twins.tilt_between(ref, imu.q_true)[len(ref) // 4:] ** 2)) < 3.0


@pytest.mark.parametrize("profile", ["32", "8"])
@pytest.mark.parametrize("name", list(QUAT))
def test_no_drift_over_1e6_samples(name, profile):
    """10^6 samples (~33 min at 512 Hz) of slow motion with gyro bias: the
    tilt error to the truth in the last 10 % is no larger than in the first
    10 % after convergence (plus a small margin), and |q| stays 1."""
    mod = _backend()
    if mod is reference:
        pytest.skip("needs the compiled imufuse_c (10^6 samples)")
    n = 1_000_000
    imu = sim.imu("slow", rate=RATE, duration=n / RATE, seed=5)
    g, a = twins.quantise(imu, GYR_SCALE, ACC_1G)
    kw, _ = QUAT[name]
    f = getattr(mod, name)(imu.dt, **kw, gyr_scale=GYR_SCALE, profile=profile)
    q = f.run(g, a)[:, :4].astype(float) * 2.0 ** -30
    err = twins.tilt_between(q, imu.q_true)
    first = np.sqrt(np.mean(err[n // 20: n // 20 + n // 10] ** 2))
    last = np.sqrt(np.mean(err[-n // 10:] ** 2))
    norm = np.linalg.norm(q, axis=1)
    print(f"{name} p{profile}: tilt RMS first {first:.3f} last {last:.3f} deg; "
          f"|q|-1 max {np.abs(norm - 1).max():.2e}")
    assert last <= first * 1.5 + 0.1
    assert np.abs(norm - 1.0).max() < 1e-3


def test_complementary1dq_vs_float64_twin():
    ax = sim.axis1d("slow", rate=500.0, duration=20.0, seed=2)
    gs, an = 1e-3, 1e-4
    r = np.clip(np.round(ax.gyr / gs), -32768, 32767).astype(np.int16)
    ang = np.clip(np.round(ax.acc_angle / an), -32768, 32767).astype(np.int16)
    mod = _backend()
    f = mod.Complementary1DQ(1 / 500, 0.995, gyr_scale=gs, angle_scale=an)
    th = f.run(r, ang)[:, 0] * 2.0 ** -15 * an
    tw = reference.Complementary1D(1 / 500, 0.995).run(r * gs, ang * an)[:, 0]
    assert np.degrees(np.sqrt(np.mean((th - tw) ** 2))) < 0.01


def test_mahony1dbiasq_vs_float64_twin():
    ax = sim.axis1d("slow", rate=500.0, duration=30.0, seed=3)
    gs, an = 1e-3, 1e-4
    r = np.clip(np.round(ax.gyr / gs), -32768, 32767).astype(np.int16)
    ang = np.clip(np.round(ax.acc_angle / an), -32768, 32767).astype(np.int16)
    mod = _backend()
    f = mod.Mahony1DBiasQ(1 / 500, 2.0, 0.2, gyr_scale=gs, angle_scale=an)
    s = f.run(r, ang)
    sf = f.state_to_float(s)
    tw = reference.Mahony1DBias(1 / 500, 2.0, 0.2).run(r * gs, ang * an)
    assert np.degrees(np.sqrt(np.mean((sf[:, 0] - tw[:, 0]) ** 2))) < 0.01
    assert np.sqrt(np.mean((sf[:, 1] - tw[:, 1]) ** 2)) < 2e-3   # rad/s


@pytest.mark.parametrize("profile", ["32", "8"])
def test_multiwiiq_and_kkq_vs_float64_twins(profile):
    """MultiWiiQ and KKQ against the float64 MultiWii and KK on the same
    counts (KK is a small-angle filter: 10 deg amplitude)."""
    imu, g, a = _data("slow", duration=30.0, seed=4, amplitude=np.radians(10.0))
    mod = _backend()
    mw = mod.MultiWiiQ(imu.dt, 600, gyr_scale=GYR_SCALE, acc_1g=ACC_1G, profile=profile)
    d = mw.state_to_float(mw.run(g, a))
    tw = reference.MultiWii(imu.dt, 600, acc_1g=ACC_1G).run(g * GYR_SCALE, a.astype(float))
    cos = np.sum(d[:, :3] * tw[:, :3], 1) / np.linalg.norm(d[:, :3], axis=1) / np.linalg.norm(tw[:, :3], axis=1)
    ang = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    kk = mod.KKQ(imu.dt, 0.002, gyr_scale=GYR_SCALE, profile=profile)
    t = kk.state_to_float(kk.run(g, a))
    tk = reference.KK(imu.dt, 0.002).run(g * GYR_SCALE, a.astype(float))
    e = np.degrees(np.abs(t - tk))
    print(f"p{profile}: MultiWiiQ direction RMS diff {np.sqrt(np.mean(ang ** 2)):.4f} deg, "
          f"accLPF max diff {np.abs(d[:, 3:] - tw[:, 3:]).max():.3f} counts; "
          f"KKQ RMS diff {np.sqrt(np.mean(e ** 2)):.4f} deg")
    assert np.sqrt(np.mean(ang ** 2)) < 0.05
    assert np.abs(d[:, 3:] - tw[:, 3:]).max() < 1.0
    assert np.sqrt(np.mean(e ** 2)) < 0.05
