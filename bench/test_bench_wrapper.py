"""What the Python wrapper costs on top of the C, side by side with the
wrappers of vqf (BasicVQF, Cython over C++) and imufusion (x-io Fusion, C
extension), and a bare C loop (cffi, bench/plain_loop.py).

  run/N       imufuse_c MadgwickIMU.run() on N samples (N = 0: the fixed cost per
              call), against BasicVQF.updateBatch and the bare C loop
  state       reading .state, against imufusion's get_quaternion(); "kept": every
              read kept (the last three in a deque), so that each read is a new
              array (imufuse_c/_stateout.pxi), against the same for imufusion
  update      update() with ndarray rows, against imufusion's update_no_magnetometer
              and BasicVQF.update; "floor": an empty call with the same two
              arguments (operator.is_), to which the C update's own time
              (run() per sample, N = 1000) is added in the table
  update+read the pair, per sample, as a Python loop does it
  convert     a float32 filter given float64 arrays (converted in C, no temporaries)

The filters differ (Madgwick, VQF, Fusion): what is compared is the cost of
getting to the C and back, which is why N = 0 and the per-call operations
matter. `python bench/wrapper_table.py` runs this file and prints the table of
bench/RESULTS.md and the README.
"""
import collections
import operator

import numpy as np
import pytest

import imufuse_c
from imufuse.registry import Case
from test_bench_filters import plain_runner

vqf = pytest.importorskip("vqf", reason="the bench extra: pip install 'imufuse[bench]'")
imufusion = pytest.importorskip("imufusion", reason="the bench extra: pip install 'imufuse[bench]'")

DT = 0.01
NS = (0, 1, 10, 100, 1000)
CASE = Case("MadgwickIMU", dict(dt=DT, beta=0.1))


def _inputs(n, dtype=np.float64):
    g = np.random.default_rng(1)
    gyr = g.normal(0, 0.5, (n, 3))
    acc = g.normal(0, 0.3, (n, 3)) + [0.0, 0.0, 9.81]
    return np.ascontiguousarray(gyr, dtype=dtype), np.ascontiguousarray(acc, dtype=dtype)


@pytest.mark.parametrize("n", NS)
def test_run_imufuse(benchmark, n):
    benchmark.group = f"run N={n}"
    f = imufuse_c.MadgwickIMU(dt=DT, dtype="float64")
    gyr, acc = _inputs(n)
    benchmark.extra_info.update(samples=n)
    benchmark(f.run, gyr, acc)


@pytest.mark.parametrize("n", NS)
def test_run_vqf(benchmark, n):
    benchmark.group = f"run N={n}"
    v = vqf.BasicVQF(DT)
    gyr, acc = _inputs(n)
    benchmark.extra_info.update(samples=n)
    benchmark(v.updateBatch, gyr, acc)


@pytest.mark.parametrize("n", NS)
def test_run_plain_c(benchmark, n):
    """The bare C loop: MadgwickIMU's update and a state copy per sample, called
    through cffi (whose own call costs are part of this figure)."""
    benchmark.group = f"run N={n}"
    gyr, acc = _inputs(n)
    benchmark.extra_info.update(samples=n)
    benchmark(plain_runner(CASE, "float64", (gyr, acc)))


@pytest.mark.parametrize("n", (10, 1000))
def test_run_float32_from_float64(benchmark, n):
    benchmark.group = f"convert N={n}"
    f = imufuse_c.MadgwickIMU(dt=DT, dtype="float32")
    gyr, acc = _inputs(n)
    benchmark(f.run, gyr, acc)


@pytest.mark.parametrize("n", (10, 1000))
def test_run_float32_native(benchmark, n):
    benchmark.group = f"convert N={n}"
    f = imufuse_c.MadgwickIMU(dt=DT, dtype="float32")
    gyr, acc = _inputs(n, np.float32)
    benchmark(f.run, gyr, acc)


def test_state_imufuse(benchmark):
    benchmark.group = "state"
    f = imufuse_c.MadgwickIMU(dt=DT)
    benchmark(operator.attrgetter("state"), f)      # no Python frame around the read


def test_state_imufusion(benchmark):
    benchmark.group = "state"
    a = imufusion.Ahrs()
    benchmark(a.get_quaternion)


def test_state_kept_imufuse(benchmark):
    benchmark.group = "state kept"
    f = imufuse_c.MadgwickIMU(dt=DT)
    keep = collections.deque(maxlen=3)
    benchmark(lambda: keep.append(f.state))


def test_state_kept_imufusion(benchmark):
    benchmark.group = "state kept"
    a = imufusion.Ahrs()
    keep = collections.deque(maxlen=3)
    benchmark(lambda: keep.append(a.get_quaternion()))


def test_update_floor(benchmark):
    benchmark.group = "update"
    gyr, acc = _inputs(1)
    benchmark(operator.is_, gyr[0], acc[0])


def test_update_imufuse(benchmark):
    benchmark.group = "update"
    f = imufuse_c.MadgwickIMU(dt=DT)
    gyr, acc = _inputs(1)
    benchmark(f.update, gyr[0], acc[0])


def test_update_dt_imufuse(benchmark):
    """update(..., dt=) with a per-sample period (a Python float): within a few ns of
    update() (it was 9.5 us through a Python-level check)."""
    benchmark.group = "update"
    f = imufuse_c.MadgwickIMU(dt=DT)
    gyr, acc = _inputs(1)
    benchmark(f.update, gyr[0], acc[0], dt=DT)


def test_update_imufusion(benchmark):
    benchmark.group = "update"
    a = imufusion.Ahrs()
    gyr, acc = _inputs(1)
    benchmark(a.update_no_magnetometer, np.degrees(gyr[0]), acc[0] / 9.81)


def test_update_vqf(benchmark):
    benchmark.group = "update"
    v = vqf.BasicVQF(DT)
    gyr, acc = _inputs(1)
    benchmark(v.update, gyr[0], acc[0])


def test_update_and_read_imufuse(benchmark):
    benchmark.group = "update+read"
    f = imufuse_c.MadgwickIMU(dt=DT)
    gyr, acc = _inputs(1)
    g, a = gyr[0], acc[0]

    def step():
        f.update(g, a)
        return f.state
    benchmark(step)


def test_update_and_read_imufusion(benchmark):
    benchmark.group = "update+read"
    ahrs = imufusion.Ahrs()
    gyr, acc = _inputs(1)
    g, a = np.degrees(gyr[0]), acc[0] / 9.81

    def step():
        ahrs.update_no_magnetometer(g, a)
        return ahrs.get_quaternion()
    benchmark(step)
