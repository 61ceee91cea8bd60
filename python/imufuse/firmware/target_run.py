"""A built firmware program run on its emulator, sample by sample, logs of any length.

Before each run the host writes the next chunk of samples (and, from the second chunk on, the
image of the firmware's RAM as the previous chunk left it) into the linked image. A chunk that
resumes copies the image over .data and .bss instead of calling the firmware's init, so static
variables of the firmware carry across chunks as they would in one run.

The states come back as one binary record per sample (imf_fw_main.c: escaped for the
emulators' text channels, with the sample's index), decoded with numpy. Reported with the
states: per-update counts (cycles on AVR, instructions on ARM), the stack the update reached
(painted band). A fault, exit(), a reset, a stack overflow or a timeout is a TargetError
naming the sample: the first whose record did not arrive whole.
"""
from __future__ import annotations

import dataclasses
import struct
import subprocess
import time
from typing import List, Optional, Sequence, Tuple

import numpy as np

from ..shared.bits import words_as_values
from ..mcu import toolchains as _tc
from ..mcu.emulators import _emulator_cmd, _simavr_text, _to_counts
from .elf import _Elf
from .target_build import _IN_KIND, _MAGIC, Program, StateType
from .targets import TargetError, harness_target

__all__ = ["TargetRun", "run_program"]

@dataclasses.dataclass
class TargetRun:
    """The firmware's states after every sample and what it cost."""
    program: Program
    states: List[np.ndarray]        # per state word: (N,) values in the firmware's type
    counts: np.ndarray              # (N,) cycles (AVR) or instructions (ARM) per update
    count_unit: str
    stack: Optional[int]            # deepest stack an update reached, bytes
    stack_band: int                 # bytes painted below the stack pointer
    chunks: int
    emulator_seconds: float
    parse_seconds: float


def _patch(prog: Program, elf: _Elf, n: int, resume: bool, image: bytes, rows: np.ndarray,
           near: int = 0) -> None:
    kind = _IN_KIND[prog.in_dtype]
    with open(prog.elf, "r+b") as fh:
        fh.seek(elf.offset("imf_fw_hdr"))
        fh.write(struct.pack("<7I", _MAGIC, n, int(resume), len(image), kind, prog.row, near))
        fh.seek(elf.offset("imf_fw_in"))
        fh.write(np.ascontiguousarray(rows, dtype=prog.in_dtype.newbyteorder("<")).tobytes())
        if image:
            fh.seek(elf.offset("imf_fw_ram"))
            fh.write(image)


#: the near band (imf_fw_main.c) of a chunk: bytes below the stack pointer painted and read
#: around every step, at least this many, and twice the deepest stack seen plus _NEAR_MARGIN;
#: the rest of the band is painted once per chunk and checked at its end
_NEAR_MIN = {"avr": 256}
_NEAR_MIN_DEFAULT = 1024
_NEAR_MARGIN = 64


@dataclasses.dataclass
class _Chunk:
    """What one emulator run of a chunk printed."""
    text: str
    code: Optional[int]
    timed_out: bool
    types: Optional[List[int]] = None
    overhead: Optional[int] = None
    stack: Optional[int] = None         # M: the chunk's stack bytes, band, deep flag
    band: int = 0
    deep: bool = False
    image: Optional[bytes] = None
    ended: bool = False
    fault: Optional[str] = None
    words: Optional[np.ndarray] = None
    counts: Optional[np.ndarray] = None
    got: int = 0


def _read_chunk(out: bytes, code: Optional[int], timed_out: bool, avr: bool, widths: Sequence[int],
                first: bool) -> _Chunk:
    text = out.decode("latin-1")
    if avr:
        text = _simavr_text(text)
    c = _Chunk(text, code, timed_out)
    recs: List[bytes] = []
    for raw in text.encode("latin-1").split(b"\n"):
        if raw[:1] == b"S" and c.overhead is not None and not c.ended:
            recs.append(raw)        # a sample's record (binary: not stripped)
            continue
        line = raw.decode("latin-1").strip()
        if line.startswith("T"):
            t = [int(w, 16) for w in line[1:].split()]
            if (c.types is not None or not first) and c.overhead is not None:
                c.fault = "reset"       # the program started again: a jump to the reset vector
                break
            c.types = t
        elif line.startswith("K "):
            c.overhead = int(line[2:], 16)
        elif line.startswith("M "):
            m = [int(w, 16) for w in line[2:].split()]
            c.stack, c.band, c.deep = m[0], m[1], len(m) > 3 and m[3] != 0
        elif line.startswith("R "):
            c.image = bytes.fromhex(line[2:])
        elif line == "IMF_END":
            c.ended = True
        elif "IMF_FAULT" in line:
            c.fault = "fault"
        elif "IMF_RESET" in line:
            c.fault = "reset"
        elif "IMF_STACK_OVERFLOW" in line:
            c.fault = "stack"
        elif line.startswith("IMF_EXIT"):
            c.fault = "exit " + str(int(np.uint32(int(line.split()[-1], 16)).view(np.int32)))
    if recs:
        c.words, c.counts, c.got = _records(b"".join(recs), widths)
    return c


