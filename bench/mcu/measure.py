"""Measure every filter on the emulated MCUs: code size, RAM, stack, cycles/instructions per update.

    python bench/mcu/measure.py            # every filter x target; writes RESULTS.md, results.json
    python bench/mcu/measure.py --filters Mahony1D-float32 --targets avr,m0 --no-write
    python bench/mcu/measure.py --targets m7,rv32imac --merge   # these cores; the other rows
                                                                # kept from results.json
    python bench/mcu/measure.py --kernels  # the harness's own example kernels (mcu_cases.CASES)

Per (filter configuration and precision, target), generically from imufuse.registry, plus
the hand-written library cases of mcu_cases.LIBRARY_CASES (FusionAHRS: its update takes dt and
Fusion's units, so the generic driver cannot call it; measured with its Case's driver, bits
= its state on the target equals the host build's):
  text            bytes of the filter's <c>_init + <c>_update (nm -S of its object, built with
                  the contract's flags and -ffunction-sections); static helpers they call
                  separately are in the object's other functions, not here
  linked          bytes the filter adds to a linked program (-Wl,--gc-sections): its functions
                  plus the library routines it pulls in (soft float, sqrtf, isfinite) and its
                  init call: a settings struct as a static const initialiser (its bytes
                  counted here; on AVR also copied to RAM at start-up, not in ram below);
                  fixed point initialised by <c>_init_consts (checked: <c>_init is not in
                  the ELF)
  linked_double_init  fixed point: the same, initialised by the double <c>_init instead
  data, bss       bytes of the filter's object file (the library has no globals: 0)
  ram             sizeof(<c>_t): RAM of one filter instance
  stack_static    -fstack-usage frame of <c>_update alone (no callees)
  stack_measured  deepest stack an update reached (stack painting), library calls included
  per_update      avr: CPU cycles at 16 MHz (Timer1 at clk/1, simavr's cycle model); the
                  Cortex-M cores: instructions (qemu -icount, SysTick); rv32imac/rv32imafc:
                  instructions (qemu -icount, read through mcycle); host: x86-64 instructions
                  under callgrind. QEMU counts instructions, not cycles: it models no pipeline,
                  wait states or caches.
                  median and max over the samples (motion, then the corners)
  samples         input rows run: N_MOTION samples of motion and the corners, or
                  imufuse.mcu.filters.N_MOTION_SMALL of motion where the program does not fit
                  the target with N_MOTION stored (RobustIMU/RobustAHRS on AVR), as
                  tests/test_mcu_filters.py does (one function: filters.run_fitting)
  bits            the target's state after every sample equals the host build's and the
                  Python reference's, bit for bit (the measurement runs are checked too)
Before measuring, the counters are validated on kernels of known cost (AVR: _delay_loop_2
takes exactly 4k + 3 cycles; Arm: a subs/bne loop exactly 2k + 2 instructions; RISC-V: an
addi/bnez loop exactly 2k + 2 instructions).

What is measured: mcu_cases.py; how it is written (RESULTS.md, results.json, the docs'
generated blocks): results_md.py.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Optional

import numpy as np

# bench/mcu/mcu_cases.py and results_md.py, beside this script (the script's folder is on sys.path)
import mcu_cases
from results_md import N_MOTION, fixed_vs_float, fixed_vs_float_table, summary, table, write_results

HERE = Path(__file__).resolve().parent
mcu = mcu_cases.mcu
mf = mcu_cases.mf
#: every target, in the tables' order
ALL_TARGETS = ["m4f", "m0", "avr", "m3", "m7", "m33", "m55", "rv32imac", "rv32imafc", "host"]


# --------------------------------------------------------------------------------------------
# counters


def validate_counters(targets) -> dict:
    """The counters count exactly what they claim, on kernels of known cost."""
    out = {}
    if "avr" in targets:
        k = np.array([1, 10, 1000, 16384, 40000, 65535], dtype=np.uint16)
        drv = mcu.Driver(prelude="#include <util/delay_basic.h>", step="_delay_loop_2(k);", state=[])
        res = mcu.run("avr", driver=drv, inputs={"k": k}, count=True)
        want = (4 * k.astype(np.int64) + 3).tolist()
        if res.counts.tolist() != want:
            raise SystemExit(f"avr Timer1 counter invalid: {res.counts.tolist()} != {want}")
        out["avr"] = "_delay_loop_2(k) counted as exactly 4k + 3 cycles"
    for t in targets:
        method = mcu.TARGETS[t].count_method
        if method not in ("systick", "csr"):
            continue
        k = np.array([1, 10, 1000, 65535], dtype=np.uint16)
        if method == "systick":
            loop = ('uint32_t c = k;\n__asm__ volatile(".syntax unified\\n1: subs %0, %0, #1\\n'
                    '\\tbne 1b\\n.syntax divided" : "+l"(c) : : "cc");')
            what, extra = "subs/bne", 2
        else:
            loop = ('uint32_t c = k;\n__asm__ volatile("1: addi %0, %0, -1\\n\\tbnez %0, 1b"'
                    ' : "+r"(c));')
            what, extra = "addi/bnez", 2
        res = mcu.run(t, driver=mcu.Driver(step=loop, state=[]), inputs={"k": k}, count=True)
        want = (2 * k.astype(np.int64) + extra).tolist()
        if res.counts.tolist() != want:
            raise SystemExit(f"{t} instruction counter invalid: {res.counts.tolist()} != {want}")
        out[t] = f"{what} loop counted as exactly 2k + {extra} instructions"
    return out


# --------------------------------------------------------------------------------------------
# sizes


def _tool(target, name):
    cc = mcu.TARGETS[target].cc
    return cc[:-3] + name if target != "host" and cc.endswith("gcc") else name


def _compile(target, src, obj, spec, extra=()):
    cmd = [mcu.TARGETS[target].cc, *mcu.cflags(target), "-ffunction-sections", "-fdata-sections",
           *extra, *[f"-D{k}" if v is None else f"-D{k}={v}" for k, v in spec.defines.items()],
           f"-I{spec.csrc}", f"-I{spec.csrc / 'fixed'}", "-c", str(src), "-o", str(obj)]
    subprocess.run(cmd, check=True, capture_output=True, text=True)


def _symbol_sizes(target, obj):
    out = subprocess.run([_tool(target, "nm"), "-S", "--size-sort", str(obj)], check=True,
                         capture_output=True, text=True).stdout
    sizes = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 4:
            sizes[parts[3]] = int(parts[1], 16)
    return sizes


def sizes(spec, target, wd: Path) -> dict:
    c = spec.c
    obj = wd / f"{c.source.stem}.o"
    _compile(target, c.source, obj, spec)
    sym = _symbol_sizes(target, obj)
    text = sum(sym.get(f, 0) for f in (f"{c.c_name}_init", c.c_update))
    sz = subprocess.run([_tool(target, "size"), "-B", str(obj)], check=True, capture_output=True,
                        text=True).stdout.splitlines()[1].split()
    probe = wd / "ram_probe.c"
    probe.write_text(f'#include "{c.header.name}"\nchar imf_ram_probe[sizeof({c.c_name}_t)] = {{1}};\n')
    _compile(target, probe, wd / "ram_probe.o", spec)
    ram = _symbol_sizes(target, wd / "ram_probe.o")["imf_ram_probe"]
    su = mcu.stack_usage(target, [c.source], [spec.csrc, spec.csrc / "fixed"], spec.defines,
                         workdir=wd / "su")
    return {"text": text, "data": int(sz[1]), "bss": int(sz[2]), "ram": ram,
            "stack_static": su.get(c.c_update, {}).get("bytes")}


def _elf_text(target, elf):
    out = subprocess.run([_tool(target, "size"), "-B", str(elf)], check=True, capture_output=True,
                         text=True).stdout.splitlines()[1].split()
    return int(out[0]) + int(out[1])


_EMPTY = {}


def _empty_driver(spec, drv):
    """The same program without the filter: it reads every input and prints as many state
    words of the same kinds (from volatile dummies), so only the filter's cost remains."""
    ctype = {np.dtype(np.float32): "float", np.dtype(np.float64): "double",
             np.dtype(np.int16): "int16_t"}[np.dtype(spec.input_dtype())]
    names = mf.INPUT_NAMES[spec.kind]
    scalar = spec.kind in ("1d", "vario")     # scalar inputs (VarioKF: accel, baro_alt, dt)
    reads = [f"imf_sink = {n};" if scalar else f"imf_sink = {n}[{j}];"
             for n in names for j in (range(1) if scalar else range(3))]
    # one array per kind, read in the order of the filter's state words: a run of words the
    # filter's driver dumps in a loop is a loop here too (mcu.driver)
    count: dict = {}
    state = []
    for _, k in drv.state:
        state.append((f"imf_dummy_{k}[{count.get(k, 0)}]", k))
        count[k] = count.get(k, 0) + 1
    ctypes = {"f32": "float", "f64": "double", "i32": "int32_t", "u32": "uint32_t", "i16": "int16_t"}
    prelude = f"static volatile {ctype} imf_sink;\n" + "\n".join(
        f"static volatile {ctypes[k]} imf_dummy_{k}[{n}];" for k, n in sorted(count.items()))
    return mcu.Driver(prelude=prelude, step="\n".join(reads), state=state)


