"""The one C-prototype reader of imufuse (firmware harness, MCU runner,
catalogue checks): `void f(T *const self, float a, const float g[3]);` ->
Prototype(name, returns, params)."""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Optional, Tuple

__all__ = ["CParam", "Prototype", "PrototypeError", "strip_comments", "parse_prototype",
           "find_prototype"]

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