def run_program(prog: Program, inputs: np.ndarray, timeout: float) -> TargetRun:
    """Run (N, row) inputs through the program chunk by chunk. TargetError on a fault, an
    exit, a reset, a stack overflow or a timeout, naming the sample. A chunk runs with a near
    band (imf_fw_main.c) sized from the stack seen so far, and again with the whole band
    painted before every step when it reports that something reached below the near band, or
    when it stops on a fault (the figure and the states are those of the whole band's run)."""
    name = harness_target(prog.target)
    tgt = _tc.TARGETS[name]
    _tc._require(tgt, [tgt.emulator or "emulator"])
    elf = _Elf.read(prog.elf)
    inputs = np.asarray(inputs, dtype=prog.in_dtype).reshape(len(inputs), prog.row)
    n_total = inputs.shape[0]
    words: List[np.ndarray] = []       # per chunk: (n, state words) bit patterns
    raw_counts: List[np.ndarray] = []
    widths = [8 if t.size > 4 else 4 for t in prog.types]
    near_min = _NEAR_MIN.get(name, _NEAR_MIN_DEFAULT)
    near = near_min
    stack = 0
    band = 0
    image = b""
    t_emu = t_parse = 0.0
    chunks = 0
    types_seen: Optional[List[int]] = None
    first_overhead = 0
    start = 0
    while start < n_total or (n_total == 0 and chunks == 0):
        n = min(prog.chunk, n_total - start)
        while True:
            _patch(prog, elf, n, bool(image), image, inputs[start:start + n], near)
            cmd = _emulator_cmd(tgt, prog.elf, True)
            t0 = time.perf_counter()
            timed_out = False
            try:
                proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                      stdin=subprocess.DEVNULL, timeout=timeout)
                out, code = proc.stdout, proc.returncode
            except subprocess.TimeoutExpired as e:
                out, code, timed_out = (e.stdout or b""), None, True
            t_emu += time.perf_counter() - t0
            t1 = time.perf_counter()
            c = _read_chunk(out, code, timed_out, name == "avr", widths, types_seen is None)
            t_parse += time.perf_counter() - t1
            again = c.deep or (c.fault is not None or "Lockup" in c.text)
            if near and again and not timed_out:
                near = 0            # the whole band before every step, from here on
                continue
            break
        text, got = c.text, c.got
        if c.types is not None and types_seen is None:
            types_seen = c.types
        overhead = c.overhead
        if c.words is not None and c.counts is not None:
            words.append(c.words)
            raw_counts.append(c.counts)
        k = start + got
        if chunks == 0:
            first_overhead = overhead or 0
        fault = c.fault
        msg = None
        if fault == "fault":
            msg = f"the firmware crashed with a hard fault at sample {k} on the {prog.target}"
        elif fault == "stack":
            msg = (f"stack overflow at sample {k} on the {prog.target}: the update's stack reached "
                   "the static data (a large local array or deep recursion?)")
        elif fault == "reset":
            msg = (f"the {prog.target} restarted at sample {k} (a jump to address 0: a NULL "
                   "function pointer, or a corrupted return address)")
        elif fault and fault.startswith("exit"):
            msg = f"the firmware called exit({fault.split()[1]}) at sample {k} on the {prog.target}"
        elif "Lockup" in text:
            msg = (f"the {prog.target} locked up at sample {k} (a fault while entering the fault "
                   "handler: the stack pointer left RAM, a stack overflow)")
        elif timed_out:
            msg = (f"the firmware gave no answer within {timeout:g} s at sample {k} on the "
                   f"{prog.target} (an endless loop?)")
        elif not c.ended or got != n or overhead is None:
            where = "during init" if (overhead is None or types_seen is None) and start == 0 \
                else f"at sample {k}"
            tail = " ".join(text.strip().splitlines()[-2:])[-200:]
            msg = (f"the firmware stopped {where} on the {prog.target} (exit status {c.code}; a "
                   f"fault, exit() or a stop: {tail!r})")
        if msg:
            raise TargetError(msg + _stack_hint(prog), k)
        if c.stack is not None:
            if c.stack < c.band:
                stack = max(stack, c.stack)
            else:
                stack = -1
            band = c.band
        if c.image is not None:
            image = c.image
        if near:
            near = 0 if stack < 0 else max(near_min, -(-(2 * stack + _NEAR_MARGIN) // 16) * 16)
        chunks += 1
        start += n
        if n_total == 0:
            break
    ns = len(prog.types)
    if types_seen is not None and len(types_seen) != ns:
        raise TargetError("the state types printed do not match the program")
    t1 = time.perf_counter()
    states = _decode(words, prog.types)
    counted = np.concatenate(raw_counts) if raw_counts else np.zeros(0, np.int64)
    t_parse += time.perf_counter() - t1
    counts = _to_counts(tgt, counted, first_overhead if counted.size else 0)
    return TargetRun(prog, states, counts, tgt.count_unit, None if stack < 0 else stack, band,
                     chunks, t_emu, t_parse)


def _stack_hint(prog: Program) -> str:
    """The firmware's largest stack frame (-fstack-usage) when it exceeds the free RAM."""
    tgt = _tc.TARGETS[harness_target(prog.target)]
    free = tgt.ram - prog.ram_image
    worst = (0, "")
    for obj in prog.user_objects:
        su = obj.with_suffix(".su")
        if not su.is_file():
            continue
        for line in su.read_text(errors="replace").splitlines():
            parts = line.split("\t")
            if len(parts) >= 2 and parts[1].isdigit() and int(parts[1]) > worst[0]:
                worst = (int(parts[1]), parts[0].rsplit(":", 1)[-1])
    if worst[0] > free:
        return (f"; {worst[1]} needs {worst[0]} B of stack (-fstack-usage) and the "
                f"{prog.target} has {free} B of RAM left for the stack: a stack overflow")
    return ""


#: the escape byte of the binary records (imf_fw_main.c's imf_fw_put): '~' and the byte + 0x40
_ESC = 0x7E
_REC = ord("S")


def _records(body: bytes, widths: Sequence[int]) -> Tuple[np.ndarray, np.ndarray, int]:
    """One chunk's records, their lines joined (imf_fw_main.c): (n, words) uint64 bit
    patterns, (n,) raw counts and n, the samples that completed. A record counts only when it is
    whole, starts with 'S' and carries its sample's index (mod 256) in its last byte: a
    dropped or extra byte ends the run of records there, and whatever follows the last good
    record (an emulator's message after a lockup) is not a sample."""
    a = np.frombuffer(body, dtype=np.uint8)
    esc = np.flatnonzero(a == _ESC)
    esc = esc[esc + 1 < a.size]
    if esc.size:
        a = a.copy()
        a[esc + 1] -= 0x40
        keep = np.ones(a.size, dtype=bool)
        keep[esc] = False
        a = a[keep]
    size = 1 + sum(widths) + 4 + 1
    n = a.size // size
    r = a[:n * size].reshape(n, size)
    ok = (r[:, 0] == _REC) & (r[:, -1] == (np.arange(n) & 0xFF))
    if not ok.all():
        n = int(np.argmin(ok))
        r = r[:n]
    words = np.zeros((n, len(widths)), dtype=np.uint64)
    off = 1
    for j, w in enumerate(widths):
        cell = np.ascontiguousarray(r[:, off:off + w])
        words[:, j] = cell.view("<u8" if w == 8 else "<u4").reshape(n)
        off += w
    counts = np.ascontiguousarray(r[:, off:off + 4]).view("<u4").reshape(n).astype(np.int64)
    return words, counts, n


def _decode(words: List[np.ndarray], types: Sequence[StateType]) -> List[np.ndarray]:
    w = np.concatenate(words) if words else np.zeros((0, len(types)), dtype=np.uint64)
    if w.shape[1] != len(types):
        raise TargetError("samples differ in the number of state words")
    return [words_as_values(w[:, j], t.size, t.integer, t.signed) for j, t in enumerate(types)]
