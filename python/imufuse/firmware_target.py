"""A user's firmware on the emulated MCU it ships on (`imufuse validate --target`).

The user's sources are built by the target's cross compiler with the user's own flags (the
target adds only its architecture flags), linked with the harness driver
(``mcu/data/imf_fw_main.c``) and run on the emulator: Cortex-M4F (QEMU mps2-an386), Cortex-M0
(QEMU microbit), ATmega328P (simavr). Every state variable comes back after every sample.

Logs of any length: the program is linked once with an input block in flash; before each run
the host writes the next chunk of samples (and, from the second chunk on, the image of the
firmware's RAM as the previous chunk left it) into the linked image. A chunk that resumes
copies the image over .data and .bss instead of calling the firmware's init, so static
variables of the firmware carry across chunks as they would in one run.

Reported with the states: per-update counts (cycles on AVR, instructions on ARM), the stack the
update reached (painted band), the firmware's flash and RAM in the linked image.
"""
from __future__ import annotations

import dataclasses
import math
import os
import re
import shutil
import struct
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .catalogue import entry
from .estimate import ADAPTERS
from .mcu import toolchains as _tc
from .mcu.emulators import _simavr_text

#: user-facing target names -> harness targets
TARGETS = {"cortex-m4f": "m4f", "cortex-m0": "m0", "atmega328p": "avr"}
#: what each target is, for reports
DESCRIPTION = {
    "cortex-m4f": "Cortex-M4F (fpv4-sp-d16, hard float), QEMU mps2-an386",
    "cortex-m0": "Cortex-M0 (no FPU: soft float), QEMU microbit",
    "atmega328p": "ATmega328P at 16 MHz (no FPU, double is 32 bits), simavr",
}
#: the default flags of a cross build: what a firmware build does (the compiler's own standard)
DEFAULT_TARGET_CFLAGS = ("-O2",)
#: samples per chunk at most (bounds one emulator run's output)
MAX_CHUNK = 50_000
_MAGIC = 0x494D4601
_IN_KIND = {np.dtype(np.float32): 1, np.dtype(np.float64): 2, np.dtype(np.int16): 3,
            np.dtype(np.int32): 4}


class TargetError(RuntimeError):
    """The firmware failed on the target: one line naming the sample (see .sample)."""

    def __init__(self, msg: str, sample: Optional[int] = None):
        super().__init__(msg)
        self.sample = sample


def target_names() -> List[str]:
    return ["host", *TARGETS]


def harness_target(target: str) -> str:
    try:
        return TARGETS[target]
    except KeyError:
        raise ValueError(f"unknown target {target!r}; known: {', '.join(target_names())}") from None


# ---------------------------------------------------------------------------
# ELF: symbols and the file offsets of their bytes (ELF32 little endian: ARM and AVR)

