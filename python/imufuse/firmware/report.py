"""What a validation says beyond bit-exact or not, and the files a CI reads.

``classify``: rounding (the same computation rounded differently: a few ulps at the first differing
sample, growing without a step) or formula (a different computation: large from the first differing
sample, or a step later), with the error's growth per decade of samples. ``tolerance``: the verdict
of a variant not meant to be bit-exact, its orientation difference over the run in degrees against a
bound (`imufuse validate --within`). ``report_dict``: a validation as JSON (verdict, first divergence
as bit patterns, class, causes, cost, timing, the build as it was: compiler, flags, the sha256 of
every file the compiler read); ``error_dict`` the same for a firmware that could not be built or
run; ``junit_xml`` either as JUnit test cases; ``write_reports`` writes them whole or not at all.
"""
from __future__ import annotations

import datetime
import hashlib
import json
import os
import re
import shutil
import socket
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass
from typing import Any, Dict, List, Mapping, Optional, Sequence

import numpy as np

from .. import __version__
from ..shared.atomic import replacing
from ..shared.bits import as_bits
from ..catalogue import FILTERS as FILTER_NAMES, entry
from ..shared.estimate import ADAPTERS
from .causes import quaternion_angles_deg
from ..mcu import toolchains as _tc
from .host import compiler_command, compiler_identity, dependency_files
from .targets import DEFAULT_TARGET_CFLAGS, harness_target

__all__ = ["Classification", "GrowthRow", "Tolerance", "classify", "orientation_difference_deg",
           "tolerance", "build_info", "report_dict", "error_dict", "junit_xml", "write_reports",
           "ROUNDING_ULPS", "FORMULA_ULPS", "FORMULA_RELATIVE", "STEP_FACTOR"]

#: at most this many ulps at the first differing sample (and no step): rounding
ROUNDING_ULPS = 64
#: at least this many ulps, or this relative difference, at the first differing sample: formula
FORMULA_ULPS = 1e3
FORMULA_RELATIVE = 1e-4
#: a step: one sample's error >= FORMULA_ULPS and this many times the largest before it
STEP_FACTOR = 100.0


@dataclass
class GrowthRow:
    """The error over samples start..stop-1 (one decade of samples)."""
    start: int
    stop: int
    differ: int                    # samples with any state variable different
    max_abs: float                 # max |got - want| over the state variables
    max_deg: Optional[float]       # max orientation difference (None: no orientation)


@dataclass
class Classification:
    """Rounding or formula (see the module doc), where it starts and how it grows."""
    kind: str                      # "rounding" | "formula"
    sample: int                    # the first differing sample
    variable: str                  # the first differing state variable
    first_ulps: float              # the largest difference at that sample, in ulps (counts)
    first_relative: float
    step: Optional[int]            # a sample where the error jumped (formula)
    step_from: float               # ... the largest error before it, in ulps of the scale
    step_to: float                 # ... and its error there
    max_scale_ulps: float          # largest error over the run, ulps of the variable's scale
    growth: List[GrowthRow]
    unit: str = "ulps"             # "counts" for an integer (fixed-point) state

    def short(self) -> str:
        """The class in a few words (the parenthesis of the --within line)."""
        if self.kind == "rounding":
            return f"rounding: {self._first()} ({self.variable}), growing without a step"
        if self.step is not None:
            return f"a different computation: a step at sample {self.step}"
        return f"a different computation: {self._first()} ({self.variable})"

    def _first(self, relative: bool = False) -> str:
        if self.unit == "deg":  # orientations of states of different kinds (versus.py)
            return f"first difference {self.first_ulps:.2g} deg of orientation at sample {self.sample}"
        rel = f" (relative {self.first_relative:.2g})" if relative and self.unit == "ulps" else ""
        return f"first difference {_n(self.first_ulps, self.unit)}{rel} at sample {self.sample}"

    def text(self) -> str:
        first = self._first(relative=True) + f" ({self.variable})"
        scale = "of the variable's largest magnitude"
        if self.kind == "rounding":
            head = (f"class: rounding (the same computation rounded differently): {first}; "
                    f"the error grows without a step, to at most "
                    f"{_n(self.max_scale_ulps, self.unit)} {scale}")
        elif self.step is not None:
            head = (f"class: formula (a different computation): a step at sample {self.step}: "
                    f"the error jumped from {_n(self.step_from, self.unit)} to "
                    f"{_n(self.step_to, self.unit)} {scale} in one sample; {first}")
        else:
            head = f"class: formula (a different computation): {first}"
        deg = any(r.max_deg is not None for r in self.growth)
        lines = [head, "error growth per decade of samples:",
                 f"  {'samples':14s} {'differ':>7s} {'max |diff|':>11s}"
                 + (f" {'max deg':>10s}" if deg else "")]
        for r in self.growth:
            lines.append(f"  {f'{r.start}-{r.stop - 1}':14s} {r.differ:7d} {r.max_abs:11.4g}"
                         + (f" {r.max_deg:10.4g}" if r.max_deg is not None else ""))
        return "\n".join(lines)


