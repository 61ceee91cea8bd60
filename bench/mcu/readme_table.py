"""The compact per-filter MCU table docs/firmware.md quotes, from
bench/mcu/results.json: one row per filter class and precision (its first
registry configuration), float32 and fixed point. `python bench/mcu/measure.py`
refreshes it in docs/firmware.md (and the fixed-vs-float table in docs/fixed-point.md) after a measurement.

    python bench/mcu/readme_table.py            # print the compact table
    python bench/mcu/readme_table.py --write    # refresh its block in docs/firmware.md
"""
import json
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def table():
    out = []
    rows = json.load(open(os.path.join(HERE, "results.json")))["rows"]
    by, order = {}, []
    for r in rows:
        by.setdefault(r["filter"], {})[r["target"]] = r
        if r["filter"] not in order:
            order.append(r["filter"])
    out.append("| filter | AVR cycles | M0 instr. | M4F instr. | flash AVR / M0 / M4F (bytes) | RAM (bytes) |"
          " bits vs host and reference |")
    out.append("|---|---:|---:|---:|---|---:|---|")
    seen = set()
    for name in order:
        t = by[name]
        first = next(iter(t.values()))
        key = (first["class"], first["precision"])
        if key in seen or first["precision"] == "float64":
            continue
        seen.add(key)

        def g(target, k):
            v = t.get(target, {}).get(k)
            return "n/a" if v is None else f"{v:.0f}"
        bits = "equal" if all(x["bits"] for x in t.values()) else "DIFFER"
        out.append(f"| {name} | {g('avr', 'per_update_median')} | {g('m0', 'per_update_median')} | "
              f"{g('m4f', 'per_update_median')} | {g('avr', 'linked')} / {g('m0', 'linked')} / "
              f"{g('m4f', 'linked')} | {g('m4f', 'ram')} | {bits} |")


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
