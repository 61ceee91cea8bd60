"""The Fusion suite (Longbin's Fusion walkthrough) on its own terms: C against the pure-Python
twin bit for bit in both precisions, bad input, the non-finite policy, long
runs at rest, and what FusionOffset buys on a log with a gyroscope bias.

FusionAHRS is driven here and not by the generic harnesses of
imufuse.registry: its update takes dt per call and Fusion's units (deg/s, g).
The oracle comparison with imufusion 1.2.3 is tests/test_fusion_oracle.py."""
import math

import numpy as np
import pytest

import imufuse_c
from imufuse.reference import _fusion
from imufuse import reference as ref

from bits import assert_same_bits
from fusion_sim import simulated_log
from imufuse.registry import FUSION_CASES

DTYPES = ("float32", "float64")
CONFIGS = {c.label: c.params for c in FUSION_CASES if c.name == "FusionAHRS"}


def drive(f, log, n_mag, n_ext):
    """update / external heading / no magnetometer, with set_heading and reset."""
    a, b = n_mag, n_mag + n_ext
    parts = [f.run(log.gyr[:a], log.acc[:a], log.mag[:a], dt=log.dt[:a])]
    f.set_heading(25.0)
    parts.append(f.run(log.gyr[a:b], log.acc[a:b], dt=log.dt[a:b], heading=log.yaw[a:b]))
    f.reset()
    parts.append(f.run(log.gyr[b:], log.acc[b:], dt=float(np.mean(log.dt))))
    return np.concatenate(parts)


@pytest.mark.parametrize("config", list(CONFIGS))
@pytest.mark.parametrize("convention", ["NWU", "ENU", "NED"])
@pytest.mark.parametrize("dtype", DTYPES)
def test_c_matches_twin(dtype, convention, config):
    log = simulated_log(seed=11, n=1200)
    c = imufuse_c.FusionAHRS(convention=convention, **CONFIGS[config], dtype=dtype)
    r = ref.FusionAHRS(convention=convention, **CONFIGS[config], dtype=dtype)
    sc, sr = drive(c, log, 600, 250), drive(r, log, 600, 250)
    assert sc.dtype == np.dtype(dtype)
    assert_same_bits(sc, sr, c.state_names)
    oc, orf = c.outputs_batch(sc), r.outputs_batch(sc)
    for name in _fusion.OUTPUTS:
        assert_same_bits(np.asarray(oc[name]).reshape(len(sc), -1),
                         np.asarray(orf[name]).reshape(len(sc), -1), None)
    for name in _fusion.FLAGS:
        np.testing.assert_array_equal(oc[name], orf[name])
    one_c, one_r = c.outputs(), r.outputs()
    assert_same_bits(np.asarray(one_c["euler"]), np.asarray(oc["euler"][-1]), None)
    assert_same_bits(np.asarray(one_c["euler"]), np.asarray(one_r["euler"]), None)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("backend", [imufuse_c, ref])
def test_update_equals_run(backend, dtype):
    log = simulated_log(seed=12, n=400)
    f = backend.FusionAHRS(**CONFIGS["short"], dtype=dtype)
    want = f.run(log.gyr, log.acc, log.mag, dt=log.dt)
    f = backend.FusionAHRS(**CONFIGS["short"], dtype=dtype)
    got = []
    for k in range(len(log.dt)):
        f.update(log.gyr[k], log.acc[k], log.mag[k], log.dt[k])
        got.append(f.state)
    assert_same_bits(np.array(got), want, f.state_names)


@pytest.mark.parametrize("dtype", DTYPES)
def test_float64_differs_from_float32(dtype):
    log = simulated_log(seed=13, n=300)
    s32 = imufuse_c.FusionAHRS(dtype="float32").run(log.gyr, log.acc, log.mag, dt=log.dt)
    s64 = imufuse_c.FusionAHRS(dtype="float64").run(log.gyr, log.acc, log.mag, dt=log.dt)
    assert not np.array_equal(s64.astype(np.float32), s32)
    np.testing.assert_allclose(s64[:, :4], s32[:, :4], atol=1e-4)


