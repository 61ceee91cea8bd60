"""A hostile round on declared firmware APIs (imufuse.firmware.declared, declfile, ctemplate):
what an adversarial or careless declaration file does, and what it now gets.

- the file: nested too deeply (a RecursionError before), a byte-order mark (refused as "not
  TOML"), wrong types for keys (an int, a table or a list where a string goes: an
  AttributeError or TypeError at build time), parameters that are tables or strings for
  numbers, sources that are no C file, a directory or the same file twice, a header name that
  injects code, --source-dir or an include directory missing: one FirmwareError naming the
  file and the key, at load time;
- the templates: an unterminated `${`, a placeholder inside a string literal, a `}` that
  closes the harness's function, `return`, `#define`, an unclosed comment, constructor
  arguments that end the new-expression, state expressions with side effects or a comma,
  a type that is a pointer or a statement, a name that is a keyword or the harness's: refused
  with the key; `${dt*1000}` and `${dt:ms}` were silently ignored (dt passed unscaled) and dt
  was passed as a double on the host but as value_type on the MCU: dt now scales and converts
  like every input; a zero, infinite or subnormal factor is refused (1e999 was a ValueError);
- the harness's own names (x, k, n, p, out, dt) shadowed the firmware's: a C global `x`
  read as state gave the sample's inputs ("not bit-exact" for a correct firmware); objects
  named k or out did not compile: every harness name is imf_fw_... now;
- C++: a class whose operator new is deleted, an elaborated `class X` type and a scalar
  object type did not compile (the class's operator new, `fw.~class X()`, `fw.~float()`):
  the global placement new and a destroy template;
- bare metal: a C++ firmware using new/delete (or a virtual destructor, whose deleting form
  needs operator delete) or printf, and a C firmware using malloc, did not link on the Arm
  targets (_sbrk, _write, ... undefined) and a C++ new did not link on the ATmega328P
  (no operator new): a heap in .bss (inside the RAM image saved between chunks, so an
  allocation made by a constructor carries over chunks) and output that goes nowhere.
"""
import textwrap

import numpy as np
import pytest

import declared_class

from imufuse import sim
from imufuse.catalogue import resolve_params
from imufuse.firmware import FirmwareError, validate_isolated
from imufuse.firmware.declfile import load_declaration
from imufuse.mcu import ensure_toolchains

pytest.importorskip("cffi")


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return str(tmp_path_factory.mktemp("fw-cache"))


@pytest.fixture(autouse=True)
def _cache_env(cache, monkeypatch):
    monkeypatch.setenv("IMUFUSE_CACHE", cache)


H, CPP, TOML = declared_class.H, declared_class.CPP, declared_class.TOML


def _files(tmp_path, toml=TOML, h=H, cpp=CPP, edits=()):
    return declared_class.write(tmp_path, toml=toml, h=h, cpp=cpp, edits=edits)


def _validate(path, target="host", seconds=1.0):
    d = load_declaration(path)
    s = sim.axis1d("fast", rate=200.0, duration=seconds, seed=3)
    p = resolve_params(d.filter, s.dt, d.params)
    return validate_isolated(d.firmware, d.filter, p, [s.gyr, s.acc_angle], target=target)


def _refused(tmp_path, edits, *words, **kw):
    path = _files(tmp_path, edits=edits, **kw)
    with pytest.raises(FirmwareError) as e:
        load_declaration(path)
    msg = str(e.value)
    assert msg.startswith(str(path)), msg
    for w in words:
        assert w in msg, msg
    assert "\n" not in msg, msg
    return msg


CALL = 'call = "fw.step(${rate}, ${angle}, ${dt})"'
INIT = 'init = ["fw.begin(${k0})"]'
STATE = 'theta = "fw.theta_"'
TYPE = 'type = "Attitude"'
HEAD = 'headers = ["att.hpp"]'


# ---------------------------------------------------------------------------
# the file

