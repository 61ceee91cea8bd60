"""Nair's accelerometer-magnitude gate on MadgwickIMU/AHRS and
MahonyIMU/AHRS: outside lo..hi (units of acc_1g) the update integrates the
gyro only; inside, and with the gate off (the default), the filter is the
ungated one bit for bit. The C builds against the twins are in the
registry's bit-exact matrix (imufuse.registry, labels "gate*")."""
import numpy as np
import pytest

import imufuse.reference as reference
import imufuse_c
from bits import assert_same_bits
from imufuse.registry import DTYPES, each, each_dtype

# (class, gains that make it a pure gyro integrator)
FILTERS = [("MadgwickIMU", dict(beta=0.0)), ("MadgwickAHRS", dict(beta=0.0)),
           ("MahonyIMU", dict(kp=0.0, ki=0.0)), ("MahonyAHRS", dict(kp=0.0, ki=0.0))]
GAINS = {"MadgwickIMU": dict(beta=0.2), "MadgwickAHRS": dict(beta=0.2),
         "MahonyIMU": dict(kp=2.0, ki=0.5), "MahonyAHRS": dict(kp=2.0, ki=0.5)}


def _inputs(name, acc_norm, n=400, seed=0):
    g = np.random.default_rng(seed)
    gyr = g.normal(0, 0.5, (n, 3))
    d = g.normal(size=(n, 3)) * 0.2 + [0.1, -0.2, 1.0]
    acc = d / np.linalg.norm(d, axis=1, keepdims=True) * np.asarray(acc_norm)[..., None]
    mag = np.tile([0.5, 0.1, -0.8], (n, 1)) + g.normal(0, 0.05, (n, 3))
    return (gyr, acc, mag) if name.endswith("AHRS") else (gyr, acc)


def _make(mod, name, dtype, **kw):
    return getattr(mod, name)(dt=0.005, dtype=dtype, **kw)


@pytest.mark.parametrize("name,gyro_only", FILTERS, ids=[f[0] for f in FILTERS])
@each_dtype
@each("mod", [imufuse_c, reference])
def test_outside_the_gate_is_gyro_only(mod, name, gyro_only, dtype):
    for norm in (0.5, 1.5, 3.0):                    # below 0.6 g, above 1.4 g
        x = _inputs(name, np.full(400, norm))
        gated = _make(mod, name, dtype, **GAINS[name], acc_gate=(0.6, 1.4)).run(*x)
        gyro = _make(mod, name, dtype, **gyro_only).run(*x)
        ungated = _make(mod, name, dtype, **GAINS[name]).run(*x)
        assert_same_bits(gated[:, :4], gyro[:, :4])
        assert not np.array_equal(gated, ungated)   # the gate did something


@pytest.mark.parametrize("name", [f[0] for f in FILTERS])
@each_dtype
@each("mod", [imufuse_c, reference])
def test_inside_the_gate_and_off_are_ungated(mod, name, dtype):
    x = _inputs(name, np.random.default_rng(1).uniform(0.65, 1.35, 400))
    ungated = _make(mod, name, dtype, **GAINS[name]).run(*x)
    assert_same_bits(_make(mod, name, dtype, **GAINS[name], acc_gate=(0.6, 1.4)).run(*x),
                     ungated)
    assert_same_bits(_make(mod, name, dtype, **GAINS[name], acc_gate=None).run(*x), ungated)


@pytest.mark.parametrize("name", [f[0] for f in FILTERS])
def test_mixed_sequence_and_units(name):
    """Magnitudes across the gate, accelerometer in m/s^2 with acc_1g = 9.81:
    C equals the twin bit for bit, and the share of gated samples matters."""
    norms = np.random.default_rng(2).uniform(0.3, 2.0, 600) * 9.81
    x = _inputs(name, norms, n=600)
    for dtype in DTYPES:
        kw = dict(**GAINS[name], acc_gate=(0.6, 1.4), acc_1g=9.81)
        assert_same_bits(_make(imufuse_c, name, dtype, **kw).run(*x),
                         _make(reference, name, dtype, **kw).run(*x))


def test_bounds_are_inclusive_on_squares():
    """|a|^2 == (lo g)^2 and == (hi g)^2 pass; just outside does not."""
    for name in ("MadgwickIMU", "MahonyIMU"):
        for a, inside in (([0.0, 0.0, 0.5], True), ([0.0, 0.0, 2.0], True),
                          ([0.0, 0.0, np.nextafter(0.5, 0)], False),
                          ([0.0, 0.0, np.nextafter(2.0, 3)], False)):
            f = _make(imufuse_c, name, "float64", **GAINS[name], acc_gate=(0.5, 2.0))
            gyro = _make(imufuse_c, name, "float64", **dict(FILTERS)[name])
            ref = _make(reference, name, "float64", **GAINS[name], acc_gate=(0.5, 2.0))
            w = [0.1, 0.2, 0.3]
            for h in (f, gyro, ref):
                s = h.state
                s[:4] = [0.96, 0.2, -0.1, 0.17]     # tilted away from a
                s[:4] /= np.linalg.norm(s[:4])
                h.state = s
                h.update(w, a)
            assert np.array_equal(f.state, ref.state)
            assert np.array_equal(f.state[:4], gyro.state[:4]) != inside


@pytest.mark.parametrize("kwargs,msg", [
    (dict(acc_gate=(1.4, 0.6)), r"^acc_gate\[1\]:"), (dict(acc_gate=(-0.1, 1.4)), r"^acc_gate\[0\]:"),
    (dict(acc_gate=1.4), r"^acc_gate:"), (dict(acc_gate=(0.6, float("inf"))), r"^acc_gate\[1\]:"),
    (dict(acc_gate=(0.6, 1.4), acc_1g=0.0), r"^acc_1g:"), (dict(acc_1g=float("nan")), r"^acc_1g:")])
@pytest.mark.parametrize("name", [f[0] for f in FILTERS])
@each("mod", [imufuse_c, reference])
def test_bad_gate(mod, name, kwargs, msg):
    with pytest.raises(ValueError, match=msg):
        _make(mod, name, "float64", **kwargs)