@pytest.mark.parametrize("backend", [imufuse_c, ref])
def test_state_and_quaternion_setters(backend):
    f = backend.FusionAHRS(**CONFIGS["short"], dtype="float32")
    log = simulated_log(seed=14, n=200)
    f.run(log.gyr, log.acc, log.mag, dt=log.dt)
    st = f.state
    g = backend.FusionAHRS(**CONFIGS["short"], dtype="float32")
    g.state = st
    assert_same_bits(g.state, st, None)
    a = f.run(log.gyr[:50], log.acc[:50], log.mag[:50], dt=log.dt[:50])
    b = g.run(log.gyr[:50], log.acc[:50], log.mag[:50], dt=log.dt[:50])
    assert_same_bits(a, b, f.state_names)
    f.quaternion = [0.0, 1.0, 0.0, 0.0]
    assert list(f.quaternion) == [0.0, 1.0, 0.0, 0.0]
    for bad in ([0, 0, 0, 0], [1, 0, 0], [math.nan, 0, 0, 1]):
        with pytest.raises(ValueError, match="quaternion"):
            f.quaternion = bad
    bad = st.copy()
    bad[14] = 0.5
    with pytest.raises(ValueError, match="integers"):
        f.state = bad
    bad = st.copy()
    bad[17] = 101
    with pytest.raises(ValueError, match="acceleration_recovery_trigger"):
        f.state = bad


@pytest.mark.parametrize("backend", [imufuse_c, ref])
@pytest.mark.parametrize("kw,match", [
    (dict(convention="XYZ"), "convention"), (dict(gain=-1), "gain"),
    (dict(gain=math.nan), "gain"), (dict(gyroscope_range=-5), "gyroscope_range"),
    (dict(acceleration_rejection=200), "acceleration_rejection"),
    (dict(magnetic_rejection="x"), "magnetic_rejection"),
    (dict(recovery_trigger_period=-1), "recovery_trigger_period"),
    (dict(recovery_trigger_period=2.5), "recovery_trigger_period"),
    (dict(invsqrt="slow"), "invsqrt"), (dict(dtype="int8"), "dtype")])
def test_bad_settings(backend, kw, match):
    with pytest.raises(ValueError, match=match):
        backend.FusionAHRS(**kw)


@pytest.mark.parametrize("backend", [imufuse_c, ref])
def test_bad_inputs(backend):
    f = backend.FusionAHRS()
    with pytest.raises(ValueError, match="gyr"):
        f.update([1, 2], [0, 0, 1], [1, 0, 0], 0.01)
    with pytest.raises(ValueError, match="dt"):
        f.update([1, 2, 3], [0, 0, 1], [1, 0, 0], -0.01)
    with pytest.raises(ValueError, match="heading"):
        f.set_heading(math.inf)
    g = np.zeros((5, 3))
    with pytest.raises(ValueError, match="shapes"):
        f.run(g, g[:4], g, dt=0.01)
    with pytest.raises(ValueError, match="dt"):
        f.run(g, g, g, dt=np.zeros(4))
    with pytest.raises(ValueError, match="dt"):
        f.run(g, g, g, dt=-1.0)
    with pytest.raises(ValueError, match="not both"):
        f.run(g, g, g, dt=0.01, heading=np.zeros(5))
    with pytest.raises(ValueError, match="sample_rate"):
        backend.FusionOffset(0)
    bad = np.zeros((2, 22))
    bad[:, 0] = 1.0
    bad[1, 17] = 1e20
    with pytest.raises(ValueError, match="integral"):
        f.outputs_batch(bad)
    with pytest.raises(ValueError, match="states"):
        f.outputs_batch(bad[:, :5])


@pytest.mark.parametrize("dtype", DTYPES)
def test_non_finite_policy(dtype):
    """A hostile burst is rejected sample by sample, identically in both
    backends; sane input afterwards brings the attitude back."""
    log = simulated_log(seed=15, n=900)
    gyr, acc, mag, dt = log.gyr.astype(dtype), log.acc.astype(dtype), log.mag.astype(dtype), \
        log.dt.astype(dtype)
    gyr[100] = np.nan
    acc[101] = np.inf
    mag[102, 1] = -np.inf
    dt[103] = np.nan
    # squares overflow: |a|^2 = inf, 1/sqrt(inf) = 0, the normalised vector
    # is zero and so is the feedback -- Fusion's own result, finite: accepted
    acc[104] = 3e38
    res = []
    for mod in (imufuse_c, ref):
        f = mod.FusionAHRS(**CONFIGS["short"], dtype=dtype)
        res.append(f.run(gyr, acc, mag, dt=dt))
        assert f.skipped == 4
        assert np.isfinite(res[-1]).all()
    assert_same_bits(res[0], res[1], _fusion.AHRS_STATE_NAMES)
    assert_same_bits(res[0][100], res[0][99], None)
    clean = imufuse_c.FusionAHRS(**CONFIGS["short"], dtype=dtype).run(
        log.gyr, log.acc, log.mag, dt=log.dt)
    assert np.abs(np.abs(np.sum(res[0][-1, :4] * clean[-1, :4])) - 1) < 1e-4


