"""What the compiler and the source say about a host divergence (``explain_source``, called by
imufuse.firmware.validate when the firmware is not bit-exact on the host).

- the code that ran up to the first divergent sample (the firmware built with gcov);
- the compiler's warnings on the user's files (-Wall -Wextra -Wstrict-aliasing=2
  -Wdouble-promotion -Wconversion ...), those in code that ran first, the most relevant first;
- undefined behaviour, from a run under UBSan and ASan (imufuse.firmware.sanitize);
- the data model: the source depends on the width of long (64 bits on the x86-64 host, 32 on
  ARM and AVR), of int (16 bits on AVR) or of double (32 bits on AVR);
- a changed constant: a literal near one of the filter's parameters, confirmed by rebuilding
  with the parameter's value in its place.
(Whether the first difference is rounding-level or a formula's is imufuse.firmware.report's.)
Each becomes a ``Cause`` (imufuse.firmware.causes) or a note of the Validation.
"""
from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .causes import Cause, ordered
from .sanitize import RunInputs, build_program, run_program, sanitize

__all__ = ["WARNING_FLAGS", "Diagnostic", "compiler_warnings", "RunPath", "run_path",
           "data_model", "constants", "explain_source"]

WARNING_FLAGS = ("-Wall", "-Wextra", "-Wstrict-aliasing=2", "-Wdouble-promotion", "-Wconversion",
                 "-Wfloat-conversion", "-fdiagnostics-format=text", "-fno-diagnostics-show-caret")
#: the warnings that most often change what a float filter computes, first
_PRIORITY = [("-Wstrict-aliasing", "-Warray-bounds", "-Wstringop-overread"),
             ("-Wdouble-promotion",), ("-Wfloat-conversion",),
             ("-Wuninitialized", "-Wmaybe-uninitialized", "-Woverflow", "-Wshift-count-overflow",
              "-Wshift-negative-value", "-Wsequence-point", "-Wconversion")]
MAX_WARNINGS = 8
#: constants near a parameter confirmed by rebuilding (one validation each)
MAX_CONSTANTS = 2
_WARN = re.compile(r"^(.*?):(\d+):(\d+): warning: (.*) \[(-W[^\]]+?)=?\]$")


def _users(files: Sequence[str]) -> set:
    return {os.path.realpath(f) for f in files}


@dataclasses.dataclass(frozen=True)
class Diagnostic:
    path: str
    line: int
    col: int
    flag: str
    message: str

    @property
    def where(self) -> str:
        return f"{os.path.basename(self.path)}:{self.line}:{self.col}"

    @property
    def rank(self) -> int:
        return next((i for i, g in enumerate(_PRIORITY) if self.flag in g), len(_PRIORITY))


def compiler_warnings(cmd: Sequence[str], sources: Sequence[str], wd: Path,
                      user_files: Sequence[str]) -> List[Diagnostic]:
    """The warnings of compiling each source with `cmd` (the user's compiler, flags, defines
    and include directories) and WARNING_FLAGS, in the user's files only, each once."""
    users, seen, out = _users(user_files), set(), []
    for i, src in enumerate(sources):
        try:
            p = subprocess.run([*cmd, *WARNING_FLAGS, "-c", src, "-o", str(wd / f"w{i}.o")],
                               cwd=wd, capture_output=True, text=True, timeout=120)
        except (OSError, subprocess.SubprocessError):
            continue
        for ln in p.stderr.splitlines():
            m = _WARN.match(ln)
            if not m:
                continue
            path = os.path.realpath(os.path.join(wd, m.group(1)))
            d = Diagnostic(path, int(m.group(2)), int(m.group(3)), m.group(5), m.group(4))
            if path in users and (d.path, d.line, d.col, d.flag) not in seen:
                seen.add((d.path, d.line, d.col, d.flag))
                out.append(d)
    return out


