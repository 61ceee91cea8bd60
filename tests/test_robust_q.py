"""RobustIMUQ, the recommended filter in fixed point (csrc/fixed/robust_q.c).

The project-wide suites run it from the registry (bit for bit against the twin on the host,
Cortex-M0 and ATmega328P, hostile counts, arbitrary states under UBSan, the fuzz driver, long
rests). Here: real recordings as published, converted to the counts of common MEMS parts;
the accuracy against the float64 filter on the same counts; the one profile; the ranges the
C refuses; the upside-down start.
"""
import glob
import os

import numpy as np
import pytest

import imufuse_c
from imufuse import evaluation, mcu, reference, rotations
from imufuse.mcu import filters as mf
from bits import assert_same_bits
from broad_data import BROAD, SKIP_REASON

GS = np.deg2rad(1 / 16.4)   # +-2000 deg/s on 16 bits: 16.4 LSB per deg/s
AS = 4096 / 9.81            # +-8 g on 16 bits: 4096 LSB per g (acc in m/s^2)


def counts(x, scale):
    return np.clip(np.round(np.asarray(x) * scale), -32768, 32767).astype(np.int16)


def trial_counts(path):
    d = np.load(path)
    return d, 1.0 / float(d["rate"]), counts(d["gyr"], 1 / GS), counts(d["acc"], AS)


PROFILES = ("32", "8")


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
@pytest.mark.parametrize("profile", PROFILES)
def test_bit_exact_on_a_recording(profile):
    """BROAD's fastest trial (up to 1400 deg/s, rest breaks) as int16 counts: the C and the
    twin after every sample, every state word."""
    d, dt, g, a = trial_counts(os.path.join(BROAD, "09_undisturbed_fast_rotation_with_breaks_B.npz"))
    n = 12_000
    c = imufuse_c.RobustIMUQ(dt, gyr_scale=GS, profile=profile).run(g[:n], a[:n])
    r = reference.RobustIMUQ(dt, gyr_scale=GS, profile=profile).run(g[:n], a[:n])
    assert_same_bits(c, r)
    # the run went through rest (B1) and motion beyond tau_acc (B3)
    names = reference.RobustIMUQ.state_names
    assert c[:, names.index("n_rest")].max() == np.ceil(1.5 / dt)
    assert np.abs(np.diff(c[:, names.index("bx")])).max() > 0


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
@pytest.mark.parametrize("profile", PROFILES)
def test_broad_accuracy_against_float64(profile):
    """The seven development trials as int16 counts (2000 deg/s, 8 g): tilt RMSE of the fixed
    point within 0.02 deg of float64's on the same counts, mean and every trial, each profile
    (measured: 0.616 against 0.617, docs/fixed-point.md), and the two estimates within
    0.05 deg of each other at every sample."""
    paths = sorted(glob.glob(os.path.join(BROAD, "*.npz")))
    assert len(paths) == 7
    tilt_q, tilt_f, worst = [], [], 0.0
    for path in paths:
        d, dt, g, a = trial_counts(path)
        qq = imufuse_c.RobustIMUQ(dt, gyr_scale=GS, profile=profile).run(g, a)[:, :4] * 2.0 ** -30
        # the float filter with the fixed point's B1/B3 (a calibrated gyro's: gyr_bias_max 0)
        qf = imufuse_c.RobustIMU(dt, dtype="float64", gyr_bias_max=0.0).run(
            g * GS, a.astype(float))[:, :4]
        for q, out in ((qq, tilt_q), (qf, tilt_f)):
            out.append(evaluation.evaluate(q, d["quat_ref"], est_frame="NWU", ref_frame="ENU",
                                           movement=d["movement"]).inclination)
        # the angle between the two estimates' vertical, every sample
        up_q = rotations.quat_rotate_inv(qq, [0.0, 0.0, 1.0])
        up_f = rotations.quat_rotate_inv(qf, [0.0, 0.0, 1.0])
        cos = np.sum(up_q * up_f, axis=1) / np.linalg.norm(up_q, axis=1)
        worst = max(worst, float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max()))
    diff = np.abs(np.array(tilt_q) - np.array(tilt_f))
    assert abs(np.mean(tilt_q) - np.mean(tilt_f)) < 0.02, (tilt_q, tilt_f)
    assert diff.max() < 0.02, diff
    assert worst < 0.05, worst
    assert np.mean(tilt_q) < 0.62


