"""Speed of Nair's variometer (pytest-benchmark; `pytest bench/test_bench_vario.py`).

  run        imufuse_c VarioKF.run() on 10^6 barometer samples -> ns per sample
  update     VarioKF.update() per call from Python
  reference  the pure-Python twin, per sample
  vertical   imufuse_c.vertical_accel on 10^6 IMU samples
"""
import numpy as np
import pytest

import imufuse.reference as reference
import imufuse_c

N_RUN = 10 ** 6
N_REF = 2000
DTYPES = ("float32", "float64")


def inputs(n, dtype):
    g = np.random.default_rng(0)
    return (g.normal(0, 50, n).astype(dtype), (1e5 + np.cumsum(g.normal(0, 10, n))).astype(dtype),
            np.full(n, 0.02, dtype=dtype))


@pytest.mark.parametrize("predict", ["seed", "model"])
@pytest.mark.parametrize("dtype", DTYPES)
def test_run(benchmark, dtype, predict):
    x = inputs(N_RUN, dtype)
    f = imufuse_c.VarioKF(predict=predict, dtype=dtype)
    benchmark.extra_info.update(samples=N_RUN)
    benchmark.pedantic(lambda: f.run(*x), setup=f.reset, rounds=3, iterations=1)


def test_update(benchmark):
    f = imufuse_c.VarioKF(z0=0.0)
    benchmark(f.update, 12.0, 3.0, 0.02)


@pytest.mark.parametrize("dtype", DTYPES)
def test_reference(benchmark, dtype):
    x = inputs(N_REF, dtype)
    f = reference.VarioKF(dtype=dtype)
    benchmark.extra_info.update(samples=N_REF)
    benchmark.pedantic(lambda: f.run(*x), setup=f.reset, rounds=2, iterations=1)


@pytest.mark.parametrize("dtype", DTYPES)
def test_vertical_accel(benchmark, dtype):
    g = np.random.default_rng(1)
    q = g.normal(size=(N_RUN, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q, a = q.astype(dtype), g.normal(0, 1, (N_RUN, 3)).astype(dtype)
    benchmark.extra_info.update(samples=N_RUN)
    benchmark.pedantic(lambda: imufuse_c.vertical_accel(q, a, dtype=dtype), rounds=3,
                       iterations=1)
