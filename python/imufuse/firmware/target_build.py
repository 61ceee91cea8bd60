"""A user's firmware built for the emulated MCU it ships on (`imufuse validate --target`).

The user's sources are built by the target's cross compiler with the user's own flags (the
target adds only its architecture flags) and linked with the harness driver
(``mcu/data/imf_fw_main.c``, which includes the driver of imufuse.firmware.csource) and an
input block in flash: Cortex-M4F (QEMU mps2-an386), Cortex-M0 (QEMU microbit), ATmega328P
(simavr). The link runs twice: a probe sizes the input block to the flash left, then the
program. The ``Program`` says what was built: the state words' C types, the samples per chunk,
the firmware's flash and RAM, the library routines it pulls in (imufuse.firmware.target_run
runs it).

Programs are cached (imufuse.firmware.target_cache): a hit copies the image and the
firmware's objects into the work directory (the runs write their inputs into the image).
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import struct
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np

from ..mcu import toolchains as _tc
from .elf import _Elf, _Map
from .host import compiler_identity
from .target_cache import _program_cache, _program_key, _read_entry, _store_entry, cache_limit
from .targets import TargetError, harness_target

__all__ = ["StateType", "Program", "build_program", "MAX_CHUNK", "CXX_TARGET_FLAGS", "is_cxx",
           "cxx_flags"]

#: samples per chunk at most (bounds one emulator run's output)
MAX_CHUNK = 50_000
_MAGIC = 0x494D4601
_IN_KIND = {np.dtype(np.float32): 1, np.dtype(np.float64): 2, np.dtype(np.int16): 3,
            np.dtype(np.int32): 4}


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
    cached: bool = False        # the build came from the program cache (build_seconds: the
                                # look-up's)


def _strip_warnings(flags: Sequence[str]) -> List[str]:
    """The user's flags for the harness's own files: warnings are theirs, not the driver's."""
    return [f for f in flags if not (f.startswith("-W") and not f.startswith(("-Wl,", "-Wa,")))
            and not f.startswith("-pedantic")]


#: what a C++ firmware is built with on an MCU target unless the flags say otherwise: the
#: embedded C++ toolchains' usual no exceptions, no RTTI, no thread-safe static guards (which
#: a bare-metal build cannot link)
CXX_TARGET_FLAGS = ("-fno-exceptions", "-fno-rtti", "-fno-threadsafe-statics")
CXX_EXTENSIONS = (".cpp", ".cc", ".cxx", ".C", ".c++")


def is_cxx(src: str) -> bool:
    return str(src).endswith(CXX_EXTENSIONS)


def _cxx(cc: str) -> str:
    """The C++ compiler beside a C compiler (arm-none-eabi-gcc -> arm-none-eabi-g++)."""
    if cc.endswith("gcc"):
        return cc[:-3] + "g++"
    if cc.endswith("clang"):
        return cc + "++"
    return "c++" if cc == "cc" else cc


def cxx_flags(flags: Sequence[str]) -> List[str]:
    """The flags for a C++ unit: the user's, less the C-only ones (-std=c99, which the C++
    compiler refuses), plus CXX_TARGET_FLAGS unless the user asks for exceptions, RTTI or
    thread-safe statics."""
    out = [f for f in flags if not (f.startswith("-std=") and "++" not in f)]
    for f in CXX_TARGET_FLAGS:
        positive = "-f" + f[len("-fno-"):]
        if positive not in out and f not in out:
            out.append(f)
    return out


def _run(cmd: Sequence[str], cwd: Path, what: str) -> subprocess.CompletedProcess:
    try:
        proc = subprocess.run(list(cmd), cwd=cwd, capture_output=True, text=True, timeout=600)
    except FileNotFoundError:
        raise _tc.ToolchainMissing(f"{cmd[0]} not found; run tools/install-toolchains.sh "
                                   "(Debian: gcc-arm-none-eabi, libnewlib-arm-none-eabi, "
                                   "qemu-system-arm, gcc-avr, avr-libc, simavr, "
                                   "gcc-riscv64-unknown-elf, picolibc-riscv64-unknown-elf, "
                                   "qemu-system-misc)") from None
    if proc.returncode != 0:
        raise _BuildFailed(f"{what} failed:\n  {' '.join(map(str, cmd))}\n"
                           f"{(proc.stdout + proc.stderr).strip()[-3000:]}")
    return proc


