"""Fusion 1.3 (imufuse_c.FusionAHRS13 / imufuse.reference.FusionAHRS13, FusionBias) against
its oracles, bit for bit (see fusion13_oracle.py): Fusion 1.3's C as published compiled with
cffi (every state member and output after every sample) and the PyPI package imufusion 1.3.3
itself; float64 C against its twin; and planted differences in each path 1.3 added (bias,
skip start-up, remap, sample period) that the comparisons must catch.

Longer than 500 lines because: its tests run against the oracles that its module-scoped
fixtures fetch and compile (tests/conftest.py keeps such a module on one worker); split in
two, the oracles would be built twice.
"""
import numpy as np
import pytest

import imufuse_c
from imufuse.reference import _fusion, _fusion13
from imufuse import reference as ref
from imufuse.reference import fusion13 as twin13

import fusion13_oracle as oracle
from bits import assert_same_bits
from fusion_sim import simulated_log

# the oracles are fetched and built (as tests/test_fusion_oracle.py's, in conftest's SLOW)
pytestmark = pytest.mark.slow

CONVENTIONS = ("NWU", "ENU", "NED")
#: the settings the scenario runs with: rejection and recovery reachable within the log
SETTINGS = dict(sample_rate=100.0, gain=0.5, gyroscope_range=2000.0,
                acceleration_rejection=10.0, magnetic_rejection=10.0, rejection_timeout=1.0)
CHANGED = dict(sample_rate=125.0, gain=0.8, gyroscope_range=2000.0,
               acceleration_rejection=20.0, magnetic_rejection=15.0, rejection_timeout=0.5)
FLAG_BITS = {"startup": 1, "overrange recovery": 2, "acceleration recovery": 4,
             "magnetic recovery": 8, "accelerometer ignored": 16, "magnetometer ignored": 32}


@pytest.fixture(scope="module")
def sdist():
    return oracle.fetch_sdist()


@pytest.fixture(scope="module")
def fusion_exact(sdist):
    return oracle.fusion_c(sdist, normal_sqrt=True)


@pytest.fixture(scope="module")
def fusion_fast(sdist):
    return oracle.fusion_c(sdist, normal_sqrt=False)


@pytest.fixture(scope="module")
def imufusion(sdist):
    return oracle.imufusion_module(sdist)


# ---- the scenario: one log, update forms, events and sample periods in segments -------