@pytest.mark.parametrize("cls", ["FusionAHRS", "FusionAHRS13"])
def test_float32_overflow_of_one_sample_warns_in_neither_backend(cls):
    """1e39 and 1e300 in a float32 filter's update (or sample period) become inf as C
    converts them and the sample is rejected; the twin said so with numpy's RuntimeWarning
    "overflow encountered in cast", an error under -W error, where the compiled class is
    silent."""
    import warnings
    g, a, m = [1.0, 2.0, 3.0], [0.0, 0.0, 1.0], [0.4, 0.0, -0.9]
    calls = [lambda f, h: f.update([h, 0.0, 0.0], a, m, 0.01),
             lambda f, h: f.update(g, a, m, h),
             lambda f, h: f.update_no_magnetometer(g, [0.0, h, 1.0], 0.01),
             lambda f, h: f.update_external_heading(g, a, h, 0.01)]
    if cls == "FusionAHRS13":
        calls.append(lambda f, h: f.set_sample_period(h))
    for call in calls:
        for h in (1e39, 1e300):
            fs = [getattr(mod, cls)(dtype="float32") for mod in (imufuse_c, ref)]
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                for f in fs:
                    call(f, h)
            assert fs[0].skipped == fs[1].skipped
            assert_same_bits(fs[0].state, fs[1].state, None)
    for f in (mod.FusionOffset(sample_rate=100, dtype="float32") if cls == "FusionAHRS" else
              mod.FusionBias(dtype="float32") for mod in (imufuse_c, ref)):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            f.update([1e39, 0.0, 0.0])


@pytest.mark.parametrize("dtype", DTYPES)
def test_long_run_at_rest(dtype):
    """One hour at 100 Hz, level and still, noise-free: the attitude stays the
    identity's tilt, unit norm, the flags settle."""
    n = 360_000
    gyr = np.zeros((n, 3), dtype)
    acc = np.tile(np.array([0.0, 0.0, 1.0], dtype), (n, 1))
    mag = np.tile(np.array([20.0, 0.0, -42.0], dtype), (n, 1))
    f = imufuse_c.FusionAHRS(**CONFIGS["short"], dtype=dtype)
    s = f.run(gyr, acc, mag, dt=0.01)
    q = s[:, :4].astype(np.float64)
    assert np.abs(np.linalg.norm(q, axis=1) - 1).max() < 1e-6
    out = f.outputs_batch(s[-1:])
    assert np.abs(out["euler"]).max() < 1e-3
    assert not out["initialising"][0] and not out["acceleration_recovery"][0]
    assert f.skipped == 0


def test_offset_estimator_demonstration(capsys):
    """Longbin's reason for FusionOffset: a gyroscope bias, rest phases,
    no magnetometer. Without the estimator the heading drifts at the bias
    rate; with it the drift stops once the 5 s rest timeout has passed."""
    n = 12000
    log = simulated_log(seed=16, n=n, bias=(0.4, -0.3, 1.2))
    err, total = {}, {}
    for use_offset in (False, True):
        gyr = log.gyr
        if use_offset:
            gyr, _ = imufuse_c.FusionOffset(100, dtype="float32").run(log.gyr)
        f = imufuse_c.FusionAHRS(gain=0.5, dtype="float32")
        s = f.run(gyr, log.acc, dt=log.dt)
        yaw = f.outputs_batch(s)["euler"][:, 2]
        d = (yaw - log.yaw + 180.0) % 360.0 - 180.0
        a = log.phases["rest3"][0]
        total[use_offset] = float(np.abs(d[-1] - d[300]))   # heading held at 0 while initialising
        err[use_offset] = float(np.abs(d[-1] - d[a]))       # drift over the last rest phase
    t_rest = float(np.sum(log.dt[log.phases["rest3"][0]:]))
    with capsys.disabled():
        print(f"\nz bias 1.2 deg/s, {np.sum(log.dt):.0f} s log: heading drift over the whole "
              f"log without / with FusionOffset {total[False]:.1f} / {total[True]:.1f} deg; "
              f"over the last {t_rest:.0f} s rest {err[False]:.1f} / {err[True]:.2f} deg")
    assert err[True] < err[False] / 3
    assert total[True] < total[False] / 2.5


