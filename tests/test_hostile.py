"""Hostile input (docs/robustness.md): every registry configuration, both
backends, both precisions. Bursts of NaN, +-Inf, huge (1e30, 3.4e38, 1e300),
subnormal, -0 and alternating extreme samples, and a 1e6 rad/s gyro, followed
by sane static input. Checked: C equals the reference bit for bit (every state
variable after every sample) and counts the same rejected samples; a burst of
non-finite samples is counted exactly; the state is a valid attitude after
every sample; the filter returns to the static attitude within the stated
number of samples; 1e6 constant samples (C run()) stay valid. The Fusion suite
in its own units and update forms alike. What the backends accept and how the API
resists misuse: tests/test_hostile_api.py."""
import itertools
import math

import numpy as np
import pytest

import imufuse.reference as reference
import imufuse_c
from imufuse import catalogue
from imufuse.reference import _fusion
from bits import assert_same_bits
from imufuse.registry import DTYPES, FLOAT_CASES, FUSION_CASES, each_dtype


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
    catalogue entry's budget (imufuse.shared.recovery, docs/robustness.md)."""
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
        if m > 1 and S[-1].tobytes() == S[-2].tobytes():
            # a fixed point: the same reading leaves the state as it is (the state is the
            # whole filter), so every later sample of the budget has this state
            break
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
    n, block = 1_000_000, 1 << 14
    inputs = _static(case.kind, scale=scale, n=n)
    # in blocks (the states of a block stay in the cache; a run of 10^6 states of 80 words
    # is 640 MB): every state finite, 400 rows spread over the run valid
    rows, stride = [], max(1, n // 400)
    for k in range(0, n, block):
        S = c.run(*(x[k:k + block] for x in inputs))
        assert np.isfinite(S).all(), k
        if k == 0:
            head = tuple(x[:1000] for x in inputs)
            assert_same_bits(S[:1000], r.run(*head), c.state_names)
        rows.append(S[(-k) % stride::stride])
    _valid(case, c, np.concatenate(rows + [S[-1:]]))
    assert c.skipped == 0
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
    (imufuse.shared.recovery.fusion_ahrs), at the sample interval FDT."""
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
