"""What bench/mcu/measure.py writes from its rows: the tables of bench/mcu/RESULTS.md, the
rows of bench/mcu/results.json, and the generated blocks of docs/fixed-point.md (fixed point
against float32: cycles, flash) and docs/firmware.md (the compact table of readme_table.py).
"""

from __future__ import annotations

import functools
import json
import re
import subprocess
from pathlib import Path

import mcu_cases
import readme_table
from imufuse import catalogue, reference, registry
from imufuse.firmware.targets import CORES

HERE = Path(__file__).resolve().parent
mcu = mcu_cases.mcu
mf = mcu_cases.mf
COMMAND = "python bench/mcu/measure.py"
#: samples of simulated motion every filter runs (then the corner cases)
N_MOTION = 200

COLS = ["filter", "target", "text", "linked", "linked_double_init", "data", "bss", "ram",
        "stack_static", "stack_measured", "per_update_median", "per_update_max", "unit",
        "samples", "bits"]


def _fmt(v):
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "**NO**"
    if isinstance(v, float):
        return f"{v:.0f}" if v == int(v) else f"{v:.1f}"
    return str(v)


def table(rows, cols=COLS) -> str:
    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        out.append("| " + " | ".join(_fmt(r.get(c)) for c in cols) + " |")
    return "\n".join(out)


_UNIT = {"cycles": "cycles", "instructions": "instr."}


def summary(rows, targets) -> str:
    """filter x target: per-update cost and linked flash, one line per filter."""
    names = list(dict.fromkeys(r["filter"] for r in rows))
    by = {(r["filter"], r["target"]): r for r in rows}
    head = ["filter"]
    for t in targets:
        unit = _UNIT.get(mcu.TARGETS[t].count_unit, "x86 instr.")
        head += [f"{t} {unit}", f"{t} flash"]
    out = ["| " + " | ".join(head) + " | bits |", "|" + "---|" * (len(head) + 1)]
    for n in names:
        cells = [n]
        ok = True
        for t in targets:
            r = by.get((n, t))
            cells += [_fmt(r["per_update_median"]) if r else "n/a", _fmt(r.get("linked")) if r else "n/a"]
            ok = ok and (r is None or r["bits"])
        out.append("| " + " | ".join(cells) + f" | {'yes' if ok else '**NO**'} |")
    return "\n".join(out)


#: fixed-vs-float targets (issue "fixed point must beat soft-float on MCUs"): per target, the
#: fixed-point profile measured, the largest allowed ratio fixed / float32 per update, and the
#: fixed-point classes the target applies to (the others are listed for information)
# (profile measured, {class: limit}, limit of every other Q class or None): on AVR every Q
# filter at <= 1/2 of its float32 twin, the quaternion filters at <= 1/3 with a 10 % margin
# (0.30); on Cortex-M0 the quaternion filters at <= 1/2, the others for information
#: the quaternion filters, from the catalogue (a new one gets the quaternion goal)
QUATERNION_Q = tuple(e.name for e in catalogue.FIXED if e.estimate == "quaternion")
#: the recommended filter's goal (issue "RobustIMU and RobustAHRS in fixed point"): <= 1/3 on
#: both targets, without margin
ROBUST_Q = {e.name: 1 / 3 for e in catalogue.FIXED if e.name.startswith("Robust")}
FIXED_TARGETS = {"avr": ("p8", {**dict.fromkeys(QUATERNION_Q, 0.3), **ROBUST_Q}, 1 / 2),
                 "m0": ("p32", {**dict.fromkeys(QUATERNION_Q, 1 / 2), **ROBUST_Q}, None)}


def _measured_profile(cls: str, target: str) -> str:
    """The profile FIXED_TARGETS measures on `target`, or the class's only one if it is built in
    one profile."""
    from imufuse import reference
    want = FIXED_TARGETS[target][0]
    have = ["p" + p for p in getattr(getattr(reference, cls, None), "profiles", ())]
    return want if want in have or not have else have[0]


@functools.lru_cache(maxsize=None)
def _learns_mag_offset(filter_label: str) -> bool:
    """Whether a configuration (a row's filter label) runs B6, the magnetometer offset
    learning of the Robust filters: fixed point with mag_learn=True, float unless
    mag_learn=False (its default is on); False for every other filter."""
    case_id = filter_label.rsplit("-", 1)[0]
    case = next((c for c in (*registry.FLOAT_CASES, *registry.FIXED_CASES) if c.id == case_id),
                None)
    if case is None:
        return False
    if case.name.endswith("Q"):
        return bool(case.params.get("mag_learn", False))
    settings = getattr(reference, case.name)(**{"dt": 0.01, **case.params})._args
    return bool(getattr(settings, "mag_learn", False))


