"""Host speed of the recommended AHRS beside MadgwickAHRS and VQF (vqf's updateBatch),
side by side in one run (pytest-benchmark; `pytest bench/test_bench_robust.py -s`).

Each callable runs a 9-D batch of N samples (a simulated rotation with a passing magnet,
285.714 Hz); the timings are the minimum of several interleaved repeats, in ns per
sample, stored in extra_info and printed.
"""
import os
import time
import types

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


# ---- every length, side by side with VQF ----------------------------------------------

LENGTHS = (10, 1_000, 100_000, 1_000_000)
#: samples run per timed round at each length (short runs repeated: the per-call cost counts)
PER_ROUND = 100_000


#: a real recording when the BROAD development trials are at hand (research/broad_compare.py)
BROAD = os.environ.get("IMUFUSE_BROAD", os.path.join(os.path.dirname(__file__), "..", "..",
                                                      "shared", "data", "broad"))
BROAD_TRIAL = "09_undisturbed_fast_rotation_with_breaks_B.npz"


@pytest.fixture(scope="module", params=["sim", "broad"])
def recording(request, data):
    # (name, dt, gyr, acc, mag): the simulation above, or BROAD's trial 9 (fast rotations,
    # rests, the heading in use), skipped without it
    if request.param == "sim":
        return "sim", data.dt, data.gyr, data.acc, data.mag
    path = os.path.join(BROAD, BROAD_TRIAL)
    if not os.path.exists(path):
        pytest.skip(f"no BROAD trial at {path} (IMUFUSE_BROAD)")
    d = np.load(path)
    return "broad", 1.0 / float(d["rate"]), d["gyr"], d["acc"], d["mag"]


def _length_callables(rec, n):
    # the recording tiled to n samples (a wrap every trial: the speed does not care)
    _, dt, gyr, acc, mag = rec
    s = types.SimpleNamespace(dt=dt)
    reps = -(-n // len(gyr))
    g, a, m = (np.ascontiguousarray(np.tile(v, (reps, 1))[:n], dtype=np.float64)
               for v in (gyr, acc, mag))
    g32, a32, m32 = (v.astype(np.float32) for v in (g, a, m))
    calls = {
        "RobustAHRS f64 q": lambda: imufuse_c.RobustAHRS(s.dt).run(g, a, m, outputs="q"),
        "RobustAHRS f32 q": lambda: imufuse_c.RobustAHRS(s.dt, dtype="float32").run(
            g32, a32, m32, outputs="q"),
        "RobustIMU f64 q": lambda: imufuse_c.RobustIMU(s.dt).run(g, a, outputs="q"),
    }
    if n <= 100_000:  # the full state: 81 words per sample (648 MB at 10^6 in float64)
        calls["RobustAHRS f64 state"] = lambda: imufuse_c.RobustAHRS(s.dt).run(g, a, m)
    try:
        from vqf import VQF
        calls["VQF 9D f64"] = lambda: VQF(s.dt).updateBatch(g, a, m)
    except ImportError:
        pass
    return calls


def _per_sample(calls, n, rounds):
    # the minimum over interleaved rounds of the time per sample, ns
    k = max(1, PER_ROUND // n)
    best = {name: float("inf") for name in calls}
    for _ in range(rounds):
        for name, f in calls.items():
            t0 = time.perf_counter()
            for _ in range(k):
                f()
            best[name] = min(best[name], (time.perf_counter() - t0) / (k * n))
    return {name: v * 1e9 for name, v in best.items()}


@pytest.mark.parametrize("n", LENGTHS)
def test_lengths_vs_vqf(benchmark, recording, n):
    calls = _length_callables(recording, n)
    ns = _per_sample(calls, n, rounds=3 if n >= 1_000_000 else 7)
    benchmark.extra_info.update({k: round(v, 1) for k, v in ns.items()})
    benchmark.pedantic(calls["RobustAHRS f64 q"], rounds=1, iterations=1)
    vqf = ns.get("VQF 9D f64")
    print()
    for k, v in ns.items():
        ratio = f"  VQF / this {vqf / v:5.2f}" if vqf else ""
        print(f"{recording[0]:5s} n={n:>9} {k:22s} {v:8.1f} ns/sample{ratio}")
