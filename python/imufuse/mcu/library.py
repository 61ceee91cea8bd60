"""What the C library's headers say about one filter, for the MCU runner.

``c_library(c_name)`` finds the header under ``csrc/`` (or ``csrc/fixed/``) that declares
``<c_name>_init`` and reads, through ``imufuse.shared.cproto`` (the project's one C-prototype reader),
the values init takes (its parameters, or the members of the settings struct it takes), the
update's parameters, the fixed-point ``<c_name>_init_consts`` and whether the filter struct
counts ``skipped`` samples. ``init_call`` writes the C of an init call, ``literal`` an exact C
literal of one argument in its parameter's type.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

from ..shared.resources import csrc_dir
from ..shared.bits import c_double_literal, c_float_literal
from ..shared.cproto import CParam, PrototypeError, find_prototype, init_params, struct_members
from .toolchains import HarnessError

__all__ = ["CSRC", "CFilter", "c_library", "init_call", "literal"]

#: csrc/ as shipped in the package (imufuse/csrc)
CSRC = csrc_dir()


@dataclasses.dataclass(frozen=True)
class CFilter:
    """What the headers say about one C filter."""

    c_name: str
    c_update: str                # the update it runs: <c_name>_update or _update_imu
    header: Path
    source: Path
    init: Tuple[CParam, ...]     # the values init takes (the settings struct's members)
    init_returns: str            # "void" or an integer type (fixed point: 0 = ok)
    update: Tuple[CParam, ...]   # without self
    has_skipped: bool
    init_consts: Optional[Tuple[CParam, ...]] = None  # fixed point: <c_name>_init_consts
    init_struct: Optional[str] = None         # init(self, const T *settings): T
    init_consts_struct: Optional[str] = None  # init_consts(self, const T *consts): T


def _prototype(text: str, func: str) -> Tuple[str, Tuple[CParam, ...]]:
    """(returns, parameters after the filter pointer) of ``func`` declared in ``text``."""
    try:
        p = find_prototype(text, func)
    except PrototypeError as e:
        raise HarnessError(str(e)) from None
    if p is None:
        raise HarnessError(f"no prototype of {func}()")
    if not p.params or not p.params[0].pointer:
        raise HarnessError(f"{func}(): the first parameter must be the filter pointer")
    return p.returns, p.params[1:]


def _init_values(text: str, func: str) -> Tuple[str, Optional[str], Tuple[CParam, ...]]:
    """(returns, settings struct or None, the values): an init that takes a settings
    struct takes its members."""
    ret, _ = _prototype(text, func)
    try:
        got = init_params(text, func)
    except PrototypeError as e:
        raise HarnessError(str(e)) from None
    assert got is not None
    return ret, got[0], got[1]


def _declares(text: str, func: str) -> bool:
    try:
        return find_prototype(text, func) is not None
    except PrototypeError as e:
        raise HarnessError(str(e)) from None


def _members(text: str, type_name: str) -> Tuple[CParam, ...]:
    try:
        return struct_members(text, type_name) or ()
    except PrototypeError as e:
        raise HarnessError(str(e)) from None


def init_call(func: str, var: str, struct: Optional[str], params: Sequence[CParam],
              args: Sequence[str], static: bool = True) -> Tuple[str, str]:
    """(declarations, call expression) of init ``func`` on ``&var`` with ``args``:
    positional (no declarations), or (``struct``) through a settings struct ``<var>_set``:
    with ``static``, a ``static const`` struct initialised by the values in the members'
    order, as firmware whose settings are known when it is built writes it (the values are
    the program's constant data, the call passes one address: on AVR fewer bytes than ten
    values in registers, or a struct on the stack filled member by member); else that
    struct on the stack filled member by member (``args`` need not be constant
    expressions: a compound literal of a q-scale). Valid C and C++."""
    if struct is None:
        return "", f"{func}(&{var}{''.join(', ' + a for a in args)})"
    if len(args) != len(params):
        raise HarnessError(f"{func}: {len(args)} values for the {len(params)} members of {struct}")
    if static:
        return (f"static const {struct} {var}_set = {{{', '.join(args)}}};",
                f"{func}(&{var}, &{var}_set)")
    fill = "".join(f" {var}_set.{p.name} = {a};" for p, a in zip(params, args))
    return f"{struct} {var}_set;{fill}", f"{func}(&{var}, &{var}_set)"


def _headers(csrc: Path) -> List[Path]:
    return sorted(csrc.glob("*.h")) + sorted((csrc / "fixed").glob("*.h"))


_HEADER_CACHE: Dict[Tuple[str, str, str], CFilter] = {}


def c_library(c_name: str, csrc: Path = CSRC, c_update: str = "") -> CFilter:
    """Find ``<c_name>_init`` in the headers of ``csrc`` and read the filter's prototypes;
    the update is ``c_update`` (a reference class's: a family's form without magnetometer
    is ``<c_name>_update_imu``), by default ``<c_name>_update``."""
    c_update = c_update or c_name + "_update"
    key = (str(csrc), c_name, c_update)
    if key in _HEADER_CACHE:
        return _HEADER_CACHE[key]
    for h in _headers(Path(csrc)):
        text = h.read_text()
        if not _declares(text, c_name + "_init"):
            continue
        ret, init_struct, init = _init_values(text, c_name + "_init")
        _, update = _prototype(text, c_update)
        init_consts, consts_struct = None, None
        if _declares(text, c_name + "_init_consts"):
            _, consts_struct, init_consts = _init_values(text, c_name + "_init_consts")
        has_skipped = any(m.name == "skipped" for m in _members(text, c_name + "_t"))
        src = h.with_suffix(".c")
        if not src.is_file():
            raise HarnessError(f"{c_name}: {h} has no {src.name} next to it")
        cf = CFilter(c_name, c_update, h, src, init, ret, update, has_skipped, init_consts, init_struct,
                     consts_struct)
        _HEADER_CACHE[key] = cf
        return cf
    raise HarnessError(f"no header under {csrc} declares {c_name}_init()")


def literal(param: CParam, value, real: str) -> str:
    """An exact C literal of ``value`` for ``param``'s type; ``imf_real`` is ``real``
    ("float" or "double")."""
    t = re.sub(r"\bconst\b", "", param.ctype).strip()
    if isinstance(value, dict):
        # a nested constants struct (RobustAHRSQ's RobustIMUQ part), by its members in
        # declaration order: q-scales, and int32 or uint32 integers
        def member(k, v):
            ct = ("imf_qscale_t" if hasattr(v, "m") else
                  "int32_t" if -(1 << 31) <= int(v) < (1 << 31) else "uint32_t")
            return literal(CParam(k, ct, False), v, real)
        return f"({t}){{" + ", ".join(member(k, v) for k, v in value.items()) + "}"
    if t == "imf_qscale_t":
        m, s = (int(v) for v in (value.m, value.s))
        return f"(imf_qscale_t){{(int16_t){m}, (int16_t)({s})}}"
    if t == "imf_real":
        t = real
    if t in ("float", "double"):
        # double on AVR is float: the compiler rounds the exact double literal once, as C's
        # conversion of a double argument would
        v = float(value)
        try:
            return c_float_literal(v) if t == "float" else c_double_literal(v)
        except ValueError:
            raise HarnessError(f"non-finite init argument {v!r}") from None
    if re.fullmatch(r"(unsigned\s+)?(int|long|short|char|u?int(8|16|32|64)_t)", t) or t == "unsigned":
        iv = int(value)
        if iv != value:
            raise HarnessError(f"{param.name}: integer parameter got {value!r}")
        return f"({t}){iv}" if iv >= 0 else f"({t})({iv})"
    raise HarnessError(f"{param.name}: unsupported C parameter type {param.ctype!r}")
