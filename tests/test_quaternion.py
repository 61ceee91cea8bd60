"""Quaternion filters (Mahony in quaternion form, Madgwick's gradient descent):
accuracy on simulated data, the article's claims (chapters 4, 5 and the
appendix), the published guards and the fast inverse square root.

Bit-exactness of C against the reference is tests/test_bitexact.py (registry
CASES_QUATERNION); compatibility with the published C is test_published.py.
"""
import math
import struct
from fractions import Fraction

import numpy as np
import pytest

import imufuse_c
import imufuse.reference as reference
from imufuse import rotations as rot
from imufuse import sim
from imufuse.reference import _math
from imufuse.reference import madgwick as madgwick_ref

from bits import assert_same_bits, ulps

DTYPES = ("float32", "float64")
RATE = 200.0
DT = 1.0 / RATE


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def make(name, dtype, **params):
    return getattr(imufuse_c, name)(DT, dtype=dtype, **params)


# ---- accuracy on simulated data ------------------------------------------------
#
# Bound: tilt error <= 2 deg RMS after 20 s of convergence, slow motion
# (sim "slow": roll/pitch within 30 deg, up to 0.2 Hz), realistic MEMS noise
# (sim defaults: gyro 0.005 rad/s white + bias (0.012, -0.017, 0.009) rad/s,
# accelerometer 0.005 g white, magnetometer 0.5 % white), 200 Hz.
# Why 2 deg: the error budget of a correctly working filter is well below it:
#  - accelerometer noise 0.005 g is 0.29 deg per sample; the filter averages it
#    over its time constant 1/Kp (0.5-1 s, 100-200 samples): ~0.03 deg;
#  - gyro white noise integrates to 0.005 rad/s * sqrt(dt) = 0.02 deg/sqrt(s)
#    over the same time constant: ~0.02 deg;
#  - the gyro bias (0.02 rad/s across the tilt axes) is removed by the integral
#    term (Mahony, ki > 0) or outrun by the bounded gradient step (Madgwick:
#    2 beta = 0.2 rad/s > 0.02 rad/s);
#  - no linear acceleration in this test.
# Measured: 0.1-0.4 deg. 2 deg is loose enough for any seed and float32, and
# tight enough to fail a filter that does not cancel the bias: a P-only
# Mahony filter at the published kp = 0.5 sits at |b_tilt| / kp ~ 2.2 deg
# (test_p_only_mahony_offset), a sign or ordering error diverges by tens of
# degrees.
TILT_BOUND_DEG = 2.0
CONVERGE_S = 20.0

ACCURACY_CASES = [
    ("MahonyIMU", dict(kp=1.0, ki=0.3)),
    ("MahonyIMU", dict(kp=2.0, ki=0.5, invsqrt="fast")),
    ("MadgwickIMU", dict(beta=0.1)),
    ("MadgwickIMU", dict(beta=0.1, delta_s="simplified")),
    ("MadgwickIMU", dict(beta=0.1, invsqrt="fast")),
    ("MahonyAHRS", dict(kp=2.0, ki=0.5)),
    ("MahonyAHRS", dict(kp=2.0, ki=0.5, invsqrt="fast")),
    ("MadgwickAHRS", dict(beta=0.1)),
    ("MadgwickAHRS", dict(beta=0.1, invsqrt="fast")),
]


def _inputs(f, d):
    return (d.gyr, d.acc, d.mag) if f.kind == "ahrs" else (d.gyr, d.acc)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name,params", ACCURACY_CASES,
                         ids=[f"{n}-{'-'.join(f'{k}={v}' for k, v in p.items())}"
                              for n, p in ACCURACY_CASES])
@pytest.mark.parametrize("seed", [0, 1])
def test_tilt_accuracy_slow_motion(name, params, dtype, seed):
    d = sim.imu("slow", rate=RATE, duration=60.0, seed=seed)
    f = make(name, dtype, **params)         # starts at identity: must converge
    S = f.run(*_inputs(f, d))
    k0 = int(CONVERGE_S * RATE)
    err = np.degrees(rot.tilt_error(S[k0:, :4].astype(float), d.q_true[k0:]))
    print(f"{name} {params} {dtype} seed {seed}: tilt RMS {rms(err):.3f} deg, max {err.max():.3f}")
    assert rms(err) <= TILT_BOUND_DEG
    assert f.skipped == 0


