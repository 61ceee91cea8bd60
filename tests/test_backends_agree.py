"""The two backends agree on every input type and every output bit, NaN sign and payload
included: a property test over every filter of the catalogue (one case each: the other
configurations are the bit-exact suites') and every free function.

Inputs mix Gaussian values with the IEEE specials (both NaN signs, +-Inf, +-0, subnormals,
the largest finite values) and are given as the types users have: float64 and float32
arrays, int arrays, lists, Fortran-ordered and strided views. Inputs that are not real
numbers (complex, None, strings, objects) must be refused by both backends with the same
exception type, before any conversion.
"""
import numpy as np
import pytest

import imufuse_c
from imufuse import catalogue
from imufuse import reference as ref
from imufuse.reference import fusion as rfusion
from imufuse.reference import vario as rvario

from bits import UINT

DTYPES = ("float32", "float64")
SPECIALS = np.array([np.nan, -np.nan, np.inf, -np.inf, 0.0, -0.0, 1e-40, -3e-42, 1e-310,
                     3e38, -3e38, 1e300, 1.0, -1.0])


def hostile(rng, shape, p=0.3):
    x = rng.normal(0.0, 1.0, shape)
    m = rng.random(shape) < p
    x[m] = rng.choice(SPECIALS, int(m.sum()))
    return x


def same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape, (a.dtype, a.shape, b.dtype, b.shape)
    u = UINT.get(a.dtype, a.dtype)      # integer states compare as they are
    diff = np.flatnonzero(a.view(u).ravel() != b.view(u).ravel())
    assert diff.size == 0, (f"{diff.size} elements differ, first at flat index {diff[0]}: "
                            f"{a.ravel()[diff[0]]!r} ({a.view(u).ravel()[diff[0]]:#x}) vs "
                            f"{b.ravel()[diff[0]]!r} ({b.view(u).ravel()[diff[0]]:#x})")


def forms(x):
    """The same values as users pass them."""
    yield "float64", np.ascontiguousarray(x, np.float64)
    with np.errstate(over="ignore"):
        yield "float32", np.ascontiguousarray(x, np.float32)
    yield "fortran", np.asfortranarray(x)
    yield "strided", np.repeat(x, 2, axis=0)[::2]
    yield "list", x.tolist()
    ints = np.nan_to_num(x, nan=0.0, posinf=5.0, neginf=-5.0)
    yield "int", np.clip(np.round(ints * 3), -100, 100).astype(np.int32)


# ---- free functions -----------------------------------------------------------------

def _free(dtype, rng):
    """(name, C call, twin call) of every free function over one hostile input set."""
    n = 400
    x, acc, mag, q = hostile(rng, (n, 3)), hostile(rng, (n, 3)), hostile(rng, (n, 3)), \
        hostile(rng, (n, 4))
    M, s, b = np.array([[1.1, 0.01, 0.0], [0.0, 0.9, 0.02], [0.0, 0.0, 1.0]]), \
        np.array([1.0, 1.01, 0.99]), np.array([0.1, -0.2, 0.05])
    out = [("calibrate_inertial", lambda v: imufuse_c.calibrate_inertial(v, M, s, b, dtype=dtype),
            lambda v: rfusion.calibrate_inertial(v, M, s, b, dtype), x),
           ("calibrate_magnetic", lambda v: imufuse_c.calibrate_magnetic(v, M, b, dtype=dtype),
            lambda v: rfusion.calibrate_magnetic(v, M, b, dtype), x),
           ("axes_apply", lambda v: imufuse_c.axes_apply(v, "+Y-Z-X", dtype=dtype),
            lambda v: rfusion.axes_apply(v, "+Y-Z-X", dtype), x)]
    for conv in ("NWU", "ENU", "NED"):
        for inv in ("exact", "fast"):
            out.append((f"compass_heading-{conv}-{inv}",
                        lambda v, c=conv, i=inv: imufuse_c.compass_heading(c, v, mag, invsqrt=i,
                                                                           dtype=dtype),
                        lambda v, c=conv, i=inv: rfusion.compass_heading(c, v, mag, invsqrt=i,
                                                                         dtype=dtype), acc))
    for conv in ("nwu", "ned", "ned_seed"):
        out.append((f"vertical_accel-{conv}",
                    lambda v, c=conv: imufuse_c.vertical_accel(q, v, c, dtype=dtype),
                    lambda v, c=conv: rvario.vertical_accel(q, v, c, dtype=dtype), acc))
    return out


@pytest.mark.parametrize("dtype", DTYPES)
def test_free_functions_agree_bit_for_bit(dtype):
    rng = np.random.default_rng(11)
    names = []
    for name, c, r, v in _free(dtype, rng):
        for _form, arg in forms(v):
            with np.errstate(all="ignore"):
                same_bits(c(arg), r(arg))
        names.append(name)
    assert len(names) == 12


