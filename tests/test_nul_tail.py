"""A CSV log from a preallocated SD-card file: the rows, then NUL bytes to the end. Read up to
the NUL tail with a note, in memory bounded by the rows (not the file's size); a row cut by
the tail is dropped and named; NUL bytes inside the text are still an error."""
import tracemalloc

import numpy as np
import pytest

from imufuse import io, sim
from imufuse.io import LogError, read_log


@pytest.fixture
def rows(tmp_path):
    d = sim.imu("slow", rate=100.0, duration=10.0, seed=1)
    p = tmp_path / "log.csv"
    io.write_log(str(p), d.t, d.gyr, d.acc)
    return p, d


def test_a_nul_tail_is_the_end_of_the_log(rows):
    p, d = rows
    text = p.read_bytes()
    with open(p, "ab") as fh:
        fh.write(b"\0" * (40 << 20))                     # 40 MB of preallocated space
    tracemalloc.start()
    try:
        log = read_log(str(p))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(log) == len(d.t) and np.array_equal(log.gyr, np.asarray(d.gyr, dtype=np.float64))
    assert any("ends in NUL bytes after line" in w for w in log.warnings), log.warnings
    assert peak < 20e6, f"{peak / 1e6:.0f} MB for {len(text) / 1e6:.1f} MB of rows"


def test_a_small_file_with_a_nul_tail_and_a_cut_row(tmp_path):
    p = tmp_path / "small.csv"
    p.write_bytes(b"time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,1\n0.01,0,0,0,0,0,1\n"
                  b"0.02,0,0," + b"\0" * 5000)
    log = read_log(str(p))
    assert len(log) == 2
    assert any("a row cut by them was dropped ('0.02,0,0,')" in w for w in log.warnings)


def test_nul_inside_the_text_is_still_an_error(tmp_path):
    p = tmp_path / "mixed.csv"
    p.write_bytes(b"time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0\0,0,0,0,1\n0.01,0,0,0,0,0,1\n")
    with pytest.raises(LogError, match="NUL"):
        read_log(str(p))


def test_a_2_gb_preallocated_file_reads_in_bounded_memory_and_time(rows, tmp_path):
    """The case as it happens: 10 s of rows, then a NUL-filled preallocation to 2 GB (sparse
    here, as most file systems store it). Read in a fresh process: peak resident memory below
    150 MB (it was 21 GB for a 2 GB file), the tail found in a few block reads, the rows all
    there."""
    import subprocess
    import sys
    p, d = rows
    with open(p, "ab") as fh:
        fh.truncate(2 << 30)
    # the child's own peak (VmHWM of its new address space): ru_maxrss is carried over from
    # the parent through fork and exec, and a long pytest process is large
    code = ("import re, sys, time\nfrom imufuse.io import read_log\n"
            "t = time.perf_counter()\nlog = read_log(sys.argv[1])\n"
            "hwm = re.search(r'VmHWM:\\s*(\\d+)', open('/proc/self/status').read()).group(1)\n"
            "print(len(log), time.perf_counter() - t, hwm)\n")
    r = subprocess.run([sys.executable, "-c", code, str(p)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    n, seconds, rss_kb = r.stdout.split()
    assert int(n) == len(d.t)
    assert int(rss_kb) < 150_000, f"peak RSS {int(rss_kb) / 1e3:.0f} MB"
    assert float(seconds) < 30.0