def _n(x: float, unit: str) -> str:
    return f"{(n := f'{x:.0f}' if x < 1e4 else f'{x:.2g}')} {unit[:-1] if n == '1' else unit}"


def orientation_difference_deg(name: str, params: Optional[Mapping[str, Any]], got: np.ndarray,
                               want: np.ndarray, names: Sequence[str]) -> Optional[np.ndarray]:
    """The orientation difference after every sample, degrees (a NaN counts as 180), from
    the filter's estimate as imufuse.firmware.causes.angle_divergence_deg takes it; None when
    the filter has none (or the state given does not make one). params: needed for a
    fixed-point single-axis filter only (its angle_scale). FusionAHRS: from q0..q3."""
    names = tuple(names)
    if name not in FILTER_NAMES:                                  # FusionAHRS
        cols = [names.index(f"q{i}") for i in range(4) if f"q{i}" in names]
        return quaternion_angles_deg(got[:, cols], want[:, cols]) if len(cols) == 4 else None
    e = entry(name)
    if e.estimate is None:
        return None
    names = tuple(names)
    if set(names) == set(e.state_names) and names != tuple(e.state_names):
        order = [names.index(n) for n in e.state_names]
        got, want, names = got[:, order], want[:, order], tuple(e.state_names)
    g, w = got.astype(np.float64), want.astype(np.float64)
    try:
        if e.fixed and e.estimate == "angle":
            f = e.make("ref", **dict(params or {}))
            g, w = (np.column_stack(f._state_float(list(a.T))) for a in (g, w))
        eg, ew = (ADAPTERS[e.estimate](names, e.kind, a) for a in (g, w))
    except Exception:  # noqa: BLE001 - degrees are extra information, never a failure
        return None
    if eg.q is not None and ew.q is not None:
        return quaternion_angles_deg(eg.q, ew.q)
    if eg.angle is None or ew.angle is None:
        return None
    with np.errstate(all="ignore"):
        ang = np.degrees(np.abs(eg.angle - ew.angle))
    return np.where(np.isnan(ang), 180.0, ang)


