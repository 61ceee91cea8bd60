"""A filter's API declared in a small file, not written as a shim: ``DeclaredFirmware``.

The firmware people carry is mostly not a C function pair: a C++ class with ``begin(rate)``
and ``update(gx, ..., mz)`` in deg/s and private members, x-io Fusion's structs passed by
value, a settings struct and setters. A declaration file (TOML) says how to create and
initialise the filter, how to call its update with each sample, how to read its state, and
which imufuse filter to compare it with; imufuse generates the harness around it (C or C++,
from the sources' extensions) and validates it as any firmware, with no user-written code::

    [firmware]
    sources = ["MadgwickAHRS.cpp"]        # relative to this file (or to source_dir)
    headers = ["MadgwickAHRS.h"]
    include = ["."]                       # optional; cflags, defines, language also

    [filter]                              # the imufuse filter to compare with
    name = "MadgwickAHRS"
    params = { beta = 0.1 }               # its parameters (dt from the log)

    [object]                              # one object `fw` of this type (optional: globals)
    type = "Madgwick"
    init = ["fw.begin(${rate})"]          # statements, once before the first sample

    [update]                              # one sample
    call = "fw.update(${gx:deg/s}, ${gy:deg/s}, ${gz:deg/s}, ${ax}, ${ay}, ${az}, ${mx}, ${my}, ${mz})"

    [state]                               # imufuse state name = expression (private members too)
    q0 = "fw.q0"

Placeholders, replaced by C literals or expressions:

- in ``init`` and the constructor's ``args``: ``${NAME}`` any C init value or parameter of the
  imufuse filter (``${beta}``, ``${dt}``), ``${rate}`` (1/dt), as exact double literals;
- in ``call``: the inputs ``${gx} ${gy} ${gz} ${ax} ... ${mz}`` (1-D filters: ``${rate}`` and
  ``${angle}``; fixed point: the int16 counts) and ``${dt}``; with a unit ``${gx:deg/s}``
  (gyroscope: rad/s, deg/s; accelerometer: g, m/s^2), or a factor ``${mx*0.01}``; a whole
  vector as a local array ``${gyr[float]}`` (``${acc[double]:m/s^2}``).

Values are converted to ``value_type`` (``${dt}`` too; ``${dt*1000}``, ``${dt:ms}``), a
vector to its element type. A C++ source makes the harness C++, compiled with
``-fno-access-control`` so that private members can be read and written without editing
the user's code. ``$$`` is a literal ``$``.

The templates are checked before anything is generated (FirmwareError naming the key):
brackets balanced, literals and comments closed, no placeholder inside a literal, no ``#``
directive, no ``return``/``goto``/``break``/``continue`` (they would leave the harness's
code); a state expression is one expression without assignment, ``++``/``--``, ``;`` or
braces; the object's name is no keyword and no harness name (``imf_``/``imufuse_``).
"""
from __future__ import annotations

import math
import os
import re
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

from ..shared.checks import KINDS
from ..shared.bits import c_double_literal
from . import ctemplate
from .declaration import DEFAULT_CFLAGS, FirmwareError
from .host import Firmware

__all__ = ["DeclaredFirmware", "CXX_EXTENSIONS", "DEFAULT_CXXFLAGS"]

CXX_EXTENSIONS = (".cpp", ".cc", ".cxx", ".C", ".c++")
#: the host flags of a C++ firmware: the numerical contract, and private members readable
DEFAULT_CXXFLAGS = ("-O2", "-ffp-contract=off", "-fno-access-control")
_UNITS = {"rad/s": 1.0, "deg/s": 180.0 / math.pi, "g": 1.0, "m/s^2": 9.80665, "m/s2": 9.80665,
          "rad": 1.0, "deg": 180.0 / math.pi, "s": 1.0, "ms": 1e3, "us": 1e6}
_UNIT_OF = {"g": ("rad/s", "deg/s"), "a": ("g", "m/s^2", "m/s2"), "m": (), "rate": ("rad/s", "deg/s"),
            "angle": ("rad", "deg"), "dt": ("s", "ms", "us")}
