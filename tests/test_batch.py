"""Many parameter sets in one compiled call (imufuse_c run_many / run_filters): every set's
trajectory, final state and `skipped` are bit for bit its own run()'s, for every 3-D float
filter configuration of the registry, both precisions, every lane width this CPU runs, per
sample dt and init="first"; the scores computed while the filters run equal
imufuse.evaluation.evaluate on each run()'s estimate within 1e-12; the filters without a
compiled batch path (single-axis, fixed point, Fusion, the variometer) return each run()'s
result; and `tune` on the batch path reports what scoring each set in Python reports.
RobustIMU/RobustAHRS's lane kernel has tests of its own: groups of settings that pick
different code paths per lane, over a log that reaches every block's branches, hostile inputs,
a stored offset and bias, every width and precision, bit for bit with each filter's run()."""
import copy
import math
import re
from pathlib import Path

import numpy as np
import pytest

import imufuse_c
from imufuse import catalogue, sim
from imufuse.evaluation import evaluate, prepare_reference
from imufuse.session import chunked_estimate
from imufuse.tune import Tuner
from imufuse.registry import DTYPES, FLOAT_CASES, FIXED_CASES

WIDTHS = [0, *imufuse_c.lane_widths()]
CLASSES_3D = sorted({c.name for c in FLOAT_CASES if c.kind in ("imu", "ahrs")})
METRICS = ("total", "heading", "inclination")


def _bits(a):
    a = np.ascontiguousarray(a)
    return a.view(np.uint64 if a.dtype == np.float64 else np.uint32)


@pytest.fixture(scope="module")
def log():
    """Fast motion with hostile samples: NaN rows, an all-zero magnetometer and
    accelerometer, overflowing values, a magnitude outside every gate."""
    d = sim.imu("fast", rate=200.0, duration=6.0, seed=7)
    gyr, acc, mag = d.gyr.copy(), d.acc.copy(), d.mag.copy()
    gyr[100] = np.nan
    acc[150] = 0.0
    mag[160:170] = 0.0
    acc[200] = 1e200
    mag[210] = 1e200
    acc[300:320] *= 2.5
    gyr[400, 1] = np.inf
    dts = np.full(len(gyr), d.dt)
    dts[::7] *= 1.5
    return d, (gyr, acc, mag), dts


def _inputs(kind, ins):
    return ins if kind == "ahrs" else ins[:2]


def _sets(name):
    """The registry's configurations of ``name`` and each with its first gain doubled: the
    options (invsqrt, delta_s, gates) mixed within one call."""
    out = []
    for c in FLOAT_CASES:
        if c.name != name:
            continue
        out.append(dict(c.params))
        eff = catalogue.resolve_params(name, c.params.get("dt", 0.01),
                                       {k: v for k, v in c.params.items() if k != "dt"})
        gain = next((k for k, v in eff.items() if k != "dt" and isinstance(v, float) and v > 0),
                    None)
        if gain is not None:
            out.append({**c.params, gain: eff[gain] * 2.0})
    return out


