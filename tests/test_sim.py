"""Tests of imufuse.rotations and imufuse.sim (ground truth and simulated IMU samples)."""

import math

import numpy as np
import pytest

from imufuse import rotations as rot
from imufuse import sim

try:
    from scipy.spatial.transform import Rotation
except ImportError:  # pragma: no cover - scipy is optional
    Rotation = None

needs_scipy = pytest.mark.skipif(Rotation is None, reason="scipy not installed")

E_Z = np.array([0.0, 0.0, 1.0])


def random_quats(n, seed=1):
    return rot.quat_normalize(np.random.default_rng(seed).standard_normal((n, 4)))


def same_rotation(p, q, tol=1e-12):
    """|<p, q>| == 1: equal up to the quaternion sign."""
    return np.allclose(np.abs(np.sum(p * q, axis=-1)), 1.0, rtol=0, atol=tol)


def bits_equal(a, b):
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


# ------------------------------------------------------------------------------------------
# rotations

def test_quat_mul_composes_matrices_and_is_associative():
    p, q, r = random_quats(50, 1), random_quats(50, 2), random_quats(50, 3)
    np.testing.assert_allclose(rot.quat_to_matrix(rot.quat_mul(p, q)),
                               rot.quat_to_matrix(p) @ rot.quat_to_matrix(q), atol=1e-14)
    np.testing.assert_allclose(rot.quat_mul(rot.quat_mul(p, q), r),
                               rot.quat_mul(p, rot.quat_mul(q, r)), atol=1e-14)
    np.testing.assert_allclose(rot.quat_mul(p, rot.quat_conj(p)),
                               np.tile(rot.IDENTITY, (50, 1)), atol=1e-15)
    # broadcasting (4,) x (N, 4)
    np.testing.assert_allclose(rot.quat_mul(p[0], q), rot.quat_mul(np.tile(p[0], (50, 1)), q))


def test_quat_mul_known_product():
    qx = rot.quat_from_axis_angle([1, 0, 0], math.pi / 2)
    qy = rot.quat_from_axis_angle([0, 1, 0], math.pi / 2)
    # body y after qx (x) qy: R_x R_y e_y = R_x e_y = e_z
    np.testing.assert_allclose(rot.quat_rotate(rot.quat_mul(qx, qy), [0, 1, 0]), E_Z, atol=1e-15)
    # i * j = k
    np.testing.assert_array_equal(rot.quat_mul([0, 1, 0, 0], [0, 0, 1, 0]), [0, 0, 0, 1])


def test_matrix_round_trip_and_orthonormal():
    q = random_quats(2000)
    R = rot.quat_to_matrix(q)
    assert R.shape == (2000, 3, 3)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-14)
    q2 = rot.matrix_to_quat(R)
    assert np.all(q2[:, 0] >= 0)
    assert same_rotation(q, q2)
    # Shepperd pivots: 180 deg rotations about each axis (trace -1) survive
    for axis in np.eye(3):
        qa = rot.quat_from_axis_angle(axis, math.pi)
        assert same_rotation(rot.matrix_to_quat(rot.quat_to_matrix(qa)), qa)


def test_quat_rotate_matches_matrix_and_inverse():
    q = random_quats(100)
    v = np.random.default_rng(5).standard_normal((100, 3))
    np.testing.assert_allclose(rot.quat_rotate(q, v), np.einsum("nij,nj->ni",
                               rot.quat_to_matrix(q), v), atol=1e-14)
    np.testing.assert_allclose(rot.quat_rotate_inv(q, rot.quat_rotate(q, v)), v, atol=1e-14)
    # a level sensor yawed by 90 deg: body x points to earth y (west in NWU)
    q = rot.quat_from_axis_angle(E_Z, math.pi / 2)
    np.testing.assert_allclose(rot.quat_rotate(q, [1, 0, 0]), [0, 1, 0], atol=1e-15)