class Scenario:
    """op bits before a sample: 1 restart, 2 skip start-up, 4 new settings (CHANGED)."""

    def __init__(self, convention, n=3000, seed=1):
        self.log = log = simulated_log(seed=seed, n=n,
                                       frame="FRD" if convention == "NED" else "NWU")
        self.convention = convention
        self.mode = np.zeros(n, dtype=np.int32)     # 0 update, 1 external heading, 2 no mag.
        self.mode[int(0.55 * n):int(0.62 * n)] = 1
        self.mode[int(0.62 * n):int(0.75 * n)] = 2
        self.op = np.zeros(n, dtype=np.int32)
        self.op[int(0.40 * n)] = 4
        self.op[int(0.70 * n)] = 1
        self.op[int(0.90 * n)] = 1 | 2
        self.heading = np.full(n, np.nan, dtype=np.float32)
        self.heading[int(0.33 * n)] = 37.5
        self.heading[int(0.85 * n)] = -120.0
        # the measured period before every update, except from the settings change on to
        # 0.5 n, where the settings' period integrates
        self.period = log.dt.copy()
        self.period[int(0.40 * n):int(0.50 * n)] = np.nan
        self.ext = (log.yaw + np.float32(3.0)).astype(np.float32)

    def settings(self, s):
        return np.array([s["sample_rate"], _fusion.CONVENTIONS[self.convention], s["gain"],
                         s["gyroscope_range"], s["acceleration_rejection"],
                         s["magnetic_rejection"], s["rejection_timeout"]], dtype=np.float32)

    def run_oracle(self, ffi, lib, settings=SETTINGS):
        n, log = len(self.mode), self.log
        state = np.empty((n, 23), dtype=np.float32)
        out = np.empty((n, 16), dtype=np.float32)
        flags = np.empty(n, dtype=np.uint32)
        s1, s2 = self.settings(settings), self.settings(CHANGED)

        def p(a):
            return oracle.buf(ffi, a)

        lib.ahrs_run(p(s1), p(s2), n, p(self.mode), p(self.op), p(self.heading),
                     p(self.period), p(log.gyr), p(log.acc), p(log.mag), p(self.ext),
                     p(state), p(out), p(flags))
        return state, out, flags

    def cuts(self):
        n = len(self.mode)
        nan = np.isnan(self.period)
        return sorted({0, n, *(np.nonzero(np.diff(self.mode))[0] + 1), *np.nonzero(self.op)[0],
                       *np.nonzero(~np.isnan(self.heading))[0],
                       *(np.nonzero(np.diff(nan))[0] + 1)})

    def run_ours(self, f):
        log, parts, cuts = self.log, [], self.cuts()
        for a, b in zip(cuts[:-1], cuts[1:]):
            if self.op[a] & 4:
                f.set_settings(**CHANGED)
            if self.op[a] & 1:
                f.restart()
            if self.op[a] & 2:
                f.skip_startup()
            if not np.isnan(self.heading[a]):
                f.set_heading(self.heading[a])
            sl = slice(a, b)
            dt = None if np.isnan(self.period[a]) else self.period[sl]
            if self.mode[a] == 0:
                parts.append(f.run(log.gyr[sl], log.acc[sl], log.mag[sl], dt=dt))
            elif self.mode[a] == 1:
                parts.append(f.run(log.gyr[sl], log.acc[sl], dt=dt, heading=self.ext[sl]))
            else:
                parts.append(f.run(log.gyr[sl], log.acc[sl], dt=dt))
        return np.concatenate(parts)


def make(mod, convention, settings=SETTINGS, dtype="float32", **kw):
    return mod.FusionAHRS13(**{**settings, "convention": convention}, dtype=dtype, **kw)


def assert_outputs_equal(f, states, out, flags):
    got = f.outputs_batch(states)
    want = _fusion.pack_outputs(out, flags)
    for name in _fusion.OUTPUTS:
        assert_same_bits(np.asarray(got[name]).reshape(len(states), -1),
                         np.asarray(want[name]).reshape(len(states), -1), None)
    for name in _fusion.FLAGS:
        np.testing.assert_array_equal(got[name], want[name], err_msg=name)


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_ahrs_matches_fusion13_c(fusion_exact, convention):
    """Every state member and output after every sample, through rejection, recovery,
    overrange, magnetic disturbance, the three update forms, set heading, new settings,
    restart, skipped start-up and measured sample periods; every path reached."""
    ffi, lib = fusion_exact
    sc = Scenario(convention)
    state, out, flags = sc.run_oracle(ffi, lib)
    for name, bit in FLAG_BITS.items():
        assert np.any(flags & bit), f"the scenario never reached {name}"
    assert np.any(state[:, 15] == 0) and np.any(state[:, 15] == 1)
    mods = (imufuse_c, ref) if convention == "NWU" else (imufuse_c,)
    for mod in mods:
        f = make(mod, convention)
        got = sc.run_ours(f)
        assert_same_bits(got, state, f.state_names)
        after = make(mod, convention, CHANGED)     # outputs with the settings then in force
        k = int(0.40 * len(got))
        assert_outputs_equal(make(mod, convention), got[:k], out[:k], flags[:k])
        assert_outputs_equal(after, got[k:], out[k:], flags[k:])
        assert f.skipped == 0


def test_ahrs_fast_invsqrt_matches_fusion13_c(fusion_fast):
    """Fusion's default build (fast inverse square root) against invsqrt="fast"."""
    ffi, lib = fusion_fast
    sc = Scenario("NWU", n=2000, seed=3)
    state, _, _ = sc.run_oracle(ffi, lib)
    got = sc.run_ours(make(imufuse_c, "NWU", invsqrt="fast"))
    assert_same_bits(got, state, _fusion13.AHRS_STATE_NAMES)