def _valid(name, sets, dtype):
    good = []
    for p in sets:
        try:
            getattr(imufuse_c, name)(**p, dtype=dtype)
        except ValueError:
            continue
        good.append(p)
    return good


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name", CLASSES_3D)
@pytest.mark.parametrize("start", ["identity", "first", "dt"])
def test_run_many_is_each_run(name, start, dtype, log):
    data, ins, dts = log
    cls = getattr(imufuse_c, name)
    inputs = _inputs(cls.kind, ins)
    sets = _valid(name, _sets(name), dtype)
    assert sets
    kw = {} if start != "first" else {"init": "first", "init_window": 3}
    params = [{**p, **kw} for p in sets]
    dt = dts if start == "dt" else None
    own = []
    for p in params:
        f = cls(**p, dtype=dtype)
        own.append((f.run(*inputs, dt=dt), f.state, f.skipped))
    assert any(s for _, _, s in own), "the hostile samples must reach the rejection paths"
    widths = WIDTHS if imufuse_c.has_lanes(name, dtype) else [0, None]
    for lanes in widths:
        filters = [cls(**p, dtype=dtype) for p in params]
        out = imufuse_c.run_filters(filters, *inputs, dt=dt, lanes=lanes, threads=2)
        assert out.shape == (len(params), len(inputs[0]), len(cls.state_names))
        for i, (traj, state, skipped) in enumerate(own):
            np.testing.assert_array_equal(_bits(out[i]), _bits(traj),
                                          err_msg=f"{name} set {i} lanes={lanes}")
            np.testing.assert_array_equal(_bits(filters[i].state), _bits(state))
            assert filters[i].skipped == skipped
            # the filter continues as its own would (its dt restored after a per-sample dt)
            g = [np.asarray(x[:50]) for x in inputs]
            own_next = cls(**params[i], dtype=dtype)
            own_next.run(*inputs, dt=dt)
            np.testing.assert_array_equal(_bits(filters[i].run(*g)), _bits(own_next.run(*g)))


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name", [n for n in CLASSES_3D
                                  if imufuse_c.has_lanes(n) and n.startswith("Madgwick")])
def test_lanes_long_rest_then_motion(name, dtype):
    """300 000 samples at rest (tilted, upside down), then motion, then rest: every lane
    width bit for bit with the filter's own update; gates that differ between lanes."""
    parts = []
    for q0 in ([0.9, 0.3, 0.3, 0.1], [0.0, 1.0, 0.0, 0.0]):
        parts.append(sim.imu("static", rate=500.0, duration=200.0, seed=3, q0=q0))
    move = sim.imu("fast", rate=500.0, duration=10.0, seed=4)
    gyr = np.concatenate([p.gyr for p in parts] + [move.gyr, parts[0].gyr])
    acc = np.concatenate([p.acc for p in parts] + [move.acc, parts[0].acc])
    mag = np.concatenate([p.mag for p in parts] + [move.mag, parts[0].mag])
    cls = getattr(imufuse_c, name)
    inputs = _inputs(cls.kind, (gyr, acc, mag))
    params = [dict(dt=0.002, beta=b, init="first") for b in (0.005, 0.03, 0.1, 0.3, 1.0)]
    params += [dict(dt=0.002, beta=0.1, acc_gate=(lo, hi), init="first")
               for lo, hi in ((0.9, 1.1), (0.99, 1.01), (0.5, 1.5))]
    own = [cls(**p, dtype=dtype).run(*inputs) for p in params]
    assert len(gyr) >= 300_000
    for lanes in WIDTHS[1:]:
        out = cls.run_many(params, *inputs, lanes=lanes, dtype=dtype)
        for i, traj in enumerate(own):
            np.testing.assert_array_equal(_bits(out[i]), _bits(traj), err_msg=f"lanes={lanes}")
    norms = np.linalg.norm(own[0][:, :4].astype(np.float64), axis=1)
    assert np.all(np.abs(norms - 1) < 1e-5)


def _robust_log():
    """RobustAHRS's branches in one log (100 Hz): rest (tilted), fast and slow motion, rest
    again; a hard-iron offset to learn (B6 trusts it); a disturbance of the field's norm, a
    changed dip for 5 s, 1.5 s of absurd readings (B6 restarts), a disturbance at rest, weak
    readings at rest; no magnetometer or accelerometer reading, readings beyond and within
    100 g, non-finite samples."""
    rate = 100.0
    parts = [sim.imu("static", rate=rate, duration=12.0, seed=11, q0=[0.9, 0.3, 0.3, 0.1]),
             sim.imu("fast", rate=rate, duration=30.0, seed=12),
             sim.imu("slow", rate=rate, duration=20.0, seed=13),
             sim.imu("static", rate=rate, duration=6.0, seed=14)]
    gyr = np.concatenate([p.gyr for p in parts])
    acc = np.concatenate([p.acc for p in parts])
    mag = np.concatenate([p.mag for p in parts]) + np.array([0.3, -0.2, 0.1])
    n0 = 4200
    mag[n0 + 300:n0 + 600] *= 1.4
    mag[n0 + 900:n0 + 1400, 2] += 0.5
    mag[n0 + 1600:n0 + 1750] *= 100.0
    mag[500:510] = 0.0
    acc[2000] = 0.0
    gyr[700] = np.nan
    acc[2500, 1] = np.inf
    mag[3100, 2] = np.nan
    acc[3300:3320] *= 200.0
    acc[3400:3410] *= 50.0                 # a shock within 100 g: a reading
    mag[300:310] *= 0.15                   # at rest, a reading at 0.15 of the field
    mag[6300:6800] *= 1.3                  # at rest, a disturbed field
    dts = np.full(len(gyr), 1 / rate)
    dts[::5] *= 1.3
    return (gyr, acc, mag), dts


