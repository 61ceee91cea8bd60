"""The C API for people who read headers: every init takes at most four values after the
filter (more go in a settings struct with a ..._default_settings()), every settings member
documents its unit, range and default, and the C defaults are those of the Python classes,
bit for bit, in float32 and in float64."""
import dataclasses
import inspect
import math
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from imufuse import catalogue
from imufuse.reference._settings import FIXED
from imufuse.shared import cproto

ROOT = Path(__file__).resolve().parents[1]
CSRC = ROOT / "csrc"
HEADER_FILES = sorted(CSRC.glob("*.h")) + sorted((CSRC / "fixed").glob("*.h"))
HEADERS = "\n".join(h.read_text() for h in HEADER_FILES)
ENTRIES = [*catalogue.FLOAT, *catalogue.FIXED, *catalogue.VARIO]
INIT = re.compile(r"\b(imf_\w+_init\w*)\s*\(")
_INT = re.compile(r"u?int(8|16|32|64)?(_t)?")


def init_functions(text):
    return sorted(set(INIT.findall(cproto.strip_comments(text))))


def with_struct(e):
    got = cproto.init_params(HEADERS, e.c_name + "_init")
    return got is not None and got[0] is not None


SETTINGS = [e for e in ENTRIES if with_struct(e)]


def wide_inits(text):
    out = []
    for f in init_functions(text):
        p = cproto.find_prototype(text, f)
        if p is not None and len(p.params) - 1 > 4:
            out.append(f"{f}: {len(p.params) - 1} values")
    return out


def test_no_init_takes_more_than_four_values():
    """No init in the public headers takes more than four positional values after the
    filter (none of them is a published signature: the article's and Madgwick's code
    have no init)."""
    assert len(init_functions(HEADERS)) >= 20
    assert wide_inits(HEADERS) == []


def test_the_width_check_can_fail():
    text = "int imf_x_init(imf_x_t *self, double a, double b, double c, double d, int e);\n"
    assert wide_inits(text) == ["imf_x_init: 5 values"]


def test_every_filter_with_many_settings_has_a_struct():
    """The filters whose Python class takes more than four C values take a settings struct
    and have a default_settings function; the fixed-point ones with more than four integer
    constants take a constants struct."""
    names = {e.name for e in SETTINGS}
    for e in ENTRIES:
        if len(e.init_args) - (1 if e.fixed and "profile" in e.init_args else 0) > 4:
            assert e.name in names, f"{e.c_name}_init takes no settings struct"
    for e in SETTINGS:
        st = cproto.init_params(HEADERS, e.c_name + "_init")[0]
        assert st == e.c_name + "_settings_t", st
        p = cproto.find_prototype(HEADERS, e.c_name + "_default_settings")
        assert p is not None and [q.ctype for q in p.params] == [st], e.c_name
    assert len(SETTINGS) >= 11


def member_comments(struct):
    """{member: its comment} of `typedef struct {...} struct;` in the headers."""
    m = re.search(r"typedef\s+struct\s*\{([^{}]*)\}\s*" + re.escape(struct) + r"\s*;", HEADERS)
    assert m, struct
    out, last, open_comment = {}, None, False
    for line in m.group(1).split("\n"):
        if open_comment:
            out[last] += " " + line.strip()
            open_comment = "*/" not in line
            continue
        code, _, comment = line.partition("/*")
        d = re.match(r"\s*[\w ]+?\s(\w+)\s*;", code)
        if d:
            last = d.group(1)
            out[last] = comment
            open_comment = bool(comment) and "*/" not in comment
    return out


@pytest.mark.parametrize("e", SETTINGS, ids=[e.name for e in SETTINGS])
def test_every_setting_documents_its_default(e):
    st = cproto.struct_members(HEADERS, e.c_name + "_settings_t")
    alias = re.search(r"typedef\s+(\w+)\s+" + e.c_name + r"_settings_t\s*;", HEADERS)
    comments = member_comments(alias.group(1) if alias else e.c_name + "_settings_t")
    assert [p.name for p in st] == list(comments)
    for name, text in comments.items():
        assert "default" in text, f"{e.c_name}_settings_t.{name}: no default in {text!r}"


