"""Why a firmware run differs from imufuse, and by how much.

``find_causes`` looks at what a build produced (the disassembly of the objects, the flags,
the -Wdouble-promotion warnings of the sources) for what changes float results: fused
multiply-add, double arithmetic in a float32 build, fast-math, AVR's 32-bit double; each
``Cause`` names its fix, which imufuse.firmware.validate confirms by rebuilding.
On the host validate also looks at the source (imufuse.firmware.diagnostics,
imufuse.firmware.sanitize): undefined behaviour, the data model, a changed constant, the
compiler's warnings; ``ordered`` puts the causes in the report's order.
``angle_divergence_deg`` is the largest orientation difference over the run.
"""
from __future__ import annotations

import dataclasses
import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from ..catalogue import entry
from ..shared.estimate import ADAPTERS

__all__ = ["Cause", "find_causes", "double_promotions", "angle_divergence_deg", "ordered",
           "BUILD"]

#: the causes found in what was built, confirmed by rebuilding with a flag
BUILD = ("fma", "double", "fast-math", "avr-double", "together")
_NAMES = {"fma": "fused multiply-add (a*b+c contracted into one rounding)",
          "double": "double-precision arithmetic in a float32 build",
          "fast-math": "fast-math optimisation (reassociation, reciprocals)",
          "avr-double": "double is 32 bits on the ATmega328P",
          "undefined behaviour": "undefined behaviour",
          "data model": "data model (type sizes differ between host and targets)",
          "constant": "a constant differs from the filter's parameter"}


@dataclasses.dataclass
class Cause:
    """A likely cause of a divergence found in what was built or in the source.

    what: "fma", "double", "fast-math", "avr-double", "together" (found in the build; fix is
    the flag that removes it, confirmed by rebuilding with it); "undefined behaviour" (a
    UBSan/ASan report), "data model" (the source depends on the width of long, int or
    double), "constant" (a literal near a parameter's value), "warning" (a compiler warning).
    For these `advice` is the change to make in the source, and `fix` is set to it only when
    the cause is established (confirmed by the sanitizer run or by rebuilding the changed
    source, at or before the first divergent sample)."""
    what: str
    evidence: str             # what was seen (instructions, calls, flags, warnings, reports)
    fix: Optional[str]        # the flag that removes it (see above for the source causes)
    confirmed: Optional[bool] = None   # rebuilt with the fix: bit-exact (True) or not (False)
    where: Optional[str] = None        # file:line[:col] in the user's source
    sample: Optional[int] = None       # the sample it happened at (None: init, or not known)
    advice: Optional[str] = None       # the change to make in the source
    detail: Optional[str] = None       # a sub-kind: the sanitizer's check, the warning's flag

    def text(self) -> str:
        if self.what == "together":
            return (f"together: rebuilt with {self.fix}, the firmware is bit-exact" if self.confirmed
                    else f"together: rebuilt with {self.fix}, still not bit-exact")
        if self.what == "warning":
            return f"compiler warning {self.where}: {self.evidence} [{self.detail}]"
        if self.what not in BUILD:
            return self._source_text()
        s = f"cause: {_NAMES[self.what]}: {self.evidence}"
        if self.fix:
            s += f"\n  fix: add {self.fix}"
            if self.confirmed is True:
                s += f" (confirmed: rebuilt with {self.fix}, the firmware is bit-exact)"
            elif self.confirmed is False:
                s += f" (rebuilt with {self.fix}: still not bit-exact, so not the only cause)"
        return s

    def _source_text(self) -> str:
        name = _NAMES.get(self.what, self.what)
        if self.what == "undefined behaviour" and self.detail:
            name += f" ({self.detail})"
        at = f" at {self.where}" if self.where else ""
        if self.what == "undefined behaviour":
            at += f", sample {self.sample}" if self.sample is not None else ", during init"
        s = f"cause: {name}{at}: {self.evidence}"
        if self.advice:
            s += f"\n  fix: {self.advice}"
        return s


def ordered(causes: Sequence[Cause]) -> List[Cause]:
    """The report's order: causes confirmed by rebuilding first, then undefined behaviour,
    the data model, a changed constant, the build causes not confirmed, compiler warnings."""
    together = any(c.what == "together" and c.confirmed for c in causes)

    def rank(c: Cause) -> int:
        if c.what in BUILD or c.what == "constant":
            if c.confirmed or (together and c.what in BUILD and c.fix):
                return 0
            return 3 if c.what == "constant" else 4
        return {"undefined behaviour": 1, "data model": 2}.get(c.what, 5)
    return sorted(causes, key=rank)


_FAST = ("-ffast-math", "-Ofast", "-freciprocal-math", "-funsafe-math-optimizations",
         "-fassociative-math")
_FMA_ARM = re.compile(r"\bv?fn?m[as]\.f(?:32|64)\b|\bvfnm[as]\b")
_FMA_X86 = re.compile(r"\bv?fn?m(?:add|sub)\d{3}[sp][sd]\b")
_FMA_RISCV = re.compile(r"\bfn?m(?:add|sub)\.[sdh]\b")
_DOUBLE_INSNS = re.compile(r"\bcvtss2sd\b|\b\w+sd\s+%xmm|\bv(?:add|sub|mul|div|sqrt|fm[as]|"
                           r"fnm[as]|neg|abs|mla|mls|cvt)\.f64\b|\bvcvt\.f64\.f32\b|"
                           r"\bf(?:add|sub|mul|div|sqrt|n?madd|n?msub)\.d\b|\bfcvt\.d\.s\b")
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
    fma = sorted(set(_FMA_ARM.findall(asm) + _FMA_X86.findall(asm) + _FMA_RISCV.findall(asm)))
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
        # double in hardware: x86 SSE, the Cortex-M7/M55's fpv5-d16 (.f64), RISC-V D (.d)
        x86 = _DOUBLE_INSNS.findall(asm) if not calls else []
        warn = double_promotions(compile_cmd, sources, cwd)
        if calls or x86 or warn:
            found: List[str] = []
            if calls:
                found.append(f"double routines called: {', '.join(calls)}")
            if x86:
                names = sorted({x.split()[0] for x in x86})
                found.append(f"{len(x86)} double-precision instruction(s) ({', '.join(names)})")
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


def quaternion_angles_deg(a: Any, b: Any) -> np.ndarray:
    """The angle between two runs' quaternions (w, x, y, z; each normalised) after every
    sample, degrees; 180 where either is not a number."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    with np.errstate(all="ignore"):
        d = np.abs(np.sum(a * b, axis=1)) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        ang = 2.0 * np.degrees(np.arccos(np.clip(d, 0.0, 1.0)))
    return np.where(np.isnan(ang), 180.0, ang)
