"""Hostile input (docs/robustness.md): every registry configuration, both
backends, both precisions. Bursts of NaN, +-Inf, huge (1e30, 3.4e38, 1e300),
subnormal, -0 and alternating extreme samples, and a 1e6 rad/s gyro, followed
by sane static input. Checked: C equals the reference bit for bit (every state
variable after every sample) and counts the same rejected samples; a burst of
non-finite samples is counted exactly; the state is a valid attitude after
every sample; the filter returns to the static attitude within the stated
number of samples; 1e6 constant samples (C run()) stay valid. Also: the
constructor and input acceptance of both backends agree (hypothesis), and no
compiled object can crash the interpreter when its __init__ never ran."""
import itertools
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st, HealthCheck

import imufuse.reference as reference
import imufuse_c
from imufuse import _fusion, catalogue, sim
from imufuse._checks import KINDS
from bits import assert_same_bits
from imufuse.registry import (DTYPES, FIXED_CASES, fixed_matrix, FLOAT_CASES, FUSION_CASES, PROFILES, each_backend,
                      each_dtype, representatives)

TILT = math.radians(30.0)
UP = np.array([0.0, math.sin(TILT), math.cos(TILT)])     # a static 30 deg roll
BURST = 12
TAIL = 200
HOSTILE = {
    "nan": math.nan, "inf": math.inf, "-inf": -math.inf, "1e30": 1e30, "3.4e38": 3.4e38,
    "1e300": 1e300, "subnormal32": 1e-40, "subnormal64": 5e-324, "-0": -0.0,
}
BACKENDS = ("c", "ref")
CASES = [c for c in FLOAT_CASES if c.name in reference.FILTERS and not c.name.startswith("Fusion")]


def _up(angle):
    return np.array([0.0, math.sin(angle), math.cos(angle)])


def _static(kind, n, angle=TILT, scale=1.0):
    """n samples at rest at the static attitude, a roll of angle (acc in units
    of scale per g)."""
    if kind == "1d":
        return np.zeros(n), np.full(n, angle)
    g, a = np.zeros((n, 3)), np.tile(_up(angle) * scale, (n, 1))
    if kind == "ahrs":
        # (0.4, 0, -0.9) at the 30 deg roll, the same earth field at any other
        c, s = math.cos(TILT - angle), math.sin(TILT - angle)
        return g, a, np.tile([0.4, 0.0 - 0.9 * s, -0.9 * c], (n, 1))
    return g, a


def _burst(kind, value, where, scale=1.0):
    """BURST hostile samples: value in the gyro, the accelerometer, every
    channel, or alternating +-value in every channel."""
    n = BURST
    sane = _static(kind, n, scale=scale)
    out = [np.array(x, dtype=float) for x in sane]
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    sel = {"gyr": [0], "acc": [1], "all": range(len(out)), "alt": range(len(out))}[where]
    for i in sel:
        v = value * (sign if where == "alt" else 1.0)
        out[i] = (np.broadcast_to(v[:, None] if np.ndim(v) else v, out[i].shape).copy()
                  if out[i].ndim == 2 else np.broadcast_to(v, out[i].shape).copy())
    return tuple(out)


