"""The fixed-point updates with the float updates' scalar inputs: what each form costs on the MCUs.

    python research/fixed_input_forms.py                   # every form, ATmega328P and Cortex-M0
    python research/fixed_input_forms.py --forms F2 --filters KKQ-p8 --targets avr

The float updates take one sample as scalars (gx, gy, gz, ax, ay, az[, mx, my, mz]); the
fixed-point 3-D updates took int16 arrays. For each form below the tree of the measurement
(git archive of --rev, by default 73f407a: the last tree whose 3-D updates took arrays only;
F2 is what the library adopted after it) is copied, the form applied to the six 3-D updates' C, and
bench/mcu/measure.py run in the copy beside the unchanged tree (cycles or instructions per
update, linked flash, bits against the Python twins): docs/history/fixed-point.md, "The float
updates' scalar inputs", holds the tables. The forms:

  F1   the update takes the scalars and copies them into the arrays its body reads (the body,
       made static, inlined into it)
  F1b  the same with the array body a separate function, not inlined
  F2   the scalar update a static inline wrapper in the header: the arrays built at the call
       site, the array update out of line
  F3   a static inline wrapper that stores the scalars into the filter (int16_t in[6], in[9])
       and calls an out-of-line update reading them there

Every copy keeps the Python side and the values: only the C call changes.

    python research/fixed_input_forms.py --callers         # the call sites alone

compiles callers of an external update (-O2, ATmega328P and Cortex-M0), the sample in RAM or
its values in registers (read one by one), and prints their bytes and, on AVR, their cycles
counted from the listing (calls and jumps excluded).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Dict, Tuple

ROOT = Path(__file__).resolve().parents[1]
FORMS = ("F1", "F1b", "F2", "F3")
FILTERS = ("KKQ-p8,MultiWiiQ-p8,MultiWiiQ-nolpf-p8,MahonyIMUQ-p8,MahonyIMUQ-p32,MadgwickIMUQ-p8,"
           "MadgwickIMUQ-p32,RobustIMUQ-defaults-p8,RobustIMUQ-defaults-p32,RobustAHRSQ-defaults-p8,"
           "RobustAHRSQ-defaults-p32,RobustAHRSQ-learn-p8")
#: (file stem under csrc/fixed, update, filter type, number of input vectors)
UPDATES = (("gravity_q", "imf_kk_q_update", "imf_kk_q_t", 2),
           ("gravity_q", "imf_multiwii_q_update", "imf_multiwii_q_t", 2),
           ("madgwick_q", "imf_madgwick_imu_q_update", "imf_madgwick_imu_q_t", 2),
           ("mahony_q", "imf_mahony_imu_q_update", "imf_mahony_imu_q_t", 2),
           ("robust_q", "imf_robust_imu_q_update", "imf_robust_imu_q_t", 2),
           ("robust_q", "imf_robust_ahrs_q_update", "imf_robust_ahrs_q_t", 3))


def apply_form(tree: Path, form: str) -> None:
    """Rewrite the six 3-D updates of the copy ``tree`` in ``form``."""
    for stem, func, typ, n in UPDATES:
        hp, cp = tree / "csrc" / "fixed" / f"{stem}.h", tree / "csrc" / "fixed" / f"{stem}.c"
        h, c = hp.read_text(), cp.read_text()
        vs = "gam"[:n]
        scalars = ", ".join(f"int16_t {v}{a}" for v in vs for a in "xyz")
        arrays = ", ".join(f"{v}{v}[3] = {{ {v}x, {v}y, {v}z }}" for v in vs)
        array_params = ", ".join(f"const int16_t {v}[3]" for v in ("gyr", "acc", "mag")[:n])
        names = ", ".join(v + v for v in vs)
        decl = re.compile(r"void " + func + r"\(([^)]*)\);")
        definition = re.compile(r"void " + func + r"\(")
        if not decl.search(h) or len(definition.findall(c)) != 1:
            raise SystemExit(f"{func}: not found once in {stem}.h/.c")
        wrapper = f"static inline void {func}({typ} *self, {scalars})"
        if form in ("F1", "F1b"):
            h = decl.sub(f"void {func}({typ} *self, {scalars});", h)
            body = "static void " if form == "F1" else "__attribute__((noinline)) void "
            c = definition.sub(body + func + "_v(", c)
            c += (f"\nvoid {func}({typ} *const self, {scalars})\n{{\n    const int16_t {arrays};\n"
                  f"    {func}_v(self, {names});\n}}\n")
        elif form == "F2":
            h = decl.sub(lambda _m: f"void {func}_v({typ} *self, {array_params});\n{wrapper};\n{wrapper}\n"
                         f"{{\n    const int16_t {arrays};\n    {func}_v(self, {names});\n}}", h)
            c = definition.sub("void " + func + "_v(", c)
        elif form == "F3":
            end = re.search(r"\}\s*" + typ + ";", h)
            if end is None:
                raise SystemExit(f"{typ}: no typedef in {stem}.h")
            k = h.rfind("typedef struct {", 0, end.start()) + len("typedef struct {")
            h = h[:k] + f"\n    int16_t in[{3 * n}];" + h[k:]
            stores = " ".join(f"self->in[{3 * i + j}] = {v}{a};" for i, v in enumerate(vs)
                              for j, a in enumerate("xyz"))
            h = decl.sub(lambda _m: f"void {func}_v({typ} *self);\n{wrapper};\n{wrapper}\n"
                         f"{{\n    {stores}\n    {func}_v(self);\n}}", h)
            c = definition.sub("static void " + func + "_b(", c)
            ins = ", ".join(f"self->in + {3 * i}" for i in range(n))
            c += f"\nvoid {func}_v({typ} *const self)\n{{\n    {func}_b(self, {ins});\n}}\n"
        else:
            raise SystemExit(f"unknown form {form}")
        hp.write_text(h)
        cp.write_text(c)


def measure(tree: Path, filters: str, targets: str) -> Dict[Tuple[str, str], Tuple[float, int]]:
    """bench/mcu/measure.py run in ``tree`` (its own package first on the path): (filter,
    target) -> (per update, linked flash)."""
    env = dict(os.environ, PYTHONPATH=f"{tree / 'python'}{os.pathsep}{tree}")
    out = subprocess.run([sys.executable, str(tree / "bench" / "mcu" / "measure.py"), "--filters", filters,
                          "--targets", targets, "--no-write", "--no-install", "--jobs", "1"],
                         cwd=tree, env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{tree}: measure.py failed (bits differ?)\n{out.stdout}\n{out.stderr}")
    lines = out.stdout.split("\n\n")[0].splitlines()
    head = [h.strip() for h in lines[0].strip("|").split("|")]
    rows: Dict[Tuple[str, str], Tuple[float, int]] = {}
    for line in lines[2:]:
        cells = [x.strip() for x in line.strip("|").split("|")]
        for t in targets.split(","):
            count = next(i for i, h in enumerate(head) if h.startswith(t + " "))
            rows[(cells[0], t)] = (float(cells[count]), int(cells[count + 1]))
    return rows


CALLERS = r"""
#include <stdint.h>
typedef struct { int32_t t[2]; int16_t in[6]; } f_t;
extern f_t f;
extern int16_t rd(void);
extern int16_t gyr[3], acc[3];
void upd_arr(f_t *self, const int16_t g[3], const int16_t a[3]);
void upd_sc(f_t *self, int16_t gx, int16_t gy, int16_t gz, int16_t ax, int16_t ay, int16_t az);
void upd_self(f_t *self);
static inline void upd_f2(f_t *self, int16_t gx, int16_t gy, int16_t gz, int16_t ax, int16_t ay,
                          int16_t az)
{ const int16_t g[3] = { gx, gy, gz }, a[3] = { ax, ay, az }; upd_arr(self, g, a); }
static inline void upd_f3(f_t *self, int16_t gx, int16_t gy, int16_t gz, int16_t ax, int16_t ay,
                          int16_t az)
{ self->in[0] = gx; self->in[1] = gy; self->in[2] = gz; self->in[3] = ax; self->in[4] = ay;
  self->in[5] = az; upd_self(self); }