@pytest.mark.parametrize("edits,words", [
    ([(STATE, "theta = " + "[" * 3000 + "]" * 3000)], ["nested too deeply"]),
    ([(TYPE, "type = 5")], ["[object] type", "a string"]),
    ([(TYPE, "type = { a = 1 }")], ["[object] type", "a string"]),
    ([(TYPE, 'type = "Attitude"\nname = 5')], ["[object] name", "a string"]),
    ([(TYPE, 'type = "Attitude"\nargs = [1, 2]')], ["[object] args", "a string"]),
    ([(CALL, "value_type = 4\n" + CALL)], ["[update] value_type", "a string"]),
    ([(HEAD, HEAD + "\nlanguage = 1")], ["[firmware] language", "a string"]),
    ([(HEAD, HEAD + "\ndefines = { A = { b = 1 } }")], ["[firmware] defines", "A"]),
    ([(HEAD, HEAD + "\ndefines = { A = false }")], ["[firmware] defines", "A"]),
    ([(HEAD, HEAD + '\ndefines = { "A B" = 1 }')], ["[firmware] defines", "macro name"]),
    ([("params = { k0 = 0.02 }", "params = { k0 = { a = 1 } }")], ["[filter] params", "k0"]),
    ([("params = { k0 = 0.02 }", 'params = { k0 = "abc" }')], ["[filter] params", "k0"]),
    ([("params = { k0 = 0.02 }", "params = { k9 = 0.02 }")], ["[filter] params", "k9"]),
    ([("params = { k0 = 0.02 }", "params = { k0 = 0.02, dt = 0 }")], ["[filter] params", "dt"]),
    ([(STATE, 'theta = " "')], ["[state] theta"]),
    ([('sources = ["att.cpp"]', 'sources = ["/etc/passwd"]')], ["[firmware] sources",
                                                               "not a C or C++ source"]),
    ([('sources = ["att.cpp"]', 'sources = ["."]')], ["[firmware] sources", "not a regular file"]),
    ([('sources = ["att.cpp"]', 'sources = ["att.cpp", "./att.cpp"]')],
     ["[firmware] sources", "the same file"]),
    ([(HEAD, 'headers = ["att.hpp\\"\\nint evil;//"]')], ["[firmware] headers"]),
    ([(HEAD, HEAD + '\ninclude = ["nowhere"]')], ["[firmware] include", "no such directory"]),
])
def test_file_faults_are_named_at_load(tmp_path, edits, words):
    _refused(tmp_path, edits, *words)


def test_source_dir_missing_and_bom(tmp_path):
    path = _files(tmp_path)
    for d, word in [(tmp_path / "gone", "not found"), (path, "not a directory")]:
        with pytest.raises(FirmwareError, match=r"--source-dir.*" + word):
            load_declaration(path, source_dir=str(d))
    # a byte-order mark (Windows editors) is read as UTF-8, as the other small files are
    _files(tmp_path, toml=b"\xef\xbb\xbf" + TOML.encode())
    assert load_declaration(path).filter == "Kalman1D"


# ---------------------------------------------------------------------------
# the templates

@pytest.mark.parametrize("edits,words", [
    ([(CALL, 'call = "fw.step(${rate}, ${angle}, ${dt}) ${"')], ["[update] call", "'${'"]),
    ([(INIT, 'init = ["fw.begin(${k0)"]')], ["[object] init", "'${'"]),
    ([(CALL, 'call = "fw.step(${rate}, ${angle}, ${dt}); const char *s = \\"${rate}\\""')],
     ["[update] call", "literal"]),
    ([(CALL, 'call = "fw.step(${rate}, ${angle}, ${dt}); } void evil() {"')],
     ["[update] call", "unbalanced '}'"]),
    ([(CALL, 'call = "return; fw.step(${rate}, ${angle}, ${dt})"')], ["[update] call", "return"]),
    ([(CALL, 'call = "fw.step(${rate}, ${angle}, ${dt}); break"')], ["[update] call", "break"]),
    ([(INIT, 'init = ["fw.begin(${k0}); return"]')], ["[object] init", "return"]),
    ([(INIT, 'init = ["fw.begin(${k0}); } {"]')], ["[object] init", "unbalanced"]),
    ([(CALL, 'call = "\\n#define fw fw2\\nfw.step(${rate}, ${angle}, ${dt})"')],
     ["[update] call", "'#'"]),
    ([(CALL, 'call = "fw.step(${rate}, ${angle}, ${dt}) /*"')], ["[update] call", "comment"]),
    # the brackets' other spellings: the digraph call compiled and left the output unwritten
    ([(CALL, 'call = "fw.step(${rate}, ${angle}, ${dt}); %> %> void e(double *o) <% <%"')],
     ["[update] call", "digraph"]),
    ([(CALL, 'call = "fw.step(${rate}, ${angle}, ${dt}); ??> void e() ??<"')],
     ["[update] call", "trigraph"]),
    ([(CALL, 'call = "fw.step(${rate}, ${angle}, ${dt} + 1\'0); } void e() { int z = 1\'0"')],
     ["[update] call", "digit separator"]),
    ([(CALL, 'call = "fw.step(${rate}, ${angle}, ${dt}); const char *s = R\\"(})\\""')],
     ["[update] call", "raw string"]),
    ([(TYPE, TYPE + '\nargs = "); int evil = (1"')], ["[object] args", "unbalanced ')'"]),
    ([(STATE, 'theta = "fw.theta_++"')], ["[state] theta", "'++'"]),
    ([(STATE, 'theta = "fw.theta_ = 0"')], ["[state] theta", "'='"]),
    ([(STATE, 'theta = "fw.theta_ *= 2"')], ["[state] theta", "'*='"]),
    ([(STATE, 'theta = "fw.theta_, 1.0"')], ["[state] theta", "comma"]),
    ([(STATE, 'theta = "({ fw.theta_ = 0; fw.theta_; })"')], ["[state] theta", "one expression"]),
    ([(STATE, 'theta = "fw.theta_ /* x"')], ["[state] theta", "comment"]),
    ([(TYPE, 'type = "Attitude *"')], ["[object] type", "pointer"]),
    ([(TYPE, 'type = "Attitude; int evil"')], ["[object] type"]),
    ([(TYPE, 'type = "3"')], ["[object] type"]),
    ([(TYPE, TYPE + '\nname = "int"')], ["[object] name", "keyword"]),
    ([(TYPE, TYPE + '\nname = "imf_fw_store"')], ["[object] name", "harness"]),
    ([(TYPE, TYPE + '\nname = "Attitude"')], ["[object] name"]),
    ([(CALL, 'call = ""')], ["[update] call"]),
    ([(CALL, 'call = "fw.step(0, 0, ${dt})"')], ["[update] call", "none of the inputs"]),
    ([(CALL, 'value_type = "static float"\n' + CALL)], ["[update] value_type"]),
])
def test_template_injection_is_refused_with_the_key(tmp_path, edits, words):
    _refused(tmp_path, edits, *words)


