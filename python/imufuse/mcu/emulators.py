"""Running harness programs in the emulators and reading their output."""
from __future__ import annotations

import dataclasses
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from .programs import build
from .driver import Driver
from .toolchains import AVR_OVF_ISR_CYCLES, HarnessError, ICOUNT_SHIFT, Target, _require, _target

@dataclasses.dataclass
class Result:
    """What one emulated run returned.

    state:   (N, n_words) bit patterns after every sample: numpy.uint32, or uint64 when a
             word is 64-bit (f64).
    counts:  (N,) int64 per-step counts (cycles on avr, instructions on m4f/m0) with the
             measurement overhead removed; None unless run(count=True).
    raw_counts, overhead: the counter values as printed, and the empty-call calibration.
    elf:     the program; it survives the call only when run() was given a workdir.
    stack_bytes: deepest stack the step reached over all samples (stack painting), beyond an
             empty call, including library calls (soft float, sqrtf); None on host.
    """

    target: str
    state: np.ndarray
    names: Optional[List[str]]
    kinds: Optional[List[str]]
    counts: Optional[np.ndarray]
    raw_counts: np.ndarray
    overhead: int
    elf: Path
    stdout: str
    seconds: float
    stack_bytes: Optional[int] = None

    def values(self) -> List[np.ndarray]:
        """The state columns converted to their C types (needs a Driver with kinds)."""
        if self.kinds is None:
            raise ValueError("kinds unknown (raw C driver)")
        conv = {
            "f32": np.float32, "f64": np.float64, "u32": np.uint32, "i32": np.int32,
            "u16": np.uint32, "i16": np.int32, "u8": np.uint32, "i8": np.int32,
        }
        out = []
        for col, kind in enumerate(self.kinds):
            bits = self.state[:, col]
            if kind == "f64":
                out.append(bits.astype(np.uint64).view(np.float64))
            else:
                out.append(bits.astype(np.uint32).view(conv[kind]))
        return out


_LINE = re.compile(r"^S((?: [0-9a-f]{8}(?:[0-9a-f]{8})?)*) c([0-9a-f]{8})$")


def _parse(text: str, n_expected: int) -> Tuple[np.ndarray, np.ndarray, int, Optional[int], Optional[int]]:
    overhead = None
    stack = window = None
    rows: List[List[int]] = []
    widths: set = set()
    counts: List[int] = []
    ended = False
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("K "):
            overhead = int(line[2:], 16)
            continue
        if line.startswith("M "):
            stack, window = (int(t, 16) for t in line[2:].split())
            continue
        if line == "IMF_END":
            ended = True
            continue
        m = _LINE.match(line)
        if m:
            toks = m.group(1).split()
            widths.update(len(t) for t in toks)
            rows.append([int(t, 16) for t in toks])
            counts.append(int(m.group(2), 16))
    if not ended or len(rows) != n_expected or overhead is None:
        raise HarnessError(
            f"incomplete output: {len(rows)} of {n_expected} samples, end marker {ended}\n"
            + text[-2000:]
        )
    if len({len(r) for r in rows}) > 1:
        raise HarnessError("samples differ in the number of state words")
    dtype = np.uint64 if 16 in widths else np.uint32
    state = np.array(rows, dtype=dtype).reshape(len(rows), -1 if rows[0] else 0)
    return state, np.array(counts, dtype=np.int64), overhead, stack, window


def _emulator_cmd(tgt: Target, elf: Path, count: bool) -> List[str]:
    if tgt.name == "host":
        return [str(elf)]
    if tgt.emulator == "qemu-system-arm":
        cmd = [
            "qemu-system-arm", "-M", str(tgt.machine), "-nographic", "-monitor", "none",
            "-serial", "null", "-semihosting-config", "enable=on,target=native",
            "-kernel", str(elf),
        ]
        if count:
            cmd += ["-icount", f"shift={ICOUNT_SHIFT},align=off,sleep=off"]
        return cmd
    if tgt.emulator == "qemu-system-riscv32":
        cmd = [
            "qemu-system-riscv32", "-M", str(tgt.machine), "-bios", "none", "-nographic",
            "-monitor", "none", "-serial", "null", "-semihosting-config",
            "enable=on,target=native", "-kernel", str(elf),
        ]
        if count:
            cmd += ["-icount", f"shift={ICOUNT_SHIFT},align=off,sleep=off"]
        return cmd
    if tgt.emulator == "simavr":
        return ["simavr", "-m", "atmega328p", "-f", "16000000", str(elf)]
    raise AssertionError(tgt.emulator)