def fixed_vs_float(rows) -> list:
    """One entry per (fixed-point configuration, target of FIXED_TARGETS): its median cost per
    update against the cheapest float32 configuration of its float twin (the class without the
    trailing Q) on the same target that runs the same blocks (B6 on or off); ratio, target and
    the remaining gap in cycles/instructions."""
    by_class = {}
    for r in rows:
        by_class.setdefault((r["class"], r["precision"], r["target"]), []).append(r)
    out = []
    for (cls, prec, target), rs in by_class.items():
        if target not in FIXED_TARGETS or prec != _measured_profile(cls, target):
            continue
        _, limits, other = FIXED_TARGETS[target]
        limit = limits.get(cls, other)
        twin = cls[:-1]
        floats = by_class.get((twin, "float32", target), [])
        for r in rs:
            same = [f for f in floats
                    if _learns_mag_offset(f["filter"]) == _learns_mag_offset(r["filter"])]
            ref = min(same or floats, key=lambda f: f["per_update_median"]) if floats else None
            e = {"fixed": r["filter"], "target": target, "unit": r["unit"],
                 "fixed_per_update": r["per_update_median"], "float": ref and ref["filter"],
                 "float_per_update": ref and ref["per_update_median"], "limit": limit,
                 "applies": limit is not None}
            if ref and limit is not None:
                e["ratio"] = r["per_update_median"] / ref["per_update_median"]
                e["met"] = e["ratio"] <= limit
                e["gap"] = max(0.0, r["per_update_median"] - limit * ref["per_update_median"])
            elif ref:
                e["ratio"] = r["per_update_median"] / ref["per_update_median"]
            out.append(e)
    return out


def fixed_vs_float_table(entries) -> str:
    out = ["| fixed point | target | per update | float32 twin (cheapest) | per update | ratio | "
           "target | met |",
           "|---|---|---|---|---|---|---|---|"]
    for e in sorted(entries, key=lambda e: (e["target"], e["fixed"])):
        lim = "-" if not e["applies"] else (f"<= 1/{round(1 / e['limit'])}"
                                             if abs(1 / e["limit"] - round(1 / e["limit"])) < 1e-9
                                             else f"<= {e['limit']:.2f}")
        if e["float"] is None:
            cells = ["n/a (no float twin measured)", "-", "-", lim, "-"]
        else:
            met = ("yes" if e["met"] else f"**no**: {e['gap']:.0f} {e['unit']} over") \
                if e["applies"] else "-"
            cells = [e["float"], _fmt(e["float_per_update"]), f"{e['ratio']:.3f}", lim, met]
        out.append("| " + " | ".join([e["fixed"], e["target"],
                                        f"{_fmt(e['fixed_per_update'])} {e['unit']}", *cells]) + " |")
    return "\n".join(out)


def fixed_flash(rows) -> list:
    """Per fixed-point configuration on the soft-float MCUs (AVR, Cortex-M0): the linked flash
    of a firmware initialised by <c>_init_consts (the headline: it needs no floating point),
    that of one initialised by <c>_init (double parameters), and the smallest linked flash of
    a float32 configuration of its float twin on the same target."""
    twins = {}
    for r in rows:
        if r["precision"] == "float32" and r.get("linked") is not None:
            k = (r["class"], r["target"])
            if k not in twins or r["linked"] < twins[k]["linked"]:
                twins[k] = r
    out = []
    for r in rows:
        if not r["precision"].startswith("p") or r["target"] not in ("avr", "m0"):
            continue
        t = twins.get((r["class"][:-1], r["target"]))
        out.append({"fixed": r["filter"], "target": r["target"], "init_consts": r["linked"],
                    "double_init": r.get("linked_double_init"), "float": t and t["filter"],
                    "float_flash": t and t["linked"],
                    "ratio": t and r["linked"] / t["linked"]})
    return out


def fixed_flash_table(entries) -> str:
    out = ["| fixed point | target | flash, init_consts | flash, double init | "
           "float32 twin (smallest) | flash | init_consts / float32 |",
           "|---|---|---:|---:|---|---:|---:|"]
    for e in sorted(entries, key=lambda e: (e["target"], e["fixed"])):
        tw = [e["float"], _fmt(e["float_flash"]), f"{e['ratio']:.2f}"] if e["float"] else ["-"] * 3
        out.append("| " + " | ".join([e["fixed"], e["target"], _fmt(e["init_consts"]),
                                        _fmt(e["double_init"]), *tw]) + " |")
    return "\n".join(out)


def _versions(targets):
    v = {}
    for t in targets:
        cc = mcu.TARGETS[t].cc
        try:
            v[t] = subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.splitlines()[0]
        except (OSError, IndexError):
            v[t] = "?"
    for tool in ("qemu-system-arm", "qemu-system-riscv32", "simavr", "valgrind"):
        try:
            p = subprocess.run([tool, "--version"], capture_output=True, text=True)
            v[tool] = (p.stdout or p.stderr).strip().splitlines()[0]
        except (OSError, IndexError):
            v[tool] = "?"
    return v


def _kept_block(md: Path, tag: str, command: str) -> str:
    """A block of RESULTS.md another command writes (kept as it is when this one rewrites the
    page)."""
    if md.exists():
        m = re.search(rf"<!-- {tag} -->\n.*?<!-- end {tag} -->", md.read_text(), re.S)
        if m:
            return m.group(0)
    return f"<!-- {tag} -->\n(run `{command}`)\n<!-- end {tag} -->"


