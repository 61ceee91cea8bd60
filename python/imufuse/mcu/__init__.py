"""Emulated-MCU harness: build C for a microcontroller, run it in an emulator, read the state back.

Targets (see ``TARGETS``):

- ``"m4f"``  Cortex-M4F, hard float, ``qemu-system-arm -M mps2-an386`` (semihosting output)
- ``"m0"``   Cortex-M0, soft float, ``qemu-system-arm -M microbit`` (semihosting output)
- ``"avr"``  ATmega328P, ``simavr -m atmega328p -f 16000000`` (UART0 output, Timer1 cycles)
- ``"host"`` the machine's own ``cc``, run as a normal process (the bit-exactness reference)

Every build uses ``-std=c99 -O2 -ffp-contract=off`` and the warning set of ``WARN_FLAGS``.

A program is the generic driver (``data/imf_driver_main.c``) plus a generated header with the
inputs as constant arrays (in flash / PROGMEM) plus the *driver*: file-scope C and three
functions ``imf_user_init()``, ``imf_user_step()`` and ``imf_user_dump()``. ``Driver``
generates them from a few lines::

    drv = Driver(
        prelude='#include "madgwick.h"\\nstatic imf_madgwick_t f;',
        init="imf_madgwick_init(&f, 1.0f / 512.0f, 0.1f);",
        step="imf_madgwick_update(&f, gyr, acc);",     # gyr, acc: the current input rows
        state=state_words("f.q", "f32", 4),
    )
    res = run("m4f", sources=["csrc/madgwick.c"], include_dirs=["csrc"],
              driver=drv, inputs={"gyr": gyr_f32, "acc": acc_f32})
    res.state          # (N, 4) numpy.uint32: bit patterns after every sample

Without ``Driver`` the driver is C text (``driver="..."``) that defines, after the harness's
output helpers are visible::

    #include "madgwick.h"
    static imf_madgwick_t f;
    static void imf_user_init(void) { imf_madgwick_init(&f, 1.0f / 512.0f, 0.1f); }
    static void imf_user_step(void) { imf_madgwick_update(&f, gyr, acc); }
    static void imf_user_dump(void) { imf_out_f32(f.q[0]); imf_out_f32(f.q[1]); /* ... */ }

Dumpers: imf_out_f32/f64/u32/i32/u16/i16/u8/i8. Inputs appear as file-scope variables named
like the inputs, holding the current sample (``float gyr[3]``; ``int16_t rate`` for 1-D).

Output protocol (one line each): ``K <hex>`` empty-call count; per sample
``S <hex word> ... c<hex count>``; ``M <hex stack bytes> <hex painted band>``; ``IMF_END``.
Inputs live in flash (PROGMEM on AVR): the ATmega328P's 32 KB hold about 1000 samples of six
float32 words. Each run ends by itself (semihosting exit; AVR: sleep with interrupts off)
and is killed after ``timeout`` seconds.

``run(..., count=True)`` also measures every ``imf_user_step()``: CPU cycles on ``avr``
(Timer1 at clk/1), instructions on ``m4f``/``m0`` (qemu ``-icount`` and SysTick);
``callgrind_instructions()`` gives instructions per update of a host build.
``code_size()`` and ``stack_usage()`` measure objects built with the same flags.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

__all__ = [
    "TARGETS",
    "WARN_FLAGS",
    "BASE_FLAGS",
    "Target",
    "Driver",
    "Result",
    "HarnessError",
    "ToolchainMissing",
    "state_words",
    "build",
    "run",
    "run_elf",
    "code_size",
    "stack_usage",
    "callgrind_instructions",
    "available",
    "missing_tools",
    "ensure_toolchains",
    "DATA_DIR",
    "INSTALL_SCRIPT",
]

DATA_DIR = Path(__file__).resolve().parent / "data"
# tools/install-toolchains.sh of the source tree (absent in an installed wheel).
INSTALL_SCRIPT = Path(__file__).resolve().parents[3] / "tools" / "install-toolchains.sh"

BASE_FLAGS = ("-std=c99", "-O2", "-ffp-contract=off")
WARN_FLAGS = ("-Wall", "-Wextra", "-pedantic", "-Wdouble-promotion", "-Werror")

# Cycles the AVR Timer1 overflow interrupt adds to a count, per overflow (entry, push/pop,
# 16-bit increment, reti); checked by tests/test_mcu_harness.py against _delay_loop_2.
AVR_OVF_ISR_CYCLES = 40

# qemu -icount shift used for instruction counts on ARM: one instruction takes 2**shift ns of
# virtual time, so one instruction spans many SysTick ticks and rounding is exact.
ICOUNT_SHIFT = 10


class HarnessError(RuntimeError):
    """A build or an emulator run failed; the message holds the command and its output."""


class ToolchainMissing(HarnessError):
    """A compiler or emulator for the target is not installed."""


@dataclasses.dataclass(frozen=True)
class Target:
    name: str
    cc: str
    arch_flags: Tuple[str, ...]
    size_tool: str
    emulator: Optional[str]
    sources: Tuple[str, ...]  # port files from DATA_DIR
    link_flags: Tuple[str, ...] = ()
    machine: Optional[str] = None  # qemu machine
    flash: int = 0  # bytes
    ram: int = 0
    count_unit: str = ""  # what run(count=True) measures
    systick_hz: float = 0.0  # SysTick (processor) clock under qemu

    @property
    def tools(self) -> Tuple[str, ...]:
        t = [self.cc, self.size_tool]
        if self.emulator:
            t.append(self.emulator)
        return tuple(t)


_ARM_LINK = ("-nostartfiles", "-Wl,--gc-sections", "--specs=nano.specs")

TARGETS: Dict[str, Target] = {
    "m4f": Target(
        name="m4f",
        cc="arm-none-eabi-gcc",
        arch_flags=("-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard"),
        size_tool="arm-none-eabi-size",
        emulator="qemu-system-arm",
        sources=("arm_startup.c",),
        link_flags=_ARM_LINK,
        machine="mps2-an386",
        flash=4 << 20,
        ram=4 << 20,
        count_unit="instructions",
        systick_hz=25e6,
    ),
    "m0": Target(
        name="m0",
        cc="arm-none-eabi-gcc",
        arch_flags=("-mcpu=cortex-m0", "-mthumb", "-mfloat-abi=soft"),
        size_tool="arm-none-eabi-size",
        emulator="qemu-system-arm",
        sources=("arm_startup.c",),
        link_flags=_ARM_LINK,
        machine="microbit",
        flash=256 << 10,
        ram=16 << 10,
        count_unit="instructions",
        systick_hz=16e6,
    ),
    "avr": Target(
        name="avr",
        cc="avr-gcc",
        arch_flags=("-mmcu=atmega328p", "-DF_CPU=16000000UL"),
        size_tool="avr-size",
        emulator="simavr",
        sources=("avr_port.c",),
        link_flags=("-Wl,--gc-sections",),
        flash=32 << 10,
        ram=2 << 10,
        count_unit="cycles",
    ),
    "host": Target(
        name="host",
        cc=os.environ.get("CC", "cc"),
        arch_flags=(),
        size_tool="size",
        emulator=None,
        sources=("host_port.c",),
        link_flags=(),
        count_unit="",
    ),
}

_SECTION_FLAGS = ("-ffunction-sections", "-fdata-sections")


# --------------------------------------------------------------------------------------------
# toolchains


def missing_tools(target: str) -> List[str]:
    """Executables the target needs that are not on PATH."""
    tgt = _target(target)
    return [t for t in tgt.tools if shutil.which(t) is None]


def available(target: str) -> bool:
    return not missing_tools(target)


def ensure_toolchains(targets: Iterable[str] = ("m4f", "m0", "avr"), install: bool = True) -> Dict[str, str]:
    """Make the targets' tools available, running tools/install-toolchains.sh if needed.

    Returns {target: reason} for the targets still unavailable (empty when all are there).
    """
    targets = list(targets)
    need = {t: missing_tools(t) for t in targets}
    if any(need.values()) and install:
        if INSTALL_SCRIPT.is_file():
            proc = subprocess.run(["sh", str(INSTALL_SCRIPT)], capture_output=True, text=True)
            if proc.returncode != 0:
                reason = f"install-toolchains.sh failed ({proc.returncode}): {proc.stderr.strip()[-400:]}"
                return {t: reason for t in targets if missing_tools(t)}
        need = {t: missing_tools(t) for t in targets}
    return {t: "missing: " + " ".join(m) for t, m in need.items() if m}


def _target(name: str) -> Target:
    try:
        return TARGETS[name]
    except KeyError:
        raise ValueError(f"unknown target {name!r}; known: {sorted(TARGETS)}") from None


def _require(tgt: Target, tools: Sequence[str]) -> None:
    miss = [t for t in tools if shutil.which(t) is None]
    if miss:
        raise ToolchainMissing(
            f"target {tgt.name!r} needs {' '.join(miss)}; run tools/install-toolchains.sh"
        )


def cflags(target: str, warnings: bool = True) -> List[str]:
    """The full compiler flag list for a target (arch, base, warnings)."""
    tgt = _target(target)
    flags = list(tgt.arch_flags) + list(BASE_FLAGS)
    if warnings:
        flags += list(WARN_FLAGS)
    return flags


# --------------------------------------------------------------------------------------------
# driver


_KINDS = {
    # kind: (dumper, width in bits)
    "f32": ("imf_out_f32", 32),
    "f64": ("imf_out_f64", 64),
    "u32": ("imf_out_u32", 32),
    "i32": ("imf_out_i32", 32),
    "u16": ("imf_out_u16", 32),
    "i16": ("imf_out_i16", 32),
    "u8": ("imf_out_u8", 32),
    "i8": ("imf_out_i8", 32),
}


def state_words(expr: str, kind: str, count: Optional[int] = None) -> List[Tuple[str, str]]:
    """State spec helper: ``state_words("f.q", "f32", 4)`` -> ``[("f.q[0]", "f32"), ...]``."""
    if kind not in _KINDS:
        raise ValueError(f"unknown state kind {kind!r}; known: {sorted(_KINDS)}")
    if count is None:
        return [(expr, kind)]
    return [(f"{expr}[{k}]", kind) for k in range(count)]


@dataclasses.dataclass
class Driver:
    """How one filter plugs into the harness.

    prelude: C at file scope (``#include``s of the filter, its state variable, helpers).
    init:    C statements run once before the first sample.
    step:    C statements for one update. Each input of ``run(inputs=...)`` is visible as a
             file-scope variable of the same name holding the current sample: ``float gyr[3]``
             for a (N, 3) float32 input, ``int16_t rate`` for a (N,) int16 input.
    state:   the state words printed after every sample, as (C lvalue, kind) pairs; kinds
             f32 f64 u32 i32 u16 i16 u8 i8 (narrow integers are widened to 32 bits).
    """

    step: str
    state: Sequence[Tuple[str, str]]
    init: str = ""
    prelude: str = ""

    def __post_init__(self) -> None:
        self.state = [tuple(s) for s in self.state]
        for expr, kind in self.state:
            if kind not in _KINDS:
                raise ValueError(f"state {expr!r}: unknown kind {kind!r}; known: {sorted(_KINDS)}")

    @property
    def names(self) -> List[str]:
        return [e for e, _ in self.state]

    @property
    def kinds(self) -> List[str]:
        return [k for _, k in self.state]

    def c_source(self) -> str:
        dump = "\n".join(f"    {_KINDS[k][0]}({e});" for e, k in self.state)
        return (
            "/* Generated by imufuse.mcu.Driver. */\n"
            f"{self.prelude}\n\n"
            "static void imf_user_init(void)\n{\n"
            f"{_indent(self.init)}\n}}\n\n"
            "static void imf_user_step(void)\n{\n"
            f"{_indent(self.step)}\n}}\n\n"
            "static void imf_user_dump(void)\n{\n"
            f"{dump}\n}}\n"
        )


def _indent(text: str) -> str:
    lines = [ln for ln in text.strip("\n").splitlines()]
    return "\n".join(("    " + ln) if ln.strip() else "" for ln in lines) if lines else "    ;"


# --------------------------------------------------------------------------------------------
# inputs


_INPUT_TYPES = {
    # numpy dtype: (C type, storage type, storage bits, formatter)
    np.dtype(np.float32): ("float", "uint32_t", 32),
    np.dtype(np.float64): ("double", "uint64_t", 64),
    np.dtype(np.int32): ("int32_t", "uint32_t", 32),
    np.dtype(np.uint32): ("uint32_t", "uint32_t", 32),
    np.dtype(np.int16): ("int16_t", "uint16_t", 16),
    np.dtype(np.uint16): ("uint16_t", "uint16_t", 16),
}

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def _inputs_header(inputs: Mapping[str, np.ndarray], target: str, n: Optional[int]) -> Tuple[str, int]:
    arrays = {}
    for name, a in inputs.items():
        if not _IDENT.match(name) or name.startswith("imf_"):
            raise ValueError(f"input name {name!r} must be a C identifier not starting with imf_")
        a = np.asarray(a)
        if a.dtype not in _INPUT_TYPES:
            raise ValueError(
                f"input {name!r}: dtype {a.dtype} not supported; use one of "
                f"{sorted(str(d) for d in _INPUT_TYPES)}"
            )
        if a.ndim not in (1, 2):
            raise ValueError(f"input {name!r}: shape {a.shape}; expected (N,) or (N, k)")
        if a.dtype == np.float64 and target == "avr":
            raise ValueError(f"input {name!r}: float64 is not available on avr (double is 32-bit)")
        arrays[name] = a
    lengths = {name: a.shape[0] for name, a in arrays.items()}
    if n is None:
        if not lengths:
            raise ValueError("no inputs: pass n= for the number of steps")
        n = next(iter(lengths.values()))
    if any(v != n for v in lengths.values()):
        raise ValueError(f"inputs differ in length: {lengths} (n={n})")
    if n < 1:
        raise ValueError("need at least one sample")
    flash = TARGETS[target].flash
    total = sum(a.nbytes for a in arrays.values())
    if flash and total > flash - 4096:
        raise ValueError(
            f"{target}: the inputs take {total} bytes of {flash} bytes flash (the program needs a few "
            "KB more); pass fewer samples or int16 inputs"
        )

    out = [
        "/* Generated by imufuse.mcu: input samples. */",
        "#ifndef IMF_INPUTS_H",
        "#define IMF_INPUTS_H",
        "#include <stdint.h>",
        "#include <string.h>",
        f"#define IMF_N {n}u",
        "#if defined(__AVR__)",
        "#include <avr/pgmspace.h>",
        "#define IMF_FLASH PROGMEM",
        "#define IMF_RD16(p) pgm_read_word(p)",
        "#define IMF_RD32(p) pgm_read_dword(p)",
        "#define IMF_HAVE_F64 0",
        "#else",
        "#define IMF_FLASH",
        "#define IMF_RD16(p) (*(p))",
        "#define IMF_RD32(p) (*(p))",
        "#define IMF_HAVE_F64 1",
        "#endif",
        "",
    ]
    loads = []
    for name, a in arrays.items():
        ctype, stype, bits = _INPUT_TYPES[a.dtype]
        k = 1 if a.ndim == 1 else a.shape[1]
        flat = np.ascontiguousarray(a).reshape(-1)
        raw = flat.view({16: np.uint16, 32: np.uint32, 64: np.uint64}[bits])
        width = bits // 4
        suffix = {16: "u", 32: "ul", 64: "ull"}[bits]
        body = []
        per_line = max(1, 96 // (width + 6))
        for s in range(0, raw.size, per_line):
            body.append("    " + ", ".join(f"0x{int(v):0{width}x}{suffix}" for v in raw[s : s + per_line]) + ",")
        out.append(f"static const {stype} imf_in_{name}[{raw.size}] IMF_FLASH = {{")
        out.extend(body)
        out.append("};")
        if a.ndim == 1:
            out.append(f"static {ctype} {name};")
            dst = f"&{name}"
        else:
            out.append(f"static {ctype} {name}[{k}];")
            dst = f"&{name}[j]"
        out.append("")
        if bits == 64:
            rd = f"imf_in_{name}[i * {k}u + j]"
        elif bits == 32:
            rd = f"IMF_RD32(&imf_in_{name}[i * {k}u + j])"
        else:
            rd = f"IMF_RD16(&imf_in_{name}[i * {k}u + j])"
        if a.ndim == 1:
            loads.append(f"    {{ const uint32_t j = 0u; {stype} b = {rd}; memcpy({dst}, &b, sizeof b); }}")
        else:
            loads.append(
                f"    for (j = 0u; j < {k}u; ++j) {{ {stype} b = {rd}; memcpy({dst}, &b, sizeof b); }}"
            )
    out.append("static void imf_load_row(uint32_t i)\n{")
    out.append("    uint32_t j;")
    out.extend(loads)
    out.append("    (void)i;\n    (void)j;\n}")
    out.append("#endif\n")
    return "\n".join(out), n


# --------------------------------------------------------------------------------------------
# build


def _run_cmd(cmd: Sequence[str], cwd: Optional[Path] = None, timeout: float = 300) -> subprocess.CompletedProcess:
    try:
        proc = subprocess.run(list(cmd), cwd=cwd, capture_output=True, text=True, timeout=timeout)
    except FileNotFoundError as e:
        raise ToolchainMissing(f"{cmd[0]} not found; run tools/install-toolchains.sh") from e
    if proc.returncode != 0:
        raise HarnessError(
            f"command failed ({proc.returncode}): {' '.join(map(str, cmd))}\n{proc.stdout}{proc.stderr}"
        )
    return proc


def _as_paths(xs: Optional[Iterable[Union[str, os.PathLike]]]) -> List[Path]:
    return [Path(x).resolve() for x in (xs or [])]


def _define_flags(defines: Optional[Mapping[str, object]]) -> List[str]:
    out = []
    for k, v in (defines or {}).items():
        out.append(f"-D{k}" if v is None or v is True else f"-D{k}={v}")
    return out


def _compile(
    tgt: Target,
    src: Path,
    obj: Path,
    include_dirs: Sequence[Path],
    defines: Sequence[str],
    extra: Sequence[str] = (),
) -> None:
    cmd = [tgt.cc, *cflags(tgt.name), *_SECTION_FLAGS, *extra, *defines]
    cmd += [f"-I{d}" for d in include_dirs]
    cmd += ["-c", str(src), "-o", str(obj)]
    _run_cmd(cmd, cwd=obj.parent)


def build(
    target: str,
    sources: Sequence[Union[str, os.PathLike]] = (),
    include_dirs: Sequence[Union[str, os.PathLike]] = (),
    defines: Optional[Mapping[str, object]] = None,
    driver: Union[Driver, str, None] = None,
    inputs: Optional[Mapping[str, np.ndarray]] = None,
    n: Optional[int] = None,
    workdir: Union[str, os.PathLike, None] = None,
    extra_cflags: Sequence[str] = (),
) -> Path:
    """Build the driver program for ``target``; returns the path of the ELF (host: executable).

    sources: the C files under test (compiled with the harness flags, e.g. csrc/madgwick.c).
    driver:  a ``Driver`` or C source text defining imf_user_init/step/dump.
    inputs:  {name: array}; see ``Driver`` for how they appear in C.
    workdir: where objects, .su files and the ELF go (default: a new temporary directory).
    """
    tgt = _target(target)
    _require(tgt, [tgt.cc])
    if driver is None:
        raise ValueError("driver is required (a Driver or C source text)")
    wd = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix=f"imf_mcu_{target}_"))
    wd.mkdir(parents=True, exist_ok=True)
    header, n = _inputs_header(inputs or {}, target, n)
    (wd / "imf_inputs.h").write_text(header)
    drv_src = driver.c_source() if isinstance(driver, Driver) else str(driver)
    (wd / "imf_driver.h").write_text(drv_src)
    incs = [wd, DATA_DIR, *_as_paths(include_dirs)]
    defs = _define_flags(defines)

    objs: List[Path] = []
    for i, src in enumerate(_as_paths(sources)):
        obj = wd / f"u{i}_{src.stem}.o"
        _compile(tgt, src, obj, incs, defs, ["-fstack-usage", *extra_cflags])
        objs.append(obj)
    for name in (*tgt.sources, "imf_driver_main.c"):
        obj = wd / f"h_{Path(name).stem}.o"
        _compile(tgt, DATA_DIR / name, obj, incs, defs, ["-fstack-usage", *extra_cflags])
        objs.append(obj)

    elf = wd / f"imf_{target}.elf"
    cmd = [tgt.cc, *tgt.arch_flags, *tgt.link_flags]
    if tgt.machine is not None:
        ld = wd / "imf.ld"
        ld.write_text(
            (DATA_DIR / "arm.ld.in")
            .read_text()
            .replace("@FLASH_LEN@", str(tgt.flash))
            .replace("@RAM_LEN@", str(tgt.ram))
        )
        cmd += [f"-T{ld}"]
    cmd += [str(o) for o in objs] + ["-o", str(elf), "-lm"]
    try:
        _run_cmd(cmd, cwd=wd)
    except HarnessError as e:
        if "overflowed" in str(e) or "will not fit" in str(e):
            raise HarnessError(
                f"{e}\n{target}: the program does not fit ({tgt.flash} bytes flash, {tgt.ram} bytes "
                "RAM); inputs are stored in flash: pass fewer samples (or int16 inputs)"
            ) from None
        raise
    return elf


# --------------------------------------------------------------------------------------------
# run


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
    if tgt.emulator == "simavr":
        return ["simavr", "-m", "atmega328p", "-f", "16000000", str(elf)]
    raise AssertionError(tgt.emulator)


def _simavr_text(out: str) -> str:
    # simavr prints UART0 lines with ANSI colour codes; other lines are its own messages.
    # A UART line ends in "." where the newline was.
    out = re.sub(r"\x1b\[[0-9;]*m", "", out)
    return "\n".join(ln[:-1] if ln.endswith(".") else ln for ln in out.splitlines())


def _to_counts(tgt: Target, raw: np.ndarray, overhead: int) -> np.ndarray:
    if tgt.name == "avr":
        def fix(c):
            c = np.asarray(c, dtype=np.int64)
            return c - (c >> 16) * AVR_OVF_ISR_CYCLES
        return fix(raw) - int(fix(overhead))
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
        out = e.stdout or b""
        out = out.decode(errors="replace") if isinstance(out, bytes) else out
        raise HarnessError(f"{target}: timeout after {timeout} s: {' '.join(cmd)}\n{out[-2000:]}") from None
    seconds = time.perf_counter() - t0
    text = proc.stdout
    if tgt.emulator == "simavr":
        text = _simavr_text(text)
    if proc.returncode != 0 or "IMF_FAULT" in text:
        raise HarnessError(f"{target}: exit status {proc.returncode}: {' '.join(cmd)}\n{text[-3000:]}")
    state, raw, overhead, stack, window = _parse(text, n)
    if stack is not None and stack >= window:
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
    wd = Path(tempfile.mkdtemp(prefix=f"imf_mcu_{target}_")) if own else Path(workdir)
    try:
        if n is None and inputs:
            n = len(np.asarray(next(iter(inputs.values()))))
        elf = build(target, sources, include_dirs, defines, driver, inputs, n, wd)
        return run_elf(target, elf, n if n is not None else 0, count=count, timeout=timeout, driver=driver)
    finally:
        if own:
            shutil.rmtree(wd, ignore_errors=True)


# --------------------------------------------------------------------------------------------
# measurements


def code_size(
    target: str,
    sources: Sequence[Union[str, os.PathLike]],
    include_dirs: Sequence[Union[str, os.PathLike]] = (),
    defines: Optional[Mapping[str, object]] = None,
    workdir: Union[str, os.PathLike, None] = None,
) -> Dict[str, Dict[str, int]]:
    """text/data/bss bytes of each source's object (keys: file names) and ``"total"``.

    Built with the harness flags plus -ffunction-sections; library calls (soft float, sqrtf)
    are not included: they are linked from libgcc/libm.
    """
    tgt = _target(target)
    _require(tgt, [tgt.cc, tgt.size_tool])
    own = workdir is None
    wd = Path(tempfile.mkdtemp(prefix=f"imf_size_{target}_")) if own else Path(workdir)
    wd.mkdir(parents=True, exist_ok=True)
    try:
        objs = []
        for i, src in enumerate(_as_paths(sources)):
            obj = wd / f"s{i}_{src.stem}.o"
            _compile(tgt, src, obj, _as_paths(include_dirs), _define_flags(defines))
            objs.append((src.name, obj))
        out = _run_cmd([tgt.size_tool, "-B", *[str(o) for _, o in objs]]).stdout
        result: Dict[str, Dict[str, int]] = {}
        total = {"text": 0, "data": 0, "bss": 0}
        lines = [ln.split() for ln in out.strip().splitlines()[1:]]
        for (name, _), cols in zip(objs, lines):
            d = {"text": int(cols[0]), "data": int(cols[1]), "bss": int(cols[2])}
            result[name] = d
            for k in total:
                total[k] += d[k]
        result["total"] = total
        return result
    finally:
        if own:
            shutil.rmtree(wd, ignore_errors=True)


def stack_usage(
    target: str,
    sources: Sequence[Union[str, os.PathLike]],
    include_dirs: Sequence[Union[str, os.PathLike]] = (),
    defines: Optional[Mapping[str, object]] = None,
    workdir: Union[str, os.PathLike, None] = None,
) -> Dict[str, Dict[str, object]]:
    """Static stack use per function from -fstack-usage: {function: {"bytes": n, "kind": q}}.

    kind is GCC's qualifier ("static", "dynamic", "dynamic,bounded"). Callees are not added:
    the figure is each function's own frame.
    """
    tgt = _target(target)
    _require(tgt, [tgt.cc])
    own = workdir is None
    wd = Path(tempfile.mkdtemp(prefix=f"imf_stack_{target}_")) if own else Path(workdir)
    wd.mkdir(parents=True, exist_ok=True)
    try:
        result: Dict[str, Dict[str, object]] = {}
        for i, src in enumerate(_as_paths(sources)):
            obj = wd / f"k{i}_{src.stem}.o"
            _compile(tgt, src, obj, _as_paths(include_dirs), _define_flags(defines), ["-fstack-usage"])
            for line in obj.with_suffix(".su").read_text().splitlines():
                parts = line.split("\t")
                if len(parts) != 3:
                    continue
                func = parts[0].rsplit(":", 1)[-1]
                result[func] = {"bytes": int(parts[1]), "kind": parts[2], "file": src.name}
        return result
    finally:
        if own:
            shutil.rmtree(wd, ignore_errors=True)


def callgrind_instructions(
    sources: Sequence[Union[str, os.PathLike]] = (),
    include_dirs: Sequence[Union[str, os.PathLike]] = (),
    defines: Optional[Mapping[str, object]] = None,
    driver: Union[Driver, str, None] = None,
    inputs: Optional[Mapping[str, np.ndarray]] = None,
    n: Optional[int] = None,
    workdir: Union[str, os.PathLike, None] = None,
    timeout: float = 300.0,
) -> Dict[str, float]:
    """Host instructions per update: the host build under valgrind --tool=callgrind.

    Counts the instructions executed inside the driver's step wrapper (imf_step, the
    user's step and everything it calls), for all samples. Returns
    {"total": Ir, "samples": N, "per_update": Ir / N}.
    """
    if shutil.which("valgrind") is None:
        raise ToolchainMissing("valgrind not found; run tools/install-toolchains.sh")
    own = workdir is None
    wd = Path(tempfile.mkdtemp(prefix="imf_cg_")) if own else Path(workdir)
    try:
        if n is None and inputs:
            n = len(np.asarray(next(iter(inputs.values()))))
        # -fno-inline-functions-called-once keeps imf_step a separate function to toggle on.
        exe = build("host", sources, include_dirs, defines, driver, inputs, n, wd)
        outfile = wd / "callgrind.out"
        cmd = [
            "valgrind", "--tool=callgrind", f"--callgrind-out-file={outfile}",
            "--collect-atstart=no", "--toggle-collect=imf_step", str(exe),
        ]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=wd)
        if proc.returncode != 0:
            raise HarnessError(f"callgrind failed: {proc.stderr[-2000:]}")
        total = None
        for line in outfile.read_text().splitlines():
            if line.startswith("totals:") or line.startswith("summary:"):
                total = int(line.split()[1])
        if total is None:
            raise HarnessError("callgrind output has no totals")
        return {"total": total, "samples": int(n or 0), "per_update": total / float(n or 1)}
    finally:
        if own:
            shutil.rmtree(wd, ignore_errors=True)
