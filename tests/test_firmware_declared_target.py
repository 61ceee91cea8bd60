"""C++ and declared firmware on the emulated MCUs (`imufuse validate --declaration F --target T`):
built by the target's g++ with its default flags, linked with the harness, run sample by sample.

- a C++ class with private state (tests/test_firmware_declared.py's Attitude) is bit-exact on
  the Cortex-M0 and the ATmega328P with the default flags, and on the Cortex-M4F with
  -ffp-contract=off; without it, the M4F's fused multiply-add is named;
- a C++ firmware with a static object whose constructor sets its state, and a build with
  exceptions on (-fexceptions: the unwinder's tables need __exidx_start/__exidx_end), link and
  run on the Arm targets: the constructor has run before the first sample;
- the Arduino-style Madgwick class (tests/declared/MadgwickAHRS.cpp, `long` type pun included)
  validates with the default flags on all three targets: 32-bit `long` there, so the pun works
  and it is a close variant of MadgwickAHRS (within 0.01 deg).
"""
import os
import sys
import textwrap

import pytest

from imufuse import sim
from imufuse.catalogue import inputs_for, resolve_params
from imufuse.firmware import validate_isolated
from imufuse.firmware.declfile import load_declaration
from imufuse.mcu import ensure_toolchains

HERE = os.path.dirname(os.path.abspath(__file__))
DECLARED = os.path.join(HERE, "declared")
TARGETS = ("cortex-m4f", "cortex-m0", "atmega328p")

pytestmark = pytest.mark.xdist_group("declared_target")


@pytest.fixture(scope="module", autouse=True)
def _toolchains():
    missing = ensure_toolchains(("m4f", "m0", "avr"))
    assert not missing, f"MCU toolchains missing: {missing}"


CLASS_H = textwrap.dedent("""
    class Attitude {
    public:
        Attitude() : theta_(0.0f), k0_(0.0f), omk0_(1.0f), boot_(0.0f) {}
        void begin(float k0) { k0_ = k0; omk0_ = 1.0f - k0; theta_ = 0.0f; }
        void step(float gyro, float acc_angle, float dt);
        float boot_;
    private:
        float theta_, k0_, omk0_;
    };
""")
CLASS_CPP = textwrap.dedent("""
    #include <math.h>
    #include "att.hpp"
    void Attitude::step(float gyro, float acc_angle, float dt)
    {
        if (!__builtin_isfinite(gyro) || !__builtin_isfinite(acc_angle)) return;
        float pred = theta_ + gyro * dt;
        float th = omk0_ * pred + k0_ * acc_angle;
        if (__builtin_isfinite(th)) theta_ = th + boot_;
    }
""")
# a static object whose constructor must have run before the first sample: it sets the
# value init turns into the offset the update adds (0 when it ran; 1 when it did not, so a
# missing run diverges); the volatile keeps the compiler from initialising it statically
STATIC_CPP = textwrap.dedent("""
    #include "att.hpp"
    struct Boot { float one; Boot() { volatile float v = 1.0f; one = v; } };
    static Boot boot_object;
    float boot_value() { return boot_object.one; }
""")
TOML = textwrap.dedent("""
    [firmware]
    sources = SOURCES

    [filter]
    name = "Kalman1D"
    params = { k0 = 0.02 }

    [object]
    type = "Attitude"
    init = INIT

    [update]
    call = "fw.step(${rate}, ${angle}, ${dt})"

    [state]
    theta = "fw.theta_"
""")


def _class(tmp_path, static=False):
    (tmp_path / "att.hpp").write_text(CLASS_H)
    (tmp_path / "att.cpp").write_text(CLASS_CPP)
    sources = '["att.cpp"]'
    init = '["fw.begin(${k0})", "fw.boot_ = 1.0f"]' if static else '["fw.begin(${k0})"]'
    if static:
        (tmp_path / "boot.cpp").write_text(STATIC_CPP)
        sources = '["att.cpp", "boot.cpp"]'
        # the offset comes from the static object: 0 only if its constructor ran
        init = ('["fw.begin(${k0})", "extern float boot_value(); '
                'fw.boot_ = 1.0f - boot_value()"]')
    text = TOML.replace("SOURCES", sources).replace("INIT", init)
    (tmp_path / "att.toml").write_text(text.replace('headers', 'headers'))
    p = tmp_path / "att.toml"
    p.write_text(text.replace("[firmware]\n", '[firmware]\nheaders = ["att.hpp"]\n'))
    return p