@pytest.mark.parametrize("profile", PROFILES)
def test_exactly_upside_down_from_the_first_sample(profile):
    """An int16 accelerometer reading exactly (0, 0, -1 g) from power-up: gravity is
    antiparallel to earth z, the smallest rotation is a half turn about any horizontal axis
    (about x, as the float filter). 300 000 samples at rest; the twin bit for bit on the
    first 2 000."""
    n = 300_000
    g = np.zeros((n, 3), np.int16)
    a = np.tile(np.array([0, 0, -4096], np.int16), (n, 1))
    f = imufuse_c.RobustIMUQ(0.002, gyr_scale=1.0642e-3, profile=profile)
    S = f.run(g, a)
    q = S[:, :4] * 2.0 ** -30
    # the norm the full normalisation leaves at the first sample (imf_q_normalise: its inverse
    # square root's relative error < 1e-4; the 8-bit profile's imf_q_normalise_p8: < 2.5e-3,
    # removed by the first-order steps), and from the second sample on
    assert np.abs(np.sum(q * q, axis=1) - 1.0).max() < (2e-4 if profile == "32" else 2.5e-3)
    assert np.abs(np.sum(q[1:] * q[1:], axis=1) - 1.0).max() < 2e-4
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    assert np.allclose(np.abs(q[0]), [0.0, 1.0, 0.0, 0.0], atol=1e-4), q[0]
    up = rotations.quat_rotate_inv(q[-1], [0.0, 0.0, 1.0])
    assert np.allclose(up, [0.0, 0.0, -1.0], atol=1e-6), up
    r = reference.RobustIMUQ(0.002, gyr_scale=1.0642e-3, profile=profile).run(g[:2000], a[:2000])
    assert_same_bits(S[:2000], r)


@pytest.mark.parametrize("profile", PROFILES)
@pytest.mark.parametrize("acc", [(300, -200, -4096), (1, 0, -4096), (0, 1, -16000),
                                 (3000, -2000, -1000), (-32768, 5, -32768)])
def test_turned_over_first_sample(profile, acc):
    """A start turned over but not exactly upside down (the inclination's u_z < 0, where 1 +
    u_z is a difference of nearly equal numbers): the first sample's vertical within 0.05 deg
    of the reading's (measured: 0.02 at most), the norm within the first sample's bound, the
    twin bit for bit."""
    n = 200
    g = np.zeros((n, 3), np.int16)
    a = np.tile(np.array(acc, np.int16), (n, 1))
    S = imufuse_c.RobustIMUQ(0.002, gyr_scale=1.0642e-3, profile=profile).run(g, a)
    q = S[0, :4] * 2.0 ** -30
    assert abs(q @ q - 1.0) < (2e-4 if profile == "32" else 2.5e-3)
    up = rotations.quat_rotate_inv(q / np.linalg.norm(q), [0.0, 0.0, 1.0])
    want = np.array(acc, float) / np.linalg.norm(acc)
    assert np.degrees(np.arccos(np.clip(up @ want, -1.0, 1.0))) < 0.05, (up, want)
    r = reference.RobustIMUQ(0.002, gyr_scale=1.0642e-3, profile=profile).run(g, a)
    assert_same_bits(S, r)


