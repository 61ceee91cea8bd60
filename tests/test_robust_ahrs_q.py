"""RobustAHRSQ, the recommended filter with a magnetometer in fixed point (csrc/fixed/robust_q.c).

The project-wide suites run it from the registry (bit for bit against the twin on the host,
Cortex-M0 and ATmega328P, hostile counts, arbitrary states under UBSan, the fuzz driver, long
rests with the field). Here: real recordings as published, converted to the counts of common
MEMS parts (0.15 uT per count for the magnetometer); tilt and heading against the float64
filter on the same counts; B4's disturbance handling; the stored offset; what is refused.
"""
import glob
import os

import numpy as np
import pytest

import imufuse_c
from imufuse import evaluation, reference, rotations
from imufuse.reference.fixed_robust import MAG_LAYOUT
from bits import assert_same_bits
from broad_data import BROAD, SKIP_REASON
from test_robust_q import AS, GS, c_init_returns, counts

MS = 1 / 0.15               # magnetometer counts per uT (0.15 uT per LSB)


def trial_counts(path):
    d = np.load(path)
    return (d, 1.0 / float(d["rate"]), counts(d["gyr"], 1 / GS), counts(d["acc"], AS),
            counts(d["mag"], MS))


def float64(dt):
    """The float64 filter the fixed point is measured against: RobustAHRS without B6 (not
    built in fixed point), on the same counts."""
    # the fixed point's B1/B3 are a calibrated gyro's (gyr_bias_max 0)
    return imufuse_c.RobustAHRS(dt, dtype="float64", gyr_bias_max=0.0, mag_learn=False)


PROFILES = ("32", "8")


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
@pytest.mark.parametrize("profile", PROFILES)
def test_bit_exact_on_a_recording(profile):
    """BROAD's trial with a magnet attached, as int16 counts: the C and the twin after every
    sample, every state word; the run went through B4's branches (the field used, rejected,
    and matching again)."""
    d, dt, g, a, m = trial_counts(os.path.join(BROAD, "34_disturbed_attached_magnet_3cm.npz"))
    c = imufuse_c.RobustAHRSQ(dt, gyr_scale=GS, profile=profile).run(g, a, m)
    names = reference.RobustAHRSQ.state_names
    n_ok = c[:, names.index("n_ok")]
    # the twin over the first 6 000 samples, and from the C's state across the magnet's arrival
    k0 = int(np.flatnonzero(n_ok == 0)[0]) - 1000
    r = reference.RobustAHRSQ(dt, gyr_scale=GS, profile=profile)
    assert_same_bits(c[:6000], r.run(g[:6000], a[:6000], m[:6000]))
    r.state = c[k0 - 1]
    assert_same_bits(c[k0:k0 + 6000], r.run(g[k0:k0 + 6000], a[k0:k0 + 6000], m[k0:k0 + 6000]))
    assert n_ok[k0:k0 + 6000].max() == np.ceil(0.5 / dt) and (n_ok[k0:k0 + 6000] == 0).any()
    assert np.abs(np.diff(c[:, names.index("rn")])).max() > 0


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
@pytest.mark.parametrize("profile", PROFILES)
def test_broad_accuracy_against_float64(profile):
    """The seven development trials as int16 counts (2000 deg/s, 8 g, 0.15 uT): tilt and
    heading RMSE of the fixed point within 0.02 deg and 0.05 deg of float64's on the same
    counts, mean and every trial (measured: tilt 0.6164 against 0.6170, heading 1.2360
    against 1.2353; docs/fixed-point.md), and the two attitudes within 0.1 deg of each other
    at every sample once the heading has settled (the first tau_mag)."""
    paths = sorted(glob.glob(os.path.join(BROAD, "*.npz")))
    assert len(paths) == 7
    res_q, res_f, worst = [], [], 0.0
    for path in paths:
        d, dt, g, a, m = trial_counts(path)
        qq = imufuse_c.RobustAHRSQ(dt, gyr_scale=GS, profile=profile).run(g, a, m)[:, :4] * 2.0 ** -30
        qf = float64(dt).run(g * GS, a.astype(float), m.astype(float))[:, :4]
        for q, out in ((qq, res_q), (qf, res_f)):
            e = evaluation.evaluate(q, d["quat_ref"], est_frame="NWU", ref_frame="ENU",
                                    movement=d["movement"])
            out.append((e.inclination, e.heading))
        qn = qq / np.linalg.norm(qq, axis=1, keepdims=True)
        settled = int(10.0 / dt)
        dot = np.abs(np.sum(qn[settled:] * qf[settled:], axis=1))
        worst = max(worst, float(np.degrees(2 * np.arccos(np.clip(dot, -1.0, 1.0))).max()))
    rq, rf = np.array(res_q), np.array(res_f)
    assert np.abs(rq.mean(0) - rf.mean(0)).max() < [0.02, 0.05][1], (rq.mean(0), rf.mean(0))
    assert abs(rq[:, 0].mean() - rf[:, 0].mean()) < 0.02
    assert np.abs(rq[:, 0] - rf[:, 0]).max() < 0.02, rq - rf
    assert np.abs(rq[:, 1] - rf[:, 1]).max() < 0.05, rq - rf
    assert worst < 0.1, worst
    assert rq[:, 1].mean() < 1.25