_PLACE = re.compile(r"\$\$|\$\{([^}]*)\}")
_INPUT = re.compile(r"^(?P<name>[A-Za-z_]\w*)(?:\[(?P<vtype>[A-Za-z_][\w ]*)\])?"
                    r"(?::(?P<unit>[^*]+)|\*(?P<factor>[-+0-9.eE]+))?$")
_IDENT = re.compile(r"[A-Za-z_]\w*$")


def _inputs_of(kind: str) -> Dict[str, Tuple[int, int]]:
    """{placeholder: (first column, width)} of a kind's inputs: gx.. or gyr (width 3)."""
    if kind == "1d":
        return {"rate": (0, 1), "angle": (1, 1)}
    out = {}
    for j, vec in enumerate(KINDS[kind]):
        out[vec] = (3 * j, 3)
        for a, axis in enumerate("xyz"):
            out[vec[0] + axis] = (3 * j + a, 1)
    return out


class DeclaredFirmware(Firmware):
    """Firmware whose init, update and state come from a declaration's templates (see the
    module's doc). ``values`` are the literals init's placeholders take (set by
    ``bind``); the state may name a subset of the imufuse filter's state. Every template is
    checked here (imufuse.firmware.ctemplate): FirmwareError naming the key."""

    partial_state = True

    def __init__(self, sources: Sequence[str], *, update: str, state: Mapping[str, str],
                 object_type: Optional[str] = None, object_name: str = "fw",
                 object_args: Optional[str] = None, init: Sequence[str] = (),
                 headers: Sequence[str] = (), include_dirs: Sequence[str] = (),
                 defines: Optional[Mapping[str, Any]] = None,
                 cflags: Optional[Sequence[str]] = None, language: Optional[str] = None,
                 cache_dir: Optional[str] = None, value_type: str = "float") -> None:
        if isinstance(sources, str) or not all(isinstance(x, str) and x for x in sources):
            raise FirmwareError("[firmware] sources: a list of file names")
        self.sources = [os.path.abspath(s) for s in sources]
        for s in self.sources:
            if not os.path.isfile(s):
                raise FirmwareError(f"source file not found: {s}" if not os.path.exists(s)
                                    else f"[firmware] sources: {s}: not a regular file")
        if language is None:
            language = "c++" if any(s.endswith(CXX_EXTENSIONS) for s in self.sources) else "c"
        if language not in ("c", "c++"):
            raise FirmwareError(f"[firmware] language: 'c' or 'c++', got {language!r}")
        self.language = language
        self.include_dirs = [os.path.abspath(d) for d in include_dirs]
        for h in headers:
            if not isinstance(h, str) or not re.fullmatch(r"<[^<>\"\n\0]+>|[^<>\"\n\0]+", h):
                raise FirmwareError(f"[firmware] headers: {h!r}: a file name (or <name>)")
        self.headers = list(headers)
        self.defines = dict(defines or {})
        default = DEFAULT_CXXFLAGS if language == "c++" else DEFAULT_CFLAGS
        self.cflags_given = None if cflags is None else list(cflags)
        self.cflags = list(default if cflags is None else cflags)
        self.cache_dir = cache_dir or os.environ.get("IMUFUSE_CACHE") or os.path.join(
            os.path.expanduser("~"), ".cache", "imufuse", "firmware")
        if object_type is not None:
            if not isinstance(object_type, str) or not ctemplate.TYPE.match(object_type.strip()):
                raise FirmwareError(f"[object] type: {object_type!r}: a struct or class type "
                                    "(Madgwick, ns::Filter<float>, struct s), not a pointer "
                                    "or an array")
            ctemplate.scan(object_type, "[object] type", "args")
            object_type = object_type.strip()
            last = (re.sub(r"<.*", "", object_type).split("::")[-1].split() or [""])[-1]
            if not isinstance(object_name, str) or not _IDENT.match(object_name) \
                    or object_name in ctemplate.KEYWORDS or object_name == last \
                    or object_name.startswith(("imf_", "imufuse_")):
                raise FirmwareError(f"[object] name {object_name!r}: a C identifier, not a "
                                    "keyword, the type's name or a harness name (imf_..., "
                                    "imufuse_...)")
            if object_args is not None and not isinstance(object_args, str):
                raise FirmwareError("[object] args: the constructor's arguments (a string)")
        self.object_type, self.object_name = object_type, object_name
        self.object_args = None if object_args is None else \
            ctemplate.scan(object_args, "[object] args", "args")
        self.value_type = ctemplate.value_type(value_type, "[update] value_type")
        if isinstance(init, str) or not all(isinstance(x, str) for x in init):
            raise FirmwareError("[object] init: statements (strings)")
        self.init_statements = [ctemplate.scan(x, "[object] init" + (f"[{j}]" if len(init) > 1
                                                                      else ""), "stmt")
                                for j, x in enumerate(init)]
        if not isinstance(update, str) or not update.strip().strip(";"):
            raise FirmwareError("[update] call: the update statement (a string, not empty)")
        self.update_template = ctemplate.scan(update, "[update] call", "stmt")
        if not state:
            raise FirmwareError("state: map at least one imufuse state name to an expression")
        self.state = {}
        for k, v in state.items():
            if not isinstance(v, str) or not v.strip():
                raise FirmwareError(f"[state] {k}: an expression (a string)")
            self.state[str(k)] = ctemplate.scan(v, f"[state] {k}", "expr").strip()
        self.values: Dict[str, float] = {}
        # what Firmware's run() and the prototype-based code paths look at
        self.init = None
        self.update = None
        self.self_type = None
        self.set_state = False
        self.init_args: Dict[str, Any] = {}
        self.init_struct = None

    # -- binding ---------------------------------------------------------
    def bind(self, c_values: Any, params: Mapping[str, Any]) -> None:
        """The values of init's placeholders: the imufuse filter's C init values by name,
        its parameters, and rate = 1/dt."""
        vals: Dict[str, float] = {}
        for k, v in {**dict(params), **(c_values if isinstance(c_values, dict) else {})}.items():
            try:
                vals[k] = float(v)
            except (TypeError, ValueError):
                continue
        if vals.get("dt"):
            vals["rate"] = 1.0 / vals["dt"]
        if vals != self.values:
            self._lib = None           # the init literals are in the harness
        self.values = vals

    def placeholders(self) -> List[Tuple[str, str]]:
        """(key, name) of every placeholder of init and the constructor's arguments."""
        texts = [("[object] args", self.object_args or "")] + \
            [("[object] init", t) for t in self.init_statements]
        return [(w, m.group(1).strip()) for w, t in texts for m in _PLACE.finditer(t)
                if m.group(1) is not None]

    def _fill_init(self, text: str, where: str) -> str:
        def rep(m: "re.Match[str]") -> str:
            if m.group(1) is None:
                return "$"
            name = m.group(1).strip()
            if name not in self.values:
                raise FirmwareError(f"{where}: ${{{name}}} is neither a parameter of the imufuse "
                                    f"filter nor rate/dt (it has {', '.join(sorted(self.values))})")
            return f"({c_double_literal(self.values[name])})"
        return _PLACE.sub(rep, text)

    def _init_code(self) -> str:
        return "".join(f"    {{ {self._fill_init(s, '[object] init').strip().rstrip(';')}; }}\n"
                       for s in self.init_statements)

    def _fill_update(self, kind: str, stored: bool = False
                     ) -> Tuple[List[str], str, int, List[str]]:
        """(declarations, the update statement, inputs a sample has, loads). Each value is
        converted to value_type (a vector to its element type) once; stored: into
        file-scope variables by the loads (the MCU driver, where the update is measured
        alone, from the sample imf_fw_sample), else into locals before the call (the host
        harness, from imf_fw_x)."""
        cols = _inputs_of(kind)
        total = 2 if kind == "1d" else 3 * len(KINDS[kind])
        decls: List[str] = []
        loads: List[str] = []
        used: List[str] = []
        vt = self.value_type
        row = "imf_fw_sample" if stored else "imf_fw_x"

        def rep(m: "re.Match[str]") -> str:
            if m.group(1) is None:
                return "$"
            text = m.group(1).replace(" ", "") if "[" not in m.group(1) else m.group(1).strip()
            p = _INPUT.match(text)
            where = f"[update] call: ${{{m.group(1)}}}"
            if p is None:
                raise FirmwareError(f"{where}: expected ${{gx}}, ${{gx:deg/s}}, ${{gx*0.01}}, "
                                    "${gyr[float]} or ${dt}")
            name, vtype, unit, factor = p.group("name", "vtype", "unit", "factor")
            if name not in cols and name != "dt":
                raise FirmwareError(f"{where}: {name!r} is not an input of a {kind} filter "
                                    f"({', '.join(cols)}, dt)")
            col, width = cols.get(name, (-1, 1))
            scale = 1.0
            if unit is not None:
                unit = unit.strip()
                ok = _UNIT_OF.get(name if kind == "1d" or name == "dt" else name[0], ())
                if unit not in _UNITS or unit not in ok:
                    raise FirmwareError(f"{where}: unit {unit!r} for {name} "
                                        f"(known: {', '.join(ok) or 'none; give a factor *K'})")
                scale = _UNITS[unit]
            elif factor is not None:
                try:
                    scale = float(factor)
                except ValueError:
                    raise FirmwareError(f"{where}: factor {factor!r}") from None
                if not math.isfinite(scale) or abs(scale) < 2.2250738585072014e-308:
                    raise FirmwareError(f"{where}: factor {factor!r}: a finite, non-zero, "
                                        "normal number")
            lit = "" if scale == 1.0 else f" * {c_double_literal(scale)}"
            if vtype is not None:
                vtype = ctemplate.value_type(vtype, where)
            if width == 3:
                if vtype is None:
                    raise FirmwareError(f"{where}: a whole vector needs its element type, e.g. "
                                        f"${{{name}[float]}}")
                var = f"imf_v{len(decls)}_{name}"
                vals = [f"({vtype})({row}[{col + j}]{lit})" for j in range(3)]
                if stored:
                    decls.append(f"static {vtype} {var}[3];")
                    loads.extend(f"{var}[{j}] = {v};" for j, v in enumerate(vals))
                else:
                    decls.append(f"{vtype} {var}[3] = {{ {', '.join(vals)} }};")
                used.append(name)
                return var
            if vtype is not None:
                raise FirmwareError(f"{where}: {name} is one value")
            var = f"imf_a{len(decls)}_{name}"
            value = f"imf_fw_dt{lit}" if name == "dt" else f"{row}[{col}]{lit}"
            if stored:
                decls.append(f"static {vt} {var};")
                loads.append(f"{var} = ({vt})({value});")
            else:
                decls.append(f"const {vt} {var} = ({vt})({value});")
            used.append(name)
            return var
        call = _PLACE.sub(rep, self.update_template).strip()
        if not [u for u in used if u != "dt"]:
            raise FirmwareError(f"[update] call: takes none of the inputs ({', '.join(cols)}): "
                                "a sample reaches the firmware only through them")
        if not call.endswith((";", "}")):
            call += ";"
        return decls, "{ " + call + " }", total, loads

    def check(self, kind: str, names: Sequence[str]) -> None:
        """Every placeholder against a `kind` filter whose init values and parameters are
        `names` (FirmwareError naming the key), before anything is built."""
        self._fill_update(kind)
        known = {*names, "dt", "rate"}
        for where, name in self.placeholders():
            if name not in known:
                raise FirmwareError(f"{where}: ${{{name}}} is neither a parameter of the imufuse "
                                    f"filter nor rate/dt (it has {', '.join(sorted(known))})")

    def prepare(self, kind, c_args=(), params=None):
        self.bind(c_args, params or {})
        super().prepare(kind, c_args, params)

    def load(self, kind, c_args=(), params=None):
        self.bind(c_args, params or {})
        super().load(kind, c_args, params)

    def run(self, kind, inputs, dt, c_args=(), params=None, state0=None):
        self.bind(c_args, params or {})
        return super().run(kind, inputs, dt, c_args, params, state0)

    def dtype(self, kind="1d", c_args=(), params=None):
        self.bind(c_args, params or {})
        return super().dtype(kind, c_args, params)

    # -- the generated C / C++ ---------------------------------------------
    def _object_code(self) -> Tuple[str, str, str]:
        """(file-scope declarations, the start of a run, the end of a run). C++: the object
        in static storage, made by the global placement new (a class's own operator new,
        deleted or not, is not called) and destroyed through a template (any type name)."""
        t, n = self.object_type, self.object_name
        if t is None:
            return "", "", ""
        args = "" if self.object_args is None else self._fill_init(self.object_args,
                                                                   "[object] args")
        if self.language == "c++":
            top = (f"alignas({t}) static unsigned char imf_fw_store[sizeof({t})];\n"
                   f"static {t} &{n} = *reinterpret_cast<{t} *>(imf_fw_store);\n"
                   "template <class T> static void imf_fw_destroy(T &o) { o.~T(); }\n")
            start = f"    ::new (static_cast<void *>(imf_fw_store)) {t}({args.strip()});\n"
            return top, start, f"    imf_fw_destroy({n});\n"
        top = f"static {t} {n};\n"
        return top, f"    memset(&{n}, 0, sizeof {n});\n", ""

    def _includes(self) -> str:
        return "".join(f"#include {h}\n" if h.startswith("<") else f'#include "{h}"\n'
                       for h in self.headers)

    def source(self, kind: str, n_init: int) -> str:
        """The host harness: imufuse_fw_run and imufuse_fw_sizes, as Firmware's (its loop's
        line as imufuse.firmware.sanitize finds it). The declared code is in functions of
        its own whose names are all imf_fw_..., so no name of the firmware's is shadowed."""
        decls, call, n_in, _ = self._fill_update(kind)
        top, start, end = self._object_code()
        st = list(self.state.values())
        cxx = self.language == "c++"
        store = "".join(f"    imf_fw_out[{j}] = (double)({e});\n" for j, e in enumerate(st))
        sizes = "".join(f"    imf_fw_sz[{j}] = (int)sizeof({e});\n" for j, e in enumerate(st))
        isint = "".join(f"    imf_fw_isint[{j}] = ((({e}) * 0 + 1) / 2 == 0);\n"
                        for j, e in enumerate(st))
        return (
            "#include <string.h>\n#include <stddef.h>\n" + ("#include <new>\n" if cxx else "")
            + self._includes() + top +
            "static void imf_fw_begin(int *imf_fw_isint)\n{\n" + start + self._init_code()
            + isint + "}\n"
            "static void imf_fw_sample(const double *imf_fw_x, double imf_fw_dt, "
            "double *imf_fw_out)\n{\n" + "".join(f"    {d}\n" for d in decls) +
            f"    {call}\n" + store + "    (void)imf_fw_x; (void)imf_fw_dt;\n}\n"
            "static void imf_fw_end(void)\n{\n" + end + "}\n"
            "void imufuse_fw_run(const double *p, const double *s0, int set_state, size_t n,\n"
            "                    const double *in, double dt, double *out, int *isint)\n{\n"
            "    size_t k;\n    (void)p; (void)s0; (void)set_state;\n"
            "    imf_fw_begin(isint);\n"
            "    for (k = 0; k < n; ++k) {\n"
            f"        imf_fw_sample(in + k * {n_in}, dt, out + k * {len(st)});\n"
            "    }\n    imf_fw_end();\n}\n"
            "void imufuse_fw_sizes(int *imf_fw_sz)\n{\n" + sizes + "}\n")

    def _update_plan(self, kind: str):
        """Firmware's: no parameter plan; the number of input values a sample has."""
        return [], (2 if kind == "1d" else 3 * len(KINDS[kind]))

    def target_source(self, kind, init_values, dt, state0=None, c89=False):
        """The driver of an emulated-MCU build (mcu/data/imf_fw_main.c includes it): C
        firmware directly; C++ firmware through the adapter unit (target_adapter), which
        the driver calls and whose state words it prints through their addresses."""
        decls, call, total, loads = self._fill_update(kind, stored=True)
        n = len(self.state)
        dt_lit = c_double_literal(float(dt)) if not c89 or dt == 0 else f"{float(dt):.17g}"
        out = ["/* Generated by imufuse.firmware.declared: the firmware under validation. */"]
        if self.language == "c++":
            out += [f"#define IMF_FW_ROW {total}",
                    "void imf_cxx_init(void);", "void imf_cxx_load(const double *x);",
                    "void imf_cxx_step(void);", "const void *imf_cxx_word(int j);",
                    f"extern const uint32_t imf_fw_types[{max(n, 1)}] IMF_FLASH;",
                    "static void imf_user_init(void) { imf_cxx_init(); }",
                    "static void imf_user_load(const double *x) { imf_cxx_load(x); }",
                    "static void imf_user_step(void) { imf_cxx_step(); }",
                    _DUMP_WORD,
                    "static void imf_user_dump(void)\n{\n    int j;\n"
                    f"    for (j = 0; j < {n}; ++j) {{\n"
                    "        imf_fw_dump_word(imf_cxx_word(j), IMF_RD32(&imf_fw_types[j]));\n"
                    "    }\n}"]
            return "\n".join(out) + "\n"
        top, start, _ = self._object_code()
        st = list(self.state.values())
        out += [self._includes(), f"#define IMF_FW_ROW {total}", ctemplate.BARE_METAL,
                top, f"static const double imf_fw_dt = {dt_lit};", *decls]
        out.append("static void imf_user_init(void)\n{\n" + start + self._init_code() + "}")
        out.append("static void imf_user_load(const double *imf_fw_sample)\n{\n" +
                   "".join(f"    {ld}\n" for ld in loads) + "    (void)imf_fw_sample;\n}")
        out.append(f"static void imf_user_step(void)\n{{\n    {call}\n}}")
        out.append("static void imf_user_dump(void)\n{\n" +
                   "".join(f"    IMF_FW_DUMP({e});\n" for e in st) + "}")
        types = ", ".join(f"IMF_FW_TYPE({e})" for e in st) or "0u"
        out.append(f"const uint32_t imf_fw_types[] IMF_FLASH = {{ {types} }};")
        return "\n".join(out) + "\n"

    def target_adapter(self, kind, dt):
        """(file name, C++ text) of the adapter unit of a C++ firmware on an MCU target, or
        None for C: the object, init, the loads, the update call and the state words' types
        and addresses, with C linkage for the driver. Built with the firmware's flags."""
        if self.language != "c++":
            return None
        decls, call, total, loads = self._fill_update(kind, stored=True)
        top, start, end = self._object_code()
        st = list(self.state.values())
        words = "".join(
            f"    case {j}: {{\n        static typename imf_rcv<__typeof__({e})>::t w;\n"
            f"        w = ({e});\n        return &w;\n    }}\n" for j, e in enumerate(st))
        types = ", ".join(f"imf_type<typename imf_rcv<__typeof__({e})>::t>::v" for e in st) or "0u"
        return "imf_fw_adapter.cpp", (
            "/* Generated by imufuse.firmware.declared: a C++ firmware's calls, for the C "
            "driver. */\n#include <stdint.h>\n#include <string.h>\n"
            "#if defined(__AVR__)\n#include <avr/pgmspace.h>\n#define IMF_FLASH PROGMEM\n"
            "#include <stddef.h>\ninline void *operator new(size_t, void *p) throw() "
            "{ return p; }\n#else\n#define IMF_FLASH\n#include <new>\n#endif\n"
            + self._includes() + _CXX_TRAITS + ctemplate.BARE_METAL_CXX
            + 'extern "C" {\n' + ctemplate.BARE_METAL + "}\n"
            + top.replace("alignas(" + str(self.object_type) + ") static unsigned char",
                          f"static unsigned char __attribute__((aligned(__alignof__("
                          f"{self.object_type}))))") +
            f"static const double imf_fw_dt = {c_double_literal(float(dt))};\n"
            + "".join(f"{d}\n" for d in decls) +
            'extern "C" {\n'
            f"extern const uint32_t imf_fw_types[{max(len(st), 1)}] IMF_FLASH;\n"
            "void imf_cxx_init(void);\nvoid imf_cxx_load(const double *imf_fw_sample);\n"
            "void imf_cxx_step(void);\nconst void *imf_cxx_word(int j);\n}\n"
            f"const uint32_t imf_fw_types[{max(len(st), 1)}] IMF_FLASH = {{ {types} }};\n"
            "void imf_cxx_init(void)\n{\n" + start + self._init_code() + "}\n"
            "void imf_cxx_load(const double *imf_fw_sample)\n{\n"
            + "".join(f"    {ld}\n" for ld in loads) + "    (void)imf_fw_sample;\n}\n"
            f"void imf_cxx_step(void)\n{{\n    {call}\n}}\n"
            "const void *imf_cxx_word(int j)\n{\n    switch (j) {\n" + words +
            "    default:\n        return 0;\n    }\n}\n")