@pytest.mark.parametrize("placeholder,words", [
    ("${dt:deg/s}", ["unit 'deg/s' for dt"]),
    ("${dt[float]}", ["dt is one value"]),
    ("${rate*1e999}", ["factor '1e999'"]),
    ("${rate*0}", ["factor '0'"]),
    ("${rate*-0}", ["factor '-0'"]),
    ("${rate*1e-320}", ["factor '1e-320'"]),
    ("${angle:deg/s}", ["unit 'deg/s' for angle"]),
])
def test_units_and_factors_that_cannot_be_right(tmp_path, placeholder, words):
    edits = [(CALL, f'call = "fw.step(${{rate}}, ${{angle}}, ${{dt}} + 0 * {placeholder})"')]
    if placeholder.startswith("${rate"):
        edits = [(CALL, f'call = "fw.step({placeholder}, ${{angle}}, ${{dt}})"')]
    elif placeholder.startswith("${angle"):
        edits = [(CALL, f'call = "fw.step(${{rate}}, {placeholder}, ${{dt}})"')]
    _refused(tmp_path, edits, "[update] call", *words)


def test_dt_scales_and_converts_like_every_input(tmp_path):
    """`${dt*1000}` and `${dt:ms}` pass dt in milliseconds (both were ignored: dt in
    seconds), converted to value_type as on the MCU (the host passed the double)."""
    h = H.replace("void step(float gyro, float acc_angle, float dt);",
                  "void step(float gyro, float acc_angle, double dt) { dtv_ = dt; }\n"
                  "    double dtv_;")
    s = sim.axis1d("fast", rate=300.0, duration=0.05, seed=3)
    for ph in ("${dt*1000}", "${dt:ms}"):
        path = _files(tmp_path, h=h, cpp="#include \"att.hpp\"\n",
                      edits=[(CALL, f'call = "fw.step(${{rate}}, ${{angle}}, {ph})"'),
                             (STATE, 'theta = "fw.dtv_"')])
        d = load_declaration(path)
        p = resolve_params(d.filter, s.dt, d.params)
        got = d.firmware.run("1d", [s.gyr, s.acc_angle], s.dt, p, p)
        assert got.dtype == np.float64
        assert np.all(got[:, 0] == float(np.float32(s.dt * 1000.0))), (ph, got[0, 0])


# ---------------------------------------------------------------------------
# the harness's names

C_SRC = textwrap.dedent("""
    #include "att.h"
    float x[1];
    static float k0_, omk0_;
    void att_begin(float k0) { k0_ = k0; omk0_ = 1.0f - k0; x[0] = 0.0f; }
    void att_step(float gyro, float acc_angle, float dt)
    {
        float pred, th;
        if (!__builtin_isfinite(gyro) || !__builtin_isfinite(acc_angle)) return;
        pred = x[0] + gyro * dt;
        th = omk0_ * pred + k0_ * acc_angle;
        if (__builtin_isfinite(th)) x[0] = th;
    }
""")
C_TOML = textwrap.dedent("""
    [firmware]
    sources = ["att.c"]
    headers = ["att.h"]

    [filter]
    name = "Kalman1D"
    params = { k0 = 0.02 }

    [object]
    init = ["att_begin(${k0})"]

    [update]
    call = "att_step(${rate}, ${angle}, ${dt})"

    [state]
    theta = "x[0]"
""")


