"""The declaration file of a firmware's API (TOML): ``load_declaration`` reads it into a
``DeclaredFirmware`` (imufuse.firmware.declared, where the format is described), the imufuse
filter to compare with and its parameters; every mistake is one FirmwareError naming the file
and the key."""
from __future__ import annotations

import os
from typing import Any, Dict, List, Mapping, Optional

from .declaration import FirmwareError
from .declared import DeclaredFirmware
from .validate import _filter_entry

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


_KNOWN = {"firmware": {"sources", "headers", "include", "cflags", "defines", "language"},
          "filter": {"name", "params"}, "object": {"type", "name", "args", "init"},
          "update": {"call", "value_type"}, "state": None}


def load_declaration(path: "str | os.PathLike[str]", source_dir: Optional[str] = None,
                     cache_dir: Optional[str] = None) -> Declared:
    """Read a declaration file (TOML, see the module's doc). Relative paths are relative to
    ``source_dir`` (default: the file's directory). FirmwareError naming the file and the
    key for anything it cannot use."""
    path = os.fspath(path)
    try:
        import tomllib as toml
    except ImportError:                       # Python < 3.11
        try:
            import tomli as toml
        except ImportError:
            raise FirmwareError(f"{path}: reading a declaration needs Python 3.11 or "
                                "`pip install tomli`") from None
    try:
        with open(path, "rb") as fh:
            raw = fh.read(1 << 20 + 1)
        if len(raw) > 1 << 20:
            raise FirmwareError(f"{path}: larger than 1 MiB; not a declaration")
        data = toml.loads(raw.decode("utf-8"))
    except OSError as e:
        raise FirmwareError(f"{path}: cannot read: {e.strerror or e}") from None
    except UnicodeDecodeError as e:
        raise FirmwareError(f"{path}: not UTF-8 (byte {e.start})") from None
    except toml.TOMLDecodeError as e:
        raise FirmwareError(f"{path}: not TOML: {e}") from None
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
    params = flt.get("params", {})
    if not isinstance(params, dict):
        raise FirmwareError(f"{path}: [filter] params must be a table")
    if "call" not in upd or not isinstance(upd["call"], str):
        raise FirmwareError(f"{path}: [update] call: the update statement (a string)")
    for k, v in state.items():
        if not isinstance(v, str):
            raise FirmwareError(f"{path}: [state] {k}: an expression (a string)")
    defines = fwt.get("defines", {})
    if not isinstance(defines, dict):
        raise FirmwareError(f"{path}: [firmware] defines must be a table")
    fw = DeclaredFirmware(
        [here(s) for s in _strings(fwt.get("sources", []), "[firmware] sources", path)],
        update=upd["call"], state=state, object_type=obj.get("type"),
        object_name=obj.get("name", "fw"), object_args=obj.get("args"),
        init=_strings(obj.get("init", []), "[object] init", path),
        headers=_strings(fwt.get("headers", []), "[firmware] headers", path),
        include_dirs=[here(d) for d in _strings(fwt.get("include", ["."]),
                                                "[firmware] include", path)],
        defines={k: (None if v is True else str(v)) for k, v in defines.items()},
        cflags=(_strings(fwt["cflags"], "[firmware] cflags", path) if "cflags" in fwt
                else None),
        language=fwt.get("language"), cache_dir=cache_dir,
        value_type=str(upd.get("value_type", "float")))
    if not fw.sources:
        raise FirmwareError(f"{path}: [firmware] sources: give the firmware's sources")
    unknown = [k for k in fw.state if k not in known.state_names]
    if unknown:
        raise FirmwareError(f"{path}: [state] {unknown[0]}: {name} has no state variable of "
                            f"that name (it has {', '.join(known.state_names)})")
    return Declared(fw, name, dict(params), path)
