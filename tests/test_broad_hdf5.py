"""BROAD trials as published (HDF5: imu_gyr rad/s, imu_acc m/s^2, imu_mag uT, opt_quat ENU,
opt_pos, movement, and the rate as the file attribute `sampling_rate`): read as they are, with
only the datasets a log uses loaded. Checked on a file written with every key and attribute of
the real layout, and on the real published trial where it is present, against the same trial
converted to NPZ by the dataset's authors."""
import os
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest

from broad_data import BROAD
from imufuse.io import read_log

h5py = pytest.importorskip("h5py", reason="h5py is in the test extra (pip install 'imufuse[test]')")

PUBLISHED = os.path.join(BROAD, "published", "03_undisturbed_slow_rotation_C.hdf5") if BROAD else None


def _write(path, n=2000, rate=285.7142857142857, extra_big=False):
    rng = np.random.default_rng(5)
    with h5py.File(path, "w") as f:
        f.attrs["info"] = "Berlin Robust Orientation Estimation Assessment Dataset (BROAD) ..."
        f.attrs["sampling_rate"] = rate
        f["imu_gyr"] = rng.normal(0, 0.3, (n, 3))
        f["imu_acc"] = rng.normal(0, 0.1, (n, 3)) + [0, 0, 9.81]
        f["imu_mag"] = rng.normal(0, 1, (n, 3)) + [20, 0, -40]
        q = rng.normal(size=(n, 4))
        f["opt_quat"] = q / np.linalg.norm(q, axis=1, keepdims=True)
        f["opt_pos"] = rng.normal(size=(n, 3))
        f["movement"] = rng.random(n) > 0.3
        if extra_big:     # declared, never written: 8 GB if a reader loaded it
            f.create_dataset("video", shape=(10 ** 9,), dtype="f8", chunks=(1 << 16,))
    return path


def test_published_layout(tmp_path):
    p = _write(str(tmp_path / "trial.hdf5"))
    log = read_log(p)
    assert log.dt == pytest.approx(1 / 285.7142857142857) and len(log) == 2000
    assert log.ref_frame == "ENU" and log.q_ref.shape == (2000, 4)
    with h5py.File(p) as f:
        assert np.array_equal(log.acc, f["imu_acc"][:] * (1.0 / 9.80665))   # m/s^2 -> g
        assert np.array_equal(log.gyr, f["imu_gyr"][:])
        assert np.array_equal(log.movement, f["movement"][:])


def test_unused_datasets_are_not_loaded(tmp_path):
    p = _write(str(tmp_path / "big.hdf5"), extra_big=True)
    tracemalloc.start()
    try:
        read_log(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50e6


def test_not_a_broad_file_names_what_is_there(tmp_path):
    p = str(tmp_path / "other.hdf5")
    with h5py.File(p, "w") as f:
        f["temperature"] = np.zeros(3)
    with pytest.raises(Exception, match="expected arrays gyr and acc.*found temperature"):
        read_log(p)


@pytest.mark.skipif(PUBLISHED is None or not os.path.isfile(PUBLISHED),
                    reason="the published BROAD trial 03 (HDF5) is not beside the checkout")
def test_real_published_trial_equals_its_npz(tmp_path):
    out = {}
    for name, src in (("h5", PUBLISHED), ("npz", os.path.join(BROAD, "03_undisturbed_slow_rotation_C.npz"))):
        p = subprocess.run([sys.executable, "-m", "imufuse", "run", src, "-f", "MadgwickAHRS", "-o",
                            str(tmp_path / f"{name}.npz")], capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        assert "against the log's reference q (ENU)" in p.stderr
        out[name] = np.load(tmp_path / f"{name}.npz")
    assert all(np.array_equal(out["h5"][k], out["npz"][k]) for k in out["npz"].files)


def _npz(path, **arrays):
    base = dict(gyr=np.zeros((50, 3)), acc=np.tile([0, 0, 9.81], (50, 1)), rate=np.array(100.0))
    base.update(arrays)
    np.savez(path, **{k: v for k, v in base.items() if v is not None})
    return str(path)


@pytest.mark.parametrize("arrays, msg", [
    (dict(rate=np.array([])), "rate has 0 values"),
    (dict(rate=np.array(0.0)), "rate is 0.0"),
    (dict(rate=np.array(np.nan)), "rate is nan"),
    (dict(gyr=np.array(1.0)), "array gyr has shape ()"),
    (dict(gyr=np.array([["a", "b", "c"]] * 50)), "array gyr holds <U1 values"),
    # gyr transposed read as 3 samples: "array acc has shape (50, 3); expected (3, 3)"
    (dict(gyr=np.zeros((3, 50))), "array gyr has shape (3, 50); expected (N, 3), one row per "
     "sample (transposed?)"),
    # one array short: the other blamed, "array acc has shape (50, 3); expected (40, 3)"
    (dict(gyr=np.zeros((40, 3))), "array acc has 50 rows, gyr 40: every array holds one row "
     "per sample"),
    # the file's own name of the array, not "quat"
    (dict(quat_ref=np.zeros((50, 3))), "array quat_ref has shape (50, 3); expected (50, 4)"),
])
def test_bad_npz_contents_are_data_errors(tmp_path, arrays, msg):
    """exit 4 naming the file, the key and what was expected: never an internal error."""
    p = _npz(tmp_path / "bad.npz", **arrays)
    r = subprocess.run([sys.executable, "-m", "imufuse", "run", p, "-f", "MadgwickIMU"],
                       capture_output=True, text=True)
    assert r.returncode == 4 and msg in r.stderr and "bad.npz" in r.stderr, r.stderr


def test_bad_hdf5_datasets_are_data_errors(tmp_path):
    p = _write(str(tmp_path / "null.hdf5"))
    with h5py.File(p, "a") as f:
        del f["imu_mag"]
        f.create_dataset("imu_mag", data=h5py.Empty("f8"))         # a null dataspace
    q = _write(str(tmp_path / "link.hdf5"))
    with h5py.File(q, "a") as f:
        del f["imu_mag"]
        f["imu_mag"] = h5py.ExternalLink(str(tmp_path / "missing.hdf5"), "/x")
    for path in (p, q):
        r = subprocess.run([sys.executable, "-m", "imufuse", "run", path, "-f", "MadgwickIMU"],
                           capture_output=True, text=True)
        assert r.returncode == 4 and "imu_mag" in r.stderr and "internal" not in r.stderr, r.stderr