def test_euler_round_trip_and_zyx_order():
    rng = np.random.default_rng(7)
    e = np.column_stack([rng.uniform(-math.pi, math.pi, 500),
                         rng.uniform(-1.5, 1.5, 500),
                         rng.uniform(-math.pi, math.pi, 500)])
    q = rot.euler_to_quat(e)
    np.testing.assert_allclose(rot.quat_to_euler(q), e, atol=1e-12)
    # q = qz(yaw) qy(pitch) qx(roll)
    qz = rot.quat_from_axis_angle([0, 0, 1], e[:, 2])
    qy = rot.quat_from_axis_angle([0, 1, 0], e[:, 1])
    qx = rot.quat_from_axis_angle([1, 0, 0], e[:, 0])
    np.testing.assert_allclose(rot.quat_mul(qz, rot.quat_mul(qy, qx)), q, atol=1e-15)
    # quaternion round trip through Euler, sign-invariant
    q = random_quats(500)
    assert same_rotation(rot.euler_to_quat(rot.quat_to_euler(q)), q, tol=1e-11)


def test_euler_gimbal_lock_clamped():
    # slightly non-unit quaternion at pitch = +90 deg: asin argument is clamped, no NaN
    q = rot.euler_to_quat([0.3, math.pi / 2, 0.0]) * (1 + 1e-12)
    e = rot.quat_to_euler(q)
    assert np.all(np.isfinite(e))
    assert e[1] == pytest.approx(math.pi / 2, abs=1e-6)


def test_rotvec_exp_log():
    rv = np.random.default_rng(3).standard_normal((300, 3)) * 1.5
    rv = rv[np.linalg.norm(rv, axis=1) < math.pi]
    q = rot.quat_from_rotvec(rv)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(rot.quat_to_rotvec(q), rv, atol=1e-13)
    np.testing.assert_allclose(rot.quat_to_rotvec(-q), rv, atol=1e-13)
    # zero and tiny angles: exact identity / first-order
    np.testing.assert_array_equal(rot.quat_from_rotvec([0, 0, 0]), [1, 0, 0, 0])
    tiny = np.array([1e-9, -2e-9, 3e-9])
    np.testing.assert_allclose(rot.quat_from_rotvec(tiny), [1, *(tiny / 2)], rtol=1e-15, atol=0)
    np.testing.assert_allclose(rot.quat_to_rotvec(rot.quat_from_rotvec(tiny)), tiny, rtol=1e-14)
    # axis-angle agrees with rotvec
    axis = np.array([1.0, 2.0, -2.0])
    np.testing.assert_allclose(rot.quat_from_axis_angle(axis, 0.7),
                               rot.quat_from_rotvec(axis / 3 * 0.7), atol=1e-16)


@needs_scipy
def test_scipy_conversion_agrees_with_scipy():
    q = random_quats(500)
    r = Rotation.from_quat(rot.to_scipy(q))
    np.testing.assert_allclose(r.as_matrix(), rot.quat_to_matrix(q), atol=1e-14)
    v = np.random.default_rng(9).standard_normal((500, 3))
    np.testing.assert_allclose(r.apply(v), rot.quat_rotate(q, v), atol=1e-13)
    np.testing.assert_allclose(r.apply(v, inverse=True), rot.quat_rotate_inv(q, v), atol=1e-13)
    # scipy's intrinsic "ZYX" (yaw, pitch, roll) is our ZYX (roll, pitch, yaw)
    np.testing.assert_allclose(r.as_euler("ZYX")[:, ::-1], rot.quat_to_euler(q), atol=1e-12)
    rv = r.as_rotvec()
    assert same_rotation(rot.quat_from_rotvec(rv), q)
    np.testing.assert_allclose(rot.quat_to_rotvec(q), rv, atol=1e-12)
    # from_scipy takes arrays and Rotation objects; round trip is exact
    np.testing.assert_array_equal(rot.from_scipy(rot.to_scipy(q)), q)
    assert same_rotation(rot.from_scipy(r), q)
    np.testing.assert_allclose(rot.matrix_to_quat(r.as_matrix()),
                               rot.from_scipy(Rotation.from_matrix(r.as_matrix())
                                              .as_quat(canonical=True)), atol=1e-14)