def _ulp(x: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """The ulp at |x| in `dtype` (at least the smallest normal's; inf for a non-finite x)."""
    x = np.maximum(np.abs(x), float(np.finfo(dtype).tiny))
    with np.errstate(all="ignore"):
        u = np.spacing(x.astype(dtype)).astype(np.float64)
    return np.where(np.isfinite(u), u, np.inf)


def classify(v: Any) -> Optional[Classification]:
    """Rounding or formula for a Validation (None when bit-exact); see the module doc.

    The first differing sample's difference is counted in ulps of the larger of the two
    values, but never of less than 1/1024 of the variable's largest magnitude over the run
    (a value crossing zero is not thousands of ulps away from its neighbour); an integer
    state counts in counts. A step: one sample whose error, in ulps of the variable's
    largest magnitude, is at least FORMULA_ULPS and STEP_FACTOR times the largest before it."""
    c = v.comparison
    if c.bit_exact or c.first_sample is None:
        return None
    got, want = np.atleast_2d(np.asarray(v.got).T).T, np.atleast_2d(np.asarray(v.want).T).T
    integer = got.dtype.kind in "iu"
    diff = (got != want) if integer else (as_bits(got) != as_bits(want))
    with np.errstate(all="ignore"):
        ad = np.abs(got.astype(np.float64) - want.astype(np.float64))
        ad[diff & np.isnan(ad)] = np.inf           # a NaN against a number
        ad[~diff] = 0.0
        aw = np.abs(want.astype(np.float64))
        scale = np.where(np.isfinite(aw), aw, 0.0).max(axis=0)
        k = int(c.first_sample)
        mag = np.maximum(np.abs(got[k].astype(np.float64)), np.abs(want[k].astype(np.float64)))
        if integer:
            mag, u, per_sample = np.maximum(mag, 1.0), ad[k], ad.max(axis=1)
        else:
            mag = np.where(np.isnan(mag), np.inf, np.maximum(mag, scale / 1024.0))
            u = np.nan_to_num(np.where(np.isfinite(ad[k]), ad[k] / _ulp(mag, got.dtype), np.inf),
                              nan=np.inf)
            per_sample = (ad / _ulp(scale, got.dtype)[None, :]).max(axis=1)
        rel = np.where(diff[k], np.nan_to_num(ad[k] / mag, nan=np.inf), 0.0)
    first_ulps, first_rel = float(np.max(np.where(diff[k], u, 0.0))), float(rel.max())
    # a step after the first differing sample
    step, s_from, s_to = None, 0.0, 0.0
    before, after = np.maximum.accumulate(per_sample)[k:-1], per_sample[k + 1:]
    with np.errstate(all="ignore"):
        jump = (after >= FORMULA_ULPS) & np.isfinite(before) & \
            (after >= STEP_FACTOR * np.maximum(before, 1.0))
    if jump.any():
        i = int(np.argmax(jump))
        step, s_from, s_to = k + 1 + i, float(before[i]), float(after[i])
    formula = (first_ulps > ROUNDING_ULPS or (not integer and first_rel >= FORMULA_RELATIVE)
               or step is not None)
    ang = orientation_difference_deg(v.filter, getattr(v, "params", None), got, want, c.names)
    # a float filter against its fixed-point port: degrees (no ulps between their quaternions)
    dg = getattr(v, "as_orientations", False) and ang is not None
    return Classification("formula" if formula or dg else "rounding", k, str(c.first_variable),
                          float(ang[k]) if dg and ang is not None else first_ulps, first_rel,
                          None if dg else step, s_from, s_to, float(per_sample.max()), _growth(ad, diff, ang),
                          "deg" if dg else "counts" if integer else "ulps")


def _growth(ad: np.ndarray, diff: np.ndarray, ang: Optional[np.ndarray]) -> List[GrowthRow]:
    rows, start, stop = [], 0, 10
    while start < len(ad):
        end = min(stop, len(ad))
        rows.append(GrowthRow(start, end, int(diff[start:end].any(axis=1).sum()),
                              float(ad[start:end].max()),
                              None if ang is None else float(ang[start:end].max())))
        start, stop = stop, stop * 10
    return rows


@dataclass
class Tolerance:
    """A variant not meant to be bit-exact: its orientation against imufuse's over the run."""
    deg: float                     # the bound
    passed: bool                   # max_deg <= deg
    max_deg: float
    rms_deg: float
    samples: int
    max_abs: Dict[str, float]      # per state variable, max |got - want|
    kind: Optional[str] = None     # the Classification's short text (None when bit-exact)

    def text(self) -> str:
        return (f"{'within' if self.passed else 'NOT within'} {self.deg:g} deg: max "
                f"{self.max_deg:.3g} deg, RMS {self.rms_deg:.3g} deg over {self.samples} samples"
                + (f" ({self.kind})" if self.kind else ""))


def tolerance(v: Any, deg: float) -> Tolerance:
    """The tolerance verdict of Validation `v` against `deg` degrees (max orientation
    difference over the run <= deg). ValueError when the filter has no orientation."""
    c = v.comparison
    ang = orientation_difference_deg(v.filter, getattr(v, "params", None), np.asarray(v.got),
                                     np.asarray(v.want), c.names)
    if ang is None:
        raise ValueError(f"{v.filter}: no orientation estimate of its state to compare in deg")
    mx = float(ang.max()) if ang.size else 0.0
    rms = float(np.sqrt(np.mean(ang ** 2))) if ang.size else 0.0
    cls = v.classification
    return Tolerance(float(deg), bool(mx <= deg), mx, rms, int(ang.size), dict(c.max_abs),
                     cls.short() if cls is not None else None)


# ---------------------------------------------------------------------------
# the build as it was


def _sha256(path: str) -> Optional[str]:
    try:
        with open(path, "rb") as fh:
            return hashlib.sha256(fh.read()).hexdigest()
    except OSError:
        return None


def _host_deps(fw: Any, name: str, params: Mapping[str, Any]):
    """(every file the host compiler reads, from Firmware._deps, or None; the sha256 of the
    generated harness)."""
    e = entry(name)
    args = e.reference._params(**params)           # imufuse.firmware.validate's C init values
    names = list(e.init_args)
    c_args = tuple(args) if len(names) != len(args) else dict(zip(names, args))
    src = fw.source(e.kind, len(fw._init_values(c_args, params)) if fw.init else 0)
    return fw._deps(src), hashlib.sha256(src.encode()).hexdigest()


def _target_deps(cmd: Sequence[str], fw: Any) -> Optional[List[str]]:
    """Every file the target compiler reads for the sources and the headers the driver
    includes (its -M output), or None."""
    with tempfile.TemporaryDirectory(prefix="imufuse-deps-") as tmp:
        heads = os.path.join(tmp, "headers.c")
        with open(heads, "w") as fh:
            fh.write("".join(f'#include "{h}"\n' for h in fw.headers))
        deps = dependency_files([[*cmd, src] for src in [heads, *fw.sources]])
        if deps is None:
            return None
        return [d for d in deps if d != os.path.realpath(heads)]


def build_info(fw: Any, name: str, params: Optional[Mapping[str, Any]], target: str = "host",
               cflags: Optional[Sequence[str]] = None) -> Dict[str, Any]:
    """The build as it was: the compiler (command, resolved path, --version text), flags,
    defines, include directories and the sha256 of every file the compiler read (its -M
    output: sources, headers, system headers; the sources and headers given when -M fails).
    cflags: the flags of a target build (default the firmware's, else -O2)."""
    harness: Optional[str] = None
    deps: Optional[List[str]] = None
    arch: List[str] = []
    srcdirs = sorted({os.path.dirname(s) for s in fw.sources})
    if target == "host":
        cc = compiler_command()
        ident = compiler_identity()
        compiler: Dict[str, Any] = {"command": cc, "path": ident[len(cc)], "version": ident[-1]}
        flags = list(fw.cflags)
        try:
            deps, harness = _host_deps(fw, name, params or {})
        except Exception:  # noqa: BLE001 - a declaration that does not bind: the files given
            deps = None
    else:
        tgt = _tc.TARGETS[harness_target(target)]
        path = shutil.which(tgt.cc)
        compiler = {"command": [tgt.cc], "path": os.path.realpath(path) if path else None,
                    "version": ((compiler_identity([tgt.cc])[-1] or "unknown") if path
                                else "not installed")}
        flags = list(cflags if cflags is not None else fw.cflags_given
                     if fw.cflags_given is not None else DEFAULT_TARGET_CFLAGS)
        arch = list(tgt.arch_flags)
        defs = [f"-D{k}" if v is None else f"-D{k}={v}" for k, v in fw.defines.items()]
        if path:
            deps = _target_deps([tgt.cc, *arch, *[f for f in flags if not f.startswith(
                ("-M", "-o", "-flto"))], *defs, *[f"-I{d}" for d in fw.include_dirs + srcdirs]],
                fw)
    files = deps if deps is not None else list(fw.sources) + [
        os.path.realpath(f[0]) for f in ([os.path.join(d, h) for d in [*fw.include_dirs, *srcdirs]
                                          if os.path.isfile(os.path.join(d, h))]
                                         for h in fw.headers) if f]
    return {"target": target, "compiler": compiler, "arch_flags": arch, "flags": flags,
            "defines": {k: (None if v is None else str(v)) for k, v in fw.defines.items()},
            "include_dirs": list(fw.include_dirs), "sources": list(fw.sources),
            "headers": list(fw.headers),
            "files_from": "the compiler's -M output" if deps is not None else
            "the sources and headers given (the compiler's -M failed)",
            "files": [{"path": f, "sha256": _sha256(f)} for f in files],
            "harness_sha256": harness}


# ---------------------------------------------------------------------------
# JSON and JUnit


def _clean(x: Any) -> Any:
    """JSON-safe: numpy scalars as numbers, non-finite floats as "nan"/"inf"/"-inf"."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, (np.integer, np.bool_)):
        return x.item()
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else "nan" if np.isnan(x) else "inf" if x > 0 else "-inf"
    return x


def _pattern(a: np.ndarray, k: int, j: int) -> Dict[str, Any]:
    """A value of a (N, n) trajectory and its bit pattern in hex."""
    a = np.atleast_2d(np.asarray(a).T).T[k:k + 1, j]
    width = a.dtype.itemsize * 2 if a.dtype.kind == "f" else 8
    return {"value": a[0].item(), "bits": f"0x{int(as_bits(a)[0]):0{width}x}"}


def report_dict(v: Any, tol: Optional[Tolerance] = None, build: Optional[Dict[str, Any]] = None,
                inputs: Optional[str] = None, timing: Optional[Mapping[str, float]] = None,
                within: Optional[float] = None) -> Dict[str, Any]:
    """Validation `v` as the JSON report (see the module doc); tol: its tolerance verdict;
    timing: more seconds (the command's total) beside v.timing."""
    c = v.comparison
    first = None
    if not c.bit_exact:
        j, k = list(c.names).index(c.first_variable), int(c.first_sample)
        first = {"sample": k, "variable": c.first_variable,
                 "got": _pattern(v.got, k, j), "want": _pattern(v.want, k, j)}
    cls = v.classification
    kind = "bit-exact" if v.bit_exact else "within" if tol is not None and tol.passed else "differs"
    cost = None if v.cost is None else {f: getattr(v.cost, f) for f in (
        "unit", "min", "median", "max", "flash", "ram", "stack", "library", "library_flash")}
    message = c.text() if c.bit_exact else (tol.text() if tol is not None else
                                            str(c.summary()))
    rep = {"imufuse": __version__, "verdict": kind, "message": message, "filter": v.filter,
           "params": dict(getattr(v, "params", None) or {}), "backend": v.backend,
           "dtype": c.dtype, "target": v.target, "inputs": inputs, "samples": c.n_samples,
           "state": list(c.names), "first_divergence": first, "n_different": c.n_different,
           "max_abs": dict(c.max_abs), "max_ulps": dict(c.max_ulps),
           "max_angle_deg": v.max_angle_deg,
           "classification": None if cls is None else asdict(cls),
           "within_deg": within, "within": None if tol is None else asdict(tol),
           "causes": [{"name": x.what, **{k: val for k, val in asdict(x).items() if k != "what"}}
                      for x in v.causes],
           "notes": list(v.notes), "cost": cost,
           "timing": _timing({**dict(v.timing), **dict(timing or {})}), "build": build,
           "text": v.text() + (f"\n{tol.text()}" if tol is not None and not v.bit_exact else "")}
    return _clean(rep)


#: an error message naming a run-time fault (the build passed); any other error is the build's
_RUN_FAULT = re.compile(r"crashed|called exit\(|gave no answer|stack overflow|restarted at "
                        r"sample|locked up|stopped (during init|at sample)|while being loaded")


def error_dict(message: str, filter: str, target: str = "host",
               build: Optional[Dict[str, Any]] = None, inputs: Optional[str] = None,
               params: Optional[Mapping[str, Any]] = None, within: Optional[float] = None,
               timing: Optional[Mapping[str, float]] = None) -> Dict[str, Any]:
    """The JSON report of a firmware that could not be built, bound or run: verdict
    "error", the message, and stage "run" (a crash, exit(), a hang, a stack overflow) or
    "build" (the compiler, the linker, the declaration)."""
    return _clean({"imufuse": __version__, "verdict": "error", "message": message,
                   "stage": "run" if _RUN_FAULT.search(message) else "build",
                   "filter": filter, "params": dict(params or {}), "target": target,
                   "inputs": inputs, "within_deg": within, "causes": [],
                   "timing": dict(timing or {}), "build": build, "text": message})


def _timing(t: Dict[str, Any]) -> Dict[str, Any]:
    """The report's timing: build_cached as true or false (the build's seconds then are the
    cache look-up's)."""
    if "build_cached" in t:
        t["build_cached"] = bool(t["build_cached"])
    return t


_XML_BAD = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def _x(s: Any) -> str:
    return _XML_BAD.sub("?", str(s))


def junit_xml(rep: Mapping[str, Any]) -> str:
    """A report (report_dict or error_dict) as JUnit XML: one testsuite, one testcase per
    check of the target: "build" (compiled and linked), "bit-exact" (or "within DEG deg"),
    "causes" when any were named (compiler warnings are not causes); a failure with the
    message (an error for a run-time fault; the check skipped when the build failed; the
    causes fail only when the check does)."""
    target, kind, deg = rep.get("target", "host"), rep["verdict"], rep.get("within_deg")
    timing = rep.get("timing") or {}
    total = float(timing.get("total", 0.0) or 0.0)
    no_build = kind == "error" and rep.get("stage") == "build"
    built = total if no_build else float(timing.get("build", 0.0) or 0.0)
    msg, cases = str(rep.get("message", "")), []

    def case(name: str, seconds: float, tag: Optional[str] = None, message: str = "",
             typ: str = "", text: Optional[str] = None) -> None:
        el = ET.Element("testcase", classname=f"imufuse.validate.{target}", name=name,
                        time=f"{max(seconds, 0.0):.3f}")
        if tag == "system-out":
            ET.SubElement(el, tag).text = _x(message)
        elif tag is not None:
            ET.SubElement(el, tag, message=_x(message), type=typ).text = _x(text or message)
        cases.append(el)

    if timing.get("build_cached"):
        case("build", built, "system-out", "cached: the program built before from the same "
             "sources, files read, flags and toolchain")
    else:
        case("build", built, "failure" if no_build else None, msg, "build")
    check = f"within {deg:g} deg" if deg is not None else "bit-exact"
    if no_build:
        case(check, 0.0, "skipped", "not run: the firmware was not built")
    elif kind == "error":
        case(check, total - built, "error", msg, "firmware fault")
    else:
        case(check, total - built, "failure" if kind == "differs" else "system-out", msg,
             "differs", str(rep.get("text", "")))
    causes = [c for c in rep.get("causes") or () if c["name"] != "warning"]
    if causes:
        said = "; ".join(f"{c['name']}: fix {c['fix']}" + (" (confirmed)" if c["confirmed"] else "")
                         if c["fix"] else str(c["name"]) for c in causes)
        detail = "\n".join(f"{c['name']}: {c['evidence']}" for c in causes)
        case("causes", 0.0, *(("failure", said, "causes", detail) if kind == "differs" else
                              ("system-out", detail)))
    n = {t: str(sum(1 for c in cases if c.find(t) is not None))
         for t in ("failure", "error", "skipped")}
    attrs = dict(tests=str(len(cases)), failures=n["failure"], errors=n["error"],
                 skipped=n["skipped"], time=f"{total:.3f}")
    root = ET.Element("testsuites", {"name": "imufuse validate", **attrs})
    stamp = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0).isoformat()
    suite = ET.SubElement(root, "testsuite", {
        "name": f"imufuse validate {rep.get('filter')} on {target}", "timestamp": stamp,
        "hostname": _x(socket.gethostname()), **attrs})
    props = ET.SubElement(suite, "properties")
    for k in ("verdict", "filter", "target", "imufuse"):
        ET.SubElement(props, "property", name=k, value=_x(rep.get(k)))
    suite.extend(cases)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def write_reports(rep: Mapping[str, Any], json_path: Optional[str] = None,
                  junit_path: Optional[str] = None) -> None:
    """Write the JSON and/or JUnit report, each whole or not at all (imufuse.shared.atomic);
    OSError "--json PATH: cannot write: ..." when one cannot be written."""
    for opt, path in (("--json", json_path), ("--junit", junit_path)):
        if path is None:
            continue
        text = json.dumps(rep, indent=2, allow_nan=False) + "\n" if opt == "--json" \
            else junit_xml(rep)
        try:
            with replacing(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
                fh.write(text)
        except OSError as e:
            raise OSError(f"{opt} {path}: cannot write: {e.strerror or e}") from None
