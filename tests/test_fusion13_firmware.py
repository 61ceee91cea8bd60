"""x-io Fusion 1.3's C as published (the imufusion 1.3.3 sdist, pinned and hash-checked by
tests/fusion13_oracle.py), through examples/declarations/fusion-1.3.3.toml, unmodified:
bit-exact with imufuse's FusionAHRS13 on the host, the Cortex-M4F with -ffp-contract=off, the
Cortex-M0 and the ATmega328P (avr-libc's sinf, cosf, atan2f and asinf, the functions a
difference could come from, give the same bits on this run), every state member after every
sample; on the M4F with GCC's defaults the fused multiply-add is named. And imufuse's own C
(csrc/fusion13.c) in the emulators, bit-exact with its twin (its cost is in docs/fusion.md).

validate knows both Fusion AHRS classes (imufuse.catalogue.FUSION_AHRS): Fusion's units, the
settings as the C init values, the period given with every update; the command line's
`imufuse validate --declaration fusion-1.3.3.toml` is run as written.
"""
import os
import subprocess
import sys

import numpy as np
import pytest

import imufuse.mcu as mcu
from imufuse import reference
from imufuse.reference._fusion13 import ADVANCED
from imufuse.shared.resources import csrc_dir

from bits import assert_same_bits

HERE = os.path.dirname(os.path.abspath(__file__))
import fusion13_oracle  # tests/ (on the suite's pythonpath)
import fusion_oracle

DECLARATION = os.path.join(os.path.dirname(HERE), "examples", "declarations",
                           "fusion-1.3.3.toml")

pytestmark = [pytest.mark.xdist_group("declared_target"), pytest.mark.emulator,
              pytest.mark.slow]


@pytest.fixture(scope="module")
def fusion_dir(tmp_path_factory):
    return fusion_oracle.fusion_sources(fusion13_oracle.fetch_sdist(), fusion13_oracle.VERSION,
                                        tmp_path_factory.mktemp("fusion13"))


def _validate(fusion_dir, target, flags=None, seconds=3.0):
    return fusion_oracle.validate_declared_fusion(DECLARATION, fusion_dir, target, flags,
                                                  seconds)


def test_fusion13_as_published_is_bit_exact_on_the_host(fusion_dir):
    v = _validate(fusion_dir, "host")
    assert v.bit_exact, v.text()
    assert len(v.comparison.names) == 23


def test_the_command_line_validates_fusion13_as_published(fusion_dir):
    """`imufuse validate --declaration fusion-1.3.3.toml --source-dir DIR`, as the file's
    first lines say to run it."""
    r = subprocess.run([sys.executable, "-m", "imufuse", "validate", "--declaration",
                        DECLARATION, "--source-dir", fusion_dir, "--duration", "3"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "vs imufuse FusionAHRS13" in r.stdout and "bit-exact: 600 samples x 23" in r.stdout, \
        r.stdout


@pytest.mark.parametrize("target,flags", [("cortex-m4f", ["-O2", "-ffp-contract=off"]),
                                          ("cortex-m0", None), ("atmega328p", None)])
def test_fusion13_as_published_on_the_mcus(fusion_dir, target, flags):
    missing = mcu.ensure_toolchains(("m4f", "m0", "avr"))
    assert not missing, f"MCU toolchains missing: {missing}"
    v = _validate(fusion_dir, target, flags)
    assert v.bit_exact, v.text()
    assert len(v.comparison.names) == 23


def test_fusion13_fma_is_named_on_the_m4f(fusion_dir):
    """Under GCC's defaults the M4F fuses multiply-adds: not bit-exact, and validate says why."""
    v = _validate(fusion_dir, "cortex-m4f", seconds=2.0)
    assert not v.bit_exact
    assert any(c.what == "fma" and c.confirmed for c in v.causes), v.text()


# ---------------------------------------------------------------------------
# imufuse's own C (csrc/fusion13.c) in the emulators: the twin's state after every sample

def _mcu_inputs(n):
    rng = np.random.default_rng(3)
    return {"gyr": rng.normal(0, 30.0, (n, 3)).astype(np.float32),            # deg/s
            "acc": (rng.normal(0, 0.2, (n, 3)) + [0, 0, 1]).astype(np.float32),  # g
            "mag": (rng.normal(0, 0.1, (n, 3)) + [0.4, 0, -0.8]).astype(np.float32)}


#: x-io's advanced settings through imf_fusion13_ahrs_init, one update per sample at the
#: settings' period (1 / 100 Hz, the 0.01 s of the 1.2.3 port's case in bench/mcu)
DRIVER13 = dict(
    prelude='#include "fusion13.h"\nstatic imf_fusion13_ahrs_t k;',
    init=("imf_fusion13_ahrs_settings_t s;\nimf_fusion13_ahrs_default_settings(&s);\n"
          "s.gyroscope_range = 2000.0f; s.acceleration_rejection = 10.0f;\n"
          "s.magnetic_rejection = 10.0f; s.rejection_timeout = 5.0f;\n"
          "imf_fusion13_ahrs_init(&k, &s, IMF_FUSION_INVSQRT_EXACT);"),
    step=("imf_fusion13_ahrs_update(&k, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2], "
          "mag[0], mag[1], mag[2]);"))


@pytest.mark.parametrize("target", ["m4f", "m0", "avr"])
def test_fusion_ahrs13_on_mcu(target):
    """FusionAHRS13 (float32) built for the MCU and run in its emulator gives the twin's
    state after every sample, bit for bit; the cost per update is measured on the way."""
    missing = mcu.ensure_toolchains([target])
    assert target not in missing, f"toolchain for {target} unavailable: {missing}"
    csrc = str(csrc_dir())
    state = (mcu.state_words("((const float *)(const void *)&k.x)", "f32", 15)
             + [(f"((const int32_t *)(const void *)&k.x)[{15 + j}]", "i32") for j in range(8)]
             + [("k.skipped", "u32")])
    inputs = _mcu_inputs(300)
    res = mcu.run(target, sources=[os.path.join(csrc, "fusion13.c")], include_dirs=[csrc],
                  driver=mcu.Driver(state=state, **DRIVER13), inputs=inputs, count=True)
    f = reference.FusionAHRS13(**ADVANCED, dtype="float32")
    want = f.run(inputs["gyr"], inputs["acc"], inputs["mag"])
    vals = res.values()
    assert_same_bits(np.column_stack(vals[:15]).astype(np.float32), want[:, :15], None)
    np.testing.assert_array_equal(np.column_stack(vals[15:23]).astype(np.float64),
                                  want[:, 15:].astype(np.float64))
    assert int(vals[23][-1]) == 0
    assert res.counts is not None and len(res.counts) == 300