def _valid(case, f, S):
    """Every row of S is a valid attitude (the state-write rule), quaternions
    unit within the stated tolerance."""
    R = np.float32 if S.dtype == np.float32 else float
    ref = case.make("ref", S.dtype.name)
    for row in S[:: max(1, len(S) // 400)]:
        problem = ref._valid_state(ref._args, R, row)
        assert problem is None, (case.id, row, problem)
    unit = 3 if case.name == "Mahony2D" and case.params.get("error") == "exact" else \
        4 if case.name.startswith(("Mahony", "Madgwick")) and case.kind != "1d" \
        and case.name != "Mahony2D" else 0
    if unit:        # quaternions, and Eq. 4.3's d (renormalised every update)
        tol = 4e-3 if case.params.get("invsqrt") == "fast" else \
            (1e-5 if S.dtype == np.float32 else 1e-12)
        n = np.linalg.norm(S[:, :unit].astype(float), axis=1)
        assert np.abs(n - 1.0).max() <= tol, (case.id, np.abs(n - 1.0).max())


def recovery_budget(case, dtype):
    """The stated number of samples to return to the static attitude: the
    catalogue entry's budget (imufuse.recovery, docs/robustness.md)."""
    return catalogue.entry(case.name).recovery_budget(case.params, dtype)


def _recover(case, f, dtype, angle=TILT):
    """Run the filter's recovery budget of samples at rest through f (from a block of rest
    samples reused, not an array of the whole budget: some budgets are 10^7 samples) and
    check the states as _valid does, 400 rows spread over the whole run; returns the last
    block's states."""
    n = recovery_budget(case, dtype)
    # blocks of 2^14 samples: the states of a block stay in the cache (2^18 took 1.7 times as
    # long over a budget of 4.6e7 samples); the rows checked are the same
    block = _static(case.kind, angle=angle, scale=case.params.get("acc_1g", 1.0), n=min(n, 1 << 14))
    stride, done, rows = max(1, n // 400), 0, []
    while done < n:
        m = min(n - done, len(block[0]))
        S = f.run(*(b[:m] for b in block))
        rows.append(S[(-done) % stride::stride])
        done += m
    _valid(case, f, np.concatenate(rows + [S[-1:]]))
    return S


def _error(case, S, angle=TILT):
    """Attitude error (rad) of the last state against the static attitude."""
    est = catalogue.estimate(getattr(reference, case.name), S[-1:])
    if est.q is not None:
        q0, q1, q2, q3 = est.q[-1]
        up = np.array([2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1),
                       q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3])
        c = float(np.dot(up, _up(angle)) / np.linalg.norm(up))
        return math.acos(max(-1.0, min(1.0, c)))
    return abs(float(est.angle[-1]) - angle)


WHERE = ("gyr", "acc", "all", "alt")


def _each(fn, *loops):
    """fn(*combination) for every combination of the loops; a failure names it."""
    for combo in itertools.product(*loops):
        try:
            fn(*combo)
        except AssertionError as e:
            raise AssertionError(f"{combo}: {e}") from e


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in CASES])
def test_hostile_burst(case):
    """Every hostile value in both precisions (one test item per filter configuration)."""
    _each(lambda d, v: _hostile_burst(case, d, v), DTYPES, list(HOSTILE))


def _hostile_burst(case, dtype, value):
    """The value in the gyro, then in the accelerometer, then in every channel,
    then alternating +-value (BURST samples each), between sane samples."""
    c, r = case.make("c", dtype), case.make("ref", dtype)
    scale = case.params.get("acc_1g", 1.0)
    where = WHERE if case.kind != "1d" else ("all", "alt")
    parts = [_static(case.kind, scale=scale, n=100)]
    for w in where:
        parts.append(_burst(case.kind, HOSTILE[value], w, scale))
        parts.append(_static(case.kind, scale=scale, n=20))
    inputs = tuple(np.concatenate(x) for x in zip(*parts))
    got, want = c.run(*inputs), r.run(*inputs)
    assert_same_bits(got, want, c.state_names)
    assert c.skipped == r.skipped
    if math.isnan(HOSTILE[value]) or math.isinf(HOSTILE[value]):
        assert c.skipped == BURST * len(where)   # every non-finite sample, nothing else
    assert np.isfinite(got).all()
    _valid(case, c, got)
    S = _recover(case, c, dtype)
    assert _error(case, S) <= math.radians(2.0), (case.id, math.degrees(_error(case, S)))


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in CASES if c.kind != "1d"])
@each_dtype
def test_gyro_1e6_rad_s_then_recovery(case, dtype):
    c, r = case.make("c", dtype), case.make("ref", dtype)
    g, *rest = _static(case.kind, scale=case.params.get("acc_1g", 1.0), n=BURST)
    g = np.tile([1e6, -1e6, 1e6], (BURST, 1))
    tail = _static(case.kind, scale=case.params.get("acc_1g", 1.0), n=TAIL)
    inputs = tuple(np.concatenate(x) for x in zip((g, *rest), tail))
    assert_same_bits(c.run(*inputs), r.run(*inputs), c.state_names)
    assert c.skipped == r.skipped
    S = _recover(case, c, dtype)
    assert _error(case, S) <= math.radians(2.0)


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in CASES])
@each_dtype
def test_a_million_constant_samples_then_recovery(case, dtype):
    """1e6 samples at rest (a long run: whatever an integral term or an
    unrenormalised vector can drift to, it has drifted), every one accepted,
    then the body rolls to -30 deg: the filter follows within the recovery
    budget, still rejecting nothing. Mahony2D with Eq. 4.3 used to fail here:
    |d| grew to its limit after 54 500 samples and from then on every sample
    was rejected, the attitude frozen at the old tilt."""
    c, r = case.make("c", dtype), case.make("ref", dtype)
    scale = case.params.get("acc_1g", 1.0)
    inputs = _static(case.kind, scale=scale, n=1_000_000)
    S = c.run(*inputs)
    assert np.isfinite(S).all()
    _valid(case, c, S)
    assert c.skipped == 0
    head = tuple(x[:1000] for x in inputs)
    assert_same_bits(S[:1000], r.run(*head), c.state_names)
    S = _recover(case, c, dtype, angle=-TILT)
    assert c.skipped == 0
    assert _error(case, S, -TILT) <= math.radians(2.0), \
        (case.id, math.degrees(_error(case, S, -TILT)))