@pytest.mark.parametrize("mod", [imufuse_c, reference], ids=["c", "ref"])
def test_two_profiles(mod):
    """Both profiles are built, by both backends, and they differ (the 8-bit one narrows its
    operands); any other profile is refused, saying which are."""
    assert reference.RobustIMUQ.profiles == PROFILES
    rng = np.random.default_rng(3)
    g = rng.integers(-2000, 2000, (300, 3)).astype(np.int16)
    a = (rng.integers(-300, 300, (300, 3)) + [0, 0, 4096]).astype(np.int16)
    S = [mod.RobustIMUQ(0.01, gyr_scale=1e-3, profile=p).run(g, a) for p in PROFILES]
    assert not np.array_equal(S[0], S[1])
    with pytest.raises(ValueError, match="'32' or '8'"):
        mod.RobustIMUQ(0.01, gyr_scale=1e-3, profile="16")


def test_reciprocals_on_every_mantissa():
    """B5's running means and B2's gains divide by reciprocals: robust_q_recip (32-bit
    profile, the square of imf_invsqrt_u32) and robust_q_recip_p8 (Newton's z (2 - a z)).
    Each depends on x's 16 leading bits (and the rest of x through the truncation): every
    one of the 32 768, and then x with every low bit set, against 2^N / x in float64; the
    twins raise where an int32 or uint32 bound fails. Relative error (measured 1.16e-4 and
    7.05e-5; with x's low bits set, 1.00e-4 and 5.5e-5): below 1.2e-4 and 7.1e-5; the
    q-scale's mantissa within [2^14, 2^15)."""
    from imufuse.reference import fixed_robust_ops as fo
    from imufuse.reference import fixed_robust_p8 as fr
    a = np.arange(32768, 65536)
    for fn, bound, bound_low in ((fo.recip, 1.2e-4, 1.2e-4), (fr.recip_p8, 7.1e-5, 7.1e-5)):
        worst = worst_low = 0.0
        for v in a.tolist():
            for x, n in ((v << 16, 47), ((v << 16) | 0xFFFF, 47), (v, 31)):
                r = fn(x, n)
                assert 16384 <= r.m < 32768, (fn.__name__, x, r)
                err = abs(r.m * 2.0 ** -r.s * x / 2.0 ** n - 1.0)   # against 2^N / x
                if x & 0xFFFF == 0xFFFF:
                    worst_low = max(worst_low, err)
                else:
                    worst = max(worst, err)
        assert worst < bound, (fn.__name__, worst)
        assert worst_low < bound_low, (fn.__name__, worst_low)
    # the start-up's 1 / (n + 1) for every n of a 10 s start-up at 1 kHz
    for n in range(1, 10_001):
        r = fr.recip_p8(n, 0)
        assert abs(r.m * 2.0 ** -r.s * n - 1.0) < 7.1e-5, n


#: quaternions far from unit length (q30): zero, below the snapshot's LSB, the smallest
#: nonzero snapshot (the slowest to grow: 29 steps), saturated, mixed signs, three random
FAR_QUATERNIONS = [[0, 0, 0, 0], [16383, -9000, 0, 5], [16384, 0, 0, 0],
                   [2**31 - 1] * 4, [-2**31] * 4, [2**31 - 1, -2**31, 123456789, -5],
                   [1 << 29, 0, 0, 0], [3 << 29, 1 << 20, -(1 << 25), 7],
                   [1070000000, -2**31, 999, 0]]


FAR_G, FAR_A = [3, -2, 1], [300, -200, 4000]


def far_state(mod, far):
    """The state of mod's RobustIMUQ p8 after one update from s = far, c = far reversed (set
    after a first update at power-up)."""
    g, a = np.array(FAR_G, np.int16), np.array(FAR_A, np.int16)
    f = mod.RobustIMUQ(0.01, gyr_scale=1e-3, profile="8")
    f.update(g, a)
    st = np.array(f.state)
    st[4:8] = far
    st[8:12] = far[::-1]
    f.state = st
    f.update(g, a)
    return np.array(f.state)