@pytest.mark.parametrize("dtype", DTYPES)
def test_offset_c_matches_twin(dtype):
    log = simulated_log(seed=17, n=3000)
    a, sa = imufuse_c.FusionOffset(100, dtype=dtype).run(log.gyr)
    b, sb = ref.FusionOffset(100, dtype=dtype).run(log.gyr)
    assert_same_bits(a, b, None)
    assert_same_bits(sa, sb, _fusion.OFFSET_STATE_NAMES)
    f = imufuse_c.FusionOffset(100, dtype=dtype)
    one = np.array([f.update(g) for g in log.gyr])
    assert_same_bits(one, a, None)


@pytest.mark.parametrize("dtype", DTYPES)
def test_models_and_alignments_c_match_twin(dtype):
    g = np.random.default_rng(18)
    x = g.normal(0, 10, (300, 3))
    M, s, b = np.eye(3) + g.normal(0, 0.1, (3, 3)), g.uniform(0.9, 1.1, 3), g.normal(0, 1, 3)
    assert_same_bits(imufuse_c.calibrate_inertial(x, M, s, b, dtype=dtype),
                     ref.fusion.calibrate_inertial(x, M, s, b, dtype=dtype), None)
    assert_same_bits(imufuse_c.calibrate_magnetic(x, M, b, dtype=dtype),
                     ref.fusion.calibrate_magnetic(x, M, b, dtype=dtype), None)
    for name in _fusion.ALL_ALIGNMENTS:
        assert_same_bits(imufuse_c.axes_apply(x, name, dtype=dtype),
                         ref.fusion.axes_apply(x, name, dtype=dtype), None)
    acc, mag = x + [0, 0, 30], x + [20, 0, -40]
    for conv in ("NWU", "ENU", "NED"):
        for inv in ("exact", "fast"):
            assert_same_bits(imufuse_c.compass_heading(conv, acc, mag, invsqrt=inv, dtype=dtype),
                             ref.fusion.compass_heading(conv, acc, mag, invsqrt=inv, dtype=dtype),
                             None)


def test_seed002_mapping_is_a_reflection():
    """Nair's acc_N = acc_y, acc_E = acc_x, acc_D = acc_z: one of the 24
    reflections, which FusionAxesSwap cannot express."""
    assert not _fusion.alignment_is_rotation("+Y+X+Z")
    out = imufuse_c.axes_apply([[1.0, 2.0, 3.0]], "+Y+X+Z")
    assert out.tolist() == [[2.0, 1.0, 3.0]]
    for bad in ("+X+X+Z", "XYZ", "+X+Y+W", 5):
        with pytest.raises(ValueError, match="alignment"):
            imufuse_c.axes_apply([[1.0, 2.0, 3.0]], bad)


@pytest.mark.parametrize("target", ["m4f", "m0", "avr"])
def test_fusion_ahrs_on_mcu(target):
    """FusionAHRS (float32) built for the MCU and run in its emulator gives the
    twin's state after every sample, bit for bit (the driver is bench/mcu's
    fusion_ahrs_f32 case, whose cycles are in docs/fusion.md)."""
    import imufuse.mcu as mcu
    import mcu_cases          # bench/mcu/mcu_cases.py (on the suite's pythonpath: pyproject.toml)
    missing = mcu.ensure_toolchains([target])
    if target in missing:
        pytest.skip(f"toolchain for {target} unavailable: {missing[target]}")
    case = mcu_cases.CASES["fusion_ahrs_f32"]
    inputs = case.make_inputs(300)
    res = mcu.run(target, sources=case.sources, include_dirs=case.include_dirs,
                  driver=case.driver, inputs=inputs)
    f = ref.FusionAHRS(gain=0.5, gyroscope_range=2000.0, acceleration_rejection=10.0,
                       magnetic_rejection=10.0, recovery_trigger_period=500, dtype="float32")
    want = f.run(inputs["gyr"], inputs["acc"], inputs["mag"], dt=np.float32(0.01))
    vals = res.values()
    got = np.column_stack([np.asarray(v, dtype=np.float64) for v in vals[:22]])
    np.testing.assert_array_equal(got[:, 14:], want[:, 14:].astype(np.float64))
    assert_same_bits(np.column_stack(vals[:14]).astype(np.float32), want[:, :14], None)
    assert int(vals[22][-1]) == 0


