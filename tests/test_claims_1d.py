"""The article's claims about the single-axis filters (chapters 2 and 3),
checked numerically on the compiled filters (float64 unless stated)."""
import cmath
import math

import numpy as np
import pytest

import imufuse_c as C

DT = 0.001


def measured_response(f, omega, channel, n_periods=8, settle=None):
    """Complex gain of filter f at omega (rad/sample), from a simulated sine
    on one input channel (the other zero): least-squares fit of the steady
    state to A sin + B cos, so H = A + jB."""
    period = 2 * math.pi / omega
    settle = settle if settle is not None else int(20 * period) + 20000
    n = settle + int(n_periods * period) + 1
    k = np.arange(n)
    x = np.sin(omega * k)
    zero = np.zeros(n)
    traj = f.run(zero, x) if channel == "a" else f.run(x, zero)
    y = traj[settle:, 0]
    kk = k[settle:]
    basis = np.column_stack([np.sin(omega * kk), np.cos(omega * kk)])
    (a, b), *_ = np.linalg.lstsq(basis, y, rcond=None)
    return complex(a, b)


# ---- chapter 2 ---------------------------------------------------------------

@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_eq_2_2_equals_eq_2_5_up_to_rounding(dtype):
    """Observation (1) of 2.4: Eq. 2.2 and Eq. 2.5 with alpha = 1 - K0 are the
    same filter; the trajectories differ by rounding only."""
    rng = np.random.default_rng(5)
    w, a = rng.normal(0, 1, 20000), rng.normal(0, 0.5, 20000)
    k0 = 0.02
    comp = C.Complementary1D(0.01, alpha=1 - k0, dtype=dtype).run(w, a)[:, 0]
    kal = C.Kalman1D(0.01, k0=k0, dtype=dtype).run(w, a)[:, 0]
    eps = np.finfo(dtype).eps
    scale = eps * np.abs(kal).max()
    print(f"{dtype}: max |diff| {np.abs(comp - kal).max():.3g} = "
          f"{np.abs(comp - kal).max() / scale:.1f} eps*max|theta|; "
          f"{(comp != kal).mean():.1%} of samples differ")
    assert np.abs(comp - kal).max() <= 64 * eps * np.abs(kal).max()


def test_complementary_and_mahony_share_eq_2_1_but_not_the_update_law():
    """2.4 (2)-(4): same transfer function Eq. 2.1/2.7 (Kp = 1/T), different
    discrete update laws (Eq. 2.12). Each filter's measured frequency response
    matches its analytic discrete response within 1 % (in fact ~1e-9), both
    approach Eq. 2.1 at low frequency, and their trajectories differ."""
    T = 0.05
    alpha = (T / DT) / (1 + T / DT)
    kp = 1 / T
    comp = C.Complementary1D(DT, alpha=alpha)
    mah = C.Mahony1D(DT, kp=kp)
    for omega in (0.002, 0.02, 0.2, 1.0):
        u = cmath.exp(-1j * omega)
        want = {
            (comp, "a"): (1 - alpha) / (1 - alpha * u),
            (comp, "w"): alpha * DT / (1 - alpha * u),
            (mah, "a"): kp * DT / (1 - (1 - kp * DT) * u),
            (mah, "w"): DT / (1 - (1 - kp * DT) * u),
        }
        for (f, ch), h in want.items():
            f.reset()
            got = measured_response(f, omega, ch, settle=3000 + int(20 * 2 * math.pi / omega))
            assert abs(got - h) <= 0.01 * abs(h), (type(f).__name__, ch, omega, got, h)
        # Eq. 2.1 in continuous time: a / (1 + T s), s = j omega / dt; the
        # discretisation error is of order omega/2, so compare where it is small
        if omega <= 0.002:
            s = 1j * omega / DT
            h_cont = 1 / (1 + T * s)
            for f in (comp, mah):
                f.reset()
                got = measured_response(f, omega, "a", settle=3000)
                assert abs(got - h_cont) <= 0.01 * abs(h_cont)
    rng = np.random.default_rng(1)
    w, a = rng.normal(0, 1, 5000), rng.normal(0, 0.5, 5000)
    comp.reset()
    mah.reset()
    diff = np.abs(comp.run(w, a) - mah.run(w, a)).max()
    print(f"max trajectory difference Complementary1D vs Mahony1D: {diff:.3g} rad")
    assert diff > 1e-4


# ---- chapter 3 ---------------------------------------------------------------