def test_full_normalisation_from_any_state():
    """The 8-bit profile's full normalisation (robust_q_normalise_p8, Newton steps from |q|^2
    - 1 in q15 saturated): from every FAR_QUATERNIONS state of s and c, one update by the C
    equals the twin's, every state word, and leaves |q|^2, |s|^2 and |c|^2 within 2^-8 of 1
    (the first-order band) with their directions kept (s's to 1e-4, once the update's small
    rate is undone). The step bound holds with room: the slowest start needs 29 of the 40
    steps (with 28 it is left outside the band)."""
    from imufuse.reference import fixed_robust_p8 as fr
    names = reference.RobustIMUQ.state_names
    for far in FAR_QUATERNIONS:
        fs = [far_state(mod, far) for mod in (imufuse_c, reference)]
        assert_same_bits(fs[0][None], fs[1][None])
        for k in (0, 4, 8):
            v = fs[0][k:k + 4] * 2.0 ** -30
            assert abs(v @ v - 1.0) < 2.0 ** -8, (far, names[k], v @ v)
        if any(far):
            want = np.array(far, float) / np.linalg.norm(far)
            got = fs[0][4:8] / np.linalg.norm(fs[0][4:8])
            assert abs(abs(want @ got) - 1.0) < 1e-4 or np.abs(np.array(far)).max() < 32768, far
    # the slowest start: the smallest nonzero snapshot, growing by 3/2 a step
    def band(q):
        qs = fq_snapshot(q)
        return 1069547520 < fr.fq.norm2(q, qs) < 1077936128
    fq_snapshot = fr.fq.snapshot
    assert fr.NORM_STEPS == 40
    assert band(fr.normalise_p8([16384, 0, 0, 0]))
    try:
        fr.NORM_STEPS = 28
        assert not band(fr.normalise_p8([16384, 0, 0, 0]))
    finally:
        fr.NORM_STEPS = 40


@pytest.mark.parametrize("target", ["m0", "avr"])
def test_full_normalisation_from_any_state_on_the_mcu(target):
    """test_full_normalisation_from_any_state on the Cortex-M0 and the ATmega328P (int 16
    bits wide): from every FAR_QUATERNIONS state of s and c, the state after one update
    equals the twin's, every word."""
    missing = mcu.ensure_toolchains([target])
    if missing:
        pytest.skip(f"toolchain for {target} unavailable: {missing[target]}")
    g, a = FAR_G, FAR_A
    ref = reference.RobustIMUQ(0.01, gyr_scale=1e-3, profile="8")
    fields = [("q", 4), ("s", 4), ("c", 4), ("f", 3), ("v", 3), ("p", 3), ("b", 3), ("lw", 3),
              ("la", 3)]
    words = [f"imf_f.x.{n}[{i}]" for n, m in fields for i in range(m)]
    words += ["imf_f.x.n", "imf_f.x.n_rest"]
    assert len(words) == len(reference.RobustIMUQ.state_names)
    table = ",\n".join("{" + ", ".join(f"(int32_t){v}L" if v != -2**31 else "INT32_MIN"
                                          for v in far) + "}" for far in FAR_QUATERNIONS)
    pre = ('#include <stdint.h>\n#include "robust_q.h"\nstatic imf_robust_imu_q_t imf_f;\n'
           f"static const int16_t imf_g[3] = {{{g[0]}, {g[1]}, {g[2]}}};\n"
           f"static const int16_t imf_a[3] = {{{a[0]}, {a[1]}, {a[2]}}};\n"
           f"static const int32_t imf_far[][4] = {{\n{table}}};\n")
    step = (f"{ref.c_init_call('imf_f')}\nimf_robust_imu_q_update_v(&imf_f, imf_g, imf_a);\n"
            "{ int i; for (i = 0; i < 4; ++i) { imf_f.x.s[i] = imf_far[k][i]; "
            "imf_f.x.c[i] = imf_far[k][3 - i]; } }\n"
            "imf_robust_imu_q_update_v(&imf_f, imf_g, imf_a);")
    drv = mcu.Driver(prelude=pre, step=step, state=[(w, "i32") for w in words])
    res = mcu.run(target, sources=[str(mf.CSRC / "fixed" / "robust_q.c")],
                  include_dirs=[mf.CSRC / "fixed"], driver=drv,
                  inputs={"k": np.arange(len(FAR_QUATERNIONS), dtype=np.int16)})
    got = np.column_stack([np.asarray(col, np.int64) for col in res.values()]).astype(np.int32)
    assert_same_bits(got, np.array([far_state(reference, far) for far in FAR_QUATERNIONS]))