@pytest.mark.parametrize("dtype", DTYPES)
def test_set_settings_mid_run(dtype):
    """FusionAhrsSetSettings at any time: both backends alike; after the ramp
    the gain jumps to the new one, the timeouts to the new period."""
    log = simulated_log(seed=19, n=900)
    res = []
    for mod in (imufuse_c, ref):
        f = mod.FusionAHRS(**CONFIGS["short"], dtype=dtype)
        a = f.run(log.gyr[:500], log.acc[:500], log.mag[:500], dt=log.dt[:500])
        f.set_settings(gain=2.0, recovery_trigger_period=40, convention="NED")
        st = f.state
        assert st[7] == 2.0 and st[18] == 40 and st[21] == 40
        b = f.run(log.gyr[500:], log.acc[500:], log.mag[500:], dt=log.dt[500:])
        res.append(np.concatenate([a, b]))
        with pytest.raises(ValueError, match="gain"):
            f.set_settings(gain=-1.0)
    assert_same_bits(res[0], res[1], _fusion.AHRS_STATE_NAMES)


@pytest.mark.parametrize("convention,up", [("NWU", 1.0), ("ENU", 1.0), ("NED", -1.0)])
def test_gravity_output_at_rest(convention, up):
    """gravity is what the accelerometer reads at rest, per convention."""
    acc = np.tile([0.0, 0.0, up], (2000, 1))
    f = imufuse_c.FusionAHRS(convention=convention)
    s = f.run(np.zeros((2000, 3)), acc, dt=0.01)
    out = f.outputs_batch(s[-1:])
    np.testing.assert_allclose(out["gravity"][0], [0.0, 0.0, up], atol=1e-9)
    np.testing.assert_allclose(out["linear_acceleration"][0], 0.0, atol=1e-9)
    np.testing.assert_allclose(out["earth_acceleration"][0], 0.0, atol=1e-9)


@pytest.mark.parametrize("mod", [imufuse_c, ref.fusion])
def test_model_parameter_errors(mod):
    x = np.zeros((4, 3))
    with pytest.raises(ValueError, match=r"M: expected shape \(3, 3\)"):
        mod.calibrate_inertial(x, np.eye(2), [1, 1, 1], [0, 0, 0])
    with pytest.raises(ValueError, match="s: must be finite"):
        mod.calibrate_inertial(x, np.eye(3), [1, np.nan, 1], [0, 0, 0])
    with pytest.raises(ValueError, match=r"h: expected shape \(3,\)"):
        mod.calibrate_magnetic(x, np.eye(3), [0, 0])
    with pytest.raises(ValueError, match="shapes"):
        mod.calibrate_magnetic(np.zeros((4, 2)), np.eye(3), [0, 0, 0])




@pytest.mark.parametrize("backend", ["c", "ref"])
def test_set_settings_names_what_it_changes(backend):
    """invsqrt is chosen at construction (as the C init takes it): set_settings refuses it, and
    unknown names, with the six settings it does change (it raised 'multiple values for
    keyword argument')."""
    import imufuse_c
    from imufuse import reference
    f = (imufuse_c if backend == "c" else reference).FusionAHRS()
    with pytest.raises(ValueError, match=r"invsqrt: chosen at construction.*convention, gain"):
        f.set_settings(invsqrt="fast")
    with pytest.raises(ValueError, match="gian: not a setting of FusionAHRS"):
        f.set_settings(gian=0.3)
    f.set_settings(gain=0.3)
