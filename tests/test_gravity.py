"""Gravity-vector and DCM filters (article 4.1-4.3 and the appendix): accuracy
on simulated data and the article's claims. Accuracy runs use the compiled
filters (the reference equals them bit for bit, test_bitexact.py).

Tilt is compared with rotations.tilt_error: every filter gives ZYX (roll,
pitch) through angles() (or, for runs, the same formula on the state), which
euler_to_quat turns into a yaw-free quaternion with the same body up vector.
"""
import math

import numpy as np
import pytest

import imufuse_c as C
import imufuse.reference as reference
from imufuse import rotations as rot, sim
from imufuse.reference.mahony2d import tilt_angles

from bits import assert_same_bits
from imufuse.registry import CASES_GRAVITY, DTYPES

DEG = math.degrees(1.0)


def up_of(name, S):
    """Body up vector estimate from a run() trajectory, float64."""
    S = np.asarray(S, dtype=float)
    if name == "KK":   # small-angle: up ~ (-pitch, roll, 1); take the exact ZYX vector
        p, r = S[:, 0], S[:, 1]
        return np.column_stack([-np.sin(p), np.sin(r) * np.cos(p), np.cos(r) * np.cos(p)])
    return S[:, 6:9] if name == "DCM" else S[:, 0:3]


def tilt_err(name, S, q_true):
    u = up_of(name, S)
    roll = np.arctan2(u[:, 1], u[:, 2])
    pitch = np.arctan2(-u[:, 0], np.hypot(u[:, 1], u[:, 2]))
    q = rot.euler_to_quat(np.column_stack([roll, pitch, np.zeros(len(u))]))
    return rot.tilt_error(q, q_true)


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


# ---- angles(): an output in double, the same bits on both backends ------------------------

@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in CASES_GRAVITY])
@pytest.mark.parametrize("dtype", DTYPES)
def test_angles_match_reference(case, dtype):
    data = sim.imu("slow", rate=200, duration=2, seed=4)
    c, r = case.make("c", dtype), case.make("ref", dtype)
    acc = data.acc * case.params.get("acc_1g", 1.0)
    assert_same_bits(c.run(data.gyr, acc), r.run(data.gyr, acc))
    got, want = np.array(c.angles()), np.array(r.angles())
    assert got.dtype == np.float64
    assert_same_bits(got, want)


def test_tilt_angles_follow_rotations():
    q = rot.euler_to_quat([0.3, -0.4, 1.2])
    u = rot.quat_rotate_inv(q, [0.0, 0.0, 2.5])   # any length
    assert np.allclose(tilt_angles(*u), rot.quat_to_euler(q)[:2], atol=1e-15)


# ---- accuracy on simulated slow motion (defaults: MEMS noise and gyro bias) ---------------

SLOW = dict(rate=200, duration=60, seed=3)
SETTLE = 20.0  # s, ignored at the start (convergence from level)


@pytest.fixture(scope="module")
def slow():
    return sim.imu("slow", **SLOW)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name,kw", [("Mahony2D", dict(kp=2.0, ki=0.5)),
                                     ("Mahony2D", dict(kp=2.0, ki=0.5, error="exact")),
                                     ("DCM", dict(kp=2.0, ki=0.5))])
def test_mahony_tilt_within_2deg(slow, name, kw, dtype):
    """Slow motion (+-30 deg, <= 0.2 Hz), gyro noise 0.005 rad/s and bias ~0.02 rad/s,
    accelerometer noise 0.005 g: tilt error <= 2 deg RMS after convergence."""
    S = getattr(C, name)(dt=slow.dt, **kw, dtype=dtype).run(slow.gyr, slow.acc)
    e = tilt_err(name, S, slow.q_true)[int(SETTLE / slow.dt):]
    print(f"{name} {kw} {dtype}: tilt RMS {rms(e) * DEG:.3f} deg, max {e.max() * DEG:.3f} deg")
    assert rms(e) * DEG <= 2.0