def test_p_only_mahony_offset():
    """Without integral action (the published ki = 0) the gyro bias leaves a
    tilt offset of about |b_perp| / kp (article chapter 3: the P controller
    cannot cancel a constant disturbance); the 2 deg bound above is chosen to
    catch it."""
    d = sim.imu("static", rate=RATE, duration=40.0, seed=0)
    f = make("MahonyIMU", "float64", kp=0.5, ki=0.0)
    S = f.run(d.gyr, d.acc)
    err = rot.tilt_error(S[-2000:, :4], d.q_true[-2000:])
    b = np.array(d.params["gyr_bias"])
    expected = math.hypot(b[0], b[1]) / 0.5            # level: x, y are the tilt axes
    assert abs(rms(err) / expected - 1.0) < 0.1
    assert math.degrees(rms(err)) > TILT_BOUND_DEG


# ---- gyro bias estimate --------------------------------------------------------
#
# The integral term I converges to minus the gyro bias. With an accelerometer
# only, the bias component along the current vertical is invisible, so the
# motion must tilt the sensor far enough for all three axes to be seen:
# tilt steps to random attitudes within +-60 deg, holding 4 s each.

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mahony_imu_estimates_gyro_bias(dtype, seed):
    d = sim.imu("tilt_steps", rate=RATE, duration=120.0, seed=seed,
                amplitude=math.radians(60.0), hold=4.0, ramp=1.0)
    f = make("MahonyIMU", dtype, kp=1.0, ki=0.3)
    S = f.run(d.gyr, d.acc)
    bias = np.array(d.params["gyr_bias"])
    est = -S[-int(30 * RATE):, 4:].astype(float).mean(axis=0)   # I -> -bias
    rel = np.abs(est - bias) / np.abs(bias)
    print(f"seed {seed} {dtype}: bias {bias}, estimate {est}, error per axis {100 * rel} %")
    assert np.all(rel <= 0.05)


@pytest.mark.parametrize("dtype", DTYPES)
def test_mahony_ahrs_estimates_gyro_bias(dtype):
    """With a magnetometer all three bias components are observable in any attitude."""
    d = sim.imu("slow", rate=RATE, duration=60.0, seed=4)
    f = make("MahonyAHRS", dtype, kp=2.0, ki=0.5)
    S = f.run(d.gyr, d.acc, d.mag)
    bias = np.array(d.params["gyr_bias"])
    est = -S[-int(20 * RATE):, 4:].astype(float).mean(axis=0)
    assert np.all(np.abs(est - bias) <= 0.05 * np.abs(bias))


# ---- heading -------------------------------------------------------------------

AHRS_CASES = [c for c in ACCURACY_CASES if c[0].endswith("AHRS")]


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name,params", AHRS_CASES,
                         ids=[f"{n}-{'-'.join(f'{k}={v}' for k, v in p.items())}"
                              for n, p in AHRS_CASES])
def test_ahrs_holds_heading(name, params, dtype):
    """The AHRS variants converge to and hold the true heading (RMS <= 2 deg
    after 20 s, measured 0.1-0.5 deg); the IMU variants, even started at the
    true attitude, drift with the gyro's z bias (0.009 rad/s, ~0.5 deg/s)."""
    d = sim.imu("slow", rate=RATE, duration=60.0, seed=2)
    k0 = int(CONVERGE_S * RATE)
    f = make(name, dtype, **params)
    S = f.run(d.gyr, d.acc, d.mag)
    head = np.degrees(rot.heading_error(S[k0:, :4].astype(float), d.q_true[k0:]))
    print(f"{name} {params} {dtype}: heading RMS {rms(head):.3f} deg, max {np.abs(head).max():.3f}")
    assert rms(head) <= 2.0
    imu = make(name.replace("AHRS", "IMU"), dtype, **params)
    imu.state = np.r_[d.q0, np.zeros(len(imu.state_names) - 4)]
    S_imu = imu.run(d.gyr, d.acc)
    drift = np.degrees(rot.heading_error(S_imu[k0:, :4].astype(float), d.q_true[k0:]))
    assert rms(drift) > 5.0


