"""Speed of the Fusion suite (pytest-benchmark; `pytest bench/test_bench_fusion.py`).

  run       imufuse_c FusionAHRS.run() with magnetometer, per-sample dt -> ns per sample
  outputs   FusionAHRS.outputs_batch() over the run's states          -> ns per sample
  update    FusionAHRS.update() per call from Python                   -> ns per call
  reference the pure-Python twin, per sample
  offset    FusionOffset.run()                                         -> ns per sample
"""
import numpy as np
import pytest

import imufuse.reference as reference
import imufuse_c

N_RUN = 10 ** 6
N_REF = 2000
SETTINGS = dict(gain=0.5, gyroscope_range=2000.0, acceleration_rejection=10.0,
                magnetic_rejection=10.0, recovery_trigger_period=500)


def inputs(n, dtype):
    g = np.random.default_rng(0)
    gyr = g.normal(0, 30, (n, 3)).astype(dtype)
    acc = (g.normal(0, 0.2, (n, 3)) + [0, 0, 1]).astype(dtype)
    mag = (g.normal(0, 0.1, (n, 3)) + [0.4, 0, -0.8]).astype(dtype)
    dt = g.uniform(0.0076, 0.0302, n).astype(dtype)
    return gyr, acc, mag, dt


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_run(benchmark, dtype):
    gyr, acc, mag, dt = inputs(N_RUN, dtype)
    f = imufuse_c.FusionAHRS(**SETTINGS, dtype=dtype)
    benchmark.extra_info["samples"] = N_RUN
    S = benchmark(lambda: f.run(gyr, acc, mag, dt=dt))
    assert S.shape == (N_RUN, 22)


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_outputs(benchmark, dtype):
    gyr, acc, mag, dt = inputs(N_RUN, dtype)
    f = imufuse_c.FusionAHRS(**SETTINGS, dtype=dtype)
    S = f.run(gyr, acc, mag, dt=dt)
    benchmark.extra_info["samples"] = N_RUN
    out = benchmark(lambda: f.outputs_batch(S))
    assert out["euler"].shape == (N_RUN, 3)


def test_update(benchmark):
    gyr, acc, mag, dt = inputs(1, "float64")
    f = imufuse_c.FusionAHRS(**SETTINGS)
    g, a, m, d = gyr[0], acc[0], mag[0], float(dt[0])
    benchmark(lambda: f.update(g, a, m, d))


def test_reference(benchmark):
    gyr, acc, mag, dt = inputs(N_REF, "float32")
    benchmark.extra_info["samples"] = N_REF
    benchmark.pedantic(lambda: reference.FusionAHRS(**SETTINGS, dtype="float32").run(
        gyr, acc, mag, dt=dt), rounds=3)


def test_offset(benchmark):
    gyr, _, _, _ = inputs(N_RUN, "float32")
    f = imufuse_c.FusionOffset(100, dtype="float32")
    benchmark.extra_info["samples"] = N_RUN
    benchmark(lambda: f.run(gyr))
