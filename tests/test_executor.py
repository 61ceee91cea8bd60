"""Sweeps beyond one machine: Tuner.search and compare_logs take any
concurrent.futures.Executor; a dask.distributed cluster of worker processes (a local one
here) and a process pool give the local run's results to the bit, the logs read by the
workers from their paths. The command line's --executor is the same code.
"""
import concurrent.futures as cf
import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from imufuse import sim
from imufuse.comparison import compare_logs
from imufuse.session import ReadOptions, ScoreOptions, Session
from imufuse.tune import Tuner

distributed = pytest.importorskip("dask.distributed", reason="dask[distributed] is in the test "
                                  "extra; install it to run the cluster tests")

SCORE = ScoreOptions(ref_frame="NWU")
GRID = [("beta", [0.01, 0.05, 0.2, -1.0])]        # -1: refused by the filter, on every log


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    paths = []
    for seed in (3, 4, 5):
        s = sim.imu("fast", rate=200.0, duration=6.0, seed=seed)
        p = d / f"log{seed}.npz"
        np.savez(p, gyr=s.gyr, acc=s.acc * 9.81, mag=s.mag, quat_ref=s.q_true, rate=200.0)
        paths.append(str(p))
    return paths


@pytest.fixture(scope="module")
def cluster():
    """A local dask.distributed cluster of two worker processes, one thread each."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as c, distributed.Client(c) as client:
        yield client


def _same(a, b):
    assert set(a.results) == set(b.results)
    for p, (s, evs) in a.results.items():
        t, fvs = b.results[p]
        if isinstance(evs, str):
            assert math.isnan(s) and math.isnan(t) and evs == fvs
            continue
        assert s == t, p                                     # to the bit
        assert [e.total for e in evs] == [e.total for e in fvs]
    assert a.best == b.best


@pytest.mark.parametrize("name", ["MadgwickAHRS", "MahonyIMU"])
def test_tune_on_a_dask_cluster_is_the_local_run(logs, cluster, name):
    local = Tuner([Session(p) for p in logs], name, score=SCORE)
    remote = Tuner(logs, name, score=SCORE)
    grid = GRID if name == "MadgwickAHRS" else [("kp", [0.3, 1.0, 3.0])]
    seen = []
    a = local.search(grid, refine=1)
    b = remote.search(grid, refine=1, executor=cluster.get_executor(),
                      progress=lambda n, k: seen.append((n, k)))
    _same(a, b)
    assert seen[-1] == (len(logs), len(logs))
    # the driver read none of the logs: the workers read them
    assert not remote._sessions


def test_tune_in_a_process_pool_and_python_scoring(logs):
    """A process pool, and the sets scored in Python (the reference backend's path)."""
    local = Tuner([Session(p) for p in logs], "MadgwickIMU", score=SCORE)
    local.batch = False
    with cf.ProcessPoolExecutor(2) as ex:
        remote = Tuner(logs, "MadgwickIMU", score=SCORE)
        remote.batch = False
        _same(local.search(GRID, refine=0), remote.search(GRID, refine=0, executor=ex))


def test_a_log_without_reference_is_named_from_the_worker(logs, tmp_path, cluster):
    s = sim.imu("fast", rate=200.0, duration=2.0, seed=9)
    bare = tmp_path / "bare.npz"
    np.savez(bare, gyr=s.gyr, acc=s.acc * 9.81, rate=200.0)
    t = Tuner([logs[0], str(bare)], "MadgwickIMU", score=SCORE)
    with pytest.raises(ValueError, match="bare.npz: no reference orientation"):
        t.search(GRID, refine=0, executor=cluster.get_executor())


def test_compare_logs_on_a_cluster_is_the_local_run(logs, cluster):
    filters = ["MadgwickAHRS", "MahonyAHRS", "RobustAHRS"]
    a = compare_logs(logs, filters, read=ReadOptions(), score=SCORE)
    b = compare_logs(logs, filters, read=ReadOptions(), score=SCORE,
                     executor=cluster.get_executor())
    assert [x.path for x in a.logs] == [x.path for x in b.logs] == logs
    assert a.means() == b.means()
    for x, y in zip(a.logs, b.logs):
        for f in filters:
            u, v = x.results[f], y.results[f]
            assert (u.evaluation.total, u.evaluation.inclination) == \
                (v.evaluation.total, v.evaluation.inclination)
            assert np.array_equal(u.final, v.final)


def test_the_command_line_executor(logs):
    base = [sys.executable, "-m", "imufuse", "tune", *logs, "-f", "MadgwickIMU", "--grid",
            "beta=0.02,0.1", "--refine", "0", "--ref-frame", "NWU"]
    env = dict(os.environ, COLUMNS="200")
    here = subprocess.run(base, capture_output=True, text=True, env=env, timeout=300)
    pool = subprocess.run(base + ["--executor", "processes:2"], capture_output=True, text=True,
                          env=env, timeout=300)
    assert here.returncode == 0, here.stderr
    assert pool.returncode == 0, pool.stderr
    assert pool.stdout == here.stdout
    bad = subprocess.run(base + ["--executor", "threads"], capture_output=True, text=True,
                         env=env, timeout=300)
    assert bad.returncode == 2 and "processes[:N], dask:ADDRESS or dask-local[:N]" in bad.stderr


def test_compare_on_the_command_line_with_an_executor(logs):
    """`imufuse compare LOG... --executor processes:2`: the same tables and means as here."""
    base = [sys.executable, "-m", "imufuse", "compare", *logs, "-f", "MadgwickAHRS,MahonyIMU",
            "--ref-frame", "NWU"]
    here = subprocess.run(base, capture_output=True, text=True, timeout=300)
    pool = subprocess.run(base + ["--executor", "processes:2"], capture_output=True, text=True,
                          timeout=300)
    assert here.returncode == 0 and pool.returncode == 0, (here.stderr, pool.stderr)

    def table(out):          # the timing column (samples per second) differs between runs
        return [re.sub(r"\d(?:\.\d+)?e[+-]\d+", "RATE", ln).split() for ln in out.splitlines()]
    assert table(pool.stdout) == table(here.stdout)
    assert sum("MadgwickAHRS" in ln for ln in pool.stdout.splitlines()) >= 4   # 3 logs, mean


def test_the_docs_example_runs():
    """docs/logs.md's executor example, as written (a local cluster of two workers)."""
    docs = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "logs.md")
    block = next(b for b in re.findall(r"```python\n(.*?)```", open(docs).read(), re.S)
                 if "executor=" in b)
    exec(compile(block, "docs/logs.md", "exec"), {})
