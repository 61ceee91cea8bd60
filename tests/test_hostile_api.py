"""Hostile calls (docs/robustness.md), the other half of tests/test_hostile.py (hostile
samples): both backends accept and reject the same constructor arguments, inputs and
state writes (hypothesis, every registry configuration, float and fixed point); no
compiled object crashes the interpreter when its __init__ never ran; every run() layout
and dtype; the reproductions of earlier defects (a huge sample, parameters at the edge
of their precision and stable range, runaway integral terms, parameters that vanish in
float32); fixed-point extreme counts bit for bit."""
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st, HealthCheck

import imufuse.reference as reference
import imufuse_c
from imufuse import catalogue, session, sim
from imufuse.shared.checks import KINDS
from bits import assert_same_bits
from imufuse.registry import (DTYPES, FIXED_CASES, PROFILES, each_backend, fixed_matrix,
                              representatives)
from test_hostile import CASES, _each, _error, _static


# ---- acceptance: both backends accept and reject the same things -------------

_ODD = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10 ** 400, 10 ** 400),
    st.sampled_from(["0.5", "", "x", None, True, 1 + 2j, np.complex128(1), {1, 2, 3},
                     {"a": 1}, [1.0, 2.0], np.float32(0.1), 1e39, 1e-50, 5e-324, -0.0]))


def _outcome(fn):
    try:
        fn()
        return "ok"
    except (ValueError, TypeError) as e:
        return f"{type(e).__name__}: {e}"


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
@given(case=st.sampled_from(CASES), dtype=st.sampled_from([*DTYPES, None, "float16"]),
       key=st.integers(0, 10), value=_ODD)
def test_constructors_agree(case, dtype, key, value):
    params = dict(case.params)
    names = list(params)
    params[names[key % len(names)]] = value
    out = [_outcome(lambda m=m: getattr(m, case.name)(**params, dtype=dtype))
           for m in (imufuse_c, reference)]
    assert out[0] == out[1]


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
@given(case=st.sampled_from(CASES), dtype=st.sampled_from(DTYPES), slot=st.integers(0, 8),
       value=_ODD, vector=st.booleans())
def test_update_inputs_agree(case, dtype, slot, value, vector):
    one = _static(case.kind, scale=case.params.get("acc_1g", 1.0), n=1)
    args = [list(x[0]) if np.ndim(x[0]) else float(x[0]) for x in one]
    i = slot % len(args)
    if vector and case.kind != "1d":
        args[i][slot % 3] = value
    else:
        args[i] = value
    fs = [case.make(b, dtype) for b in ("c", "ref")]
    out = [_outcome(lambda f=f: f.update(*args)) for f in fs]
    assert out[0] == out[1]
    assert_same_bits(fs[0].state, fs[1].state)
    assert fs[0].skipped == fs[1].skipped


@pytest.mark.parametrize("profile", PROFILES)
@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in FIXED_CASES])
def test_fixed_constructors_agree(case, profile):
    for name in case.params:
        for bad in (math.nan, math.inf, 1e39, 1e-50, "0.5", None, 10 ** 400, 1e-5):
            p = {**case.params, name: bad}
            out = [_outcome(lambda m=m: getattr(m, case.name)(**p, profile=profile))
                   for m in (imufuse_c, reference)]
            assert out[0] == out[1], (name, bad, out)


# ---- API misuse ----------------------------------------------------------------

@pytest.mark.parametrize("name", [*imufuse_c.FILTERS, *imufuse_c.FILTERS_FIXED])
def test_uninitialised_object_raises(name):
    cls = getattr(imufuse_c, name)
    types = list(cls._impl.values()) if hasattr(cls, "_impl") else [cls]
    for t in types:
        o = t.__new__(t)
        repr(o)
        for attr in ("skipped", "state", "state_float"):
            if hasattr(t, attr):
                with pytest.raises(TypeError, match="not initialised"):
                    getattr(o, attr)
        n = {"1d": 2, "imu": 2, "ahrs": 3}[t._ref.kind]
        for meth, args in (("reset", ()), ("update", (0.0,) * n), ("run", (np.zeros(1),) * n)):
            with pytest.raises(TypeError, match="not initialised"):
                getattr(o, meth)(*args)


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in representatives(CASES)])
def test_run_layouts_and_dtypes(case):
    """run()'s input conversion is the base class's (imufuse_c/_base.pxi, reference/_base.py):
    one filter of each base, both backends and precisions."""
    _each(lambda b, d: _run_layouts(case, d, b), ("c", "ref"), DTYPES)


