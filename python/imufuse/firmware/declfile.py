"""The declaration file of a firmware's API (TOML): ``load_declaration`` reads it into a
``DeclaredFirmware`` (imufuse.firmware.declared, where the format is described), the imufuse
filter to compare with and its parameters; every mistake is one FirmwareError naming the file
and the key."""
from __future__ import annotations

import inspect
import os
import re
from typing import Any, Dict, List, Mapping, Optional

from ..catalogue import FUSION_AHRS, entry, param_names, resolve_params
from .declaration import FirmwareError
from .declared import CXX_EXTENSIONS, DeclaredFirmware
from .validate import _c_values, _filter_entry

try:
    import tomllib as toml
except ImportError:                       # Python < 3.11
    try:
        import tomli as toml
    except ImportError:
        toml = None

__all__ = ["Declared", "load_declaration"]


class Declared:
    """A loaded declaration file: the firmware, the imufuse filter and its parameters."""

    def __init__(self, firmware: DeclaredFirmware, filter: str, params: Dict[str, Any],
                 path: str) -> None:
        self.firmware, self.filter, self.params, self.path = firmware, filter, params, path


def _table(data: Mapping[str, Any], key: str, path: str, required: bool = True) -> Dict[str, Any]:
    v = data.get(key)
    if v is None:
        if required:
            raise FirmwareError(f"{path}: no [{key}] table")
        return {}
    if not isinstance(v, dict):
        raise FirmwareError(f"{path}: {key} must be a table ([{key}])")
    return v


def _strings(v: Any, what: str, path: str) -> List[str]:
    if isinstance(v, str):
        return [v]
    if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
        raise FirmwareError(f"{path}: {what} must be a string or a list of strings")
    return list(v)


def _string(t: Mapping[str, Any], key: str, what: str, path: str, default: Any = None) -> Any:
    """t[key], which must be a string when given (else `default`)."""
    v = t.get(key, default)
    if v is not default and not isinstance(v, str):
        raise FirmwareError(f"{path}: {what}: a string, got {type(v).__name__} {v!r:.40}")
    return v


_KNOWN = {"firmware": {"sources", "headers", "include", "cflags", "defines", "language"},
          "filter": {"name", "params"}, "object": {"type", "name", "args", "init"},
          "update": {"call", "value_type"}, "state": None}
_C_FILES = (".c", *CXX_EXTENSIONS)
FUSION = FUSION_AHRS       # outside the float catalogue: their parameters are their settings


