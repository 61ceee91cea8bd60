"""RobustAHRS B6 on a magnetometer as it comes off the board: the BROAD development trials
with a hard-iron offset of tens of uT added to the readings (the stored offset 0, as after
a first power-up), and with soft iron as well (scale errors of +-10 %, a few degrees of
skew), which B6 does not model (docs/recommended-ahrs.md, "A large offset").

Heading and tilt RMSE (BROAD's metrics) over the movement after its first 60 s (the
learning phase). Before the early use of the estimate and B4's new reference after a change
of the offset in use (measured on the same trials): 47 uT 57.0 deg mean (worst 143),
21 uT 12.5 (27.0), 47 uT with 10 % soft iron 105.6 (145).
"""
import glob
import os

import numpy as np
import pytest

import imufuse_c
from imufuse.evaluation import evaluate
from broad_data import BROAD, SKIP_REASON

#: the distortions m' = S m + o: S symmetric near the identity, o in uT
OFFSET_47 = (np.eye(3), np.array([25.0, -40.0, 10.0]))
OFFSET_21 = (np.eye(3), np.array([-12.0, 8.0, -15.0]))
SOFT_10 = (np.array([[1.10, 0.04, -0.03], [0.04, 0.90, 0.05], [-0.03, 0.05, 1.02]]),
           np.array([25.0, -40.0, 10.0]))
LEARN = 60.0   # s of movement before the errors count


def run(d, distortion=None):
    mag = d["mag"] if distortion is None else d["mag"] @ distortion[0].T + distortion[1]
    f = imufuse_c.RobustAHRS(1.0 / float(d["rate"]))
    S = f.run(d["gyr"], d["acc"], mag)
    mv = np.asarray(d["movement"], bool).copy()
    k0 = int(np.argmax(mv))
    mv[:k0 + int(LEARN * float(d["rate"]))] = False
    e = evaluate(S[:, :4], d["quat_ref"], movement=mv)
    return S, f.state_names, e.inclination, e.heading


@pytest.fixture(scope="module")
def trials():
    return [(p, dict(np.load(p))) for p in sorted(glob.glob(os.path.join(BROAD, "*.npz")))]


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_broad_with_a_large_offset(trials):
    rows = {}
    early = 0
    for path, d in trials:
        _, _, t0, h0 = run(d)
        r = [t0, h0]
        for dist in (OFFSET_47, OFFSET_21):
            S, names, t, h = run(d, dist)
            u = S[:, [names.index(n) for n in ("ux", "uy", "uz")]]
            k = int(np.argmax(np.any(u != 0.0, axis=1)))
            # the offset in use first left the stored one (0) before the estimate was
            # trusted (standard deviation 0.01): the norm said the stored one was wrong
            early += bool(u[k].any() and S[k, names.index("m_std")] >= 0.01)
            r += [t, h]
        rows[os.path.basename(path)[:2]] = r
    print("\ntrial: tilt/heading undistorted, 47 uT, 21 uT")
    for k, r in rows.items():
        print(f"{k}: " + "  ".join(f"{r[i]:.3f}/{r[i + 1]:.2f}" for i in (0, 2, 4)))
    m = np.mean(list(rows.values()), axis=0)
    print("mean: " + "  ".join(f"{m[i]:.3f}/{m[i + 1]:.2f}" for i in (0, 2, 4)))
    assert early >= 3                                    # 6 of the 14 runs when measured
    # 47 uT: 2.95 deg mean (57.0 before), 21 uT: 5.45 (12.5); tilt unchanged within 0.02
    assert m[3] < 3.5 and m[5] < 6.5, m
    assert m[2] < m[0] + 0.02 and m[4] < m[0] + 0.02, m
    assert max(r[3] for r in rows.values()) < 12.0       # 143 before (trial 31)


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_broad_with_soft_iron_is_not_learnt(trials):
    """Soft iron of 10 % is beyond B6's model: the offset is still replaced (105.6 deg mean
    before), but the heading keeps errors of several degrees (the limit the docs state)."""
    heads = [run(d, SOFT_10)[3] for _, d in trials]
    print(f"\nsoft iron 10 % and 47 uT: heading mean {np.mean(heads):.2f}, worst "
          f"{max(heads):.2f} deg")
    assert np.mean(heads) < 25.0                         # 17.1 when measured