def eq_3_10(kp, ki, s):
    """Eq. 3.10: accelerometer and gyro channel transfer functions at s."""
    den = 1 + kp / ki * s + s * s / ki
    return (1 + kp / ki * s) / den, (s / ki) / den


def test_second_order_frequency_response_matches_eq_3_10():
    kp, ki = 2.0, 0.3
    mah = C.Mahony1DBias(DT, kp=kp, ki=ki)
    comp = C.Complementary1DBias(DT, kp=kp, ki=ki)
    for omega_c in (0.1, 0.5, 1.0, 3.0, 10.0):        # rad/s, omega_c * dt <= 0.01
        omega = omega_c * DT
        h_a, h_w = eq_3_10(kp, ki, 1j * omega_c)
        for f in (mah, comp):
            for ch, h in (("a", h_a), ("w", h_w)):
                f.reset()
                got = measured_response(f, omega, ch, n_periods=3, settle=60000)
                assert abs(got - h) <= 0.01 * abs(h), (type(f).__name__, ch, omega_c, got, h)


@pytest.mark.parametrize("cls", ["Mahony1DBias", "Complementary1DBias"])
def test_resonance_and_damping_match_eq_3_11(cls):
    """Underdamped gains (xi < 1): the step response of the accelerometer
    channel oscillates at omega0 sqrt(1 - xi^2) with logarithmic decrement
    2 pi xi / sqrt(1 - xi^2); recover omega0 and xi and compare with Eq. 3.11."""
    omega0, xi = 2.0, 0.2
    kp, ki = 2 * xi * omega0, omega0 ** 2
    f = getattr(C, cls)(DT, kp=kp, ki=ki)
    n = 20000
    err = f.run(np.zeros(n), np.ones(n))[:, 0] - 1.0
    peaks = [k for k in range(1, n - 1) if abs(err[k]) >= abs(err[k - 1]) and abs(err[k]) > abs(err[k + 1])
             and abs(err[k]) > 1e-6]
    # successive same-sign extrema are one damped period apart
    same = [k for k in peaks if err[k] > 0]
    period = np.mean(np.diff(same[:4])) * DT
    decrement = math.log(err[same[0]] / err[same[1]])
    xi_m = decrement / math.sqrt(4 * math.pi ** 2 + decrement ** 2)
    omega0_m = 2 * math.pi / period / math.sqrt(1 - xi_m ** 2)
    print(f"{cls}: omega0 {omega0_m:.4f} (Eq. 3.11: {omega0}), xi {xi_m:.4f} (Eq. 3.11: {xi})")
    assert omega0_m == pytest.approx(math.sqrt(ki), rel=0.01)
    assert xi_m == pytest.approx(kp / (2 * math.sqrt(ki)), rel=0.02)


def test_eq_3_12_criterion_and_rule_of_thumb():
    t = C.Complementary1DBias.__doc__ and __import__("imufuse.reference", fromlist=["tuning"]).tuning
    r = t(2.0, 1.0)
    assert r["eq_3_12"] and r["xi"] == 1.0 and r["omega0"] == 1.0
    assert not t(2.0, 1.01)["eq_3_12"]
    r = t(2.0, 0.3)
    assert r["ki_rule_of_thumb"] == pytest.approx((0.2, 0.4)) and r["in_rule_of_thumb"]
    assert not t(2.0, 0.5)["in_rule_of_thumb"]
    assert r["xi"] == pytest.approx(2.0 / (2 * math.sqrt(0.3)))


def test_from_omega0_xi_equals_kp_ki():
    a = C.Complementary1DBias(0.01, omega0=1.5, xi=2.0)
    b = C.Complementary1DBias(0.01, kp=2 * 2.0 * 1.5, ki=1.5 ** 2)
    w = np.random.default_rng(2).normal(size=(2, 500))
    assert (a.run(*w).view(np.uint64) == b.run(*w).view(np.uint64)).all()


@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("params", [dict(dt=0.01, kp=2.0, ki=0.3), dict(dt=0.002, omega0=1.5, xi=2.0),
                                    dict(dt=1 / 512, kp=2.0, ki=0.3)], ids=["kp_ki", "omega0_xi", "512Hz"])
