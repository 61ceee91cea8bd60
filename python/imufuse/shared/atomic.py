"""Outputs written whole or not at all: a file is written beside its destination under a
temporary name and renamed over it only once complete, so a write that fails (a full disk, a
file-size limit, an error half way) leaves the previous file as it was and no truncated one.
A destination that is a symbolic link is replaced at the file it points to; one that is not a
regular file (a device, a pipe) is written in place, never replaced.

A read-merge-write (a calibration file that `imufuse calibrate` merges a section into) holds
`locked(path)` around the whole of it, so that two processes writing different sections of
one file both keep theirs."""
from __future__ import annotations

import contextlib
import os
import stat
import sys
import tempfile
from typing import Iterator

if sys.platform == "win32":
    import msvcrt
else:
    import fcntl

__all__ = ["replacing", "locked"]


def _mode_for(path: str) -> int:
    try:
        return os.stat(path).st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


@contextlib.contextmanager
def replacing(path: "str | os.PathLike[str]") -> Iterator[str]:
    """Yield a temporary path beside `path`; on success rename it over `path` (keeping an
    existing file's permissions), on any error remove it and leave `path` untouched."""
    dest = os.path.realpath(os.fspath(path))
    try:
        st = os.stat(dest)
    except OSError:
        st = None
    if st is not None and not stat.S_ISREG(st.st_mode):
        # a device, a pipe, a terminal: written in place, never replaced (/dev/full stays a
        # device; its write fails as a write there should)
        yield dest
        return
    d, base = os.path.split(dest)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{base}.", suffix=".part", dir=d or ".")
    except OSError:
        # a directory where no new file can be made: the existing file is written in place
        yield dest
        return
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, _mode_for(dest))
        os.replace(tmp, dest)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _lock(fd: int) -> None:
    if sys.platform == "win32":
        while True:
            try:
                msvcrt.locking(fd, msvcrt.LK_LOCK, 1)   # gives up after 10 s: wait again
                return
            except OSError:
                continue
    else:
        fcntl.flock(fd, fcntl.LOCK_EX)


def _unlock(fd: int) -> None:
    if sys.platform == "win32":
        os.lseek(fd, 0, os.SEEK_SET)
        msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)


@contextlib.contextmanager
def locked(path: "str | os.PathLike[str]") -> Iterator[None]:
    """Hold an exclusive lock for a read-merge-write of `path` (waiting for another holder):
    on the file `.<name>.lock` beside it, created if needed and left there (the data file
    itself is replaced by `replacing`'s rename, so a lock on it would guard nothing).
    fcntl.flock on POSIX, msvcrt.locking on Windows. A destination that is not a regular
    file, a directory where the lock file cannot be made (`replacing` then writes in place)
    or a file system without locks is written unlocked."""
    dest = os.path.realpath(os.fspath(path))
    fd = -1
    if os.path.isfile(dest) or not os.path.exists(dest):
        d, base = os.path.split(dest)
        with contextlib.suppress(OSError):
            fd = os.open(os.path.join(d, f".{base}.lock"), os.O_RDWR | os.O_CREAT, 0o666)
    if fd >= 0:
        try:
            _lock(fd)
        except OSError:
            # a file system without locks (ENOLCK): written as before, unlocked
            os.close(fd)
            fd = -1
    try:
        yield
    finally:
        if fd >= 0:
            with contextlib.suppress(OSError):
                _unlock(fd)
            os.close(fd)


class OutputConflict(ValueError):
    """An output that is one of the command's inputs, or another of its outputs."""


class OutputUnwritable(OSError):
    """An output that cannot be created (a directory, a missing directory)."""


def _same(a: str, b: str) -> bool:
    try:
        if os.path.samefile(a, b):
            return True
    except OSError:
        pass
    return os.path.abspath(a) == os.path.abspath(b) or \
        os.path.realpath(a) == os.path.realpath(b)


def check_outputs(inputs, outputs) -> None:
    """Before any work: refuse an output that is an input of the command (the log, a
    calibration file, a column map, a firmware source; also through a link) or that another
    output also names, and one that cannot be created. inputs: paths (None ignored);
    outputs: (option, path) pairs (None and "-" ignored)."""
    seen: list = []
    for opt, out in outputs:
        if out in (None, "-"):
            continue
        for inp in inputs:
            if inp is not None and _same(out, inp):
                raise OutputConflict(f"{opt} {out}: is the input {inp}; refusing to overwrite it")
        for opt2, out2 in seen:
            if _same(out, out2):
                raise OutputConflict(f"{opt} {out}: is also the {opt2} output; give two files")
        if os.fspath(out) == "":
            raise OutputUnwritable(f"{opt}: an empty file name; give a file name")
        if os.path.isdir(out):
            raise OutputUnwritable(f"{opt} {out}: is a directory; give a file name")
        if os.fspath(out).endswith(("/", os.sep)):
            # the file would be written as the name without the slash
            raise OutputUnwritable(f"{opt} {out}: names a directory (the final '/'), which "
                                   "does not exist; give a file name")
        d = os.path.dirname(os.path.abspath(out))
        if not os.path.isdir(d):
            raise OutputUnwritable(f"{opt} {out}: directory {d} does not exist")
        seen.append((opt, out))