def test_float64_c_equals_twin():
    sc = Scenario("ENU", n=1500, seed=5)
    got = sc.run_ours(make(imufuse_c, "ENU", dtype="float64"))
    want = sc.run_ours(make(ref, "ENU", dtype="float64"))
    assert_same_bits(got, want, _fusion13.AHRS_STATE_NAMES)
    a, b = make(imufuse_c, "ENU", dtype="float64"), make(ref, "ENU", dtype="float64")
    for k in ("gravity", "earth_acceleration", "euler", "acceleration_error"):
        assert_same_bits(np.asarray(a.outputs_batch(got)[k]).reshape(len(got), -1),
                         np.asarray(b.outputs_batch(want)[k]).reshape(len(got), -1), None)


def _xio():
    data = np.loadtxt(__file__.rsplit("/", 1)[0] + "/data/xio_sensor_data_14s.csv",
                      delimiter=",", skiprows=1)
    t = data[:, 0]
    dt = np.diff(t, prepend=t[0] - 0.01).astype(np.float32)
    f32 = np.float32
    return dt, data[:, 1:4].astype(f32), data[:, 4:7].astype(f32), data[:, 7:10].astype(f32)


def test_xio_recording_matches_imufusion_package(imufusion):
    """x-io's own recording (its first 14 s) with x-io's advanced settings (Fusion's
    README: rejection 10 degrees, timeout 5 s; range 2000 deg/s), the bias algorithm in
    front and the measured period before every update, as x-io's advanced example: the
    PyPI package imufusion 1.3.3 and ours, quaternion, outputs and flags after every
    sample, and the bias offset."""
    dt, gyr, acc, mag = _xio()
    adv = _fusion13.ADVANCED
    bias_p = imufusion.Bias().set_settings(imufusion.BiasSettings(sample_rate=100.0))
    ahrs_p = imufusion.Ahrs().set_settings(imufusion.AhrsSettings(
        sample_rate=adv["sample_rate"], convention=imufusion.CONVENTION_NWU, gain=adv["gain"],
        gyroscope_range=adv["gyroscope_range"],
        acceleration_rejection=adv["acceleration_rejection"],
        magnetic_rejection=adv["magnetic_rejection"],
        rejection_timeout=adv["rejection_timeout"]))
    n = len(dt)
    want = {k: np.empty((n, w), dtype=np.float32) for k, w in
            (("q", 4), ("gravity", 3), ("linear_acceleration", 3), ("earth_acceleration", 3),
             ("offset", 3), ("err", 4))}
    wflags = np.empty((n, 6), dtype=bool)
    for k in range(n):
        g = bias_p.update(gyr[k])
        ahrs_p.set_sample_period(float(dt[k])).update(g, acc[k], mag[k])
        want["q"][k] = ahrs_p.get_quaternion()
        want["gravity"][k] = ahrs_p.get_gravity()
        want["linear_acceleration"][k] = ahrs_p.get_linear_acceleration()
        want["earth_acceleration"][k] = ahrs_p.get_earth_acceleration()
        want["offset"][k] = bias_p.get_offset()
        st, fl = ahrs_p.get_internal_states(), ahrs_p.get_flags()
        want["err"][k] = (st.acceleration_error, st.acceleration_recovery_trigger,
                          st.magnetic_error, st.magnetic_recovery_trigger)
        wflags[k] = (fl.startup, fl.overrange_recovery, fl.acceleration_recovery,
                     fl.magnetic_recovery, st.accelerometer_ignored, st.magnetometer_ignored)
    assert wflags[:, 0].any() and not wflags[:, 0].all()
    for mod in (imufuse_c, ref):
        bias = mod.FusionBias(100.0, dtype="float32")
        corrected, bstate = bias.run(gyr)
        assert_same_bits(bstate[:, :3], want["offset"], None)
        f = make(mod, "NWU", adv)
        states = f.run(corrected, acc, mag, dt=dt)
        assert_same_bits(states[:, :4], want["q"], None)
        out = f.outputs_batch(states)
        for k in ("gravity", "linear_acceleration", "earth_acceleration"):
            assert_same_bits(out[k], want[k], None)
        errs = np.stack([out["acceleration_error"], out["acceleration_recovery_trigger"],
                         out["magnetic_error"], out["magnetic_recovery_trigger"]], axis=1)
        assert_same_bits(errs, want["err"], None)
        got_flags = np.stack([out[k] for k in _fusion.FLAGS], axis=1)
        np.testing.assert_array_equal(got_flags, wflags)
        eul = np.stack([imufusion.quaternion_to_euler(q) for q in want["q"][::50]])
        assert_same_bits(out["euler"][::50], eul.astype(np.float32), None)