def linked_size(spec, target, inputs, elf, wd: Path) -> int:
    """Bytes of flash the filter adds to a program: ELF(filter) - ELF(same driver, no filter)."""
    drv, _ = mf._driver([spec])
    n = len(next(iter(inputs.values())))
    key = (target, spec.precision, spec.kind, tuple(k for _, k in drv.state), n)
    if key not in _EMPTY:
        used = {n: inputs[n] for n in mf.INPUT_NAMES[spec.kind]}
        e = mcu.build(target, driver=_empty_driver(spec, drv), inputs=used,
                      workdir=wd / "empty")
        _EMPTY[key] = _elf_text(target, e)
    return _elf_text(target, elf) - _EMPTY[key]


def _elf_symbols(target, elf) -> set:
    out = subprocess.run([_tool(target, "nm"), str(elf)], check=True, capture_output=True,
                         text=True).stdout
    return {ln.split()[-1] for ln in out.splitlines() if ln.split()}


def double_init_flash(spec, target, inputs, elf, wd: Path) -> Optional[int]:
    """Fixed point: the linked flash of the same firmware initialised by <c>_init (double
    parameters) instead of <c>_init_consts; and a check that the _init_consts firmware
    (``elf``) does not contain the double init."""
    c = spec.c
    if f"{c.c_name}_init" in _elf_symbols(target, elf):
        raise SystemExit(f"{spec.label} on {target}: the init_consts firmware links {c.c_name}_init")
    drv, _ = mf._driver([spec], double_init=True)

    def build(ins):
        return mcu.build(target, sources=[str(c.source)],
                         include_dirs=[spec.csrc, spec.csrc / "fixed"], defines=spec.defines,
                         driver=drv, inputs=mf._inputs_of([spec], ins), workdir=wd / "dbl")
    try:
        e = build(inputs)
    except mcu.HarnessError as err:
        # the double init's soft float and the stored samples do not fit together: the rule
        # of run_fitting (fewer samples); the figure is a difference against the same driver
        # without the filter, with the same samples, so it does not depend on their number
        if "does not fit" not in str(err):
            raise
        e = None
        for n in (mf.N_MOTION_SMALL, 8, 1):
            inputs = mf.inputs_for(spec.precision, spec.group[1], n)
            try:
                e = build(inputs)
                break
            except mcu.HarnessError as err2:
                if "does not fit" not in str(err2):
                    raise
        if e is None:
            # not even with one sample: the double init does not fit this target with the
            # driver (n/a in the table; the init_consts firmware is the one that fits)
            return None
    if f"{c.c_name}_init" not in _elf_symbols(target, e):
        raise SystemExit(f"{spec.label} on {target}: the double-init firmware lacks {c.c_name}_init")
    return linked_size(spec, target, inputs, e, wd)


