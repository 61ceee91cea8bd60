"""What validate names when firmware differs on the host (imufuse.firmware.diagnostics,
imufuse.firmware.sanitize): causes planted in small Kalman1D-style firmware (globals,
att_begin(k0), att_step(gyro, acc_angle, dt)), each named with file:line and, for undefined
behaviour, the sample:

- a signed int counter that overflows and feeds the state (UBSan, at the divergent sample);
- a left shift of a negative value (UBSan, after a divergence of its own);
- a lookup table read one past its end (UBSan's bounds check);
- the fast inverse square root through `*(long *)&y` (ASan: an 8-byte read of a 4-byte float;
  the data model; the strict-aliasing warning), also in the Arduino Madgwick class of
  tests/declared;
- a double literal (the double-promotion cause, confirmed, then the warnings);
- a re-associated sum: no compiler cause (not FMA), the code run up to the divergence;
- a changed constant: named, and confirmed by rebuilding with the parameter's value.
"""
import os
import re
import stat

import numpy as np
import pytest

from imufuse import sim
from imufuse.catalogue import inputs_for, resolve_params
from imufuse.firmware import Firmware, validate
from imufuse.firmware.causes import Cause, ordered
from imufuse.firmware.diagnostics import _preprocessed, constants, data_model
from imufuse.firmware.sanitize import RunInputs, parse_report, sanitize

pytest.importorskip("cffi")

HERE = os.path.dirname(os.path.abspath(__file__))
F32 = np.float32
PARAMS = dict(dt=0.005, k0=0.02)

HEADER = ("extern float att_theta;\nvoid att_begin(float k0);\n"
          "void att_step(float gyro, float acc_angle, float dt);\n")
BASE = """#include <math.h>
float att_theta;
static float att_k0, att_omk0;
void att_begin(float k0) { att_k0 = k0; att_omk0 = 1.0f - k0; att_theta = 0.0f; }
void att_step(float gyro, float acc_angle, float dt)
{
    float pred, th;
    if (!isfinite(gyro) || !isfinite(acc_angle)) return;
    pred = att_theta + gyro * dt;
    th = att_omk0 * pred + att_k0 * acc_angle;
    if (isfinite(th)) att_theta = th;
}
"""


@pytest.fixture(scope="module", autouse=True)
def _cache(tmp_path_factory):
    d = str(tmp_path_factory.mktemp("fw-cache"))
    old = os.environ.get("IMUFUSE_CACHE")
    os.environ["IMUFUSE_CACHE"] = d
    yield d
    if old is None:
        del os.environ["IMUFUSE_CACHE"]
    else:
        os.environ["IMUFUSE_CACHE"] = old


@pytest.fixture(scope="module")
def inputs():
    d = sim.axis1d("fast", rate=200.0, duration=600 / 200.0, seed=3)
    return [d.gyr, d.acc_angle]


def _plant(tmp_path, edits, base=BASE):
    text = base
    for old, new in edits:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    (tmp_path / "att.c").write_text(text)
    (tmp_path / "att.h").write_text(HEADER)
    fw = Firmware([str(tmp_path / "att.c")], headers=["att.h"], include_dirs=[str(tmp_path)],
                  init="att_begin", update="att_step", state={"theta": "att_theta"})
    return fw, text


# the planted causes (also run on a target: tests/test_firmware_causes_target.py)
# a nanosecond clock in an int: it overflows at sample 429 and skips the prediction there
OVERFLOW = [
    ("static float att_k0, att_omk0;", "static float att_k0, att_omk0;\nstatic int att_t_ns;"),
    ("    pred = att_theta + gyro * dt;\n",
     "    att_t_ns += (int)(dt * 1e9f);\n    pred = att_theta + gyro * dt;\n"
     "    if (att_t_ns < 0) pred = att_theta;   /* the clock went backwards */\n")]

# the angle quantised to Q12 and shifted left: undefined from the first negative angle
NEG_SHIFT = [("    th = att_omk0 * pred + att_k0 * acc_angle;\n",
              "    {\n        int q = (int)(acc_angle * 4096.0f);\n"
              "        int q4 = q << 4;\n"
              "        th = att_omk0 * pred + att_k0 * ((float)q4 / 65536.0f);\n"
              "    }\n")]