def test_scipy_conversion_layout_without_scipy():
    np.testing.assert_array_equal(rot.to_scipy([1, 2, 3, 4]), [2, 3, 4, 1])
    np.testing.assert_array_equal(rot.from_scipy([2, 3, 4, 1]), [1, 2, 3, 4])


def test_error_metrics():
    q_true = rot.euler_to_quat([0.2, -0.1, 1.0])
    # pure yaw difference: no tilt error, heading error = the yaw step
    q_yaw = rot.quat_mul(rot.quat_from_axis_angle(E_Z, 0.3), q_true)
    assert rot.tilt_error(q_yaw, q_true) == pytest.approx(0.0, abs=1e-15)
    assert rot.heading_error(q_yaw, q_true) == pytest.approx(0.3, abs=1e-12)
    assert rot.quat_angle_error(q_yaw, q_true) == pytest.approx(0.3, abs=1e-12)
    # rotation about a body horizontal axis at level: tilt error = angle
    q_lvl = rot.IDENTITY
    q_roll = rot.quat_from_axis_angle([1, 0, 0], 0.05)
    assert rot.tilt_error(q_roll, q_lvl) == pytest.approx(0.05, rel=1e-12)
    assert rot.tilt_error(q_roll, -q_lvl) == pytest.approx(0.05, rel=1e-12)
    assert rot.quat_angle_error(-q_roll, q_lvl) == pytest.approx(0.05, rel=1e-12)
    # tiny errors stay accurate (atan2 form, not acos)
    q_tiny = rot.quat_from_axis_angle([0, 1, 0], 1e-9)
    assert rot.tilt_error(q_tiny, q_lvl) == pytest.approx(1e-9, rel=1e-6)
    # heading wrap: 179 deg vs -179 deg is 2 deg, not 358
    a = rot.euler_to_quat([0, 0, math.radians(179)])
    b = rot.euler_to_quat([0, 0, math.radians(-179)])
    assert rot.heading_error(a, b) == pytest.approx(math.radians(-2), abs=1e-12)
    assert rot.heading_error(b, a) == pytest.approx(math.radians(2), abs=1e-12)
    # batches
    qs = random_quats(20)
    assert rot.tilt_error(qs, qs[0]).shape == (20,)
    assert np.all(rot.quat_angle_error(qs, qs) < 1e-7)


def test_shape_errors():
    with pytest.raises(ValueError, match=r"q must have shape .*\(3,\)"):
        rot.quat_conj([1, 2, 3])
    with pytest.raises(ValueError, match="R must have shape"):
        rot.matrix_to_quat(np.eye(4))
    with pytest.raises(ValueError, match="zero"):
        rot.quat_normalize([0, 0, 0, 0])


# ------------------------------------------------------------------------------------------
# trajectories

KINDS3 = ["static", "slow", "tilt_steps", "yaw_spin", "fast"]


@pytest.mark.parametrize("kind", KINDS3)
def test_gyro_integration_reproduces_truth(kind):
    d = sim.imu(kind, rate=200, duration=12, seed=4, q0="random" if kind != "slow" else None,
                gyr_bias=0, gyr_noise=0, acc_noise=0, mag_noise=0)
    q = d.q0
    out = np.empty_like(d.q_true)
    for k, w in enumerate(d.gyr):
        q = rot.quat_mul(q, rot.quat_from_rotvec(w * d.dt))
        out[k] = q
    np.testing.assert_allclose(out, d.q_true, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(d.q_true, axis=1), 1.0, atol=1e-12)
    assert len(d) == 2400 and d.t[0] == pytest.approx(1 / 200) and d.t[-1] == pytest.approx(12)


