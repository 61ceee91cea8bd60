"""The one timing helper of the bench modules that time a callable on their own (beside
pytest-benchmark's figure): the shortest of a few runs, the least disturbed by a shared
machine's load."""
import time


def best_of(fn, repeats=3, clock=time.perf_counter):
    """The shortest wall time (s) of `repeats` calls of fn(); clock=time.process_time: the
    shortest CPU time of the process (every thread), which other processes' load on a shared
    machine does not inflate."""
    t = []
    for _ in range(repeats):
        t0 = clock()
        fn()
        t.append(clock() - t0)
    return min(t)