# ---- published guards ------------------------------------------------------------

@pytest.mark.parametrize("backend", ["c", "ref"])
@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("family,params", [("Mahony", dict(kp=1.0, ki=0.3)),
                                           ("Mahony", dict(invsqrt="fast")),
                                           ("Madgwick", dict(beta=0.1)),
                                           ("Madgwick", dict(invsqrt="fast"))])
def test_zero_magnetometer_is_the_imu_update(family, params, dtype, backend):
    """AHRS with an all-zero magnetometer (+0 or -0) runs exactly the IMU update."""
    mod = imufuse_c if backend == "c" else reference
    g = np.random.default_rng(3)
    n = 300
    gyr, acc = g.normal(0, 0.3, (n, 3)), g.normal(0, 1, (n, 3)) + [0, 0, 1]
    mag = np.zeros((n, 3))
    mag[::7] = -0.0
    ahrs = getattr(mod, family + "AHRS")(DT, dtype=dtype, **params)
    imu = getattr(mod, family + "IMU")(DT, dtype=dtype, **params)
    assert_same_bits(ahrs.run(gyr, acc, mag), imu.run(gyr, acc), ahrs.state_names)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name,params", [("MahonyIMU", dict(kp=1.0, ki=0.3)),
                                         ("MadgwickIMU", dict(beta=0.1)),
                                         ("MahonyAHRS", dict(kp=1.0, ki=0.3)),
                                         ("MadgwickAHRS", dict(beta=0.1))])
def test_zero_accelerometer_integrates_gyro_only(name, params, dtype):
    """An all-zero accelerometer skips the correction: the update is the pure
    gyro integration (the same as a filter with zero gains fed a real
    accelerometer) and the integral term is neither updated nor applied nor
    reset."""
    g = np.random.default_rng(5)
    n = 200
    gyr = g.normal(0, 0.5, (n, 3))
    inputs = (gyr, np.zeros((n, 3))) + ((g.normal(0, 1, (n, 3)),) if "AHRS" in name else ())
    f = make(name, dtype, **params)
    start = f.state.copy()
    start[:4] = rot.quat_normalize([0.9, 0.1, -0.3, 0.2])
    if "Mahony" in name:
        start[4:] = [0.01, -0.02, 0.03]
    f.state = start
    got = f.run(*inputs)
    gains = dict(kp=0.0, ki=0.0) if "Mahony" in name else dict(beta=0.0)
    nofb = make(name.replace("AHRS", "IMU"), dtype, **{**params, **gains})
    nofb.state = start
    if "Mahony" in name:
        # the held integral term is not applied: integrate the raw gyro
        nofb.state = np.r_[start[:4], 0.0, 0.0, 0.0]
    # a real accelerometer reading with zero gains: the feedback path runs and adds nothing
    want = nofb.run(gyr, g.normal(0, 1, (n, 3)) + [0, 0, 1])
    assert_same_bits(got[:, :4], want[:, :4])
    if "Mahony" in name:
        assert_same_bits(got[:, 4:], np.tile(start[4:], (n, 1)).astype(dtype))


# ---- article claims, chapter 5: perfect data -----------------------------------
#
# "with perfect gyro and accelerometer data ... in Mahony's filter the error
# vector is zero, e = 0. In Madgwick's filter, the correction step ds is
# however not zero (since a = -q^-1 e_z q)."
# Checked in exact rational arithmetic (the reference filters run on
# fractions.Fraction; rational unit quaternions from Pythagorean quadruples
# keep every normalisation exact) and in floating point.

QUADRUPLES = [(1, 2, 2, 4, 5), (2, 4, 5, 6, 9), (1, 2, 4, 10, 11), (2, 3, 6, 0, 7),
              (3, 4, 12, 84, 85), (7, 4, 4, 0, 9)]


def _rational_quats():
    out = []
    for a, b, c, d, n in QUADRUPLES:
        for signs in ((1, 1, 1, 1), (1, -1, 1, -1), (-1, 1, -1, -1)):
            q = [Fraction(s * v, n) for s, v in zip(signs, (a, b, c, d))]
            out.append(q)
            out.append(q[1:] + q[:1])
    return out