@pytest.mark.parametrize("dtype", DTYPES)
def test_kk_tilt_within_its_validity(slow, dtype):
    """KK on the same +-30 deg motion. Bound, from the filter's own errors:
    the accelerometer angle is sin(theta), not theta: theta - sin(theta) = 1.35 deg at
    30 deg; the gyro bias |b| ~ 0.021 rad/s lags the P loop by |b| dt / Kp = 0.6 deg;
    the neglected second-order kinematics (Eq. 4.5 keeps only theta w_z) add up to
    ~1 deg at 30 deg and 0.4 rad/s. Max <= 3 deg; RMS (the errors are largest only at
    the extremes) <= 1.5 deg."""
    assert np.abs(rot.quat_to_euler(slow.q_true)[:, :2]).max() <= math.radians(30.0)
    S = C.KK(dt=slow.dt, kp=0.01, dtype=dtype).run(slow.gyr, slow.acc)
    e = tilt_err("KK", S, slow.q_true)[int(SETTLE / slow.dt):]
    print(f"KK {dtype}: tilt RMS {rms(e) * DEG:.3f} deg, max {e.max() * DEG:.3f} deg")
    assert rms(e) * DEG <= 1.5
    assert e.max() * DEG <= 3.0


def test_kk_static_converges_to_small_angle_values():
    """At rest the P loop settles on the accelerometer angles of the small-angle
    model, pitch = sin(theta), roll = sin(phi) cos(theta): exactly, to rounding."""
    roll, pitch = math.radians(20.0), math.radians(-25.0)
    q = rot.euler_to_quat([roll, pitch, 0.7])
    n = 4000
    acc = np.tile(rot.quat_rotate_inv(q, [0.0, 0.0, 1.0]), (n, 1))
    f = C.KK(dt=0.005, kp=0.02)
    f.run(np.zeros((n, 3)), acc)
    assert np.allclose(f.state, [math.sin(pitch), math.sin(roll) * math.cos(pitch)],
                       rtol=0, atol=1e-12)


def test_kk_yaw_coupling_sign():
    """Eq. 4.5 read literally (w_yaw = +w_z) contradicts Eq. 4.2; imufuse uses
    w_yaw = -w_z. Spinning about earth z at 1 rad/s while tilted, the literal sign
    (fed by negating w_z, which enters only the coupling) is many times worse."""
    q0 = rot.euler_to_quat([math.radians(15.0), math.radians(-10.0), 0.0])
    data = sim.imu("yaw_spin", rate=200, duration=30, seed=1, q0=q0, amplitude=1.0)
    lit = data.gyr * [1.0, 1.0, -1.0]
    e_ok = tilt_err("KK", C.KK(dt=data.dt, kp=0.01).run(data.gyr, data.acc), data.q_true)
    e_lit = tilt_err("KK", C.KK(dt=data.dt, kp=0.01).run(lit, data.acc), data.q_true)
    k = int(10 / data.dt)
    print(f"KK yaw spin: RMS {rms(e_ok[k:]) * DEG:.2f} deg; literal sign {rms(e_lit[k:]) * DEG:.2f} deg")
    assert rms(e_ok[k:]) * DEG <= 1.0
    assert rms(e_lit[k:]) >= 10 * rms(e_ok[k:])


@pytest.mark.parametrize("dtype", DTYPES)
def test_multiwii_static_bias_lag(dtype):
    """A constant gyro bias b rotates d by b dt per sample and the complementary step
    removes 1/(F+1) of the error: e_n = (e_{n-1} + b dt) F/(F+1), so the tilt settles at
    e* = b dt F (1.5 s worth of bias at F = 600, dt = 1/400)."""
    dt, F, b, n = 1 / 400, 600, 0.01, 400 * 40
    gyr = np.tile([b, 0.0, 0.0], (n, 1))
    acc = np.tile([0.0, 0.0, 1.0], (n, 1))
    S = C.MultiWii(dt=dt, cmpf=F, dtype=dtype).run(gyr, acc)
    u = S[-1, :3].astype(float)
    e = math.atan2(math.hypot(u[0], u[1]), u[2])
    print(f"MultiWii static bias lag {dtype}: {e:.6f} rad, predicted {b * dt * F:.6f}")
    assert abs(e / (b * dt * F) - 1.0) <= 0.02


