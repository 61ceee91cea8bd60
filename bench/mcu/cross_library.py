"""The table a firmware engineer chooses from: imufuse's 3-D filters beside the peers' own code
(x-io Fusion's C as in imufusion 1.2.3 and 1.3.3, VQF 2.1.2's C++ in single precision), on
every emulated core, in one table of bench/mcu/RESULTS.md and docs/firmware.md.

    python bench/mcu/cross_library.py [--cores m4f,m0] [--no-write] [--dir BROAD]

Per filter and core, through the firmware validation (imufuse.firmware.validate; the peers
through their declarations in examples/declarations/, their sdists fetched and SHA-256
checked by bench/mcu/peers.py, never committed), built as a release firmware with
`-O2 -ffp-contract=off -DNDEBUG` (C++: the same, no exceptions, no RTTI):
  per update   median over 300 samples of simulated motion: CPU cycles on the ATmega328P
               (simavr), instructions on the QEMU cores (QEMU counts instructions, not cycles)
  flash        the filter's objects plus the library code they pull in (soft float, libm)
  RAM          the filter's static RAM (its object; not the heap the harness links for a
               firmware that allocates); stack: the deepest an update reached
  bits         imufuse's filters and Fusion: the firmware's state after every sample equals
               imufuse's (Fusion: its bit-exact twins FusionAHRS, FusionAHRS13); VQF has no
               twin: its target build against its host build (firmware against firmware), the
               largest orientation difference and its cause
Accuracy: the seven BROAD development trials (../shared/data/broad, imufuse.evaluation), each
trial's RMS averaged: inclination (tilt) and heading in degrees, in float32, from the firmware
itself on the host (the peers' code through cffi; imufuse's filters through imufuse_c, which
the firmware equals bit for bit on every core), catalogue defaults / the declarations'
settings, at each trial's rate.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from imufuse import catalogue, evaluation, sim
from imufuse.shared.resources import csrc_dir
from imufuse.firmware import (FirmwareError, csrc_firmware, load_declaration, validate,
                              validate_isolated)
from imufuse.firmware.targets import CORES
from imufuse.firmware.versus import compare_firmware

import peers  # bench/mcu/peers.py and readme_table.py, beside this script
import readme_table

HERE = Path(__file__).resolve().parent

COMMAND = "python bench/mcu/cross_library.py"
FLAGS = ["-O2", "-ffp-contract=off", "-DNDEBUG"]   # a release build: asserts compiled out
G = 9.80665
DEFAULT_DIR = HERE.parents[2] / "shared" / "data" / "broad"
#: the cores in the table's order (harness names)
ALL_CORES = ["avr", "m0", "m3", "m4f", "m7", "m33", "m55", "rv32imac", "rv32imafc"]
_USER = {c.harness: name for name, c in CORES.items()}
#: what keeps a C++ peer off a core
NO_CXX = {"avr": "avr-g++ has no C++ standard library (VQF includes <algorithm>, <cmath>)",
          "rv32imac": "Debian 12's riscv64-unknown-elf-g++ has no C++ standard library",
          "rv32imafc": "Debian 12's riscv64-unknown-elf-g++ has no C++ standard library"}


# --------------------------------------------------------------------------------------------
# the filters


def imufuse_filters():
    """(row name, kind, builder) of every imufuse 3-D float filter, float32, defaults."""
    out = []
    for name in catalogue.filter_names({"imu", "ahrs"}):
        out.append((f"imufuse {name}", catalogue.entry(name).kind, ("imufuse", name)))
    return out


def peer_filters():
    """(rows of the peers whose declaration loads, {peer: why not} of the others): Fusion
    1.3.3's declaration comes with imufuse's port of it."""
    rows, missing = [], {}
    for name, p in peers.PEERS.items():
        if not p.declaration_path.is_file():
            missing[name] = f"no {p.declaration} in examples/declarations"
            continue
        try:
            _peer(name)
        except FirmwareError as e:
            missing[name] = _why(str(e))
            continue
        rows.append((name, "ahrs", ("peer", name)))
    return rows, missing


def _missing(msg: str, core: str) -> str:
    """Why a filter has no figures on a core, in one clause."""
    if "does not fit" in msg or "overflow" in msg:
        return "does not fit beside the validation driver " + \
            msg.split("memory ", 1)[-1].split(":")[0]
    return "does not build: " + msg.splitlines()[0][:160]


def _why(error: str) -> str:
    """A declaration that does not load, in one clause: what its loader said, up to the
    first ';' (without the file's path)."""
    return "its declaration does not load: " + error.split(".toml: ", 1)[-1].split(";")[0]


def _peer(name):
    """The peer's declaration, built with FLAGS (C++: private members readable on the host)."""
    p = peers.PEERS[name]
    d = load_declaration(p.declaration_path, source_dir=str(peers.fetch(name)))
    d.firmware.cflags = d.firmware.cflags_given = list(FLAGS) + (
        ["-fno-access-control"] if p.sdist.startswith("vqf") else [])
    return d


def _units(name, gyr, acc):
    """Fusion takes deg/s and g; VQF's declaration converts g to m/s^2 itself."""
    return (np.degrees(gyr), acc) if name.startswith("Fusion") else (gyr, acc)


def _peer_params(d, dt):
    params = dict(d.params, dt=dt)
    if "sample_rate" in params:
        params["sample_rate"] = 1.0 / dt
    return params


# --------------------------------------------------------------------------------------------
# cost on a core


_HOST_RUNS: dict = {}


def _host_run(name):
    """The peer built for the host on the cost inputs (made before the threads start: cffi
    changes the working directory while it builds)."""
    if name not in _HOST_RUNS:
        d = _peer(name)
        dt, gyr, acc, mag = _motion()
        g, a = _units(name, gyr, acc)
        _HOST_RUNS[name] = validate_isolated(d.firmware, d.filter, _peer_params(d, dt),
                                             [g, a, mag], target="host", explain=False)
    return _HOST_RUNS[name]


def _motion():
    s = sim.imu("fast", rate=100.0, duration=3.0, seed=3)
    return s.dt, np.asarray(s.gyr), np.asarray(s.acc), np.asarray(s.mag)


def cost(row, core) -> dict:
    """One filter on one core: the validation's cost and verdict."""
    label, kind, (src, name) = row
    target = _USER[core]
    dt, gyr, acc, mag = _motion()
    out = {"filter": label, "core": core}
    try:
        if src == "imufuse":
            fw = csrc_firmware(name, str(csrc_dir()), "float32", cflags=list(FLAGS))
            ins = [gyr, acc] + ([mag] if kind == "ahrs" else [])
            v = validate(fw, name, dict(catalogue.entry(name).defaults, dt=dt), ins,
                         target=target, explain=False)
            out["bits"] = "bit-exact" if v.bit_exact else "DIFFERS"
        else:
            if name.startswith("VQF") and core in NO_CXX:
                return {**out, "missing": f"does not build: {NO_CXX[core]}"}
            d = _peer(name)
            g, a = _units(name, gyr, acc)
            params = _peer_params(d, dt)
            v = validate_isolated(d.firmware, d.filter, params, [g, a, mag], target=target,
                                  explain=False)
            if name.startswith("VQF"):
                pair = compare_firmware(_host_run(name), v, "host", target)
                why = [n.split(": ", 2)[1] for n in pair.notes if n.startswith("cause:")]
                out["bits"] = ("bit-exact with its host build" if pair.bit_exact else
                               f"vs its host build: {pair.max_angle_deg:.1e} deg "
                               f"({', '.join(why) or 'cause not found'})")
            else:
                out["bits"] = ("bit-exact with imufuse " + d.filter) if v.bit_exact \
                    else f"DIFFERS from imufuse {d.filter}"
    except FirmwareError as e:
        return {**out, "missing": _missing(str(e), core)}
    c = v.cost
    out.update(unit=c.unit, per_update=float(c.median), flash=(c.flash or 0) + c.library_flash,
               ram=c.ram, stack=c.stack)
    return out


# --------------------------------------------------------------------------------------------
# accuracy on BROAD


def _trials(d):
    files = sorted(Path(d).glob("*.npz"))
    if not files:
        raise SystemExit(f"no BROAD trials (*.npz) in {d}")
    return [np.load(f) for f in files]


def accuracy(row, trials) -> dict:
    label, kind, (src, name) = row
    ev = []
    for t in trials:
        dt = 1.0 / float(t["rate"])
        gyr, acc, mag = (np.asarray(t[k], dtype=np.float64) for k in ("gyr", "acc", "mag"))
        acc_g = acc / G
        if src == "imufuse":
            f = catalogue.make_filter(name, "c", "float32",
                                      dict(catalogue.entry(name).defaults, dt=dt))
            args = (gyr, acc) + ((mag,) if kind == "ahrs" else ())
            q, frame = catalogue.estimate(f, f.run(*args)).q, "NWU"
        else:
            d = _peer(name)
            g, a = _units(name, gyr, acc_g)
            v = validate_isolated(d.firmware, d.filter, _peer_params(d, dt), [g, a, mag],
                                  target="host", explain=False, timeout=900.0)
            names = list(v.comparison.names)
            q = np.asarray(v.got[:, [names.index(f"q{k}") for k in range(4)]], dtype=float)
            frame = "ENU" if name.startswith("VQF") else "NWU"
        ev.append(evaluation.evaluate(q, t["quat_ref"], est_frame=frame, ref_frame="ENU",
                                      movement=t["movement"]))
    m = evaluation.mean_over_trials(ev)
    return {"inclination": m["inclination"],
            "heading": m["heading"] if kind == "ahrs" else math.nan}


# --------------------------------------------------------------------------------------------
# the table


def _f(v, fmt="{:.0f}"):
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else fmt.format(v)


def table(rows, acc) -> str:
    out = ["| filter | core | per update | flash (B) | RAM (B) | stack (B) | bits | "
           "BROAD tilt (deg) | BROAD heading (deg) |",
           "|---|---|---:|---:|---:|---:|---|---:|---:|"]
    for r in rows:
        a = acc.get(r["filter"], {})
        tilt, head = _f(a.get("inclination"), "{:.2f}"), _f(a.get("heading"), "{:.2f}")
        core = _USER[r["core"]]
        if "missing" in r:
            out.append(f"| {r['filter']} | {core} | {r['missing']} | - | - | - | - | {tilt} | "
                       f"{head} |")
            continue
        unit = "cycles" if r["unit"] == "cycles" else "instr."
        out.append(f"| {r['filter']} | {core} | {_f(r['per_update'])} {unit} | {_f(r['flash'])} | "
                   f"{_f(r['ram'])} | {_f(r['stack'])} | {r['bits']} | {tilt} | {head} |")
    return "\n".join(out)


def block(rows, acc, seconds, missing_peers) -> str:
    note = "".join(f" Not in the table: {n}: {why}." for n, why in missing_peers.items())
    return "\n".join([
        f"Generated by `{COMMAND}` (about {seconds:.0f} s). Every filter built with "
        f"`{' '.join(FLAGS)}` for each core and run on 300 samples of simulated motion; "
        "**per update: CPU cycles on the ATmega328P (simavr), instructions on every QEMU core "
        "(QEMU counts instructions, not cycles: no pipeline, wait states or caches)**. Flash: the "
        "filter's code plus the library code it pulls in; RAM: its static data; stack: the "
        "deepest an update reached. Accuracy: BROAD's seven development trials, float32, the "
        "mean of each trial's RMS (inclination for every filter, heading for the 9-D ones), the "
        "same on every core where the build is bit-exact." + note,
        "",
        table(rows, acc),
    ])


def _write_pages(text):
    """The block in RESULTS.md and docs/firmware.md (a RESULTS.md without the block yet gets
    it from bench/mcu/measure.py, which keeps it)."""
    for page in (HERE / "RESULTS.md", HERE.parents[1] / "docs" / "firmware.md"):
        try:
            page.write_text(readme_table.replace_block(page.read_text(), "cross-library", text))
            print(f"wrote the cross-library block of {page}")
        except SystemExit:
            print(f"{page}: no <!-- cross-library --> block (bench/mcu/measure.py writes it)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cores", default=",".join(ALL_CORES))
    ap.add_argument("--dir", default=os.environ.get("IMUFUSE_BROAD", str(DEFAULT_DIR)))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--no-write", action="store_true", help="print only")
    ap.add_argument("--json-only", action="store_true",
                    help="write cross_library.json, not the pages' blocks")
    ap.add_argument("--render", action="store_true",
                    help="only rewrite the pages' blocks from cross_library.json")
    ap.add_argument("--only", metavar="FILTER",
                    help="measure this row's filter only (e.g. 'Fusion 1.3.3'); the other rows "
                         "are kept from cross_library.json")
    args = ap.parse_args(argv)
    if args.render:
        d = json.loads((HERE / "cross_library.json").read_text())
        missing = {n: _why(w) if "does not load" in w else w for n, w in d["missing"].items()}
        for r in d["rows"]:
            if r.get("missing", "").startswith("does not fit:"):
                r["missing"] = _missing(r["missing"], r["core"])
        _write_pages(block(d["rows"], d["accuracy"], d["seconds"], missing))
        return 0
    t0 = time.perf_counter()
    cores = [c for c in args.cores.split(",") if c]
    prows, missing = peer_filters()      # fetches the sources once, before the threads
    filters = imufuse_filters() + prows
    kept: dict = {}
    if args.only:
        kept = json.loads((HERE / "cross_library.json").read_text())
        filters = [f for f in filters if f[0] == args.only]
        if not filters:
            raise SystemExit(f"--only {args.only!r}: no such row ({', '.join(missing)} missing)")
    # the host builds first and one at a time (cffi changes the working directory while it
    # builds); then the cross builds and emulator runs, which are processes, in threads
    trials = _trials(args.dir)
    accs = {f[0]: accuracy(f, trials) for f in filters}
    for n, _, _ in prows:
        if n.startswith("VQF"):
            _host_run(n)
    jobs = [(f, c) for f in filters for c in cores]
    with ThreadPoolExecutor(max_workers=args.jobs) as ex:
        rows = list(ex.map(lambda j: cost(*j), jobs))
    seconds = time.perf_counter() - t0
    if kept:
        order = [f[0] for f in imufuse_filters() + prows]
        rows = sorted([r for r in kept["rows"] if r["filter"] != args.only] + rows,
                      key=lambda r: (order.index(r["filter"]), ALL_CORES.index(r["core"])))
        accs = {**kept["accuracy"], **accs}
        seconds += kept["seconds"]
    text = block(rows, accs, seconds, missing)
    print(text)
    if not args.no_write:
        (HERE / "cross_library.json").write_text(json.dumps(
            {"command": COMMAND, "flags": FLAGS, "rows": rows, "accuracy": accs,
             "missing": missing, "seconds": round(seconds)}, indent=1, default=float) + "\n")
        if not args.json_only:
            _write_pages(text)
    bad = [f"{r['filter']} on {r['core']}" for r in rows if "DIFFERS" in r.get("bits", "")]
    if bad:
        print("bits differ: " + ", ".join(bad), file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