def _up_in_body(q):
    """d = Im[q^-1 e_z q] (appendix, Mahony step 3): what a level accelerometer
    at rest reads, in the convention of the published code and imufuse."""
    q0, q1, q2, q3 = q
    return (2 * (q1 * q3 - q0 * q2), 2 * (q0 * q1 + q2 * q3), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3)


def _exact_filter(cls, **params):
    f = cls(DT, **params)
    f._R = Fraction                       # run the reference twin in exact arithmetic
    f.reset()
    return f


@pytest.mark.parametrize("sign", [+1, -1], ids=["a=+d", "a=-d (article)"])
def test_mahony_error_vector_exactly_zero_with_perfect_data(sign):
    """Exact arithmetic: one update with perfect data (a = +-d, zero rate)
    leaves q exactly unchanged and the integral term exactly zero: e = a x d = 0."""
    for q in _rational_quats():
        a = [sign * v for v in _up_in_body(q)]
        assert sum(v * v for v in a) == 1
        for cls in (reference.MahonyIMU, reference.MahonyAHRS):
            f = _exact_filter(cls, kp=2.0, ki=0.5)
            f.q0, f.q1, f.q2, f.q3 = q
            args = [Fraction(0)] * 3 + a
            if cls.kind == "ahrs":
                args += [Fraction(0)] * 3                  # no magnetometer reading
            f._update(*args)
            assert [f.q0, f.q1, f.q2, f.q3] == q
            assert [f.ix, f.iy, f.iz] == [0, 0, 0]


def test_madgwick_ds_with_perfect_data_exact():
    """Exact arithmetic: the article's sign convention a = -q^-1 e_z q
    (accelerometer = gravity direction) gives ds != 0 where Mahony's e = 0, so
    the claim holds as stated. With the published code's own convention
    (a = +d, a level sensor reads +1 g on z, as in imufuse), ds = J^T f = 0
    exactly: the objective f is zero, for the full and the simplified form."""
    for q in _rational_quats():
        d = _up_in_body(q)
        for form in (madgwick_ref.ds_full, madgwick_ref.ds_simplified):
            assert form(Fraction, q, *d) == [0, 0, 0, 0]
            assert any(v != 0 for v in form(Fraction, q, *[-v for v in d]))


@pytest.mark.parametrize("dtype", DTYPES)
def test_perfect_data_floating_point(dtype):
    """Floating point, perfect data in the imufuse/published convention
    (noise-free, bias-free sensors; filters started at the true attitude,
    exact inverse square root). Mahony's error vector is at rounding level and
    so is its correction: the estimate stays on the truth to a few eps.
    Madgwick's raw ds is also at rounding level, but the step normalises it:
    whenever it is not exactly zero it becomes a unit vector and the filter
    takes a full step beta dt in a direction set by rounding noise -- the
    estimate is pushed away from the correct attitude (article chapter 5).

    The motion is a spin about the vertical at a fixed tilt: the discrete
    filters compare a_k with d(q_{k-1}) (the previous estimate, article 2.4),
    which agree exactly only when the body's vertical does not move; under a
    general motion both error vectors carry the one-step rotation (measured
    ~1e-3 rad tilt error for both on sim "slow"), which is not the claim."""
    d = sim.imu("yaw_spin", rate=RATE, duration=10.0, seed=1, q0=rot.euler_to_quat([0.4, -0.3, 0.2]),
                amplitude=1.0, gyr_bias=0.0, gyr_noise=0.0, acc_noise=0.0, mag_noise=0.0)
    eps = float(np.finfo(dtype).eps)
    errs = {}
    for name, params in (("MahonyIMU", dict(kp=1.0, ki=0.3)), ("MadgwickIMU", dict(beta=0.1))):
        f = make(name, dtype, **params)
        f.state = np.r_[d.q0, np.zeros(len(f.state_names) - 4)]
        S = f.run(d.gyr, d.acc).astype(float)
        errs[name] = float(np.max(rot.tilt_error(S[:, :4], d.q_true)))
    print(f"{dtype}: max tilt error with perfect data: Mahony {errs['MahonyIMU']:.3g} rad, "
          f"Madgwick {errs['MadgwickIMU']:.3g} rad (eps {eps:.3g})")
    assert errs["MahonyIMU"] < 100 * eps
    assert errs["MadgwickIMU"] > 1e-4              # ~ beta dt = 5e-4 rad

    # the mechanism, sample by sample on the true attitudes (reference twin)
    R = np.float32 if dtype == "float32" else float
    n_unit = n_zero = 0
    max_e = max_raw = 0.0
    for q_true in d.q_true[::50]:
        q = [R(v) for v in q_true]
        a = [R(v) for v in _up_in_body(q_true)]
        a = _math.normalise3(R, *a, _math.INVSQRT_EXACT)[1]
        dd = _up_in_body(q)
        e = np.cross(np.array(a, dtype=float), np.array(dd, dtype=float))
        max_e = max(max_e, float(np.abs(e).max()))
        s = madgwick_ref.ds_full(R, q, *a)
        max_raw = max(max_raw, max(abs(float(v)) for v in s))
        sn = _math.normalise4(R, *s, _math.INVSQRT_EXACT)[1]
        if any(sn):
            n_unit += abs(math.sqrt(sum(float(v) ** 2 for v in sn)) - 1.0) < 1e3 * eps
        else:
            n_zero += 1
    print(f"{dtype}: max |e| {max_e:.3g}, max |raw ds| {max_raw:.3g}, "
          f"normalised ds unit in {n_unit} of {n_unit + n_zero} samples")
    assert max_e < 100 * eps and max_raw < 1000 * eps      # rounding level
    assert n_unit >= 0.9 * (n_unit + n_zero)