def test_multiwii_slow_motion():
    """At the firmware's rate (~400 Hz) on slow motion: without gyro bias the error is
    the accelerometer LPF's lag (15 dt ~ 40 ms at <= 0.45 rad/s, under 1 deg) and noise:
    RMS <= 0.5 deg. With the default bias the error is the lag e* = |b_perp| F dt of
    test_multiwii_static_bias_lag (b_perp: the bias perpendicular to gravity, which is
    what tilts d): RMS within 30 % of its RMS."""
    for bias in (0.0, sim.GYR_BIAS):
        data = sim.imu("slow", rate=400, duration=60, seed=3, gyr_bias=bias)
        S = C.MultiWii(dt=data.dt).run(data.gyr, data.acc)
        k = int(SETTLE / data.dt)
        e = rms(tilt_err("MultiWii", S, data.q_true)[k:])
        up = rot.quat_rotate_inv(data.q_true[k:], [0.0, 0.0, 1.0])
        b = np.broadcast_to(np.asarray(bias, dtype=float), up.shape)
        b_perp = b - up * np.sum(up * b, axis=1, keepdims=True)
        pred = rms(np.linalg.norm(b_perp, axis=1)) * data.dt * 600
        print(f"MultiWii slow bias={bias}: RMS {e * DEG:.3f} deg, bias lag {pred * DEG:.3f} deg")
        if pred == 0.0:
            assert e * DEG <= 0.5
        else:
            assert abs(e / pred - 1.0) <= 0.3


# ---- gyro bias: I converges to minus the bias seen ----------------------------------------

def _bias_sim(euler):
    q0 = rot.euler_to_quat(euler)
    return sim.imu("static", rate=200, duration=60, seed=8, q0=q0)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("euler", [(0.0, 0.0, 0.0), (0.35, -0.25, 1.0)], ids=["level", "tilted"])
@pytest.mark.parametrize("name,kw", [("Mahony2D", dict(kp=2.0, ki=0.5)),
                                     ("Mahony2D", dict(kp=2.0, ki=0.5, error="exact")),
                                     ("DCM", dict(kp=2.0, ki=0.5))])
def test_bias_estimate_within_5pct(name, kw, euler, dtype):
    """At rest only the bias perpendicular to gravity is observable. DCM: I -> -b;
    Mahony2D: the part of I perpendicular to d -> -d x b, so d x I / |d|^2 -> b_perp
    (|d| ~ 1 with Eq. 4.4; |d| = 1 with Eq. 4.3, see test_mahony2d_norm).
    Averaged over the last 10 s."""
    data = _bias_sim(euler)
    S = getattr(C, name)(dt=data.dt, **kw, dtype=dtype).run(data.gyr, data.acc)
    S = S[-2000:].astype(float)
    up = rot.quat_rotate_inv(data.q0, [0.0, 0.0, 1.0])
    b = np.asarray(sim.GYR_BIAS)
    b_perp = b - up * (up @ b)
    if name == "DCM":
        est = -S[:, 9:].mean(axis=0)
        est = est - up * (up @ est)
    else:
        d = S[:, 0:3]
        est = (np.cross(d, S[:, 3:6]) / np.sum(d * d, axis=1, keepdims=True)).mean(axis=0)
    err = np.linalg.norm(est - b_perp) / np.linalg.norm(b_perp)
    print(f"{name} {kw} {euler} {dtype}: bias error {err * 100:.2f} %")
    assert err <= 0.05


def test_dcm_bias_in_motion():
    """In slow motion the DCM's I (body frame) keeps estimating the horizontal-axis
    biases within 5 %; the component about gravity (body z near level) is only weakly
    observable from +-30 deg of tilt and is not asserted."""
    data = sim.imu("slow", rate=200, duration=60, seed=3)
    S = C.DCM(dt=data.dt, kp=2.0, ki=0.5).run(data.gyr, data.acc)
    est = -S[-4000:, 9:11].mean(axis=0)
    b = np.asarray(sim.GYR_BIAS[:2])
    print(f"DCM bias in motion: {est}, true {b}")
    assert np.all(np.abs(est / b - 1.0) <= 0.05)


# ---- article claims ------------------------------------------------------------------------