class _BuildFailed(RuntimeError):
    pass


def _run_all(jobs: Sequence[Tuple[Sequence[str], str]], cwd: Path) -> None:
    """The commands run side by side; _BuildFailed for the first (in the given order) that
    failed, with the message _run gives."""
    procs = []
    try:
        for cmd, what in jobs:
            try:
                procs.append((subprocess.Popen(list(cmd), cwd=cwd, stdout=subprocess.PIPE,
                                               stderr=subprocess.PIPE, text=True), cmd, what))
            except FileNotFoundError:
                _run(cmd, cwd, what)        # raises ToolchainMissing
        failed = None
        for proc, cmd, what in procs:
            try:
                out, err = proc.communicate(timeout=600)
            except subprocess.TimeoutExpired:
                proc.kill()
                out, err = proc.communicate()
                proc.returncode = proc.returncode or 1
            if proc.returncode != 0 and failed is None:
                failed = _BuildFailed(f"{what} failed:\n  {' '.join(map(str, cmd))}\n"
                                      f"{(out + err).strip()[-3000:]}")
        if failed is not None:
            raise failed
    finally:
        for proc, _, _ in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def _port_cache() -> Path:
    return Path(tempfile.gettempdir()) / f"imf_fw_ports_{os.getuid()}"


def _port_key(cmd: Sequence[str]) -> str:
    """The cache key of a harness port object: its command, the port's source and the
    compiler (path, size and time)."""
    h = hashlib.sha256("\0".join(cmd).encode())
    h.update(Path(cmd[-1]).read_bytes())
    h.update((_tc.DATA_DIR / "imf_port.h").read_bytes())
    cc = shutil.which(cmd[0])
    if cc:
        st = os.stat(cc)
        h.update(f"{cc}:{st.st_size}:{st.st_mtime_ns}".encode())
    return h.hexdigest()[:32]


def _cached_port(cmd: Sequence[str], wd: Path) -> Tuple[Path, Optional[List[str]]]:
    """(object, None) from the cache, or (object in wd, the command that compiles it)."""
    hit = _port_cache() / f"{_port_key(cmd)}.o"
    if hit.is_file():
        return hit, None
    obj = wd / "imf_port.o"
    return obj, [*cmd, "-o", str(obj)]


def _keep_port(cmd: Sequence[str], obj: Path) -> None:
    try:
        d = _port_cache()
        d.mkdir(parents=True, exist_ok=True)
        tmp = d / f"{_port_key(cmd)}.{os.getpid()}.tmp"
        shutil.copyfile(obj, tmp)
        os.replace(tmp, d / f"{_port_key(cmd)}.o")
    except OSError:
        pass                                # a cache that cannot be written: compiled next time


def _from_entry(meta: dict, blobs: dict, wd: Path, target: str, cflags: Sequence[str],
                row: int, t0: float) -> Program:
    """The cached program, its files copied into the work directory (the runs patch the
    image's input block: the cache's copy stays as built)."""
    for name, data in blobs.items():
        (wd / name).write_bytes(data)
    return Program(target, wd / meta["elf"], wd, [wd / o for o in meta["objects"]], list(cflags),
                   [StateType(*t) for t in meta["types"]], int(meta["chunk"]),
                   int(meta["ram_image"]), row, np.dtype(meta["in_dtype"]), meta["flash"],
                   int(meta["ram"]), list(meta["library"]), int(meta["library_flash"]),
                   time.perf_counter() - t0, True)


def _block_source(chunk_bytes: int, ram_cap: int) -> str:
    return (
        "/* Generated by imufuse.firmware: the block the host rewrites before every run. */\n"
        "#include <stdint.h>\n"
        "#if defined(__AVR__)\n#include <avr/pgmspace.h>\n#define IMF_FLASH PROGMEM\n"
        "#else\n#define IMF_FLASH\n#endif\n"
        f"const uint32_t imf_fw_hdr[7] IMF_FLASH = {{ 0x{_MAGIC:08x}u, 0u, 0u, 0u, 0u, 0u, 0u }};\n"
        f"const uint8_t imf_fw_in[{max(chunk_bytes, 1)}] IMF_FLASH = {{ 1u }};\n"
        f"const uint8_t imf_fw_ram[{max(ram_cap, 1)}] IMF_FLASH = {{ 1u }};\n")


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
        return _build_in(fw, target, name, tgt, driver, row, cflags, in_dtype, wd, t0, kind)
    except BaseException:
        if not workdir:
            shutil.rmtree(wd, ignore_errors=True)
        raise


