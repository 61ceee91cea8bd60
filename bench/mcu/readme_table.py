"""The compact per-filter MCU table docs/firmware.md quotes, from
bench/mcu/results.json: one row per filter class and precision (its first
registry configuration), float32, float64 and fixed point; per core its cost per
update (cycles on the ATmega328P, instructions on the QEMU cores), linked flash
and measured stack. `python bench/mcu/measure.py`
refreshes it in docs/firmware.md (and the fixed-vs-float table in docs/fixed-point.md) after a measurement.

    python bench/mcu/readme_table.py            # print the compact table
    python bench/mcu/readme_table.py --write    # refresh its block in docs/firmware.md
"""
import json
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


#: the cores of the compact table, in its order: (harness target, column title)
CORES = [("avr", "ATmega328P cycles"), ("m0", "M0"), ("m3", "M3"), ("m4f", "M4F"), ("m7", "M7"),
         ("m33", "M33"), ("m55", "M55"), ("rv32imac", "RV32IMAC"), ("rv32imafc", "RV32IMAFC")]


def table():
    """One row per filter class and precision (its first registry configuration); per core
    one cell: cost per update / linked flash / measured stack (bytes)."""
    out = []
    rows = json.load(open(os.path.join(HERE, "results.json")))["rows"]
    by, order = {}, []
    for r in rows:
        by.setdefault(r["filter"], {})[r["target"]] = r
        if r["filter"] not in order:
            order.append(r["filter"])
    present = [(t, title) for t, title in CORES if any(t in v for v in by.values())]
    out.append("| filter | " + " | ".join(title for _, title in present) +
               " | RAM (bytes) | bits vs host and reference |")
    out.append("|---|" + "---:|" * len(present) + "---:|---|")
    seen = set()
    for name in order:
        t = by[name]
        first = next(iter(t.values()))
        key = (first["class"], first["precision"])
        if key in seen:
            continue
        seen.add(key)

        def g(target, k):
            v = t.get(target, {}).get(k)
            return "-" if v is None else f"{v:.0f}"

        def cell(target):
            if target not in t:
                return "n/a"
            return (f"{g(target, 'per_update_median')} / {g(target, 'linked')} / "
                    f"{g(target, 'stack_measured')}")
        ram = next((x["ram"] for x in t.values() if x.get("ram") is not None), None)
        bits = "equal" if all(x["bits"] for x in t.values()) else "DIFFER"
        out.append(f"| {name} | " + " | ".join(cell(c) for c, _ in present) +
                   f" | {'-' if ram is None else ram} | {bits} |")
    return "\n".join(out)


def replace_block(text, tag, body):
    pat = re.compile(rf"(<!-- {tag}[^>]*-->\n).*?(<!-- end {tag} -->)", re.S)
    new, n = pat.subn(lambda m: m.group(1) + body.strip("\n") + "\n" + m.group(2), text)
    if n != 1:
        raise SystemExit(f"no <!-- {tag} --> block in the page")
    return new


def main(argv):
    if "--write" not in argv:
        print(table())
        return
    readme_path = os.path.join(HERE, "..", "..", "docs", "firmware.md")
    text = replace_block(open(readme_path).read(), "mcu-table", table())
    open(readme_path, "w").write(text)


if __name__ == "__main__":
    main(sys.argv[1:])