def test_bias_stationary_detection_and_nvm_across_restart(fusion_exact):
    """The bias algorithm through rest, motion and rest again (the offset adapts only
    after the stationary period), its offset kept across a restart (FusionBiasGetOffset,
    Initialise, SetOffset) as non-volatile memory keeps it."""
    ffi, lib = fusion_exact
    log = simulated_log(seed=4, n=3000)
    settings = np.array([100.0, 3.0, 2.0], dtype=np.float32)
    n, at = len(log.gyr), 2000
    out = np.empty((n, 3), dtype=np.float32)
    st = np.empty((n, 4), dtype=np.float32)
    lib.bias_run(oracle.buf(ffi, settings), n, oracle.buf(ffi, log.gyr), at,
                 oracle.buf(ffi, out), oracle.buf(ffi, st))
    assert st[:at, 3].max() == 200 and np.any(st[:at, 3] == 0)       # timer: full and reset
    assert np.any(np.diff(st[:at, 0]) != 0)                         # the offset adapted
    assert st[at, 3] <= 1 and np.any(st[at:, 0] != 0)
    for mod in (imufuse_c, ref):
        b = mod.FusionBias(100.0, 3.0, 2.0, dtype="float32")
        o1, s1 = b.run(log.gyr[:at])
        kept = b.offset
        b = mod.FusionBias(100.0, 3.0, 2.0, dtype="float32")
        b.offset = kept
        o2, s2 = b.run(log.gyr[at:])
        assert_same_bits(np.concatenate([s1, s2]), st, _fusion13.BIAS_STATE_NAMES)
        assert_same_bits(np.concatenate([o1, o2]), out, None)


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_compass_matches_fusion13_c(fusion_exact, convention):
    """FusionCompass of 1.3 is the 1.2.3 port's compass_heading, bit for bit."""
    ffi, lib = fusion_exact
    log = simulated_log(seed=2, n=600, zero_rows=False)
    want = np.empty(len(log.acc), dtype=np.float32)
    lib.compass(_fusion.CONVENTIONS[convention], len(log.acc), oracle.buf(ffi, log.acc),
                oracle.buf(ffi, log.mag), oracle.buf(ffi, want))
    for got in (imufuse_c.compass_heading(convention, log.acc, log.mag, dtype="float32"),
                ref.fusion.compass_heading(convention, log.acc, log.mag, dtype="float32")):
        assert_same_bits(np.asarray(got, dtype=np.float32), want, None)


def test_every_remap_alignment_matches_fusion13_c(fusion_exact):
    ffi, lib = fusion_exact
    x = np.random.default_rng(7).normal(0, 50, (64, 3)).astype(np.float32)
    x[0] = (-0.0, 0.0, -0.0)
    for i, name in enumerate(_fusion13.REMAP_ALIGNMENTS):
        want = np.empty_like(x)
        lib.remap(i, len(x), oracle.buf(ffi, x), oracle.buf(ffi, want))
        assert_same_bits(twin13.remap(x, i, dtype="float32"), want, None)
        assert_same_bits(imufuse_c.remap(x, name, dtype="float32"), want, None)