def _build_in(fw: Any, target: str, name: str, tgt: "_tc.Target", driver: str, row: int,
              cflags: Sequence[str], in_dtype: Optional[np.dtype], wd: Path, t0: float,
              kind: str = "1d") -> Program:
    (wd / "imf_driver.h").write_text(driver)
    data = _tc.DATA_DIR
    defs = [f"-D{k}" if v is None else f"-D{k}={v}" for k, v in fw.defines.items()]
    incs = [f"-I{d}" for d in fw.include_dirs] + \
        [f"-I{d}" for d in sorted({os.path.dirname(s) for s in fw.sources})]
    user = list(cflags)
    # the target's architecture, then any the user's flags set (an ABI the harness's own
    # objects must share: -mfloat-abi=softfp, -mcpu=...)
    arch = list(tgt.arch_flags) + [f for f in user if f.startswith(
        ("-mcpu", "-mfpu", "-mfloat-abi", "-march", "-mabi", "-mthumb", "-marm", "-mmcu"))]
    objs: List[Path] = []
    cxx = _cxx(tgt.cc)
    adapter = fw.target_adapter(kind, getattr(fw, "values", {}).get("dt", 0.0)) \
        if hasattr(fw, "target_adapter") else None
    sources = list(fw.sources)
    if adapter is not None:
        (wd / adapter[0]).write_text(adapter[1])
        sources.append(str(wd / adapter[0]))
    any_cxx = any(is_cxx(src) for src in sources)
    # the firmware's units, the driver and the probe's input block compile side by side; the
    # harness port (the same for every firmware of a target and architecture) comes from a cache
    jobs = []
    for i, src in enumerate(sources):
        obj = wd / f"fw{i}_{Path(src).stem}.o"
        cc, flags = (cxx, cxx_flags(user)) if is_cxx(src) else (tgt.cc, user)
        if adapter is not None and src == sources[-1]:
            flags = [*flags, "-fno-access-control"]   # reads private members
        jobs.append(([cc, *arch, *flags, *defs, *incs, "-fstack-usage", "-c", src, "-o",
                      str(obj)], f"compiling {src} for {target}"))
        objs.append(obj)
    port_cmd = [tgt.cc, *arch, *_tc.BASE_FLAGS, f"-I{data}", "-c", str(data / tgt.sources[0])]
    port, port_job = _cached_port(port_cmd, wd)
    if port_job is not None:
        jobs.append((port_job, "compiling the harness port"))
    main = wd / "imf_fw_main.o"
    # the driver with the user's flags (ABI, defines) and the harness's section flags, as
    # the MCU benchmarks build their drivers (same call code, same counts)
    main_cmd = [tgt.cc, *arch, *_strip_warnings(user), *_tc._SECTION_FLAGS, *defs, f"-I{wd}",
                f"-I{data}", *incs, "-c", str(data / "imf_fw_main.c"), "-o", str(main)]
    script = _tc.linker_script(tgt)
    # the program cache: the same firmware, flags, driver and toolchain give the same
    # program, whatever log it then runs (the inputs are written into the image at run time)
    entry: Optional[Path] = None
    compiles = [j[0] for j in jobs[:len(sources)]] + [main_cmd, port_cmd]
    settings = [target, name, kind, row, None if in_dtype is None else np.dtype(in_dtype).str,
                user, sorted((str(k), str(v)) for k, v in fw.defines.items()),
                list(fw.include_dirs), list(fw.sources), len(fw.state),
                str(getattr(fw, "object_type", None)), str(getattr(fw, "object_name", None)),
                any_cxx, list(tgt.link_flags), [tgt.flash, tgt.ram, tgt.ram_origin],
                list(compiler_identity([tgt.cc])),
                list(compiler_identity([cxx])) if any_cxx else None]
    key = _program_key(wd, compiles, settings,
                       [driver, adapter[1] if adapter else "", script or ""])
    if key is not None:
        cache_limit()       # a bad $IMUFUSE_CACHE_MAX_MB is said before the build
        entry = _program_cache(fw) / f"{name}-{key}"
        hit = _read_entry(entry)
        if hit is not None:
            return _from_entry(*hit, wd, target, cflags, row, t0)
    jobs.append((main_cmd,
                 f"compiling the validation driver with the firmware's headers for {target}"))
    (wd / "imf_fw_block1.c").write_text(_block_source(1, 1))
    jobs.append(([tgt.cc, *arch, *_tc.BASE_FLAGS, "-c", str(wd / "imf_fw_block1.c"), "-o",
                  str(wd / "imf_fw_block1.o")], "compiling the input block"))
    try:
        _run_all(jobs, wd)
    except _BuildFailed as e:
        raise TargetError(str(e)) from None
    if port_job is not None:
        _keep_port(port_cmd, port)

    def link(chunk_bytes, ram_cap, probe=False):
        if probe:
            blk = wd / "imf_fw_block1.o"          # compiled with the firmware
        else:
            (wd / "imf_fw_block.c").write_text(_block_source(chunk_bytes, ram_cap))
            blk = wd / "imf_fw_block.o"
            _run([tgt.cc, *arch, *_tc.BASE_FLAGS, "-c", str(wd / "imf_fw_block.c"), "-o",
                  str(blk)], wd, "compiling the input block")
        elf = wd / f"imf_fw_{name}.elf"
        # C++ objects link through the C++ driver (its runtime: the unwinder's tables are
        # placed by the linker script, static constructors run by the start-up code)
        cmd = [cxx if any_cxx else tgt.cc, *arch, *(cxx_flags(user) if any_cxx else user),
               *tgt.link_flags]
        if script is not None:
            ld = wd / "imf.ld"
            ld.write_text(script)
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

    probe = link(1, 1, probe=True)
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
    free = tgt.flash - probe.flash_used(tgt.ram_origin) - ram_image - 512
    chunk = min(MAX_CHUNK, free // max(row_bytes, 1))
    if chunk < 1:
        raise TargetError(f"the firmware leaves no flash for inputs on the {target} "
                            f"({tgt.flash} B)")
    elf = link(chunk * row_bytes, ram_image)
    if elf.symbols["__heap_start"][0] - elf.symbols["__data_start"][0] != ram_image:
        raise TargetError("the RAM layout changed between the probe and the program")
    map_text = (wd / "imf_fw.map").read_text(errors="replace")
    lmap = _Map.parse(map_text)
    flash, ram = lmap.of_objects(objs)
    if any(f.startswith("-flto") for f in cflags):
        # link-time optimisation: the image's code comes from ltrans objects; count the symbols
        # the firmware's objects define, as they ended up in the image
        flash = ram = 0
        for sym in _defined(_tool_prefix(tgt), objs, wd):
            if sym in elf.symbols:
                addr, size, _ = elf.symbols[sym]
                if addr >= tgt.ram_origin:
                    ram += size
                else:
                    flash += size
        flash_or_none: Optional[int] = flash or None   # None: inlined across units
    else:
        flash_or_none = flash
    obj = elf.symbols.get("imf_fw_obj")
    if obj:
        ram += obj[1]
    elif getattr(fw, "object_type", None) and adapter is None:
        # a declared C firmware's object lives in the driver
        ram += elf.symbols.get(getattr(fw, "object_name", "fw"), (0, 0, 0))[1]
    # the heap the harness gives a firmware that allocates (ctemplate.BARE_METAL: linked only
    # when something calls malloc, e.g. newlib's assert) is the harness's size, not the
    # firmware's: not counted
    ram -= sum(elf.symbols.get(h, (0, 0, 0))[1] for h in ("imf_fw_heap", "imf_fw_brk"))
    routines, lib_flash = lmap.library(_undefined(_tool_prefix(tgt), objs, wd), objs)
    prog = Program(target, elf.path, wd, objs, list(cflags), types, int(chunk), int(ram_image),
                   row, in_dtype, flash_or_none, ram, routines, lib_flash,
                   time.perf_counter() - t0)
    if entry is not None:
        _store_entry(entry, prog, map_text)
    return prog