def test_second_order_settles_on_a_constant_angle(params, dtype):
    """At rest the gyro channel of Eq. 3.10 vanishes and the accelerometer
    channel has unit gain at DC: the angle settles on the accelerometer's, in
    both precisions. Run as a direct-form section (poles near z = 1) the float32
    filter missed it by up to 0.6 % of the angle (0.28 deg at 45 deg, 2.1 deg
    upside down; docs/filters.md); in PI form it settles within a few ulps."""
    for deg in (45.0, 90.0, 180.0, -120.0):
        f = C.Complementary1DBias(**params, dtype=dtype)
        n = int(300 / params["dt"])     # 49 time constants of the slowest pole (Kp 2, Ki 0.3)
        theta = f.run(np.zeros(n), np.full(n, math.radians(deg)))[-1, 0]
        want = np.array(math.radians(deg), dtype=dtype)
        off = abs(float(theta) - float(want))
        assert off <= 4 * float(np.spacing(abs(want))), (deg, math.degrees(off))


BIAS = 0.05     # rad/s, constant gyro bias; the true angle is 0
SETTLE = {"Mahony1DBias": 2000, "Kalman1DBias": 2000}   # samples at dt = 0.01


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_bias_estimates_converge(dtype):
    """With a constant gyro bias, the integral of Mahony1DBias converges to
    -bias and the bias state of Kalman1DBias (natural sign, k1 < 0) to +bias,
    within 1 % after SETTLE samples (and stay there)."""
    n = 4000
    w, a = np.full(n, BIAS), np.zeros(n)
    mah = C.Mahony1DBias(0.01, kp=2.0, ki=0.5, dtype=dtype).run(w, a)[:, 1]
    kal = C.Kalman1DBias(0.01, k0=0.02, k1=-0.5, dtype=dtype).run(w, a)[:, 1]
    for name, est, target in (("Mahony1DBias", mah, -BIAS), ("Kalman1DBias", kal, BIAS)):
        rel = np.abs(est - target) / BIAS
        first = int(np.argmax(np.maximum.accumulate(rel[::-1])[::-1] < 0.01))
        print(f"{name} {dtype}: within 1 % from sample {first}")
        assert (rel[SETTLE[name]:] < 0.01).all(), name
        assert rel[0] > 0.5   # it did have to converge


def test_corollary_2_plus_sign():
    """Corollary #2: changing the sign of the bias correction to '+' without
    changing the bias update law is not the substitution b -> -b. With the
    same k1 > 0, '+' converges (b -> -bias) while '-' diverges; '-' needs k1 < 0,
    and '-' with k1 = -c is exactly (bit for bit) '+' with k1 = +c and b -> -b."""
    n = 4000
    w, a = np.full(n, BIAS), np.zeros(n)
    plus = C.Kalman1DBias(0.01, k0=0.02, k1=0.5, bias_sign=+1).run(w, a)
    assert abs(plus[-1, 1] + BIAS) < 0.01 * BIAS
    minus_same_k1 = C.Kalman1DBias(0.01, k0=0.02, k1=0.5, bias_sign=-1, allow_unstable=True).run(w, a)
    assert np.abs(minus_same_k1[-1]).max() > 1e3 * BIAS       # diverges
    with pytest.raises(ValueError, match="Corollary #2"):
        C.Kalman1DBias(0.01, k0=0.02, k1=0.5, bias_sign=-1)
    minus = C.Kalman1DBias(0.01, k0=0.02, k1=-0.5, bias_sign=-1).run(w, a)
    assert (minus[:, 0].view(np.uint64) == plus[:, 0].view(np.uint64)).all()
    assert (minus[:, 1].view(np.uint64) == (-plus[:, 1]).view(np.uint64)).all()


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_corollary_1_reversed_order(dtype):
    """Corollary #1: Eq. 3.9 (integrate first) with Kp' = Kp + Ki dt is Eq. 3.6
    up to rounding."""
    rng = np.random.default_rng(9)
    w, a = rng.normal(0, 1, 20000), rng.normal(0, 0.5, 20000)
    kp, ki, dt = 2.0, 0.3, 0.01
    x = C.Mahony1DBias(dt, kp=kp, ki=ki, dtype=dtype).run(w, a)
    y = C.Mahony1DBias(dt, kp=kp + ki * dt, ki=ki, integrate_first=True, dtype=dtype).run(w, a)
    eps = np.finfo(dtype).eps
    d = np.abs(x - y).max(axis=0)
    print(f"{dtype}: max |diff| theta {d[0]:.3g}, I {d[1]:.3g} "
          f"({(d / (eps * np.abs(x).max(axis=0))).max():.1f} eps*max|x|)")
    assert (d <= 64 * eps * np.abs(x).max(axis=0)).all()
