"""Nair's variometer Kalman filter and vertical acceleration: the C
builds equal the pure-Python twins bit for bit (every state variable after
every sample), the filter computes Nair's equations (against an
independent matrix implementation), and bad input is refused by name."""
import os
import re

import numpy as np
import pytest

import imufuse.reference as reference
import imufuse_c
from bits import assert_same_bits
from imufuse.rotations import quat_rotate
from imufuse.registry import CASES_VARIO, DTYPES, vario_matrix

N = 600


def _flight(g, n, dt=0.02):
    """A smooth climb with noisy barometer altitude (cm) and vertical accel (cm/s^2)."""
    t = np.arange(n) * dt
    acc = 80.0 * np.sin(0.7 * t)
    v = np.cumsum(acc) * dt
    z = 50000.0 + np.cumsum(v) * dt
    return acc + 12.0 + g.normal(0, 30, n), z + g.normal(0, 15, n), dt


def _nonfinite(g, n):
    a, z, dt = _flight(g, n)
    dt = np.full(n, dt)
    a[g.integers(0, n, 15)] = np.nan
    z[g.integers(0, n, 15)] = np.inf
    dt[g.integers(0, n, 10)] = -np.inf
    dt[g.integers(0, n, 10)] = 0.0
    dt[g.integers(0, n, 5)] = -0.01
    z[0] = np.nan                      # the start waits for the first good sample
    return a, z, dt