# ---- the Fusion suite (Longbin's Fusion walkthrough): FusionAHRS, FusionOffset ----------------------
# Fusion's units (gyroscope deg/s, accelerometer g, dt with every update) and its
# three update forms, so not in CASES. The same matrix: every FusionAHRS registry
# configuration x update form x float32/float64 x hostile value, in every channel
# (dt and the external heading included) and alternating +-; C equals the twin bit
# for bit, non-finite samples are counted exactly, q stays a unit quaternion, and
# the static attitude comes back within the stated budget.

FDT = 0.01                       # s
F_BURST = 13     # odd: a huge gyro turns q by ~180 deg per sample, an even burst would cancel
HEADING = 25.0                   # deg, for update_external_heading
F_HOSTILE = {**HOSTILE, "gyro1e6": math.degrees(1e6)}   # 1e6 rad/s, in deg/s (gyro only)
FUSION_AHRS = [c for c in FUSION_CASES if c.name == "FusionAHRS"]
FORMS = {"mag": "update", "nomag": "update_no_magnetometer",
         "heading": "update_external_heading"}


def _fusion_static(form, n, angle=TILT):
    """n samples at rest at a roll of angle, as run() columns (deg/s, g, s)."""
    g, a, *m = _static("ahrs" if form == "mag" else "imu", n, angle)
    cols = {"gyr": g, "acc": a, "dt": np.full(n, FDT)}
    if form == "mag":
        cols["mag"] = m[0]
    if form == "heading":
        cols["heading"] = np.full(n, HEADING)
    return cols


def _fusion_burst(form, value, where, n=F_BURST):
    """n samples with value in one channel, in all, or alternating +- in all;
    dt takes |value| (a negative dt is refused by run() with ValueError)."""
    cols = _fusion_static(form, n)
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    names = list(cols) if where in ("all", "alt") else [where]
    for k in names:
        v = value * sign if where == "alt" else np.full(n, value)
        v = np.abs(v) if k == "dt" else v
        cols[k] = np.broadcast_to(v[:, None] if cols[k].ndim == 2 else v, cols[k].shape).copy()
    return cols


def _fusion_run(f, cols):
    return f.run(cols["gyr"], cols["acc"], cols.get("mag"), dt=cols["dt"],
                 heading=cols.get("heading"))


