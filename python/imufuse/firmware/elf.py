"""Reading what a cross build produced: the ELF image (symbols and the file offsets of their
bytes, ELF32 little endian: ARM and AVR) and the GNU ld map file (the flash and RAM of each
object, the archive members library calls pull in).
"""
from __future__ import annotations

import dataclasses
import os
import re
import struct
from pathlib import Path
from typing import Dict, List, Sequence, Tuple

from .targets import TargetError

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
