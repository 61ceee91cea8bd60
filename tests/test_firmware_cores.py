"""`imufuse validate --target` on the cores added after the first three: Cortex-M3, M7, M33,
M55 (QEMU mps2/mps3 machines) and RV32IMAC, RV32IMAFC (QEMU riscv32 virt, picolibc).

The firmware is examples/firmware-tests/cf.c (Eq. 2.2 as firmware writes it), copies of it with
planted faults, and imufuse's own C as a firmware; the expected results are computed here: the
fused multiply-add model of cf.c in exact rational arithmetic (tests/test_firmware_target.py),
the per-update counts of the MCU benchmark harness.
"""
import numpy as np
import pytest

from imufuse import sim
from imufuse.shared.resources import csrc_dir
from imufuse.firmware import DEFAULT_CFLAGS, FirmwareError, csrc_firmware, speed_note, validate
from imufuse.firmware.targets import CORES
from imufuse.mcu import ensure_toolchains
from imufuse.mcu import filters as mf
from imufuse.reference import MadgwickIMU

import test_firmware_target as tft

NEW = ("cortex-m3", "cortex-m7", "cortex-m33", "cortex-m55", "rv32imac", "rv32imafc")


@pytest.fixture(scope="module", autouse=True)
def _toolchains():
    """Installed when missing (tools/install-toolchains.sh); a core that still cannot run
    fails here, it is not skipped."""
    missing = ensure_toolchains([CORES[t].harness for t in NEW])
    assert not missing, f"MCU toolchains missing: {missing}"


@pytest.mark.parametrize("target", NEW)
def test_contract_flags_are_bit_exact(target):
    v, _, _ = tft._validate(*tft._cf(), ["-O2", "-ffp-contract=off"], target, n=200)
    assert v.bit_exact, v.text()
    c = v.cost
    assert c.unit == "instructions" and 0 < c.min <= c.median <= c.max and len(c.counts) == 200
    assert c.flash and c.flash > 0 and c.ram >= 20 and c.stack is not None


@pytest.mark.parametrize("target", ["cortex-m33", "rv32imafc"])
def test_gnu_defaults_on_a_single_precision_fpu_fuse(target):
    """Under gnu defaults the M33's vfma.f32 and the RV32F's fmadd.s compute exactly the
    contracted expression, and the report names the instruction and the fix."""
    v, dt, ins = tft._validate(*tft._cf(), ["-O2"], target, n=200)
    assert not v.bit_exact
    model = tft._fma_model(dt, ins)
    assert np.array_equal(v.got[:, 0].view(np.uint32), model.view(np.uint32))
    insn = CORES[target].contraction
    assert "fused multiply-add" in v.text() and insn in v.text(), v.text()
    assert "-ffp-contract=off (confirmed" in v.text()
    assert insn.split(".")[0] in speed_note(target)


def test_gnu_defaults_fuse_float64_in_hardware():
    """float64 runs in the M7's FPU: under gnu defaults GCC fuses it into vfma.f64, and the
    report says so; with -ffp-contract=off the float64 filter is bit-exact, without a double
    routine of libgcc."""
    target = "cortex-m7"
    s = sim.imu("slow", rate=200.0, duration=0.5, seed=1)
    params = dict(dt=s.dt, beta=0.1)
    fused = csrc_firmware("MadgwickIMU", str(csrc_dir()), "float64", cflags=["-O2"])
    v = validate(fused, "MadgwickIMU", params, (s.gyr, s.acc), target=target)
    assert not v.bit_exact
    fma = [c for c in v.causes if c.what == "fma"]
    assert fma and "vfma.f64" in fma[0].evidence and fma[0].confirmed, v.text()
    exact = csrc_firmware("MadgwickIMU", str(csrc_dir()), "float64", cflags=list(DEFAULT_CFLAGS))
    w = validate(exact, "MadgwickIMU", params, (s.gyr, s.acc), target=target)
    assert w.bit_exact, w.text()
    assert not any(r.startswith("__aeabi_d") for r in w.cost.library), w.cost.library


@pytest.mark.parametrize("target", ["cortex-m3", "rv32imac"])
def test_gnu_defaults_without_an_fpu_stay_bit_exact(target):
    v, _, _ = tft._validate(*tft._cf(), ["-O2"], target, n=200)
    assert v.bit_exact, v.text()
    assert "no FPU" in v.text() and "no multiply-add" in v.text()


def test_double_in_hardware_is_named(tmp_path):
    """A double constant in float code runs in the M7's double FPU (no library call): the
    report still names double-precision arithmetic, by its instructions."""
    src, inc = tft._cf(tmp_path, "s->oma * angle", "(1.0 - s->alpha) * angle")
    v, _, _ = tft._validate(src, inc, ["-O2", "-ffp-contract=off"], "cortex-m7", n=200)
    assert not v.bit_exact
    dbl = [c for c in v.causes if c.what == "double"]
    assert dbl and ".f64" in dbl[0].evidence, v.text()


@pytest.mark.parametrize("fault", ["hard fault", "exit"])
def test_riscv_faults_name_the_sample(tmp_path, fault):
    """A trap (a jump to address 0) and exit() on the RV32 name the sample, as on the Arm
    cores."""
    code = {"hard fault": "if (s->n == 50u) { ((void (*)(void))0)(); }",
            "exit": "if (s->n == 50u) { exit(3); }"}[fault]
    src, inc = tft._cf(tmp_path, "/* FAULT */", code, "#include <stdlib.h>\n")
    with pytest.raises(FirmwareError) as e:
        tft._validate(src, inc, ["-O2", "-ffp-contract=off"], "rv32imac", timeout=10.0)
    msg = str(e.value)
    assert "\n" not in msg
    assert ("hard fault at sample 49" if fault == "hard fault" else "exit(3) at sample 49") in msg


@pytest.mark.parametrize("target", ["cortex-m33", "rv32imafc"])
def test_same_counts_as_the_mcu_benchmarks(target):
    """imufuse's MadgwickIMU validated as firmware costs, update for update, what bench/mcu
    measures on the same inputs (the same counter, the same overhead removed)."""
    params = dict(dt=1 / 100, beta=0.1)
    spec = mf.FilterSpec.make(MadgwickIMU, params, "float32")
    ins = mf.inputs_for("float32", "3d", 120)
    bench = mf.run_filters(CORES[target].harness, [spec], ins, count=True).results[0].counts
    fw = csrc_firmware("MadgwickIMU", str(csrc_dir()), "float32", cflags=list(DEFAULT_CFLAGS))
    v = validate(fw, "MadgwickIMU", params, [ins["gyr"], ins["acc"]], target=target)
    assert v.bit_exact, v.text()
    assert np.array_equal(v.cost.counts, bench)


def test_counting_is_described_honestly():
    """Every QEMU core counts instructions and says they are not cycles; simavr counts
    cycles."""
    for name, c in CORES.items():
        if name == "atmega328p":
            assert "cycles" in c.counting and "simavr" in c.counting
        else:
            assert c.counting.startswith("instructions") and "not cycles" in c.counting
