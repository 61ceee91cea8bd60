"""Runs of True in a boolean array: the still stretches of a log (imufuse.calibration.fit's
rests, imufuse.plausible's still gyro) are found by the one function here.

  runs(mask)      [(start, stop), ...] of each run of True (stop exclusive)
  longest(mask)   the first longest run, (0, 0) without one
"""
from typing import List, Tuple

import numpy as np


def runs(mask) -> List[Tuple[int, int]]:
    """(start, stop) of the runs of True in a boolean array (stop exclusive)."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.diff(m.astype(np.int8))
    return [(int(s), int(e)) for s, e in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1))]


def longest(mask) -> Tuple[int, int]:
    """The first of the longest runs of True, (start, stop); (0, 0) if there is none."""
    return max(runs(mask), key=lambda r: r[1] - r[0], default=(0, 0))