@pytest.mark.parametrize("q0", [(1.0, 0.0, -0.0, 0.0), (-0.0, 1.0, 0.0, -0.0), (0.5, 0.5, 0.5, 0.5)])
def test_integrate_at_rest_is_the_step_by_step_product(q0):
    """integrate() repeats q over a run of exactly zero rate once a step gives q back bit for
    bit: the same bits as multiplying every step, zeros of either sign included."""
    from imufuse.sim.motion import integrate
    om = np.zeros((3000, 3))
    om[500:510, 0] = 0.3       # a turn between rests
    om[900:1500, 1] = -0.0     # a rate of minus zero is no rest for the fast path
    om[2000] = (1e-300, 0.0, 0.0)
    got = integrate(q0, om, 0.01)
    want = np.empty_like(got)
    q = np.asarray(q0)
    for k, dq in enumerate(rot.quat_from_rotvec(om * 0.01)):
        q = rot.quat_mul(q, dq)
        want[k] = q
    assert bits_equal(got, want)


def test_earth_frame_custom_rates():
    # constant earth-z rate from a tilted start: tilt unchanged, heading advances at that rate
    q0 = rot.euler_to_quat([0.3, -0.2, 0.0])
    tr = sim.trajectory("custom", omega=lambda t: np.tile([0.0, 0.0, 0.5], (len(t), 1)),
                        frame="earth", rate=100, duration=4, q0=q0)
    assert np.all(rot.tilt_error(tr.q, q0) < 1e-12)
    yaw = np.unwrap(rot.quat_to_euler(tr.q)[:, 2])
    np.testing.assert_allclose(yaw, 0.5 * tr.t, atol=1e-12)
    np.testing.assert_allclose(rot.quat_rotate(tr.q[:-1], tr.omega[1:]),
                               np.tile([0, 0, 0.5], (len(tr) - 1, 1)), atol=1e-12)
    # and the body rates integrate back to q
    np.testing.assert_allclose(sim.integrate(q0, tr.omega, tr.dt), tr.q, atol=1e-12)


def test_custom_array_and_yaw_spin_agree():
    a = sim.trajectory("yaw_spin", amplitude=0.7, rate=50, duration=3)
    b = sim.trajectory(omega=np.tile([0.0, 0.0, 0.7], (150, 1)), rate=50)
    assert b.params["kind"] == "custom" and len(b) == 150
    np.testing.assert_allclose(a.q, b.q, atol=1e-14)


def test_slow_follows_bounded_euler_path():
    amp = math.radians(20)
    tr = sim.trajectory("slow", amplitude=amp, rate=100, duration=30, seed=11)
    s = {k: np.array(v) for k, v in tr.params["sines"].items()}
    t = np.concatenate([[0.0], tr.t])
    e = np.sum(s["amp"] * np.sin(2 * np.pi * s["freq"] * t[:, None, None] + s["phase"]), axis=1)
    path = rot.euler_to_quat(e)
    assert same_rotation(tr.q0, path[0], tol=1e-15)
    assert np.all(rot.quat_angle_error(tr.q, path[1:]) < 1e-10)
    e_q = rot.quat_to_euler(tr.q)
    assert np.all(np.abs(e_q[:, :2]) <= amp + 1e-9)
    assert np.all(np.abs(e_q[:, 2]) <= 2 * amp + 1e-9)
    assert np.max(np.abs(e_q[:, :2])) > 0.3 * amp       # it actually moves
    assert np.max(np.linalg.norm(tr.omega, axis=1)) < 2 * np.pi * 0.2 * 4 * amp


def test_tilt_steps_hold_and_reach_targets():
    tr = sim.trajectory("tilt_steps", rate=100, duration=8, seed=2, hold=1.0, ramp=0.5)
    targets = tr.params["targets"]
    assert len(targets) == 5          # 1 + 0.5 + 1 + 0.5 ... over 8 s -> ramps at 1, 2.5, 4, 5.5, 7
    # orientation at the end of each ramp (sample index 149 for the first) equals the target
    for i, (r, p) in enumerate(targets[:4]):
        k = 100 + i * 150 + 50 - 1
        assert rot.quat_angle_error(tr.q[k], rot.euler_to_quat([r, p, 0.0])) < 1e-12
        assert np.all(tr.omega[k + 1:k + 101] == 0.0)   # hold
    assert np.all(tr.omega[:100] == 0.0)