def test_harness_names_do_not_shadow_the_firmware(tmp_path):
    """A C global named x (read as the state) gave the harness's input row: not bit-exact
    for a correct firmware; objects named like the harness's locals did not compile."""
    (tmp_path / "att.h").write_text("extern float x[1];\nvoid att_begin(float k0);\n"
                                    "void att_step(float gyro, float acc_angle, float dt);\n")
    (tmp_path / "att.c").write_text(C_SRC)
    (tmp_path / "c.toml").write_text(C_TOML)
    v = _validate(tmp_path / "c.toml")
    assert v.bit_exact, v.text()
    for name in ("out", "k", "p"):
        d = tmp_path / name
        d.mkdir()
        toml = TOML.replace(TYPE, f'{TYPE}\nname = "{name}"').replace("fw.", f"{name}.")
        v = _validate(_files(d, toml=toml))
        assert v.bit_exact, (name, v.text())


# ---------------------------------------------------------------------------
# C++

def test_cpp_object_types_that_did_not_compile(tmp_path):
    # a class whose own operator new is deleted: the global placement new builds it
    h = H.replace("public:", "public:\n    static void *operator new(__SIZE_TYPE__) = delete;\n"
                  "    static void *operator new(__SIZE_TYPE__, void *) = delete;")
    (tmp_path / "a").mkdir()
    v = _validate(_files(tmp_path / "a", h=h))
    assert v.bit_exact, v.text()
    # an elaborated type specifier (a C header's struct, in C++)
    (tmp_path / "b").mkdir()
    v = _validate(_files(tmp_path / "b", edits=[(TYPE, 'type = "class Attitude"')]))
    assert v.bit_exact, v.text()
    # a scalar object: a running sum of rate * dt, as float
    (tmp_path / "c").mkdir()
    path = _files(tmp_path / "c", edits=[(TYPE, 'type = "float"'), (INIT, 'init = ["fw = 0"]'),
                                         (CALL, 'call = "fw = fw + ${rate} * ${dt}"'),
                                         (STATE, 'theta = "fw"')])
    d = load_declaration(path)
    s = sim.axis1d("fast", rate=200.0, duration=0.1, seed=3)
    p = resolve_params(d.filter, s.dt, d.params)
    got = d.firmware.run("1d", [s.gyr, s.acc_angle], s.dt, p, p)
    want, acc = [], np.float32(0)
    for g in s.gyr:
        acc = np.float32(acc + np.float32(g) * np.float32(s.dt))
        want.append(acc)
    assert got.dtype == np.float32 and np.array_equal(got[:, 0], np.array(want))


# ---------------------------------------------------------------------------
# bare metal: the heap and printf

HEAP_H = H.replace("public:", "public:\n    Attitude() : buf_(new float[8]) { buf_[0] = 0.0f; }\n"
                   "    virtual ~Attitude() { delete[] buf_; }\n    float *buf_;"
                   ).replace("theta_ = 0.0f; }", "buf_[0] = 0.0f; }")
HEAP_CPP = "#include <stdio.h>\n" + CPP.replace("float pred = theta_ +", "float pred = buf_[0] +") \
    .replace("if (__builtin_isfinite(th)) theta_ = th;",
             "if (__builtin_isfinite(th)) buf_[0] = th;\n    printf(\"%d\\n\", (int)(th * 1000));")


@pytest.mark.parametrize("target,seconds", [("cortex-m0", 1.0), ("atmega328p", 40.0)])
def test_cpp_heap_and_printf_on_bare_metal(tmp_path, target, seconds):
    """State in a buffer the constructor allocates with new (a virtual destructor deletes
    it), printf in the update: bit-exact; on the ATmega328P over several chunks, so the
    heap is carried with the RAM image."""
    assert not ensure_toolchains(("m0", "avr"))
    path = _files(tmp_path, h=HEAP_H, cpp=HEAP_CPP, edits=[(STATE, 'theta = "fw.buf_[0]"')])
    v = _validate(path, target, seconds)
    assert v.bit_exact, v.text()
    if target == "atmega328p":
        assert v.timing["chunks"] >= 2


def test_c_malloc_on_the_cortex_m0(tmp_path):
    assert not ensure_toolchains(("m0",))
    (tmp_path / "att.h").write_text("extern float *x;\nvoid att_begin(float k0);\n"
                                    "void att_step(float gyro, float acc_angle, float dt);\n")
    (tmp_path / "att.c").write_text(
        "#include <stdlib.h>\n#include <stdio.h>\n" +
        C_SRC.replace("float x[1];", "float *x;").replace(
            "x[0] = 0.0f; }", "x = (float *)malloc(4 * sizeof(float)); x[0] = 0.0f; }").replace(
            "x[0] = th;", "{ x[0] = th; puts(\"step\"); }"))
    (tmp_path / "c.toml").write_text(C_TOML)
    v = _validate(tmp_path / "c.toml", "cortex-m0")
    assert v.bit_exact, v.text()