def write_results(rows, targets, checks, seconds, md: Path, js: Path) -> None:
    versions = _versions(targets)
    cross = _kept_block(md, "cross-library", "python bench/mcu/cross_library.py")
    md.write_text("\n".join([
        "# imufuse on microcontrollers: size, stack, cost per update",
        "",
        f"Generated by `{COMMAND}` (from the repository root; about {seconds:.0f} s). Do not edit:",
        "rerun the command. Every filter configuration of `python/imufuse/registry.py`, each precision;",
        "targets emulated (harness name: what it is):",
        "",
        *[f"- `{c.harness}`: {c.description}; counts {c.counting}" for c in CORES.values()],
        "- `host`: x86-64, instructions under callgrind",
        "",
        "**QEMU counts instructions, not cycles**: every instruction takes the same virtual time,",
        "so a division, a flash wait state or a cache miss costs what an add costs. Only the",
        "ATmega328P's figures are cycles (simavr models the AVR's cycle timing). On a real",
        "Cortex-M or RISC-V part expect more cycles than instructions (see docs/firmware.md,",
        "\"What to expect from each core\"). Flags: `-std=c99 -O2 -ffp-contract=off` plus the",
        "target's `-mcpu`/`-march`/`-mmcu` (bench/mcu/measure.py docstring defines every column).",
        "",
        "Counters validated before measuring: " + "; ".join(f"{t}: {s}" for t, s in checks.items()) + ".",
        f"Inputs: {N_MOTION} samples of simulated motion, then the corner cases (zero vectors,",
        "NaN/Inf, overflow, subnormals) and more motion; per-update figures are medians over all samples.",
        "",
        "## Summary (median per update: instructions on the QEMU cores, cycles on the AVR; "
        "flash = bytes the filter adds to a linked program)",
        "",
        summary(rows, targets),
        "",
        "## Across libraries: imufuse's 3-D filters beside x-io Fusion's C and VQF's C++",
        "",
        cross,
        "",
        "## Fixed point against float32 (soft float on Cortex-M0 and ATmega328P)",
        "",
        "Median cost per update of each fixed-point configuration (8-bit profile on AVR, 32-bit",
        "profile on Cortex-M0; a class built in one profile only, in that one) against the",
        "cheapest float32 configuration of its float twin (class name without the Q) on the same",
        "target that runs the same blocks (the Robust filters: B6, the magnetometer offset",
        "learning, on or off). Targets: on AVR every Q filter <= 1/2, and the quaternion filters",
        f"({' and '.join(q for q in QUATERNION_Q if q not in ROBUST_Q)}) <= 0.30 (1/3 with a 10 %",
        "margin); on Cortex-M0 the quaternion filters <= 1/2 (the others for information: '-');",
        f"{' and '.join(ROBUST_Q)} <= 1/3 on both.",
        "",
        fixed_vs_float_table(fixed_vs_float(rows)),
        "",
        "## Flash of the fixed-point filters",
        "",
        "Bytes a fixed-point filter adds to a linked program (`-Wl,--gc-sections`, library",
        "routines included) when the firmware initialises it with `<filter>_init_consts()` (the",
        "headline figure: integer constants, no floating point linked; the measurement checks",
        "that `<filter>_init` is absent from that ELF) and when it calls the double-precision",
        "`<filter>_init()` instead, against the smallest float32 configuration of its float twin.",
        "",
        fixed_flash_table(fixed_flash(rows)),
        "",
        "## All figures",
        "",
        "text: the filter's init + update functions; linked: flash added to a program, library",
        "routines included (soft float, sqrtf), fixed point initialised by `_init_consts`;",
        "linked_double_init: the same with the double `_init`; ram: one filter instance; stacks",
        f"in bytes; samples: inputs run (a program that does not fit the AVR with {N_MOTION}",
        f"samples of motion stored runs {mf.N_MOTION_SMALL}, the rule of tests/test_mcu_filters.py).",
        "",
        table(rows),
        "",
        "Toolchains: " + "; ".join(f"{k}: {v}" for k, v in versions.items()),
        "",
    ]))
    js.write_text(json.dumps({"command": COMMAND, "counter_checks": checks, "versions": versions,
                              "seconds": round(seconds),
                              "samples_motion": N_MOTION, "rows": rows,
                              "fixed_vs_float": fixed_vs_float(rows),
                              "fixed_flash": fixed_flash(rows)}, indent=1) + "\n")
    # the docs quote both tables, between their markers
    docs = HERE.parents[1] / "docs"
    if docs.is_dir():
        fx = docs / "fixed-point.md"
        text = readme_table.replace_block(fx.read_text(), "fixed-vs-float",
                                          fixed_vs_float_table(fixed_vs_float(rows)))
        fx.write_text(readme_table.replace_block(text, "fixed-flash",
                                                 fixed_flash_table(fixed_flash(rows))))
        fw = docs / "firmware.md"
        fw.write_text(readme_table.replace_block(fw.read_text(), "mcu-table", readme_table.table()))