def _still(n, field, acc=(0, 0, 4096)):
    return (np.zeros((n, 3), np.int16), np.tile(np.array(acc, np.int16), (n, 1)),
            np.tile(np.array(field, np.int16), (n, 1)))


def _yaw(S):
    """The yaw of the quaternions in S's first four columns (q30), in a form that holds for
    any norm (the 8-bit profile's output is normalised to 2e-4 only)."""
    q = S[:, :4] * 2.0 ** -30
    return np.degrees(np.arctan2(2 * (q[:, 0] * q[:, 3] + q[:, 1] * q[:, 2]),
                                 q[:, 0] ** 2 + q[:, 1] ** 2 - q[:, 2] ** 2 - q[:, 3] ** 2))


@pytest.mark.parametrize("profile", PROFILES)
def test_heading_from_the_field_and_a_magnet_rejected(profile):
    """Level and still, the field 30 deg east of the sensor's x (dip 60 deg, 333 counts: 50 uT
    at 0.15 uT per count): the heading is -30 deg from the first sample on. A magnet then adds
    a field of the same size along y for 20 s: the norm and dip tests reject it, the heading
    does not move (at rest a steady new field never becomes the reference); removed, the field
    matches again and is used. The twin bit for bit."""
    c30, s30 = np.cos(np.radians(30)), np.sin(np.radians(30))
    h = 333 * np.cos(np.radians(60))
    field = np.round([h * c30, -h * s30, -333 * np.sin(np.radians(60))]).astype(int)
    magnet = field + [0, 333, 0]
    dt = 0.01
    parts = [_still(1000, field), _still(2000, magnet), _still(1000, field)]
    g, a, m = (np.concatenate([p[i] for p in parts]) for i in range(3))
    S = imufuse_c.RobustAHRSQ(dt, gyr_scale=GS, profile=profile).run(g, a, m)
    assert_same_bits(S[:1500], reference.RobustAHRSQ(dt, gyr_scale=GS, profile=profile).run(
        g[:1500], a[:1500], m[:1500]))
    yaw = _yaw(S)
    want = -np.degrees(np.arctan2(field[1], field[0]))   # minus the field's azimuth
    assert np.abs(yaw[:1000] - want).max() < 0.05, yaw[:3]
    # rejected: the gyro only. The heading stays within the resolution of its q15 direction
    # (2^-15 rad per component: 0.0035 deg), where the magnet would turn it by 45 deg
    assert np.abs(yaw[1000:3000] - yaw[999]).max() < 0.01
    names = reference.RobustAHRSQ.state_names
    assert S[2999, names.index("n_dist")] == 2000
    assert S[-1, names.index("n_dist")] == 0 and abs(yaw[-1] - want) < 0.05
    # the float64 filter on the same counts does the same, within that resolution
    F = imufuse_c.RobustAHRS(dt, dtype="float64", gyr_bias_max=0.0, mag_learn=False).run(
        g * GS, a * 1.0, m * 1.0)
    assert np.abs(yaw - _yaw(F * 2.0 ** 30)).max() < 0.01


def test_stored_offset_is_taken_off_exactly():
    """A hard-iron offset in the readings and the same offset stored with set_mag_offset:
    every state word but the stored offset (u, and B6's so) equals that of the clean
    readings, in both backends (the reading less the offset is exact in counts)."""
    rng = np.random.default_rng(5)
    n = 3000
    g = rng.integers(-400, 400, (n, 3)).astype(np.int16)
    a = (rng.integers(-300, 300, (n, 3)) + [0, 0, 4096]).astype(np.int16)
    m = (rng.integers(-20, 20, (n, 3)) + [250, 40, -280]).astype(np.int16)
    off = np.array([-1200, 700, 95])
    for mod in (imufuse_c, reference):
        clean = mod.RobustAHRSQ(0.005, gyr_scale=GS).run(g, a, m)
        f = mod.RobustAHRSQ(0.005, gyr_scale=GS)
        f.set_mag_offset(tuple(int(v) for v in off))
        shifted = f.run(g, a, (m + off).astype(np.int16))
        u = reference.RobustAHRSQ.state_names.index("ux")
        so = reference.RobustAHRSQ.state_names.index("sox")
        np.testing.assert_array_equal(shifted[:, u:u + 3], np.tile(off, (n, 1)))
        np.testing.assert_array_equal(shifted[:, so:so + 3], np.tile(off, (n, 1)))
        cols = list(range(u, u + 3)) + list(range(so, so + 3))
        np.testing.assert_array_equal(np.delete(shifted, cols, 1), np.delete(clean, cols, 1))
    for bad in ((1, 2), (0.5, 0, 0), (40000, 0, 0), "abc"):
        for mod in (imufuse_c, reference):
            with pytest.raises(ValueError, match="mag offset"):
                mod.RobustAHRSQ(0.005, gyr_scale=GS).set_mag_offset(bad)