# --------------------------------------------------------------------------------------------
# one filter on one target


def measure_filter(name: str, target: str, host_cache: dict) -> dict:
    spec = mcu_cases.FILTER_SPECS[name]
    wd = Path(tempfile.mkdtemp(prefix=f"imf_measure_{target}_"))
    try:
        row = {"filter": name, "class": spec.ref_class.__name__, "precision": spec.precision,
               "target": target, **sizes(spec, target, wd)}
        if target == "host":
            inputs = mf.inputs_for(spec.precision, spec.group[1], N_MOTION)
            want, _ = mf.reference_states(spec, inputs)
            drv, _ = mf._driver([spec])
            cg = mcu.callgrind_instructions(sources=[spec.c.source],
                                            include_dirs=[spec.csrc, spec.csrc / "fixed"],
                                            defines=spec.defines, driver=drv, inputs=inputs,
                                            workdir=wd / "cg")
            exe = wd / "cg" / "imf_host.elf"
            row["linked"] = linked_size(spec, target, inputs, exe, wd) if exe.exists() else None
            res = mf.run_filters("host", [spec], inputs, workdir=wd / "run")
            row.update(unit="x86-64 instructions", per_update_median=round(cg["per_update"], 1),
                       per_update_max=None, stack_measured=None,
                       samples=len(next(iter(inputs.values()))),
                       bits=bool(np.array_equal(res.states[0], want)))
            return row
        # the rule of tests/test_mcu_filters.py: a filter whose program does not fit with
        # N_MOTION samples stored runs on mf.N_MOTION_SMALL
        res, inputs = mf.run_fitting(target, [spec], N_MOTION, count=True, workdir=wd / "run")
        n = len(next(iter(inputs.values())))          # samples run (motion and corners)
        want, _ = mf.reference_states(spec, inputs)
        r = res.results[0]
        host = host_cache.get((name, n))
        if host is None:
            host = mf.run_filters("host", [spec], inputs).states[0]
            host_cache[(name, n)] = host
        row["linked"] = linked_size(spec, target, inputs, r.elf, wd)
        if spec.fixed:
            row["linked_double_init"] = double_init_flash(spec, target, inputs, r.elf, wd)
        c = r.counts
        if res.cflags:      # built for size: run_fitting's last resort, said in the row
            row["extra_cflags"] = list(res.cflags)
        row.update(unit=mcu.TARGETS[target].count_unit, samples=n,
                   per_update_median=float(np.median(c)), per_update_max=int(c.max()),
                   stack_measured=r.stack_bytes,
                   bits=bool(np.array_equal(res.states[0], want) and np.array_equal(res.states[0], host)))
        return row
    finally:
        shutil.rmtree(wd, ignore_errors=True)


