"""Small files a user writes by hand (a calibration file, a column map): read whole within a
size bound (1 MiB) as UTF-8 text (a byte-order mark allowed), and, for the JSON ones, parsed
into an object with a bounded nesting and every key once. Whatever is wrong is one
FileContentError naming the file and the fault: the byte offset of an encoding error, the
size, the line of a syntax error or of a nesting too deep, a key given twice; never a
RecursionError or a bare decode error. Callers turn it into their own exception (LogError,
CalibrationError) with its `kind`."""
from __future__ import annotations

import json
import os
import re
import stat
from typing import Any, Dict, List, Tuple

__all__ = ["FileContentError", "read_text", "parse_object", "read_object", "MAX_BYTES",
           "MAX_DEPTH"]

#: the largest file read (a calibration file is under 1 KB, a column map a few)
MAX_BYTES = 1 << 20
#: the deepest nesting of arrays and objects (a calibration file needs 3)
MAX_DEPTH = 32

_STRING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"', re.S)
_BRACKET = re.compile(r"[\[\]{}]")
_JSON_TYPES = {list: "an array", str: "a string", int: "a number", float: "a number",
               bool: "true or false", type(None): "null"}


class FileContentError(ValueError):
    """A file that cannot be used; `kind` is "file" (missing, unreadable), "data" (its
    contents) or "usage" (a key given twice, where the caller counts it a usage error)."""

    def __init__(self, message: str, kind: str = "data") -> None:
        super().__init__(message)
        self.kind = kind


class _Repeated(Exception):
    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _size(n: int) -> str:
    return f"{n >> 20} MiB" if n % (1 << 20) == 0 else f"{n} bytes"


def read_text(path: "str | os.PathLike[str]", what: str, limit: int = MAX_BYTES) -> str:
    """The text of a small file; FileContentError ("file") when it cannot be read, ("data")
    when it is larger than `limit` bytes or not UTF-8."""
    try:
        with open(path, "rb") as fh:
            st = os.fstat(fh.fileno())
            size = st.st_size if stat.S_ISREG(st.st_mode) else 0
            if size > limit:
                raise FileContentError(f"{path}: {size} bytes, too large for a {what} (at most "
                                       f"{_size(limit)})")
            raw = fh.read(limit + 1)       # a device or a pipe: read no more than the bound
    except OSError as e:
        raise FileContentError(f"{path}: cannot read the {what} ({e.strerror or e})",
                               "file") from None
    if len(raw) > limit:
        raise FileContentError(f"{path}: more than {_size(limit)}, too large for a {what}")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        at = len(raw) - len(e.object) + e.start      # e.object: after a byte-order mark
        line = raw.count(b"\n", 0, at) + 1
        raise FileContentError(f"{path}: not UTF-8 text (byte 0x{raw[at]:02x} at offset {at}, "
                               f"line {line}); save the {what} as UTF-8") from None


def _too_deep(text: str, limit: int) -> int:
    """The line where arrays and objects first nest deeper than `limit`, else 0."""
    bare = _STRING.sub(lambda m: "s" * len(m.group()), text)
    depth = 0
    for m in _BRACKET.finditer(bare):
        if m.group() in "[{":
            depth += 1
            if depth > limit:
                return bare.count("\n", 0, m.start()) + 1
        else:
            depth -= 1
    return 0


def _once(items: List[Tuple[str, Any]]) -> Dict[str, Any]:
    out: Dict[str, Any] = {}
    for k, v in items:
        if k in out:
            raise _Repeated(k)
        out[k] = v
    return out


def parse_object(text: str, path: "str | os.PathLike[str]", what: str,
                 repeated: str = "data", max_depth: int = MAX_DEPTH) -> Dict[str, Any]:
    """A JSON object from `text` (read from `path`); FileContentError naming the fault. A
    key given twice in one object is of kind `repeated`."""
    if not text.strip():
        raise FileContentError(f"{path}: empty; a {what} is a JSON object {{...}}")
    deep = _too_deep(text, max_depth)
    if deep:
        raise FileContentError(f"{path}: not a {what}: arrays and objects nested deeper than "
                               f"{max_depth} levels (line {deep})")
    try:
        data = json.loads(text, object_pairs_hook=_once)
    except _Repeated as e:
        raise FileContentError(f"{path}: key {e.key!r} given twice; give it once",
                               repeated) from None
    except json.JSONDecodeError as e:
        raise FileContentError(f"{path}: not valid JSON ({e.msg}, line {e.lineno} column "
                               f"{e.colno})") from None
    except (ValueError, RecursionError) as e:
        # e.g. an integer of more digits than Python converts
        raise FileContentError(f"{path}: not a usable {what} ({' '.join(str(e).split())[:200]})") \
            from None
    if not isinstance(data, dict):
        raise FileContentError(f"{path}: not a {what}: expected a JSON object {{...}}, got "
                               f"{_JSON_TYPES.get(type(data), type(data).__name__)}")
    return data


def read_object(path: "str | os.PathLike[str]", what: str, repeated: str = "data",
                limit: int = MAX_BYTES) -> Dict[str, Any]:
    """read_text and parse_object: the JSON object of a small file."""
    return parse_object(read_text(path, what, limit), path, what, repeated)
