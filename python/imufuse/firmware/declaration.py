"""The user's declaration of their firmware, bound to imufuse's inputs and state.

``Declaration`` reads the init and update prototypes (given, or looked up in the user's
headers through imufuse.shared.cproto), finds the filter object and any settings struct init takes,
checks the state expressions, and binds: the values init receives (by name or by position,
``_init_values``), the C of an init call (``_init_call``) and which input each update
parameter takes (``_update_plan``). ``imufuse.firmware.Firmware`` builds on it.
"""
import math
import os
import re

from ..shared import cproto
from ..shared.checks import KINDS

__all__ = ["Declaration", "FirmwareError", "parse_prototype", "DEFAULT_CFLAGS"]

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


class Declaration:
    """User C sources plus a declaration; see imufuse.firmware's doc."""

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