# RobustIMU / RobustAHRS groups whose settings select different code paths in each lane
_ROBUST_SETS = [{}, dict(tau_acc=1.0), dict(tau_acc=6.0, rate_ref=0.0),
                dict(tau_bias=0.0, tau_bias_rest=1.0), dict(gyr_bias_max=0.0),
                dict(latency=0.02), dict(rest_gyr=0.0), dict(rest_time=0.3, rest_acc=0.2),
                dict(tau_rest=2.0, gyr_bias_max=20.0), dict(tau_bias=10.0)]
_ROBUST_MAG_SETS = [dict(mag_learn=False), dict(tau_mag=2.0, mag_new_time=2.0, mag_hold=0.2),
                    dict(mag_dip=2.0, mag_norm=0.3, tau_mag_ref=3.0),
                    dict(mag_noise=0.2, mag_lag=0.0, mag_offset_min=0.0),
                    dict(mag_learn=False, gyr_bias_max=0.0, latency=0.01)]


def _robust_lanes_equal_own(name, dtype, params, inputs, dt=None):
    """Every lane width: each set's trajectory (every state word after every sample), final
    state and `skipped` bit for bit its own run()'s; returns the own runs."""
    cls = getattr(imufuse_c, name)
    assert imufuse_c.has_lanes(name, dtype)
    own = []
    for p in params:
        f = cls(**p, dtype=dtype)
        own.append((f.run(*inputs, dt=dt), f.state, f.skipped))
    for lanes in WIDTHS[1:]:
        filters = [cls(**p, dtype=dtype) for p in params]
        out = imufuse_c.run_filters(filters, *inputs, dt=dt, lanes=lanes, threads=1)
        for i, (traj, state, skipped) in enumerate(own):
            np.testing.assert_array_equal(_bits(out[i]), _bits(traj),
                                          err_msg=f"{name} {dtype} set {i} lanes={lanes}")
            np.testing.assert_array_equal(_bits(filters[i].state), _bits(state))
            assert filters[i].skipped == skipped, (i, lanes)
    return own