def test_models_match_imufusion_package(imufusion):
    rng = np.random.default_rng(8)
    x = rng.normal(0, 40, (50, 3)).astype(np.float32)
    m = (np.eye(3) + rng.normal(0, 0.02, (3, 3))).astype(np.float32)
    s, b = rng.normal(1, 0.05, 3).astype(np.float32), rng.normal(0, 2, 3).astype(np.float32)
    got_i = twin13.model_inertial(x, m, s, b, dtype="float32")
    got_m = twin13.model_magnetic(x, m, b, dtype="float32")
    assert_same_bits(got_i, np.stack([imufusion.model_inertial(r, m, s, b) for r in x]), None)
    assert_same_bits(got_m, np.stack([imufusion.model_magnetic(r, m, b) for r in x]), None)
    assert_same_bits(imufuse_c.model_inertial(x, m, s, b, dtype="float32"), got_i, None)
    assert_same_bits(imufuse_c.model_magnetic(x, m, b, dtype="float32"), got_m, None)


# ---- planted differences: the comparisons above catch each new path ---------------------

class _NoSkip(twin13.FusionAHRS13):
    def skip_startup(self):
        pass


class _RateOnly(twin13.FusionAHRS13):
    def _set_sample_period(self, dt):
        pass


class _BiasLate(twin13.FusionBias):
    def _set_settings(self, *a):
        super()._set_settings(*a)
        self.timeout += 1


def _remap_swapped(x, i, dtype):
    return twin13.remap(x, (i + 1) % 24 if i == 5 else i, dtype=dtype)


def test_planted_differences_are_caught(fusion_exact):
    """A twin that ignores skip_startup, one that ignores the measured period, a bias one
    sample late and a remap with one alignment swapped: each is told apart from Fusion."""
    ffi, lib = fusion_exact
    sc = Scenario("NWU", n=1200, seed=6)
    sc.op[int(0.90 * 1200)] = 2          # skip start-up alone
    state, _, _ = sc.run_oracle(ffi, lib)
    for planted in (_NoSkip, _RateOnly):
        got = sc.run_ours(planted(convention="NWU", **SETTINGS, dtype="float32"))
        with pytest.raises(AssertionError):
            assert_same_bits(got, state, _fusion13.AHRS_STATE_NAMES)
    log = simulated_log(seed=4, n=3000)
    settings = np.array([100.0, 3.0, 2.0], dtype=np.float32)
    out = np.empty((3000, 3), dtype=np.float32)
    st = np.empty((3000, 4), dtype=np.float32)
    lib.bias_run(oracle.buf(ffi, settings), 3000, oracle.buf(ffi, log.gyr), -1,
                 oracle.buf(ffi, out), oracle.buf(ffi, st))
    _, s = _BiasLate(100.0, 3.0, 2.0, dtype="float32").run(log.gyr)
    with pytest.raises(AssertionError):
        assert_same_bits(s, st, None)
    x = np.random.default_rng(7).normal(0, 50, (16, 3)).astype(np.float32)
    want = np.empty_like(x)
    lib.remap(5, len(x), oracle.buf(ffi, x), oracle.buf(ffi, want))
    with pytest.raises(AssertionError):
        assert_same_bits(_remap_swapped(x, 5, "float32"), want, None)


# ---- the API: both backends accept, reject and compute the same --------------------------

@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_update_forms_equal_run(dtype):
    """update() per sample (dt given, dt omitted, no magnetometer, external heading) gives
    run()'s states, in both backends; run_many gives each set's run()."""
    log = simulated_log(seed=11, n=400)
    for mod in (imufuse_c, ref):
        f, g = make(mod, "NED", dtype=dtype), make(mod, "NED", dtype=dtype)
        want = f.run(log.gyr, log.acc, log.mag, dt=log.dt)
        got = []
        for k in range(400):
            g.update(log.gyr[k], log.acc[k], log.mag[k], float(log.dt[k]))
            got.append(g.state)
        assert_same_bits(np.array(got), want, _fusion13.AHRS_STATE_NAMES)
        f, g = make(mod, "NWU", dtype=dtype), make(mod, "NWU", dtype=dtype)
        want = f.run(log.gyr, log.acc, heading=log.yaw)
        got = []
        for k in range(400):
            g.update_external_heading(log.gyr[k], log.acc[k], float(log.yaw[k]))
            got.append(g.state)
        assert_same_bits(np.array(got), want, None)
    sets = [dict(SETTINGS, convention="ENU"), dict(CHANGED, convention="NWU")]
    many = imufuse_c.FusionAHRS13.run_many(sets, log.gyr, log.acc, dtype=dtype, dt=log.dt)
    for p, got in zip(sets, many):
        assert_same_bits(got, imufuse_c.FusionAHRS13(**p, dtype=dtype).run(
            log.gyr, log.acc, dt=log.dt), None)