def _validate(path, target, cflags=None, seconds=1.0, kind="1d"):
    d = load_declaration(path)
    if cflags is not None:
        d.firmware.cflags = d.firmware.cflags_given = list(cflags)
    s = (sim.axis1d("fast", rate=200.0, duration=seconds, seed=3) if kind == "1d" else
         sim.imu("fast", rate=200.0, duration=seconds, seed=3))
    p = resolve_params(d.filter, s.dt, d.params)
    inputs = [s.gyr, s.acc_angle] if kind == "1d" else inputs_for(kind, s)
    return validate_isolated(d.firmware, d.filter, p, inputs, target=target)


@pytest.mark.parametrize("target", TARGETS)
def test_cpp_class_on_each_target(tmp_path, target):
    flags = ["-O2", "-ffp-contract=off"] if target == "cortex-m4f" else None
    v = _validate(_class(tmp_path), target, flags)
    assert v.bit_exact, v.text()
    assert v.cost is not None and v.cost.median > 0


def test_cpp_class_fma_is_named_on_the_m4f(tmp_path):
    v = _validate(_class(tmp_path), "cortex-m4f")
    assert not v.bit_exact
    assert any(c.what == "fma" for c in v.causes), v.text()


@pytest.mark.parametrize("target,flags", [("cortex-m0", None), ("cortex-m4f", None),
                                          ("cortex-m4f", ["-O2", "-ffp-contract=off",
                                                          "-fexceptions"])])
def test_static_constructors_and_exceptions_link(tmp_path, target, flags):
    flags = flags or (["-O2", "-ffp-contract=off"] if target == "cortex-m4f" else None)
    v = _validate(_class(tmp_path, static=True), target, flags)
    assert v.bit_exact, v.text()


@pytest.mark.parametrize("target", TARGETS)
def test_arduino_style_class_with_default_flags(target):
    v = _validate(os.path.join(DECLARED, "madgwick_arduino.toml"), target, seconds=1.5,
                  kind="ahrs")
    assert v.max_angle_deg is not None and v.max_angle_deg < 0.01, v.text()
    assert v.cflags == ("-O2",), v.cflags         # the target's default flags, as given


# ---------------------------------------------------------------------------
# x-io Fusion's C as published (the imufusion 1.2.3 sdist, pinned and hash-checked by
# tests/fusion_oracle.py), through examples/declarations/fusion-1.2.3.toml, unmodified

FUSION_DECLARATION = os.path.join(os.path.dirname(HERE), "examples", "declarations",
                                  "fusion-1.2.3.toml")


@pytest.fixture(scope="module")
def fusion_dir(tmp_path_factory):
    import fusion_oracle
    return fusion_oracle.fusion_sources(fusion_oracle.fetch_sdist(), fusion_oracle.VERSION,
                                        tmp_path_factory.mktemp("fusion"))


def _fusion(fusion_dir, target, flags=None, seconds=3.0):
    import fusion_oracle
    return fusion_oracle.validate_declared_fusion(FUSION_DECLARATION, fusion_dir, target,
                                                  flags, seconds)


@pytest.mark.parametrize("target,flags", [("host", None),
                                          ("cortex-m4f", ["-O2", "-ffp-contract=off"]),
                                          ("cortex-m0", None), ("atmega328p", None)])
def test_fusion_as_published_is_bit_exact(fusion_dir, target, flags):
    v = _fusion(fusion_dir, target, flags)
    assert v.bit_exact, v.text()
    assert len(v.comparison.names) == 22


def test_fusion_fma_is_named_on_the_m4f(fusion_dir):
    v = _fusion(fusion_dir, "cortex-m4f", seconds=2.0)
    assert not v.bit_exact
    assert any(c.what == "fma" and c.confirmed for c in v.causes), v.text()


def test_fusion_from_the_command_line(fusion_dir, tmp_path):
    """`imufuse validate --declaration fusion-1.2.3.toml --source-dir DIR`: the inputs in
    Fusion's units (deg/s), bit-exact; without a declaration FusionAHRS is refused with the
    way to declare it."""
    import subprocess
    env = {**os.environ, "IMUFUSE_CACHE": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-m", "imufuse", "validate", "--declaration",
                        FUSION_DECLARATION, "--source-dir", fusion_dir, "--duration", "3"],
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "deg/s" in r.stdout and "bit-exact: 600 samples x 22" in r.stdout, r.stdout
    r = subprocess.run([sys.executable, "-m", "imufuse", "validate", "-f", "FusionAHRS",
                        os.path.join(fusion_dir, "FusionAhrs.c")], capture_output=True,
                       text=True, env=env, timeout=600)
    assert r.returncode == 2 and "--declaration" in r.stderr, r.stderr