@pytest.mark.parametrize("start", ["identity", "first", "dt"])
@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name", ["RobustIMU", "RobustAHRS"])
def test_robust_lanes_every_branch(name, dtype, start):
    """RobustIMU / RobustAHRS in lanes: a group of mixed settings (B1 off, B3 off, a
    calibrated gyro, latency, constant process noise; B6 on and off, B4's detector tuned to
    replace the reference) over a log that reaches every block's branches, bit for bit with
    each filter's own update at every lane width."""
    ins, dts = _robust_log()
    sets = _ROBUST_SETS + (_ROBUST_MAG_SETS if name == "RobustAHRS" else [])
    kw = {"init": "first", "init_window": 3} if start == "first" else {}
    params = [dict(dt=0.01, **p, **kw) for p in sets]
    own = _robust_lanes_equal_own(name, dtype, params, _inputs(getattr(imufuse_c, name).kind, ins),
                                  dts if start == "dt" else None)
    names = getattr(imufuse_c, name).state_names
    traj = own[0][0]
    col = {n: traj[:, names.index(n)] for n in ("t_rest", "m_std", "t_dist", "m_bad")}
    assert own[0][2] > 0                                 # rejected samples
    assert np.any(col["t_rest"] >= 1.5)                  # rest (B1's bias at rest)
    bu = own[len(_ROBUST_SETS) - 1][0][:, names.index("bu")]
    assert bu[0] > 0 and np.any(bu == 0)                 # the bias learnt in motion
    if name == "RobustAHRS":
        assert np.any(col["m_std"] < 0.01)               # B6's offset trusted
        assert np.any(col["t_dist"] > 0)                 # B4 disturbed
        assert np.any(col["m_bad"] > 0)                  # absurd readings


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name", ["RobustIMU", "RobustAHRS"])
def test_robust_lanes_stored_offset_and_bias(name, dtype):
    """Filters given a stored magnetometer offset (near the true one: B6 keeps it; far: the
    estimate replaces it) and a known gyro bias before the call: each lane starts from its
    filter's state and ends bit for bit where the filter's own run() ends."""
    ins, _ = _robust_log()
    cls = getattr(imufuse_c, name)
    inputs = _inputs(cls.kind, ins)
    sets = _ROBUST_SETS + (_ROBUST_MAG_SETS if name == "RobustAHRS" else [])
    made = []
    for i, p in enumerate(sets):
        f = cls(dt=0.01, **p, dtype=dtype)
        if i % 2 == 0 and p.get("gyr_bias_max", 6.0) > 0.1:
            f.set_gyr_bias((0.01, -0.005, 0.002))
        if name == "RobustAHRS":
            f.set_mag_offset((0.31, -0.19, 0.1) if i % 3 else (1.0, 0.0, -0.5))
        made.append(f)
    own = [copy.copy(f) for f in made]
    trajs = [f.run(*inputs) for f in own]
    for lanes in WIDTHS[1:]:
        filters = [copy.copy(f) for f in made]
        out = imufuse_c.run_filters(filters, *inputs, lanes=lanes, threads=1)
        for i, f in enumerate(own):
            np.testing.assert_array_equal(_bits(out[i]), _bits(trajs[i]),
                                          err_msg=f"{name} {dtype} set {i} lanes={lanes}")
            np.testing.assert_array_equal(_bits(filters[i].state), _bits(f.state))
            assert filters[i].skipped == f.skipped
    if name == "RobustAHRS":
        names = cls.state_names
        u = trajs[1][-1, names.index("ux"):names.index("ux") + 3]
        s = trajs[1][-1, names.index("sx"):names.index("sx") + 3]
        np.testing.assert_array_equal(u, s)          # the stored offset kept
        u0 = trajs[0][-1, names.index("ux"):names.index("ux") + 3]
        assert abs(float(u0[0]) - 0.3) < 0.05        # the far one replaced by the estimate


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name", ["RobustIMU", "RobustAHRS"])
def test_robust_lanes_hostile(name, dtype):
    """Absurd but finite inputs (rates and readings near the type's largest value, tiny and
    subnormal readings, an upside-down start, gravity straight down), per-sample dt: every
    lane width bit for bit with each filter's own update, rejected samples included."""
    big = float(np.finfo(dtype).max) / 4
    tiny = float(np.finfo(dtype).tiny) / 8
    d = sim.imu("fast", rate=100.0, duration=8.0, seed=21, q0=[0.0, 1.0, 0.0, 0.0])
    gyr, acc, mag = d.gyr.copy(), d.acc.copy(), d.mag.copy()
    gyr[0] = 0.0
    acc[0] = (0.0, 0.0, -1.0)                # gravity straight down: the levelling's half turn
    mag[0] = (-0.5, 0.0, 0.8)                # then the field due south: B4's half turn
    gyr[50:60] *= big
    acc[70:75] = big
    acc[80:85] = tiny
    mag[90:100] = big
    mag[100:110] = tiny
    mag[110:120] = (0.0, 0.0, 1.0)
    acc[130:140] = (0.0, 0.0, -big)
    gyr[150:160] = (big, -big, big)
    mag[200:299] *= 1e6                       # absurd readings: B6 restarts after 1 s ...
    mag[299:310] = tiny                       # ... and cannot start from a reading of no norm
    mag[310:330] *= 1e6
    acc[400:410] = -acc[400:410] * 1e3
    gyr[500:700] *= 50.0
    gyr[700:790] = (400.0, -300.0, 200.0)     # B2's process noise at its cap
    dts = np.full(len(gyr), 0.01)
    dts[300:320] = 1e-6
    dts[320:330] = 0.5
    sets = _ROBUST_SETS + (_ROBUST_MAG_SETS if name == "RobustAHRS" else [])
    params = [dict(dt=0.01, **p) for p in sets]
    inputs = _inputs(getattr(imufuse_c, name).kind, (gyr, acc, mag))
    for dt in (None, dts):
        own = _robust_lanes_equal_own(name, dtype, params, inputs, dt)
        assert all(s > 0 for _, _, s in own)


