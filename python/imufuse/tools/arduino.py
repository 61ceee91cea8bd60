"""The C library as an Arduino library (`imufuse export arduino DIR [--zip]`).

Writes a standard (1.5 format) Arduino library:

    imufuse/library.properties
    imufuse/keywords.txt
    imufuse/src/imufuse.h            umbrella header: every filter of csrc/ and csrc/fixed/
    imufuse/src/*.c *.h, src/fixed/  the C sources as in csrc/ (compiled by the IDE, recursively)
    imufuse/examples/<Sketch>/<Sketch>.ino, example_data.h, input.csv

Each example reads a small built-in input table (in flash), runs one filter, prints the state
after every sample as hex bit patterns (`q <w> <x> <y> <z>`), then `us/update <n>` (micros()
around the update alone) and `end`. input.csv holds the same samples as a log, so that
`imufuse run input.csv ...` shows the same quaternion on a PC (see the sketch's comment).

The numerical contract's flags do not reach an Arduino build (the IDE has no per-library flags;
the AVR core builds with -std=gnu11 -Os -flto). On AVR boards the library is correct without
them: there is no FPU, every float operation is a library call that rounds on its own, so there
is nothing for the compiler to fuse (tests/test_arduino.py runs every AVR example on simavr and
compares every printed bit with imufuse). On ARM boards with an FPU (Cortex-M4F: Nano 33 BLE,
Teensy, Portenta) GCC's gnu default contracts a*b+c into fused multiply-adds; there the results
stay within float32 rounding of imufuse's but not bit for bit: check your build with
`imufuse validate --target cortex-m4f --cflags "<your board's flags>"`.
"""
from __future__ import annotations

import os
import re
import shutil
import zipfile
from pathlib import Path
from typing import Dict, List, Sequence, Tuple

import numpy as np

from .. import __version__
from ..shared.atomic import replacing
from ..shared.resources import csrc_dir
from ..catalogue import entry, resolve_params
from ..io import example_log, read_log
from ..mcu.filters import FilterSpec

__all__ = ["export_arduino", "EXAMPLES", "example_inputs"]

#: the examples: sketch name -> (filter, precision, samples, what it shows)
EXAMPLES: Dict[str, Tuple[str, str, int, str]] = {
    "MadgwickAHRS": ("MadgwickAHRS", "float32", 96,
                     "Madgwick's AHRS (gyro, accelerometer, magnetometer), float32"),
    "RobustAHRS": ("RobustAHRS", "float32", 64,
                   "imufuse's recommended AHRS, float32: for ARM boards (on an Uno it fits, "
                   "but takes about 7 ms per update)"),
    "MahonyIMUQ_Uno": ("MahonyIMUQ", "p32", 96,
                       "Mahony's IMU filter in fixed point (int16 sensor counts, no float "
                       "arithmetic in the update): for an Uno"),
    "RobustIMUQ_Uno": ("RobustIMUQ", "p8", 96,
                       "imufuse's recommended filter (gyro and accelerometer) in fixed point "
                       "(int16 sensor counts): for an Uno"),
    "RobustAHRSQ_Uno": ("RobustAHRSQ", "p8", 96,
                        "imufuse's recommended filter with a magnetometer in fixed point "
                        "(int16 sensor counts, heading from the field): for an Uno"),
}
#: where the examples' samples start in the shipped log (a stretch with rotation)
FIRST_SAMPLE = 3000
#: the sensor scales of the fixed-point example (a 16-bit MEMS IMU at 2000 deg/s, 8 g)
GYR_SCALE = 1.0642e-3    # rad/s per count
ACC_COUNTS = 4096.0      # counts per g
MAG_COUNTS = 1 / 0.15    # magnetometer counts per uT (0.15 uT per count)


def example_inputs(name: str) -> Tuple[float, Dict[str, np.ndarray]]:
    """(dt, inputs) of an example: samples of the shipped BROAD excerpt, float32 (or int16
    counts for the fixed-point example)."""
    filt, precision, n, _ = EXAMPLES[name]
    log = read_log(example_log())
    sl = slice(FIRST_SAMPLE, FIRST_SAMPLE + n)
    dt = float(log.dt)
    if precision.startswith("p"):
        g = np.clip(np.rint(log.gyr[sl] / GYR_SCALE), -32768, 32767).astype(np.int16)
        a = np.clip(np.rint(log.acc[sl] * ACC_COUNTS), -32768, 32767).astype(np.int16)
        out = {"gyr": g, "acc": a}
        if entry(filt).kind == "ahrs":
            out["mag"] = np.clip(np.rint(log.mag[sl] * MAG_COUNTS), -32768, 32767).astype(np.int16)
        return dt, out
    ins = {"gyr": log.gyr[sl].astype(np.float32), "acc": log.acc[sl].astype(np.float32)}
    if entry(filt).kind == "ahrs":
        ins["mag"] = log.mag[sl].astype(np.float32)
    return dt, ins


