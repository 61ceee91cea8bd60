"""Pure-Python twins of the compiled filters in imufuse_c: same names, same
signatures, same state, bit for bit the same results."""
from ._base import ReferenceFilter
from .filters_1d import (Complementary1D, Complementary1DBias, Kalman1D, Kalman1DBias,
                         Mahony1D, Mahony1DBias, tuning)

FILTERS_1D = ("Complementary1D", "Kalman1D", "Mahony1D",
              "Kalman1DBias", "Mahony1DBias", "Complementary1DBias")

#: every float filter, by class name (the compiled package exports the same names)
FILTERS = FILTERS_1D

__all__ = ["ReferenceFilter", "FILTERS", "tuning", *FILTERS]
