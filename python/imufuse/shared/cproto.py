"""The one C-prototype reader of imufuse (firmware harness, MCU runner,
catalogue checks): `void f(T *const self, float a, const float g[3]);` ->
Prototype(name, returns, params)."""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Optional, Tuple

__all__ = ["CParam", "Prototype", "PrototypeError", "strip_comments", "parse_prototype",
           "find_prototype", "struct_members", "init_params"]

_QUALIFIERS = ("const", "volatile", "restrict", "struct")


class PrototypeError(ValueError):
    """Text that is not a C prototype this reader understands."""


@dataclass(frozen=True)
class CParam:
    name: str
    ctype: str                     # element type without qualifiers, * or [] ("imf_real",
                                   # "struct att_t", "unsigned int")
    pointer: bool                  # declared with *
    array: bool = False            # declared with []
    length: Optional[int] = None   # declared array length (imf_real gyr[3])

    @property
    def vector(self) -> bool:
        """Takes an address: pointer or array parameter."""
        return self.pointer or self.array


@dataclass(frozen=True)
class Prototype:
    name: str
    returns: str                   # "void", "int", ... (storage class and inline dropped)
    params: Tuple[CParam, ...]


_PROTO = re.compile(r"^\s*([\w\s\*]*?)\b(\w+)\s*\((.*)\)\s*;?\s*$", re.S)


def strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    return re.sub(r"//[^\n]*", " ", text)


def _param(i: int, func: str, text: str) -> CParam:
    p = " ".join(text.split())
    m = re.search(r"\[\s*(\d*)\s*\]", p)
    p0 = re.sub(r"\[[^\]]*\]", "", p)
    words = [w for w in re.findall(r"\w+", p0) if w not in _QUALIFIERS]
    if len(words) < 2:
        raise PrototypeError(f"parameter {i + 1} of {func}: name it ({p!r})")
    ctype = " ".join(words[:-1])
    if "struct" in p0.split():
        ctype = "struct " + ctype
    return CParam(words[-1], ctype, "*" in p0, m is not None,
                  int(m.group(1)) if m and m.group(1) else None)


def parse_prototype(text: str) -> Prototype:
    """One prototype: 'void f(T *self, float a, const float g[3])'."""
    m = _PROTO.match(strip_comments(text).strip())
    if not m:
        raise PrototypeError(f"cannot read C prototype {text!r}")
    ret = " ".join(w for w in m.group(1).split() if w not in ("static", "inline", "extern"))
    body = m.group(3).strip()
    params: Tuple[CParam, ...] = ()
    if body and body != "void":
        params = tuple(_param(i, m.group(2), p) for i, p in enumerate(body.split(",")))
    return Prototype(m.group(2), ret or "int", params)


def find_prototype(text: str, func: str) -> Optional[Prototype]:
    """The declaration of `func` in C source text (a header), or None."""
    m = re.search(r"(?:^|[;}\n])\s*([\w \t\*]*?\b" + re.escape(func) + r"\s*\([^)]*\)\s*;)",
                  strip_comments(text))
    return parse_prototype(m.group(1)) if m else None


def struct_members(text: str, type_name: str) -> Optional[Tuple[CParam, ...]]:
    """The members of the struct `type_name` in C source text, in order: `typedef struct
    [tag] {...} type_name;`, `struct tag {...}; typedef struct tag type_name;`, or one
    typedef alias `typedef other_t type_name;` followed. None when not defined there.
    PrototypeError for members this reader does not take as values: nested or anonymous
    structs and unions, bit-fields, function pointers."""
    text = strip_comments(text)
    m = re.search(r"typedef\s+struct\s+(\w+)\s+" + re.escape(type_name) + r"\s*;", text)
    start: Optional[int] = None
    if m:
        body = re.search(r"struct\s+" + re.escape(m.group(1)) + r"\s*\{", text)
        if body is None:
            return None
        start = body.end()
    else:
        m = re.search(r"typedef\s+(\w+)\s+" + re.escape(type_name) + r"\s*;", text)
        if m and m.group(1) != "struct":
            return struct_members(text, m.group(1))
        m = re.search(r"typedef\s+struct\s*\w*\s*\{", text)
        while m:
            # the body of this typedef, braces balanced, then the name it defines
            depth, k = 1, m.end()
            while depth and k < len(text):
                depth += {"{": 1, "}": -1}.get(text[k], 0)
                k += 1
            if re.match(r"\s*" + re.escape(type_name) + r"\s*;", text[k:]):
                start = m.end()
                break
            m = re.compile(r"typedef\s+struct\s*\w*\s*\{").search(text, k)
    if start is None:
        return None
    depth, k = 1, start
    while depth and k < len(text):
        depth += {"{": 1, "}": -1}.get(text[k], 0)
        k += 1
    body_text = text[start:k - 1]
    if "{" in body_text:
        raise PrototypeError(f"{type_name}: a nested struct or union member; only numbers can "
                             "be set from imufuse's settings")
    out: list = []
    for decl in body_text.split(";"):
        decl = " ".join(decl.split())
        if not decl:
            continue
        if ":" in decl:
            raise PrototypeError(f"{type_name}: bit-field member {decl!r}; only plain "
                                 "numbers can be set from imufuse's settings")
        if "(" in decl:
            raise PrototypeError(f"{type_name}: function pointer member {decl!r}; only plain "
                                 "numbers can be set from imufuse's settings")
        # "imf_real a, b" -> two members of type imf_real
        first, *more = decl.split(",")
        p = _param(len(out), type_name, first)
        if re.search(r"\bconst\b", first.split("*")[0]):
            raise PrototypeError(f"{type_name}.{p.name}: a const member cannot be set")
        out.append(p)
        for name in more:
            out.append(_param(len(out), type_name, p.ctype + " " + name))
    return tuple(out)


def init_params(text: str, func: str) -> Optional[Tuple[Optional[str], Tuple[CParam, ...]]]:
    """The values an init function `func` takes after `self`: its parameters, or, when it
    takes one `const T *settings` (a settings or constants struct), T's members.
    Returns (T or None, values), or None if `func` is not declared in text."""
    proto = find_prototype(text, func)
    if proto is None:
        return None
    rest = proto.params[1:]
    if len(rest) == 1 and rest[0].pointer and rest[0].ctype.endswith("_t"):
        members = struct_members(text, rest[0].ctype)
        if members is not None:
            return rest[0].ctype, members
    return None, rest