@dataclasses.dataclass
class RunPath:
    """The user's functions and lines run up to and including sample `n - 1` (gcov)."""
    n: int
    functions: List[Tuple[str, str, int, int, int]]   # path, name, first line, last, calls
    lines: Dict[str, Dict[int, int]]                   # path -> line -> count

    def on_path(self, path: str, line: int) -> Optional[bool]:
        """True: in a function that ran; False: in one that did not; None: outside any."""
        for p, _, a, b, count in self.functions:
            if p == path and a <= line <= b:
                return count > 0
        return None

    def text(self) -> str:
        ran = [f for f in self.functions if f[4] > 0]
        parts = [f"{f[1]} ({os.path.basename(f[0])}:{f[2]}-{f[3]})" for f in ran[:8]]
        more = f" and {len(ran) - 8} more" if len(ran) > 8 else ""
        return (f"the firmware's code run up to the first divergence (samples 0-{self.n - 1}, "
                f"gcov): {', '.join(parts) or 'none of its functions'}{more}")


def run_path(fw: Any, run: RunInputs, wd: Path, n: int, timeout: float = 60.0) -> Optional[RunPath]:
    """Build the firmware with gcov and run the first n samples: what ran (None when the
    compiler or gcov cannot tell)."""
    gcov = shutil.which("gcov")
    if gcov is None:
        return None
    d = wd / "cov"
    exe, _ = build_program(fw, run, d, ("--coverage", "-O0", "-g"), "fw_cov")
    if exe is None:
        return None
    code, _, _ = run_program(exe, run, d, n, timeout=timeout)
    if code != 0:
        return None
    users = _users(fw.sources) | _users(_headers(fw))
    path = RunPath(n, [], {})
    for gcda in sorted(d.glob("*.gcda")):
        try:
            p = subprocess.run([gcov, "-j", "-t", str(gcda)], cwd=d, capture_output=True,
                               text=True, timeout=60)
            docs = [json.loads(ln) for ln in p.stdout.splitlines() if ln.strip()]
        except (OSError, subprocess.SubprocessError, ValueError):
            return None
        for doc in docs:
            for f in doc.get("files", []):
                fp = os.path.realpath(os.path.join(doc.get("current_working_directory", ""),
                                                   f["file"]))
                if fp not in users:
                    continue
                for fn in f.get("functions", []):
                    name = fn.get("demangled_name") or fn["name"]
                    path.functions.append((fp, name, fn["start_line"], fn["end_line"],
                                           fn["execution_count"]))
                lines = path.lines.setdefault(fp, {})
                for ln in f.get("lines", []):
                    lines[ln["line_number"]] = lines.get(ln["line_number"], 0) + ln["count"]
    path.functions.sort(key=lambda f: (f[0], f[2]))
    return path if path.functions else None


def _headers(fw: Any) -> List[str]:
    out = []
    for d in {*fw.include_dirs, *(os.path.dirname(s) for s in fw.sources)}:
        try:
            out += [os.path.join(d, f) for f in os.listdir(d) if f.endswith((".h", ".c", ".inc"))]
        except OSError:
            pass
    return out


def warning_causes(diags: Sequence[Diagnostic], path: Optional[RunPath]
                   ) -> Tuple[List[Cause], List[str]]:
    """The warnings in code that ran up to the first divergence (or at file scope; all of
    them without a RunPath) as Causes, the most relevant first, up to MAX_WARNINGS; a note
    counts the rest."""
    def key(d: Diagnostic):
        return (d.rank, d.path, d.line, d.col)
    off = [d for d in diags if path is not None and path.on_path(d.path, d.line) is False]
    on = sorted((d for d in diags if d not in off), key=key)
    shown = on[:MAX_WARNINGS]
    causes = [Cause("warning", d.message, None, where=d.where, detail=d.flag) for d in shown]
    rest = on[MAX_WARNINGS:] + off
    if not rest:
        return causes, []
    flags: Dict[str, int] = {}
    for d in rest:
        flags[d.flag] = flags.get(d.flag, 0) + 1
    where = f", {len(off)} of them in code not run before the first divergence" if off else ""
    return causes, [f"{len(rest)} more compiler warning(s) not shown{where}: " +
                    ", ".join(f"{f} x{c}" for f, c in sorted(flags.items(), key=lambda t: -t[1]))]


