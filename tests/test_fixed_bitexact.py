"""Fixed-point filters: the C (csrc/fixed, gcc + UBSan test driver, and the
compiled imufuse_c classes) equals the pure-Python reference integer for
integer, every state variable after every sample, both profiles."""
from __future__ import annotations


import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

import cbuild  # noqa: E402

import imufuse.reference as reference  # noqa: E402
from imufuse import catalogue  # noqa: E402
from imufuse.registry import FIXED_CASES, fixed_matrix  # noqa: E402
from imufuse.shared.checks import KINDS  # noqa: E402

N = 600


def inputs(kind, seq, n=N, seed=0):
    """int16 count sequences: ordinary motion, extremes and the corners."""
    g = np.random.default_rng(seed)
    lo, hi = -32768, 32767
    if kind == "1d":
        t = np.arange(n)
        s = {
            "random": (g.integers(-3000, 3000, n), g.integers(-8000, 8000, n)),
            "full": (g.integers(lo, hi + 1, n), g.integers(lo, hi + 1, n)),
            "extreme": (np.where(t % 2, hi, lo), np.where(t % 3, lo, hi)),
            "sine": ((3000 * np.cos(t / 40)).astype(int), (8000 * np.sin(t / 40)).astype(int)),
            "zero": (np.zeros(n, int), np.zeros(n, int)),
        }[seq]
        return tuple(np.asarray(a, dtype=np.int16) for a in s)
    t = np.arange(n)[:, None]
    s = {
        "random": (g.integers(-3000, 3000, (n, 3)), g.integers(-6000, 6000, (n, 3)) + [0, 0, 4096]),
        "full": (g.integers(lo, hi + 1, (n, 3)), g.integers(lo, hi + 1, (n, 3))),
        "extreme": (np.where((t + np.arange(3)) % 2, hi, lo) * np.ones((n, 3), int),
                    np.where((t + np.arange(3)) % 3, lo, hi) * np.ones((n, 3), int)),
        "sine": ((3000 * np.sin(t / 30 + np.arange(3))).astype(int),
                 (4096 * np.cos(t / 50 + np.arange(3))).astype(int)),
        "zero_acc": (g.integers(-2000, 2000, (n, 3)), np.zeros((n, 3), int)),
        # at rest, level (q stays at the identity: q0 = 1.0 exactly) and tilted with
        # +-2 counts of noise: the normalisation must hold |q| at 1 (issue 10)
        "rest": (np.zeros((n, 3), int), np.tile([0, 0, 4096], (n, 1))),
        "rest_noise": (g.integers(-2, 3, (n, 3)), g.integers(-2, 3, (n, 3)) + [0, 2896, 2896]),
        "zero_mag": (g.integers(-2000, 2000, (n, 3)), g.integers(-3000, 3000, (n, 3))),
        # B4's branches: a steady field, a magnet attached (a new field, steady: it becomes
        # the reference), removed again, and a field straight down (no heading)
        "mag_steps": (g.integers(-40, 40, (n, 3)), g.integers(-20, 20, (n, 3)) + [0, 0, 4096]),
    }[seq]
    if kind == "ahrs":
        field = np.array([1200, 300, -2000])
        s = s + ({
            "random": g.integers(-900, 900, (n, 3)) + field,
            "full": g.integers(lo, hi + 1, (n, 3)),
            "extreme": np.where((t + np.arange(3)) % 5, hi, lo) * np.ones((n, 3), int),
            "sine": (2400 * np.cos(t / 70 + np.arange(3) * 2)).astype(int),
            "zero_acc": g.integers(-3, 4, (n, 3)) + field,
            # still, then a magnet attached: rejected, and at rest never the new reference
            "rest": np.where(t < n // 3, field, field + [0, 2500, -800]),
            "rest_noise": g.integers(-3, 4, (n, 3)) + field,
            "zero_mag": np.zeros((n, 3), int),
            "mag_steps": g.integers(-3, 4, (n, 3)) + np.select(
                [t < n // 4, t < n // 2, t < 3 * n // 4], [field, field + [2500, -900, 400],
                                                            field], [[0, 0, -1500]]),
        }[seq],)
    return tuple(np.asarray(a, dtype=np.int16) for a in s)


SEQS = ("random", "full", "extreme", "sine")
SEQS_KIND = {"1d": SEQS + ("zero",), "imu": SEQS + ("zero_acc", "rest", "rest_noise")}
SEQS_KIND["ahrs"] = SEQS_KIND["imu"] + ("zero_mag", "mag_steps")


def c_driver_run(case, profile, arrays, state=None, params=None):
    f = _make(case.name, params if params is not None else case.params, profile)
    args = f._args
    st = " ".join(str(int(v)) for v in state) if state is not None else ""
    head = (f"{case.name} {args[-1]} " + " ".join(float(v).hex() for v in args[:-1])
            + f" ; {st} ;\n")
    cols = np.column_stack([a.reshape(len(a), -1) for a in arrays])
    body = "\n".join(" ".join(map(str, row)) for row in cols.tolist())
    out = cbuild.run("filter_driver", head + body + "\n")
    return np.array([[int(v) for v in line.split()] for line in out.strip().split("\n")],
                     dtype=np.int64).reshape(len(cols), -1)


def _make(name, params, profile, backend="ref"):
    import importlib
    mod = reference if backend == "ref" else importlib.import_module("imufuse_c")
    return getattr(mod, name)(**params, profile=profile)


needs_gcc = pytest.mark.skipif(not cbuild.have_gcc(), reason="needs gcc")


@needs_gcc
@pytest.mark.parametrize("case,profile", fixed_matrix())
def test_c_driver_equals_reference(case, profile):
    """The C of csrc/fixed (gcc, UBSan: any report fails) against the reference."""
    for seq in SEQS_KIND[case.kind]:
        arrays = inputs(case.kind, seq)
        want = case.make_fixed("ref", profile).run(*arrays)
        got = c_driver_run(case, profile, arrays)
        assert got.shape == want.shape
        diff = np.argwhere(got != want)
        assert diff.size == 0, f"{seq}: first difference at sample {diff[0][0]}, " \
            f"variable {case.make_fixed('ref', profile).state_names[diff[0][1]]}: " \
            f"{got[tuple(diff[0])]} vs {want[tuple(diff[0])]}"


def _compiled():
    try:
        import imufuse_c
        return imufuse_c if hasattr(imufuse_c, "FILTERS_FIXED") else None
    except ImportError:
        return None


@needs_gcc
@pytest.mark.parametrize("case,profile", [p for p in fixed_matrix() if p.values[0].kind != "1d"])
def test_c_driver_exact_axis_readings(case, profile):
    """A still sensor whose quantised accelerometer reads exactly +-1 g along one axis (a
    board lying flat, on its side, upside down: the readings real MEMS parts give), each axis
    in turn from power-up and after a turn: the C driver against the reference. Gravity
    exactly antiparallel to earth z is a singular case of the inclination (RobustIMUQ's half
    turn)."""
    rows = []
    for axis in range(3):
        for sign in (-1, 1):
            a = [0, 0, 0]
            a[axis] = sign * 4096
            rows += [([0, 0, 0], a)] * 40 + [([300, -200, 100], a)] * 5
    g = np.array([r[0] for r in rows], dtype=np.int16)
    a = np.array([r[1] for r in rows], dtype=np.int16)
    # from power-up with the board upside down, then every axis in turn
    order = np.r_[np.arange(180, 225), np.arange(len(rows))]
    arrays = (g[order], a[order])
    if case.kind == "ahrs":
        # a constant field, exactly along an axis too: vertical (no heading) while upside
        # down, then horizontal
        m = np.where(np.arange(len(order))[:, None] < 45, [0, 0, 2000], [2000, 0, 0])
        arrays += (m.astype(np.int16),)
    want = case.make_fixed("ref", profile).run(*arrays)
    np.testing.assert_array_equal(c_driver_run(case, profile, arrays), want)


@pytest.mark.parametrize("case,profile", fixed_matrix())
def test_compiled_equals_reference(case, profile):
    if _compiled() is None:
        pytest.skip("imufuse_c not built with the fixed-point classes")
    for seq in SEQS_KIND[case.kind]:
        arrays = inputs(case.kind, seq)
        c, r = case.make_fixed("c", profile), case.make_fixed("ref", profile)
        got, want = c.run(*arrays), r.run(*arrays)
        assert got.dtype == np.int32 and want.dtype == np.int32
        np.testing.assert_array_equal(got, want, err_msg=seq)
        np.testing.assert_array_equal(c.state, r.state)


@pytest.mark.parametrize("case,profile", fixed_matrix())
def test_update_matches_run_and_reset(case, profile):
    arrays = inputs(case.kind, "random", n=120, seed=3)
    backends = ["ref"] + (["c"] if _compiled() else [])
    for b in backends:
        f = case.make_fixed(b, profile)
        init = f.state.copy()
        traj = f.run(*arrays)
        f.reset()
        np.testing.assert_array_equal(f.state, init)
        steps = []
        for row in zip(*arrays):
            f.update(*row)
            steps.append(f.state)
        np.testing.assert_array_equal(np.array(steps), traj)
        # state round trip
        g = case.make_fixed(b, profile)
        g.state = traj[60]
        np.testing.assert_array_equal(g.run(*[a[61:] for a in arrays]), traj[61:])


def _hyp(kind):
    c = st.integers(-32768, 32767)
    if kind == "1d":
        return st.lists(st.tuples(c, c), min_size=1, max_size=80).map(
            lambda rows: tuple(np.array(col, dtype=np.int16) for col in zip(*rows)))
    v = st.tuples(c, c, c)
    return st.lists(st.tuples(*[v] * len(KINDS[kind])), min_size=1, max_size=60).map(
        lambda rows: tuple(np.array(col, dtype=np.int16) for col in zip(*rows)))


@needs_gcc
@pytest.mark.parametrize("case,profile", fixed_matrix())
def test_hypothesis_full_int16_range(case, profile):
    """Any int16 inputs, from any reachable state: C (UBSan) == reference."""
    @settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck),
              derandomize=True)
    @given(_hyp(case.kind))
    def check(arrays):
        want = case.make_fixed("ref", profile).run(*arrays)
        np.testing.assert_array_equal(c_driver_run(case, profile, arrays), want)
    check()


