"""API of the fixed-point classes on both backends: constructor validation
(ValueError naming the parameter), int16 count inputs, int32 state,
state_float, profiles."""
from __future__ import annotations

import numpy as np
import pytest

import imufuse.reference as reference
from imufuse.registry import FIXED_CASES, PROFILES


def _backends():
    out = [reference]
    try:
        import imufuse_c
        if hasattr(imufuse_c, "FILTERS_FIXED"):
            out.append(imufuse_c)
    except ImportError:
        pass
    return out


BACKENDS = [pytest.param(m, id=m.__name__) for m in _backends()]


@pytest.mark.parametrize("mod", BACKENDS)
def test_all_fixed_classes_exported(mod):
    for name in reference.FILTERS_FIXED:
        assert hasattr(mod, name)


@pytest.mark.parametrize("mod", BACKENDS)
@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FIXED_CASES])
def test_state_types_and_float(mod, case):
    f = getattr(mod, case.name)(**case.params, profile="32")
    assert f.state.dtype == np.int32 and f.state.shape == (len(f.state_names),)
    sf = f.state_float
    assert sf.dtype == np.float64 and sf.shape == f.state.shape
    if case.name in ("MahonyIMUQ", "MadgwickIMUQ"):
        assert sf[0] == 1.0 and not sf[1:4].any()


BAD = [
    ("MahonyIMUQ", dict(dt=0.01, kp=1.0, gyr_scale=1e-3, profile="16"), "profile"),
    ("MahonyIMUQ", dict(dt=-0.01, kp=1.0, gyr_scale=1e-3), "dt"),
    ("MahonyIMUQ", dict(dt=0.01, kp=-1.0, gyr_scale=1e-3), "kp"),
    ("MahonyIMUQ", dict(dt=0.01, kp=1.0, gyr_scale=0.0), "gyr_scale"),
    ("MahonyIMUQ", dict(dt=0.01, kp=1.0, gyr_scale=1.0), "gyr_scale"),   # > 0.25 rad/sample
    ("MahonyIMUQ", dict(dt=0.01, kp=float("nan"), gyr_scale=1e-3), "kp"),
    ("MadgwickIMUQ", dict(dt=0.01, beta=1e3, gyr_scale=1e-3), "beta"),
    ("Complementary1DQ", dict(dt=0.01, alpha=1.5, gyr_scale=1e-3, angle_scale=1e-4), "alpha"),
    ("Complementary1DQ", dict(dt=0.01, alpha=0.9, gyr_scale=1e-3), "angle_scale"),
    ("Mahony1DBiasQ", dict(dt=0.01, kp=2.0, ki=0.3, gyr_scale=1e-3, angle_scale=-1.0), "angle_scale"),
    # Kp dt < 1 and Ki dt^2 < 2^-8 (stable in float, outside the 16-bit gains)
    ("Mahony1DBiasQ", dict(dt=0.01, kp=100.0, ki=0.3, gyr_scale=1e-3, angle_scale=1e-4), "^kp[:*]"),
    ("Mahony1DBiasQ", dict(dt=0.01, kp=150.0, ki=0.3, gyr_scale=1e-3, angle_scale=1e-4), "^kp[:*]"),
    ("Mahony1DBiasQ", dict(dt=0.01, kp=99.99999, ki=0.3, gyr_scale=1e-3, angle_scale=1e-4),
     "^kp[:*]"),                                               # rounds to 1 in 15 bits
    ("Mahony1DBiasQ", dict(dt=0.01, kp=2.0, ki=39.0625, gyr_scale=1e-3, angle_scale=1e-4), "^ki[:*]"),
    ("Mahony1DBiasQ", dict(dt=0.1, kp=2.0, ki=0.5, integrate_first=True, gyr_scale=1e-3,
                           angle_scale=1e-4), "^ki[:*]"),
    ("KKQ", dict(dt=0.01, kp=2.0, gyr_scale=1e-3), "kp"),
    ("KKQ", dict(dt=0.01, kp=1.5, gyr_scale=1e-3), "kp"),   # > 1: more than the whole error
    ("MultiWiiQ", dict(dt=0.01, cmpf=600, gyr_scale=1e-3, acc_1g=-1.0), "acc_1g"),
    ("MultiWiiQ", dict(dt=0.01, cmpf=600, gyr_scale=1e-3, acc_1g=4096, acc_lpf_shift=16),
     "acc_lpf_shift"),
]


@pytest.mark.parametrize("mod", BACKENDS)
@pytest.mark.parametrize("name,kw,word", BAD)
def test_bad_parameters_raise(mod, name, kw, word):
    with pytest.raises((ValueError, TypeError), match=word):
        getattr(mod, name)(**kw)