# a gain table indexed by |gyro| clamped to 4 instead of 3
OUT_OF_BOUNDS = [
    ("static float att_k0, att_omk0;",
     "static float att_k0, att_omk0;\nstatic struct { float gain[4]; float offset; } att_cal;"),
    ("att_theta = 0.0f; }", "att_theta = 0.0f;\n    for (int j = 0; j < 4; ++j) "
                            "att_cal.gain[j] = 1.0f;\n    att_cal.offset = 0.0f; }"),
    ("    pred = att_theta + gyro * dt;\n",
     "    {\n        int idx = (int)fabsf(gyro);\n        if (idx > 4) idx = 4;\n"
     "        pred = att_theta + gyro * dt * att_cal.gain[idx] + att_cal.offset;\n    }\n")]

# a double literal in a float expression
DOUBLE_LITERAL = [
    ("static float att_k0, att_omk0;", "static float att_k0, att_omk0, att_k2;"),
    ("att_omk0 = 1.0f - k0;", "att_omk0 = 1.0f - k0; att_k2 = 2.0f * k0;"),
    ("att_k0 * acc_angle;", "0.5 * att_k2 * acc_angle;")]


def _line(text, marker):
    """The 1-based line of the source holding marker."""
    return next(i + 1 for i, ln in enumerate(text.splitlines()) if marker in ln)


def _only(v, what):
    cs = [c for c in v.causes if c.what == what]
    assert len(cs) == 1, v.text()
    return cs[0]