# ---------------------------------------------------------------------------
# the data model, from the preprocessed source

_LONG = r"(?:unsigned\s+|signed\s+)?long(?:\s+int)?(?!\s+long)"
_LONG_PTR = re.compile(r"\(\s*(?:const\s+|volatile\s+)*" + _LONG + r"\s*(?:const\s*)?\*\s*\)")
_SIZEOF_LONG = re.compile(r"sizeof\s*\(\s*" + _LONG + r"\s*\)")
_MAGIC = re.compile(r"0x5f3759df|0x5f375a86|0x5F3759DF", re.I)
_INT_DECL = re.compile(r"\b(?:(?:unsigned\s+|signed\s+)?(?:int|short)|unsigned(?!\s+(?:long|char)))\b")
_INT_LIT = re.compile(r"(?<![\w.])(0[xX][0-9a-fA-F]+|\d+)([uU]?)(?![\w.])")
_DOUBLE_DECL = re.compile(r"\bdouble\s+\**\s*[A-Za-z_]\w*\s*[=;,\[)]")


def _preprocessed(cmd: Sequence[str], src: str, wd: Path) -> List[Tuple[str, int, str]]:
    """(file, line, text) of every line of the source after the preprocessor."""
    try:
        p = subprocess.run([*cmd, "-E", src], cwd=wd, capture_output=True, text=True,
                           timeout=120)
    except (OSError, subprocess.SubprocessError):
        return []
    out, cur, line = [], src, 1
    for ln in p.stdout.splitlines():
        m = re.match(r'^#\s*(\d+)\s+"((?:[^"\\]|\\.)*)"', ln)
        if m:
            line, cur = int(m.group(1)), os.path.realpath(os.path.join(wd, m.group(2)))
            continue
        out.append((cur, line, ln))
        line += 1
    return out


def data_model(preprocessed: Sequence[Sequence[Tuple[str, int, str]]],
               user_files: Sequence[str]) -> List[Cause]:
    """Where the user's preprocessed sources (_preprocessed of each) depend on the width of
    long, int or double."""
    users, seen, out = _users(user_files), set(), []
    doubles: Dict[str, List[int]] = {}
    for pre in preprocessed:
        for n, (path, line, text) in enumerate(pre):
            if path not in users or not text.strip() or (path, line) in seen:
                continue
            seen.add((path, line))
            where = f"{os.path.basename(path)}:{line}"
            code = text.strip()
            if _LONG_PTR.search(text):
                near = " ".join(t for p2, _, t in pre[n:n + 4] if p2 == path)
                magic = " (the fast inverse square root: its magic 0x5f3759df is for 32 bits)" \
                    if _MAGIC.search(near) else ""
                out.append(Cause("data model", f"`{code}`: a pointer cast to long *{magic}: long "
                                 "is 8 bytes on the x86-64 host, 4 on ARM and AVR, so a float "
                                 "(4 bytes) read through it takes 4 more bytes here",
                                 None, where=where, detail="long",
                                 advice="use int32_t/uint32_t (stdint.h) and memcpy for a "
                                        "float's bits: the same width on every target"))
            if _SIZEOF_LONG.search(text):
                out.append(Cause("data model", f"`{code}`: sizeof(long) is 8 on the x86-64 "
                                 "host, 4 on ARM and AVR", None, where=where, detail="long",
                                 advice="use the fixed-width types of stdint.h"))
            big = [v for v in (int(t[0], 0) for t in _INT_LIT.findall(text)) if v > 32767]
            if big and _INT_DECL.search(text) and "long" not in text:
                out.append(Cause("data model", f"`{code}`: int with a value beyond 16 bits "
                                 f"({big[0]}): int is 32 bits here and on ARM, 16 on the "
                                 "ATmega328P", None, where=where, detail="int",
                                 advice="use int32_t (or long) for values beyond 32767"))
            if _DOUBLE_DECL.search(text):
                doubles.setdefault(path, []).append(line)
    for path, lines in doubles.items():
        more = f" (and {len(lines) - 1} more line(s))" if len(lines) > 1 else ""
        out.append(Cause("data model", f"double variables{more}: double is 64 bits here, on "
                         "the Cortex-M and on RISC-V (in hardware on the M7 and M55, in software "
                         "on the others: the M4F's, M33's and RV32F's FPUs are single "
                         "precision), 32 bits on the ATmega328P (avr-gcc)", None,
                         where=f"{os.path.basename(path)}:{lines[0]}", detail="double",
                         advice="use float where float32 is meant; where double is meant, "
                                "validate on each target"))
    return out