def _run_layouts(case, dtype, backend):
    """Any memory layout and real dtype gives the trajectory of the contiguous
    float64 input; complex, string and object inputs are refused."""
    f = case.make(backend, dtype)
    base = [np.asarray(x, dtype=float) for x in _static(case.kind, scale=case.params.get("acc_1g", 1.0), n=20)]
    base[0] = base[0] + 0.01 * np.arange(20).reshape((20,) + (1,) * (base[0].ndim - 1))
    want = f.run(*base)
    variants = [
        [np.asfortranarray(x) for x in base],
        [x.astype(np.float32).astype(np.float64) if dtype == "float32" else x for x in base],
        [np.repeat(x, 2, axis=0)[::2] for x in base],                 # strided
        [x.astype(">f8") for x in base],                             # byte-swapped
        [x.tolist() for x in base],
    ]
    for v in variants:
        f.reset()
        assert_same_bits(f.run(*v), want, f.state_names)
    for bad in (base[0].astype(complex), base[0].astype(str), base[0].astype(object)):
        with pytest.raises(ValueError, match=r"^run\(\): "):
            f.run(bad, *base[1:])


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in CASES if c.kind != "1d"])
@each_backend
def test_state_writes_must_be_valid(case, backend):
    f = case.make(backend, "float64")
    s = f.state.copy()
    f.state = s                                   # the state it has is valid
    bad = s.copy()
    bad[:3] *= 1e6 if case.name != "KK" else 1.0
    if case.name != "KK":
        with pytest.raises(ValueError, match="^state: not a valid attitude"):
            f.state = bad
        zero = s.copy()
        zero[:4 if case.name.startswith(("Mahony", "Madgwick")) and case.name != "Mahony2D" else 3] = 0
        with pytest.raises(ValueError, match="^state: "):
            f.state = zero
    assert_same_bits(f.state, s)


# ---- the reproductions of the defects, as tests -----------------------------------

@pytest.mark.parametrize("name,dtype,huge", [
    ("MahonyIMU", "float32", 1e30), ("MahonyAHRS", "float32", 1e30),
    ("MadgwickIMU", "float32", 1e30), ("MadgwickAHRS", "float32", 1e30),
    ("MahonyIMU", "float64", 1e300), ("MadgwickIMU", "float64", 1e300)])
@each_backend
def test_one_huge_sample_is_rejected_not_fatal(backend, name, dtype, huge):
    mod = imufuse_c if backend == "c" else reference
    f = getattr(mod, name)(dt=0.005, dtype=dtype)
    args = [[huge, 0.0, 0.0], [0.0, 0.0, 1.0]] + ([[0.4, 0.0, -0.9]] if f.kind == "ahrs" else [])
    q = f.state.copy()
    f.update(*args)
    assert f.skipped == 1 and f.state.tobytes() == q.tobytes()
    f.update(*[[0.0, 0.0, 0.0]] + args[1:])
    assert f.skipped == 1 and abs(np.linalg.norm(f.state[:4]) - 1.0) < 1e-5