@pytest.mark.parametrize("dtype", DTYPES)
def test_multiwii_norm_drifts_without_renormalisation(dtype):
    """Appendix: MultiWii never renormalises d (task T2 left to the complementary
    filter). With the accelerometer outside the window (here zero) rotateV alone runs:
    d + d x delta, with delta perpendicular to d, grows |d| by sqrt(1 + |delta|^2) every
    sample: 60 s at 1 rad/s and 400 Hz, +7.8 %. With the window open the pull towards
    |a| = 1 holds |d| within F |delta|^2 / 2 ~ 0.2 % of 1."""
    dt, n = 1 / 400, 24000
    f = C.MultiWii(dt=dt, dtype=dtype)
    f.state = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0]   # LPF empty: the window is closed from the start
    S = f.run(np.tile([0.6, -0.8, 0.0], (n, 1)), np.zeros((n, 3)))
    norm = np.linalg.norm(S[:, :3].astype(float), axis=1)
    pred = (1.0 + dt * dt) ** (np.arange(1, n + 1) / 2)
    rel = np.abs(norm / pred - 1.0).max()
    print(f"MultiWii gyro-only {dtype}: |d| {norm[-1]:.6f} after {n} samples, predicted "
          f"{pred[-1]:.6f}, max rel dev {rel:.2e}")
    assert norm[-1] > 1.07
    assert rel <= (1e-12 if dtype == "float64" else 1e-4)
    data = sim.imu("slow", rate=400, duration=60, seed=3)
    S = C.MultiWii(dt=data.dt, dtype=dtype).run(data.gyr, data.acc)[int(SETTLE / data.dt):]
    dev = np.abs(np.linalg.norm(S[:, :3].astype(float), axis=1) - 1.0).max()
    print(f"MultiWii slow motion {dtype}: max ||d| - 1| = {dev:.2e}")
    assert dev <= 2e-3


@pytest.mark.parametrize("dtype", DTYPES)
def test_dcm_stays_orthonormal_1e6_steps(dtype):
    """4.3: P&B's re-orthogonalisation keeps R orthonormal. 10^6 samples (5000 s at
    200 Hz) of tumbling up to ~2 rad/s with noisy accelerometer: max |R R^T - I| over
    every sample <= 1e-6 (the first-order correction leaves O(|w dt|^4) ~ 1e-7; float32
    rounding a few ulps)."""
    rng = np.random.default_rng(0)
    n, dt = 10 ** 6, 1 / 200
    t = np.arange(n) * dt
    gyr = np.column_stack([2.0 * np.sin(2 * np.pi * 0.3 * t),
                           1.5 * np.cos(2 * np.pi * 0.17 * t + 1.0),
                           1.0 + np.sin(2 * np.pi * 0.05 * t)]) + rng.normal(0, 0.01, (n, 3))
    acc = rng.normal(0, 0.2, (n, 3)) + [0.0, 0.0, 1.0]
    S = C.DCM(dt=dt, kp=2.0, ki=0.5, dtype=dtype).run(gyr, acc)
    worst = 0.0
    for k in range(0, n, 200000):
        R = S[k:k + 200000, :9].astype(float).reshape(-1, 3, 3)
        worst = max(worst, np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max())
    print(f"DCM {dtype}: max |R R^T - I| over 1e6 steps = {worst:.2e}")
    assert worst <= 1e-6


def test_eq44_approx_agrees_with_eq43_near_convergence():
    """4.2: with d a good estimate of a (a.d ~ 1) E = d x (a x d) reduces to a - d.
    P controller, no bias: the two estimates stay within 0.01 deg of each other after
    convergence; with the PI controller and bias within 1 deg (and both within the
    accuracy bound, test_mahony_tilt_within_2deg)."""
    for bias, ki, tol in ((0.0, 0.0, 0.01), (sim.GYR_BIAS, 0.5, 1.0)):
        data = sim.imu("slow", rate=200, duration=60, seed=3, gyr_bias=bias)
        a = C.Mahony2D(dt=data.dt, kp=2.0, ki=ki).run(data.gyr, data.acc)[:, :3]
        e = C.Mahony2D(dt=data.dt, kp=2.0, ki=ki, error="exact").run(data.gyr, data.acc)[:, :3]
        ang = np.arctan2(np.linalg.norm(np.cross(a, e), axis=1), np.sum(a * e, axis=1))
        ang = ang[int(SETTLE / data.dt):]
        print(f"Eq. 4.4 vs 4.3 (ki={ki}): max {ang.max() * DEG:.4f} deg, RMS {rms(ang) * DEG:.4f}")
        assert ang.max() * DEG <= tol