def test_fast_rate_bound():
    tr = sim.trajectory("fast", amplitude=6.0, max_freq=3.0, rate=400, duration=5, seed=3)
    assert np.max(np.abs(tr.omega)) <= 6.0 + 1e-12
    assert np.max(np.abs(tr.omega)) > 2.0


# ------------------------------------------------------------------------------------------
# IMU samples

def test_static_noise_free_reads_up():
    d = sim.imu("static", rate=100, duration=1, gyr_bias=0, gyr_noise=0, acc_noise=0,
                mag_noise=0)
    np.testing.assert_array_equal(d.acc, np.tile([0.0, 0.0, 1.0], (100, 1)))
    np.testing.assert_array_equal(d.gyr, np.zeros((100, 3)))
    np.testing.assert_array_equal(d.q_true, np.tile([1.0, 0, 0, 0], (100, 1)))
    dip = sim.MAG_DIP
    np.testing.assert_allclose(d.mag, np.tile([math.cos(dip), 0, -math.sin(dip)], (100, 1)),
                               atol=1e-16)
    d2 = sim.imu("static", rate=100, duration=1, acc_noise=0, acc_unit="m/s^2")
    np.testing.assert_allclose(d2.acc, np.tile([0.0, 0.0, sim.GRAVITY], (100, 1)), atol=1e-15)
    # upside down: -1 g on z
    d3 = sim.imu("static", rate=100, duration=0.1, acc_noise=0,
                 q0=rot.quat_from_axis_angle([1, 0, 0], math.pi))
    np.testing.assert_allclose(d3.acc, np.tile([0.0, 0.0, -1.0], (10, 1)), atol=1e-15)


@pytest.mark.parametrize("kind", KINDS3)
def test_noise_free_acc_is_gravity_in_body_frame(kind):
    d = sim.imu(kind, rate=100, duration=5, seed=8, acc_noise=0, mag_noise=0)
    R = rot.quat_to_matrix(d.q_true)
    np.testing.assert_allclose(d.acc, np.einsum("nji,j->ni", R, E_Z), atol=1e-14)
    # acc is the third row of R (what R^T e_z means)
    np.testing.assert_allclose(d.acc, R[:, 2, :], atol=1e-14)


def test_linear_acceleration():
    d0 = sim.imu("slow", rate=100, duration=5, seed=8, acc_noise=0)
    d = sim.imu("slow", rate=100, duration=5, seed=8, acc_noise=0, lin_acc=3.0)
    np.testing.assert_array_equal(d.q_true, d0.q_true)
    assert 0.5 < np.max(np.abs(d.lin_acc)) <= 3.0
    np.testing.assert_allclose(d.acc - d0.acc, rot.quat_rotate_inv(d.q_true, d.lin_acc) /
                               sim.GRAVITY, atol=1e-14)
    # callable profile: free fall (lin_acc = -g e_z) reads zero
    df = sim.imu("fast", rate=100, duration=1, acc_noise=0,
                 lin_acc=lambda t: np.tile([0, 0, -sim.GRAVITY], (len(t), 1)))
    np.testing.assert_allclose(df.acc, 0.0, atol=1e-15)


@pytest.mark.parametrize("dip_deg", [-30.0, 0.0, 45.0, 66.0])
def test_mag_inclination(dip_deg):
    dip = math.radians(dip_deg)
    d = sim.imu("fast", rate=100, duration=5, seed=5, acc_noise=0, mag_noise=0, mag_dip=dip,
                mag_field=48.0)
    np.testing.assert_allclose(np.linalg.norm(d.mag, axis=1), 48.0, rtol=1e-14)
    cosang = np.sum(d.acc * d.mag, axis=1) / (np.linalg.norm(d.acc, axis=1) * 48.0)
    # acc points up, the field dip below horizontal: angle = 90 deg + dip
    np.testing.assert_allclose(np.arccos(cosang), math.pi / 2 + dip, atol=1e-9)
    # heading: the horizontal field component points north (earth x)
    m_e = rot.quat_rotate(d.q_true, d.mag)
    np.testing.assert_allclose(m_e, np.tile(sim.mag_earth(dip, 48.0), (len(d), 1)), atol=1e-12)


