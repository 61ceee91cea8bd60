"""The emulated MCUs a user's firmware is validated on (`imufuse validate --target`): their
user-facing names, what each is, the default flags of a cross build, and the note a report
gives about each one's floating point.
"""
from __future__ import annotations

from typing import List, Optional

__all__ = ["TARGETS", "DESCRIPTION", "DEFAULT_TARGET_CFLAGS", "TargetError", "target_names",
           "harness_target", "speed_note"]

#: user-facing target names -> harness targets
TARGETS = {"cortex-m4f": "m4f", "cortex-m0": "m0", "atmega328p": "avr"}
#: what each target is, for reports
DESCRIPTION = {
    "cortex-m4f": "Cortex-M4F (fpv4-sp-d16, hard float), QEMU mps2-an386",
    "cortex-m0": "Cortex-M0 (no FPU: soft float), QEMU microbit",
    "atmega328p": "ATmega328P at 16 MHz (no FPU, double is 32 bits), simavr",
}
#: the default flags of a cross build: what a firmware build does (the compiler's own standard)
DEFAULT_TARGET_CFLAGS = ("-O2",)


class TargetError(RuntimeError):
    """The firmware failed on the target: one line naming the sample (see .sample)."""

    def __init__(self, msg: str, sample: Optional[int] = None):
        super().__init__(msg)
        self.sample = sample


def target_names() -> List[str]:
    return ["host", *TARGETS]


def harness_target(target: str) -> str:
    try:
        return TARGETS[target]
    except KeyError:
        raise ValueError(f"unknown target {target!r}; known: {', '.join(target_names())}") from None


def speed_note(target: str) -> str:
    if target == "cortex-m4f":
        return ("the cortex-m4f has a single-precision FPU with vfma: under gnu defaults "
                "(-ffp-contract=fast) GCC fuses a*b+c in float32 code")
    if target == "cortex-m0":
        return ("the cortex-m0 has no FPU: every float operation is a libgcc call that rounds "
                "on its own, so there is no multiply-add for the compiler to fuse")
    if target == "atmega328p":
        return ("the ATmega328P has no FPU: every float operation is an avr-libc call that "
                "rounds on its own (no fused multiply-add), and double is 32 bits")
    return ""
