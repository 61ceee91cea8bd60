"""Static MCU checks of csrc/fixed (no cycle counts; those come from the MCU
harness): cross-compile the fixed-point filters for ATmega328P (avr-gcc) and
Cortex-M0 (arm-none-eabi-gcc) and check that no update function calls a
64-bit, division or soft-float helper.  Prints the helpers each update uses."""
from __future__ import annotations

import pathlib
import re
import shutil
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
FIXED = ROOT / "csrc" / "fixed"
SOURCES = sorted(FIXED.glob("*.c"))

TARGETS = {
    "avr": (["avr-gcc", "-mmcu=atmega328p"], "avr-objdump",
            re.compile(r"__(mul|umul|div|udiv|mod)[a-z]*di3|__(u)?divmod|__[a-z]+sf[0-9]|__[a-z]+df[0-9]")),
    "cortex-m0": (["arm-none-eabi-gcc", "-mcpu=cortex-m0", "-mthumb"], "arm-none-eabi-objdump",
                  re.compile(r"__aeabi_(l|ui?div|idiv|f|d)|__(mul|div|udiv)di3|__[a-z]+sf[0-9]")),
}


def _calls(target, src, tmp):
    cc, objdump, _ = TARGETS[target]
    obj = tmp / (src.stem + ".o")
    subprocess.run([*cc, "-std=c99", "-Os", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror",
                    f"-I{FIXED}", "-c", str(src), "-o", str(obj)], check=True)
    dis = subprocess.run([objdump, "-dr", str(obj)], check=True, capture_output=True, text=True).stdout
    calls, fn = {}, None
    for line in dis.splitlines():
        m = re.match(r"^[0-9a-f]+ <([^>]+)>:", line)
        if m:
            fn = m.group(1)
        m = re.search(r"R_(AVR_CALL|ARM_THM_CALL)\s+(\S+)", line)
        if m and fn:
            calls.setdefault(fn, set()).add(m.group(2))
    return calls


@pytest.mark.parametrize("target", list(TARGETS))
def test_updates_use_no_int64_division_or_float(target, tmp_path):
    if shutil.which(TARGETS[target][0][0]) is None:
        pytest.skip(f"{TARGETS[target][0][0]} not installed")
    bad = TARGETS[target][2]
    for src in SOURCES:
        calls = _calls(target, src, tmp_path)
        # every function except the init-time ones (init may use soft-float:
        # it runs once); local calls appear as section offsets, so the union
        # over all non-init functions covers whatever the updates can reach
        upd = [f for f in calls if "_init" not in f and "from_double" not in f
               and "param_ok" not in f]
        helpers = sorted({c for f in upd for c in calls[f] if c.startswith("__")})
        print(f"{target} {src.name} (update paths): {', '.join(helpers) or '-'}")
        assert not [h for h in helpers if bad.search(h)], (src.name, helpers)