# the driver's dump of one state word of a C++ firmware, from its address and type word
# (imf_fw_main.c's IMF_FW_DUMP, for a word whose C type the C driver does not know)
_DUMP_WORD = """static void imf_fw_dump_word(const void *p, uint32_t type)
{
    uint32_t size = type & 0xFFu;
    if ((type & 0x100u) != 0u) {
        if (size == 1u) {
            if ((type & 0x200u) != 0u) { imf_fw_put32((uint32_t)(int32_t)*(const int8_t *)p); }
            else { imf_fw_put32(*(const uint8_t *)p); }
        } else if (size == 2u) {
            if ((type & 0x200u) != 0u) { imf_fw_put32((uint32_t)(int32_t)*(const int16_t *)p); }
            else { imf_fw_put32(*(const uint16_t *)p); }
        } else if (size == 4u) {
            if ((type & 0x200u) != 0u) { imf_fw_put32((uint32_t)*(const int32_t *)p); }
            else { imf_fw_put32(*(const uint32_t *)p); }
        } else {
            unsigned long long v = 0u;
            memcpy(&v, p, 8u);
            imf_fw_out_u64(v);
        }
    } else if (size == 4u) {
        float f;
        memcpy(&f, p, 4u);
        imf_fw_out_f32(f);
    } else {
        double d;
        memcpy(&d, p, sizeof d);
        imf_fw_out_double(d);
    }
}"""