# --------------------------------------------------------------------------------------------
# the harness's example kernels (mcu_cases.CASES)


def measure_case(name: str, case, target: str, samples: int) -> dict:
    inputs = case.make_inputs(samples)
    common = dict(sources=case.sources, include_dirs=case.include_dirs, defines=case.defines)
    size = mcu.code_size(target, **common)["total"]
    stack = mcu.stack_usage(target, **common).get(case.step_function, {})
    row = {"filter": name, "target": target, **size, "stack_static": stack.get("bytes")}
    host = mcu.run("host", driver=case.driver, inputs=inputs, **common)
    if target == "host":
        cg = mcu.callgrind_instructions(driver=case.driver, inputs=inputs, **common)
        row.update(unit="x86-64 instructions", per_update_median=cg["per_update"], bits=True)
        return row
    res = mcu.run(target, driver=case.driver, inputs=inputs, count=True, **common)
    row.update(unit=mcu.TARGETS[target].count_unit, per_update_median=float(np.median(res.counts)),
               per_update_max=int(res.counts.max()), stack_measured=res.stack_bytes,
               bits=bool(np.array_equal(res.state, host.state)))
    return row


def measure_library_case(name: str, target: str) -> dict:
    """A library filter the generic path cannot drive (mcu_cases.LIBRARY_CASES: FusionAHRS takes
    dt and Fusion's units in every update): measure_case, plus the linked flash (ELF of the
    case minus the same program whose init and step only read the inputs); bits: the target's
    state equals the host build's (tests/test_fusion.py checks the host against the reference)."""
    case = mcu_cases.CASES[name]
    row = measure_case(name, case, target, N_MOTION)
    row.update({"class": mcu_cases.LIBRARY_CASES[name], "precision": "float32",
                "samples": N_MOTION})
    inputs = case.make_inputs(N_MOTION)
    wd = Path(tempfile.mkdtemp(prefix=f"imf_measure_{target}_"))
    try:
        common = dict(sources=case.sources, include_dirs=case.include_dirs, defines=case.defines)
        elf = mcu.build(target, driver=case.driver, inputs=inputs, workdir=wd / "f", **common)
        ctype = {np.dtype(np.float32): "float", np.dtype(np.int16): "int16_t"}
        reads = [f"imf_sink_{k} = {k}[{j}];" for k, a in inputs.items() for j in range(a.shape[1])]
        pre = "\n".join(f"static volatile {ctype[a.dtype]} imf_sink_{k};" for k, a in inputs.items())
        empty = mcu.Driver(prelude=case.driver.prelude + "\n" + pre, step="\n".join(reads),
                           state=case.driver.state)
        e = mcu.build(target, driver=empty, inputs=inputs, workdir=wd / "e", **common)
        row["linked"] = _elf_text(target, elf) - _elf_text(target, e)
    finally:
        shutil.rmtree(wd, ignore_errors=True)
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--filters", default=",".join(mcu_cases.filter_names()))
    ap.add_argument("--targets", default=",".join(ALL_TARGETS))
    ap.add_argument("--merge", action="store_true",
                    help="keep the rows of results.json for the filters and targets not measured now")
    ap.add_argument("--kernels", action="store_true", help="measure the harness's example kernels instead")
    ap.add_argument("--no-write", action="store_true", help="print only; do not write RESULTS.md/results.json")
    ap.add_argument("--jobs", type=int, default=8)
    ap.add_argument("--no-install", action="store_true", help="do not run install-toolchains.sh")
    args = ap.parse_args(argv)

    targets = [t for t in args.targets.split(",") if t]
    missing = mcu.ensure_toolchains(targets, install=not args.no_install)
    for t, why in missing.items():
        print(f"skipping {t}: {why}", file=sys.stderr)
    targets = [t for t in targets if t not in missing]
    t0 = time.perf_counter()
    if args.kernels:
        rows = [measure_case(n, mcu_cases.CASES[n], t, 200) for n in mcu_cases.names() for t in targets
                if t == "host" or t in mcu_cases.CASES[n].targets]
        print(table(rows))
        return 0 if all(r["bits"] for r in rows) else 1

    checks = validate_counters(targets)
    jobs = [(n, t) for n in args.filters.split(",") if n and n not in mcu_cases.LIBRARY_CASES
            for t in targets
            if mcu_cases.FILTER_SPECS[n].precision in mf.TARGET_PRECISIONS[t]]
    host_cache: dict = {}
    lib = [(n, t) for n in mcu_cases.LIBRARY_CASES if n in args.filters.split(",")
           or args.filters == ap.get_default("filters") for t in targets
           if t == "host" or t in mcu_cases.CASES[n].targets]
    with ThreadPoolExecutor(max_workers=args.jobs) as ex:
        rows = list(ex.map(lambda j: measure_filter(j[0], j[1], host_cache), jobs))
        rows += list(ex.map(lambda j: measure_library_case(j[0], j[1]), lib))
    seconds = time.perf_counter() - t0
    if args.merge and (HERE / "results.json").exists():
        old = json.loads((HERE / "results.json").read_text())
        done = {(r["filter"], r["target"]) for r in rows}
        rows += [r for r in old["rows"] if (r["filter"], r["target"]) not in done]
        checks = {**{t: c for t, c in old.get("counter_checks", {}).items() if t not in targets},
                  **checks}
        seconds += old.get("seconds", 0.0)
        targets = [t for t in ALL_TARGETS if t in {r["target"] for r in rows}]
        order = {t: i for i, t in enumerate(ALL_TARGETS)}
        names = {n: i for i, n in enumerate(dict.fromkeys(r["filter"] for r in old["rows"]))}
        rows.sort(key=lambda r: (names.get(r["filter"], len(names)), order[r["target"]]))
    print(summary(rows, targets))
    print()
    print(fixed_vs_float_table(fixed_vs_float(rows)))
    if not args.no_write:
        write_results(rows, targets, checks, seconds, HERE / "RESULTS.md", HERE / "results.json")
        print(f"wrote {HERE / 'RESULTS.md'} and {HERE / 'results.json'} ({seconds:.0f} s)")
    bad = [f"{r['filter']} on {r['target']}" for r in rows if not r["bits"]]
    if bad:
        print("bits differ: " + ", ".join(bad), file=sys.stderr)
    return 0 if not bad else 1


if __name__ == "__main__":
    sys.exit(main())
