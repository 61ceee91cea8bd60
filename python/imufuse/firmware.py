"""Validate firmware filter code against imufuse, bit for bit.

Compile your C sources with cffi, bind the filter through a short
declaration, run it on the same inputs as an imufuse filter and compare every
state variable after every sample.

    from imufuse.firmware import Firmware, validate
    fw = Firmware(sources=["fw/attitude.c"], include_dirs=["fw"], headers=["attitude.h"],
                  init="void att_init(att_t *self, float dt, float k0)",
                  update="void att_update(att_t *self, float rate, float angle)",
                  state={"theta": "x.theta"})
    report = validate(fw, "Kalman1D", dict(dt=0.005, k0=0.01), inputs)
    print(report.text())

The declaration:
  init, update  C prototypes (or only the function names: the prototypes are
                then looked up in `headers`). If the first parameter of init
                (or, without init, of update) is a pointer to a non-float type,
                it is the filter object: the harness allocates one (zeroed) and
                passes its address. Without it, the filter lives in globals.
  init's other parameters receive the imufuse filter's C init arguments
                (imufuse.reference.X._params(...), the order of csrc's
                <c_name>_init) when the counts match; otherwise they are matched
                by name to the filter's parameters (dt included) or to
                `init_args` {name: value}.
  update's other parameters receive the inputs in the imufuse order: 1d: rate,
                angle; imu: gyr x, y, z, acc x, y, z; ahrs: + mag x, y, z.
                A scalar parameter takes one value, an array or pointer
                parameter (`const float g[3]`, `float *g`) one 3-vector; a
                scalar parameter named dt / deltat / delta_t gets the sample
                period.
  state         {imufuse state name: C expression}: a member path relative to
                the filter object (`x.theta`, `q[0]`) or any C expression
                using `self` or globals, marked by a leading `=`
                (`=self->x.theta`, `=q0`). Default: `x.<name>` for every
                state name (csrc's convention).
  set_state     True: after init, write the imufuse filter's initial state into
                the state expressions (they must then be lvalues); default:
                only when there is no init function.
The precision of the firmware is read from sizeof of the state expressions.

Compilation: `cflags` default DEFAULT_CFLAGS (the numerical contract of
docs/internals.md); give a list to replace them. `defines` {NAME: value or None}.
Builds are cached under $IMUFUSE_CACHE or ~/.cache/imufuse/firmware, keyed by
the generated source, the flags and the contents of the sources and headers.
"""
import glob
import hashlib
import importlib.util
import json
import inspect
import math
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from . import cproto
from ._checks import KINDS
from .bits import Comparison, compare_states, ulps
from . import firmware_target as ft
from .catalogue import entry, make_filter, reference_class
from .firmware_target import Cause, angle_divergence_deg, find_causes

__all__ = ["Firmware", "FirmwareError", "Validation", "validate", "csrc_firmware",
           "parse_prototype", "Comparison", "compare_states", "ulps", "DEFAULT_CFLAGS"]

DEFAULT_CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off")
_FLOAT_TYPES = {"float", "double", "imf_real", "real", "float32_t", "float64_t", "real_t"}
_DT_NAMES = {"dt", "deltat", "delta_t"}


class FirmwareError(ValueError):
    """A declaration that cannot be bound, or sources that do not compile."""


# ---------------------------------------------------------------------------
# declarations

def parse_prototype(text: str) -> cproto.Prototype:
    """'void f(T *self, float a, const float g[3])' -> cproto.Prototype."""
    try:
        return cproto.parse_prototype(text)
    except cproto.PrototypeError as e:
        raise FirmwareError(str(e)) from None


def _header_text(headers, include_dirs):
    """The text of the headers that exist (as given, or under include_dirs)."""
    out = []
    for h in headers:
        for d in ["", *include_dirs]:
            path = os.path.join(d, h) if d else h
            if os.path.isfile(path):
                with open(path) as fh:
                    out.append(fh.read())
                break
    return "\n".join(out)


def _find_prototype(fname, headers, include_dirs):
    for h in headers:
        for d in ["", *include_dirs]:
            path = os.path.join(d, h) if d else h
            if os.path.isfile(path):
                with open(path) as fh:
                    proto = cproto.find_prototype(fh.read(), fname)
                if proto:
                    return proto
    raise FirmwareError(f"prototype of {fname} not found in headers {list(headers)} "
                        f"(include dirs {list(include_dirs)}); give the full prototype")


_INT_TYPE = re.compile(r"(unsigned\s+|signed\s+)?(int|long|long long|short|char|unsigned|"
                       r"u?int(8|16|32|64)_t|u?int_(fast|least)(8|16|32|64)_t|size_t)")


def _is_integer_type(ctype):
    return bool(_INT_TYPE.fullmatch(ctype.strip()))


def _is_self(p):
    return p.pointer and p.ctype.split()[-1] not in _FLOAT_TYPES


def _state_expr(expr, has_self):
    """A member path relative to the filter object (or, without one, a global
    variable path), or '=C expression'."""
    expr = expr.strip()
    if expr.startswith("="):
        return expr[1:].strip()
    if not re.fullmatch(r"[A-Za-z_]\w*(\s*(\.\s*[A-Za-z_]\w*|\[\s*\d+\s*\]))*", expr):
        raise FirmwareError(f"state expression {expr!r}: give a member path (x.theta, q[0]) "
                            "or a C expression after '=' (=self->x.theta, =q0)")
    return "self->" + expr if has_self else expr


# ---------------------------------------------------------------------------
# the firmware object