def test_harness_sees_one_lsb():
    """A reference with one rounding changed (ties down instead of up in
    the quaternion normalisation) must be caught by the comparison."""
    from imufuse.reference import _cint as ci
    from imufuse.reference import fixed_quat as fq

    case = next(c for c in FIXED_CASES if c.name == "MahonyIMUQ")
    arrays = inputs("imu", "random")
    good = case.make_fixed("ref", "32").run(*arrays)
    orig = fq.add_normalise

    def biased(q, dq):
        q = [ci.add_sat32(a, b) for a, b in zip(q, dq)]
        qs = fq.snapshot(q)
        y, sh = ci.invsqrt_u32(sum(v * v for v in qs))
        y14 = 32767 if y >= 65535 else y >> 1         # truncates instead of rounding
        return [ci.mul_32x16(v, y14, sh - 16) for v in q]
    fq.add_normalise = biased
    try:
        bad = case.make_fixed("ref", "32").run(*arrays)
    finally:
        fq.add_normalise = orig
    assert (bad != good).any()


# ---- extreme parameters and arbitrary states: no UB, still bit-exact --------

def _logu(lo, hi):
    return st.floats(np.log(lo), np.log(hi)).map(np.exp)


PARAM_SPACE = {
    "Complementary1DQ": dict(dt=_logu(1e-5, 1.0), alpha=st.floats(0.0, 1.0),
                             gyr_scale=_logu(1e-7, 1.0), angle_scale=_logu(1e-7, 1.0)),
    "Mahony1DBiasQ": dict(dt=_logu(1e-5, 0.1), kp=_logu(1e-3, 100.0), ki=_logu(1e-4, 1e3),
                          gyr_scale=_logu(1e-7, 1.0), angle_scale=_logu(1e-7, 1.0)),
    "KKQ": dict(dt=_logu(1e-5, 0.1), kp=st.one_of(st.just(1.0), st.floats(0.0, 1.0)), gyr_scale=_logu(1e-7, 1e-2)),
    "MultiWiiQ": dict(dt=_logu(1e-5, 0.1), cmpf=st.one_of(st.just(0.0), _logu(1e-3, 1e6)),
                      acc_lpf_shift=st.integers(0, 15), acc_1g=st.floats(1e-3, 32767.0),
                      window=st.floats(0.0, 1.0), gyr_scale=_logu(1e-7, 1e-2)),
    "MahonyIMUQ": dict(dt=_logu(1e-5, 0.1), kp=_logu(1e-4, 1e3), ki=_logu(1e-5, 1e3),
                       gyr_scale=_logu(1e-7, 1e-2)),
    "MadgwickIMUQ": dict(dt=_logu(1e-5, 0.1), beta=_logu(1e-4, 1e3), gyr_scale=_logu(1e-7, 1e-2)),
    "RobustIMUQ": dict(dt=_logu(1e-3, 1e-2), tau_acc=_logu(2.0, 8.0),
                       rate_ref=st.one_of(st.just(0.0), _logu(1.0, 1e4)),
                       tau_bias=st.one_of(st.just(0.0), _logu(80.0, 1e4)),
                       tau_bias_rest=_logu(1e-3, 1e3), rest_gyr=_logu(1e-3, 1e3),
                       rest_acc=st.floats(0.0, 1.0), rest_time=st.floats(0.0, 5.0),
                       tau_rest=_logu(1e-3, 10.0), latency=st.floats(0.0, 0.1),
                       gyr_scale=_logu(1e-6, 1e-3)),
}
PARAM_SPACE["RobustAHRSQ"] = dict(
    PARAM_SPACE["RobustIMUQ"], tau_mag=_logu(1e-3, 1e3), mag_norm=st.floats(0.0, 1.0),
    mag_dip=st.floats(0.0, 180.0), tau_mag_ref=_logu(1e-3, 1e3),
    mag_new_time=st.floats(0.0, 50.0), mag_hold=st.floats(0.0, 5.0), mag_learn=st.booleans(),
    mag_noise=_logu(1e-3, 2.0), mag_lag=st.floats(0.0, 0.2), mag_offset_min=st.floats(0.0, 2.0))