# the type word of imf_fw_main.c's IMF_FW_TYPE, in C++ (no library headers: avr-g++ has none)
_CXX_TRAITS = """template <class T> struct imf_rcv { typedef T t; };
template <class T> struct imf_rcv<const T> { typedef T t; };
template <class T> struct imf_rcv<volatile T> { typedef T t; };
template <class T> struct imf_rcv<const volatile T> { typedef T t; };
template <class T> struct imf_rcv<T &> { typedef typename imf_rcv<T>::t t; };
template <class T> struct imf_fl { enum { v = 0 }; };
template <> struct imf_fl<float> { enum { v = 1 }; };
template <> struct imf_fl<double> { enum { v = 2 }; };
template <> struct imf_fl<long double> { enum { v = 2 }; };
template <class T, int F> struct imf_sg { enum { v = ((T)-1 < (T)0) }; };
template <class T> struct imf_sg<T, 1> { enum { v = 0 }; };
template <class T> struct imf_sg<T, 2> { enum { v = 0 }; };
template <class T> struct imf_type {
    static const uint32_t v = (uint32_t)sizeof(T) | (imf_fl<T>::v ? 0u : 0x100u)
                              | (imf_sg<T, imf_fl<T>::v>::v ? 0x200u : 0u)
                              | (imf_fl<T>::v == 2 && sizeof(T) == sizeof(double) ? 0x400u : 0u);
};
"""