# ---------------------------------------------------------------------------
# constants near a parameter's value

_FLOAT_LIT = re.compile(r"(?<![\w.])((?:\d+\.\d*|\.\d+)(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+)([fFlL]?)"
                        r"(?![\w.])")


def _code_lines(text: str) -> List[str]:
    """The lines of a C file with comments, strings and preprocessor conditionals' text
    blanked (columns kept)."""
    def blank(m):
        return re.sub(r"[^\n]", " ", m.group(0))
    text = re.sub(r"/\*.*?\*/|//[^\n]*|\"(?:\\.|[^\"\\\n])*\"|'(?:\\.|[^'\\\n])*'", blank, text,
                  flags=re.S)
    return text.splitlines()


@dataclasses.dataclass
class Constant:
    path: str
    line: int
    col: int                 # 1-based
    literal: str
    name: str                # "k0" or "1 - k0"
    value: float             # the parameter's value in the firmware's precision
    replacement: str

    @property
    def where(self) -> str:
        return f"{os.path.basename(self.path)}:{self.line}:{self.col}"

    @property
    def shown(self) -> str:
        return self.replacement.rstrip("f") + (" (float32)" if self.replacement.endswith("f")
                                               else "")


def constants(files: Sequence[str], params: Mapping[str, Any], dtype: str,
              rel: float = 0.05) -> List[Constant]:
    """Float literals within `rel` of a parameter p, or within rel * p of 1 - p (0 < p < 1,
    dt aside: the complement of a gain), but not equal to it in the firmware's precision;
    the nearest first."""
    f = np.float32 if dtype == "float32" else np.float64
    targets = []
    for k, v in params.items():
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.floating)) or v == 0:
            continue
        pv = f(v)
        targets.append((k, float(pv), rel * abs(float(pv))))
        if 0 < v < 1 and k != "dt":
            targets.append((f"1 - {k}", float(f(f(1.0) - pv)), rel * float(pv)))
    out, seen = [], set()
    for path in dict.fromkeys(os.path.realpath(p) for p in files):
        try:
            lines = _code_lines(Path(path).read_text(errors="replace"))
        except OSError:
            continue
        for i, ln in enumerate(lines):
            for m in _FLOAT_LIT.finditer(ln):
                lit = float(m.group(1))
                single = m.group(2) in ("f", "F")
                val = float(np.float32(lit)) if single or dtype == "float32" else lit
                for name, t, tol in targets:
                    if val != t and abs(lit - t) <= tol and (path, i, m.start()) not in seen:
                        seen.add((path, i, m.start()))
                        rep = (np.format_float_positional(np.float32(t), unique=True,
                                                          trim="0") + "f") if single else repr(t)
                        out.append(Constant(path, i + 1, m.start() + 1, m.group(0), name, t, rep))
    out.sort(key=lambda c: abs(float(c.literal.rstrip("fFlL")) - c.value) / abs(c.value))
    return out