def test_signed_overflow_is_named_at_its_sample(tmp_path, inputs):
    """A nanosecond clock in an int overflows at sample 429; the wrapped (negative) time
    skips the prediction there: UBSan names the line and that sample."""
    fw, text = _plant(tmp_path, OVERFLOW)
    v = validate(fw, "Kalman1D", PARAMS, inputs)
    k = int(2 ** 31 // 5_000_000)                     # 429: the sum passes 2^31 - 1 there
    assert not v.bit_exact and v.comparison.first_sample == k
    ub = _only(v, "undefined behaviour")
    line = _line(text, "att_t_ns +=")
    assert re.fullmatch(rf"att\.c:{line}:\d+", ub.where) and ub.sample == k
    assert ub.detail == "signed integer overflow" and "type 'int'" in ub.evidence
    assert ub.fix and "16 bits on the ATmega328P" in ub.fix      # established: the cause
    t = v.text()
    assert f"cause: undefined behaviour (signed integer overflow) at {ub.where}, sample {k}" in t
    assert "none of the known build causes" not in t
    assert "att_step (att.c:" in t                    # the code run up to the divergence


def test_shift_of_a_negative_value_is_named_with_its_sample(tmp_path, inputs):
    """The angle quantised to Q12 and shifted: it diverges from sample 0 (the quantisation),
    the shift is undefined from the first negative angle on: named, but not as the cause."""
    fw, text = _plant(tmp_path, NEG_SHIFT)
    v = validate(fw, "Kalman1D", PARAMS, inputs)
    q = np.trunc(F32(inputs[1]).astype(np.float32) * F32(4096.0))
    k = int(np.flatnonzero(q < 0)[0])
    assert v.comparison.first_sample == 0 < k
    ub = _only(v, "undefined behaviour")
    assert re.fullmatch(rf"att\.c:{_line(text, 'q << 4')}:\d+", ub.where)
    assert ub.sample == k and ub.detail == "shift of a negative value"
    assert ub.fix is None and "after the first divergence, at sample 0" in ub.evidence
    assert "none of the known build causes" in v.text()


def test_out_of_bounds_read_of_a_table_is_named(tmp_path, inputs):
    """A gain table indexed by |gyro| clamped to 4 instead of 3 reads the offset behind it."""
    fw, text = _plant(tmp_path, OUT_OF_BOUNDS)
    v = validate(fw, "Kalman1D", PARAMS, inputs)
    k = int(np.flatnonzero(np.abs(F32(inputs[0]).astype(np.float32)) >= 4)[0])
    assert v.comparison.first_sample == k
    ub = _only(v, "undefined behaviour")
    assert re.fullmatch(rf"att\.c:{_line(text, 'att_cal.gain[idx]')}:\d+", ub.where)
    assert ub.sample == k and ub.detail == "index out of bounds"
    assert "index 4 out of bounds for type 'float [4]'" in ub.evidence


INVSQRT = """static float invSqrt(float x)
{
    float halfx = 0.5f * x;
    float y = x;
    long i = *(long*)&y;
    i = 0x5f3759df - (i>>1);
    y = *(float*)&i;
    y = y * (1.5f - (halfx * y * y));
    return y;
}
void att_begin"""


def test_fast_inverse_square_root_through_long(tmp_path, inputs):
    """long is 8 bytes here: the pun reads 4 bytes past the float. Undefined behaviour
    (ASan, sample 0), the data model (confirmed by that run), the strict-aliasing warning;
    in that order."""
    fw, text = _plant(tmp_path, [("void att_begin", INVSQRT),
                                 ("att_k0 * acc_angle;", "att_k0 * acc_angle * (invSqrt(4.0f) * 2.0f);")])
    v = validate(fw, "Kalman1D", PARAMS, inputs)
    line = _line(text, "*(long*)&y")
    ub = _only(v, "undefined behaviour")
    assert ub.where == f"att.c:{line}" and ub.sample == 0 and ub.detail == "type pun"
    assert "read of 8 bytes of 'y' (4 bytes" in ub.evidence
    dm = [c for c in v.causes if c.what == "data model"]
    assert [c.where for c in dm] == [f"att.c:{line}"], v.text()
    assert dm[0].confirmed and "0x5f3759df" in dm[0].evidence and "int32_t" in dm[0].fix
    warn = [c for c in v.causes if c.what == "warning"]
    assert any(c.detail == "-Wstrict-aliasing" and c.where.startswith(f"att.c:{line}:")
               for c in warn)
    kinds = [c.what for c in v.causes]
    assert kinds.index("undefined behaviour") < kinds.index("data model") < kinds.index("warning")
    assert f"cause: data model (type sizes differ between host and targets) at att.c:{line}:" \
        in v.text()


def test_arduino_madgwick_invsqrt_is_named(tmp_path):
    """The classic Arduino MadgwickAHRS class (tests/declared, C++): the same pun, found in
    the C++ harness's program."""
    from imufuse.firmware.declfile import load_declaration
    d = load_declaration(os.path.join(HERE, "declared", "madgwick_arduino.toml"))
    s = sim.imu("fast", rate=200.0, duration=0.5, seed=3)
    p = resolve_params(d.filter, s.dt, d.params)
    v = validate(d.firmware, d.filter, p, inputs_for("ahrs", s))
    src = open(os.path.join(HERE, "declared", "MadgwickAHRS.cpp")).read()
    line = _line(src, "*(long *)&y")
    ub = _only(v, "undefined behaviour")
    assert (ub.where, ub.sample, ub.detail) == (f"MadgwickAHRS.cpp:{line}", 0, "type pun")
    dm = [c for c in v.causes if c.what == "data model" and c.where == f"MadgwickAHRS.cpp:{line}"]
    assert dm and dm[0].confirmed, v.text()


def test_double_literal_is_still_the_confirmed_cause(tmp_path, inputs):
    fw, text = _plant(tmp_path, DOUBLE_LITERAL)
    v = validate(fw, "Kalman1D", PARAMS, inputs)
    line = _line(text, "0.5 * att_k2")
    assert v.causes[0].what == "double" and v.causes[0].confirmed, v.text()
    assert f"-Wdouble-promotion warns at att.c:{line}:" in v.causes[0].evidence
    assert not any(c.what in ("fma", "undefined behaviour", "data model") for c in v.causes)
    warn = [c for c in v.causes if c.what == "warning"]
    assert warn and warn[0].detail == "-Wdouble-promotion"
    assert f"compiler warning att.c:{line}:" in v.text()
    assert "no undefined behaviour reported" in v.text()


REASSOC = """#include <math.h>
float mb_theta, mb_i;
static float mb_kp, mb_ki_dt, mb_dt;
void mb_begin(float dt, float kp, float ki)
{ mb_dt = dt; mb_kp = kp; mb_ki_dt = ki * dt; mb_theta = 0.0f; mb_i = 0.0f; }
void mb_step(float rate, float angle)
{
    float e, i, theta;
    if (!isfinite(rate) || !isfinite(angle)) return;
    e = angle - mb_theta;
    i = mb_i + mb_ki_dt * e;
    theta = mb_theta + (mb_kp * e + (i + rate)) * mb_dt;
    if (!isfinite(theta) || !isfinite(i)) return;
    mb_theta = theta;
    mb_i = i;
}
"""


MB_PARAMS = dict(dt=0.005, kp=2.0, ki=0.3)


def reassociated(tmp_path):
    """REASSOC as firmware (mb.c, mb.h), declared against Mahony1DBias (MB_PARAMS)."""
    (tmp_path / "mb.c").write_text(REASSOC)
    (tmp_path / "mb.h").write_text("extern float mb_theta, mb_i;\n"
                                   "void mb_begin(float dt, float kp, float ki);\n"
                                   "void mb_step(float rate, float angle);\n")
    return Firmware([str(tmp_path / "mb.c")], headers=["mb.h"], include_dirs=[str(tmp_path)],
                    init="mb_begin", update="mb_step", state={"theta": "mb_theta", "i": "mb_i"})


def test_reassociated_sum_is_not_blamed_on_a_compiler_cause(tmp_path, inputs):
    """(kp*e + i) + rate written kp*e + (i + rate): another computation. No FMA, no double,
    no undefined behaviour; the report says no known build cause and where the code ran."""
    fw = reassociated(tmp_path)
    v = validate(fw, "Mahony1DBias", MB_PARAMS, inputs)
    assert not v.bit_exact and v.comparison.first_sample > 0
    assert [c for c in v.causes if c.what != "warning"] == [], v.text()
    t = v.text()
    assert "none of the known build causes" in t and "fused multiply-add" not in t.split(
        "none of the known build causes")[0]
    assert f"(samples 0-{v.comparison.first_sample}, gcov): mb_begin (mb.c:4-5), " \
        "mb_step (mb.c:6-16)" in t
    assert "no undefined behaviour reported by UBSan and ASan" in t


def test_changed_constant_is_named_and_confirmed(tmp_path, inputs):
    fw, text = _plant(tmp_path, [("att_omk0 = 1.0f - k0;", "att_omk0 = 0.981f;")])
    v = validate(fw, "Kalman1D", PARAMS, inputs)
    c = v.causes[0]
    col = text.splitlines()[3].index("0.981f") + 1
    assert (c.what, c.where, c.confirmed) == ("constant", f"att.c:4:{col}", True), v.text()
    assert "0.981f where 1 - k0 = 0.98 (float32); rebuilt with 0.98f there, the firmware is " \
        "bit-exact" in v.text()
    assert "none of the known build causes" not in v.text()


# ---------------------------------------------------------------------------
# the pieces

ASAN = """=================================================================
==1==ERROR: AddressSanitizer: stack-buffer-overflow on address 0x7ff at pc 0x55 bp 0x7f sp 0x7f
READ of size 8 at 0x7fff90c980d0 thread T0
    #0 0x55e98980f2ab in invSqrt /src/fw/imu.c:5
    #1 0x55e98980f336 in imufuse_fw_run /tmp/x/fw_san_harness.c:11
Address 0x7fff90c980d0 is located in stack of thread T0 at offset 32 in frame
  This frame has 1 object(s):
    [32, 36) 'y' (line 4) <== Memory access at offset 32 partially overflows this variable
SUMMARY: AddressSanitizer: stack-buffer-overflow /src/fw/imu.c:5 in invSqrt

imufuse-sample: 17
"""
UBSAN = """/src/fw/imu.c:12:9: runtime error: signed integer overflow: 2147483647 + 1 cannot be \
represented in type 'int'
    #0 0x55 in step /src/fw/imu.c:12
    #1 0x56 in imufuse_fw_run /tmp/x/fw_san_harness.c:20

imufuse-sample: -1
"""


def test_sanitizer_reports_are_parsed():
    f = parse_report(ASAN, ["/src/fw/imu.c"])
    assert (f.kind, f.where, f.sample, f.tool, f.function) == ("type pun", "imu.c:5", 17,
                                                              "ASan", "invSqrt")
    assert f.message == "stack-buffer-overflow: read of 8 bytes of 'y' (4 bytes, declared at line 4)"
    f = parse_report(UBSAN, ["/src/fw/imu.c"])
    assert (f.kind, f.where, f.sample, f.tool) == ("signed integer overflow", "imu.c:12:9", None,
                                                   "UBSan")                 # during init
    assert parse_report("all fine\n", ["/src/fw/imu.c"]) is None


def test_no_sanitizer_runtime_is_a_note(tmp_path, inputs, monkeypatch):
    """A compiler that cannot link -fsanitize programs: the check is skipped, and said so."""
    fw, _ = _plant(tmp_path, [])
    cc = tmp_path / "cc-nosan"
    cc.write_text('#!/bin/sh\nfor a in "$@"; do case "$a" in -fsanitize=*) '
                  'echo "/usr/bin/ld: cannot find -lasan: No such file" >&2; exit 1;; esac; done\n'
                  'exec cc "$@"\n')
    cc.chmod(cc.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("CC", str(cc))
    run = RunInputs.of(fw, "1d", dict(dt=0.005, k0=0.02), PARAMS, [0.0], inputs)
    cause, notes = sanitize(fw, run, tmp_path / "wd", 0)
    assert cause is None and len(notes) == 1
    assert "no sanitizer runtime" in notes[0] and "not checked for undefined behaviour" in notes[0]


def test_constants_near_a_parameter(tmp_path):
    """Literals near k0 (not in comments; 0.98f is 1 - k0 in float32, 0.005f is dt), the
    nearest first, each with the exact replacement of its kind (float, double)."""
    src = tmp_path / "k.c"
    line3 = "float a = 0.98f, b = 1.0f, c = 0.005f, d = 0.0202;"
    src.write_text(f"/* 0.0201 in a comment */\n#define K0 0.0201f\n{line3}\n")
    found = constants([str(src)], PARAMS, "float32")
    assert [(c.where, c.literal, c.name, c.replacement) for c in found] == [
        ("k.c:2:12", "0.0201f", "k0", "0.02f"),
        (f"k.c:3:{line3.index('0.0202') + 1}", "0.0202", "k0", repr(float(F32(0.02))))]


def test_report_order():
    c = [Cause("warning", "w", None, where="a.c:1:1", detail="-Wconversion"),
         Cause("data model", "d", None, where="a.c:2"),
         Cause("double", "x", "-fsingle-precision-constant", False),
         Cause("undefined behaviour", "u", None, where="a.c:3", sample=4),
         Cause("fma", "f", "-ffp-contract=off", True)]
    assert [x.what for x in ordered(c)] == ["fma", "undefined behaviour", "data model", "double",
                                            "warning"]


def test_data_model_findings(tmp_path):
    """From the preprocessed source (a macro's expansion is seen at its use), user files only."""
    src = tmp_path / "dm.c"
    src.write_text("#include <string.h>\n#define BITS(f) (*(long *)&(f))\n"
                   "long bits(float y) { return BITS(y); }\n"
                   "int words(void) { return (int)sizeof(long); }\n"
                   "int big = 40000;\nint small = 30000;\nunsigned mask = 0xFFFF;\n"
                   "long fine = 40000;\ndouble acc;\n")
    pre = [_preprocessed(["cc", "-std=c99"], str(src), tmp_path)]
    found = [(c.where, c.detail) for c in data_model(pre, [str(src)])]
    assert found == [("dm.c:3", "long"), ("dm.c:4", "long"), ("dm.c:5", "int"), ("dm.c:7", "int"),
                     ("dm.c:9", "double")]