def _read(path: str) -> Dict[str, Any]:
    """The file's TOML: at most 1 MiB, UTF-8 (a byte-order mark allowed), nested at most as
    deep as Python's parser can go; FirmwareError naming the file otherwise."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read((1 << 20) + 1)
        if len(raw) > 1 << 20:
            raise FirmwareError(f"{path}: larger than 1 MiB; not a declaration")
        return toml.loads(raw.decode("utf-8-sig"))
    except OSError as e:
        raise FirmwareError(f"{path}: cannot read: {e.strerror or e}") from None
    except UnicodeDecodeError as e:
        raise FirmwareError(f"{path}: not UTF-8 (byte {e.start})") from None
    except RecursionError:
        raise FirmwareError(f"{path}: not a declaration: arrays or tables nested too "
                            "deeply") from None
    except toml.TOMLDecodeError as e:
        raise FirmwareError(f"{path}: not TOML: {e}") from None


def _sources(files: List[str], here: Any, path: str) -> List[str]:
    """The sources, each an existing C or C++ file, none twice."""
    out: Dict[str, str] = {}
    for f in files:
        full = here(f)
        if not f.strip():
            raise FirmwareError(f"{path}: [firmware] sources: an empty file name")
        if not os.path.exists(full):
            raise FirmwareError(f"{path}: [firmware] sources: {f!r}: source file not found "
                                f"({full})")
        if not os.path.isfile(full):
            raise FirmwareError(f"{path}: [firmware] sources: {f!r}: not a regular file ({full})")
        if not full.endswith(_C_FILES):
            raise FirmwareError(f"{path}: [firmware] sources: {f!r}: not a C or C++ source "
                                f"({', '.join(_C_FILES)}; headers go in headers)")
        real = os.path.realpath(full)
        if real in out:
            raise FirmwareError(f"{path}: [firmware] sources: {f}: the same file as "
                                f"{out[real]}; give it once")
        out[real] = f
    return [here(f) for f in files]


def _defines(v: Any, path: str) -> Dict[str, Optional[str]]:
    """[firmware] defines: NAME = true (defined) or a number or a string (its value)."""
    if not isinstance(v, dict):
        raise FirmwareError(f"{path}: [firmware] defines must be a table")
    out: Dict[str, Optional[str]] = {}
    for k, x in v.items():
        if not re.fullmatch(r"[A-Za-z_]\w*(\([\w\s,.]*\))?", k):
            raise FirmwareError(f"{path}: [firmware] defines: {k!r}: a macro name")
        if x is True:
            out[k] = None
        elif isinstance(x, (int, float, str)) and not isinstance(x, bool) \
                and "\n" not in str(x) and "\0" not in str(x):
            out[k] = str(x)
        else:
            raise FirmwareError(f"{path}: [firmware] defines: {k}: true, a number or a string "
                                f"(leave out a macro not defined), got {x!r:.40}")
    return out


def _params(name: str, params: Any, path: str) -> Dict[str, Any]:
    """[filter] params: a table of numbers, strings or booleans, no dt, names the filter
    has (the values are checked with dt, when the log's rate is known)."""
    if not isinstance(params, dict):
        raise FirmwareError(f"{path}: [filter] params must be a table")
    for k, v in params.items():
        if k == "dt":
            raise FirmwareError(f"{path}: [filter] params: dt: set by the sample rate, not here")
        if not isinstance(v, (bool, int, float, str)):
            raise FirmwareError(f"{path}: [filter] params: {k}: a number, a string or a "
                                f"boolean, got {type(v).__name__}")
    if name not in FUSION:
        valid = [p for p in param_names(name) if p != "dt"]
        e = entry(name)
        defaults = {k: v.default for k, v in
                    inspect.signature(e.reference._params).parameters.items()}
        defaults.update(e.defaults)
        for k, v in params.items():
            if k not in valid:
                raise FirmwareError(f"{path}: [filter] params: {k}: {name} has no parameter of "
                                    f"that name (it has {', '.join(valid)})")
            d = defaults.get(k)
            if isinstance(d, (int, float)) and not isinstance(d, bool) and \
                    isinstance(v, (str, bool)):
                raise FirmwareError(f"{path}: [filter] params: {k}: a number like its default "
                                    f"{d!r}, got {v!r:.40}")
    return dict(params)


def _init_names(name: str, params: Dict[str, Any]) -> Optional[List[str]]:
    """The names init's placeholders may take: the filter's parameters and C init values
    (None when they cannot be known before the log's rate)."""
    if name in FUSION:
        return None
    try:
        full = resolve_params(name, 0.01, params)
        values = _c_values(_filter_entry(name), full)
    except Exception:  # noqa: BLE001 - checked with the real dt later, with its message
        return None
    return [*full, *(values if isinstance(values, dict) else ())]


def load_declaration(path: "str | os.PathLike[str]", source_dir: Optional[str] = None,
                     cache_dir: Optional[str] = None) -> Declared:
    """Read a declaration file (TOML, see the module's doc). Relative paths are relative to
    ``source_dir`` (default: the file's directory). FirmwareError naming the file and the
    key for anything it cannot use."""
    path = os.fspath(path)
    if toml is None:
        raise FirmwareError(f"{path}: reading a declaration needs Python 3.11 or "
                            "`pip install tomli`")
    if source_dir is not None and not os.path.isdir(source_dir):
        raise FirmwareError(f"source directory (--source-dir) {source_dir}: "
                            f"{'not a directory' if os.path.exists(source_dir) else 'not found'}")
    data = _read(path)
    for key in data:
        if key not in _KNOWN:
            raise FirmwareError(f"{path}: unknown table [{key}] (known: {', '.join(_KNOWN)})")
    for key, allowed in _KNOWN.items():
        t = data.get(key)
        if isinstance(t, dict) and allowed is not None:
            bad = sorted(set(t) - allowed)
            if bad:
                raise FirmwareError(f"{path}: [{key}] {bad[0]}: unknown key (known: "
                                    f"{', '.join(sorted(allowed))})")
    base = source_dir or os.path.dirname(os.path.abspath(path))

    def here(p: str) -> str:
        return p if os.path.isabs(p) else os.path.join(base, p)
    fwt = _table(data, "firmware", path)
    flt = _table(data, "filter", path)
    obj = _table(data, "object", path, required=False)
    upd = _table(data, "update", path)
    state = _table(data, "state", path)
    name = flt.get("name")
    if not isinstance(name, str):
        raise FirmwareError(f"{path}: [filter] name: the imufuse filter to compare with")
    try:
        known = _filter_entry(name)
    except Exception as e:  # noqa: BLE001 - the catalogue's message names the filter
        raise FirmwareError(f"{path}: [filter] name: {e}") from None
    params = _params(name, flt.get("params", {}), path)
    if "call" not in upd or not isinstance(upd["call"], str):
        raise FirmwareError(f"{path}: [update] call: the update statement (a string)")
    for k, v in state.items():
        if not isinstance(v, str):
            raise FirmwareError(f"{path}: [state] {k}: an expression (a string)")
    sources = _sources(_strings(fwt.get("sources", []), "[firmware] sources", path), here, path)
    if not sources:
        raise FirmwareError(f"{path}: [firmware] sources: give the firmware's sources")
    includes = [here(d) for d in _strings(fwt.get("include", ["."]), "[firmware] include", path)]
    for d in includes:
        if not os.path.isdir(d):
            raise FirmwareError(f"{path}: [firmware] include: {d}: no such directory")
    kw = dict(object_type=_string(obj, "type", "[object] type", path),
              object_name=_string(obj, "name", "[object] name", path, "fw"),
              object_args=_string(obj, "args", "[object] args", path),
              init=_strings(obj.get("init", []), "[object] init", path),
              headers=_strings(fwt.get("headers", []), "[firmware] headers", path),
              include_dirs=includes, defines=_defines(fwt.get("defines", {}), path),
              cflags=(_strings(fwt["cflags"], "[firmware] cflags", path) if "cflags" in fwt
                      else None),
              language=_string(fwt, "language", "[firmware] language", path),
              value_type=_string(upd, "value_type", "[update] value_type", path, "float"))
    try:
        fw = DeclaredFirmware(sources, update=upd["call"], state=state, cache_dir=cache_dir,
                              **kw)
        unknown = [k for k in fw.state if k not in known.state_names]
        if unknown:
            raise FirmwareError(f"[state] {unknown[0]}: {name} has no state variable of that "
                                f"name (it has {', '.join(known.state_names)})")
        names = _init_names(name, params)
        fw.check(known.kind, names if names is not None else [p for _, p in fw.placeholders()])
    except FirmwareError as e:
        raise FirmwareError(f"{path}: {e}") from None
    return Declared(fw, name, params, path)