@pytest.mark.parametrize("name,params,dtype,word", [
    ("MultiWii", dict(dt=0.01, acc_1g=1e39), "float32", "acc_1g"),
    ("MultiWii", dict(dt=0.01, acc_1g=1e20), "float32", "acc_1g"),     # derived ((1+w) g)^2
    ("MahonyIMU", dict(dt=0.01, kp=1e39), "float32", "kp"),
    ("MadgwickIMU", dict(dt=0.01, beta=1e39), "float32", "beta"),
    ("MahonyIMU", dict(dt=1e39, kp=0.0), "float32", "dt"),
    ("MahonyIMU", dict(dt=1e-50), "float32", "dt"),
    ("Kalman1D", dict(dt=1e-320, k0=0.02), "float64", "dt"),
    ("MahonyIMU", dict(dt=0.01, kp=250.0), "float64", "kp, ki"),          # 37 deg off before
    ("MahonyIMU", dict(dt=0.01, kp=1.0, ki=40000.0), "float64", "kp, ki"),
    ("MahonyIMU", dict(dt=0.01, kp=0.0, ki=0.1), "float64", "kp, ki"),
    ("MadgwickIMU", dict(dt=0.01, beta=150.0), "float64", "beta"),        # 180 deg off before
    ("MadgwickAHRS", dict(dt=0.01, beta=11.0), "float64", "beta"),
    ("Mahony2D", dict(dt=0.01, kp=200.0, ki=0.0, error="exact"), "float64", "kp, ki"),
    ("Mahony2D", dict(dt=0.01, kp=100.0, ki=20000.0, error="exact"), "float64", "kp, ki"),
])
@each_backend
def test_parameters_in_own_precision_and_stable_range(backend, name, params, dtype, word):
    mod = imufuse_c if backend == "c" else reference
    with pytest.raises(ValueError, match=rf"^{re.escape(word)}\b"):
        getattr(mod, name)(**params, dtype=dtype)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name,params,tol_deg", [
    ("MahonyIMU", dict(dt=0.01, kp=190.0), 2.0),                 # kp dt = 1.9
    ("MahonyIMU", dict(dt=0.01, kp=100.0, ki=19000.0), 2.0),     # ki dt^2 = 1.9 < 4 - 2
    ("MahonyIMU", dict(dt=1 / 512, kp=0.5), 2.0),                # published
    ("Mahony2D", dict(dt=0.01, kp=190.0, ki=0.0, error="exact"), 2.0),
    ("Mahony2D", dict(dt=0.01, kp=100.0, ki=19000.0, error="exact"), 2.0),
    ("MadgwickIMU", dict(dt=0.01, beta=10.0), math.degrees(0.2)),  # beta dt = 0.1
    ("MadgwickIMU", dict(dt=1 / 512, beta=0.1), 2.0),            # published
])
def test_edge_of_stable_range_converges(dtype, name, params, tol_deg):
    """Inside the stated range the filter settles on a static 30 deg tilt
    within its stated accuracy (Madgwick: the 2 beta dt limit cycle)."""
    f = getattr(imufuse_c, name)(**params, dtype=dtype)
    S = f.run(*_static("imu", n=int(40 / params["dt"])))
    case = next(c for c in CASES if c.name == name)
    errs = [_error(case, S[k:k + 1]) for k in range(len(S) - 200, len(S))]
    assert max(errs) <= math.radians(tol_deg), math.degrees(max(errs))
    assert f.skipped == 0


# ---- fixed point (profiles 32 and 8): extreme counts, API-level agreement ------------

@pytest.mark.parametrize("case,profile", fixed_matrix())
def test_fixed_extreme_counts_bit_exact(case, profile):
    """Full-scale int16 counts (-32768, 32767), alternating extremes and long
    constant stretches: C equals the reference bit for bit."""
    c, r = case.make_fixed("c", profile), case.make_fixed("ref", profile)
    g = np.random.default_rng(3)
    ext = np.array([-32768, -32767, -1, 0, 1, 32767], dtype=np.int16)
    n = 240
    k = len(KINDS[c.kind])
    cols = 2 if c.kind == "1d" else 3 * k
    x = ext[g.integers(0, len(ext), size=(n, cols))]
    x[60:120] = 32767                                     # constant full scale
    x[120:180] = np.where(np.arange(60)[:, None] % 2 == 0, -32768, 32767)  # alternating
    args = ((x[:, 0], x[:, 1]) if c.kind == "1d"
            else tuple(x[:, 3 * i:3 * i + 3].copy() for i in range(k)))
    assert_same_bits(c.run(*args), r.run(*args))


