"""Targets, flags and toolchains of the emulated-MCU harness."""
from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
from typing import Dict, Iterable, List, Optional, Sequence, Tuple


from ..shared.resources import install_toolchains_script, mcu_data_dir


DATA_DIR = mcu_data_dir()
# tools/install-toolchains.sh, shipped in the package data
INSTALL_SCRIPT = install_toolchains_script()

BASE_FLAGS = ("-std=c99", "-O2", "-ffp-contract=off")
WARN_FLAGS = ("-Wall", "-Wextra", "-pedantic", "-Wdouble-promotion", "-Werror")

# Cycles the AVR Timer1 overflow interrupt adds to a count, per overflow (entry, push/pop,
# 16-bit increment, reti); checked by tests/test_mcu_harness.py against _delay_loop_2.
AVR_OVF_ISR_CYCLES = 40

# qemu -icount shift used for instruction counts on ARM: one instruction takes 2**shift ns of
# virtual time, so one instruction spans many SysTick ticks and rounding is exact.
ICOUNT_SHIFT = 10


class HarnessError(RuntimeError):
    """A build or an emulator run failed; the message holds the command and its output."""


class ToolchainMissing(HarnessError):
    """A compiler or emulator for the target is not installed."""


@dataclasses.dataclass(frozen=True)
class Target:
    name: str
    cc: str
    arch_flags: Tuple[str, ...]
    size_tool: str
    emulator: Optional[str]
    sources: Tuple[str, ...]  # port files from DATA_DIR
    link_flags: Tuple[str, ...] = ()
    machine: Optional[str] = None  # qemu machine
    flash: int = 0  # bytes
    ram: int = 0
    count_unit: str = ""  # what run(count=True) measures
    systick_hz: float = 0.0  # SysTick (processor) clock under qemu; 0: a counter CSR
    flash_origin: int = 0x00000000
    ram_origin: int = 0x20000000
    ldscript: str = "arm.ld.in"  # linker script template in DATA_DIR
    # how run(count=True) counts: "systick" (SysTick under qemu -icount), "csr" (RISC-V
    # mcycle under qemu -icount: the virtual clock), "timer1" (AVR cycles), "" (none)
    count_method: str = ""

    @property
    def tools(self) -> Tuple[str, ...]:
        t = [self.cc, self.size_tool]
        if self.emulator:
            t.append(self.emulator)
        return tuple(t)


_ARM_LINK = ("-nostartfiles", "-Wl,--gc-sections", "--specs=nano.specs")
_RV_LINK = ("-nostartfiles", "-Wl,--gc-sections")


def _arm(name: str, cpu_flags: Tuple[str, ...], machine: str, flash: int, ram: int,
         systick_hz: float, flash_origin: int = 0, ram_origin: int = 0x20000000) -> Target:
    return Target(name=name, cc="arm-none-eabi-gcc",
                  arch_flags=(cpu_flags[0], "-mthumb", *cpu_flags[1:]),
                  size_tool="arm-none-eabi-size", emulator="qemu-system-arm",
                  sources=("arm_startup.c",), link_flags=_ARM_LINK, machine=machine,
                  flash=flash, ram=ram, count_unit="instructions", systick_hz=systick_hz,
                  flash_origin=flash_origin, ram_origin=ram_origin, count_method="systick")


def _rv(name: str, march: str, mabi: str) -> Target:
    # qemu's virt board: everything in its RAM at 0x80000000, the first 4 MB standing for flash
    return Target(name=name, cc="riscv64-unknown-elf-gcc",
                  arch_flags=(f"-march={march}", f"-mabi={mabi}", "-mcmodel=medany",
                              "--specs=picolibc.specs"),
                  size_tool="riscv64-unknown-elf-size", emulator="qemu-system-riscv32",
                  sources=("riscv_port.c",), link_flags=_RV_LINK, machine="virt",
                  flash=4 << 20, ram=4 << 20, count_unit="instructions",
                  flash_origin=0x80000000, ram_origin=0x80400000, ldscript="riscv.ld.in",
                  count_method="csr")

