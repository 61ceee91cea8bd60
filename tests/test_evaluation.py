"""imufuse.evaluation against an independent implementation of the BROAD
metrics written with scipy.spatial.transform (rotation matrices and
swing-twist geometry, no quaternion component formulas)."""
import dataclasses
import math
import os

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as R

from imufuse import evaluation as ev, sim
from imufuse.evaluation import prepare_reference
from broad_data import BROAD, SKIP_REASON

# ../shared beside the checkout (main and CI), or two levels up (a worktree)



def _rot(q_wxyz):
    return R.from_quat(np.asarray(q_wxyz)[:, [1, 2, 3, 0]])


# earth-side maps to ENU, from their definitions as axis permutations
NWU_TO_ENU = R.from_euler("z", 90, degrees=True)
NED_TO_ENU = R.from_matrix([[0, 1, 0], [1, 0, 0], [0, 0, -1]])


def independent(q_est, q_ref, est_map, ref_map, offset_removal=False):
    """total, heading, inclination in degrees per sample, from rotations only."""
    E = (est_map * _rot(q_est)) * (ref_map * _rot(q_ref)).inv()
    z = np.array([0.0, 0.0, 1.0])
    Ez = E.apply(z)
    incl = np.degrees(np.arccos(np.clip(Ez @ z, -1, 1)))
    # swing: the shortest rotation taking z to E z; twist = swing^-1 E is about z
    axis = np.cross(z, Ez)
    nrm = np.linalg.norm(axis, axis=1, keepdims=True)
    axis = np.where(nrm > 1e-15, axis / np.where(nrm > 0, nrm, 1), 0.0)
    swing = R.from_rotvec(axis * np.radians(incl)[:, None])
    twist = swing.inv() * E
    tv = twist.as_rotvec()
    assert np.allclose(tv[:, :2], 0, atol=1e-9)        # really a rotation about z
    signed = tv[:, 2]
    if offset_removal:
        off = math.atan2(np.mean(np.sin(signed)), np.mean(np.cos(signed)))
        E = R.from_euler("z", -off) * E
        signed = np.angle(np.exp(1j * (signed - off)))
    head = np.degrees(np.abs(signed))
    total = np.degrees(E.magnitude())
    return total, head, incl


def rms(x):
    return math.sqrt(np.mean(np.asarray(x) ** 2))


@pytest.fixture(scope="module")
def pair():
    rng = np.random.default_rng(3)
    n = 500
    ref = R.random(n, random_state=rng)
    # estimate = reference perturbed by errors of up to ~60 deg, plus a heading offset
    pert = R.from_rotvec(rng.normal(scale=0.4, size=(n, 3)))
    est = R.from_euler("z", 0.3) * pert * ref
    wxyz = lambda r: r.as_quat()[:, [3, 0, 1, 2]]  # noqa: E731
    return wxyz(est), wxyz(ref)


@pytest.mark.parametrize("frame,emap", [("ENU", R.identity()), ("NWU", NWU_TO_ENU),
                                       ("NED", NED_TO_ENU)])
@pytest.mark.parametrize("offset", [False, True])
def test_metrics_equal_an_independent_implementation(pair, frame, emap, offset):
    est_enu, ref = pair
    # express the estimate in `frame` so that mapping it back gives est_enu
    est = (emap.inv() * _rot(est_enu)).as_quat()[:, [3, 0, 1, 2]]
    got = ev.evaluate(est, ref, est_frame=frame, ref_frame="ENU",
                      remove_heading_offset=offset)
    t, h, i = independent(est, ref, emap, R.identity(), offset)
    assert got.n == len(ref)
    assert got.total == pytest.approx(rms(t), rel=1e-9)
    assert got.heading == pytest.approx(rms(h), rel=1e-9)
    assert got.inclination == pytest.approx(rms(i), rel=1e-9)
    assert np.allclose(got.per_sample["inclination"], i, atol=1e-6)
    if offset:
        assert got.heading_offset == pytest.approx(math.degrees(0.3), abs=3)
    else:
        assert got.heading_offset == 0.0


def test_heading_offset_removal_removes_a_constant_offset(pair):
    _, ref = pair
    est = (R.from_euler("z", 37, degrees=True) * _rot(ref)).as_quat()[:, [3, 0, 1, 2]]
    plain = ev.evaluate(est, ref, est_frame="ENU")
    assert plain.heading == pytest.approx(37, abs=1e-9)
    assert plain.inclination == pytest.approx(0, abs=1e-6)
    off = ev.evaluate(est, ref, est_frame="ENU", remove_heading_offset=True)
    assert off.heading_offset == pytest.approx(37, abs=1e-9)
    assert off.heading == pytest.approx(0, abs=1e-6)
    assert off.total == pytest.approx(0, abs=1e-6)


