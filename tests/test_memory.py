"""Memory bounded by what is printed (docs/robustness.md): `imufuse compare` and `imufuse run`
keep a filter's estimate, never its trajectory, so their peak memory on a long log is the
log's own arrays plus a bounded amount per sample, whatever the filter's state size.

Each command runs in a fresh child whose peak resident size (ru_maxrss) is measured; the
peak of the same command on a 1 000-sample log is subtracted (the interpreter, numpy and
imufuse themselves). The bound, per sample of a log with 13 values a sample (gyr, acc, mag,
the reference quaternion; 104 bytes as float64), is MAX_BYTES_PER_SAMPLE: the log's columns
(104 B) and the (N, 3) inputs the filter reads (72 B), the estimate (32 B), the reference
quaternion (32 B) and the scorer's flags. Keeping RobustAHRS's 80-word trajectory in
float64 alone is 640 B a sample (the code before measured 1 400 B at 10^7 samples: 14 GB).
"""
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

MAX_BYTES_PER_SAMPLE = 300

# the peak resident size of a command run in a fresh child (bytes)
PEAK = textwrap.dedent("""
    import resource, subprocess, sys
    r = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if r.returncode:
        sys.exit("failed: " + r.stderr[-2000:])
    print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024)
""")


def _log(path, n, rate=200.0):
    """A BROAD-layout NPZ of n samples: a slow yaw swing, reference in NWU."""
    t = np.arange(n) / rate
    w = 0.3 * np.sin(2 * np.pi * t / 40.0)
    th = np.cumsum(w) / rate
    del t
    gyr = np.zeros((n, 3))
    gyr[:, 2] = w
    del w
    acc = np.zeros((n, 3))
    acc[:, 2] = 9.81
    c, s = np.cos(th), np.sin(th)
    mag = np.stack([20.0 * c, -20.0 * s, np.full(n, -40.0)], axis=1)
    del c, s
    q = np.zeros((n, 4))
    q[:, 0], q[:, 3] = np.cos(th / 2), np.sin(th / 2)
    # float32 in the file (half the bytes to write); the reader's columns are float64 all the same
    np.savez(path, gyr=gyr.astype(np.float32), acc=acc.astype(np.float32),
             mag=mag.astype(np.float32), quat_ref=q.astype(np.float32), rate=np.array(rate))


def _peak(*cmd):
    r = subprocess.run([sys.executable, "-c", PEAK, sys.executable, "-m", "imufuse", *cmd],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return int(r.stdout.strip())


@pytest.mark.parametrize("command,n", [
    (("compare", "{log}", "-f", "RobustAHRS", "--ref-frame", "NWU"), 3_000_000),
    (("run", "{log}", "-f", "RobustAHRS", "--ref-frame", "NWU", "-o", os.devnull), 1_000_000),
])
def test_peak_memory_per_sample(tmp_path, command, n):
    small, big = tmp_path / "small.npz", tmp_path / "big.npz"
    _log(small, 1000)
    _log(big, n)
    base = _peak(*(a.format(log=small) for a in command))
    peak = _peak(*(a.format(log=big) for a in command))
    per = (peak - base) / n
    print(f"{command[0]} of {n} samples: peak {peak / 2**20:.0f} MiB, {per:.0f} B a sample "
          f"above the {base / 2**20:.0f} MiB of a 1000-sample log")
    assert per <= MAX_BYTES_PER_SAMPLE, (command[0], per)