def test_p8_helpers_keep_the_shared_values():
    """The 8-bit profile's own compact helpers give the values of the shared ones they
    replace (their comments say so): shl_p8 / shift_p8 those of ci.shl_sat32 /
    ci.rshift_sat32 at the int32 bounds and in between, and the strapdown's qmul_p8 with
    h_0 = 0 rounded by rshr_hs_p8 that of fq.rate_p8, over random and extreme snapshots."""
    from imufuse.reference import fixed_robust_p8 as fr
    ci, fq = fr.ci, fr.fq
    rng = np.random.default_rng(26)
    xs = [0, 1, -1, 2**30 - 1, 2**30, -2**30, -2**30 - 1, 2**31 - 1, -2**31, 12345, -98765]
    xs += rng.integers(-2**31, 2**31, 200).tolist()
    for x in xs:
        for k in range(32):
            assert fr.shl_p8(x, k) == ci.shl_sat32(x, k), (x, k)
        for n in range(-20, 32):
            assert fr.shift_p8(x, n) == ci.rshift_sat32(x, n), (x, n)
    ext = [32767, -32767, -32768, 0, 1, -1]
    for _ in range(3000):
        qs = [int(v) for v in rng.choice(ext, 4)] if rng.random() < 0.3 else \
            rng.integers(-32768, 32768, 4).tolist()
        h = [int(v) for v in rng.choice(ext, 3)] if rng.random() < 0.3 else \
            rng.integers(-32768, 32768, 3).tolist()
        hs = int(rng.integers(0, 16))
        got = [fq.rshr_hs_p8(v, hs) for v in fr.qmul_p8(qs, [0] + h)]
        assert got == fq.rate_p8(qs, h, hs), (qs, h, hs)


#: settings the fixed point refuses (the float filter takes them): each with its reason
REFUSED = {
    "tau_acc below 200 dt": dict(dt=0.01, tau_acc=1.99),
    "tau_acc above 8192 dt": dict(dt=0.001, tau_acc=8.2),
    "gyro full scale too fast for dt": dict(dt=0.03, tau_acc=10.0),
    "rest_acc above 1": dict(rest_acc=1.5),
    "profile neither 32 nor 8": dict(profile=16),
}


@pytest.mark.parametrize("what", list(REFUSED))
def test_ranges_refused_by_twin_and_c(what):
    """Out-of-range settings raise in the twin (naming the parameter), and the C init returns
    -1 for the same settings (host build); the edges of the range are accepted by both."""
    p = dict(dict(dt=0.01, gyr_scale=1.0642e-3), **REFUSED[what])
    with pytest.raises(ValueError):
        reference.RobustIMUQ(**p)
    edge = dict(dt=0.01, tau_acc=2.0, gyr_scale=1.0642e-3)
    reference.RobustIMUQ(**edge)
    rc = c_init_returns("imf_robust_imu_q", [p, edge, dict(dt=0.001, tau_acc=8.192, gyr_scale=1.0642e-3,
                                                             profile=8)])
    assert rc == [-1, 0, 0], rc


def c_init_returns(c_name, sets):
    """What <c_name>_init returns (0 or -1) for each settings dict, from its defaults with
    the dict's members set: one host build of csrc/fixed/robust_q.c."""
    calls = []
    for i, s in enumerate(sets):
        fields = " ".join(f"st.{k} = {v!r};" for k, v in s.items())
        calls.append(f"{c_name}_default_settings(&st); {fields} "
                     f"imf_r{i} = {c_name}_init(&imf_f, &st);")
    pre = (f'#include "robust_q.h"\nstatic {c_name}_t imf_f;\nstatic {c_name}_settings_t st;\n'
           + "".join(f"static int32_t imf_r{i};\n" for i in range(len(sets))))
    drv = mcu.Driver(prelude=pre, step="\n".join(calls),
                     state=[(f"imf_r{i}", "i32") for i in range(len(sets))])
    res = mcu.run("host", sources=[str(mf.CSRC / "fixed" / "robust_q.c")],
                  include_dirs=[mf.CSRC / "fixed"], driver=drv, inputs={"k": np.zeros(1, np.int16)})
    return [int(np.int32(col[0])) for col in res.values()]