@pytest.mark.parametrize("case,profile", fixed_matrix())
def test_fixed_update_inputs_agree(case, profile):
    for bad in (40000, -40000, 1.5, "1", math.nan, None, 10 ** 400, 1 + 1j, {1, 2, 3}):
        fs = [case.make_fixed(b, profile) for b in ("c", "ref")]
        if fs[0].kind == "1d":
            args = (bad, 0)
        elif fs[0].kind == "ahrs":
            # the bad value in the magnetometer: the last input is checked too
            args = ([0, 0, 0], [0, 0, 4096], [2000, bad, -4000])
        else:
            args = ([bad, 0, 0], [0, 0, 4096])
        out = [_outcome(lambda f=f: f.update(*args)) for f in fs]
        assert out[0] == out[1], (bad, out)
        assert fs[0].state.tolist() == fs[1].state.tolist()


@pytest.mark.parametrize("dtype", ["int16", "int64", "float64"])
def test_fixed_run_of_a_huge_view_fails_at_once(dtype):
    """A broadcast view of 10^13 rows of counts: both backends raise MemoryError at the
    copy; the shared check first scanned it (min() and max(), and for floats isfinite and
    round over the whole view) for hours. The copy now comes first, then the checks a
    block of rows at a time."""
    import os
    import subprocess
    import sys
    code = ("import numpy as np, imufuse_c, imufuse.reference as R\n"
            f"g = np.broadcast_to(np.array([1, 2, 3], np.{dtype}), (10**13, 3))\n"
            "for m in (imufuse_c, R):\n"
            "    try:\n"
            "        m.MadgwickIMUQ(dt=0.01, gyr_scale=1e-3).run(g, g)\n"
            "    except MemoryError:\n"
            "        print('MemoryError')\n")
    import imufuse
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([os.path.dirname(os.path.dirname(m.__file__))
                                         for m in (imufuse, imufuse_c)]
                                        + [env.get("PYTHONPATH", "")])
    try:
        r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                           text=True, timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail("run() scanned the 10^13-row view instead of failing at once")
    assert r.stdout.split() == ["MemoryError"] * 2, r.stdout + r.stderr


def _binding_calls(kind, fixed):
    """update()/run() calls as a user writes them: the inputs by name, dt by position or by
    name, a magnetometer given to a filter without one, too few, too many, twice."""
    names = KINDS[kind]
    if fixed:
        one = {"rate": 100, "angle": 200, "gyr": [10, 20, 30], "acc": [0, 0, 4096],
               "mag": [100, 0, -200]}
        many = {k: np.tile(np.asarray(v, np.int16), (6, 1)).squeeze() for k, v in one.items()}
    else:
        one = {"rate": 0.1, "angle": 0.2, "gyr": [0.1, 0.2, 0.3], "acc": [0.0, 0.0, 1.0],
               "mag": [0.4, 0.0, -0.9]}
        many = {k: np.tile(np.asarray(v, float), (6, 1)).squeeze() for k, v in one.items()}
    pos, arr = [one[n] for n in names], [many[n] for n in names]
    dts = np.full(6, 0.01)
    return [
        lambda f: f.update(**dict(zip(names, pos))),
        lambda f: f.update(*pos, 0.01),
        lambda f: f.update(*pos[:1], **dict(zip(names[1:], pos[1:])), dt=0.01),
        lambda f: f.update(*pos, one["mag"]),
        lambda f: f.update(*pos, 0.01, 5),
        lambda f: f.update(*pos[:1]),
        lambda f: f.update(),
        lambda f: f.update(**{names[-1]: pos[-1]}),
        lambda f: f.update(*pos, **{names[0]: pos[0]}),
        lambda f: f.update(*pos, dtt=0.01),
        lambda f: f.run(**dict(zip(names, arr))),
        lambda f: f.run(*arr, dts),
        lambda f: f.run(*arr, dts, "state"),
        lambda f: f.run(*arr, many["mag"]),
        lambda f: f.run(*arr, None, "state", 1),
        lambda f: f.run(*arr[:1]),
        lambda f: f.run(*arr, dt=dts, outputs="state"),
    ]


@pytest.mark.parametrize("case,profile", [*[(c, None) for c in representatives(CASES)],
                                          *fixed_matrix()])