# ---- full and simplified ds agree for a unit quaternion ------------------------

@pytest.mark.parametrize("dtype", DTYPES)
def test_full_and_simplified_ds_agree(dtype):
    """The simplified ds (article, note below the appendix) equals the full
    one for |q| = 1; in floating point, with q and a normalised to rounding,
    they agree within the rounding of the full form. A priori bound: s1 sums
    8 terms whose magnitudes add up to at most 36 (|q_i|, |a_i| <= 1), so
    sequential summation errs by at most 7 * (eps/2) * 36 = 126 eps; the
    simplification's use of |q|^2 = 1 adds a few eps. Bound: 128 eps absolute."""
    R = np.float32 if dtype == "float32" else float
    eps = float(np.finfo(dtype).eps)
    g = np.random.default_rng(11)
    max_abs = 0.0
    max_ulps = 0.0
    for k in range(3000):
        q = _math.normalise4(R, *[R(v) for v in g.normal(size=4)], _math.INVSQRT_EXACT)[1]
        near = k % 2 == 1
        if near:
            # near convergence, where the filter lives: a close to d, ds small
            a = np.array(_up_in_body([float(v) for v in q])) + g.normal(0, 0.02, 3)
        else:
            a = g.normal(size=3)
        a = _math.normalise3(R, *[R(v) for v in a], _math.INVSQRT_EXACT)[1]
        full = np.array(madgwick_ref.ds_full(R, q, *a), dtype=dtype)
        simp = np.array(madgwick_ref.ds_simplified(R, q, *a), dtype=dtype)
        max_abs = max(max_abs, float(np.abs(full.astype(float) - simp.astype(float)).max()))
        if not near:
            # generic a: |ds| ~ 1, ulps are meaningful on the larger components
            big = np.abs(full) >= 0.1 * np.abs(full).max()
            max_ulps = max(max_ulps, float(ulps(full[big], simp[big]).max()))
    print(f"{dtype}: max |full - simplified| = {max_abs / eps:.1f} eps (absolute); generic a: "
          f"max {max_ulps:.0f} ulps on components >= 10 % of the largest")
    assert max_abs <= 128 * eps


@pytest.mark.parametrize("dtype", DTYPES)
def test_full_and_simplified_filters_track_together(dtype):
    """Whole filter: the two forms give trajectories that stay together on sim data."""
    d = sim.imu("slow", rate=RATE, duration=20.0, seed=6)
    a = make("MadgwickIMU", dtype, beta=0.1).run(d.gyr, d.acc).astype(float)
    b = make("MadgwickIMU", dtype, beta=0.1, delta_s="simplified").run(d.gyr, d.acc).astype(float)
    diff = rot.quat_angle_error(a, b)
    print(f"{dtype}: max angle between full and simplified trajectories {diff.max():.3g} rad")
    assert diff.max() < 1e-3