def expected_defaults(e):
    """The Python class's C values for its defaults: constructor defaults, the catalogue's
    for the values the constructor requires (or one of a choice it requires, as
    Complementary1D's alpha or T), dt = 0.01."""
    kw = {}
    for name, default in e.params.items():
        if name == "dt":
            kw[name] = 0.01
        elif default is inspect.Parameter.empty or (
                default is None and name in e.defaults):
            kw[name] = e.defaults[name]
    return dict(zip(e.init_args, e.reference._params(**kw)))


def c_defaults_program():
    """One C program printing every <c>_default_settings() member, "Name member value"."""
    lines, includes = [], set()
    for e in SETTINGS:
        header = next(h.name for h in HEADER_FILES
                      if re.search(r"\b" + e.c_name + r"_default_settings\s*\(", h.read_text()))
        includes.add(header)
        lines += ["    {", f"        {e.c_name}_settings_t s;",
                  f"        {e.c_name}_default_settings(&s);"]
        for p in cproto.struct_members(HEADERS, e.c_name + "_settings_t"):
            if _INT.fullmatch(p.ctype):
                lines.append(f'        printf("{e.name} {p.name} %ld\\n", (long)s.{p.name});')
            else:
                lines.append(f'        printf("{e.name} {p.name} %a\\n", (double)s.{p.name});')
        lines.append("    }")
    return "\n".join(["#include <stdio.h>", *(f'#include "{h}"' for h in sorted(includes)),
                      "int main(void)", "{", *lines, "    return 0;", "}", ""])


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = {}
    d = tmp_path_factory.mktemp("settings")
    c = d / "defaults.c"
    c.write_text(c_defaults_program())
    flags = ["gcc", "-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Werror", f"-I{CSRC}",
             f"-I{CSRC / 'fixed'}"]
    # csrc/fixed never reads the precision (test_cross_build.py
    # test_fixed_point_ignores_the_precision): its objects serve both programs
    fixed = d / "fixed"
    fixed.mkdir()
    subprocess.run([*flags, "-c", *sorted(str(p) for p in (CSRC / "fixed").glob("*.c"))],
                   check=True, capture_output=True, text=True, cwd=fixed)
    srcs = sorted(str(p) for p in CSRC.glob("*.c")) + sorted(str(p) for p in fixed.glob("*.o"))
    for double in (False, True):
        exe = d / f"defaults{int(double)}"
        subprocess.run([*flags, *(["-DIMF_DOUBLE"] if double else []), str(c), *srcs, "-o",
                        str(exe), "-lm"], check=True, capture_output=True, text=True)
        text = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
        for e in SETTINGS:
            out[(e.name, double)] = ({}, cproto.struct_members(HEADERS, e.c_name + "_settings_t"))
        for line in text.split("\n"):
            if line:
                name, k, v = line.split()
                out[(name, double)][0][k] = float.fromhex(v) if "0x" in v else int(v)
    return out


@pytest.mark.parametrize("double", [False, True], ids=["float32", "float64"])
@pytest.mark.parametrize("e", SETTINGS, ids=[e.name for e in SETTINGS])
def test_c_defaults_are_the_python_defaults(built, e, double):
    """<c>_default_settings() gives, member by member and bit for bit, the values the
    Python class passes to the C init for its defaults (in the build's imf_real)."""
    vals, members = built[(e.name, double)]
    want = expected_defaults(e)
    names = [p.name for p in members]
    # profile selects the fixed-point update where it is not an init value
    assert names == [a for a in e.init_args if a != "profile" or "profile" in names]
    # a member the class does not take (the other form's of one C type: RobustIMU's
    # magnetometer settings) is the class's own fixed value, not a default to agree on
    fixed = {f.name for f in dataclasses.fields(e.reference.settings_type)
             if f.metadata.get("keyword") == FIXED} if hasattr(e.reference, "settings_type") else set()
    for p in members:
        if p.name in fixed:
            continue
        w = want[p.name]
        if p.ctype == "imf_real" and not double:
            w = float(np.float32(w))
        got = vals[p.name]
        if isinstance(got, float):
            assert math.copysign(1.0, got) == math.copysign(1.0, float(w)) and got == float(w), \
                f"{e.c_name}_settings_t.{p.name}: C {got!r}, Python {w!r}"
        else:
            assert got == int(w), f"{e.c_name}_settings_t.{p.name}: C {got!r}, Python {w!r}"


