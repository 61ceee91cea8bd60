"""The program cache of `imufuse validate --target` (imufuse.firmware.target_build).

Programs are kept in targets/ beside the host builds (the firmware's cache_dir, else
$IMUFUSE_CACHE, else ~/.cache/imufuse/firmware), one directory per key (``_program_key``: the
settings, the compile commands, the generated texts, the build's own code and the contents of
every file the cross compiler's -M names). An entry holds the image, the firmware's objects
(with their -fstack-usage files) and what ``Program`` says (program.json, with each file's size
and sha256 and the libraries the link loaded, with their size and time stamp). Entries are
renamed into place whole; a damaged one is removed and rebuilt; one whose libraries changed is
rebuilt; an unwritable cache only costs the build. The cache is bounded (``_prune``,
imufuse.firmware.cache_bound): after a store, the least recently used entries, host builds and
programs together (a hit sets its directory's time), are removed until they take at most
$IMUFUSE_CACHE_MAX_MB (default CACHE_MAX_MB), and pieces a killed build left (``*.part-*`` an
hour old) go too.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, List, Optional, Sequence, Tuple

from .. import __version__
from ..mcu import toolchains as _tc
from . import cache_bound as _bound
from .cache_bound import CACHE_MAX_MB, cache_limit  # noqa: F401 - the bound, named here too
from .host import dependency_files


#: the program cache's layout (an entry of another layout is not read)
_CACHE_FORMAT = 1
_CACHE_META = "program.json"
_OWN_DIGEST: List[str] = []


def _program_cache(fw: Any) -> Path:
    """Where built programs are kept: beside the host builds (the firmware's cache_dir,
    else $IMUFUSE_CACHE, else ~/.cache/imufuse/firmware), in targets/."""
    root = getattr(fw, "cache_dir", None) or os.environ.get("IMUFUSE_CACHE") or os.path.join(
        os.path.expanduser("~"), ".cache", "imufuse", "firmware")
    return Path(root) / "targets"


def _own_digest() -> str:
    """imufuse's version and the build's own code (this module, the ELF and map reader, the
    toolchain records with the linker scripts' templates): a changed harness never reuses a
    program. Read once per process."""
    if not _OWN_DIGEST:
        h = hashlib.sha256(__version__.encode())
        here = Path(__file__)
        for f in (here, here.with_name("target_build.py"), here.with_name("elf.py"),
                  Path(_tc.__file__)):
            h.update(f.read_bytes())
        for f in sorted(_tc.DATA_DIR.glob("*.ld.in")):
            h.update(f.read_bytes())
        _OWN_DIGEST.append(h.hexdigest())
    return _OWN_DIGEST[0]


def _dep_command(cmd: Sequence[str]) -> List[str]:
    """A compile command (``... -c SRC [-o OBJ]``) as dependency_files runs it: the flags
    less the output and dependency-file options, then SRC."""
    cmd = list(cmd)
    if len(cmd) >= 2 and cmd[-2] == "-o":
        cmd = cmd[:-2]
    return [*(f for f in cmd[:-2] if f != "-fstack-usage" and not f.startswith("-M")), cmd[-1]]


def _program_key(wd: Path, compiles: Sequence[Sequence[str]], settings: Any,
                 texts: Sequence[str]) -> Optional[str]:
    """The program's name in the cache: a hash of the settings (target, flags, defines,
    include directories, row, input type, the compilers' identities...), the compile
    commands, the generated texts (driver, adapter, linker script), the build's own code
    and the contents of every file the cross compiler reads for these compiles (their -M
    output, run side by side: sources, headers in any directory, included files of any
    extension, the harness's files, system headers). None when a source cannot be
    preprocessed: never cached (the compiler says why)."""
    deps = dependency_files([_dep_command(c) for c in compiles], cwd=str(wd))
    if deps is None:
        return None
    here = [str(wd.resolve()), str(wd)]

    def norm(x: str) -> str:
        for w in here:
            x = x.replace(w, "@WD")
        return x
    h = hashlib.sha256(json.dumps([_CACHE_FORMAT, _own_digest(), settings,
                                   [[norm(a) for a in c] for c in compiles]]).encode())
    for t in texts:
        h.update(hashlib.sha256(t.encode()).digest())
    for f in deps:
        h.update(norm(f).encode() + b"\0")
        try:
            h.update(hashlib.sha256(Path(f).read_bytes()).digest())
        except OSError:
            h.update(b"\0missing")
    return h.hexdigest()[:32]


def _link_inputs(map_text: str, wd: Path) -> List[List[Any]]:
    """The files the link loaded from outside the build (start files, libc, libm, libgcc:
    the map's LOAD lines) with their size and time stamp: a cached program is used only
    while they are unchanged (a C library upgraded beside the same compiler)."""
    out = []
    inside = str(wd.resolve())
    for line in map_text.splitlines():
        if line.startswith("LOAD "):
            p = os.path.realpath(os.path.join(str(wd), line[5:].strip()))
            if not p.startswith(inside + os.sep) and os.path.isfile(p):   # not "linker stubs"
                st = os.stat(p)
                out.append([p, st.st_size, st.st_mtime_ns])
    return out


def _read_entry(entry: Path) -> Optional[Tuple[dict, dict]]:
    """(meta, {file name: bytes}) of a complete, intact and current cache entry; None when
    there is none. A damaged entry (a file missing, short or changed, unreadable meta) is
    removed, so the build that follows replaces it; a stale one (a library the link loaded
    changed since) is left for that build to replace."""
    if not entry.is_dir():
        return None
    try:
        meta = json.loads((entry / _CACHE_META).read_text())
        if meta.get("format") != _CACHE_FORMAT:
            raise ValueError("another layout")
        blobs = {}
        for name, (size, digest) in meta["files"].items():
            data = (entry / name).read_bytes()
            if len(data) != size or hashlib.sha256(data).hexdigest() != digest:
                raise ValueError(f"{name} damaged")
            blobs[name] = data
        for path, size, mtime in meta["link_inputs"]:
            try:
                st = os.stat(path)
            except OSError:
                return None
            if (st.st_size, st.st_mtime_ns) != (size, mtime):
                return None
        _bound.touch(entry)     # used now: the last to go (_prune)
        return meta, blobs
    except (OSError, ValueError, KeyError, TypeError):
        shutil.rmtree(entry, ignore_errors=True)
        return None


def _store_entry(entry: Path, prog: Any, map_text: str) -> None:
    """Keep a built program: written in a directory of its own and renamed into place when
    complete (a second process storing the same key keeps the first complete entry); a
    cache that cannot be written is skipped (built again next time)."""
    tmp: Optional[Path] = None
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f"{entry.name}.part-", dir=entry.parent))
        files = {}
        # the objects' stack usage (-fstack-usage) too: a stack overflow names the frame
        sus = [o.with_suffix(".su") for o in prog.user_objects]
        for p in (prog.elf, *prog.user_objects, *(su for su in sus if su.is_file())):
            data = p.read_bytes()
            (tmp / p.name).write_bytes(data)
            files[p.name] = [len(data), hashlib.sha256(data).hexdigest()]
        meta = {"format": _CACHE_FORMAT, "files": files, "elf": prog.elf.name,
                "objects": [o.name for o in prog.user_objects],
                "types": [dataclasses.astuple(t) for t in prog.types], "chunk": prog.chunk,
                "ram_image": prog.ram_image, "in_dtype": prog.in_dtype.str, "flash": prog.flash,
                "ram": prog.ram, "library": list(prog.library),
                "library_flash": prog.library_flash,
                "link_inputs": _link_inputs(map_text, prog.workdir)}
        (tmp / _CACHE_META).write_text(json.dumps(meta))
        for _ in range(2):
            try:
                os.rename(tmp, entry)
                _prune(entry.parent, entry.name)
                return
            except OSError:
                if _read_entry(entry) is not None:
                    return              # another process stored the same program first
                shutil.rmtree(entry, ignore_errors=True)
    except OSError:
        pass
    finally:
        if tmp is not None and tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)


def _prune(root: Path, keep: str) -> None:
    """The bound after a program is stored in ``root`` (the cache's targets/) as ``keep``: the
    whole firmware cache, host builds and programs together (imufuse.firmware.cache_bound)."""
    _bound.prune(root.parent, root / keep)