def test_noise_and_bias_statistics():
    n = 20000
    bias = np.array([0.02, -0.01, 0.015])
    d = sim.imu("static", rate=500, duration=n / 500, seed=21, gyr_bias=bias, gyr_noise=0.004,
                acc_noise=0.006, mag_noise=0.003)
    gerr = d.gyr - d.omega_true
    # mean within 5 sigma of the mean's standard error; std within ~5 standard errors
    assert np.all(np.abs(gerr.mean(0) - bias) < 5 * 0.004 / math.sqrt(n))
    np.testing.assert_allclose(gerr.std(0), 0.004, rtol=5 / math.sqrt(2 * n))
    aerr = d.acc - E_Z
    assert np.all(np.abs(aerr.mean(0)) < 5 * 0.006 / math.sqrt(n))
    np.testing.assert_allclose(aerr.std(0), 0.006, rtol=5 / math.sqrt(2 * n))
    merr = d.mag - sim.mag_earth()
    np.testing.assert_allclose(merr.std(0), 0.003, rtol=5 / math.sqrt(2 * n))
    # noises are independent across sensors and axes
    c = np.corrcoef(np.column_stack([gerr, aerr, merr]).T)
    assert np.max(np.abs(c - np.eye(9))) < 5 / math.sqrt(n)


def test_defaults_are_documented_values():
    d = sim.imu("static", rate=200, duration=50, seed=0)
    assert d.params["gyr_bias"] == list(sim.GYR_BIAS)
    assert d.params["gyr_noise"] == sim.GYR_NOISE == 0.005
    assert d.params["acc_noise"] == sim.ACC_NOISE == 0.005
    assert np.all(np.abs(np.array(sim.GYR_BIAS)) >= 0.005)
    np.testing.assert_allclose((d.gyr - d.omega_true).mean(0), sim.GYR_BIAS, atol=2e-4)


def _arrays(d):
    return [d.t, d.gyr, d.acc, d.mag, d.q_true, d.omega_true, d.lin_acc]


def test_determinism_by_seed():
    kw = dict(rate=200, duration=3, lin_acc=1.0, q0="random")
    a, b = sim.imu("slow", seed=123, **kw), sim.imu("slow", seed=123, **kw)
    assert all(bits_equal(x, y) for x, y in zip(_arrays(a), _arrays(b)))
    assert a.params == b.params
    c = sim.imu("slow", seed=124, **kw)
    for name in ("gyr", "acc", "mag", "q_true", "lin_acc"):
        assert not np.array_equal(getattr(a, name), getattr(c, name)), name
    # the motion stream is the trajectory's and is independent of noise settings
    tr = sim.trajectory("slow", seed=123, rate=200, duration=3, q0="random")
    assert bits_equal(tr.q, a.q_true)
    quiet = sim.imu("slow", seed=123, gyr_noise=0, **kw)
    assert bits_equal(quiet.q_true, a.q_true) and bits_equal(quiet.acc, a.acc)
    # a Trajectory can be passed in; noise follows imu's seed
    e = sim.imu(tr, seed=123, lin_acc=1.0)
    assert all(bits_equal(x, y) for x, y in zip(_arrays(a), _arrays(e)))


def test_seed_none_is_recorded_and_replayable():
    a = sim.imu("fast", seed=None, rate=100, duration=1)
    b = sim.imu("fast", seed=a.params["seed"], rate=100, duration=1)
    assert all(bits_equal(x, y) for x, y in zip(_arrays(a), _arrays(b)))