def test_reference_frames_and_directions(pair):
    est_enu, ref_enu = pair
    for frame, m in (("NWU", NWU_TO_ENU), ("NED", NED_TO_ENU)):
        ref_f = (m.inv() * _rot(ref_enu))
        ref_s2e = ref_f.as_quat()[:, [3, 0, 1, 2]]
        ref_e2s = ref_f.inv().as_quat()[:, [3, 0, 1, 2]]
        want = ev.evaluate(est_enu, ref_enu, est_frame="ENU")
        a = ev.evaluate(est_enu, ref_s2e, est_frame="ENU", ref_frame=frame)
        b = ev.evaluate(est_enu, ref_e2s, est_frame="ENU", ref_frame=frame,
                        ref_direction="earth-to-sensor")
        for g in (a, b):
            for k in ev.METRICS:
                assert getattr(g, k) == pytest.approx(getattr(want, k), rel=1e-9)
        # the wrong frame is visibly wrong (the 82-91 deg heading errors)
        assert ev.evaluate(est_enu, ref_s2e, est_frame="ENU").heading > 40
    # to_enu and from_enu are inverses
    for f in ev.FRAMES:
        for d in ev.DIRECTIONS:
            back = ev.from_enu(ev.to_enu(est_enu, f, d), f, d)
            assert np.allclose(back, est_enu, atol=1e-12)


def test_nan_rows_and_movement_mask(pair):
    est, ref = pair
    ref = ref.copy()
    ref[10:30] = np.nan
    mov = np.ones(len(ref), dtype=bool)
    mov[:20] = False          # 10 of the NaN rows are outside the mask
    mov[400:] = False
    got = ev.evaluate(est, ref, est_frame="ENU", movement=mov)
    use = mov & np.all(np.isfinite(ref), axis=1)
    t, h, i = independent(est[use], ref[use], R.identity(), R.identity())
    assert got.n == use.sum() == 370
    assert got.n_outside_mask == 120 and got.n_ref_nan == 10
    assert got.total == pytest.approx(rms(t), rel=1e-9)
    assert got.heading == pytest.approx(rms(h), rel=1e-9)
    assert got.inclination == pytest.approx(rms(i), rel=1e-9)
    assert np.all(np.isnan(got.per_sample["total"][~use]))
    assert "10 with a NaN reference" in got.summary()


def test_nothing_to_evaluate_and_broken_estimates(pair):
    est, ref = pair
    none = ev.evaluate(est, np.full_like(ref, np.nan), est_frame="ENU")
    assert none.n == 0 and math.isnan(none.total) and not none.ok
    bad = est.copy()
    bad[5] = np.nan
    b = ev.evaluate(bad, ref, est_frame="ENU")
    assert b.n_est_nan == 1 and math.isnan(b.total) and not b.ok


@pytest.mark.parametrize("kw,words", [
    (dict(est_frame="XYZ"), ["est_frame", "NWU"]),
    (dict(ref_direction="up"), ["direction", "sensor-to-earth"]),
    (dict(movement=np.ones(3, bool)), ["movement", "shape"]),
])
def test_bad_arguments(pair, kw, words):
    est, ref = pair
    with pytest.raises(ValueError) as e:
        ev.evaluate(est, ref, **kw)
    for w in words:
        assert w in str(e.value)
    with pytest.raises(ValueError, match="shape"):
        ev.evaluate(est[:, :3], ref)
    with pytest.raises(ValueError, match="lengths"):
        ev.evaluate(est[:5], ref)