def test_nonfinite_samples_and_periods_are_skipped_alike():
    """imufuse's non-finite policy: the sample (or period) is rejected, the state kept and
    `skipped` counted, in the C and the twin alike."""
    log = simulated_log(seed=12, n=300)
    gyr, dt = log.gyr.copy(), log.dt.copy()
    gyr[50, 1] = np.nan
    dt[120] = np.inf
    res = []
    for mod in (imufuse_c, ref):
        f = make(mod, "NWU")
        s = f.run(gyr, log.acc, log.mag, dt=dt)
        assert f.skipped == 2
        keep = [i for i in range(23) if i != 14]     # the period of sample 50 is set
        assert_same_bits(s[50, keep], s[49, keep], None)
        assert s[120, 14] == s[119, 14]              # the period before it integrates
        res.append(s)
    assert_same_bits(res[0], res[1], _fusion13.AHRS_STATE_NAMES)


@pytest.mark.parametrize("bad", [dict(sample_rate=0.0), dict(gain=-1.0),
                                 dict(convention="XYZ"), dict(rejection_timeout=-1.0),
                                 dict(sample_rate=1e6, rejection_timeout=1e6),
                                 dict(acceleration_rejection=200.0), dict(invsqrt="slow")])
def test_bad_settings_are_refused_by_both(bad):
    for mod in (imufuse_c, ref):
        with pytest.raises(ValueError, match=next(iter(bad)) if "convention" not in bad
                           else "convention"):
            mod.FusionAHRS13(**bad)


def test_copies_continue_alike():
    import copy
    import pickle
    log = simulated_log(seed=13, n=200)
    f = make(imufuse_c, "ENU")
    f.run(log.gyr[:100], log.acc[:100], log.mag[:100], dt=log.dt[:100])
    for g in (copy.copy(f), pickle.loads(pickle.dumps(f))):
        assert_same_bits(g.run(log.gyr[100:], log.acc[100:], log.mag[100:]),
                         copy.deepcopy(f).run(log.gyr[100:], log.acc[100:], log.mag[100:]),
                         None)


def test_opposite_vectors_give_a_zero_residual(fusion_exact, imufusion):
    """1.3's fix of the NaN of exactly opposite vectors: a sensor upside down against the
    identity (accelerometer exactly -up, field along the predicted east) gives a zero residual,
    as Fusion 1.3's C and the package do; the path is reached (dot < 0, cross = 0)."""
    ffi, lib = fusion_exact
    n = 40
    gyr = np.zeros((n, 3), dtype=np.float32)
    acc = np.tile(np.float32([0.0, 0.0, -1.0]), (n, 1))
    mag = np.tile(np.float32([0.0, 0.0, 0.0]), (n, 1))
    gyr[20:] = np.float32([5.0, -3.0, 1.0])
    acc[20:] = np.float32([0.1, 0.2, 0.97])
    sc = Scenario("NWU", n=n)
    sc.log.gyr, sc.log.acc, sc.log.mag = gyr, acc, mag
    sc.mode[:] = 0
    sc.op[:] = 0
    sc.heading[:] = np.nan
    sc.period[:] = np.float32(0.01)
    state, _, _ = sc.run_oracle(ffi, lib)
    assert np.all(state[:20, 8:11] == 0) and np.all(state[:20, 17] == 0)   # used, zero
    assert np.all(np.isfinite(state))
    for mod in (imufuse_c, ref):
        assert_same_bits(make(mod, "NWU").run(gyr, acc, mag, dt=sc.period), state, None)
    p = imufusion.Ahrs().set_settings(imufusion.AhrsSettings(gyroscope_range=2000.0))
    want = []
    for k in range(n):
        p.set_sample_period(0.01).update(gyr[k], acc[k], mag[k])
        want.append(p.get_quaternion())
    got = make(imufuse_c, "NWU", dict(SETTINGS, acceleration_rejection=0.0,
                                      magnetic_rejection=0.0, rejection_timeout=0.0)).run(
        gyr, acc, mag, dt=0.01)
    assert_same_bits(got[:, :4], np.array(want, dtype=np.float32), None)