@pytest.mark.parametrize("kwargs, match", [
    (dict(motion="spin"), "kind must be one of"),
    (dict(rate=0), "rate must be > 0"),
    (dict(rate=float("nan")), "rate must be finite"),
    (dict(duration=-1), "duration must be > 0"),
    (dict(rate=10, duration=0.01), "at least one sample"),
    (dict(gyr_noise=-1), "gyr_noise must be >= 0"),
    (dict(gyr_bias=[1, 2]), "gyr_bias must be a scalar or a 3-vector"),
    (dict(acc_unit="mg"), "acc_unit"),
    (dict(mag_dip=2.0), "mag_dip must be <="),
    (dict(mag_field=0.0), "mag_field must be > 0"),
    (dict(seed=-3), "seed must be"),
    (dict(motion="fast", max_freq=150, rate=200), "Nyquist"),
    (dict(motion="slow", omega=lambda t: t), "omega is required for kind='custom'"),
    (dict(motion="custom", omega=lambda t: np.zeros((len(t), 2))), "must return shape"),
    (dict(lin_acc=np.zeros((3, 3))), "lin_acc must give"),
    (dict(q0=[0, 0, 0, 0]), "zero"),
])
def test_bad_arguments(kwargs, match):
    kwargs = dict(kwargs)
    motion = kwargs.pop("motion", "slow")
    with pytest.raises(ValueError, match=match):
        sim.imu(motion, **kwargs)


# ------------------------------------------------------------------------------------------
# single axis

@pytest.mark.parametrize("motion", ["static", "slow", "tilt_steps", "fast"])
def test_axis1d_integrates_exactly(motion):
    a = sim.axis1d(motion, rate=200, duration=10, seed=6, angle0=0.1 if motion != "slow" else None)
    th = a.angle0
    out = []
    for w in a.omega_true:           # the article's theta_k = theta_{k-1} + omega_k dt
        th = th + w * a.dt
        out.append(th)
    assert bits_equal(out, a.angle)
    if motion == "static":
        assert np.all(a.angle == 0.1)


def test_axis1d_follows_sinusoid_and_tilt_targets():
    a = sim.axis1d("slow", rate=100, duration=20, seed=1, amplitude=0.4, gyr_noise=0,
                   angle_noise=0)
    s = {k: np.array(v)[:, 0] for k, v in a.params["sines"].items()}
    path = np.sum(s["amp"] * np.sin(2 * np.pi * s["freq"] * a.t[:, None] + s["phase"]), axis=1)
    np.testing.assert_allclose(a.angle, path, atol=1e-12)
    np.testing.assert_array_equal(a.acc_angle, a.angle)
    assert np.max(np.abs(a.angle)) <= 0.4
    b = sim.axis1d("tilt_steps", rate=100, duration=6, seed=1, hold=1.0, ramp=0.5)
    for i, tgt in enumerate(b.params["targets"][:3]):
        assert b.angle[100 + 150 * i + 49] == pytest.approx(tgt, abs=1e-12)


def test_axis1d_noise_bias_disturbance_and_seed():
    n = 40000
    a = sim.axis1d("static", rate=400, duration=n / 400, seed=3, gyr_bias=-0.02,
                   gyr_noise=0.006, angle_noise=0.004)
    assert abs((a.gyr - a.omega_true).mean() + 0.02) < 5 * 0.006 / math.sqrt(n)
    assert (a.gyr - a.omega_true).std() == pytest.approx(0.006, rel=5 / math.sqrt(2 * n))
    assert (a.acc_angle - a.angle).std() == pytest.approx(0.004, rel=5 / math.sqrt(2 * n))
    d = sim.axis1d("slow", rate=200, duration=5, seed=3, angle_noise=0, disturbance=0.1)
    np.testing.assert_array_equal(d.acc_angle, d.angle + d.disturbance)
    assert 0.02 < np.max(np.abs(d.disturbance)) <= 0.1
    e = sim.axis1d("slow", rate=200, duration=5, seed=3, angle_noise=0, disturbance=0.1)
    f = sim.axis1d("slow", rate=200, duration=5, seed=4, angle_noise=0, disturbance=0.1)
    assert bits_equal(d.gyr, e.gyr) and bits_equal(d.acc_angle, e.acc_angle)
    assert not np.array_equal(d.gyr, f.gyr) and not np.array_equal(d.angle, f.angle)
    with pytest.raises(ValueError, match="motion must be one of"):
        sim.axis1d("yaw_spin")
    g = sim.axis1d(omega=np.full(50, 0.2), rate=100)
    assert len(g) == 50 and g.angle[-1] == pytest.approx(0.1, abs=1e-15)