def test_the_defaults_check_can_fail(built):
    e = next(e for e in SETTINGS if e.name == "RobustAHRS")
    vals, _ = built[(e.name, False)]
    want = expected_defaults(e)
    # sin(10 deg) rounded through float32 once: the C literal must give exactly that
    assert vals["mag_dip"] == float(np.float32(want["mag_dip"]))
    assert vals["mag_dip"] != want["mag_dip"]


def test_python_sets_a_filter_through_the_settings_struct():
    """The Cython binding fills the settings struct from the Python class's values by
    name: a filter made with non-default settings differs from the default one and
    equals the twin bit for bit."""
    import imufuse_c
    from imufuse import reference
    kw = dict(dt=0.004, tau_acc=1.5, rate_ref=50.0, tau_bias=30.0, tau_bias_rest=2.0,
              rest_gyr=1.0, rest_acc=0.04, rest_time=1.0, tau_rest=0.3, latency=0.002,
              tau_mag=5.0, mag_norm=0.2, mag_dip=20.0, tau_mag_ref=10.0, mag_new_time=5.0,
              mag_hold=0.3)
    rng = np.random.default_rng(3)
    n = 3000
    gyr = rng.normal(0, 0.3, (n, 3))
    acc = np.array([0.1, 0.2, 9.7]) + rng.normal(0, 0.2, (n, 3))
    mag = np.array([20.0, 0.0, -40.0]) + rng.normal(0, 1.0, (n, 3))
    for dtype in ("float32", "float64"):
        c = imufuse_c.RobustAHRS(**kw, dtype=dtype).run(gyr, acc, mag)
        r = reference.RobustAHRS(**kw, dtype=dtype).run(gyr[:300], acc[:300], mag[:300])
        d = imufuse_c.RobustAHRS(0.004, dtype=dtype).run(gyr, acc, mag)
        assert np.array_equal(c[:300].view(np.uint8), np.asarray(r).view(np.uint8))
        assert not np.array_equal(c, d)


