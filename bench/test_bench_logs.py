"""Reading and running long logs: `imufuse run` on a 10^6-row CSV log, wall
time and peak RSS of the command (a child process), and read_log alone.

Goal (issue 9, defect 11): 10^6 rows in <= 2 s and <= 300 MB peak RSS for
`run`, with NPZ and with CSV output (the CSV text is made in C: docs/csv-output.md).

    pytest bench/test_bench_logs.py --benchmark-only
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import imufuse
import imufuse_c
from imufuse import io

ROWS = 1_000_000
PATHS = [os.path.dirname(os.path.dirname(imufuse.__file__)),
         os.path.dirname(os.path.dirname(imufuse_c.__file__))]

# the child runs the command and reports its own wall time and the peak RSS of
# the imufuse process (RUSAGE_CHILDREN of a fresh parent: that process only)
_WRAP = """
import json, resource, subprocess, sys, time
t0 = time.perf_counter()
r = subprocess.run(sys.argv[1:], capture_output=True, text=True)
dt = time.perf_counter() - t0
ru = resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({"rc": r.returncode, "s": dt, "cpu_s": ru.ru_utime + ru.ru_stime,
                  "rss_mb": ru.ru_maxrss / 1024.0, "err": r.stderr[-500:]}))
"""


@pytest.fixture(scope="module")
def big_log(tmp_path_factory):
    """10^6 rows: time, gyr, acc (rad/s, g) written with 7 significant digits,
    ~70 MB like the log of the issue."""
    p = tmp_path_factory.mktemp("biglog") / "big.csv"
    rng = np.random.default_rng(0)
    t = np.arange(ROWS) / 200.0
    gyr = rng.normal(scale=0.2, size=(ROWS, 3))
    acc = rng.normal(scale=0.05, size=(ROWS, 3)) + [0, 0, 1]
    M = np.column_stack([t, gyr, acc])
    with open(p, "w") as fh:
        fh.write("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n")
        row = "%.7g," * 6 + "%.7g\n"
        for k in range(0, ROWS, 50000):
            blk = M[k:k + 50000]
            fh.write((row * len(blk)) % tuple(blk.ravel().tolist()))
    return p


def _measure(*args):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(PATHS))
    out = subprocess.run([sys.executable, "-c", _WRAP, sys.executable, "-m", "imufuse", *map(str, args)],
                         env=env, capture_output=True, text=True, check=True)
    res = json.loads(out.stdout)
    assert res["rc"] == 0, res["err"]
    return res


@pytest.mark.parametrize("out", ["npz", "csv"])
def test_run_million_rows(benchmark, big_log, tmp_path, out):
    o = tmp_path / f"out.{out}"
    res = {}

    def go():
        res.update(_measure("run", big_log, "-f", "MadgwickIMU", "-o", o))
    benchmark.pedantic(go, rounds=1, iterations=1)
    benchmark.extra_info.update(rows=ROWS, file_mb=os.path.getsize(big_log) / 1e6,
                                wall_s=res["s"], cpu_s=res["cpu_s"], peak_rss_mb=res["rss_mb"])
    print(f"\nrun -o OUT.{out}: {ROWS} rows ({os.path.getsize(big_log) / 1e6:.0f} MB) in "
          f"{res['s']:.2f} s wall, {res['cpu_s']:.2f} s CPU, peak RSS {res['rss_mb']:.0f} MB")


def test_read_log_million_rows(benchmark, big_log):
    log = benchmark.pedantic(io.read_log, args=(big_log,), rounds=1, iterations=1)
    assert len(log) == ROWS


def test_log_gyr_access(benchmark):
    """Log.gyr once computed: an update() loop may index it per sample (issue: 1.4 ms when it
    was rebuilt on every access)."""
    from imufuse.io import example_log, read_log
    log = read_log(example_log())
    first = log.gyr
    assert benchmark(lambda: log.gyr) is first