def test_mean_over_trials(pair):
    est, ref = pair
    a = ev.evaluate(est, ref, est_frame="ENU")
    b = ev.evaluate(est[:100], ref[:100], est_frame="ENU")
    nothing = ev.evaluate(est, np.full_like(ref, np.nan), est_frame="ENU")
    m = ev.mean_over_trials([a, b, nothing])
    assert m["total"] == pytest.approx((a.total + b.total) / 2)


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_a_real_trial_against_the_independent_implementation():
    """A filter's NWU output on a real BROAD trial (ENU reference with
    dropouts, movement mask): the module and the independent code agree."""
    import imufuse_c
    z = np.load(os.path.join(BROAD, "03_undisturbed_slow_rotation_C.npz"))
    n = 20000
    f = imufuse_c.MadgwickAHRS(dt=1 / float(z["rate"]), beta=0.1)
    q = f.run(z["gyr"][:n], z["acc"][:n], z["mag"][:n])
    ref, mov = z["quat_ref"][:n], z["movement"][:n]
    got = ev.evaluate(q, ref, est_frame="NWU", ref_frame="ENU", movement=mov)
    use = mov & np.all(np.isfinite(ref), axis=1)
    assert 0 < got.n == use.sum() < n
    t, h, i = independent(q[use], ref[use], NWU_TO_ENU, R.identity())
    assert got.total == pytest.approx(rms(t), rel=1e-9)
    assert got.heading == pytest.approx(rms(h), rel=1e-9)
    assert got.inclination == pytest.approx(rms(i), rel=1e-9)


def test_blocks_and_per_sample_do_not_change_the_result(pair):
    est, ref = pair
    ref = ref.copy()
    ref[::7] = np.nan
    mov = np.arange(len(ref)) % 5 != 0
    a = ev.evaluate(est, ref, est_frame="ENU", movement=mov, remove_heading_offset=True)
    b = ev.evaluate(est, ref, est_frame="ENU", movement=mov, remove_heading_offset=True,
                    chunk=7, per_sample=False)
    assert b.per_sample == {}
    for k in ev.METRICS:
        assert getattr(b, k) == pytest.approx(getattr(a, k), rel=1e-12)
    assert (a.n, a.n_ref_nan, a.n_outside_mask) == (b.n, b.n_ref_nan, b.n_outside_mask)
    assert b.heading_offset == pytest.approx(a.heading_offset, rel=1e-12)


def test_zero_reference_rows_are_excluded_and_counted_like_nan_rows():
    """A zero reference row (a 'no tracking' marker) has no orientation: excluded and counted,
    never a NaN score with ok=True; a zero estimate row makes the evaluation not ok."""
    from imufuse.evaluation import evaluate
    q = np.tile([1.0, 0.0, 0.0, 0.0], (10, 1))
    r = q.copy()
    r[3] = 0.0
    r[7] = np.nan
    e = evaluate(q, r, est_frame="NWU", ref_frame="NWU")
    assert (e.n, e.n_ref_nan, e.total) == (8, 2, 0.0) and e.ok
    q[5] = 0.0
    e = evaluate(q, r, est_frame="NWU", ref_frame="NWU")
    assert e.n_est_nan == 1 and not e.ok


def test_reference_rows_whose_norm_overflows_are_excluded():
    """A reference row (1e308, 1e308, 0, 0) has no orientation (its norm overflows): it is
    excluded and counted like a NaN row, not scored as 180 degrees."""
    import warnings
    q = np.tile([1.0, 0.0, 0.0, 0.0], (20, 1))
    r = q.copy()
    r[3] = [1e308, 1e308, 0.0, 0.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        e = ev.evaluate(q, r)
    assert e.n == 19 and e.inclination == 0.0


def test_a_sealed_reference_is_sealed_once():
    """Sealed again for its log, a sealed Reference is itself (tune scores every group of
    sets on a log against one copy); its fields cannot be rebound, and arrays made writeable
    again are copied and checked again."""
    d = sim.imu("fast", rate=200.0, duration=2.0, seed=11)
    n = len(d.gyr)
    sealed = prepare_reference(d.q_true, ref_frame="NWU").sealed(n)
    assert sealed.sealed(n) is sealed
    with pytest.raises(AttributeError, match="sealed Reference cannot change"):
        sealed.n = 0
    with pytest.raises(ValueError, match="a reference of"):
        sealed.sealed(n - 1)
    sealed.use.flags.writeable = True
    sealed.use[:] = 2
    with pytest.raises(ValueError, match="0 or 1 only"):
        sealed.sealed(n)
    # an owner may resize its read-only arrays: then it is checked whole (C read past them)
    other = prepare_reference(d.q_true, ref_frame="NWU").sealed(n)
    other.r.resize((2, 4))
    other.use.resize((2,))
    with pytest.raises(ValueError, match="a reference of 2 samples"):
        other.sealed(n)
    # dataclasses.replace gives a copy that is checked whole when it is sealed
    again = prepare_reference(d.q_true, ref_frame="NWU").sealed(n)
    with pytest.raises(ValueError, match="Reference.n is 5"):
        dataclasses.replace(again, n=5).sealed(n)
    copy = dataclasses.replace(again)
    assert copy.sealed(n) is not copy and copy.sealed(n).n == again.n
