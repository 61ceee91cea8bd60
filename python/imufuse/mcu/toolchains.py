"""Targets, flags and toolchains of the emulated-MCU harness."""
from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
from typing import Dict, Iterable, List, Optional, Sequence, Tuple


from .._resources import install_toolchains_script, mcu_data_dir


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
    systick_hz: float = 0.0  # SysTick (processor) clock under qemu

    @property
    def tools(self) -> Tuple[str, ...]:
        t = [self.cc, self.size_tool]
        if self.emulator:
            t.append(self.emulator)
        return tuple(t)


_ARM_LINK = ("-nostartfiles", "-Wl,--gc-sections", "--specs=nano.specs")

TARGETS: Dict[str, Target] = {
    "m4f": Target(
        name="m4f",
        cc="arm-none-eabi-gcc",
        arch_flags=("-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard"),
        size_tool="arm-none-eabi-size",
        emulator="qemu-system-arm",
        sources=("arm_startup.c",),
        link_flags=_ARM_LINK,
        machine="mps2-an386",
        flash=4 << 20,
        ram=4 << 20,
        count_unit="instructions",
        systick_hz=25e6,
    ),
    "m0": Target(
        name="m0",
        cc="arm-none-eabi-gcc",
        arch_flags=("-mcpu=cortex-m0", "-mthumb", "-mfloat-abi=soft"),
        size_tool="arm-none-eabi-size",
        emulator="qemu-system-arm",
        sources=("arm_startup.c",),
        link_flags=_ARM_LINK,
        machine="microbit",
        flash=256 << 10,
        ram=16 << 10,
        count_unit="instructions",
        systick_hz=16e6,
    ),
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


def cflags(target: str, warnings: bool = True) -> List[str]:
    """The full compiler flag list for a target (arch, base, warnings)."""
    tgt = _target(target)
    flags = list(tgt.arch_flags) + list(BASE_FLAGS)
    if warnings:
        flags += list(WARN_FLAGS)
    return flags