def _patched(c: Constant, sources: Sequence[str], d: Path) -> Optional[List[str]]:
    """Copies of the sources (and of c's file) in d, c's literal replaced by its value."""
    d.mkdir(parents=True, exist_ok=True)
    names = [os.path.basename(s) for s in sources]
    if len(set(names)) != len(names):
        return None
    for s in sources:
        shutil.copyfile(s, d / os.path.basename(s))
    lines = Path(c.path).read_text(errors="replace").split("\n")
    ln = lines[c.line - 1]
    lines[c.line - 1] = ln[:c.col - 1] + c.replacement + ln[c.col - 1 + len(c.literal):]
    (d / os.path.basename(c.path)).write_text("\n".join(lines))
    return [str(d / n) for n in names]


# ---------------------------------------------------------------------------

def explain_source(v: Any, fw: Any, params: Mapping[str, Any], run: RunInputs,
                   cmd: Sequence[str], wd: Path,
                   rerun_sources: Callable[[List[str], List[str]], bool]) -> None:
    """Add to v (not bit-exact on the host) the causes found in the source and its runs.
    params: the filter's constructor keywords; cmd: the user's compiler, flags, defines and
    include directories; rerun_sources(sources, include_dirs): validate the firmware built
    from other sources and include directories (bit-exact or not). v.causes end in the report's order
    (imufuse.firmware.causes.ordered)."""
    first = v.comparison.first_sample
    users = list(fw.sources) + _headers(fw)
    notes: List[str] = []
    path = run_path(fw, run, wd, (first or 0) + 1)
    if path is not None:
        notes.append(path.text())
    ub, san_notes = sanitize(fw, run, wd, first)
    notes += san_notes
    pre = [_preprocessed(cmd, s, wd) for s in fw.sources]
    dm = data_model(pre, users)
    # the user's files the compiler reads (not every file of their directories)
    read = list(dict.fromkeys(f for lines in pre for f, _, _ in lines if f in _users(users)))
    if ub is not None:
        for c in dm:
            if ub.where and c.where and ub.where.split(":")[:2] == c.where.split(":")[:2]:
                c.evidence += f"; confirmed by the {ub.evidence.split(':')[0]} run: " + \
                    ub.evidence.split(": ", 1)[-1] + \
                    (f" at sample {ub.sample}" if ub.sample is not None else " during init")
                c.confirmed = ub.confirmed
                if c.confirmed:
                    c.fix = c.advice
    if len(dm) > 6:
        notes.append(f"{len(dm) - 6} more data-model finding(s) not shown")
        dm = dm[:6]
    consts = []
    cands = [k for k in constants(read or fw.sources, params, v.comparison.dtype)
             if path is None or path.on_path(k.path, k.line) is not False]
    for i, k in enumerate(cands[:MAX_CONSTANTS]):
        d = wd / f"const{i}"
        srcs = _patched(k, fw.sources, d)
        ok = None
        if srcs is not None:
            dirs = [str(d), *fw.include_dirs, *sorted({os.path.dirname(s) for s in fw.sources})]
            try:
                ok = rerun_sources(srcs, dirs)
            except Exception:  # noqa: BLE001 - a confirmation that cannot build confirms nothing
                ok = None
        c = Cause("constant", f"{k.literal} where {k.name} = {k.shown}" +
                  (f"; rebuilt with {k.replacement} there, the firmware is bit-exact" if ok else
                   f"; rebuilt with {k.replacement} there: still not bit-exact" if ok is False
                   else ""), None, ok, where=k.where,
                  advice=f"use the parameter's value ({k.replacement}) or pass it in")
        if ok:
            c.fix = c.advice
            consts.append(c)
        else:
            notes.append(f"{k.where}: {k.literal} is near {k.name} = {k.shown}" +
                         ("; rebuilt with it there: still not bit-exact" if ok is False else ""))
    warn, wnotes = warning_causes(compiler_warnings(cmd, fw.sources, wd, users), path)
    v.causes = ordered([*v.causes, *([ub] if ub else []), *dm, *consts, *warn])
    v.notes += notes + wnotes
