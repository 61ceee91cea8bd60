"""The bound of the firmware cache (the firmware's cache_dir, else $IMUFUSE_CACHE, else
~/.cache/imufuse/firmware): the host builds (``_imufuse_fw_<key>/``, imufuse.firmware.host) and
the programs of `validate --target` (``targets/<key>/``, imufuse.firmware.target_cache)
together take at most $IMUFUSE_CACHE_MAX_MB (default CACHE_MAX_MB). After a build is stored
the least recently used entries go first (an entry's directory time: set when stored and by
every hit). A host build is loaded from the cache by its path, possibly by another process a
moment after its look-up, so one used in the last IN_USE seconds stays even beyond the bound;
a program is copied out on a hit, so it has no such grace. The pieces of a build killed before
it renamed its entry into place (``*.part-*``) go once PART_AGE old."""
from __future__ import annotations

import os
import shutil
import time
from pathlib import Path
from typing import List, Optional, Tuple

from .declaration import FirmwareError

#: the cache's size bound in MB (a program takes 50 KB to 1 MB, a host build about 0.25 MB),
#: $IMUFUSE_CACHE_MAX_MB
CACHE_MAX_MB = 256.0
#: a build's piece (``*.part-*``) older than this (s) was left by a killed process
PART_AGE = 3600.0
#: a host build used this recently (s) stays: a process may be about to load it
IN_USE = 600.0
#: the host builds' prefix (imufuse.firmware.host) and the programs' directory
HOST_PREFIX = "_imufuse_fw_"
TARGETS = "targets"


def cache_limit() -> int:
    """The cache's bound in bytes: $IMUFUSE_CACHE_MAX_MB (MB, >= 0), else CACHE_MAX_MB."""
    text = os.environ.get("IMUFUSE_CACHE_MAX_MB", "").strip()
    if not text:
        return int(CACHE_MAX_MB * 1e6)
    try:
        mb = float(text)
    except ValueError:
        mb = -1.0
    if not mb >= 0.0 or mb == float("inf"):
        raise FirmwareError(f"IMUFUSE_CACHE_MAX_MB={text!r}: expected the firmware cache's size "
                            "in MB, a number >= 0 (0 keeps the build just stored only)")
    return int(mb * 1e6)


def _size(path: str) -> int:
    """Bytes of the files under path (a host build keeps cffi's objects in a subdirectory)."""
    total = 0
    for d, _, files in os.walk(path):
        for f in files:
            try:
                total += os.lstat(os.path.join(d, f)).st_size
            except OSError:
                pass
    return total


def touch(entry: Path) -> None:
    """A hit: the entry is used now, the last to go; its files stay untouched."""
    try:
        os.utime(entry)
    except OSError:
        pass


def prune(cache_dir: Path, keep: Optional[Path] = None) -> None:
    """Remove the least recently used host builds and programs of ``cache_dir`` until they take
    at most cache_limit(), never ``keep`` (the entry just stored) nor a host build used in the
    last IN_USE s; and the pieces of killed builds. A concurrent look-up of a removed entry is
    a miss, so it builds again."""
    limit = cache_limit()
    now = time.time()
    entries: List[Tuple[float, str, int]] = []
    total = 0
    for root, host in ((cache_dir, True), (cache_dir / TARGETS, False)):
        try:
            dirs = list(os.scandir(root))
        except OSError:
            continue
        for d in dirs:
            try:
                if not d.is_dir(follow_symlinks=False) or (host and
                                                           not d.name.startswith(HOST_PREFIX)):
                    continue
                used = d.stat(follow_symlinks=False).st_mtime
                if ".part-" in d.name:
                    if now - used > PART_AGE:
                        shutil.rmtree(d.path, ignore_errors=True)
                    continue
                size = _size(d.path)
            except OSError:
                continue
            total += size
            if keep is not None and os.path.abspath(d.path) == os.path.abspath(keep):
                continue
            if host and now - used < IN_USE:
                continue
            entries.append((used, d.path, size))
    for _, path, size in sorted(entries):
        if total <= limit:
            break
        shutil.rmtree(path, ignore_errors=True)
        total -= size