# ---- fast inverse square root -----------------------------------------------------

def _classic_int32_invsqrt(x):
    """The textbook 32-bit version on numpy int32 images (signed shift)."""
    x = np.asarray(x, dtype=np.float32)
    i = x.view(np.int32)
    i = (np.int32(0x5F3759DF) - (i >> 1)).astype(np.int32)
    y = i.view(np.float32)
    halfx = np.float32(0.5) * x
    return y * (np.float32(1.5) - halfx * y * y)


def test_fast_invsqrt_float32_matches_classic_and_bound():
    g = np.random.default_rng(2)
    xs = np.concatenate([np.float32(10.0) ** g.uniform(-37, 37, 4000),
                         g.uniform(0.5, 2.0, 4000)]).astype(np.float32)
    xs = np.concatenate([xs, np.array([np.finfo(np.float32).tiny, 1e-40, 1.0, 4.0],
                                      dtype=np.float32)])
    got = np.array([_math.invsqrt_fast(np.float32, x) for x in xs], dtype=np.float32)
    assert_same_bits(got, _classic_int32_invsqrt(xs))
    normal = xs >= np.finfo(np.float32).tiny
    rel = np.abs(got[normal].astype(float) * np.sqrt(xs[normal].astype(float)) - 1.0)
    assert rel.max() < 1.8e-3


def test_fast_invsqrt_float64_bound():
    g = np.random.default_rng(3)
    xs = 10.0 ** g.uniform(-300, 300, 3000)
    rel = [abs(_math.invsqrt_fast(float, x) * math.sqrt(x) - 1.0) for x in xs]
    assert max(rel) < 1.8e-3
    # the integer image step is the 64-bit one (not a float32 round trip)
    x = 1e200
    i = struct.unpack("<Q", struct.pack("<d", x))[0]
    y0 = struct.unpack("<d", struct.pack("<Q", 0x5FE6EB50C7B537A9 - (i >> 1)))[0]
    assert _math.invsqrt_fast(float, x) == y0 * (1.5 - 0.5 * x * y0 * y0)


# ---- parameters -------------------------------------------------------------------

@pytest.mark.parametrize("backend", [imufuse_c, reference])
def test_defaults_are_the_published_ones(backend):
    """kp = twoKp/2 = 0.5, ki = twoKi/2 = 0, beta = 0.1, full ds, exact invsqrt."""
    import inspect
    for name, want in (("MahonyIMU", dict(kp=0.5, ki=0.0, invsqrt="exact")),
                       ("MahonyAHRS", dict(kp=0.5, ki=0.0, invsqrt="exact")),
                       ("MadgwickIMU", dict(beta=0.1, delta_s="full", invsqrt="exact")),
                       ("MadgwickAHRS", dict(beta=0.1, invsqrt="exact"))):
        cls = getattr(backend, name)
        sig = inspect.signature(cls._params if backend is reference else cls)
        assert {k: sig.parameters[k].default for k in want} == want
        f = getattr(backend, name)(1 / 512, dtype="float32")
        assert list(f.state[:4]) == [1, 0, 0, 0]


@pytest.mark.parametrize("backend", [imufuse_c, reference])
@pytest.mark.parametrize("name,bad,word", [
    ("MahonyIMU", dict(kp=-1.0), "kp"), ("MahonyIMU", dict(ki=float("nan")), "ki"),
    ("MahonyAHRS", dict(invsqrt="quick"), "invsqrt"), ("MadgwickIMU", dict(beta=-0.1), "beta"),
    ("MadgwickIMU", dict(delta_s="short"), "delta_s"), ("MadgwickAHRS", dict(invsqrt=1), "invsqrt"),
    ("MadgwickAHRS", dict(dt=0.0), "dt")])
def test_bad_parameters(backend, name, bad, word):
    kwargs = {"dt": 0.01, **bad}
    with pytest.raises(ValueError, match=word):
        getattr(backend, name)(**kwargs)