def test_float64_bias_c_equals_twin():
    log = simulated_log(seed=14, n=2000)
    a = imufuse_c.FusionBias(100.0, 3.0, 1.0, dtype="float64").run(log.gyr)
    b = ref.FusionBias(100.0, 3.0, 1.0, dtype="float64").run(log.gyr)
    assert np.any(b[1][:, 0] != 0)
    for x, y in zip(a, b):
        assert_same_bits(x, y, None)


@pytest.mark.parametrize("label,settings", [
    ("defaults", dict(_fusion13.DEFAULTS)),
    ("gain 0", dict(SETTINGS, gain=0.0)),
    ("advanced", dict(_fusion13.ADVANCED, sample_rate=99.2))])
def test_other_settings_match_fusion13_c(fusion_exact, label, settings):
    """Fusion's defaults (rejection off, timeout 0), gain 0 (start-up still 3 s, rejection
    off) and x-io's advanced settings at a rate whose period is not a float32 1/100."""
    ffi, lib = fusion_exact
    sc = Scenario("ENU", n=1500, seed=21)
    state, out, flags = sc.run_oracle(ffi, lib, settings)
    f = make(imufuse_c, "ENU", settings)
    got = sc.run_ours(f)
    assert_same_bits(got, state, _fusion13.AHRS_STATE_NAMES)
    k = int(0.40 * len(got))
    assert_outputs_equal(make(imufuse_c, "ENU", settings), got[:k], out[:k], flags[:k])


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_xio_recording_every_state_member(fusion_exact, convention):
    """x-io's recording through Fusion 1.3's C with the advanced settings and the measured
    period before every update: every state member and output after every sample, each
    convention (the package above cannot read the private members)."""
    ffi, lib = fusion_exact
    dt, gyr, acc, mag = _xio()
    sc = Scenario(convention, n=len(dt))
    sc.log.gyr, sc.log.acc, sc.log.mag = gyr, acc, mag
    sc.mode[:] = 0
    sc.op[:] = 0
    sc.heading[:] = np.nan
    sc.period = dt
    state, out, flags = sc.run_oracle(ffi, lib, _fusion13.ADVANCED)
    f = make(imufuse_c, convention, _fusion13.ADVANCED)
    got = f.run(gyr, acc, mag, dt=dt)
    assert_same_bits(got, state, _fusion13.AHRS_STATE_NAMES)
    assert_outputs_equal(f, got, out, flags)


def test_a_preset_runs_at_the_logs_rate():
    """`--preset advanced` (x-io's example: 100 Hz) on a log of another rate runs at the log's
    rate, as without a preset (the rate sets the rejection timeout in samples); a sample_rate
    the user gives wins over both."""
    from imufuse import io
    from imufuse.session import RunOptions, Session
    s = Session(io.example_log())
    rate = 1.0 / s.dt()
    assert abs(rate - 100.0) > 100.0                 # the shipped BROAD excerpt: 285.7 Hz
    _, p, *_ = s.make("FusionAHRS13", {}, RunOptions(preset="advanced"))
    assert p["sample_rate"] == rate and p["rejection_timeout"] == 5.0
    assert s.make("FusionAHRS13", {})[1]["sample_rate"] == rate
    _, p, *_ = s.make("FusionAHRS13", {"sample_rate": 50.0}, RunOptions(preset="advanced"))
    assert p["sample_rate"] == 50.0
    a = s.run("FusionAHRS13", {}, RunOptions(preset="advanced")).estimate.q
    b = s.run("FusionAHRS13", {"sample_rate": rate}, RunOptions(preset="advanced")).estimate.q
    assert np.array_equal(a, b)