SEQUENCES = {
    "flight": _flight,
    "jitter_dt": lambda g, n: (*_flight(g, n)[:2], g.uniform(0.015, 0.035, n)),
    "step": lambda g, n: (np.where(np.arange(n) > n // 3, 300.0, 0.0),
                          np.where(np.arange(n) > n // 2, 2000.0, 0.0), 0.025),
    "random": lambda g, n: (g.normal(0, 1e3, n), g.normal(0, 1e5, n), g.uniform(1e-3, 0.5, n)),
    "large": lambda g, n: (g.normal(0, 1e6, n), g.normal(4e5, 1e6, n), 10.0),
    "tiny": lambda g, n: (g.normal(0, 1e-30, n), g.normal(0, 1e-30, n), 1e-6),
    "nonfinite": _nonfinite,
    "overflow": lambda g, n: (np.full(n, 3e38), np.full(n, -3e38), 1e3),
}


def generate(name, seed=0, n=N):
    return SEQUENCES[name](np.random.default_rng(seed), n)


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in CASES_VARIO])
def test_run_matches_reference(case):
    """Both precisions, every input sequence, one item per configuration."""
    for dtype in DTYPES:
        for seq in SEQUENCES:
            try:
                _run_matches_reference(case, dtype, seq)
            except AssertionError as e:
                raise AssertionError(f"{dtype} {seq}: {e}") from e


def _run_matches_reference(case, dtype, seq):
    inputs = generate(seq)
    c, r = case.make("c", dtype), case.make("ref", dtype)
    got, want = c.run(*inputs), r.run(*inputs)
    assert_same_bits(got, want, c.state_names)
    assert c.skipped == r.skipped
    assert np.isfinite(got).all()


@pytest.mark.parametrize("case,dtype", vario_matrix())
def test_update_matches_run(case, dtype):
    a, z, dt = generate("nonfinite", seed=1, n=300)
    for backend in ("c", "ref"):
        f = case.make(backend, dtype)
        traj = f.run(a, z, dt)
        skipped = f.skipped
        f.reset()
        steps = []
        for row in zip(a, z, dt):
            f.update(*row)
            steps.append(f.state)
        assert_same_bits(np.array(steps), traj, f.state_names)
        assert f.skipped == skipped > 0


@pytest.mark.parametrize("case,dtype", vario_matrix())
def test_state_set_and_reset(case, dtype):
    c, r = case.make("c", dtype), case.make("ref", dtype)
    init = c.state.copy()
    c.run(*generate("flight", n=50))
    r.run(*generate("flight", n=1))     # both started
    r.state = c.state
    tail = generate("jitter_dt", seed=7, n=50)
    assert_same_bits(c.run(*tail), r.run(*tail), c.state_names)
    c.reset()
    assert_same_bits(c.state, init)
    assert c.skipped == 0


def test_is_registered_and_named():
    assert {c.name for c in CASES_VARIO} == set(reference.FILTERS_VARIO)
    header = open(os.path.join(os.path.dirname(__file__), "..", "csrc", "vario.h")).read()
    for fn in ("init", "update"):
        assert f"void imf_vario_{fn}(" in header
    assert imufuse_c.VarioKF.state_names == reference.VarioKF.state_names


# ---- Nair's equations, against an independent matrix implementation --------

def _matrix_kf(acc, alt, dt, predict, var_z=300.0, var_acc=200.0, var_bias=1.0,
               p0=(1.0, 1.0, 1e5)):
    x = np.array([alt[0], 0.0, 0.0])
    P = np.diag(p0).astype(float)
    out = [np.r_[x, P[np.triu_indices(3)]]]
    H = np.array([[1.0, 0.0, 0.0]])
    for a, m, d in zip(acc[1:], alt[1:], dt[1:]):
        F = np.array([[1, d, -d * d / 2], [0, 1, -d], [0, 0, 1]])
        G = np.array([d * d / 2, d, 0.0])
        Q = np.array([[d**4 / 4 * var_acc, d**3 / 2 * var_acc, 0],
                      [d**3 / 2 * var_acc, d**2 * var_acc, 0], [0, 0, var_bias]])
        P = F @ P @ F.T + Q
        if predict == "model":
            x = F @ x + G * a
        else:
            v = x[1] + (a - x[2]) * d
            x = np.array([x[0] + v * d, v, x[2]])
        S = (H @ P @ H.T)[0, 0] + var_z
        K = (P @ H.T)[:, 0] / S
        x = x + K * (m - x[0])
        P = (np.eye(3) - np.outer(K, H)) @ P
        out.append(np.r_[x, P[np.triu_indices(3)]])
    return np.array(out)


@pytest.mark.parametrize("predict", ["seed", "model"])
@pytest.mark.parametrize("backend", ["c", "ref"])
def test_equations_match_matrix_form(predict, backend):
    g = np.random.default_rng(3)
    acc, alt, _ = _flight(g, 400)
    dt = g.uniform(0.015, 0.035, 400)
    mod = imufuse_c if backend == "c" else reference
    got = mod.VarioKF(predict=predict).run(acc, alt, dt)
    want = _matrix_kf(acc, alt, dt, predict)
    # order of operations differs: agreement to rounding, not bits
    scale = np.abs(want).max(axis=0)
    assert (np.abs(got - want) <= 1e-9 * scale + 1e-9 * np.abs(want)).all()


def test_predict_options_differ_as_the_seed_says():
    """One step from v0 = 0 with a constant acceleration a: the model moves z
    by a dt^2/2, Nair's order by a dt^2 (the new v times dt)."""
    for predict, factor in (("seed", 1.0), ("model", 0.5)):
        f = reference.VarioKF(z0=0.0, p0=(0.0, 0.0, 0.0), var_acc=0.0, var_bias=0.0,
                              var_z=1e30, predict=predict)
        f.update(100.0, 0.0, 0.1)
        assert f.z == pytest.approx(factor * 100.0 * 0.01, rel=1e-12)
        assert f.v == pytest.approx(10.0, rel=1e-12)


def test_first_sample_sets_z0():
    for mod in (imufuse_c, reference):
        f = mod.VarioKF()
        f.update(float("nan"), 1.0, 0.02)       # rejected: no start
        assert f.skipped == 1 and f.state[0] == 0.0
        f.update(5.0, 1234.5, 0.02)
        assert f.state[0] == 1234.5 and f.state[1] == 0.0
        np.testing.assert_array_equal(f.state[3:], [1.0, 0, 0, 1.0, 0, 1e5])
        g = mod.VarioKF(z0=10.0)
        g.update(0.0, 1234.5, 0.02)
        assert 10.0 < g.state[0] < 1234.5       # filtered, not replaced


# ---- vertical acceleration --------------------------------------------------------

def _random_q(g, n):
    q = g.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


@pytest.mark.parametrize("convention", ["nwu", "enu", "ned", "ned_seed"])
@pytest.mark.parametrize("dtype", DTYPES)
def test_vertical_accel_bits(convention, dtype):
    g = np.random.default_rng(5)
    q = np.vstack([_random_q(g, 500), [[1, 0, 0, 0], [0, 1, 0, 0]], g.normal(0, 1e20, (2, 4))])
    acc = np.vstack([g.normal(0, 2, (500, 3)), [[0, 0, 1], [np.nan, 0, 1]],
                     [[1e20, 0, 0], [0, 0, 0]]])
    got = imufuse_c.vertical_accel(q, acc, convention, 1.0, 980.0, dtype=dtype)
    want = reference.vertical_accel(q, acc, convention, 1.0, 980.0, dtype=dtype)
    assert got.dtype == want.dtype == np.dtype(dtype)
    assert_same_bits(got, want)


@pytest.mark.parametrize("convention,sign", [("nwu", 1), ("enu", 1), ("ned_seed", 1),
                                             ("ned", -1)])
def test_vertical_accel_is_earth_z(convention, sign):
    """Nair's formula is the z row of R(q) a: compare with a quaternion
    rotation; an accelerometer at rest gives 0, an upward push gives > 0."""
    g = np.random.default_rng(6)
    q, acc = _random_q(g, 200), g.normal(0, 1, (200, 3))
    want = (sign * quat_rotate(q, acc)[:, 2] - 9.81) * 100.0
    got = imufuse_c.vertical_accel(q, acc * 1.0, convention, one_g=9.81, scale=100.0)
    np.testing.assert_allclose(got, want, atol=1e-9)
    # at rest: the accelerometer reads sign * 1 g along earth z, in the body frame
    from imufuse.rotations import quat_rotate_inv
    rest = quat_rotate_inv(q, np.tile([0, 0, sign * 1.0], (200, 1)))
    np.testing.assert_allclose(reference.vertical_accel(q, rest, convention), 0.0, atol=1e-9)
    up = quat_rotate_inv(q, np.tile([0, 0, sign * 1.25], (200, 1)))   # 0.25 g upward
    np.testing.assert_allclose(reference.vertical_accel(q, up, convention), 245.0, atol=1e-9)


# ---- bad input ----------------------------------------------------------------------

@pytest.mark.parametrize("kwargs,name", [
    (dict(var_z=0.0), "var_z"), (dict(var_z=float("nan")), "var_z"),
    (dict(var_acc=-1.0), "var_acc"), (dict(var_bias=float("inf")), "var_bias"),
    (dict(p0=(1.0, 1.0)), "p0"), (dict(p0=(1.0, -1.0, 1.0)), "p0[1]"),
    (dict(z0="x"), "z0"), (dict(v0=float("nan")), "v0"), (dict(b0=None), "b0"),
    (dict(predict="exact"), "predict")])
@pytest.mark.parametrize("mod", [imufuse_c, reference], ids=["c", "ref"])
def test_bad_parameters(mod, kwargs, name):
    with pytest.raises(ValueError, match=rf"^{re.escape(name)}:"):
        mod.VarioKF(**kwargs)


@pytest.mark.parametrize("mod", [imufuse_c, reference], ids=["c", "ref"])
def test_parameters_representable_in_float32(mod):
    # (var_z = 1e-50 with the model order: Nair's would refuse it as unstable first)
    for kwargs, name in ((dict(var_z=1e39), "var_z"), (dict(var_z=1e-50, predict="model"), "var_z"),
                         (dict(p0=(1.0, 1e40, 1.0)), "p_v"), (dict(z0=-1e39), "z0")):
        with pytest.raises(ValueError, match=f"^{name}:.*float32"):
            mod.VarioKF(**kwargs, dtype="float32")
        mod.VarioKF(**kwargs, dtype="float64")           # fine in float64


@pytest.mark.parametrize("mod", [imufuse_c, reference], ids=["c", "ref"])
def test_start(mod):
    with pytest.raises(ValueError, match="^init: VarioKF has no attitude"):
        mod.VarioKF(init="first")
    with pytest.raises(ValueError, match="^q0"):
        mod.VarioKF(q0=(1, 0, 0, 0))
    s = np.arange(1.0, 10.0)
    f = mod.VarioKF(state=s)
    np.testing.assert_array_equal(f.state, s)


@pytest.mark.parametrize("mod", [imufuse_c, reference], ids=["c", "ref"])
def test_bad_inputs(mod):
    f = mod.VarioKF()
    with pytest.raises(ValueError, match="shapes"):
        f.run(np.zeros(3), np.zeros(4), 0.02)
    with pytest.raises(ValueError, match="shapes"):
        f.run(np.zeros(3), np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError, match="accel"):
        f.update("a", 0.0, 0.02)
    with pytest.raises(ValueError, match="convention"):
        mod.vertical_accel(np.zeros((2, 4)), np.zeros((2, 3)), "xyz")
    with pytest.raises(ValueError, match="shapes"):
        mod.vertical_accel(np.zeros((2, 4)), np.zeros((3, 3)))



# ---- any floats at all ------------------------------------------------------------------

@pytest.mark.parametrize("case,dtype", vario_matrix())
def test_hypothesis_sequences(case, dtype):
    from hypothesis import HealthCheck, given, settings, strategies as st
    width = 32 if dtype == "float32" else 64
    x = st.floats(width=width, allow_nan=True, allow_infinity=True)
    rows = st.lists(st.tuples(x, x, x), min_size=1, max_size=60)

    @settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck),
              derandomize=True)
    @given(rows)
    def check(r):
        a, z, d = (np.array(c, dtype=float) for c in zip(*r))
        c, ref = case.make("c", dtype), case.make("ref", dtype)
        assert_same_bits(c.run(a, z, d), ref.run(a, z, d), c.state_names)
        assert c.skipped == ref.skipped

    check()


