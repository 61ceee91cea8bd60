"""Run bench/test_bench_wrapper.py and print the wrapper-cost table (markdown)
of bench/RESULTS.md and docs/internals.md: side by side, with ratios against
vqf, imufusion and the bare C loop.

    python bench/wrapper_table.py [--runs K]

Each run is one pytest-benchmark session (every figure the min of its
rounds); with K runs every figure is the median of the K minima, and the
load average of the host before each run is printed with the table (the
host is shared: single figures move between runs, ratios within one run
much less).
"""
import argparse
import json
import os
import statistics
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


def measure_runs(runs):
    """Median over runs of each figure's min; the load averages before each run."""
    all_t, loads, machine = [], [], {}
    for _ in range(runs):
        loads.append(os.getloadavg()[0])
        t, machine = measure()
        all_t.append(t)
    return {k: statistics.median(t[k] for t in all_t) for k in all_t[0]}, loads, machine


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
    # the floor of update(): an empty call with the same arguments plus the C
    # update itself (run() per sample at N = 1000)
    t = dict(t, update_floor=t["test_update_floor"] + t["test_run_imufuse[1000]"] / 1000)
    pairs = [("state read vs imufusion get_quaternion()", "test_state_imufuse", "test_state_imufusion"),
             ("state read, every read kept (a new array each) vs the same for imufusion",
              "test_state_kept_imufuse", "test_state_kept_imufusion"),
             ("update(ndarray rows) vs imufusion update_no_magnetometer", "test_update_imufuse",
              "test_update_imufusion"),
             ("update(ndarray rows) vs vqf BasicVQF.update", "test_update_imufuse", "test_update_vqf"),
             ("update(ndarray rows) vs its floor: an empty 2-argument call + the C update",
              "test_update_imufuse", "update_floor"),
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
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1, help="benchmark sessions (median of their minima)")
    opts = ap.parse_args()
    times, loads, machine = measure_runs(opts.runs)
    cpu = machine.get("cpu", {}).get("brand_raw", "?")
    how = ("min of pytest-benchmark rounds" if opts.runs == 1 else
           f"median of {opts.runs} runs of the min of pytest-benchmark rounds")
    print(f"MadgwickIMU (float64 unless stated), {how}, {cpu}, "
          f"Python {machine.get('python_version', '?')}; 1-minute load average before each run: "
          f"{', '.join(f'{x:.1f}' for x in loads)} (2 cores).\n")
    print(table(times))
