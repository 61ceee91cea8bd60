"""Firmware validated from a declaration alone (imufuse.firmware.declared): no shim, no edit
of the user's code.

- a C++ class with private state, initialised by a method, is bit-exact with Kalman1D;
- imufuse's own C API (a settings struct, init, update) and a fixed-point filter on int16
  counts (vectors as int16_t arrays) are bit-exact, as declared in tests/declared/;
- an Arduino-style Madgwick class (tests/declared/MadgwickAHRS.cpp: deg/s inputs,
  begin(rate), private q0..q3, invSqrt through `long`) runs as it is: on this 64-bit host
  the type pun through `long` (8 bytes) makes it diverge by tens of degrees; with the pun
  fixed by the user it is a different computation (a 0.0174533 deg->rad factor, two Newton
  steps) within 0.1 deg of MadgwickAHRS;
- the command line (`imufuse validate --declaration FILE`) and the declaration's mistakes,
  each one line naming the file and the key.
"""
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

import declared_class

from imufuse import sim
from imufuse.catalogue import inputs_for, resolve_params
from imufuse.firmware import FirmwareError, counts_for, validate_isolated
from imufuse.firmware.declfile import load_declaration

pytest.importorskip("cffi")

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DECLARED = os.path.join(HERE, "declared")
CSRC = os.path.join(ROOT, "csrc")


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return str(tmp_path_factory.mktemp("fw-cache"))


def _run(path, cache, kind, seconds=3.0, source_dir=None, counts=False):
    d = load_declaration(path, source_dir=source_dir, cache_dir=cache)
    s = (sim.axis1d("fast", rate=200.0, duration=seconds, seed=3) if kind == "1d" else
         sim.imu("fast", rate=200.0, duration=seconds, seed=3))
    p = resolve_params(d.filter, s.dt, d.params)
    inputs = [s.gyr, s.acc_angle] if kind == "1d" else inputs_for(kind, s)
    if counts:
        inputs = counts_for(kind, p, inputs)
    return validate_isolated(d.firmware, d.filter, p, inputs)


CLASS_CPP, CLASS_TOML = declared_class.CPP, declared_class.TOML


def _class(tmp_path, toml=CLASS_TOML, cpp=CLASS_CPP):
    return declared_class.write(tmp_path, toml=toml, cpp=cpp)


def test_cpp_class_with_private_state_is_bit_exact(tmp_path, cache):
    v = _run(_class(tmp_path), cache, "1d")
    assert v.bit_exact, v.text()
    assert "-fno-access-control" in v.cflags


def test_cpp_class_planted_change_is_found(tmp_path, cache):
    v = _run(_class(tmp_path, cpp=CLASS_CPP.replace("k0_ * acc_angle", "k0_ * acc_angle * 1.0001f")),
             cache, "1d")
    assert not v.bit_exact and v.comparison.first_sample == 0


def test_plain_c_api_through_a_declaration(cache):
    v = _run(os.path.join(DECLARED, "csrc_madgwick.toml"), cache, "ahrs", source_dir=CSRC)
    assert v.bit_exact, v.text()


def test_fixed_point_counts_through_a_declaration(cache):
    v = _run(os.path.join(DECLARED, "csrc_madgwick_q.toml"), cache, "imu",
             source_dir=os.path.join(CSRC, "fixed"), counts=True)
    assert v.bit_exact, v.text()
    # int32_t words, compared as integers (widened to int64), reported in their own type
    assert v.comparison.dtype == "int32" and "(int32)" in v.text(), v.text()


def _arduino_copy(tmp_path, fix_pun):
    for f in ("MadgwickAHRS.h", "MadgwickAHRS.cpp", "madgwick_arduino.toml"):
        shutil.copy(os.path.join(DECLARED, f), tmp_path / f)
    if fix_pun:
        p = tmp_path / "MadgwickAHRS.cpp"
        text = p.read_text()
        old = ("    long i = *(long *)&y;\n    i = 0x5f3759df - (i >> 1);\n"
               "    y = *(float *)&i;\n")
        assert old in text
        p.write_text("#include <string.h>\n#include <stdint.h>\n" + text.replace(
            old, "    int32_t i;\n    memcpy(&i, &y, 4);\n    i = 0x5f3759df - (i >> 1);\n"
                 "    memcpy(&y, &i, 4);\n"))
    return tmp_path / "madgwick_arduino.toml"