def _simavr_text(out: str) -> str:
    # simavr prints UART0 output in chunks wrapped in ANSI colour codes, one chunk per line
    # ending in "." where the newline was; a chunk without the "." is a piece of a longer line
    # (simavr's buffer holds 256 characters) and continues in the next chunk. Text outside the
    # colour codes is simavr's own messages, kept as separate lines.
    parts = re.split(r"(\x1b\[32m.*?\n\x1b\[0m)", out, flags=re.S)
    text: List[str] = []
    for part in parts:
        m = re.match(r"\x1b\[32m(.*?)\n\x1b\[0m$", part, flags=re.S)
        if m:
            chunk = m.group(1)
            text.append(chunk[:-1] + "\n" if chunk.endswith(".") else chunk)
        else:
            plain = re.sub(r"\x1b\[[0-9;]*m", "", part)
            if plain.strip():
                text.append("\n" + plain.strip("\n") + "\n")
    return "".join(text)


def _to_counts(tgt: Target, raw: np.ndarray, overhead: int) -> np.ndarray:
    if tgt.name == "avr":
        def fix(c):
            c = np.asarray(c, dtype=np.int64)
            return c - (c >> 16) * AVR_OVF_ISR_CYCLES
        return fix(raw) - int(fix(overhead))
    if tgt.count_method == "csr":
        # mcycle under -icount reads qemu's virtual clock: 2**shift ns per instruction
        ins = np.asarray(raw, dtype=np.int64) >> ICOUNT_SHIFT
        return ins - (int(overhead) >> ICOUNT_SHIFT)
    if tgt.machine is not None:
        ticks_per_insn = (2 ** ICOUNT_SHIFT) * 1e-9 * tgt.systick_hz
        ins = np.rint(raw / ticks_per_insn).astype(np.int64)
        return ins - int(np.rint(overhead / ticks_per_insn))
    return raw.copy()


def run_elf(
    target: str,
    elf: Union[str, os.PathLike],
    n: int,
    count: bool = False,
    timeout: float = 120.0,
    driver: Union[Driver, str, None] = None,
) -> Result:
    """Run a program made by ``build`` and parse its output (n: number of samples)."""
    import time

    tgt = _target(target)
    if tgt.emulator:
        _require(tgt, [tgt.emulator])
    elf = Path(elf)
    cmd = _emulator_cmd(tgt, elf, count)
    t0 = time.perf_counter()
    try:
        # qemu writes semihosting output to stderr, simavr its UART lines too: read both.
        proc = subprocess.run(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
            text=True, timeout=timeout, errors="replace",
        )
    except subprocess.TimeoutExpired as e:
        got = e.stdout or b""
        out = got.decode(errors="replace") if isinstance(got, bytes) else got
        raise HarnessError(f"{target}: timeout after {timeout} s: {' '.join(cmd)}\n{out[-2000:]}") from None
    seconds = time.perf_counter() - t0
    text = proc.stdout
    if tgt.emulator == "simavr":
        text = _simavr_text(text)
    if proc.returncode != 0 or "IMF_FAULT" in text:
        raise HarnessError(f"{target}: exit status {proc.returncode}: {' '.join(cmd)}\n{text[-3000:]}")
    state, raw, overhead, stack, window = _parse(text, n)
    if stack is not None and window is not None and stack >= window:
        stack = None  # the step went past the painted band: no figure rather than a wrong one
    counts = _to_counts(tgt, raw, overhead) if count and tgt.count_unit else None
    names = driver.names if isinstance(driver, Driver) else None
    kinds = driver.kinds if isinstance(driver, Driver) else None
    return Result(target, state, names, kinds, counts, raw, overhead, elf, text, seconds, stack)


def run(
    target: str,
    sources: Sequence[Union[str, os.PathLike]] = (),
    include_dirs: Sequence[Union[str, os.PathLike]] = (),
    defines: Optional[Mapping[str, object]] = None,
    driver: Union[Driver, str, None] = None,
    inputs: Optional[Mapping[str, np.ndarray]] = None,
    n: Optional[int] = None,
    count: bool = False,
    timeout: float = 120.0,
    workdir: Union[str, os.PathLike, None] = None,
) -> Result:
    """Build for ``target`` and run in its emulator (host: natively); see ``build``/``Result``.

    count=True measures every step (avr: cycles; m4f/m0: instructions via qemu -icount).
    """
    own = workdir is None
    wd = Path(tempfile.mkdtemp(prefix=f"imf_mcu_{target}_")) if workdir is None else Path(workdir)
    try:
        if n is None and inputs:
            n = len(np.asarray(next(iter(inputs.values()))))
        elf = build(target, sources, include_dirs, defines, driver, inputs, n, wd)
        return run_elf(target, elf, n if n is not None else 0, count=count, timeout=timeout, driver=driver)
    finally:
        if own:
            shutil.rmtree(wd, ignore_errors=True)
