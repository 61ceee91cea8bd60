"""The emulated MCUs a user's firmware is validated on (`imufuse validate --target`), one record
per target: its user-facing name, what it is, the harness target that builds and runs it
(imufuse.mcu.toolchains: compiler, CPU flags, emulator machine), its floating point, the
instruction a compiler contracts a*b+c into, and how its cost is counted. The report's notes
about each one's floating point are made from the record.
"""
from __future__ import annotations

import dataclasses
from typing import Dict, List, Optional

__all__ = ["TARGETS", "DESCRIPTION", "CORES", "Core", "DEFAULT_TARGET_CFLAGS", "TargetError",
           "target_names", "harness_target", "speed_note", "core"]


@dataclasses.dataclass(frozen=True)
class Core:
    """One validation target."""
    name: str           # user-facing (--target)
    harness: str        # imufuse.mcu.TARGETS key
    description: str    # for reports and docs
    fpu: str            # "sp" (float32 in hardware), "dp" (float32 and float64), "" (none)
    contraction: str    # the fused multiply-add(s) a gnu-default build emits ("" if none)
    counting: str       # what a cost per update counts, and how
    double_bits: int = 64

    @property
    def has_fpu(self) -> bool:
        return bool(self.fpu)


_QEMU_ICOUNT = ("instructions (QEMU -icount: every instruction takes the same virtual time, "
                "read through {via}); not cycles: QEMU models no pipeline, wait states or caches")
_SYSTICK = _QEMU_ICOUNT.format(via="SysTick")
_MCYCLE = _QEMU_ICOUNT.format(via="the mcycle CSR, which QEMU backs with its virtual clock")

CORES: Dict[str, Core] = {c.name: c for c in (
    Core("cortex-m4f", "m4f", "Cortex-M4F (fpv4-sp-d16, hard float), QEMU mps2-an386", "sp",
         "vfma.f32", _SYSTICK),
    Core("cortex-m0", "m0", "Cortex-M0 (no FPU: soft float), QEMU microbit", "", "", _SYSTICK),
    Core("cortex-m3", "m3", "Cortex-M3 (no FPU: soft float), QEMU mps2-an385", "", "",
         _SYSTICK),
    Core("cortex-m7", "m7", "Cortex-M7 (fpv5-d16: float and double in hardware, hard float), "
         "QEMU mps2-an500", "dp", "vfma.f32/vfma.f64", _SYSTICK),
    Core("cortex-m33", "m33", "Cortex-M33 (Armv8-M Mainline, fpv5-sp-d16, hard float), QEMU "
         "mps2-an505", "sp", "vfma.f32", _SYSTICK),
    Core("cortex-m55", "m55", "Cortex-M55 (Armv8.1-M, MVE and double-precision FPU, hard "
         "float), QEMU mps3-an547", "dp", "vfma.f32/vfma.f64", _SYSTICK),
    Core("rv32imac", "rv32imac", "RV32IMAC (no FPU: soft float, ilp32, picolibc), QEMU "
         "riscv32 virt", "", "", _MCYCLE),
    Core("rv32imafc", "rv32imafc", "RV32IMAFC (single-precision F extension, ilp32f, "
         "picolibc), QEMU riscv32 virt", "sp", "fmadd.s", _MCYCLE),
    Core("atmega328p", "avr", "ATmega328P at 16 MHz (no FPU, double is 32 bits), simavr", "",
         "", "CPU cycles (simavr's cycle-accurate AVR core, Timer1 at clk/1)", 32),
)}

#: user-facing target names -> harness targets
TARGETS = {name: c.harness for name, c in CORES.items()}
#: what each target is, for reports
DESCRIPTION = {name: c.description for name, c in CORES.items()}
#: the default flags of a cross build: what a firmware build does (the compiler's own standard)
DEFAULT_TARGET_CFLAGS = ("-O2",)


class TargetError(RuntimeError):
    """The firmware failed on the target: one line naming the sample (see .sample)."""

    def __init__(self, msg: str, sample: Optional[int] = None):
        super().__init__(msg)
        self.sample = sample


def target_names() -> List[str]:
    return ["host", *TARGETS]


def core(target: str) -> Core:
    try:
        return CORES[target]
    except KeyError:
        raise ValueError(f"unknown target {target!r}; known: "
                         f"{', '.join(target_names())}") from None


def harness_target(target: str) -> str:
    return core(target).harness


def speed_note(target: str) -> str:
    """What the target's floating point means for bit-exactness (empty for the host)."""
    if target not in CORES:
        return ""
    c = CORES[target]
    name = "the ATmega328P" if c.harness == "avr" else f"the {target}"
    if not c.fpu and c.double_bits == 32:
        return (f"{name} has no FPU: every float operation is an avr-libc call that rounds "
                "on its own (no fused multiply-add), and double is 32 bits")
    if not c.fpu:
        return (f"{name} has no FPU: every float operation is a libgcc call that rounds on its "
                "own, so there is no multiply-add for the compiler to fuse")
    width = "a single-precision FPU" if c.fpu == "sp" else "a double-precision FPU"
    # the Arm single-precision cores' note as it always read ("vfma"); the others name the
    # instructions
    fused = "vfma" if c.contraction == "vfma.f32" else c.contraction.replace("/", " and ")
    code = "float32 code" if c.fpu == "sp" else "float32 and float64 code"
    return (f"{name} has {width} with {fused}: under gnu defaults (-ffp-contract=fast) GCC "
            f"fuses a*b+c in {code}")