@dataclasses.dataclass
class _Elf:
    path: Path
    symbols: Dict[str, Tuple[int, int, int]]        # name -> (address, size, type)
    sections: List[Tuple[str, int, int, int, int, int]]  # name, type, flags, addr, offset, size

    @classmethod
    def read(cls, path: Path) -> "_Elf":
        data = path.read_bytes()
        if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
            raise TargetError(f"{path}: not a 32-bit little-endian ELF file")
        shoff, = struct.unpack_from("<I", data, 0x20)
        shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
        raw = [struct.unpack_from("<IIIIIIIIII", data, shoff + k * shentsize) for k in range(shnum)]
        names_off = raw[shstrndx][4]

        def cstr(off):
            return data[off:data.index(b"\0", off)].decode()

        sections = [(cstr(names_off + s[0]), s[1], s[2], s[3], s[4], s[5]) for s in raw]
        symbols: Dict[str, Tuple[int, int, int]] = {}
        for s in raw:
            if s[1] != 2:   # SHT_SYMTAB
                continue
            strtab = raw[s[6]][4]
            for k in range(s[5] // 16):
                name, value, size, info, _, _ = struct.unpack_from("<IIIBBH", data, s[4] + 16 * k)
                if name:
                    symbols.setdefault(cstr(strtab + name), (value, size, info & 0xF))
        return cls(path, symbols, sections)

    def offset(self, name: str) -> int:
        addr = self.symbols[name][0]
        for _, typ, _, a, off, size in self.sections:
            if typ == 1 and a <= addr < a + size:   # SHT_PROGBITS
                return off + addr - a
        raise TargetError(f"{self.path}: symbol {name} is not in a loaded section")

    def read_symbol(self, name: str, size: int) -> bytes:
        with open(self.path, "rb") as fh:
            fh.seek(self.offset(name))
            return fh.read(size)

    def flash_used(self, ram_base: int) -> int:
        """Bytes of flash the image occupies (allocated sections below RAM, plus .data)."""
        total = 0
        for name, typ, flags, addr, _, size in self.sections:
            if flags & 2 and (addr < ram_base or name == ".data") and typ != 8:
                total += size
        return total


_RAM_BASE = {"m4f": 0x20000000, "m0": 0x20000000, "avr": 0x800000}


# ---------------------------------------------------------------------------
# the program

@dataclasses.dataclass
class StateType:
    size: int
    integer: bool
    signed: bool
    double: bool    # declared double (on AVR: 32 bits)

    @classmethod
    def decode(cls, word: int) -> "StateType":
        return cls(word & 0xFF, bool(word & 0x100), bool(word & 0x200), bool(word & 0x400))

    @property
    def dtype(self) -> np.dtype:
        if self.integer:
            return np.dtype(np.int64)
        return np.dtype(np.float32 if self.size == 4 else np.float64)


@dataclasses.dataclass
class Program:
    """One linked firmware image with its input block (see the module doc)."""
    target: str                 # user-facing name
    elf: Path
    workdir: Path
    user_objects: List[Path]
    cflags: List[str]
    types: List[StateType]
    chunk: int                  # samples per run
    ram_image: int              # bytes of .data/.bss saved between chunks
    row: int                    # input values per sample
    in_dtype: np.dtype
    flash: Optional[int]        # the firmware's own flash bytes in the image (None: -flto
                                # inlined it into the harness)
    ram: int                    # its static RAM bytes (filter object included)
    library: List[str]          # library routines it calls (soft float, libm)
    library_flash: int          # flash of the archive members they pull in
    build_seconds: float


def _strip_warnings(flags: Sequence[str]) -> List[str]:
    """The user's flags for the harness's own files: warnings are theirs, not the driver's."""
    return [f for f in flags if not (f.startswith("-W") and not f.startswith(("-Wl,", "-Wa,")))
            and not f.startswith("-pedantic")]


def _run(cmd: Sequence[str], cwd: Path, what: str) -> subprocess.CompletedProcess:
    try:
        proc = subprocess.run(list(cmd), cwd=cwd, capture_output=True, text=True, timeout=600)
    except FileNotFoundError:
        raise _tc.ToolchainMissing(f"{cmd[0]} not found; run tools/install-toolchains.sh "
                                   "(Debian: gcc-arm-none-eabi, libnewlib-arm-none-eabi, "
                                   "qemu-system-arm, gcc-avr, avr-libc, simavr)") from None
    if proc.returncode != 0:
        raise _BuildFailed(f"{what} failed:\n  {' '.join(map(str, cmd))}\n"
                           f"{(proc.stdout + proc.stderr).strip()[-3000:]}")
    return proc


class _BuildFailed(RuntimeError):
    pass


def _block_source(chunk_bytes: int, ram_cap: int) -> str:
    return (
        "/* Generated by imufuse.firmware_target: the block the host rewrites before every run. */\n"
        "#include <stdint.h>\n"
        "#if defined(__AVR__)\n#include <avr/pgmspace.h>\n#define IMF_FLASH PROGMEM\n"
        "#else\n#define IMF_FLASH\n#endif\n"
        f"const uint32_t imf_fw_hdr[6] IMF_FLASH = {{ 0x{_MAGIC:08x}u, 0u, 0u, 0u, 0u, 0u }};\n"
        f"const uint8_t imf_fw_in[{max(chunk_bytes, 1)}] IMF_FLASH = {{ 1u }};\n"
        f"const uint8_t imf_fw_ram[{max(ram_cap, 1)}] IMF_FLASH = {{ 1u }};\n")


@dataclasses.dataclass
class _Map:
    """What a GNU ld map file says about objects, archive members and symbols."""
    sizes: Dict[str, Dict[str, int]]        # input file -> {"flash": B, "ram": B}
    symbol_file: Dict[str, str]             # symbol -> input file defining it
    included_by: Dict[str, str]             # archive member -> the file that pulled it in

    @classmethod
    def parse(cls, text: str) -> "_Map":
        sizes: Dict[str, Dict[str, int]] = {}
        symbol_file: Dict[str, str] = {}
        included_by: Dict[str, str] = {}
        lines = text.splitlines()
        k = 0
        if lines and lines[0].startswith("Archive member included"):
            k = 1
            member = None
            while k < len(lines) and not lines[k].startswith(("Discarded", "Memory Configuration",
                                                               "Allocating common")):
                ln = lines[k]
                m = re.match(r"^(\S+\.a\(\S+\))(?:\s+(\S+) \((\S+)\))?$", ln)
                if m:
                    member = m.group(1)
                    if m.group(2):
                        included_by[member] = m.group(2)
                else:
                    m = re.match(r"^\s+(\S+) \((\S+)\)$", ln)
                    if m and member:
                        included_by[member] = m.group(1)
                k += 1
        in_map = False
        pending = None
        current = None
        for ln in lines[k:]:
            if ln.startswith("Linker script and memory map"):
                in_map = True
                continue
            if not in_map:
                continue
            m = re.match(r"^ (\.\S+|COMMON)\s*$", ln)
            if m:
                pending, current = m.group(1), None
                continue
            m = re.match(r"^ (\.\S+|COMMON)?\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S+)$", ln)
            if m:
                sec = m.group(1) or pending
                pending = None
                current = m.group(4)
                size = int(m.group(3), 16)
                d = sizes.setdefault(current, {"flash": 0, "ram": 0})
                if sec is None:
                    continue
                if sec.startswith((".bss", "COMMON", ".noinit")):
                    d["ram"] += size
                elif sec.startswith(".data"):
                    d["ram"] += size
                    d["flash"] += size
                elif sec.startswith((".text", ".rodata", ".progmem")):
                    d["flash"] += size
                continue
            m = re.match(r"^\s+0x[0-9a-f]+\s+([A-Za-z_][\w.$]*)$", ln)
            if m and current:
                symbol_file.setdefault(m.group(1), current)
                continue
            pending = None
            if not ln.startswith(" "):
                current = None
        return cls(sizes, symbol_file, included_by)

    def of_objects(self, objects: Sequence[Path]) -> Tuple[int, int]:
        names = {str(o) for o in objects} | {o.name for o in objects}
        flash = ram = 0
        for f, d in self.sizes.items():
            if f in names or os.path.basename(f) in names:
                flash += d["flash"]
                ram += d["ram"]
        return flash, ram

    def library(self, calls: Sequence[str], objects: Sequence[Path]) -> Tuple[List[str], int]:
        """The library routines among `calls` and the flash of the archive members they pull
        in (with the helpers those members pulled in)."""
        members = {self.symbol_file[c] for c in calls
                   if c in self.symbol_file and ".a(" in self.symbol_file[c]}
        grew = True
        while grew:
            grew = False
            for mem, by in self.included_by.items():
                if mem not in members and by in members:
                    members.add(mem)
                    grew = True
        routines = [c for c in calls if c in self.symbol_file and ".a(" in self.symbol_file[c]]
        return routines, sum(self.sizes.get(m, {}).get("flash", 0) for m in members)


def _defined(tool_prefix: str, objects: Sequence[Path], cwd: Path) -> List[str]:
    """Symbols the firmware's objects define (gcc-nm reads LTO objects too)."""
    nm = tool_prefix + "gcc-nm" if tool_prefix else "gcc-nm"
    if shutil.which(nm) is None:
        nm = tool_prefix + "nm"
    out = subprocess.run([nm, "--defined-only", *map(str, objects)], cwd=cwd,
                         capture_output=True, text=True).stdout
    return sorted({ln.split()[-1] for ln in out.splitlines() if len(ln.split()) >= 2})


def _undefined(tool_prefix: str, objects: Sequence[Path], cwd: Path) -> List[str]:
    """Symbols the firmware's objects use and do not define."""
    nm = tool_prefix + "nm"
    if shutil.which(nm) is None:
        return []
    und = subprocess.run([nm, "-u", *map(str, objects)], cwd=cwd, capture_output=True,
                         text=True).stdout
    defined = set(subprocess.run([nm, "--defined-only", *map(str, objects)], cwd=cwd,
                                 capture_output=True, text=True).stdout.split())
    out = set()
    for line in und.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[-2] == "U" and parts[-1] not in defined:
            out.add(parts[-1])
    return sorted(out)


def _tool_prefix(tgt: "_tc.Target") -> str:
    return tgt.cc[:-3] if tgt.cc.endswith("gcc") else ""


def build_program(fw: Any, target: str, kind: str, driver: str, row: int, cflags: Sequence[str],
                  in_dtype: Optional[np.dtype] = None, workdir: Optional[Path] = None) -> Program:
    """Compile the firmware (user flags), the driver and the port, link twice (a probe to
    size the input block, then the program). in_dtype None: from the state types (floats:
    their precision)."""
    t0 = time.perf_counter()
    name = harness_target(target)
    tgt = _tc.TARGETS[name]
    _tc._require(tgt, [tgt.cc])
    wd = Path(workdir) if workdir else Path(tempfile.mkdtemp(prefix=f"imf_fw_{name}_"))
    wd.mkdir(parents=True, exist_ok=True)
    try:
        return _build_in(fw, target, name, tgt, driver, row, cflags, in_dtype, wd, t0)
    except BaseException:
        if not workdir:
            shutil.rmtree(wd, ignore_errors=True)
        raise


def _build_in(fw: Any, target: str, name: str, tgt: "_tc.Target", driver: str, row: int,
              cflags: Sequence[str], in_dtype: Optional[np.dtype], wd: Path, t0: float) -> Program:
    (wd / "imf_driver.h").write_text(driver)
    data = _tc.DATA_DIR
    defs = [f"-D{k}" if v is None else f"-D{k}={v}" for k, v in fw.defines.items()]
    incs = [f"-I{d}" for d in fw.include_dirs] + \
        [f"-I{d}" for d in sorted({os.path.dirname(s) for s in fw.sources})]
    user = list(cflags)
    # the target's architecture, then any the user's flags set (an ABI the harness's own
    # objects must share: -mfloat-abi=softfp, -mcpu=...)
    arch = list(tgt.arch_flags) + [f for f in user if f.startswith(
        ("-mcpu", "-mfpu", "-mfloat-abi", "-march", "-mthumb", "-marm", "-mmcu"))]
    objs: List[Path] = []
    try:
        for i, src in enumerate(fw.sources):
            obj = wd / f"fw{i}_{Path(src).stem}.o"
            _run([tgt.cc, *arch, *user, *defs, *incs, "-fstack-usage", "-c", src, "-o", str(obj)],
                 wd, f"compiling {src} for {target}")
            objs.append(obj)
        port = wd / "imf_port.o"
        _run([tgt.cc, *arch, *_tc.BASE_FLAGS, f"-I{data}", "-c", str(data / tgt.sources[0]), "-o",
              str(port)], wd, "compiling the harness port")
        main = wd / "imf_fw_main.o"
        # the driver with the user's flags (ABI, defines) and the harness's section flags, as
        # the MCU benchmarks build their drivers (same call code, same counts)
        _run([tgt.cc, *arch, *_strip_warnings(user), *_tc._SECTION_FLAGS, *defs, f"-I{wd}",
              f"-I{data}", *incs, "-c",
              str(data / "imf_fw_main.c"), "-o", str(main)], wd,
             f"compiling the validation driver with the firmware's headers for {target}")
    except _BuildFailed as e:
        raise TargetError(str(e)) from None

    def link(chunk_bytes, ram_cap):
        (wd / "imf_fw_block.c").write_text(_block_source(chunk_bytes, ram_cap))
        blk = wd / "imf_fw_block.o"
        _run([tgt.cc, *arch, *_tc.BASE_FLAGS, "-c", str(wd / "imf_fw_block.c"), "-o", str(blk)],
             wd, "compiling the input block")
        elf = wd / f"imf_fw_{name}.elf"
        cmd = [tgt.cc, *arch, *user, *tgt.link_flags]
        if tgt.machine is not None:
            ld = wd / "imf.ld"
            ld.write_text((data / "arm.ld.in").read_text().replace("@FLASH_LEN@", str(tgt.flash))
                          .replace("@RAM_LEN@", str(tgt.ram)))
            cmd.append(f"-T{ld}")
        cmd += [str(o) for o in (*objs, main, port, blk)]
        cmd += ["-o", str(elf), "-lm", f"-Wl,-Map={wd / 'imf_fw.map'}"]
        try:
            _run(cmd, wd, f"linking for {target}")
        except _BuildFailed as e:
            msg = str(e)
            if "overflow" in msg or "will not fit" in msg:
                raise TargetError(f"the firmware does not fit the {target}'s memory "
                                    f"({tgt.flash} B flash, {tgt.ram} B RAM):\n{msg}") from None
            raise TargetError(msg) from None
        return _Elf.read(elf)

    probe = link(1, 1)
    n_state = len(fw.state)
    types = [StateType.decode(w) for w in
             struct.unpack(f"<{n_state}I", probe.read_symbol("imf_fw_types", 4 * n_state))] \
        if n_state else []
    ram_image = probe.symbols["__heap_start"][0] - probe.symbols["__data_start"][0]
    if in_dtype is None:
        fl = [t for t in types if not t.integer]
        in_dtype = np.dtype(np.float64 if fl and fl[0].size == 8 else np.float32)
    in_dtype = np.dtype(in_dtype)
    row_bytes = row * in_dtype.itemsize
    free = tgt.flash - probe.flash_used(_RAM_BASE[name]) - ram_image - 512
    chunk = min(MAX_CHUNK, free // max(row_bytes, 1))
    if chunk < 1:
        raise TargetError(f"the firmware leaves no flash for inputs on the {target} "
                            f"({tgt.flash} B)")
    elf = link(chunk * row_bytes, ram_image)
    if elf.symbols["__heap_start"][0] - elf.symbols["__data_start"][0] != ram_image:
        raise TargetError("the RAM layout changed between the probe and the program")
    lmap = _Map.parse((wd / "imf_fw.map").read_text(errors="replace"))
    flash, ram = lmap.of_objects(objs)
    if any(f.startswith("-flto") for f in cflags):
        # link-time optimisation: the image's code comes from ltrans objects; count the symbols
        # the firmware's objects define, as they ended up in the image
        flash = ram = 0
        for sym in _defined(_tool_prefix(tgt), objs, wd):
            if sym in elf.symbols:
                addr, size, _ = elf.symbols[sym]
                if addr >= _RAM_BASE[name]:
                    ram += size
                else:
                    flash += size
        flash_or_none: Optional[int] = flash or None   # None: inlined across units
    else:
        flash_or_none = flash
    obj = elf.symbols.get("imf_fw_obj")
    if obj:
        ram += obj[1]
    routines, lib_flash = lmap.library(_undefined(_tool_prefix(tgt), objs, wd), objs)
    return Program(target, elf.path, wd, objs, list(cflags), types, int(chunk), int(ram_image),
                   row, in_dtype, flash_or_none, ram, routines, lib_flash, time.perf_counter() - t0)


# ---------------------------------------------------------------------------
# running it

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


_SLINE = re.compile(r"^S((?: [0-9a-f]{8}(?:[0-9a-f]{8})?)*) c([0-9a-f]{8})$")


def _patch(prog: Program, elf: _Elf, n: int, resume: bool, image: bytes, rows: np.ndarray) -> None:
    kind = _IN_KIND[prog.in_dtype]
    with open(prog.elf, "r+b") as fh:
        fh.seek(elf.offset("imf_fw_hdr"))
        fh.write(struct.pack("<6I", _MAGIC, n, int(resume), len(image), kind, prog.row))
        fh.seek(elf.offset("imf_fw_in"))
        fh.write(np.ascontiguousarray(rows, dtype=prog.in_dtype.newbyteorder("<")).tobytes())
        if image:
            fh.seek(elf.offset("imf_fw_ram"))
            fh.write(image)


def _emulator(name: str, tgt: "_tc.Target", elf: Path) -> List[str]:
    if tgt.emulator == "qemu-system-arm":
        return ["qemu-system-arm", "-M", str(tgt.machine), "-nographic", "-monitor", "none",
                "-serial", "null", "-semihosting-config", "enable=on,target=native",
                "-icount", f"shift={_tc.ICOUNT_SHIFT},align=off,sleep=off", "-kernel", str(elf)]
    return ["simavr", "-m", "atmega328p", "-f", "16000000", str(elf)]


def _counts(name: str, tgt: "_tc.Target", raw: np.ndarray, overhead: int) -> np.ndarray:
    if name == "avr":
        def fix(c):
            c = np.asarray(c, dtype=np.int64)
            return c - (c >> 16) * _tc.AVR_OVF_ISR_CYCLES
        return fix(raw) - int(fix(overhead))
    per = (2 ** _tc.ICOUNT_SHIFT) * 1e-9 * tgt.systick_hz
    return np.rint(raw / per).astype(np.int64) - int(np.rint(overhead / per))


def run_program(prog: Program, inputs: np.ndarray, timeout: float) -> TargetRun:
    """Run (N, row) inputs through the program chunk by chunk. TargetError on a fault, an
    exit, a reset, a stack overflow or a timeout, naming the sample."""
    name = harness_target(prog.target)
    tgt = _tc.TARGETS[name]
    _tc._require(tgt, [tgt.emulator or "emulator"])
    elf = _Elf.read(prog.elf)
    inputs = np.asarray(inputs, dtype=prog.in_dtype).reshape(len(inputs), prog.row)
    n_total = inputs.shape[0]
    words: List[List[str]] = []
    raw_counts: List[int] = []
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
        _patch(prog, elf, n, bool(image), image, inputs[start:start + n])
        cmd = _emulator(name, tgt, prog.elf)
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
        text = out.decode("latin-1")
        if name == "avr":
            text = _simavr_text(text)
        got = 0
        overhead = None
        ended = False
        fault = None
        for line in text.splitlines():
            line = line.strip()
            m = _SLINE.match(line)
            if m:
                words.append(m.group(1).split())
                raw_counts.append(int(m.group(2), 16))
                got += 1
            elif line.startswith("T"):
                t = [int(w, 16) for w in line[1:].split()]
                if types_seen is not None and overhead is not None:
                    fault = "reset"     # the program started again: a jump to the reset vector
                    break
                types_seen = t
            elif line.startswith("K "):
                overhead = int(line[2:], 16)
            elif line.startswith("M "):
                s, b, _ = (int(w, 16) for w in line[2:].split())
                if s < b:
                    stack = max(stack, s)
                else:
                    stack = -1
                band = b
            elif line.startswith("R "):
                image = bytes.fromhex(line[2:])
            elif line == "IMF_END":
                ended = True
            elif "IMF_FAULT" in line:
                fault = "fault"
            elif "IMF_RESET" in line:
                fault = "reset"
            elif "IMF_STACK_OVERFLOW" in line:
                fault = "stack"
            elif line.startswith("IMF_EXIT"):
                fault = "exit " + str(int(np.uint32(int(line.split()[-1], 16)).view(np.int32)))
        t_parse += time.perf_counter() - t1
        k = start + got
        if chunks == 0:
            first_overhead = overhead or 0
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
        elif not ended or got != n or overhead is None:
            where = "during init" if (overhead is None or types_seen is None) and start == 0 \
                else f"at sample {k}"
            tail = " ".join(text.strip().splitlines()[-2:])[-200:]
            msg = (f"the firmware stopped {where} on the {prog.target} (exit status {code}; a "
                   f"fault, exit() or a stop: {tail!r})")
        if msg:
            raise TargetError(msg + _stack_hint(prog), k)
        chunks += 1
        start += n
        if n_total == 0:
            break
    ns = len(prog.types)
    if types_seen is not None and len(types_seen) != ns:
        raise TargetError("the state types printed do not match the program")
    t1 = time.perf_counter()
    states = _decode(words, prog.types)
    t_parse += time.perf_counter() - t1
    counts = _counts(name, tgt, np.array(raw_counts, dtype=np.int64),
                     first_overhead if raw_counts else 0)
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


def _decode(words: List[List[str]], types: Sequence[StateType]) -> List[np.ndarray]:
    n = len(words)
    out = []
    if n and any(len(w) != len(types) for w in words):
        raise TargetError("samples differ in the number of state words")
    cols = list(zip(*words)) if n else [()] * len(types)
    for j, t in enumerate(types):
        vals = np.array([int(h, 16) for h in cols[j]], dtype=np.uint64)
        a: np.ndarray
        if not t.integer:
            a = vals.astype(np.uint32).view(np.float32) if t.size == 4 else vals.view(np.float64)
        elif t.size > 4:
            a = vals.view(np.int64) if t.signed else vals.astype(np.int64)
        elif t.signed:
            a = vals.astype(np.uint32).view(np.int32).astype(np.int64)
        else:
            a = vals.astype(np.int64)
        out.append(a)
    return out


# ---------------------------------------------------------------------------
# why a build differs

@dataclasses.dataclass
class Cause:
    """A likely cause of a divergence found in what was built."""
    what: str                 # "fma", "double", "fast-math", "avr-double", "together"
    evidence: str             # what was seen (instructions, calls, flags, warnings)
    fix: Optional[str]        # the flag that removes it
    confirmed: Optional[bool] = None   # rebuilt with the fix: bit-exact (True) or not (False)

    def text(self) -> str:
        if self.what == "together":
            return (f"together: rebuilt with {self.fix}, the firmware is bit-exact" if self.confirmed
                    else f"together: rebuilt with {self.fix}, still not bit-exact")
        name = {"fma": "fused multiply-add (a*b+c contracted into one rounding)",
                "double": "double-precision arithmetic in a float32 build",
                "fast-math": "fast-math optimisation (reassociation, reciprocals)",
                "avr-double": "double is 32 bits on the ATmega328P"}[self.what]
        s = f"cause: {name}: {self.evidence}"
        if self.fix:
            s += f"\n  fix: add {self.fix}"
            if self.confirmed is True:
                s += f" (confirmed: rebuilt with {self.fix}, the firmware is bit-exact)"
            elif self.confirmed is False:
                s += f" (rebuilt with {self.fix}: still not bit-exact, so not the only cause)"
        return s


_FAST = ("-ffast-math", "-Ofast", "-freciprocal-math", "-funsafe-math-optimizations",
         "-fassociative-math")
_FMA_ARM = re.compile(r"\bv?fn?m[as]\.f(?:32|64)\b|\bvfnm[as]\b")
_FMA_X86 = re.compile(r"\bv?fn?m(?:add|sub)\d{3}[sp][sd]\b")
_DOUBLE_CALLS = re.compile(r"\b(__aeabi_d\w+|__aeabi_f2d|__\w+df\d?|__extendsfdf2|__truncdfsf2)\b")


def find_causes(objdump: str, objects: Sequence[Path], sources: Sequence[str], cflags: Sequence[str],
                compile_cmd: Sequence[str], dtype: str, target: str, state_double: bool,
                cwd: Path) -> List[Cause]:
    """Look at the objects and flags of a build for what changes float results."""
    causes: List[Cause] = []
    asm = ""
    if shutil.which(objdump):
        asm = subprocess.run([objdump, "-dr", *map(str, objects)], cwd=cwd, capture_output=True,
                             text=True).stdout
    fma = sorted(set(_FMA_ARM.findall(asm) + _FMA_X86.findall(asm)))
    fma_calls = sorted(set(re.findall(r"\b(fmaf?|fmal)\b", " ".join(
        ln for ln in asm.splitlines() if "R_" in ln))))
    if fma or fma_calls:
        n = sum(asm.count(f) for f in fma)
        ev = (f"{n} fused instruction(s) in the object ({', '.join(fma)})" if fma else "") + \
            (("; " if fma else "") + f"calls to {', '.join(fma_calls)}" if fma_calls else "")
        causes.append(Cause("fma", ev + f" built with {' '.join(cflags) or '(no flags)'}: GCC's "
                            "default -ffp-contract=fast (gnu standards) fuses a*b+c where the "
                            "target has an FMA instruction", "-ffp-contract=off"))
    fast = [f for f in cflags if f in _FAST]
    pragmas = []
    for s in sources:
        try:
            text = Path(s).read_text(errors="replace")
        except OSError:
            continue
        if re.search(r"#\s*pragma\s+GCC\s+optimize.*(fast-math|Ofast)|optimize\s*\(\s*\"(-?Ofast|"
                     r"fast-math)", text):
            pragmas.append(os.path.basename(s))
    if fast or pragmas:
        ev = (f"flags {' '.join(fast)}" if fast else "") + \
            ((" and " if fast else "") + f"optimize pragmas in {', '.join(pragmas)}" if pragmas else "")
        causes.append(Cause("fast-math", ev + ": the compiler may reassociate sums, replace "
                            "divisions by reciprocals and assume no NaN", "-fno-fast-math"))
    if dtype == "float32" and target != "atmega328p":
        calls = sorted(set(_DOUBLE_CALLS.findall(" ".join(ln for ln in asm.splitlines()
                                                          if "R_" in ln))))
        x86 = re.findall(r"\bcvtss2sd\b|\b\w+sd\s+%xmm", asm) if not calls else []
        warn = double_promotions(compile_cmd, sources, cwd)
        if calls or x86 or warn:
            found: List[str] = []
            if calls:
                found.append(f"double routines called: {', '.join(calls)}")
            if x86:
                found.append(f"{len(x86)} double-precision instruction(s)")
            if warn:
                found.append("-Wdouble-promotion warns at " + ", ".join(warn[:4]) +
                             (f" (+{len(warn) - 4} more)" if len(warn) > 4 else ""))
            causes.append(Cause("double", "; ".join(found) + ": a double constant or function "
                                "(0.5, sqrt) promotes float operands, rounding once in double "
                                "instead of in float", "-fsingle-precision-constant"))
    if target == "atmega328p" and state_double:
        causes.append(Cause("avr-double", "avr-gcc's double is the 32-bit float: the firmware's "
                            "double state was compared with imufuse in float32", None))
    return causes


def double_promotions(compile_cmd: Sequence[str], sources: Sequence[str], cwd: Path) -> List[str]:
    """file:line:col of every -Wdouble-promotion warning of the sources."""
    warn: List[str] = []
    if not compile_cmd or shutil.which(compile_cmd[0]) is None:
        return warn
    for s in sources:
        p = subprocess.run([*compile_cmd, "-Wdouble-promotion", "-fsyntax-only", s],
                           cwd=cwd, capture_output=True, text=True)
        for ln in p.stderr.splitlines():
            m = re.match(r"^(.*?):(\d+):(\d+): warning: .*\[-Wdouble-promotion\]", ln)
            if m:
                warn.append(f"{os.path.basename(m.group(1))}:{m.group(2)}:{m.group(3)}")
    return warn


def angle_divergence_deg(name: str, params: Dict[str, Any], got: np.ndarray, want: np.ndarray,
                         fixed: bool) -> Optional[float]:
    """The largest orientation difference over the run, in degrees (None without an
    orientation estimate)."""
    e = entry(name)
    if e.estimate is None:
        return None
    g = got.astype(np.float64)
    w = want.astype(np.float64)
    if fixed and e.estimate == "angle":
        f = e.make("ref", **params)
        g = np.column_stack(f._state_float(list(g.T)))
        w = np.column_stack(f._state_float(list(w.T)))
    try:
        eg = ADAPTERS[e.estimate](e.state_names, e.kind, g)
        ew = ADAPTERS[e.estimate](e.state_names, e.kind, w)
    except (ValueError, IndexError):
        return None
    with np.errstate(all="ignore"):
        if eg.q is not None and ew.q is not None:
            d = np.abs(np.sum(eg.q * ew.q, axis=1))
            ang = 2.0 * np.degrees(np.arccos(np.clip(d, 0.0, 1.0)))
        elif eg.angle is not None and ew.angle is not None:
            ang = np.degrees(np.abs(eg.angle - ew.angle))
        else:
            return None
    ang = np.where(np.isnan(ang), 180.0, ang)
    return float(ang.max()) if ang.size else 0.0


def speed_note(target: str) -> str:
    if target == "cortex-m4f":
        return ("the cortex-m4f has a single-precision FPU with vfma: under gnu defaults "
                "(-ffp-contract=fast) GCC fuses a*b+c in float32 code")
    if target == "cortex-m0":
        return ("the cortex-m0 has no FPU: every float operation is a libgcc call that rounds "
                "on its own, so there is no multiply-add for the compiler to fuse")
    if target == "atmega328p":
        return ("the ATmega328P has no FPU: every float operation is an avr-libc call that "
                "rounds on its own (no fused multiply-add), and double is 32 bits")
    return ""


def hexfloat(v: float) -> str:
    """An exact C literal of a double."""
    if not math.isfinite(v):
        raise ValueError(f"non-finite value {v!r}")
    if v == 0.0:
        return "-0.0" if math.copysign(1.0, v) < 0 else "0.0"
    return v.hex()