void ram_arrays(void) { upd_arr(&f, gyr, acc); }
void ram_scalars(void) { upd_sc(&f, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2]); }
void ram_f2(void) { upd_f2(&f, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2]); }
void ram_f3(void) { upd_f3(&f, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2]); }
void reg_arrays(void) { int16_t g[3], a[3]; g[0] = rd(); g[1] = rd(); g[2] = rd(); a[0] = rd();
  a[1] = rd(); a[2] = rd(); upd_arr(&f, g, a); }
void reg_scalars(void) { int16_t gx = rd(), gy = rd(), gz = rd(), ax = rd(), ay = rd(), az = rd();
  upd_sc(&f, gx, gy, gz, ax, ay, az); }
void reg_f2(void) { int16_t gx = rd(), gy = rd(), gz = rd(), ax = rd(), ay = rd(), az = rd();
  upd_f2(&f, gx, gy, gz, ax, ay, az); }
void reg_f3(void) { int16_t gx = rd(), gy = rd(), gz = rd(), ax = rd(), ay = rd(), az = rd();
  upd_f3(&f, gx, gy, gz, ax, ay, az); }
"""
#: AVR cycles of the instructions the callers use (every other one takes 1)
AVR_CYCLES = {"lds": 2, "sts": 2, "ld": 2, "ldd": 2, "st": 2, "std": 2, "push": 2, "pop": 2,
              "ret": 4, "sbiw": 2, "adiw": 2, "rjmp": 2}


def callers() -> None:
    """The call sites alone: bytes on both cores, cycles on AVR."""
    with tempfile.TemporaryDirectory(prefix="imf_callers_") as tmp:
        src = Path(tmp) / "callers.c"
        src.write_text(CALLERS)
        sizes: Dict[str, Dict[str, int]] = {}
        cycles: Dict[str, int] = {}
        for core, cc, nm, objdump in (
                ("avr", ["avr-gcc", "-mmcu=atmega328p"], "avr-nm", "avr-objdump"),
                ("m0", ["arm-none-eabi-gcc", "-mcpu=cortex-m0", "-mthumb"], "arm-none-eabi-nm", None)):
            obj = Path(tmp) / f"{core}.o"
            subprocess.run([*cc, "-std=c99", "-O2", "-ffp-contract=off", "-ffunction-sections", "-c",
                            str(src), "-o", str(obj)], check=True)
            for line in subprocess.run([nm, "-S", str(obj)], check=True, capture_output=True,
                                       text=True).stdout.splitlines():
                parts = line.split()
                if len(parts) == 4 and parts[2] == "T":
                    sizes.setdefault(parts[3], {})[core] = int(parts[1], 16)
            if objdump:
                fn = None
                for line in subprocess.run([objdump, "-d", str(obj)], check=True, capture_output=True,
                                           text=True).stdout.splitlines():
                    m = re.match(r"[0-9a-f]+ <(\w+)>:", line)
                    if m:
                        fn = m.group(1)
                        cycles[fn] = 0
                        continue
                    m = re.match(r"\s+[0-9a-f]+:\s+(?:[0-9a-f]{2} )+\s*(\w+)", line)
                    if m and fn and m.group(1) not in ("call", "rcall", "jmp"):
                        cycles[fn] += AVR_CYCLES.get(m.group(1), 1)
    print("| caller | AVR cycles | AVR bytes | M0 bytes |\n|---|---|---|---|")
    for fn in sorted(sizes):
        print(f"| {fn} | {cycles[fn]} | {sizes[fn]['avr']} | {sizes[fn]['m0']} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--forms", default=",".join(FORMS))
    ap.add_argument("--filters", default=FILTERS)
    ap.add_argument("--targets", default="avr,m0")
    ap.add_argument("--rev", default="73f407a", help="the tree the forms are applied to")
    ap.add_argument("--callers", action="store_true", help="measure the call sites alone")
    args = ap.parse_args(argv)
    if args.callers:
        callers()
        return 0
    forms = args.forms.split(",")
    with tempfile.TemporaryDirectory(prefix="imf_forms_") as tmp:
        results = {}
        for form in ["arrays", *forms]:
            tree = Path(tmp) / form
            tree.mkdir()
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.rev], check=True,
                                     capture_output=True).stdout
            subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
            if form != "arrays":
                apply_form(tree, form)
            results[form] = measure(tree, args.filters, args.targets)
    for t in args.targets.split(","):
        unit = "cycles" if t == "avr" else "instructions"
        print(f"\n| {t}: {unit} / flash, bytes | arrays | " + " | ".join(forms) + " |")
        print("|---" * (len(forms) + 2) + "|")
        for name in args.filters.split(","):
            n0, f0 = results["arrays"][(name, t)]
            cells = [f"{n0:.0f} / {f0}"]
            for form in forms:
                n, f = results[form][(name, t)]
                cells.append(f"{100 * (n - n0) / n0:+.1f} % / {f - f0:+d}")
            print(f"| {name} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