def test_arduino_style_class_as_published_runs_and_diverges(tmp_path, cache):
    """As written (`long` is 8 bytes here), the fast inverse square root reads past the
    float: tens of degrees off from the first sample."""
    v = _run(_arduino_copy(tmp_path, fix_pun=False), cache, "ahrs", seconds=10.0)
    assert not v.bit_exact
    assert v.comparison.first_sample == 0
    assert v.max_angle_deg is not None and v.max_angle_deg > 10.0, v.text()


def test_arduino_style_class_with_the_pun_fixed_is_a_close_variant(tmp_path, cache):
    v = _run(_arduino_copy(tmp_path, fix_pun=True), cache, "ahrs", seconds=10.0)
    assert not v.bit_exact                  # a different computation ...
    assert v.classification is not None and v.classification.kind == "formula", v.text()
    assert v.max_angle_deg is not None and v.max_angle_deg < 0.1, v.text()   # ... close
    assert not [c for c in v.causes if c.what in ("undefined behaviour", "data model")], v.text()


def test_cli_declaration(tmp_path):
    env = {**os.environ, "IMUFUSE_CACHE": str(tmp_path / "cache")}
    path = _class(tmp_path)
    r = subprocess.run([sys.executable, "-m", "imufuse", "validate", "--declaration", str(path),
                        "--duration", "2"], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0 and "bit-exact" in r.stdout, r.stdout + r.stderr
    # --param on top of the file's params: k0 differs from the firmware's begin(k0)? no: the
    # firmware takes ${k0} from the same parameters, so it stays bit-exact
    r = subprocess.run([sys.executable, "-m", "imufuse", "validate", "--declaration", str(path),
                        "--duration", "2", "-p", "k0=0.05"], capture_output=True, text=True,
                       env=env, timeout=300)
    assert r.returncode == 0 and "k0=0.05" in r.stdout, r.stdout + r.stderr
    # sources given besides the file: a usage error
    r = subprocess.run([sys.executable, "-m", "imufuse", "validate", "--declaration", str(path),
                        str(tmp_path / "att.cpp")], capture_output=True, text=True, env=env,
                       timeout=300)
    assert r.returncode == 2 and "--declaration" in r.stderr


@pytest.mark.parametrize("edit,word", [
    (("[update]", "[updates]"), "unknown table [updates]"),
    (('call = "fw.step', 'cal = "fw.step'), "[update] cal: unknown key"),
    (("${k0}", "${k9}"), "${k9} is neither a parameter"),
    (("${rate}, ${angle}", "${rate:furlongs}, ${angle}"), "unit 'furlongs'"),
    (("${rate}, ${angle}", "${gx}, ${angle}"), "'gx' is not an input of a 1d filter"),
    (("theta = ", "omega = "), "[state] omega: Kalman1D has no state variable"),
    (('name = "Kalman1D"', 'name = "Kalman9D"'), "[filter] name"),
    (('sources = ["att.cpp"]', 'sources = ["gone.cpp"]'), "source file not found"),
    (("[state]", "[state\n"), "not TOML"),
])
def test_declaration_mistakes_are_named(tmp_path, cache, edit, word):
    path = _class(tmp_path, toml=CLASS_TOML.replace(*edit))
    with pytest.raises(FirmwareError) as e:
        _run(path, cache, "1d", seconds=0.5)
    assert word in str(e.value), str(e.value)


def test_a_vector_needs_its_element_type(tmp_path, cache):
    toml = (CLASS_TOML.replace('name = "Kalman1D"', 'name = "MadgwickIMU"')
            .replace("params = { k0 = 0.02 }", "")
            .replace("${rate}, ${angle}, ${dt}", "${gyr}, ${ax}, ${dt}")
            .replace('theta = "fw.theta_"', 'q0 = "fw.theta_"'))
    path = _class(tmp_path, toml=toml.replace("fw.begin(${k0})", "fw.begin(${beta})"))
    with pytest.raises(FirmwareError, match=r"needs its element type"):
        _run(path, cache, "imu", seconds=0.5)


def test_units_convert_as_declared(tmp_path, cache):
    """${rate:deg/s} passes degrees, which a firmware in deg/s turns back into radians: a
    rounding-level difference only (no factor of 57 anywhere)."""
    cpp = CLASS_CPP.replace("float pred = theta_ + gyro * dt;",
                            "float pred = theta_ + (gyro * 0.017453292519943295f) * dt;")
    path = _class(tmp_path, cpp=cpp, toml=CLASS_TOML.replace("${rate}", "${rate:deg/s}"))
    v = _run(path, cache, "1d")
    got, want = v.got[:, 0].astype(np.float64), v.want[:, 0].astype(np.float64)
    assert np.max(np.abs(got - want)) < 1e-4
