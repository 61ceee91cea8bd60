"""Code size of Nair's variometer (csrc/vario.c) on the MCU targets.

    python bench/mcu/vario_size.py        # markdown table for docs/vario.md

Bytes of each function (nm -S of vario.o built with the contract's flags and
-ffunction-sections; soft-float routines are not counted) and the RAM of one
imf_vario_t. Cycles per update and linked flash come from bench/mcu/measure.py
(the registry's VarioKF cases are among its filters).
"""
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CSRC = ROOT / "csrc"
FLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-pedantic",
         "-Wdouble-promotion", "-Werror", "-ffunction-sections", f"-I{CSRC}"]
TARGETS = {
    "m4f": ("arm-none-eabi-", ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16",
                               "-mfloat-abi=hard"]),
    "m0": ("arm-none-eabi-", ["-mcpu=cortex-m0", "-mthumb"]),
    "avr": ("avr-", ["-mmcu=atmega328p"]),
}
FUNCS = ("imf_vario_init", "imf_vario_update", "imf_vertical_accel")
# sizeof(imf_vario_t) as a symbol's size: one static instance in a probe file
PROBE = '#include "vario.h"\nimf_vario_t imf_vario_probe;\n'


def sizes(prefix, arch, tmp):
    obj, probe = Path(tmp) / "vario.o", Path(tmp) / "probe.c"
    probe.write_text(PROBE)
    subprocess.run([prefix + "gcc", *arch, *FLAGS, "-c", str(CSRC / "vario.c"), "-o", str(obj)],
                   check=True)
    subprocess.run([prefix + "gcc", *arch, *FLAGS, "-fno-common", "-c", str(probe), "-o",
                    str(Path(tmp) / "probe.o")], check=True)
    out = {}
    for o in (obj, Path(tmp) / "probe.o"):
        nm = subprocess.run([prefix + "nm", "-S", str(o)], check=True, capture_output=True,
                            text=True).stdout
        for line in nm.splitlines():
            parts = line.split()
            if len(parts) == 4:
                out[parts[3]] = int(parts[1], 16)
    return out


def main():
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, (prefix, arch) in TARGETS.items():
            if shutil.which(prefix + "gcc") is None:
                print(f"{name}: {prefix}gcc not found", file=sys.stderr)
                continue
            s = sizes(prefix, arch, tmp)
            rows.append((name, *[s[f] for f in FUNCS], s["imf_vario_probe"]))
    print("| target (float32) | imf_vario_init, bytes | imf_vario_update, bytes | "
          "imf_vertical_accel, bytes | RAM of imf_vario_t, bytes |")
    print("|---|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(str(v) for v in r) + " |")


if __name__ == "__main__":
    main()