STATE_SIZE = {e.name: len(e.state_names) for e in catalogue.FIXED}


def test_param_space_covers_the_catalogue():
    """Every fixed filter has a parameter space for the hypothesis test, over
    parameters its constructor takes."""
    assert sorted(PARAM_SPACE) == sorted(catalogue.FILTERS_FIXED)
    for e in catalogue.FIXED:
        assert set(PARAM_SPACE[e.name]) <= set(e.params) - {"profile"}, e.name
I32 = st.one_of(st.integers(-2**31, 2**31 - 1), st.sampled_from([-2**31, -2**31 + 1, -1, 0, 1, 2**30, 2**31 - 1]))


@needs_gcc
@pytest.mark.parametrize("name,profile", [pytest.param(n, p, id=f"{n}-{p}") for n in PARAM_SPACE
                                          for p in getattr(reference, n).profiles])
def test_hypothesis_extreme_params_and_states(name, profile):
    """Parameters across their accepted range (rejected ones must raise
    ValueError), any int32 initial state, any int16 inputs: the C driver
    (UBSan: any report fails) equals the reference."""
    from hypothesis import assume
    kind = getattr(reference, name).kind

    @settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck),
              derandomize=True)
    @given(st.fixed_dictionaries(PARAM_SPACE[name]),
           st.lists(I32, min_size=STATE_SIZE[name], max_size=STATE_SIZE[name]), _hyp(kind))
    def check(params, state, arrays):
        try:
            r = _make(name, params, profile)
        except ValueError:
            assume(False)
        r.state = np.array(state, dtype=np.int64)
        want = r.run(*arrays)
        case = type("C", (), {"name": name, "params": params})
        got = c_driver_run(case, profile, arrays, state=state, params=params)
        np.testing.assert_array_equal(got, want)
    check()
