"""Parameter search at the machine's limit (issues 28 and 50): `tune` on the seven BROAD
development trials, float64, 20 values of one gain (MadgwickAHRS: beta; RobustAHRS: tau_acc),
no refinement, 2 threads, the two filters measured side by side in one run (best of 3)
against

  - the compute-only limit: samples x sets x (ns per scalar update, from run()) / cores; and
    in CPU time (every thread's), which the load of other processes on a shared machine
    does not inflate: tune's CPU against samples x sets x (CPU ns per scalar update);
  - scoring each set in Python (Tuner with batch=False: run() + imufuse.evaluation);
  - the batch API without scores (run_many, trajectories) against a loop of run();
  - the lanes against each filter's own update (run_filters, scored, lanes=0).

    pytest bench/test_bench_tune.py --benchmark-only -s

Prints the table that bench/RESULTS.md and the README's speed section quote."""
import glob
import os
import time

import numpy as np
import pytest

import imufuse_c
from imufuse.evaluation import prepare_reference
from imufuse.session import Session
from imufuse.tune import Tuner

from broad_data import BROAD, SKIP_REASON  # tests/broad_data.py (tests on the suite's pythonpath)
from timing import best_of

SETS, CORES = 20, 2
# the filters and the gain each search sweeps (20 values, log-spaced)
SEARCHES = [("MadgwickAHRS", "beta", (0.01, 1.0)), ("RobustAHRS", "tau_acc", (0.25, 25.0))]


def _measure(sessions, name, gain, span):
    samples = sum(len(s.log) for s in sessions)
    grid = [(gain, list(np.geomspace(span[0], span[1], SETS)))]
    tuner = Tuner(sessions, name)
    cls = getattr(imufuse_c, name)
    ins = [s.inputs(name)[0] for s in sessions]
    dt = sessions[0].dt()

    def scalar_runs():
        for x in ins:
            cls(dt=dt, init="first").run(*x)
    ns_update = best_of(scalar_runs, 5) / samples * 1e9
    limit = samples * SETS * ns_update * 1e-9 / CORES
    cpu_update = best_of(scalar_runs, 5, time.process_time) / samples * 1e9

    def tune():
        tuner.batch = True
        return tuner.search(grid, refine=0, jobs=CORES)
    t_tune = best_of(tune)
    cpu_tune = best_of(tune, 3, time.process_time)
    tuner.batch = False
    t_python = best_of(lambda: tuner.search(grid, refine=0, jobs=CORES))
    tuner.batch = True

    params = [{"dt": dt, gain: v, "init": "first"} for v in grid[0][1]]
    x = ins[0]
    t_loop = best_of(lambda: [cls(**p).run(*x) for p in params])
    t_many = best_of(lambda: cls.run_many(params, *x, threads=1))
    ref = prepare_reference(sessions[0].log.q_ref, ref_frame=sessions[0].ref_frame(),
                            movement=sessions[0].mask())
    lanes = {w: best_of(lambda w=w: cls.run_many(params, *x, score=ref, lanes=w, threads=1))
             for w in (0, *imufuse_c.lane_widths())}
    rows = [
        ("swept gain", gain),
        ("samples (7 trials)", f"{samples}"),
        ("scalar update (run()), ns per sample", f"{ns_update:.1f}"),
        (f"compute-only limit, {SETS} sets / {CORES} cores, s", f"{limit:.3f}"),
        ("tune (compiled batch), s", f"{t_tune:.3f}"),
        ("**tune / limit**", f"**{t_tune / limit:.2f}**"),
        ("scalar update, CPU ns per sample", f"{cpu_update:.1f}"),
        ("tune CPU / the limit's CPU (samples x sets x CPU ns)",
         f"{cpu_tune / (samples * SETS * cpu_update * 1e-9):.2f}"),
        ("tune scoring each set in Python, s", f"{t_python:.3f}"),
        ("Python scoring / compiled batch", f"{t_python / t_tune:.1f}"),
        (f"loop of run(), {SETS} sets, one trial, 1 thread, s", f"{t_loop:.3f}"),
        ("run_many (trajectories) / loop of run()", f"{t_many / t_loop:.2f}"),
    ]
    for w, t in lanes.items():
        what = ("own update" if w == 0 else
                f"{w} lane{'s' if w > 1 else ''} ({imufuse_c.lane_widths()[w]})")
        rows.append((f"scored run_many, {what}, s (ratio to own update)",
                     f"{t:.4f} ({t / lanes[0]:.2f})"))
    return rows, tune


@pytest.mark.skipif(BROAD is None, reason=SKIP_REASON)
def test_tune_against_compute_limit(benchmark):
    sessions = [Session(p) for p in sorted(glob.glob(os.path.join(BROAD, "*.npz")))]
    measured = [_measure(sessions, name, gain, span) for name, gain, span in SEARCHES]
    names = [name for name, _, _ in SEARCHES]
    print("\n| measure | " + " | ".join(names) + " |\n|---|" + "---:|" * len(names))
    for i, (k, _) in enumerate(measured[0][0]):
        print(f"| {k} | " + " | ".join(rows[i][1] for rows, _ in measured) + " |")
    for name, (rows, _) in zip(names, measured):
        benchmark.extra_info.update({f"{name}: {k}": v for k, v in rows})
    benchmark.pedantic(measured[-1][1], rounds=3, iterations=1)
