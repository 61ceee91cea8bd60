"""Every filter configuration of the registry on the cores added after the first three, bit for
bit: Cortex-M3 (soft float), Cortex-M7 (float and double in hardware), Cortex-M33 (Armv8-M,
single-precision FPU), Cortex-M55 (Armv8.1-M, double-precision FPU), RV32IMAC (soft float) and
RV32IMAFC (single-precision F), each a QEMU machine (imufuse.mcu.TARGETS).

The machinery is tests/test_mcu_filters.py's: for each (configuration, precision) of
imufuse.registry, all filters of one precision and input set in one program per core, the
state after every sample and the `skipped` counter equal to the pure-Python reference's, bit
for bit (the host build equals the reference in test_mcu_filters). test_arithmetic checks
+ - * / sqrt of each core's float and double against correctly rounded results.
"""
import numpy as np
import pytest

import imufuse.mcu as mcu
from imufuse.mcu import filters as mf

import test_mcu_filters as base

CORES = ["m3", "m7", "m33", "m55", "rv32imac", "rv32imafc"]


@pytest.fixture(scope="session")
def toolchains():
    """{core: reason} of cores that cannot run here, after trying to install."""
    return mcu.ensure_toolchains(CORES)


@pytest.fixture(scope="session")
def runs(toolchains):
    # two programs at a time: builds and emulators are processes, CI has two cores
    return base._Runs(toolchains, CORES, workers=4)


def test_every_core_runs_every_precision(toolchains, runs):
    """Nothing is left out: every core runs float32, float64 (hardware or soft double) and
    both fixed-point profiles, and every program ran."""
    assert not toolchains, f"toolchains missing: {toolchains} (tools/install-toolchains.sh)"
    for core in CORES:
        assert set(mf.TARGET_PRECISIONS[core]) == {"float32", "float64", "p32", "p8"}
    for key, r in runs.out.items():
        if isinstance(r, Exception):
            raise AssertionError(f"{key}: {r}") from r
    assert {(t, *g) for t in CORES for g in base.GROUPS} == set(runs.out)


@pytest.mark.parametrize("core", CORES)
def test_state_bits(runs, toolchains, core):
    """The core's trajectory of every registry configuration equals the reference's, bit for
    bit (one item per core: the first difference of each configuration that differs)."""
    problems = []
    for spec in base.SPECS:
        problems += base._state_bits(runs, toolchains, spec, core)
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("core", CORES)
@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_arithmetic(toolchains, core, precision):
    """+ - * / sqrt correctly rounded on the core, subnormals included."""
    base.test_arithmetic(toolchains, core, precision)


def test_a_difference_is_caught_on_a_new_core(toolchains):
    """The comparison can fail on these cores too: one constant off by one ulp on the RV32IMAFC
    changes the trajectory and the description names the sample."""
    s = next(s for s in base.SPECS if s.precision == "float32" and s.kind == "imu")
    ins = mf.inputs_for("float32", s.group[1], 40)
    bad_spec = mf.FilterSpec.make(s.ref_class, s.params, "float32", s.label)
    bad_spec._init_args = lambda: [a + "*1.0000001f" if a.endswith("f") else a
                                   for a in mf.FilterSpec._init_args(s)]
    bad = mf.run_filters("rv32imafc", [bad_spec], ins)
    want, _ = mf.reference_states(s, ins)
    msg = base._describe(bad.states[0], want, s, "rv32imafc")
    assert msg is not None and "first difference at sample" in msg
    assert np.array_equal(mf.run_filters("rv32imafc", [s], ins).states[0], want)


@pytest.mark.parametrize("core", CORES)
def test_counter_counts_exact_instructions(toolchains, core):
    """A two-instruction loop (Arm subs/bne, RISC-V addi/bnez) of k turns counts 2k + 2 over
    an empty call: SysTick's clock (a wrong one scales every count) and mcycle under -icount
    count instructions exactly."""
    k = np.array([1, 2, 10, 1000, 65535, 40000, 7], dtype=np.uint16)
    if core.startswith("rv"):
        asm = '__asm__ volatile("1: addi %0, %0, -1\\n\\tbnez %0, 1b" : "+r"(c));'
    else:
        asm = ('__asm__ volatile(".syntax unified\\n1: subs %0, %0, #1\\n\\tbne 1b\\n'
               '.syntax divided" : "+l"(c) : : "cc");')
    drv = mcu.Driver(step="uint32_t c = k;\n" + asm, state=[])
    res = mcu.run(core, driver=drv, inputs={"k": k}, count=True)
    assert res.counts.tolist() == (2 * k.astype(np.int64) + 2).tolist()
