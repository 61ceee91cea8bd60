"""Firmware against firmware (imufuse.firmware.versus; `imufuse validate ... --against FILE`,
`--against-target`, `--against-cflags`): two runs of the user's own code compared with the
same report and no imufuse reference.

- old against new: a copy of a C++ class is bit-exact with it; a changed gain is a different
  computation from the first sample;
- a float filter against its fixed-point port (imufuse's MadgwickIMU C and MadgwickIMUQ C,
  declared in tests/declared/): compared as orientations, within 0.5 deg (exit 7) and not
  within 0.001 deg (exit 1);
- host against target: the Arduino-style Madgwick class on the 64-bit host against the same
  source on the Cortex-M0 (the `long` pun: tens of degrees); the Cortex-M0 against the M4F
  with -ffp-contract=off: bit-exact;
- -O0 against -O2 (host): bit-exact under the numerical contract; against a build with the
  CPU's fused multiply-add (-mfma -ffp-contract=fast) a rounding difference.
"""
import os
import subprocess
import sys

import pytest

import declared_class

from imufuse import sim
from imufuse.firmware import FirmwareError, Firmware, validate_isolated
from imufuse.firmware.declfile import load_declaration
from imufuse.firmware.versus import compare_firmware

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DECLARED = os.path.join(HERE, "declared")

pytest.importorskip("cffi")
pytestmark = pytest.mark.xdist_group("firmware_versus")


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    return {**os.environ, "IMUFUSE_CACHE": str(tmp_path_factory.mktemp("fw-cache"))}


def _imf(env, *args):
    return subprocess.run([sys.executable, "-m", "imufuse", "validate", *map(str, args)],
                          capture_output=True, text=True, env=env, timeout=900)


CLASS_CPP = declared_class.CPP


def _version(d, cpp=CLASS_CPP):
    return declared_class.write(d, cpp=cpp)


def test_old_against_new(tmp_path, env):
    old = _version(tmp_path / "old")
    same = _version(tmp_path / "same")
    new = _version(tmp_path / "new", CLASS_CPP.replace("k0_ * acc_angle", "(k0_ * 1.01f) * acc_angle"))
    r = _imf(env, "--declaration", same, "--against", old, "--duration", 2)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "no imufuse reference" in r.stdout and "bit-exact: 400 samples" in r.stdout
    r = _imf(env, "--declaration", new, "--against", old, "--duration", 2)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "class: formula" in r.stdout and "first divergence at sample 0" in r.stdout


def test_float_against_its_fixed_point_port(env):
    fixed = os.path.join(DECLARED, "madgwick_imu_fixed.toml")
    flt = os.path.join(DECLARED, "madgwick_imu_float.toml")
    r = _imf(env, "--declaration", fixed, "--against", flt, "--duration", 5, "--within", 0.5)
    assert r.returncode == 7, r.stdout + r.stderr
    assert "compared as orientations" in r.stdout and "within 0.5 deg: max" in r.stdout
    # no ulps between unit quaternions made from an int32 state and a float one (it said
    # "first difference 2.3e+13 ulps"): the difference in degrees of orientation
    assert "ulp" not in r.stdout and "deg of orientation at sample 0" in r.stdout, r.stdout
    r = _imf(env, "--declaration", fixed, "--against", flt, "--duration", 5, "--within", 0.001)
    assert r.returncode == 1, r.stdout + r.stderr


def test_host_against_target(env):
    arduino = os.path.join(DECLARED, "madgwick_arduino.toml")
    r = _imf(env, "--declaration", arduino, "--against-target", "cortex-m0", "--duration", 2)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "firmware B on host" in r.stdout and "firmware A on cortex-m0" in r.stdout
    line = next(ln for ln in r.stdout.splitlines() if "largest orientation difference" in ln)
    assert float(line.split(":")[1].split()[0]) > 5.0, line
    r = _imf(env, "--declaration", arduino, "--target", "cortex-m0", "--against-target",
             "cortex-m4f", "--against-cflags", "-O2 -ffp-contract=off", "--duration", 2)
    assert r.returncode == 0 and "bit-exact" in r.stdout, r.stdout + r.stderr


def _cf_runs(cflags_a, cflags_b):
    src = os.path.join(ROOT, "examples", "firmware-tests", "cf.c")
    inc = os.path.dirname(src)
    d = sim.axis1d("fast", rate=200.0, duration=2.0, seed=3)
    params = dict(dt=0.005, alpha=0.98)
    out = []
    for flags in (cflags_a, cflags_b):
        fw = Firmware([src], headers=["cf.h"], include_dirs=[inc], init="cf_init",
                      update="cf_update", state={"theta": "theta"}, cflags=flags)
        out.append(validate_isolated(fw, "Complementary1D", params, [d.gyr, d.acc_angle],
                                     explain=False))
    return out


def test_o0_against_o2_and_fma():
    a, b = _cf_runs(["-std=c99", "-O0", "-ffp-contract=off"],
                    ["-std=c99", "-O2", "-ffp-contract=off"])
    v = compare_firmware(a, b)
    assert v.bit_exact, v.text()
    a, b = _cf_runs(["-std=c99", "-O2", "-ffp-contract=off"],
                    ["-std=c99", "-O2", "-mfma", "-ffp-contract=fast"])
    v = compare_firmware(a, b)
    assert not v.bit_exact
    assert v.classification is not None and v.classification.kind == "rounding", v.text()


def test_runs_of_different_lengths_or_without_a_quaternion_are_refused():
    a, b = _cf_runs(["-std=c99", "-O2"], ["-std=c99", "-O2"])
    b.got = b.got[:-1]
    with pytest.raises(FirmwareError, match="samples"):
        compare_firmware(a, b)
    a, b = _cf_runs(["-std=c99", "-O2"], ["-std=c99", "-O2"])
    b.got = b.got.astype("float64")          # another type: orientations, and there are none
    with pytest.raises(FirmwareError, match="no quaternion"):
        compare_firmware(a, b)


def test_declarations_load_with_paths_relative_to_their_file():
    d = load_declaration(os.path.join(DECLARED, "madgwick_imu_fixed.toml"))
    assert all(os.path.isfile(s) for s in d.firmware.sources)


def test_the_testing_api(tmp_path):
    """imufuse.testing: validate_declared (a C++ class from its declaration; a float and a
    fixed-point port) and against (firmware against firmware, within a tolerance)."""
    from imufuse.testing import against, validate_declared
    old = _version(tmp_path / "old")
    new = _version(tmp_path / "new", CLASS_CPP.replace("k0_ * acc_angle", "(k0_ * 1.01f) * acc_angle"))
    a, b = validate_declared(str(old), duration=2.0), validate_declared(str(new), duration=2.0)
    a.assert_bit_exact()
    with pytest.raises(AssertionError, match="not bit-exact"):
        b.assert_bit_exact()
    with pytest.raises(AssertionError):
        against(a, b).assert_bit_exact()
    against(a, a).assert_bit_exact()
    flt = validate_declared(os.path.join(DECLARED, "madgwick_imu_float.toml"), duration=5.0)
    fix = validate_declared(os.path.join(DECLARED, "madgwick_imu_fixed.toml"), duration=5.0)
    r = against(flt, fix, within=0.5)
    assert r.verdict == "within" and 0 < r.max_angle_deg < 0.5
    r.assert_passed()
    with pytest.raises(AssertionError):
        against(flt, fix, within=1e-4).assert_passed()