@pytest.mark.parametrize("profile", PROFILES)
def test_upside_down_with_a_vertical_field(profile):
    """Upside down from power-up, the field straight down the sensor's z (no horizontal part:
    no heading), then tilted so it has one: 300 000 samples, |q| stays at 1, the gravity
    estimate points down, the twin bit for bit on the first 2 000."""
    n = 300_000
    g, a, m = _still(n, (0, 0, 333), acc=(0, 0, -4096))
    m[n // 2:] = [200, 0, 266]
    f = imufuse_c.RobustAHRSQ(0.002, gyr_scale=1.0642e-3, profile=profile)
    S = f.run(g, a, m)
    q = S[:, :4] * 2.0 ** -30
    # the first sample's full normalisation (8-bit profile: < 2.5e-3), then first order
    assert np.abs(np.sum(q * q, axis=1) - 1.0).max() < (2e-4 if profile == "32" else 2.5e-3)
    assert np.abs(np.sum(q[1:] * q[1:], axis=1) - 1.0).max() < 2e-4
    up = rotations.quat_rotate_inv(q[-1] / np.linalg.norm(q[-1]), [0.0, 0.0, 1.0])
    assert np.allclose(up, [0.0, 0.0, -1.0], atol=1e-6), up
    r = reference.RobustAHRSQ(0.002, gyr_scale=1.0642e-3, profile=profile)
    assert_same_bits(S[:2000], r.run(g[:2000], a[:2000], m[:2000]))
    r.state = S[n // 2 - 1]
    assert_same_bits(S[n // 2:n // 2 + 2000], r.run(g[n // 2:n // 2 + 2000], a[:2000], m[n // 2:n // 2 + 2000]))


@pytest.mark.parametrize("mod", [imufuse_c, reference], ids=["c", "ref"])
def test_what_is_refused(mod):
    """A profile other than 32 and 8; mag_norm above 1; B6's mag_noise outside [0.01, 1]
    (its gains in q24) and mag_offset_min above 1; and RobustIMUQ's ranges and mistakes (dt
    in ms). B6 itself (mag_learn=True) is accepted."""
    mod.RobustAHRSQ(0.01, gyr_scale=GS, mag_learn=True)
    for bad in (dict(mag_noise=0.005), dict(mag_noise=1.5), dict(mag_offset_min=1.5)):
        with pytest.raises(ValueError, match=next(iter(bad))):
            mod.RobustAHRSQ(0.01, gyr_scale=GS, mag_learn=True, **bad)
    with pytest.raises(ValueError, match="'32' or '8'"):
        mod.RobustAHRSQ(0.01, gyr_scale=GS, profile="16")
    with pytest.raises(ValueError, match="mag_norm"):
        mod.RobustAHRSQ(0.01, gyr_scale=GS, mag_norm=1.5)
    with pytest.raises(ValueError, match="looks like milliseconds"):
        mod.RobustAHRSQ(10, gyr_scale=GS)
    mod.RobustAHRSQ(0.01, gyr_scale=GS, mag_learn=False, mag_norm=1.0, mag_dip=180.0)


def test_c_init_refuses_what_the_twin_refuses():
    """The C init returns -1 for mag_learn 2, B6's mag_noise out of range, mag_norm above 1
    and a bad IMU range (host build); 0 for the defaults and for B6 on."""
    rc = c_init_returns("imf_robust_ahrs_q",
                        [dict(mag_learn=2), dict(mag_learn=1, mag_noise=0.005),
                         dict(mag_norm=1.5), dict(tau_acc=1.0), {}, dict(mag_learn=1)])
    assert rc == [-1, -1, -1, -1, 0, 0], rc


PUBLISHED = os.path.join(BROAD, "published", "03_undisturbed_slow_rotation_C.hdf5") if BROAD else None


@pytest.mark.skipif(PUBLISHED is None or not os.path.isfile(PUBLISHED),
                    reason="the published BROAD trial 03 (HDF5) is not beside the checkout")
def test_published_file_through_the_reader():
    """BROAD trial 03 exactly as published (HDF5), read by imufuse.io.read_log (rad/s, g, uT)
    and quantised as a MEMS IMU and magnetometer would give it: the C and the twin bit for
    bit on its first 5 000 samples; the whole trial's tilt and heading within 0.02 deg and
    0.05 deg of float64's on the same counts."""
    from imufuse.io import read_log
    log = read_log(PUBLISHED)
    g, a, m = counts(log.gyr, 1 / GS), counts(log.acc, 4096.0), counts(log.mag, MS)
    n = 5000
    assert_same_bits(imufuse_c.RobustAHRSQ(log.dt, gyr_scale=GS).run(g[:n], a[:n], m[:n]),
                     reference.RobustAHRSQ(log.dt, gyr_scale=GS).run(g[:n], a[:n], m[:n]))
    qq = imufuse_c.RobustAHRSQ(log.dt, gyr_scale=GS).run(g, a, m)[:, :4] * 2.0 ** -30
    qf = float64(log.dt).run(g * GS, a.astype(float), m.astype(float))[:, :4]
    ev = [evaluation.evaluate(q, log.q_ref, est_frame="NWU", ref_frame=log.ref_frame,
                              movement=log.movement) for q in (qq, qf)]
    assert abs(ev[0].inclination - ev[1].inclination) < 0.02
    assert abs(ev[0].heading - ev[1].heading) < 0.05, (ev[0].heading, ev[1].heading)


@pytest.mark.skipif(PUBLISHED is None or not os.path.isfile(PUBLISHED),
                    reason="the published BROAD trial 03 (HDF5) is not beside the checkout")
def test_users_firmware_validated_on_a_published_log(tmp_path):
    """The user path of issue 26: a user's firmware around csrc/fixed/robust_q.c (its own API,
    settings in double at init, built with -Os) validated by imufuse.firmware on BROAD trial
    03 as published, the magnetometer in uT brought to counts by counts_for (4096 per uT
    would saturate every reading: the scale halves until the largest is below 2^14 counts),
    on the host and the Cortex-M0."""
    from imufuse.shared.resources import csrc_dir
    from imufuse.firmware import Firmware, counts_for, mag_counts_scale, validate
    from imufuse.io import read_log
    log = read_log(PUBLISHED)
    n = 1500
    params = dict(dt=float(log.dt), gyr_scale=GS)
    ins = counts_for("ahrs", params, (log.gyr[:n], log.acc[:n], log.mag[:n]))
    assert 8192 <= np.abs(ins[2]).max() < 16384 and mag_counts_scale(log.mag[:n]) == 256.0
    (tmp_path / "att.h").write_text(
        '#include <stdint.h>\n#include "robust_q.h"\nextern imf_robust_ahrs_q_t att;\n'
        "void att_init(void);\n"
        "void att_update(const int16_t *g, const int16_t *a, const int16_t *m);\n")
    (tmp_path / "att.c").write_text(
        '#include "att.h"\n#include "robust_q.h"\nimf_robust_ahrs_q_t att;\n'
        "void att_init(void)\n{\n    imf_robust_ahrs_q_settings_t s;\n"
        "    imf_robust_ahrs_q_default_settings(&s);\n"
        f"    s.dt = {float(params['dt'])!r};\n    s.gyr_scale = {float(GS)!r};\n"
        "    (void)imf_robust_ahrs_q_init(&att, &s);\n}\n"
        "void att_update(const int16_t *g, const int16_t *a, const int16_t *m)\n{\n"
        "    imf_robust_ahrs_q_update_v(&att, g, a, m);\n}\n")
    names = reference.RobustAHRSQ.state_names
    arrays = {"q": 4, "s": 4, "c": 4, "f": 3, "v": 3, "p": 3, "b": 3, "lw": 3, "la": 3}
    exprs = [f"=att.x.imu.{k}[{i}]" for k, m in arrays.items() for i in range(m)]
    exprs += ["=att.x.imu.n", "=att.x.imu.n_rest"]
    for member, parts in MAG_LAYOUT:         # u, B4's, B6's (arrays by index)
        exprs += ([f"=att.x.{member}[{i}]" for i in range(len(parts))] if parts
                  else [f"=att.x.{member}"])
    fx = str(csrc_dir() / "fixed")
    want = reference.RobustAHRSQ(**params).run(*ins)
    for target in ("host", "cortex-m0"):
        fw = Firmware([str(tmp_path / "att.c"), os.path.join(fx, "robust_q.c")],
                      headers=["att.h"], include_dirs=[str(tmp_path), fx], init="att_init",
                      update="att_update", state=dict(zip(names, exprs)), cflags=["-Os"])
        v = validate(fw, "RobustAHRSQ", params, ins, target=target)
        assert v.bit_exact, v.text()
        assert np.array_equal(v.got, want.astype(np.int64))
