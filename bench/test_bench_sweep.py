"""A sweep over 1 000 recordings: `Tuner.search` of MadgwickAHRS (8 betas, one refinement
round) on 1 000 simulated recordings (20 s at 100 Hz each, NPZ with a reference), run on a
local dask.distributed cluster of two worker processes (the workers read the recordings
from their paths) and in this process (the recordings read here first), side by side:
wall time per recording and what the two runs' best sets and scores are (identical).

    pytest bench/test_bench_sweep.py --benchmark-only -s -p no:xdist
"""
import time

import numpy as np
import pytest

from imufuse import sim
from imufuse.session import ScoreOptions, Session
from imufuse.tune import Tuner

distributed = pytest.importorskip("dask.distributed", reason="the sweep runs on a dask "
                                  "cluster: pip install 'dask[distributed]'")

N = 1000
GRID = [("beta", list(np.geomspace(0.005, 0.5, 8)))]
SCORE = ScoreOptions(ref_frame="NWU")


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep1000")
    base = [sim.imu("fast", rate=100.0, duration=20.0, seed=s) for s in range(10)]
    rng = np.random.default_rng(0)
    paths = []
    for k in range(N):
        s = base[k % len(base)]
        p = d / f"rec{k:04d}.npz"
        noise = rng.normal(scale=0.002, size=s.gyr.shape)
        np.savez(p, gyr=s.gyr + noise, acc=s.acc * 9.81, mag=s.mag, quat_ref=s.q_true,
                 rate=100.0)
        paths.append(str(p))
    return paths


def test_sweep_of_1000_recordings(benchmark, recordings):
    t0 = time.perf_counter()
    local = Tuner([Session(p) for p in recordings], "MadgwickAHRS", score=SCORE)
    a = local.search(GRID, refine=1)
    here = time.perf_counter() - t0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as c, distributed.Client(c) as client:
        t0 = time.perf_counter()
        remote = Tuner(recordings, "MadgwickAHRS", score=SCORE)
        b = benchmark.pedantic(remote.search, args=(GRID,),
                               kwargs=dict(refine=1, executor=client.get_executor()),
                               rounds=1, iterations=1)
        there = time.perf_counter() - t0
    assert a.best == b.best and a.score(a.best) == b.score(b.best)
    sets = len(a.results)
    benchmark.extra_info.update(recordings=N, sets=sets, local_s=here, cluster_s=there)
    print(f"\n{N} recordings x {sets} sets (2 rounds): in this process {here:.1f} s "
          f"({1e3 * here / N:.1f} ms per recording, reading included); on a local dask "
          f"cluster of 2 worker processes {there:.1f} s ({1e3 * there / N:.1f} ms per "
          f"recording: {N * 2} tasks, each reading its recording); best beta "
          f"{a.best[0]:.4g}, the same on both")