def test_mahony2d_norm():
    """E = a - d pulls |d| to 1. E = d x (a x d) is perpendicular to d, so Eq. 4.3
    does not control |d| (d.d' = d.I: the integral, applied outside the cross
    product, keeps whatever component along d it gathered while d moved); left
    alone |d| grew to 2.33 in these 60 s and without bound after. imufuse
    renormalises d after every Eq. 4.3 update (task T2, csrc/mahony2d.h): |d| = 1
    to rounding, while the integral keeps that component, and the direction is
    the one Eq. 4.3 gives (test_mahony_tilt_within_2deg, test_bias_estimate_within_5pct)."""
    data = _bias_sim((0.35, -0.25, 1.0))
    for dtype, tol in (("float64", 1e-12), ("float32", 1e-6)):
        a = C.Mahony2D(dt=data.dt, kp=2.0, ki=0.5, dtype=dtype).run(data.gyr, data.acc)
        e = C.Mahony2D(dt=data.dt, kp=2.0, ki=0.5, error="exact", dtype=dtype).run(
            data.gyr, data.acc).astype(float)
        na, ne = np.linalg.norm(a[:, :3], axis=1), np.linalg.norm(e[:, :3], axis=1)
        k = len(ne) // 2
        i_par = np.sum(e[k:, 3:6] * e[k:, :3], axis=1)
        print(f"static tilted 60 s {dtype}: |d| approx in [{na.min():.4f}, {na.max():.4f}], "
              f"exact max ||d| - 1| {np.abs(ne - 1.0).max():.2e}, I.d {np.abs(i_par).max():.3f}")
        assert np.abs(na - 1.0).max() <= 0.03
        assert np.abs(ne - 1.0).max() <= tol
        assert np.abs(i_par).max() > 0.005         # what used to lengthen d is still there
    data = sim.imu("slow", **SLOW)
    a = C.Mahony2D(dt=data.dt, kp=2.0, ki=0.5).run(data.gyr, data.acc)[:, :3]
    e = C.Mahony2D(dt=data.dt, kp=2.0, ki=0.5, error="exact").run(data.gyr, data.acc)[:, :3]
    na, ne = np.linalg.norm(a, axis=1), np.linalg.norm(e, axis=1)
    print(f"slow motion: |d| approx in [{na.min():.4f}, {na.max():.4f}], exact max "
          f"||d| - 1| {np.abs(ne - 1.0).max():.2e}")
    assert np.abs(na - 1.0).max() <= 0.03
    assert np.abs(ne - 1.0).max() <= 1e-12


# ---- parameters --------------------------------------------------------------------------

@pytest.mark.parametrize("name,kw,word", [
    ("MultiWii", dict(dt=0.01, acc_lpf_shift=True), "acc_lpf_shift"),
    ("MultiWii", dict(dt=0.01, acc_lpf_shift=17), "acc_lpf_shift"),
    ("MultiWii", dict(dt=0.01, window=0.0), "window"),
    ("MultiWii", dict(dt=0.01, acc_1g=0.0), "acc_1g"),
    ("MultiWii", dict(dt=0.01, cmpf=-1.0), "cmpf"),
    ("KK", dict(dt=0.01, kp=2.0), "kp"),
    ("Mahony2D", dict(dt=0.01, kp=1.0, ki=0.1, error="fast"), "error"),
    ("Mahony2D", dict(dt=0.01, kp=250.0, ki=0.0), "kp"),
    ("DCM", dict(dt=0.01, kp=0.0, ki=0.5), "kp"),
    ("DCM", dict(dt=float("nan"), kp=1.0, ki=0.5), "dt"),
])
@pytest.mark.parametrize("mod", [C, reference], ids=["c", "ref"])
def test_bad_parameters(mod, name, kw, word):
    with pytest.raises(ValueError, match=word):
        getattr(mod, name)(**kw)


def test_mahony2d_ki_zero_accepted():
    C.Mahony2D(dt=0.01, kp=0.5, ki=0.0)
    C.DCM(dt=0.01, kp=0.5, ki=0.0)