def test_robust_lanes_constants_are_robust_mag_h():
    """The lane kernel's copy of B6's model constants and covariance index (lanes_robust.h
    cannot include csrc/robust_mag.h, a private part of robust.c) is csrc's, value for value;
    so is its copy of B3's noise floor (csrc/robust_b3.h)."""
    root = Path(__file__).resolve().parents[1]

    def read(path):
        text = (root / path).read_text()
        defs = dict(re.findall(r"#define (ROBUST_MAG_\w+) (IMF_R\([^)]*\))", text))
        table = re.search(r"robust_pi\[6\]\[6\] = \{(.*?)\};", text, re.S).group(1)
        return defs, re.sub(r"\s+", "", table)
    c_defs, c_table = read("csrc/robust_mag.h")
    lane_defs, lane_table = read("imufuse_c/host/lanes_robust.h")
    assert len(c_defs) == 14 and lane_defs == c_defs
    assert lane_table == c_table
    # and B3's noise floor, csrc/robust_b3.h's
    an = [re.findall(r"#define ROBUST_AN_MIN (IMF_R\([^)]*\))", (root / p).read_text())
          for p in ("csrc/robust_b3.h", "imufuse_c/host/lanes_robust.h")]
    assert len(an[0]) == 1 and an[0] == an[1]