def example_spec(name: str) -> FilterSpec:
    filt, precision, _, _ = EXAMPLES[name]
    dt, _ = example_inputs(name)
    params = resolve_params(filt, dt)
    if precision.startswith("p"):
        params["gyr_scale"] = GYR_SCALE
    return FilterSpec.make(entry(filt).reference, params, precision)


def _table(name: str, a: np.ndarray) -> List[str]:
    if a.dtype == np.int16:
        ctype, vals = "int16_t", [str(int(v)) for v in a.reshape(-1)]
    else:
        ctype, vals = "uint32_t", [f"0x{int(v):08x}UL" for v in a.reshape(-1).view(np.uint32)]
    rows = [", ".join(vals[k:k + 6]) for k in range(0, len(vals), 6)]
    return [f"static const {ctype} example_{name}[{len(vals)}] PROGMEM = {{"] + \
        [f"    {r}," for r in rows] + ["};"]


def _sketch(name: str) -> Tuple[str, str, str]:
    """(sketch.ino, example_data.h, input.csv) of an example."""
    filt, precision, n, what = EXAMPLES[name]
    dt, ins = example_inputs(name)
    spec = example_spec(name)
    _, init, step, state = spec.c_parts("f")
    c = spec.c
    fixed = precision.startswith("p")
    data = [f"/* {name}: generated by imufuse {__version__} (imufuse export arduino). */",
            "#ifndef EXAMPLE_DATA_H", "#define EXAMPLE_DATA_H", "#include <stdint.h>",
            "#if defined(__AVR__)\n#include <avr/pgmspace.h>\n#else\n#define PROGMEM\n"
            "#define pgm_read_word(p) (*(const uint16_t *)(p))\n"
            "#define pgm_read_dword(p) (*(const uint32_t *)(p))\n#endif",
            f"#define EXAMPLE_N {n}u", f"/* sample period: {dt!r} s */"]
    for k, a in ins.items():
        data += _table(k, np.ascontiguousarray(a))
    data += ["#endif"]
    inputs = list(ins)
    width = "uint16_t" if fixed else "uint32_t"
    rd = "pgm_read_word" if fixed else "pgm_read_dword"
    elem = "int16_t" if fixed else "float"
    load = []
    for k in inputs:
        load.append(f"        for (j = 0; j < 3; ++j) {{\n            {width} w = "
                    f"{rd}(&example_{k}[3 * i + j]);\n            memcpy(&{k}[j], &w, sizeof w);"
                    f"\n        }}")
    call = step
    n_q = 4
    qexpr = [e for e, _ in state[:n_q]]
    qtype = "int32_t" if fixed else "float"
    init_line = init if "IMF_FAULT" not in init else \
        init.replace('imf_port_write("IMF_FAULT ' + spec.label + ' init\\n");',
                     'Serial.println(F("init failed: a constant out of range"));')
    scale = ("q30 integers (divide by 2^30)" if fixed else "float32")
    run_cmd = (f"imufuse run input.csv -f {filt} --dtype float32 --init identity --fixed-rate "
               f"-o out.npz" if not fixed else
               f"python -c \"from imufuse.tools.arduino import reference_states; "
               f"print(reference_states('{name}'))\"")
    ino = f"""/*
 * {name}: {what}.
 * Generated by imufuse {__version__} (imufuse export arduino).
 *
 * Runs {filt} over {n} samples of a real recording (BROAD trial 3, CC BY 4.0, in
 * example_data.h, stored in flash) and prints, after every sample, the quaternion as the bit
 * patterns of its {scale} components:
 *     q <w> <x> <y> <z>
 * then the microseconds one update took on average (micros() around the update alone):
 *     us/update <n>
 * The same samples are in input.csv; on a PC, imufuse computes the same bits:
 *     {run_cmd}
 */
#include <string.h>
#include <imufuse.h>
#include "example_data.h"

static {c.c_name}_t f;
static {elem} gyr[3], acc[3]{", mag[3]" if "mag" in inputs else ""};

static void print_hex32(uint32_t v)
{{
    static const char digits[] = "0123456789abcdef";
    char s[9];
    int k;
    for (k = 7; k >= 0; --k) {{
        s[k] = digits[v & 0xFu];
        v >>= 4;
    }}
    s[8] = '\\0';
    Serial.print(' ');
    Serial.print(s);
}}

void setup()
{{
    uint16_t i;
    uint8_t j;
    uint32_t us = 0;
    Serial.begin(115200);
    /* {filt}({", ".join(f"{k}={v!r}" for k, v in spec.params.items())}) */
    {init_line}
    for (i = 0; i < EXAMPLE_N; ++i) {{
        /* the next sample, out of flash */
{chr(10).join(load)}
        uint32_t t0 = micros();
        {call}
        us += micros() - t0;
        {qtype} q[4] = {{ {", ".join(qexpr)} }};
        Serial.print('q');
        for (j = 0; j < 4; ++j) {{
            uint32_t bits;
            memcpy(&bits, &q[j], sizeof bits);
            print_hex32(bits);
        }}
        Serial.println();
    }}
    Serial.print(F("us/update "));
    Serial.println(us / EXAMPLE_N);
    Serial.println(F("end"));
}}

void loop()
{{
}}
"""
    # input.csv: the samples as a log (time, gyro rad/s, accelerometer g, magnetometer)
    if fixed:
        g = ins["gyr"].astype(np.float64) * GYR_SCALE
        a = ins["acc"].astype(np.float64) / ACC_COUNTS
        cols = {"gyr": g, "acc": a}
        if "mag" in ins:
            cols["mag"] = ins["mag"].astype(np.float64) / MAG_COUNTS
    else:
        cols = {k: v.astype(np.float64) for k, v in ins.items()}
    head = ["time"] + [f"{k}_{ax}" for k in cols for ax in "xyz"]
    lines = [",".join(head)]
    for i in range(n):
        vals = [repr(i * dt)] + [repr(float(v)) for k in cols for v in cols[k][i]]
        lines.append(",".join(vals))
    return ino, "\n".join(data) + "\n", "\n".join(lines) + "\n"