def test_fixed_c_init_call_compiles_and_equals_the_double_init(tmp_path):
    """The reference's c_init_call() (the firmware's integer-only init, printed for users)
    is valid C99 for every fixed-point filter, returns 0, and builds the struct that
    <c>_init builds from the same settings, byte for byte, on the host."""
    from imufuse import catalogue as cat
    body, pre = [], ["#include <stdio.h>", "#include <string.h>"]
    for i, e in enumerate(cat.FIXED):
        f = e.make("ref", dt=0.004, **e.defaults)
        header = next(h.name for h in HEADER_FILES
                      if re.search(r"\b" + e.c_name + r"_init_consts\s*\(", h.read_text()))
        pre.append(f'#include "{header}"')
        struct, params = cproto.init_params(HEADERS, e.c_name + "_init")
        kw = dict(zip(e.init_args, e.reference._params(dt=0.004, **e.defaults)))
        vals = [repr(float(kw[p.name])) if p.ctype == "double" else str(int(kw[p.name]))
                for p in params]
        dbl = (f"{e.c_name}_init(&b{i}, &({struct}){{{', '.join(vals)}}})" if struct
               else f"{e.c_name}_init(&b{i}, {', '.join(vals)})")
        call = f.c_init_call(f"a{i}").rstrip(";")
        body += [f"    {{ static {e.c_name}_t a{i}, b{i}; int r = {call};",
                 f"      int s = {dbl};",
                 f'      printf("{e.name} %d %d %d\\n", r, s, memcmp(&a{i}, &b{i}, sizeof a{i}) != 0); }}']
    src = tmp_path / "calls.c"
    src.write_text("\n".join(pre + ["int main(void)", "{"] + body + ["    return 0;", "}", ""]))
    exe = tmp_path / "calls"
    subprocess.run(["gcc", "-std=c99", "-pedantic", "-Wall", "-Werror", "-O2", "-ffp-contract=off",
                    f"-I{CSRC}", f"-I{CSRC / 'fixed'}", str(src),
                    *sorted(str(p) for p in (CSRC / "fixed").glob("*.c")), "-o", str(exe), "-lm"],
                   check=True, capture_output=True, text=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split("\n")
    got = {line.split()[0]: line.split()[1:] for line in out if line}
    assert set(got) == {e.name for e in cat.FIXED}
    assert all(v == ["0", "0", "0"] for v in got.values()), got


def test_the_c_examples_of_the_docs_compile(tmp_path):
    """Every ```c block of docs/firmware.md compiles as written against csrc/ (C99,
    -Wall -Werror), so the documented init calls are the API's."""
    text = (ROOT / "docs" / "firmware.md").read_text()
    blocks = re.findall(r"```c\n(.*?)```", text, flags=re.S)
    assert len(blocks) >= 2
    for i, b in enumerate(blocks):
        src = tmp_path / f"doc{i}.c"
        src.write_text(b)
        p = subprocess.run(["gcc", "-std=c99", "-pedantic", "-Wall", "-Werror",
                            "-Wno-unused-function", f"-I{CSRC}", f"-I{CSRC / 'fixed'}", "-c",
                            str(src), "-o", str(tmp_path / f"doc{i}.o")],
                           capture_output=True, text=True)
        assert p.returncode == 0, f"docs/firmware.md C block {i + 1}:\n{b}\n{p.stderr}"


def test_fixed_settings_outside_the_documented_ranges_are_refused(tmp_path):
    """The ranges the fixed-point settings document are the C's: a profile other than 32 or 8,
    a MultiWiiQ window of 0 and a KKQ kp above 1 make init return -1 (the twin refuses them
    too)."""
    src = tmp_path / "ranges.c"
    src.write_text("\n".join([
        "#include <stdio.h>", '#include "mahony_q.h"', '#include "gravity_q.h"',
        '#include "madgwick_q.h"',
        "int main(void)", "{",
        "    imf_mahony_imu_q_t m; imf_mahony_imu_q_settings_t ms;",
        "    imf_multiwii_q_t w; imf_multiwii_q_settings_t ws;",
        "    imf_madgwick_imu_q_t g; imf_madgwick_imu_q_settings_t gs;",
        "    imf_kk_q_t k; imf_kk_q_settings_t ks;",
        "    imf_mahony_imu_q_default_settings(&ms); imf_multiwii_q_default_settings(&ws);",
        "    imf_madgwick_imu_q_default_settings(&gs); imf_kk_q_default_settings(&ks);",
        '    printf("%d ", imf_mahony_imu_q_init(&m, &ms));',
        '    ms.profile = 16; printf("%d ", imf_mahony_imu_q_init(&m, &ms));',
        '    printf("%d ", imf_multiwii_q_init(&w, &ws));',
        '    ws.window = 0.0; printf("%d ", imf_multiwii_q_init(&w, &ws));',
        '    printf("%d ", imf_madgwick_imu_q_init(&g, &gs));',
        '    gs.profile = 16; printf("%d ", imf_madgwick_imu_q_init(&g, &gs));',
        '    printf("%d ", imf_kk_q_init(&k, &ks));',
        '    ks.kp = 1.5; printf("%d\\n", imf_kk_q_init(&k, &ks));',
        "    return 0;", "}", ""]))
    exe = tmp_path / "ranges"
    subprocess.run(["gcc", "-std=c99", "-O2", f"-I{CSRC}", f"-I{CSRC / 'fixed'}", str(src),
                    *sorted(str(p) for p in (CSRC / "fixed").glob("*.c")), "-o", str(exe),
                    "-lm"], check=True, capture_output=True, text=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split()
    assert out == ["0", "-1", "0", "-1", "0", "-1", "0", "-1"], out
    from imufuse.reference import KKQ, MadgwickIMUQ, MahonyIMUQ, MultiWiiQ
    with pytest.raises(ValueError):
        MahonyIMUQ(0.01, gyr_scale=1e-3, profile="16")
    with pytest.raises(ValueError):
        MadgwickIMUQ(0.01, gyr_scale=1e-3, profile="16")
    with pytest.raises(ValueError, match="kp"):
        KKQ(0.01, 1.5, gyr_scale=1e-3)
    with pytest.raises(ValueError, match="window"):
        MultiWiiQ(0.01, acc_1g=4096, window=0.0, gyr_scale=1e-3)


RECORDED = [e for e in (*catalogue.FLOAT, *catalogue.VARIO)]


@pytest.mark.parametrize("e", RECORDED, ids=[e.name for e in RECORDED])
def test_the_twins_settings_record_is_the_c_struct(e):
    """Every float filter declares its settings once, as a record that mirrors its C
    settings struct member for member (names, order, integer or real), each member with
    its unit, its check and its conversion beside it; the constructor's keywords, the
    catalogue's init arguments and the binding's struct all come from it."""
    rec = e.reference.settings_type
    members = cproto.struct_members(HEADERS, e.c_name + "_settings_t")
    assert [f.name for f in dataclasses.fields(rec)] == [m.name for m in members]
    for f, m in zip(dataclasses.fields(rec), members):
        assert {"default", "unit", "check", "to_c"} <= set(f.metadata), f.name
        assert (f.type is int) == bool(_INT.fullmatch(m.ctype)), (f.name, f.type, m.ctype)
    assert e.init_args == tuple(m.name for m in members)
    assert str(inspect.signature(e.reference._params)) == str(rec.signature())
    made = e.reference._params(**e.defaults, **({"dt": 0.01} if "dt" in e.params else {}))
    assert isinstance(made, rec)



def test_the_recommended_filters_parameter_table_is_its_record():
    """docs/recommended-ahrs.md's parameter table lists RobustAHRS's settings record: every
    member but dt, in order, with the record's default and unit."""
    text = (ROOT / "docs" / "recommended-ahrs.md").read_text()
    table = text[text.index("### Parameters"):]
    rows = re.findall(r"^\| `(\w+)` \| ([^|]*) \| ([^|]*) \|", table, re.M)
    rec = catalogue.entry("RobustAHRS").reference.settings_type
    want = [f for f in dataclasses.fields(rec) if f.name != "dt"]
    assert [r[0] for r in rows[:len(want)]] == [f.name for f in want]
    for (name, default, unit), f in zip(rows, want):
        d = f.metadata["default"]
        assert (default.strip() == str(d) if isinstance(d, bool)
                else float(default) == d), (name, default, d)
        assert unit.strip() == f.metadata["unit"], (name, unit, f.metadata["unit"])


@pytest.mark.parametrize("profile", [None, "32", "8"])
def test_fixed_default_settings_give_a_profile_the_build_has(tmp_path, profile):
    """A build of one fixed-point profile (the Makefile's and CMake's FIXED_PROFILE=8, the
    ATmega328P's choice) gave default settings of profile 32, which its init refused (-1):
    the documented default_settings + init failed there. default_settings now gives the
    profile the build compiles (32 when both are)."""
    from imufuse import catalogue as cat
    pre, body = ["#include <stdio.h>"], []
    # the fixed-point filters whose settings have a profile (the catalogue's)
    two = [e.c_name for e in cat.FIXED
           if "profile" in [p.name for p in cproto.init_params(HEADERS, e.c_name + "_init")[1]]]
    assert len(two) == 4, two
    for c in two:
        pre.append("#include \"" + next(h.name for h in HEADER_FILES
                                        if re.search(r"\b" + c + r"_default_settings\s*\(",
                                                     h.read_text())) + "\"")
        body += [f"    {{ static {c}_t f; {c}_settings_t s; {c}_default_settings(&s);",
                 f'      printf("{c} %d %d\\n", s.profile, {c}_init(&f, &s)); }}']
    src = tmp_path / "defaults.c"
    src.write_text("\n".join(sorted(set(pre), key=pre.index) + ["int main(void)", "{"] + body
                             + ["    return 0;", "}", ""]))
    exe = tmp_path / "defaults"
    flags = [] if profile is None else [f"-DIMF_FIXED_PROFILE={profile}"]
    subprocess.run(["gcc", "-std=c99", "-pedantic", "-Wall", "-Werror", "-O2", "-ffp-contract=off",
                    *flags, f"-I{CSRC}", f"-I{CSRC / 'fixed'}", str(src),
                    *sorted(str(p) for p in (CSRC / "fixed").glob("*.c")), "-o", str(exe), "-lm"],
                   check=True, capture_output=True, text=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split()
    want = "8" if profile == "8" else "32"
    assert out[1::3] == [want] * 4 and out[2::3] == ["0"] * 4, out