@pytest.mark.parametrize("dtype", DTYPES)
def test_constructor_cache_keeps_starts_apart(dtype):
    """The compiled constructor reuses the checks of arguments seen before, a start given by
    values included (tune builds a filter per log and search point with init="first"): two
    starts that differ only in the window, the type of its length or the quaternion are
    never taken for one another."""
    d = sim.imu("slow", rate=100.0, duration=1.0, seed=5)
    cls = imufuse_c.MadgwickAHRS
    s = np.sqrt(0.5)
    starts = [dict(init="first", init_window=3), dict(init="first", init_window=7),
              dict(init="first", init_window=np.int64(3)), dict(q0=(1.0, 0.0, 0.0, 0.0)),
              dict(q0=(s, s, 0.0, 0.0)), dict(q0=(s, 0.0, s, 0.0)), {}]
    runs = []
    for _ in range(2):          # the second round built from the cache
        runs.append([cls(dt=0.01, dtype=dtype, **st).run(d.gyr, d.acc, d.mag)
                     for st in starts])
    for a, b in zip(*runs):
        np.testing.assert_array_equal(_bits(a), _bits(b))
    first = runs[0]
    assert not np.array_equal(first[0], first[1])      # windows 3 and 7
    np.testing.assert_array_equal(_bits(first[0]), _bits(first[2]))
    assert not np.array_equal(first[4], first[5])      # two quaternions
    assert not np.array_equal(first[3], first[4])
    with pytest.raises(ValueError):
        cls(dt=0.01, dtype=dtype, q0=(0.0, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError):
        cls(dt=0.01, dtype=dtype, q0=(0.0, 0.0, 0.0, 0.0))


def _reference_log():
    d = sim.imu("fast", rate=200.0, duration=20.0, seed=11)
    q_ref = d.q_true.copy()
    q_ref[500:520] = np.nan                      # tracking dropped out
    q_ref[900] = 0.0
    movement = np.ones(len(q_ref), dtype=bool)
    movement[:400] = False
    return d, q_ref, movement


@pytest.mark.parametrize("offset", [False, True], ids=["plain", "heading-offset"])
@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("name", CLASSES_3D)
def test_scores_equal_evaluate(name, dtype, offset):
    d, q_ref, movement = _reference_log()
    cls = getattr(imufuse_c, name)
    inputs = _inputs(cls.kind, (d.gyr, d.acc, d.mag))
    params = [{**p, "init": "first"} for p in _valid(name, _sets(name), dtype)]
    ref = prepare_reference(q_ref, ref_frame="NWU", movement=movement,
                            remove_heading_offset=offset)
    evs = cls.run_many(params, *inputs, score=ref, dtype=dtype)
    entry_cls = catalogue.reference_class(name)
    for p, ev in zip(params, evs):
        est = chunked_estimate(entry_cls, cls(**p, dtype=dtype).run(*inputs))
        want = evaluate(est.q, q_ref, est_frame="NWU", ref_frame="NWU", movement=movement,
                        remove_heading_offset=offset, per_sample=False)
        assert (ev.n, ev.n_samples, ev.n_ref_nan, ev.n_outside_mask, ev.n_est_nan) == \
            (want.n, want.n_samples, want.n_ref_nan, want.n_outside_mask, want.n_est_nan)
        assert ev.has_heading == est.heading
        for m in METRICS:
            assert getattr(ev, m) == pytest.approx(getattr(want, m), rel=1e-12, abs=1e-12), m
        assert ev.heading_offset == pytest.approx(want.heading_offset, rel=1e-12, abs=1e-12)


def test_scores_at_the_edges():
    """An estimate equal to the reference (0 deg), opposite headings (180 deg), upside down,
    and a reference with nothing to count: the arctangent kernel at its ends."""
    n = 64
    cls = imufuse_c.MadgwickAHRS
    d = sim.imu("static", rate=100.0, duration=n / 100.0, seed=1)
    filters = [cls(dt=0.01, beta=0.0) for _ in range(3)]
    gyr = np.zeros((n, 3))
    ins = (gyr, d.acc, d.mag)
    s = np.sqrt(0.5)
    for q_ref in (np.tile([1.0, 0, 0, 0], (n, 1)), np.tile([0.0, 0, 0, 1.0], (n, 1)),
                  np.tile([0.0, 1.0, 0, 0], (n, 1)), np.tile([s, 0, s, 0], (n, 1))):
        ref = prepare_reference(q_ref, ref_frame="NWU")
        evs = imufuse_c.run_filters([cls(dt=0.01, beta=0.0) for _ in range(3)], *ins,
                                    score=ref, lanes=max(WIDTHS))
        q = np.tile([1.0, 0, 0, 0], (n, 1))
        want = evaluate(q, q_ref, est_frame="NWU", ref_frame="NWU")
        for ev in evs:
            for m in METRICS:
                assert getattr(ev, m) == pytest.approx(getattr(want, m), rel=1e-12, abs=1e-12)
    empty = prepare_reference(np.full((n, 4), np.nan), ref_frame="NWU")
    ev = imufuse_c.run_filters(filters, *ins, score=empty)[0]
    assert ev.n == 0 and math.isnan(ev.total) and ev.n_ref_nan == n


def test_arguments_are_checked():
    d = sim.imu("slow", rate=100.0, duration=1.0)
    f = imufuse_c.MadgwickIMU(dt=0.01)
    with pytest.raises(ValueError, match="lanes"):
        imufuse_c.run_filters([f], d.gyr, d.acc, lanes=3)
    with pytest.raises(TypeError, match="one class"):
        imufuse_c.run_filters([f, imufuse_c.MahonyIMU(dt=0.01)], d.gyr, d.acc)
    with pytest.raises(ValueError, match="parameter set 1"):
        imufuse_c.MadgwickIMU.run_many([dict(dt=0.01), dict(dt=-1.0)], d.gyr, d.acc)
    with pytest.raises(ValueError, match="reference of 5 samples"):
        imufuse_c.run_filters([f], d.gyr, d.acc,
                              score=prepare_reference(np.tile([1.0, 0, 0, 0], (5, 1))))


@pytest.mark.parametrize("case", [c for c in FLOAT_CASES if c.kind == "1d"][:3]
                         + FIXED_CASES[:3], ids=lambda c: c.id)
def test_run_many_without_compiled_batch(case):
    """Single-axis and fixed-point filters: run_many returns each run()'s result."""
    from imufuse.testing import simulated_inputs
    _, ins = simulated_inputs(case.name, duration=3.0)
    cls = getattr(imufuse_c, case.name)
    params = [dict(case.params), dict(case.params)]
    out = cls.run_many(params, *ins)
    for p, o in zip(params, out):
        np.testing.assert_array_equal(o, cls(**p).run(*ins))


def test_tune_batch_equals_python_scoring(tmp_path):
    """Tuner on the compiled batch path and scoring each set in Python: the same scores
    (1e-12), the same best set, the same refused sets, the progress bar reaching the end."""
    from imufuse.io import Log  # noqa: F401 (the session reads the written logs)
    from imufuse.session import ScoreOptions, Session
    paths = []
    for seed in (1, 2):
        d = sim.imu("fast", rate=200.0, duration=15.0, seed=seed)
        p = tmp_path / f"log{seed}.npz"
        np.savez(p, gyr=d.gyr, acc=d.acc * 9.81, mag=d.mag, quat_ref=d.q_true, rate=200.0)
        paths.append(str(p))
    for name, grid, score in (("MadgwickAHRS", [("beta", [0.0, 0.02, 0.1, 0.5, -1.0])],
                               ScoreOptions(ref_frame="NWU")),
                              ("MahonyIMU", [("kp", [0.2, 1.0, 3.0])],
                               ScoreOptions(ref_frame="NWU", heading_offset=True))):
        t = Tuner([Session(p) for p in paths], name, score=score)
        assert t.batch
        seen = []
        batch = t.search(grid, refine=1, progress=lambda a, b: seen.append((a, b)))
        assert seen and seen[-1][0] == seen[-1][1]
        t.batch = False
        each = t.search(grid, refine=1)
        assert set(batch.results) == set(each.results)
        assert batch.best == each.best
        for p, (s, _) in each.results.items():
            if math.isnan(s):
                assert math.isnan(batch.score(p)) and "beta" in batch.results[p][1]
                continue
            assert batch.score(p) == pytest.approx(s, rel=1e-12)


def test_run_many_fusion_and_vario():
    """FusionAHRS (dt with every update) and the variometer: run_many passes run()'s
    keywords on and returns each run()'s result."""
    d = sim.imu("slow", rate=100.0, duration=3.0, seed=5)
    gyr = np.degrees(d.gyr)
    dts = np.full(len(gyr), d.dt)
    params = [dict(gain=0.5), dict(gain=2.0)]
    out = imufuse_c.FusionAHRS.run_many(params, gyr, d.acc, d.mag, dt=dts)
    for p, o in zip(params, out):
        np.testing.assert_array_equal(o, imufuse_c.FusionAHRS(**p).run(gyr, d.acc, d.mag, dt=dts))
    case = catalogue.VARIO[0].name
    cls = getattr(imufuse_c, case)
    accel, baro = np.linspace(-0.1, 0.1, 300), np.linspace(100.0, 103.0, 300)
    vparams = [dict(), dict()]
    out = cls.run_many(vparams, accel, baro, np.full(300, 0.01))
    np.testing.assert_array_equal(out[0], cls().run(accel, baro, np.full(300, 0.01)))