def test_calls_bind_alike(case, profile):
    """The twin's update() and run() take their arguments as the compiled ones do: inputs
    by name (update(gyr=g, acc=a)) and dt as the argument after them (update(g, a, 0.01)),
    which the twin refused with a TypeError while the compiled filter ran them; too few,
    too many and doubled arguments give the same TypeError, a magnetometer given to a
    filter without one the same ValueError naming it."""
    for call in _binding_calls(case.kind, profile is not None):
        fs = [case.make(b, "float64") if profile is None else case.make_fixed(b, profile)
              for b in ("c", "ref")]
        out = [_outcome(lambda f=f: call(f)) for f in fs]
        assert out[0] == out[1], out
        assert_same_bits(fs[0].state, fs[1].state)
    if profile is None:       # what the session reads from the twin's signature
        assert session.supports_dt_array(case.name)
    if case.kind == "imu" and profile is None:
        f = case.make("ref", "float64")
        with pytest.raises(ValueError, match="magnetometer given to a filter that takes none"):
            f.update([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.4, 0.0, -0.9])


@pytest.mark.parametrize("name,params", [("MahonyIMU", dict(dt=0.005, kp=1.0, ki=0.3)),
                                         ("DCM", dict(dt=0.005, kp=2.0, ki=0.5))])
@each_backend
def test_state_write_of_a_runaway_integral_term(backend, name, params):
    """I = 1e30 rad/s cannot be unwound (ki dt per sample) and makes every
    float32 sample overflow: refused; |I| dt = 1 rad is the limit. DCM cannot
    renormalise R after a turn of about 0.3 rad in one sample: from there on samples
    are rejected, I never unwinds, and the trial of the write (still samples in four
    orientations) refuses it (a real log then rejects all of its samples too)."""
    cls = getattr(imufuse_c if backend == "c" else reference, name)
    f = cls(**params, dtype="float32")
    s = f.state.copy()
    k = list(f.state_names).index("iy")
    s[k] = 1e30
    with pytest.raises(ValueError, match=r"^state: not a valid attitude \(iy = "):
        f.state = s
    s[k] = 0.99 / params["dt"]
    if name == "DCM":
        with pytest.raises(ValueError, match=r"^state: the filter cannot continue from it"):
            f.state = s
        d = sim.imu("fast", rate=1 / params["dt"], duration=1.0, seed=1)
        ref = reference.DCM(**params, dtype="float32")
        ref.iy = np.float32(s[k])                   # the write the trial refuses
        ref.run(d.gyr, d.acc)
        assert ref.skipped == len(d.gyr)            # dead: every sample rejected
        s[k] = 0.1 / params["dt"]
    f.state = s
    assert np.array_equal(f.state, s.astype(np.float32))


@pytest.mark.parametrize("e", [e for e in catalogue.FLOAT], ids=lambda e: e.name)
def test_no_state_write_leaves_a_dead_filter(e):
    """Every state component set to a finite extreme (+-3e38, 1e20): the write is either
    refused by both backends alike, or the filter then accepts samples of a real motion
    (it is not dead). test_state_write_of_a_runaway_integral_term shows a refused one."""
    d = sim.imu("fast", rate=100.0, duration=0.5, seed=3)
    n = len(e.reference.state_names)
    for i in range(n):
        for v in (3e38, -3e38, 1e20):
            outcome = []
            for backend in ("c", "ref"):
                f = e.make(backend, dt=0.01, **e.defaults, dtype="float32")
                s = f.state.copy()
                s[i] = v
                try:
                    with np.errstate(all="ignore"):
                        f.state = s
                except ValueError as err:
                    outcome.append(str(err).split(":")[0] + ":" + str(err).split(":")[1][:20])
                    continue
                with np.errstate(all="ignore"):
                    if e.kind == "1d":
                        f.run(d.gyr[:, 0], np.zeros(len(d.gyr)))
                    elif e.kind == "imu":
                        f.run(d.gyr, d.acc)
                    else:
                        f.run(d.gyr, d.acc, d.mag)
                assert f.skipped < len(d.gyr), (e.name, backend, f.state_names[i], v)
                outcome.append("accepted")
            assert outcome[0] == outcome[1], (e.name, f.state_names[i], v, outcome)


_VANISHING = [(e, name) for e in (*catalogue.FLOAT, *catalogue.VARIO, *catalogue.FUSION)
              for name, default in e.params.items()
              if name != "dt" and isinstance(default, float) and not isinstance(default, bool)]