@pytest.mark.parametrize("backend", ["c", "ref"])
def test_run_refuses_what_update_refuses(backend):
    """run(acc, baro, None) skipped every sample and returned zeros; complex values lost their
    imaginary part, objects and strings became NaN: refused, as update() refuses them."""
    import imufuse_c
    from imufuse import reference
    cls = (imufuse_c if backend == "c" else reference).VarioKF
    z = np.zeros(5)
    for args, msg in [((z, z, None), "dt: give the sample period"),
                      ((z.astype(complex), z, 0.01), "accel: expected real numbers"),
                      ((z, [None] * 5, 0.01), "baro_alt: expected real numbers"),
                      ((z, z, np.array(["0.01"] * 5)), "dt: expected real numbers")]:
        with pytest.raises(ValueError, match=msg):
            cls().run(*args)
    assert cls().run(z, z, 0.01).shape == (5, 9)


def test_seed_order_stability_is_checked_from_the_physics():
    """predict="seed" updates z with the new v (z += v dt + (a - b) dt^2) while its gain comes
    from the model (dt^2 / 2). The steady-state error dynamics (model gain, seed prediction)
    have a spectral radius above 1 where var_z is small against the process noise: the
    estimate then diverges whatever the data (var_z = 1e-12 reached 1e308). The radius
    predicts the twin's behaviour; such settings are refused in seed mode, and the model
    order runs them, bounded."""
    from imufuse.reference import vario as rv
    args = (1e-9, 200.0, 1.0, 1.0, 1.0, 1e5, 0.0, 0.0, 0.0, 0, rv.PREDICT_SEED)
    rng = np.random.default_rng(4)
    n = 6000
    acc, alt = rng.normal(0.0, 50.0, n), 100.0 + rng.normal(0.0, 30.0, n)
    for dt, diverges in ((0.1, True), (0.001, False)):
        assert (rv.seed_radius(1e-9, 200.0, 1.0, dt) > 1.0) == diverges
        f = reference.VarioKF()
        f._init(rv.VarioSettings(*args))     # Nair's order with these variances, unchecked
        out = f.run(acc, alt, np.full(n, dt))
        grew = not np.all(np.abs(out[:, :3]) < 1e12)
        assert grew == diverges, (dt, np.nanmax(np.abs(out[:, :3])))
    for mod in (imufuse_c, reference):
        for vz in (1e-12, 1e-9, 1e-3):
            with pytest.raises(ValueError, match=r"^var_z: .* too small for predict='seed'"):
                mod.VarioKF(var_z=vz)
        mod.VarioKF()                        # Nair's own settings are stable
        for dtype in ("float32", "float64"):
            f = mod.VarioKF(var_z=1e-12, predict="model", dtype=dtype)
            out = f.run(acc, alt, np.full(n, 0.01))
            assert f.skipped == 0 and np.all(np.abs(out[:, :3]) < 1e8)
