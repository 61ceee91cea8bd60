"""Run bench/test_bench_wrapper.py and print the wrapper-cost table (markdown)
of bench/RESULTS.md and the README: min times of one run, side by side, and
ratios against vqf, imufusion and the bare C loop.

    python bench/wrapper_table.py
"""
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))


def measure():
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "wrapper.json")
        subprocess.run([sys.executable, "-m", "pytest", "-q", os.path.join(HERE, "test_bench_wrapper.py"),
                        "-p", "no:cacheprovider", f"--benchmark-json={out}"], check=True,
                       cwd=os.path.dirname(HERE), stdout=subprocess.DEVNULL)
        with open(out) as f:
            data = json.load(f)
    return {b["name"]: b["stats"]["min"] * 1e9 for b in data["benchmarks"]}, data["machine_info"]


def _ns(v):
    return f"{v / 1000:.2f} us" if v >= 10000 else f"{v:.0f} ns"


def table(t):
    rows = ["| operation | imufuse_c | other | imufuse / other |", "|---|---:|---:|---:|"]
    for n in (0, 1, 10, 100, 1000):
        mine = t[f"test_run_imufuse[{n}]"]
        for label, key in (("vqf BasicVQF.updateBatch", f"test_run_vqf[{n}]"),
                           ("bare C loop (cffi)", f"test_run_plain_c[{n}]")):
            rows.append(f"| run(), N = {n} vs {label} | {_ns(mine)} | {_ns(t[key])} | "
                        f"{mine / t[key]:.2f} |")
    pairs = [("state read vs imufusion get_quaternion()", "test_state_imufuse", "test_state_imufusion"),
             ("update(ndarray rows) vs imufusion update_no_magnetometer", "test_update_imufuse",
              "test_update_imufusion"),
             ("update(ndarray rows) vs vqf BasicVQF.update", "test_update_imufuse", "test_update_vqf"),
             ("update + state read vs imufusion update + get_quaternion",
              "test_update_and_read_imufuse", "test_update_and_read_imufusion")]
    for label, a, b in pairs:
        rows.append(f"| {label} | {_ns(t[a])} | {_ns(t[b])} | {t[a] / t[b]:.2f} |")
    for n in (10, 1000):
        a, b = t[f"test_run_float32_from_float64[{n}]"], t[f"test_run_float32_native[{n}]"]
        rows.append(f"| float32 run(), N = {n}: float64 arrays vs float32 arrays | {_ns(a)} | "
                    f"{_ns(b)} | {a / b:.2f} |")
    return "\n".join(rows)


if __name__ == "__main__":
    times, machine = measure()
    cpu = machine.get("cpu", {}).get("brand_raw", "?")
    print(f"MadgwickIMU (float64 unless stated), min of pytest-benchmark rounds, {cpu}, "
          f"Python {machine.get('python_version', '?')}.\n")
    print(table(times))
