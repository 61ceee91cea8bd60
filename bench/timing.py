"""The one timing helper of the bench modules that time a callable on their own (beside
pytest-benchmark's figure): the shortest of a few runs, the least disturbed by a shared
machine's load."""
import time


def best_of(fn, repeats=3):
    """The shortest wall time (s) of `repeats` calls of fn()."""
    t = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        t.append(time.perf_counter() - t0)
    return min(t)