def _cat(parts):
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _fusion_valid(case, S):
    """Every row a state the setter accepts (finite, flags and counters in
    range, q not zero), q of unit length within the stated tolerance."""
    period = case.params.get("recovery_trigger_period", 0)
    for row in S[:: max(1, len(S) // 400)]:
        _fusion.ahrs_state(row, S.dtype.name, period)
    assert np.isfinite(S).all()
    tol = 4e-3 if case.params.get("invsqrt") == "fast" else \
        (1e-5 if S.dtype == np.float32 else 1e-12)
    n = np.linalg.norm(S[:, :4].astype(float), axis=1)
    assert np.abs(n - 1.0).max() <= tol, (case.id, np.abs(n - 1.0).max())


def fusion_recovery_budget(case, dtype):
    """Samples to return to the static attitude: the catalogue entry's budget
    (imufuse.recovery.fusion_ahrs), at the sample interval FDT."""
    return catalogue.ALL_ENTRIES[case.name].recovery_budget(case.params, dtype, dt=FDT)


def _rotation_angle(q, p):
    c = abs(float(np.dot(q.astype(float), p.astype(float))))
    c /= float(np.linalg.norm(q.astype(float)) * np.linalg.norm(p.astype(float)))
    return 2.0 * math.acos(min(1.0, c))


def _tilt_error(q, angle=TILT):
    q0, q1, q2, q3 = (float(x) for x in q)
    up = np.array([2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1),
                   q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3])
    return math.acos(max(-1.0, min(1.0, float(np.dot(up, _up(angle)) / np.linalg.norm(up)))))


def _nonfinite_in(dtype, value):
    with np.errstate(over="ignore"):
        return not np.isfinite(np.array(value, dtype=dtype))


@pytest.mark.parametrize("case,form", [pytest.param(c, form, id=f"{c.id}-{form}")
                                       for c in FUSION_AHRS for form in FORMS])
def test_fusion_ahrs_hostile_burst(case, form):
    _each(lambda d, v: _fusion_ahrs_hostile_burst(case, form, d, v), DTYPES, list(F_HOSTILE))


def _fusion_ahrs_hostile_burst(case, form, dtype, value):
    """The value in each channel in turn (gyr, acc, mag or heading, dt), then
    in all of them, then alternating +-value (F_BURST samples each), between
    sane samples; then sane input for the recovery budget."""
    c, r = (m.FusionAHRS(**case.params, dtype=dtype) for m in (imufuse_c, reference))
    x = F_HOSTILE[value]
    channels = [k for k in _fusion_static(form, 1)] if value != "gyro1e6" else ["gyr"]
    where = channels + (["all", "alt"] if value != "gyro1e6" else [])
    parts = [_fusion_static(form, 100)]
    for w in where:
        parts += [_fusion_burst(form, x, w), _fusion_static(form, 20)]
    cols = _cat(parts)
    got = _fusion_run(c, cols)
    assert_same_bits(got, _fusion_run(r, cols), c.state_names)
    assert c.skipped == r.skipped
    if _nonfinite_in(dtype, x):
        assert c.skipped == F_BURST * len(where)   # every non-finite sample, nothing else
    _fusion_valid(case, got)
    tail = _fusion_static(form, fusion_recovery_budget(case, dtype))
    S = _fusion_run(c, tail)
    _fusion_valid(case, S)
    q = S[-1, :4]
    assert _tilt_error(q) <= math.radians(2.0), (case.id, math.degrees(_tilt_error(q)))
    if form != "nomag":     # with a heading reference the whole attitude comes back
        clean = imufuse_c.FusionAHRS(**case.params, dtype=dtype)
        _fusion_run(clean, _fusion_static(form, len(cols["dt"])))
        want = _fusion_run(clean, tail)[-1, :4]
        assert _rotation_angle(q, want) <= math.radians(2.0), \
            (case.id, math.degrees(_rotation_angle(q, want)))


FUSION_BIAS = np.array([0.4, -0.3, 1.2])     # deg/s, a gyroscope at rest


def test_fusion_offset_hostile_burst():
    _each(_fusion_offset_hostile_burst, DTYPES, list(HOSTILE))


def _fusion_offset_hostile_burst(dtype, value):
    """FusionOffset: a burst in the gyroscope (and alternating +-) at rest; C
    equals the twin (corrected output and state, every sample), non-finite
    samples are counted exactly, the offset stays finite and within the range
    of the inputs it may follow (it moves only towards a reading within 3 deg/s
    of it), and it converges on the bias within the stated budget: the 5 s rest
    timeout and ln(4.2 / 0.01) time constants of its 0.02 Hz low-pass."""
    case = next(k for k in FUSION_CASES if k.name == "FusionOffset")
    c, r = (m.FusionOffset(**case.params, dtype=dtype) for m in (imufuse_c, reference))
    x = HOSTILE[value]
    sane = lambda n: np.tile(FUSION_BIAS, (n, 1))              # noqa: E731
    sign = np.where(np.arange(BURST) % 2 == 0, 1.0, -1.0)[:, None]
    gyr = np.concatenate([sane(100), np.full((BURST, 3), x), sane(20), x * sign * np.ones(3),
                          sane(20)])
    (oc, sc), (orf, sr) = c.run(gyr), r.run(gyr)
    assert_same_bits(sc, sr, c.state_names)
    assert_same_bits(oc, orf, None)
    assert c.skipped == r.skipped
    if _nonfinite_in(dtype, x):
        assert c.skipped == 2 * BURST
    assert np.isfinite(sc).all()
    assert np.abs(sc[:, :3]).max() <= np.abs(FUSION_BIAS).max() + 3.0
    budget = catalogue.ALL_ENTRIES["FusionOffset"].recovery_budget(case.params, dtype)
    _, S = c.run(sane(budget))
    assert np.abs(S[-1, :3] - FUSION_BIAS).max() <= 0.01, S[-1]
    assert c.skipped == r.skipped


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