class Firmware:
    """User C sources plus a declaration; see the module doc."""

    def __init__(self, sources, *, init=None, update, state=None, state_names=None,
                 headers=(), include_dirs=(), defines=None, cflags=None, init_args=None,
                 set_state=None, cache_dir=None):
        self.sources = [os.path.abspath(s) for s in sources]
        for s in self.sources:
            if not os.path.isfile(s):
                raise FirmwareError(f"source file not found: {s}")
        self.include_dirs = [os.path.abspath(d) for d in include_dirs]
        self.headers = list(headers)
        self.defines = dict(defines or {})
        self.cflags_given = None if cflags is None else list(cflags)
        self.cflags = list(DEFAULT_CFLAGS if cflags is None else cflags)
        self.init_args = dict(init_args or {})
        self.cache_dir = cache_dir or os.environ.get("IMUFUSE_CACHE") or os.path.join(
            os.path.expanduser("~"), ".cache", "imufuse", "firmware")

        def proto(x):
            if x is None:
                return None
            if "(" not in x:
                return _find_prototype(x, self.headers, self.include_dirs)
            return parse_prototype(x)
        self.init = proto(init)
        self.update = proto(update)
        first = (self.init or self.update).params
        self.self_type = first[0].ctype if first and _is_self(first[0]) else None
        if self.init and self.self_type and not (self.init.params and _is_self(self.init.params[0])):
            raise FirmwareError(f"{self.init.name}: expected the filter object as first parameter")
        # init(self, const T *settings): the values are T's members (a settings struct)
        self.init_struct = None
        if self.init:
            ps = self.init.params[1:] if self.self_type else self.init.params
            if len(ps) == 1 and ps[0].pointer and ps[0].ctype.split()[-1] not in _FLOAT_TYPES:
                text = _header_text(self.headers, self.include_dirs)
                try:
                    members = cproto.struct_members(text, ps[0].ctype)
                    nested = [m for m in members or () if not m.vector
                              and cproto.struct_members(text, m.ctype) is not None]
                except cproto.PrototypeError as e:
                    raise FirmwareError(f"{self.init.name}: {e}") from None
                if nested:
                    raise FirmwareError(f"{ps[0].ctype}.{nested[0].name}: a struct member "
                                        f"({nested[0].ctype}); only numbers can be set from "
                                        "imufuse's settings")
                if members is None:
                    raise FirmwareError(
                        f"{self.init.name}: takes {ps[0].ctype} *{ps[0].name}, a struct the "
                        f"headers {list(self.headers)} do not define (typedef struct {{...}} "
                        f"{ps[0].ctype};)")
                for m in members:
                    if m.vector:
                        raise FirmwareError(f"{ps[0].ctype}.{m.name}: array and pointer "
                                            "members cannot be set from imufuse's settings")
                self.init_struct = (ps[0].ctype, members)
        self.set_state = (self.init is None) if set_state is None else bool(set_state)
        if state is None:
            if state_names is None:
                raise FirmwareError("give state {name: expression} or state_names")
            state = {n: f"x.{n}" for n in state_names}
        self.state = {n: _state_expr(e, bool(self.self_type)) for n, e in state.items()}
        self._lib = None

    # -- binding -----------------------------------------------------------
    def _init_params(self):
        """The values init takes: its parameters after the filter object, or the members of
        the settings struct it takes."""
        if self.init_struct:
            return self.init_struct[1]
        return self.init.params[1:] if self.self_type else self.init.params

    def _init_call(self, args):
        """C statements calling init with ``args`` (one per _init_params())."""
        obj = ["self"] if self.self_type else []
        if not self.init_struct:
            return f"{self.init.name}({', '.join(obj + list(args))});"
        st, members = self.init_struct
        fill = " ".join(f"imf_fw_set.{m.name} = ({m.ctype})({a});" for m, a in zip(members, args))
        return f"{{ {st} imf_fw_set; {fill} {self.init.name}({', '.join(obj + ['&imf_fw_set'])}); }}"

    def _init_values(self, c_args, params):
        """Values for init's parameters after the filter object (or its settings struct's
        members): by name (--init-arg, then the imufuse filter's C init values, then its
        Python parameters), else by position when the counts agree."""
        ps = self._init_params()
        what = "member" if self.init_struct else "parameter"
        names = [p.name for p in ps]
        unknown = [k for k in self.init_args if k not in names]
        if unknown:
            raise FirmwareError(f"--init-arg {unknown[0]}: {self.init.name} has no {what} of "
                                f"that name (it takes {', '.join(names) or 'none'})")
        named = dict(c_args) if isinstance(c_args, dict) else {}
        values = list(named.values()) if named else list(c_args or ())

        def number(p, v, source):
            try:
                f = float(v)
            except (TypeError, ValueError):
                raise FirmwareError(
                    f"{self.init.name}: {what} {p.name!r} would get {v!r} ({source}), not a "
                    f"number; give it with --init-arg {p.name}=VALUE") from None
            if _is_integer_type(p.ctype) and math.isfinite(f) and f != int(f):
                raise FirmwareError(f"{self.init.name}: integer {what} {p.name!r} would get "
                                    f"{v!r} ({source}); give it with --init-arg {p.name}=N")
            return f

        by_name = []
        for p in ps:
            if p.name in self.init_args:
                by_name.append(number(p, self.init_args[p.name], "--init-arg"))
            elif p.name in named:
                by_name.append(number(p, named[p.name], "the imufuse filter's C value"))
            elif p.name in params and params[p.name] is not None:
                by_name.append(number(p, params[p.name], "the imufuse parameter"))
            else:
                by_name.append(None)
        if all(v is not None for v in by_name):
            return by_name
        if not self.init_args and len(ps) == len(values):
            return [number(p, v, "by position") for p, v in zip(ps, values)]
        p = ps[by_name.index(None)]
        raise FirmwareError(
            f"{self.init.name}: no value for {what} {p.name!r} (the imufuse filter "
            f"has {len(values)} init arguments, this init {len(ps)}; map it with "
            f"init_args / --init-arg {p.name}=VALUE)")

    def _update_plan(self, kind):
        """update's parameters after the filter object, each as (param, how, pos):
        how "dt" (the sample period), "vec" (inputs pos..pos+2) or "scalar" (input pos);
        and the number of input values a sample has."""
        names = KINDS[kind]
        n_vec = 1 if kind == "1d" else 3
        ps = self.update.params[1:] if self.self_type else self.update.params
        pos, plan = 0, []
        total = len(names) * n_vec
        for p in ps:
            if not p.vector and p.name in _DT_NAMES:
                plan.append((p, "dt", -1))
            elif p.vector:
                if kind == "1d" or pos % 3 or pos >= total:
                    raise FirmwareError(f"{self.update.name}: array parameter {p.name!r} does not "
                                        f"match the inputs ({', '.join(names)})")
                plan.append((p, "vec", pos))
                pos += 3
            else:
                if pos >= total:
                    raise FirmwareError(f"{self.update.name}: parameter {p.name!r} has no input "
                                        f"(inputs: {', '.join(names)}{' x3' if n_vec == 3 else ''})")
                plan.append((p, "scalar", pos))
                pos += 1
        if pos != total:
            raise FirmwareError(f"{self.update.name}: takes {pos} input values, a {kind} filter "
                                f"gives {total} ({', '.join(names)})")
        return plan, total

    def _update_call(self, kind):
        """C statements calling update from x (double inputs) and dt."""
        plan, total = self._update_plan(kind)
        args, decls = ["self"] if self.self_type else [], []
        for p, how, pos in plan:
            if how == "dt":
                args.append("(dt)")
            elif how == "vec":
                decls.append(f"{p.ctype} v_{p.name}[3] = {{ ({p.ctype})x[{pos}], "
                             f"({p.ctype})x[{pos + 1}], ({p.ctype})x[{pos + 2}] }};")
                args.append(f"v_{p.name}")
            else:
                args.append(f"x[{pos}]")
        return decls, f"{self.update.name}({', '.join(args)});", total

    def source(self, kind, n_init):
        decls, call, n_in = self._update_call(kind)
        heads = "".join(f'#include "{h}"\n' for h in self.headers)
        st = list(self.state.values())
        obj = ("    static " + self.self_type + " obj;\n"
               f"    {self.self_type} *const self = &obj;\n"
               "    memset(&obj, 0, sizeof obj);\n") if self.self_type else ""
        if self.init:
            init = f"    {self._init_call([f'p[{i}]' for i in range(n_init)])}\n"
        else:
            init = ""
        setst = "".join(f"    if (set_state) {e} = s0[{j}];\n" for j, e in enumerate(st)) \
            if self.set_state else ""
        store = "".join(f"        out[k * {len(st)} + {j}] = (double)({e});\n"
                        for j, e in enumerate(st))
        sizes = "".join(f"    sizes[{j}] = (int)sizeof({e});\n" for j, e in enumerate(st))
        # an integer expression gives 1 / 2 == 0 in its own arithmetic, a floating one 0.5
        isint = "".join(f"    isint[{j}] = ((({e}) * 0 + 1) / 2 == 0);\n" for j, e in enumerate(st))
        selfdecl = f"    {self.self_type} *self = 0;\n    (void)self;\n" if self.self_type else ""
        return (
            "#include <string.h>\n#include <stddef.h>\n" + heads +
            "void imufuse_fw_run(const double *p, const double *s0, int set_state, size_t n,\n"
            "                    const double *in, double dt, double *out, int *isint)\n{\n"
            "    size_t k;\n" + obj + init + setst + isint +
            "    (void)p; (void)s0; (void)set_state; (void)dt;\n"
            "    for (k = 0; k < n; ++k) {\n"
            f"        const double *x = in + k * {n_in};\n"
            + "".join(f"        {d}\n" for d in decls) +
            f"        {call}\n" + store + "    }\n}\n"
            "void imufuse_fw_sizes(int *sizes)\n{\n" + selfdecl + sizes + "}\n")

    def target_source(self, kind, init_values, dt, state0=None, c89=False):
        """The driver of imufuse.firmware_target for an emulated MCU: the filter object,
        the update's arguments as file-scope variables (loaded outside the measured step),
        init with exact literals (hexadecimal; c89: 17 significant decimal digits, which
        the compiler rounds correctly to the same double), the state words with their
        types."""
        def hexfloat(v):
            return ft.hexfloat(v) if not c89 or v == 0.0 else f"{v:.17g}"
        plan, total = self._update_plan(kind)
        heads = "".join(f'#include "{h}"\n' for h in self.headers)
        out = ["/* Generated by imufuse.firmware: the firmware under validation. */", heads]
        out.append(f"#define IMF_FW_ROW {total}")
        if self.self_type:
            out.append(f"static {self.self_type} imf_fw_obj;")
            out.append(f"static {self.self_type} *const self = &imf_fw_obj;")
        args = ["self"] if self.self_type else []
        load = []
        # one variable per input (gyr[3], acc[3]; rate, angle), as the MCU benchmarks store
        # them: the update's call is then the same code as there
        names = KINDS[kind]
        width = 1 if kind == "1d" else 3
        ctypes = {}
        for p, how, pos in plan:
            if how != "dt":
                ctypes.setdefault(names[pos // width], set()).add(p.ctype)
        for i, (p, how, pos) in enumerate(plan):
            if how == "dt":
                v = f"imf_fw_a{i}"
                out.append(f"static {p.ctype} {v};")
                load.append(f"{v} = ({p.ctype})({hexfloat(float(dt))});")
                args.append(v)
                continue
            inp = names[pos // width]
            shared = len(ctypes[inp]) == 1
            var = f"imf_fw_{inp}" if shared else f"imf_fw_a{i}"
            if how == "vec" or (shared and width == 3):
                if not shared or pos % width == 0 or how == "vec":
                    out.append(f"static {p.ctype} {var}[{width}];")
                    load += [f"{var}[{j}] = ({p.ctype})x[{pos + j}];" for j in range(width)]
                args.append(var if how == "vec" else f"{var}[{pos % width}]")
            else:
                out.append(f"static {p.ctype} {var};")
                load.append(f"{var} = ({p.ctype})x[{pos}];")
                args.append(var)
        init = []
        if self.init:
            ps = self._init_params()
            lits = []
            for p, val in zip(ps, init_values):
                val = float(val)
                if _is_integer_type(p.ctype):
                    if val != int(val):
                        raise FirmwareError(f"{self.init.name}: integer parameter {p.name} "
                                            f"gets {val!r}")
                    lits.append(f"({p.ctype})({int(val)}LL)")
                else:
                    lits.append(f"({p.ctype})({hexfloat(val)})")
            init.append(self._init_call(lits))
        if self.set_state and state0 is not None:
            for e, val in zip(self.state.values(), state0):
                val = float(val)
                lit = f"{int(val)}LL" if val == int(val) and abs(val) < 2.0 ** 53 and \
                    not (val == 0 and math.copysign(1.0, val) < 0) else hexfloat(val)
                init.append(f"{e} = {lit};")
        st = list(self.state.values())
        out.append("static void imf_user_init(void)\n{\n" + "".join(f"    {x}\n" for x in init) + "}")
        out.append("static void imf_user_load(const double *x)\n{\n" +
                   "".join(f"    {x}\n" for x in load) + "    (void)x;\n}")
        out.append("static void imf_user_step(void)\n{\n"
                   f"    {self.update.name}({', '.join(args)});\n}}")
        out.append("static void imf_user_dump(void)\n{\n" +
                   "".join(f"    IMF_FW_DUMP({e});\n" for e in st) + "}")
        types = ", ".join(f"IMF_FW_TYPE({e})" for e in st) or "0u"
        out.append(f"const uint32_t imf_fw_types[] IMF_FLASH = {{ {types} }};")
        return "\n".join(out) + "\n"

    def _build(self, kind, n_init):
        src = self.source(kind, n_init)
        h = hashlib.sha256()
        h.update(src.encode())
        h.update(json.dumps([self.cflags, sorted(self.defines.items()), self.include_dirs,
                             self.sources]).encode())
        files = list(self.sources)
        for d in self.include_dirs + sorted({os.path.dirname(s) for s in self.sources}):
            files += sorted(glob.glob(os.path.join(d, "*.h")))
        for f in files:
            h.update(f.encode())
            h.update(open(f, "rb").read())
        name = "_imufuse_fw_" + h.hexdigest()[:20]
        outdir = os.path.join(self.cache_dir, name)
        built = glob.glob(os.path.join(outdir, name + ".*so")) + \
            glob.glob(os.path.join(outdir, name + ".*pyd"))
        if not built:
            try:
                from cffi import FFI
            except ImportError:
                raise FirmwareError("validating on the host compiles the firmware with cffi, "
                                    "which is not installed: pip install 'imufuse[firmware]' "
                                    "(or validate on an emulated MCU with --target)") from None
            ffi = FFI()
            ffi.cdef("void imufuse_fw_run(const double *p, const double *s0, int set_state, "
                     "size_t n, const double *in, double dt, double *out, int *isint);\n"
                     "void imufuse_fw_sizes(int *sizes);")
            defs = [(k, None if v is None else str(v)) for k, v in self.defines.items()]
            ffi.set_source(name, src, sources=self.sources, include_dirs=self.include_dirs,
                           define_macros=defs, extra_compile_args=self.cflags)
            os.makedirs(outdir, exist_ok=True)
            try:
                path = ffi.compile(tmpdir=outdir, verbose=False)
            except Exception as e:  # cffi.VerificationError, distutils CompileError
                raise FirmwareError(f"compilation failed (compiler output above): {e}") from None
        else:
            path = built[0]
        spec = importlib.util.spec_from_file_location(name, path)
        try:
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
        except (ImportError, OSError) as e:
            m = re.search(r"undefined symbol: (\S+)", str(e))
            if m:
                raise FirmwareError(f"symbol not found: {m.group(1)} (declared or called, but "
                                    "defined in none of the sources)") from None
            raise FirmwareError(f"the compiled firmware cannot be loaded: {e}") from None
        return mod

    def prepare(self, kind, c_args=(), params=None):
        """Compile and load the firmware for a `kind` filter (no firmware code runs)."""
        n_init = len(self._init_values(c_args, params or {})) if self.init else 0
        key = (kind, n_init)
        if self._lib is None or self._lib[0] != key:
            self._lib = (key, self._build(kind, n_init))

    def run(self, kind, inputs, dt, c_args=(), params=None, state0=None):
        """Run the firmware on inputs (the run() arrays of a `kind` filter);
        return the (N, n_state) trajectory in the firmware's precision."""
        n_init = len(self._init_values(c_args, params or {})) if self.init else 0
        key = (kind, n_init)
        if self._lib is None or self._lib[0] != key:
            self._lib = (key, self._build(kind, n_init))
        mod = self._lib[1]
        ffi, lib = mod.ffi, mod.lib
        ns = len(self.state)
        sizes = ffi.new("int[]", max(ns, 1))
        lib.imufuse_fw_sizes(sizes)
        sz = set(sizes[j] for j in range(ns))
        cols = [np.asarray(a, dtype=np.float64) for a in inputs]
        x = np.ascontiguousarray(np.column_stack([c if c.ndim == 2 else c[:, None] for c in cols]))
        n = x.shape[0]
        out = np.empty((n, ns), dtype=np.float64)
        p = np.ascontiguousarray(self._init_values(c_args, params or {}) if self.init else [0.0],
                                 dtype=np.float64)
        s0 = np.zeros(max(ns, 1)) if state0 is None else np.ascontiguousarray(state0, dtype=np.float64)
        isint = ffi.new("int[]", max(ns, 1))
        lib.imufuse_fw_run(ffi.cast("double *", p.ctypes.data), ffi.cast("double *", s0.ctypes.data),
                           int(self.set_state), n, ffi.cast("double *", x.ctypes.data),
                           float(dt), ffi.cast("double *", out.ctypes.data), isint)
        ints = {bool(isint[j]) for j in range(ns)}
        if len(ints) > 1:
            raise FirmwareError("state expressions mix integer and floating-point types: "
                                + ", ".join(f"{nm} {'integer' if isint[j] else 'floating'}"
                                            for j, nm in enumerate(self.state)))
        if ints == {True}:
            if sz - {1, 2, 4, 8} or len(sz) != 1:
                raise FirmwareError(f"integer state expressions of different sizes {sorted(sz)}")
            # integers are stored through double: exact up to 2^53
            return out.astype({1: np.int8, 2: np.int16, 4: np.int32, 8: np.int64}[sz.pop()])
        if sz - {4, 8} or len(sz) != 1:
            raise FirmwareError(f"state expressions must all be float or all double; sizes {sorted(sz)}")
        dtype = np.float32 if sz == {4} else np.float64
        return out.astype(dtype)

    def dtype(self, kind="1d", c_args=(), params=None):
        S = self.run(kind, [np.zeros((0, 1 if kind == "1d" else 3))] * len(KINDS[kind]),
                     1.0, c_args, params)
        return S.dtype.name


def csrc_firmware(name: str, csrc_dir: "str | os.PathLike[str]", dtype: str = "float32",
                  **kwargs: Any) -> "Firmware":
    """A Firmware for imufuse's own filter `name` from a csrc directory
    (e.g. a copy with changes): prototypes from the headers, state x.<name>."""
    ref = reference_class(name)
    c = ref.c_name
    headers = [os.path.basename(h) for h in sorted(glob.glob(os.path.join(csrc_dir, "*.h")))]
    sources = sorted(glob.glob(os.path.join(csrc_dir, "*.c")))
    # only the family that declares the filter (its header and source), when found
    for h in headers:
        stem = os.path.splitext(h)[0]
        src = os.path.join(csrc_dir, stem + ".c")
        if os.path.isfile(src) and re.search(r"\b" + c + r"_init\s*\(",
                                             open(os.path.join(csrc_dir, h)).read()):
            headers, sources = [h], [src]
            break
    defines = {"IMF_DOUBLE": None} if dtype == "float64" else {}
    return Firmware(sources, headers=headers, include_dirs=[csrc_dir], defines=defines,
                    init=f"{c}_init", update=f"{c}_update", state_names=ref.state_names, **kwargs)


@dataclass
class Cost:
    """What one update costs on the target (from the emulated run and the linked image)."""
    unit: str                      # "cycles" (AVR) or "instructions" (ARM)
    min: int
    median: float
    max: int
    flash: Optional[int]           # bytes of the firmware's objects in the image (None: -flto
                                   # inlined them into the harness's call)
    ram: int                       # static RAM of the firmware (its filter object included)
    stack: Optional[int]           # deepest stack an update reached, bytes
    library: List[str] = field(default_factory=list)   # library routines it calls
    library_flash: int = 0         # flash of the library code they pull in
    counts: Optional[np.ndarray] = None   # (N,) per update, in `unit`

    def text(self) -> str:
        libs = (f" + {self.library_flash} B of library code for {', '.join(self.library)}"
                if self.library else "")
        stack = f"{self.stack} B" if self.stack is not None else "beyond the painted band"
        fl = f"{self.flash} B" if self.flash is not None else \
            "not separable (-flto inlined the firmware into the call)"
        return (f"cost per update: {self.min} / {self.median:.0f} / {self.max} {self.unit} "
                f"(min / median / max)\n"
                f"flash {fl}{libs}; static RAM {self.ram} B; stack {stack}")


@dataclass
class Validation:
    filter: str
    backend: str
    comparison: Comparison
    got: np.ndarray
    want: np.ndarray
    target: str = "host"
    cflags: Tuple[str, ...] = ()
    causes: List[Any] = field(default_factory=list)
    notes: List[str] = field(default_factory=list)
    max_angle_deg: Optional[float] = None
    cost: Optional[Cost] = None
    timing: Dict[str, float] = field(default_factory=dict)

    @property
    def bit_exact(self):
        return self.comparison.bit_exact

    def text(self):
        flags = " ".join(self.cflags) if self.cflags else "(none)"
        lines = [f"firmware on {self.target} (flags {flags}) vs imufuse {self.filter} "
                 f"({self.backend}, {self.comparison.dtype}):", self.comparison.text()]
        if not self.bit_exact and self.max_angle_deg is not None:
            lines.append(f"largest orientation difference over the run: {self.max_angle_deg:.3g} deg")
        for c in self.causes:
            lines.append(c.text())
        if not self.bit_exact and not any(c.fix for c in self.causes):
            lines.append("cause: none of the known build causes (fused multiply-add, double "
                         "arithmetic, fast-math) was found in the objects: the firmware computes "
                         "something else (an operation, its order, or a constant)")
        lines += [f"note: {n}" for n in self.notes]
        if self.cost is not None:
            lines.append(self.cost.text())
        return "\n".join(lines)


def counts_for(kind: str, params: Mapping[str, Any], inputs: Sequence[Any]) -> List[np.ndarray]:
    """int16 counts of float inputs for a fixed-point filter: the gyro by params' gyr_scale
    (rad/s per count), angles by angle_scale (rad per count), the accelerometer and
    magnetometer (any unit: they are normalised) at 4096 counts per unit."""
    out = []
    for k, a in enumerate(inputs):
        a = np.asarray(a, dtype=np.float64)
        if k == 0:
            c = a / params["gyr_scale"]
        elif kind == "1d":
            c = a / params["angle_scale"]
        else:
            c = a * 4096.0
        out.append(np.clip(np.rint(c), -32768, 32767).astype(np.int16))
    return out


def _state_names(fw, name, e):
    """The firmware's state names, which must be the imufuse filter's."""
    names = tuple(fw.state)
    if set(names) != set(e.state_names):
        raise FirmwareError(f"state mapping names {list(names)}; {name} has state "
                            f"{list(e.state_names)}")
    return names


def _strip_arch(flags):
    return [f for f in flags if not f.startswith(("-mmcu", "-mcpu", "-mfpu", "-mfloat-abi",
                                                  "-mthumb", "-march", "-mtune"))]


def _defs_incs(fw):
    defs = [f"-D{k}" if v is None else f"-D{k}={v}" for k, v in fw.defines.items()]
    return defs + [f"-I{d}" for d in fw.include_dirs] + \
        [f"-I{d}" for d in sorted({os.path.dirname(s) for s in fw.sources})]


def _filter_entry(name):
    return entry(name)


def _make(name, backend, dtype, params):
    e = _filter_entry(name)
    if e.fixed:
        try:
            return e.make(backend, **params)
        except (TypeError, ValueError) as err:
            raise FirmwareError(f"{name}: {err}") from None
    return make_filter(name, backend, dtype, params)


def _reference_run(name, params, inputs, backend, dtype):
    """The imufuse filter's trajectory on the inputs (rounded to dtype first, as run() does);
    returns (inputs as given to both, want, initial state)."""
    e = _filter_entry(name)
    if e.fixed:
        inputs = [np.asarray(a) for a in inputs]
        for a in inputs:
            if a.dtype.kind not in "iu" or np.any(a < -32768) or np.any(a > 32767):
                raise FirmwareError(f"{name} takes int16 counts; got {a.dtype} inputs")
        inputs = [a.astype(np.int16) for a in inputs]
    else:
        inputs = [np.asarray(a, dtype=dtype) for a in inputs]
    f = _make(name, backend, dtype, params)
    state0 = np.asarray(f.state).astype(np.float64)
    want = np.asarray(f.run(*inputs))
    return inputs, want, state0


def validate(fw: "Firmware", name: str, params: Mapping[str, Any], inputs: Sequence[Any],
             backend: str = "c", dtype: Optional[str] = None, target: str = "host",
             timeout: float = 60.0, explain: bool = True) -> "Validation":
    """Run firmware `fw` and the imufuse filter `name` (constructor keywords
    `params`, dt included) on the same inputs; return a Validation. dtype:
    the imufuse precision; default the firmware's (from sizeof of its state);
    the inputs are rounded to it first, as imufuse's run() does. A fixed-point
    filter (`...Q`) is compared as integers, on int16 count inputs.

    target: "host" (cffi, in this process) or an emulated MCU ("cortex-m4f",
    "cortex-m0", "atmega328p"): built there with the firmware's flags (default
    "-O2" for a cross target), run sample by sample on the emulator (logs of any
    length), with the cost per update. explain: when not bit-exact, look for the
    cause in what was built and confirm it by rebuilding with its fix."""
    if target != "host":
        return _validate_target(fw, name, params, inputs, backend, dtype, target, timeout, explain)
    e = _filter_entry(name)
    c_args = _c_values(e, params)
    names = _state_names(fw, name, e)
    fw_dtype = fw.dtype(e.kind, c_args, params)
    integer = np.dtype(fw_dtype).kind in "iu"
    if integer != e.fixed:
        raise FirmwareError(
            f"the firmware's state is {fw_dtype}; {name}'s state is "
            f"{'integer' if e.fixed else 'floating point'}, so they cannot be equal bit for bit "
            "(an integer state is compared as integers, with a fixed-point filter ...Q)")
    if not integer:
        dtype = dtype or fw_dtype
        if dtype != fw_dtype:
            raise FirmwareError(f"the firmware's state is {fw_dtype}, asked to compare with {dtype}")
    inputs, want, state0 = _reference_run(name, params, inputs, backend, dtype)
    order = [e.state_names.index(n) for n in names]
    want = want[:, order]
    got = fw.run(e.kind, inputs, params["dt"], c_args, params, state0[order])
    if integer:
        got, want = got.astype(np.int64), want.astype(np.int64)
    v = Validation(name, backend, compare_states(got, want, names), got, want, "host",
                   tuple(fw.cflags))
    if not v.bit_exact:
        v.max_angle_deg = _angle(name, params, got, want, names)
        if explain and not integer:
            _explain_host(v, fw, name, params, inputs, backend, dtype)
    return v


def _angle(name, params, got, want, names):
    e = _filter_entry(name)
    if tuple(names) != tuple(e.state_names):
        order = [list(names).index(n) for n in e.state_names]
        got, want = got[:, order], want[:, order]
    try:
        return angle_divergence_deg(name, dict(params), got, want, e.fixed)
    except Exception:  # noqa: BLE001 - the angle is extra information, never a failure
        return None


def _explain_host(v, fw, name, params, inputs, backend, dtype):
    """Compile the sources with the firmware's flags, look at the objects, confirm."""
    cc = os.environ.get("CC", "cc")
    if shutil.which(cc) is None:
        return
    wd = Path(tempfile.mkdtemp(prefix="imf_fw_explain_"))
    try:
        incs = [f"-I{d}" for d in fw.include_dirs] + \
            [f"-I{d}" for d in sorted({os.path.dirname(s) for s in fw.sources})]
        defs = [f"-D{k}" if val is None else f"-D{k}={val}" for k, val in fw.defines.items()]
        cmd = [cc, *fw.cflags, *defs, *incs]
        objs = []
        for i, src in enumerate(fw.sources):
            obj = wd / f"fw{i}.o"
            if subprocess.run([*cmd, "-c", src, "-o", str(obj)], capture_output=True).returncode == 0:
                objs.append(obj)
        v.causes = find_causes("objdump", objs, fw.sources, fw.cflags, cmd, v.comparison.dtype,
                               "host", False, wd)
    finally:
        shutil.rmtree(wd, ignore_errors=True)
    def rerun(extra):
        fixed = Firmware.__new__(Firmware)
        fixed.__dict__.update(fw.__dict__)
        fixed.cflags = [*fw.cflags, *extra]
        fixed._lib = None
        return validate(fixed, name, params, inputs, backend, dtype, explain=False).bit_exact

    _confirm(v.causes, rerun)


def _confirm(causes, rerun):
    """Rebuild with each cause's fix (and with all of them when none suffices alone)."""
    fixes = [c for c in causes if c.fix]
    for c in fixes:
        try:
            c.confirmed = rerun([c.fix])
        except FirmwareError:
            c.confirmed = None
    if len(fixes) > 1 and not any(c.confirmed for c in fixes):
        flags = " ".join(c.fix for c in fixes)
        try:
            causes.append(Cause("together", "", flags, rerun([c.fix for c in fixes])))
        except FirmwareError:
            pass


def _c_values(e, params):
    """The imufuse filter's C init values by name, in the C init's order."""
    args = e.reference._params(**params)
    names = list(inspect.signature(e.reference._init).parameters)[1:]
    if len(names) != len(args):
        return tuple(args)
    return dict(zip(names, args))


def _validate_target(fw, name, params, inputs, backend, dtype, target, timeout, explain,
                     cflags=None):
    e = _filter_entry(name)
    c_args = _c_values(e, params)
    names = _state_names(fw, name, e)
    flags = list(cflags if cflags is not None else
                 (fw.cflags_given if fw.cflags_given is not None else ft.DEFAULT_TARGET_CFLAGS))
    init_values = fw._init_values(c_args, params) if fw.init else []
    ref0 = _make(name, backend, dtype or "float32", params)
    state0_all = np.asarray(ref0.state).astype(np.float64)
    order = [e.state_names.index(n) for n in names]
    c89 = any(f in ("-ansi", "-std=c89", "-std=c90", "-std=iso9899:1990", "-std=iso9899:199409")
              for f in flags)
    driver = fw.target_source(e.kind, init_values, params["dt"], state0_all[order], c89)
    _, row = fw._update_plan(e.kind)
    in_dtype = np.dtype(np.int16) if e.fixed else (np.dtype(dtype) if dtype else None)
    try:
        prog = ft.build_program(fw, target, e.kind, driver, row, flags, in_dtype)
    except (ft._tc.ToolchainMissing, ft.TargetError) as err:
        raise FirmwareError(str(err)) from None
    types = prog.types
    integer = {t.integer for t in types}
    if len(integer) > 1:
        raise FirmwareError("state expressions mix integer and floating-point types on the "
                            f"{target}")
    integer_state = integer == {True}
    if integer_state != e.fixed:
        raise FirmwareError(
            f"the firmware's state is {'integer' if integer_state else 'floating point'} on the "
            f"{target}; {name}'s is {'integer' if e.fixed else 'floating point'}: compare an "
            "integer firmware with a fixed-point filter (...Q)")
    notes = [ft.speed_note(target)]
    arch = [f for f in flags if f.startswith(("-mcpu", "-mfpu", "-mfloat-abi", "-mmcu", "-march"))]
    if arch:
        tgt_flags = " ".join(ft._tc.TARGETS[ft.harness_target(target)].arch_flags)
        notes.append(f"your --cflags set the architecture ({' '.join(arch)}) after the "
                     f"target's ({tgt_flags}); the emulator models the {target}")
    if not integer_state:
        sizes = {t.size for t in types}
        if len(sizes) > 1:
            raise FirmwareError(f"state expressions must all be float or all double; sizes "
                                f"{sorted(sizes)} on the {target}")
        fw_dtype = "float32" if sizes == {4} else "float64"
        if dtype and dtype != fw_dtype:
            raise FirmwareError(f"the firmware's state is {fw_dtype} on the {target}, asked to "
                                f"compare with {dtype}")
        dtype = fw_dtype
        if np.dtype(dtype) != prog.in_dtype:
            shutil.rmtree(prog.workdir, ignore_errors=True)
            try:
                prog = ft.build_program(fw, target, e.kind, driver, row, flags, np.dtype(dtype))
            except ft.TargetError as err:
                raise FirmwareError(str(err)) from None
        if target == "atmega328p":
            if any(t.double for t in types):
                notes.append("the firmware's state is declared double, which avr-gcc makes 32 "
                             "bits: it is compared with imufuse in float32")
            # what the host compiler (64-bit double) says about the same sources
            host = [os.environ.get("CC", "cc"), *_strip_arch(flags), *_defs_incs(fw)]
            promo = ft.double_promotions(host, fw.sources, prog.workdir)
            if promo:
                notes.append("the firmware computes in double at " + ", ".join(promo[:4]) +
                             (f" (+{len(promo) - 4} more)" if len(promo) > 4 else "") +
                             ": avr-gcc's double is 32 bits, so here that is float32 arithmetic; "
                             "built where double is 64 bits (Cortex-M4F, a PC) it rounds "
                             "differently (-fsingle-precision-constant or float literals 0.5f)")
    try:
        return _finish_target(fw, name, params, inputs, backend, dtype, target, timeout, explain,
                              flags, prog, types, integer_state, notes, order, names, row, e)
    finally:
        shutil.rmtree(prog.workdir, ignore_errors=True)


def _finish_target(fw, name, params, inputs, backend, dtype, target, timeout, explain, flags,
                   prog, types, integer_state, notes, order, names, row, e):
    inputs, want, state0 = _reference_run(name, params, inputs, backend, dtype)
    want = want[:, order]
    x = np.column_stack([np.asarray(a).reshape(len(a), -1) for a in inputs]) if len(inputs[0]) \
        else np.zeros((0, row), dtype=prog.in_dtype)
    try:
        run = ft.run_program(prog, x, timeout)
    except ft.TargetError as err:
        raise FirmwareError(str(err)) from None
    if integer_state:
        got = np.column_stack(run.states) if run.states else np.zeros((len(x), 0), np.int64)
        want = want.astype(np.int64)
    else:
        got = np.column_stack(run.states).astype(dtype) if run.states else \
            np.zeros((len(x), 0), dtype)
    counts = run.counts
    cost = Cost(run.count_unit, int(counts.min()) if counts.size else 0,
                float(np.median(counts)) if counts.size else 0.0,
                int(counts.max()) if counts.size else 0, prog.flash, prog.ram, run.stack,
                prog.library, prog.library_flash, counts)
    v = Validation(name, backend, compare_states(got, want, names), got, want, target,
                   tuple(flags), notes=notes, cost=cost,
                   timing=dict(build=prog.build_seconds, emulator=run.emulator_seconds,
                               parse=run.parse_seconds, chunks=run.chunks,
                               samples=float(len(x))))
    if not v.bit_exact:
        v.max_angle_deg = _angle(name, params, got, want, names)
    if explain and not v.bit_exact and not integer_state:
        tgt = ft._tc.TARGETS[ft.harness_target(target)]
        v.causes = ft.find_causes(ft._tool_prefix(tgt) + "objdump", prog.user_objects, fw.sources,
                                  flags, [tgt.cc, *tgt.arch_flags, *flags, *_defs_incs(fw)], dtype,
                                  target, any(t.double for t in types), prog.workdir)
        _confirm(v.causes, lambda extra: _validate_target(
            fw, name, params, inputs, backend, dtype, target, timeout, False,
            [*flags, *extra]).bit_exact)
    return v


# ---------------------------------------------------------------------------
# isolation: the firmware runs in a child process

#: seconds a firmware run may take in validate_isolated (imufuse validate --timeout)
DEFAULT_TIMEOUT = 60.0


def _child(conn, fw, name, params, inputs, backend, dtype, n):  # host only
    try:
        inp = inputs if n is None else [a[:n] for a in inputs]
        conn.send(("ok", validate(fw, name, params, inp, backend, dtype)))
    except FirmwareError as e:
        conn.send(("firmware", str(e)))
    except Exception as e:  # noqa: BLE001 - reported to the parent as one line
        conn.send(("error", f"{type(e).__name__}: {e}"))
    finally:
        conn.close()


def _attempt(fw, name, params, inputs, backend, dtype, n, timeout):
    """One run in a child: ("ok", Validation) | ("firmware"|"error", msg) |
    ("signal", signum) | ("exit", code) | ("timeout", None)."""
    import multiprocessing as mp
    ctx = mp.get_context("fork")
    r, w = ctx.Pipe(duplex=False)
    p = ctx.Process(target=_child, args=(w, fw, name, params, inputs, backend, dtype, n),
                    daemon=True)
    p.start()
    w.close()
    try:
        msg = None
        if r.poll(timeout):
            try:
                msg = r.recv()
            except (EOFError, OSError):
                msg = None
        if msg is not None:
            p.join(5)
            return msg
        p.join(0.5 if p.is_alive() else 5)
        if p.is_alive():
            p.kill()
            p.join(5)
            return ("timeout", None)
        code = p.exitcode
        return ("signal", -code) if code is not None and code < 0 else ("exit", code)
    finally:
        r.close()
        if p.is_alive():
            p.kill()
            p.join(5)


def _describe(res, where, timeout):
    import signal
    kind, v = res
    if kind == "signal":
        try:
            sig = signal.Signals(v).name
        except ValueError:
            sig = f"signal {v}"
        return f"the firmware crashed with {sig} {where}"
    if kind == "exit":
        return f"the firmware called exit({v}) {where}"
    if kind == "timeout":
        return f"the firmware gave no answer after {timeout:g} s (an endless loop in init or update?)"
    return v


def validate_isolated(fw, name, params, inputs, backend="c", dtype=None, timeout=DEFAULT_TIMEOUT,
                      target="host"):
    """validate() with the firmware in a child process and a timeout.

    A crash (signal), a call to exit() or a run past `timeout` seconds raises
    FirmwareError with one line: "crashed with SIGSEGV at sample k" (found by
    re-running on shorter prefixes) or "during init", "called exit(3) ...",
    "no answer after N s". Compilation and loading (a missing symbol) happen
    first, in this process, where no firmware code runs."""
    if target != "host":
        return validate(fw, name, params, inputs, backend, dtype, target=target, timeout=timeout)
    e = _filter_entry(name)
    fw.prepare(e.kind, _c_values(e, params), params)
    res = _attempt(fw, name, params, inputs, backend, dtype, None, timeout)
    if res[0] == "ok":
        return res[1]
    if res[0] in ("firmware", "error"):
        raise FirmwareError(res[1])
    if res[0] == "timeout":
        raise FirmwareError(_describe(res, "", timeout))
    # locate the sample: the shortest prefix that fails the same way
    first = _attempt(fw, name, params, inputs, backend, dtype, 0, timeout)
    if first[0] not in ("ok", "firmware", "error"):
        raise FirmwareError(_describe(first, "during init", timeout))
    lo, hi = 0, len(inputs[0])          # run(lo) succeeds, run(hi) fails
    while hi - lo > 1:
        mid = (lo + hi) // 2
        r = _attempt(fw, name, params, inputs, backend, dtype, mid, timeout)
        if r[0] in ("ok", "firmware", "error"):
            lo = mid
        else:
            hi, res = mid, r
    raise FirmwareError(_describe(res, f"at sample {hi - 1}", timeout))
