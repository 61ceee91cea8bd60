"""Reading a 10^6-row CSV log side by side: imufuse's reader (imufuse.io.text with the C
parser of imufuse_c._csvin) against pandas' C reader, numpy.loadtxt, and imufuse's previous
reader (numpy.loadtxt fed line by line), CPU time of each, interleaved over rounds in one
process; and the peak memory of each in a child process of its own. read_log, the reader
with units, time checks and the plausibility checks, is timed beside them.

Goal (issue 50): CPU no more than pandas.read_csv's, memory no more than the
arrays it yields plus a bounded buffer.

    pytest bench/test_bench_csv.py --benchmark-only -s
"""
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from imufuse import io
from imufuse.io import text as T

pd = pytest.importorskip("pandas", reason="pandas is the peer this bench compares with "
                         "(pip install pandas)")

ROWS = 1_000_000
ALL = ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z", "mag_x", "mag_y", "mag_z"]
ROUNDS = 5


@pytest.fixture(scope="module")
def big_csv(tmp_path_factory):
    """10^6 rows of time, gyroscope, accelerometer and magnetometer with 7 and 9 significant
    digits: 100 MB, a logger's layout. Every reader reads the ten columns."""
    p = tmp_path_factory.mktemp("csvbench") / "big.csv"
    rng = np.random.default_rng(1)
    t = np.arange(ROWS) / 200.0
    M = np.column_stack([t, rng.normal(scale=0.2, size=(ROWS, 3)),
                         rng.normal(scale=0.05, size=(ROWS, 3)) + [0, 0, 1],
                         rng.normal(scale=30, size=(ROWS, 3))])
    with open(p, "w") as fh:
        fh.write(",".join(ALL) + "\n")
        row = "%.9g," + "%.7g," * 8 + "%.7g\n"
        for k in range(0, ROWS, 50000):
            blk = M[k:k + 50000]
            fh.write((row * len(blk)) % tuple(blk.ravel().tolist()))
    return p


def _gyr(cols):
    return np.column_stack([cols["gyr_x"], cols["gyr_y"], cols["gyr_z"]])


def _reader(p):
    return _gyr(T._read_csv(str(p), None, None)[0])


def _read_log(p):
    return io.read_log(p).gyr


def _reader_before(p):
    saved = T._FAST_ENCODINGS
    T._FAST_ENCODINGS = ()
    try:
        return _reader(p)
    finally:
        T._FAST_ENCODINGS = saved


def _pandas(p):
    return pd.read_csv(p, usecols=ALL, dtype=np.float64, engine="c")[ALL[1:4]].to_numpy()


def _loadtxt(p):
    return np.loadtxt(p, delimiter=",", skiprows=1, usecols=range(10))[:, 1:4]


READERS = {"imufuse.io's reader": _reader, "pandas.read_csv": _pandas,
           "numpy.loadtxt": _loadtxt, "imufuse.io before (loadtxt by lines)": _reader_before,
           "imufuse.io.read_log (reader, units, checks)": _read_log}
#: what the memory is measured of: each reader's own result (no column stacked after it)
PEAK_READERS = {**READERS,
                "imufuse.io's reader": lambda p: T._read_csv(str(p), None, None),
                "pandas.read_csv": lambda p: pd.read_csv(p, usecols=ALL, dtype=np.float64),
                "numpy.loadtxt": lambda p: np.loadtxt(p, delimiter=",", skiprows=1,
                                                      usecols=range(10))}

_PEAK = """
import json, re, sys
import test_bench_csv as B
def rss(k):
    return int(re.search(k + r":\\s+(\\d+)", open("/proc/self/status").read()).group(1)) / 1024
open("/proc/self/clear_refs", "w").write("5")    # the peak from here: imports left out
base = rss("VmRSS")
B.PEAK_READERS[sys.argv[1]](sys.argv[2])
print(json.dumps({"peak_mb": rss("VmHWM") - base}))
"""


def test_read_csv_side_by_side(benchmark, big_csv):
    ref = _pandas(big_csv)
    exact = _loadtxt(big_csv)
    cpu = {k: [] for k in READERS}
    for _ in range(ROUNDS):
        for name, f in READERS.items():
            t0 = time.process_time()
            g = f(big_csv)
            cpu[name].append(time.process_time() - t0)
            # the same values (pandas' default parser is not always correctly rounded:
            # within an ulp; the others are, and equal to the bit)
            assert g.shape == ref.shape and np.allclose(g, ref, rtol=1e-15, atol=0)
            if name != "pandas.read_csv":
                assert np.array_equal(g, exact), name
    med = {k: float(np.median(v)) for k, v in cpu.items()}
    here = str(Path(__file__).parent)
    # this module and what this process imports from, importable by name in the child
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([here, *sys.path])}
    peak = {}
    for name in READERS:
        out = subprocess.run([sys.executable, "-c", _PEAK, name, str(big_csv)],
                             capture_output=True, text=True, check=True, cwd=here, env=env)
        peak[name] = json.loads(out.stdout)
    benchmark.pedantic(_reader, args=(big_csv,), rounds=1, iterations=1)
    arrays_mb = ROWS * 10 * 8 / 2**20
    benchmark.extra_info.update(rows=ROWS, cpu_s=med, peak_mb={k: v["peak_mb"] for k, v in peak.items()},
                                arrays_mb=arrays_mb)
    print(f"\n{ROWS} rows, {big_csv.stat().st_size / 1e6:.0f} MB; median CPU of {ROUNDS} "
          "interleaved rounds; peak RSS of a child process above its start (interpreter and imports "
          f"left out); the arrays read: {arrays_mb:.0f} MiB")
    for name in READERS:
        print(f"  {name:44s} {med[name]:6.2f} s CPU  {med[name] / med['pandas.read_csv']:5.2f}x pandas"
              f"  peak +{peak[name]['peak_mb']:4.0f} MiB")
