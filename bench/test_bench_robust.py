"""Host speed of the recommended AHRS beside MadgwickAHRS and VQF (vqf's updateBatch),
side by side in one run (pytest-benchmark; `pytest bench/test_bench_robust.py -s`).

Each callable runs a 9-D batch of N samples (a simulated rotation with a passing magnet,
285.714 Hz); the timings are the minimum of several interleaved repeats, in ns per
sample, stored in extra_info and printed.
"""
import time

import numpy as np
import pytest

import imufuse_c
from imufuse.sim import disturb as sim_disturb

N = 200_000


@pytest.fixture(scope="module")
def data():
    s = sim_disturb.scenario("magnet_passing", duration=N / 285.714, rest=5.0)
    return s


def _callables(s):
    g = np.ascontiguousarray(s.gyr)
    a = np.ascontiguousarray(s.acc)
    m = np.ascontiguousarray(s.mag)
    calls = {
        "RobustAHRS float64": lambda: imufuse_c.RobustAHRS(s.dt).run(g, a, m),
        "RobustAHRS float32": lambda: imufuse_c.RobustAHRS(s.dt, dtype="float32").run(
            g.astype(np.float32), a.astype(np.float32), m.astype(np.float32)),
        "RobustIMU float64": lambda: imufuse_c.RobustIMU(s.dt).run(g, a),
        "MadgwickAHRS float64": lambda: imufuse_c.MadgwickAHRS(s.dt, beta=0.1).run(g, a, m),
    }
    try:
        from vqf import VQF
        calls["vqf VQF.updateBatch (9D)"] = lambda: VQF(s.dt).updateBatch(g, a, m)
    except ImportError:
        pass
    return calls


def test_side_by_side(benchmark, data):
    calls = _callables(data)
    best = {k: float("inf") for k in calls}
    for _ in range(5):
        for k, f in calls.items():
            t0 = time.perf_counter()
            f()
            best[k] = min(best[k], time.perf_counter() - t0)
    ns = {k: v / N * 1e9 for k, v in best.items()}
    benchmark.extra_info.update({k: round(v, 1) for k, v in ns.items()})
    benchmark.pedantic(calls["RobustAHRS float64"], rounds=3, iterations=1)
    for k, v in ns.items():
        print(f"{k:28s} {v:8.1f} ns/sample")