@pytest.mark.parametrize("mod", BACKENDS)
@pytest.mark.parametrize("profile", PROFILES)
def test_inputs_must_be_int16_counts(mod, profile):
    f = mod.MahonyIMUQ(0.01, 1.0, gyr_scale=1e-3, profile=profile)
    with pytest.raises(ValueError, match="int16"):
        f.update([40000, 0, 0], [0, 0, 4096])
    with pytest.raises(ValueError, match="integer"):
        f.run(np.full((3, 3), 0.5), np.zeros((3, 3), np.int16))
    with pytest.raises(ValueError, match="shapes"):
        f.run(np.zeros((3, 3), np.int16), np.zeros((4, 3), np.int16))
    with pytest.raises(ValueError, match="3-vector|shape"):
        f.update([1, 2], [0, 0, 1])
    g = mod.Complementary1DQ(0.01, 0.9, gyr_scale=1e-3, angle_scale=1e-4, profile=profile)
    with pytest.raises(ValueError):
        g.update(1.5, 0)
    with pytest.raises(ValueError, match="state"):
        g.state = [1, 2]


@pytest.mark.parametrize("mod", BACKENDS)
def test_three_inputs_are_checked_as_two(mod):
    """A fixed-point AHRS (RobustAHRSQ, one profile): the magnetometer is checked as the
    gyro and the accelerometer."""
    h = mod.RobustAHRSQ(0.01, gyr_scale=1e-3)
    with pytest.raises(ValueError, match="int16"):
        h.update([0, 0, 0], [0, 0, 4096], [40000, 0, 0])
    with pytest.raises(ValueError, match="integer sensor counts"):
        h.run(np.zeros((3, 3), np.int16), np.zeros((3, 3), np.int16), np.full((3, 3), 0.5))
    with pytest.raises(ValueError, match="shapes"):
        h.run(np.zeros((3, 3), np.int16), np.zeros((3, 3), np.int16), np.zeros((4, 3), np.int16))
    with pytest.raises((TypeError, ValueError)):   # the twin names the missing input
        h.update([0, 0, 0], [0, 0, 4096])


@pytest.mark.parametrize("mod", BACKENDS)
def test_profiles_differ_only_where_designed(mod):
    """MahonyIMUQ, MadgwickIMUQ, RobustIMUQ and RobustAHRSQ have distinct 8-bit updates; the
    others share one."""
    rng = np.random.default_rng(0)
    g = rng.integers(-3000, 3000, (300, 3)).astype(np.int16)
    a = (rng.integers(-500, 500, (300, 3)) + [0, 0, 4096]).astype(np.int16)
    m = (rng.integers(-20, 20, (300, 3)) + [200, 0, -300]).astype(np.int16)
    for case in FIXED_CASES:
        if "8" not in case.profiles:
            # one arithmetic: the other profile is refused, saying so
            with pytest.raises(ValueError, match="profile"):
                getattr(mod, case.name)(**case.params, profile="8")
            continue
        kind = getattr(reference, case.name).kind
        if kind not in ("imu", "ahrs"):
            continue
        ins = (g, a) if kind == "imu" else (g, a, m)
        s32 = getattr(mod, case.name)(**case.params, profile="32").run(*ins)
        s8 = getattr(mod, case.name)(**case.params, profile="8").run(*ins)
        if case.name in ("MahonyIMUQ", "MadgwickIMUQ", "RobustIMUQ", "RobustAHRSQ"):
            assert (s32 != s8).any()
        else:
            np.testing.assert_array_equal(s32, s8)


def test_compiled_classes_carry_their_twins_docstring():
    """help(imufuse_c.RobustAHRSQ) says what the class is: the binding generator copies the
    twin's docstring into each fixed-point class (the float classes get theirs from the
    dtype dispatch)."""
    import inspect
    import imufuse_c
    for name in imufuse_c.FILTERS_FIXED:
        doc = getattr(imufuse_c, name).__doc__
        assert doc and inspect.cleandoc(doc) == inspect.cleandoc(getattr(reference, name).__doc__), name


@pytest.mark.parametrize("kp", [1.5, 2.0, 5.0])
def test_kkq_names_its_own_range_of_kp(kp):
    """KKQ takes kp in [0, 1]; from 2 on the float KK's check came first and named [0, 2)."""
    import imufuse_c
    from imufuse import reference
    for m in (reference, imufuse_c):
        with pytest.raises(ValueError, match=r"kp: must be in \[0, 1\] in fixed point"):
            m.KKQ(0.01, kp, gyr_scale=1e-3)