TARGETS: Dict[str, Target] = {
    "m4f": _arm("m4f", ("-mcpu=cortex-m4", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard"),
                "mps2-an386", 4 << 20, 4 << 20, 25e6),
    "m0": _arm("m0", ("-mcpu=cortex-m0", "-mfloat-abi=soft"), "microbit", 256 << 10, 16 << 10,
               16e6),
    "m3": _arm("m3", ("-mcpu=cortex-m3", "-mfloat-abi=soft"), "mps2-an385", 4 << 20, 4 << 20,
               25e6),
    "m7": _arm("m7", ("-mcpu=cortex-m7", "-mfpu=fpv5-d16", "-mfloat-abi=hard"), "mps2-an500",
               4 << 20, 4 << 20, 25e6),
    # Armv8-M with the Security Extension: it starts in the Secure state, so the image and
    # its RAM live at the Secure aliases of the SSRAMs
    "m33": _arm("m33", ("-mcpu=cortex-m33", "-mfpu=fpv5-sp-d16", "-mfloat-abi=hard"),
                "mps2-an505", 4 << 20, 4 << 20, 20e6, 0x10000000, 0x38000000),
    "m55": _arm("m55", ("-mcpu=cortex-m55", "-mfloat-abi=hard"), "mps3-an547", 512 << 10,
                512 << 10, 32e6, 0x10000000, 0x30000000),
    "rv32imac": _rv("rv32imac", "rv32imac", "ilp32"),
    "rv32imafc": _rv("rv32imafc", "rv32imafc", "ilp32f"),
    "avr": Target(
        name="avr",
        cc="avr-gcc",
        arch_flags=("-mmcu=atmega328p", "-DF_CPU=16000000UL"),
        size_tool="avr-size",
        emulator="simavr",
        sources=("avr_port.c",),
        link_flags=("-Wl,--gc-sections",),
        flash=32 << 10,
        ram=2 << 10,
        count_unit="cycles",
        flash_origin=0,
        ram_origin=0x800000,
        ldscript="",
        count_method="timer1",
    ),
    "host": Target(
        name="host",
        cc=os.environ.get("CC", "cc"),
        arch_flags=(),
        size_tool="size",
        emulator=None,
        sources=("host_port.c",),
        link_flags=(),
        count_unit="",
        ldscript="",
    ),
}

_SECTION_FLAGS = ("-ffunction-sections", "-fdata-sections")



def missing_tools(target: str) -> List[str]:
    """Executables the target needs that are not on PATH."""
    tgt = _target(target)
    return [t for t in tgt.tools if shutil.which(t) is None]


def available(target: str) -> bool:
    return not missing_tools(target)


def ensure_toolchains(targets: Iterable[str] = ("m4f", "m0", "avr"), install: bool = True) -> Dict[str, str]:
    """Make the targets' tools available, running tools/install-toolchains.sh if needed.

    Returns {target: reason} for the targets still unavailable (empty when all are there).
    """
    targets = list(targets)
    need = {t: missing_tools(t) for t in targets}
    if any(need.values()) and install:
        if INSTALL_SCRIPT.is_file():
            proc = subprocess.run(["sh", str(INSTALL_SCRIPT)], capture_output=True, text=True)
            if proc.returncode != 0:
                reason = f"install-toolchains.sh failed ({proc.returncode}): {proc.stderr.strip()[-400:]}"
                return {t: reason for t in targets if missing_tools(t)}
        need = {t: missing_tools(t) for t in targets}
    return {t: "missing: " + " ".join(m) for t, m in need.items() if m}


def _target(name: str) -> Target:
    try:
        return TARGETS[name]
    except KeyError:
        raise ValueError(f"unknown target {name!r}; known: {sorted(TARGETS)}") from None


def _require(tgt: Target, tools: Sequence[str]) -> None:
    miss = [t for t in tools if shutil.which(t) is None]
    if miss:
        raise ToolchainMissing(
            f"target {tgt.name!r} needs {' '.join(miss)}; run tools/install-toolchains.sh"
        )


def linker_script(tgt: Target) -> Optional[str]:
    """The target's linker script (its memory map filled in), or None (avr, host)."""
    if not tgt.ldscript:
        return None
    return ((DATA_DIR / tgt.ldscript).read_text()
            .replace("@FLASH_ORIGIN@", f"0x{tgt.flash_origin:08x}")
            .replace("@RAM_ORIGIN@", f"0x{tgt.ram_origin:08x}")
            .replace("@FLASH_LEN@", str(tgt.flash)).replace("@RAM_LEN@", str(tgt.ram)))


def cflags(target: str, warnings: bool = True) -> List[str]:
    """The full compiler flag list for a target (arch, base, warnings)."""
    tgt = _target(target)
    flags = list(tgt.arch_flags) + list(BASE_FLAGS)
    if warnings:
        flags += list(WARN_FLAGS)
    return flags
