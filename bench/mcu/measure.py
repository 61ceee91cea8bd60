"""Measure filters on the emulated MCUs: code size, stack, cycles/instructions per update.

    python bench/mcu/measure.py                       # every case, every target
    python bench/mcu/measure.py --cases example_quat_f32 --targets avr,m0 --json out.json

Per (case, target):
  text/data/bss   bytes of the case's objects (arm-none-eabi-size / avr-size), library
                  routines (soft float, sqrtf) not included
  stack_static    -fstack-usage frame of the step function alone
  stack_measured  deepest stack the step reached (stack painting), library calls included
  per_update      avr: CPU cycles (Timer1); m4f/m0: instructions (qemu -icount);
                  host: x86-64 instructions under callgrind; min/median/max over samples
Every target also checks that its state bits equal the host build's.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import registry  # noqa: E402

mcu = registry.mcu


def measure(name: str, case: "registry.Case", target: str, samples: int) -> dict:
    inputs = case.make_inputs(samples)
    common = dict(sources=case.sources, include_dirs=case.include_dirs, defines=case.defines)
    size = mcu.code_size(target, **common)["total"]
    stack = mcu.stack_usage(target, **common).get(case.step_function, {})
    row = {"case": name, "target": target, **size, "stack_static": stack.get("bytes")}
    host = mcu.run("host", driver=case.driver, inputs=inputs, **common)
    if target == "host":
        cg = mcu.callgrind_instructions(driver=case.driver, inputs=inputs, **common)
        row.update(unit="x86-64 instructions", per_update_min=cg["per_update"],
                   per_update_median=cg["per_update"], per_update_max=cg["per_update"],
                   stack_measured=None, bits_equal_host=True)
        return row
    res = mcu.run(target, driver=case.driver, inputs=inputs, count=True, **common)
    c = res.counts
    row.update(
        unit=mcu.TARGETS[target].count_unit,
        per_update_min=int(c.min()),
        per_update_median=float(np.median(c)),
        per_update_max=int(c.max()),
        stack_measured=res.stack_bytes,
        bits_equal_host=bool(np.array_equal(res.state, host.state)),
    )
    return row


def table(rows: list) -> str:
    cols = ["case", "target", "text", "data", "bss", "stack_static", "stack_measured",
            "per_update_median", "per_update_max", "unit", "bits_equal_host"]
    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        out.append("| " + " | ".join(str(r.get(c, "")) for c in cols) + " |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default=",".join(registry.names()))
    ap.add_argument("--targets", default="m4f,m0,avr,host")
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--json", type=Path, help="also write the rows as JSON here")
    ap.add_argument("--no-install", action="store_true", help="do not run install-toolchains.sh")
    args = ap.parse_args(argv)

    targets = [t for t in args.targets.split(",") if t]
    missing = mcu.ensure_toolchains(targets, install=not args.no_install)
    for t, why in missing.items():
        print(f"skipping {t}: {why}", file=sys.stderr)
    rows = []
    for name in [c for c in args.cases.split(",") if c]:
        case = registry.CASES[name]
        for t in targets:
            if t in missing or (t != "host" and t not in case.targets):
                continue
            rows.append(measure(name, case, t, args.samples))
    print(table(rows))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0 if all(r["bits_equal_host"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
