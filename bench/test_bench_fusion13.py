"""Speed of Fusion 1.3 (pytest-benchmark; `pytest bench/test_bench_fusion13.py`), beside
bench/test_bench_fusion.py's 1.2.3 port with the same inputs.

  run       imufuse_c FusionAHRS13.run() with magnetometer, measured period -> ns per sample
  update    FusionAHRS13.update() per call from Python                       -> ns per call
  reference the pure-Python twin, per sample
  bias      FusionBias.run()                                                 -> ns per sample
"""
import pytest

import imufuse.reference as reference
import imufuse_c
from imufuse.reference._fusion13 import ADVANCED

from test_bench_fusion import N_REF, N_RUN, inputs


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_run(benchmark, dtype):
    gyr, acc, mag, dt = inputs(N_RUN, dtype)
    f = imufuse_c.FusionAHRS13(**ADVANCED, dtype=dtype)
    benchmark.extra_info["samples"] = N_RUN
    S = benchmark(lambda: f.run(gyr, acc, mag, dt=dt))
    assert S.shape == (N_RUN, 23)


def test_update(benchmark):
    gyr, acc, mag, dt = inputs(1, "float64")
    f = imufuse_c.FusionAHRS13(**ADVANCED)
    g, a, m, d = gyr[0], acc[0], mag[0], float(dt[0])
    benchmark(lambda: f.update(g, a, m, d))


def test_reference(benchmark):
    gyr, acc, mag, dt = inputs(N_REF, "float32")
    benchmark.extra_info["samples"] = N_REF
    benchmark.pedantic(lambda: reference.FusionAHRS13(**ADVANCED, dtype="float32").run(
        gyr, acc, mag, dt=dt), rounds=3)


def test_bias(benchmark):
    gyr, _, _, _ = inputs(N_RUN, "float32")
    f = imufuse_c.FusionBias(100.0, dtype="float32")
    benchmark.extra_info["samples"] = N_RUN
    benchmark(lambda: f.run(gyr))
