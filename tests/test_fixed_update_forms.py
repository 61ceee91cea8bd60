"""The two forms of a fixed-point 3-D update compute the same thing: `<c_name>_update`, which
takes the sample as the float updates do (scalars gx, gy, gz, ax, ay, az[, mx, my, mz]; a
static inline in the header), and `<c_name>_update_v` (arrays; the code of the update). A host
program runs every 3-D fixed-point filter of the catalogue, in each of its profiles, from its
default settings through a few hundred samples twice, once per form, and compares the whole
filter struct (constants and state) byte for byte after every sample."""
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from imufuse import catalogue
from imufuse.shared import cproto

ROOT = Path(__file__).resolve().parents[1]
FIXED = ROOT / "csrc" / "fixed"
HEADERS = "\n".join(h.read_text() for h in sorted(FIXED.glob("*.h")))
ENTRIES = [e for e in catalogue.FIXED if e.kind != "1d"]
N = 400


def test_every_3d_filter_has_both_forms():
    """Each 3-D filter's scalar update is a static inline taking the float update's inputs,
    and its array form is what the twin names c_update_v."""
    assert len(ENTRIES) >= 6
    for e in ENTRIES:
        ref = e.reference
        assert ref.c_update_v == ref.c_update + "_v"
        scalar = cproto.find_prototype(HEADERS, ref.c_update)
        arrays = cproto.find_prototype(HEADERS, ref.c_update_v)
        assert scalar is not None and arrays is not None, ref.c_update
        names = [f"{v}{a}" for v in "gam"[:len(e.inputs)] for a in "xyz"]
        assert [p.name for p in scalar.params[1:]] == names
        assert all(p.ctype == "int16_t" and not p.vector for p in scalar.params[1:])
        assert [p.name for p in arrays.params[1:]] == list(e.inputs)
        assert all(p.vector for p in arrays.params[1:])
        assert re.search(r"static inline void " + ref.c_update + r"\(", HEADERS)
    for e in catalogue.FIXED:
        if e.kind == "1d":
            assert e.reference.c_update_v == e.reference.c_update


def _program() -> str:
    out = ["#include <stdio.h>", "#include <string.h>", "#include <stdint.h>",
           *(f'#include "{h.name}"' for h in sorted(FIXED.glob("*_q.h"))), "",
           "static uint32_t seed = 12345u;",
           "static int16_t rnd(int lo, int hi) /* uniform in [lo, hi] */",
           "{",
           "    seed = seed * 1664525u + 1013904223u;",
           "    return (int16_t)(lo + (int32_t)((seed >> 8) % (uint32_t)(hi - lo + 1)));",
           "}",
           "/* sample k: a slow turn with noise, every 37th at full scale, every 53rd all zero */",
           "static void sample(int k, int16_t v[9])",
           "{",
           "    int i;",
           "    const int16_t base[9] = {0, 0, 0, 0, 0, 4096, 300, 0, -400};",
           "    for (i = 0; i < 9; ++i) v[i] = (int16_t)(base[i] + rnd(-200, 200));",
           "    v[2] = (int16_t)(v[2] + (k / 50 % 2 ? 600 : -600));",
           "    if (k % 37 == 36) for (i = 0; i < 9; ++i) v[i] = rnd(-32768, 32767);",
           "    if (k % 53 == 52) for (i = 0; i < 9; ++i) v[i] = 0;",
           "}", ""]
    main = ["int main(void)", "{", "    int bad = 0;"]
    for e in ENTRIES:
        ref, c = e.reference, e.c_name
        settings, members = cproto.init_params(HEADERS, c + "_init")
        profiles = ["32", "8"] if any(m.name == "profile" for m in members) else [""]
        n = len(e.inputs)
        scalars = ", ".join(f"v[{i}]" for i in range(3 * n))
        arrays = ", ".join(f"v + {3 * i}" if i else "v" for i in range(n))
        for p in profiles:
            label = e.name + (f"-p{p}" if p else "")
            main += ["    {",
                     f"        static {c}_t a, b;",
                     f"        {settings} s;",
                     "        int k, first = -1;",
                     f"        {c}_default_settings(&s);",
                     *([f"        s.profile = {p};"] if p else []),
                     "        memset(&a, 0, sizeof a);",
                     "        memset(&b, 0, sizeof b);",
                     f"        if ({c}_init(&a, &s) != 0 || {c}_init(&b, &s) != 0) {{",
                     f'            printf("{label} init failed\\n");',
                     "            return 2;",
                     "        }",
                     "        seed = 12345u;",
                     f"        for (k = 0; k < {N}; ++k) {{",
                     "            int16_t v[9];",
                     "            sample(k, v);",
                     f"            {ref.c_update}(&a, {scalars});",
                     f"            {ref.c_update_v}(&b, {arrays});",
                     "            if (first < 0 && memcmp(&a, &b, sizeof a) != 0) first = k;",
                     "        }",
                     f'        printf("{label} %d %d\\n", first, (int)sizeof a.x);',
                     "        bad |= first >= 0;",
                     "    }"]
    main += ["    return bad;", "}", ""]
    return "\n".join(out + main)


def test_scalar_and_array_updates_give_the_same_bits(tmp_path):
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no host C compiler")
    src = tmp_path / "forms.c"
    src.write_text(_program())
    exe = tmp_path / "forms"
    build = subprocess.run([cc, "-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra",
                            "-pedantic", "-Werror", f"-I{FIXED}", str(src),
                            *map(str, sorted(FIXED.glob("*.c"))), "-o", str(exe), "-lm"],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True)
    lines = run.stdout.split("\n")[:-1]
    assert len(lines) >= 9, run.stdout + run.stderr
    for line in lines:
        label, first, _ = line.split()
        assert first == "-1", f"{label}: the two forms differ from sample {first}"
    assert run.returncode == 0, run.stdout