def test_bias_learnt_at_rest_in_counts():
    """B1 in fixed point: a gyro offset of 37 counts (2.3 deg/s, beyond the rest threshold's
    2 deg/s only with the offset's noise absent) on a still, tilted sensor is the bias after
    a few tau_bias_rest, within 0.05 count; the attitude does not turn."""
    n = 20_000
    g = np.tile(np.array([37, -21, 12], np.int16), (n, 1))
    a = np.tile(np.array([800, -600, 3972], np.int16), (n, 1))
    f = imufuse_c.RobustIMUQ(0.005, gyr_scale=1.0642e-3, rest_gyr=5.0)
    S = f.state_to_float(f.run(g, a)[-1:])[0]
    names = f.state_names
    b = np.array([S[names.index(k)] for k in ("bx", "by", "bz")]) / 1.0642e-3
    assert np.allclose(b, [37, -21, 12], atol=0.05), b


@pytest.mark.parametrize("mod", [imufuse_c, reference], ids=["c", "ref"])
def test_ordinary_mistakes_are_named(mod):
    """The mistakes users make with a fixed-point filter, each refused with what to do: the
    gyro scale in deg/s per count, dt in milliseconds, physical units where counts belong."""
    with pytest.raises(ValueError, match="rad/s per count.*57 times"):
        mod.RobustIMUQ(0.01, gyr_scale=0.061)                 # deg/s per count
    with pytest.raises(ValueError, match="looks like milliseconds"):
        mod.RobustIMUQ(10, gyr_scale=1.0642e-3)               # dt in ms
    f = mod.RobustIMUQ(0.01, gyr_scale=1.0642e-3)
    with pytest.raises(ValueError, match="integer sensor counts"):
        f.run(np.full((5, 3), 0.1), np.tile([0.0, 0.0, 1.0], (5, 1)))   # rad/s and g


PUBLISHED = os.path.join(BROAD, "published", "03_undisturbed_slow_rotation_C.hdf5") if BROAD else None


@pytest.mark.skipif(PUBLISHED is None or not os.path.isfile(PUBLISHED),
                    reason="the published BROAD trial 03 (HDF5) is not beside the checkout")
def test_published_file_through_the_reader():
    """BROAD trial 03 exactly as published (HDF5), read by imufuse.io.read_log (rad/s, g) and
    quantised as an int16 IMU would give it: the C and the twin bit for bit on its first
    5 000 samples, and the whole trial's tilt RMSE within 0.02 deg of float64's on the same
    counts."""
    from imufuse.io import read_log
    log = read_log(PUBLISHED)
    g = counts(log.gyr, 1 / GS)
    a = counts(log.acc, 4096.0)
    n = 5000
    c = imufuse_c.RobustIMUQ(log.dt, gyr_scale=GS)
    assert_same_bits(c.run(g[:n], a[:n]), reference.RobustIMUQ(log.dt, gyr_scale=GS).run(g[:n], a[:n]))
    qq = imufuse_c.RobustIMUQ(log.dt, gyr_scale=GS).run(g, a)[:, :4] * 2.0 ** -30
    qf = imufuse_c.RobustIMU(log.dt, dtype="float64").run(g * GS, a.astype(float))[:, :4]
    tilt = [evaluation.evaluate(q, log.q_ref, est_frame="NWU", ref_frame=log.ref_frame,
                                movement=log.movement).inclination for q in (qq, qf)]
    assert abs(tilt[0] - tilt[1]) < 0.02, tilt
    assert tilt[0] < 0.45, tilt