_VANISHING_ENTRIES = [e for k, e in enumerate(x for x, _ in _VANISHING)
                      if all(e is not y for y, _ in _VANISHING[:k])]


@pytest.mark.parametrize("e", _VANISHING_ENTRIES, ids=[e.name for e in _VANISHING_ENTRIES])
def test_no_parameter_vanishes_in_float32(e):
    """Every real parameter of the entry (one item per filter)."""
    for entry, name in _VANISHING:
        if entry is e:
            try:
                _no_parameter_vanishes(e, name)
            except AssertionError as err:
                raise AssertionError(f"{name}: {err}") from err


def _no_parameter_vanishes(e, name):
    """A real parameter that is valid in float64 but below float32's smallest normal number
    (1e-46) would act as 0 in a float32 filter: both backends refuse it there, and accept it
    in float64 (or refuse it there too, for a range of their own)."""
    kw = dict(e.defaults)
    if "dt" in e.params:
        kw["dt"] = 0.01
    kw[name] = 1e-46
    for backend in ("c", "ref"):
        with pytest.raises(ValueError, match=rf"^{name}|^p_|^p0"):
            e.make(backend, **kw, dtype="float32")
    outcome = []
    for backend in ("c", "ref"):
        try:
            e.make(backend, **kw, dtype="float64")
            outcome.append("ok")
        except ValueError as err:
            outcome.append(str(err))
    assert outcome[0] == outcome[1]
    assert len(_VANISHING) > 30


@each_backend
def test_state_writes_a_still_trial_in_four_orientations_refuses(backend):
    """Writes that a single still, level sample accepts but that leave the filter rejecting
    most samples for good: DCM with |I| dt = 0.31 rad (62 % of a fast motion rejected for a
    minute), Mahony2D with I along the vertical (|I| dt = 0.05: 99 %), FusionAHRS with a
    non-unit quaternion, VarioKF with an overflowing covariance or a negative variance. Each
    is refused; the same filters with a moderate value are accepted and run."""
    mod = imufuse_c if backend == "c" else reference
    cases = [("DCM", dict(dt=0.01, kp=2.0, ki=0.5), "ix", 31.0, 10.0),
             ("Mahony2D", dict(dt=0.01, kp=2.0, ki=0.5), "iz", 5.0, 0.5)]
    for name, params, member, bad, fine in cases:
        f = getattr(mod, name)(**params, dtype="float32")
        s = f.state.copy()
        k = list(f.state_names).index(member)
        s[k] = bad
        with pytest.raises(ValueError, match=r"^state: the filter cannot continue from it"):
            f.state = s
        s[k] = fine
        f.state = s
        d = sim.imu("fast", rate=100.0, duration=2.0, seed=1)
        f.run(d.gyr, d.acc)
        assert f.skipped == 0, (name, f.skipped)
    fa = mod.FusionAHRS(dtype="float32")
    s = fa.state.copy()
    s[0] = 2.0
    with pytest.raises(ValueError, match=r"^state: not a valid attitude \(\|q\|\^2"):
        fa.state = s
    va = mod.VarioKF(dtype="float32")
    s = va.state.copy()
    s[va.state_names.index("pzv")] = 3e38
    with pytest.raises(ValueError, match=r"^state: the filter cannot continue from it"):
        va.state = s
    s = va.state.copy()
    s[va.state_names.index("pzz")] = -5.0
    with pytest.raises(ValueError, match=r"^state: not a valid attitude \(pzz = -5.0"):
        va.state = s


@each_backend
def test_refused_state_writes_warn_nothing(backend):
    """An overflowing state write is refused with its ValueError only: no numpy
    RuntimeWarning before it (under -W error that warning became the exception)."""
    import warnings
    mod = imufuse_c if backend == "c" else reference
    for name in ("DCM", "MultiWii", "MahonyIMU"):
        e = catalogue.entry(name)
        f = e.make(backend, dt=0.01, **e.defaults, dtype="float32")
        s = f.state.copy()
        s[0] = 3e38
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(ValueError, match=r"^state: "):
                f.state = s
    assert mod is not None