def reference_states(name: str) -> np.ndarray:
    """What an example prints: (N, 4) bit patterns (uint32) of imufuse's quaternion after every
    sample, from imufuse_c with the example's parameters and inputs."""
    spec = example_spec(name)
    _, ins = example_inputs(name)
    f = spec.reference()
    S = np.asarray(f.run(*ins.values()))[:, :4]
    return S.astype(np.int32).view(np.uint32) if S.dtype.kind == "i" else S.view(np.uint32)


def _properties() -> str:
    return "\n".join([
        "name=imufuse",
        f"version={__version__}",
        "author=imufuse",
        "maintainer=imufuse",
        "sentence=IMU fusion filters: complementary, Kalman, Mahony, Madgwick, DCM, x-io Fusion "
        "and a recommended AHRS, in float32 and fixed point.",
        "paragraph=The filters of OlliW's article 'IMU Data Fusing' as plain C99, bit for bit "
        "equal to imufuse's Python reference (no malloc, no globals). Fixed-point variants for "
        "boards without an FPU.",
        "category=Sensors",
        "url=https://pypi.org/project/imufuse/",
        "architectures=*",
        "includes=imufuse.h",
        ""])


def _keywords(headers: Sequence[Path]) -> str:
    types: set = set()
    funcs: set = set()
    for h in headers:
        text = h.read_text()
        types.update(re.findall(r"\}\s*(imf_\w+_t)\s*;", text))
        funcs.update(m for m in re.findall(r"\b(imf_\w+)\s*\(", text)
                     if not m.startswith("imf_fx_"))
    out = ["# imufuse: syntax colouring (Arduino IDE)"]
    out += [f"{t}\tKEYWORD1" for t in sorted(types)]
    out += [f"{f}\tKEYWORD2" for f in sorted(funcs) if f not in types]
    return "\n".join(out) + "\n"


def export_arduino(dest: "str | os.PathLike[str]", make_zip: bool = False) -> Path:
    """Write the Arduino library into dest/imufuse (and dest/imufuse-<version>.zip); returns
    the library directory. Neither may exist yet (FileExistsError before anything is
    written); the zip is written whole or not at all."""
    dest = Path(dest)
    lib = dest / "imufuse"
    z = dest / f"imufuse-{__version__}.zip"
    for p in (lib, z) if make_zip else (lib,):
        if os.path.lexists(p):
            raise FileExistsError(f"{p} exists: give a new directory")
    src = lib / "src"
    csrc = Path(csrc_dir())
    (src / "fixed").mkdir(parents=True)
    headers = []
    for p in sorted(csrc.glob("*.[ch]")):
        shutil.copy(p, src / p.name)
        if p.suffix == ".h":
            headers.append(src / p.name)
    for p in sorted((csrc / "fixed").glob("*.[ch]")):
        shutil.copy(p, src / "fixed" / p.name)
        if p.suffix == ".h":
            headers.append(src / "fixed" / p.name)
    api = [h for h in headers if re.search(r"\bvoid\s+imf_\w+_update|int\s+imf_\w+_init",
                                           h.read_text())]
    (src / "imufuse.h").write_text(
        "/* imufuse: every filter of the library (generated by imufuse export arduino). */\n"
        "#ifndef IMUFUSE_H\n#define IMUFUSE_H\n#include \"imf_version.h\"\n" +
        "".join(f'#include "{h.relative_to(src).as_posix()}"\n' for h in api) + "#endif\n")
    (lib / "library.properties").write_text(_properties())
    (lib / "keywords.txt").write_text(_keywords(headers))
    for name in EXAMPLES:
        d = lib / "examples" / name
        d.mkdir(parents=True)
        ino, data, csv = _sketch(name)
        (d / f"{name}.ino").write_text(ino)
        (d / "example_data.h").write_text(data)
        (d / "input.csv").write_text(csv)
    if make_zip:
        with replacing(z) as tmp, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
            for p in sorted(lib.rglob("*")):
                if p.is_file():
                    zf.write(p, p.relative_to(dest).as_posix())
    return lib