@pytest.mark.parametrize("bad", [None, "abc", [[1 + 2j, 0, 0]], [[object(), 1, 2]], {"a": 1}],
                         ids=["None", "str", "complex", "object", "dict"])
def test_free_functions_refuse_what_is_not_real_alike(bad):
    rng = np.random.default_rng(2)
    for name, c, r, _ in _free("float64", rng):
        errs = []
        for f in (c, r):
            try:
                f(bad)
                errs.append(None)
            except Exception as e:    # the type is compared below
                errs.append(type(e))
        assert errs[0] is not None and errs[0] == errs[1], (name, errs)


def test_undefined_heading_is_nan_in_both():
    """A zero accelerometer, a zero magnetometer and a field along gravity have no heading:
    NaN from both backends (Fusion returns 0, north); a defined heading is a number."""
    acc = [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]
    mag = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -3.0]]
    for dtype in DTYPES:
        for conv in ("NWU", "ENU", "NED"):
            for mod in (imufuse_c, rfusion):
                h = mod.compass_heading(conv, acc, mag, dtype=dtype)
                assert np.isfinite(h[0]) and np.all(np.isnan(h[1:])), (mod, conv, h)
                assert np.all(np.signbit(h[1:]) == 0)


def test_the_bit_comparison_can_fail():
    a = np.array([np.nan])
    b = -a
    with pytest.raises(AssertionError, match="differ"):
        same_bits(a, b)


# ---- the catalogue --------------------------------------------------------------------

def _entries():
    out = []
    for e in (*catalogue.FLOAT, *catalogue.FIXED):
        out.append(e)
    return out


def _inputs(e, rng, n=150):
    if e.kind == "1d":
        return [hostile(rng, n, 0.1), hostile(rng, n, 0.1)]
    k = 3 if e.kind == "ahrs" else 2
    g = hostile(rng, (n, 3), 0.1)
    a = hostile(rng, (n, 3), 0.1) + np.array([0.0, 0.0, 9.81])
    m = hostile(rng, (n, 3), 0.1) + np.array([20.0, 0.0, -40.0])
    return [g, a, m][:k]


def _fixed_inputs(e, rng, n=150):
    ins = _inputs(e, rng, n)
    return [np.clip(np.nan_to_num(v * 1000, nan=0, posinf=32767, neginf=-32768), -32768,
                    32767).astype(np.int16) for v in ins]


@pytest.mark.parametrize("e", _entries(), ids=lambda e: e.name)
def test_every_filter_agrees_on_every_input_form(e):
    """run() of the compiled filter and of the twin, on the same hostile samples given in
    every form, give the same bits (state after every sample)."""
    rng = np.random.default_rng(5)
    if e.fixed:
        ins = _fixed_inputs(e, rng)
        c = e.make("c", dt=0.002, **e.defaults).run(*ins)
        r = e.make("ref", dt=0.002, **e.defaults).run(*ins)
        same_bits(np.asarray(c), np.asarray(r))
        return
    ins = _inputs(e, rng)
    for dtype in DTYPES:
        want = None
        for form in ("float64", "float32", "fortran", "strided", "list"):
            args = [dict(forms(np.asarray(v)))[form] for v in ins]
            with np.errstate(all="ignore"):
                c = np.asarray(e.make("c", dt=0.01, **e.defaults, dtype=dtype).run(*args))
                r = np.asarray(e.make("ref", dt=0.01, **e.defaults, dtype=dtype).run(*args))
            same_bits(c, r)
            if form in ("float64", "list", "fortran", "strided"):
                want = c if want is None else want
                same_bits(c, want)     # the same values in another container: same result


@pytest.mark.parametrize("e", [e for e in _entries() if not e.fixed], ids=lambda e: e.name)
def test_every_filter_refuses_what_is_not_real_alike(e):
    rng = np.random.default_rng(6)
    ins = _inputs(e, rng, 5)
    for bad in (None, "abc", ins[0].astype(complex), np.array(ins[0], dtype=object)):
        errs = []
        for backend in ("c", "ref"):
            f = e.make(backend, dt=0.01, **e.defaults)
            try:
                f.run(bad, *ins[1:])
                errs.append(None)
            except Exception as err:   # the type is compared below
                errs.append(type(err))
        assert errs[0] is not None and errs[0] == errs[1], (e.name, type(bad), errs)


def test_the_catalogue_is_covered():
    names = {e.name for e in _entries()}
    assert {"RobustAHRS", "MadgwickIMU", "MahonyIMUQ", "DCM", "Kalman1DBias"} <= names
    assert ref.RobustAHRS is catalogue.entry("RobustAHRS").reference
