"""Pure-Python twins of the compiled filters in imufuse_c: same names, same
signatures, same state, bit for bit the same results.

Each family module (one per csrc/<family>.c) lists its classes in FILTERS.
"""
from . import dcm, filters_1d, kk, madgwick, mahony, mahony2d, multiwii
from ._base import ReferenceFilter
from .filters_1d import tuning

_FAMILIES = (filters_1d, mahony, madgwick, multiwii, kk, mahony2d, dcm)

#: every float filter, by class name (imufuse_c exports the same names)
FILTERS = tuple(name for fam in _FAMILIES for name in fam.FILTERS)
FILTERS_1D = filters_1d.FILTERS

for _fam in _FAMILIES:
    for _name in _fam.FILTERS:
        globals()[_name] = getattr(_fam, _name)

__all__ = ["ReferenceFilter", "FILTERS", "tuning", *FILTERS]

# ---- seed 002's variometer (csrc/vario.c): update(accel, baro_alt, dt)
from . import vario  # noqa: E402
from .vario import VarioKF, vertical_accel  # noqa: E402

#: filters of their own input kind, outside the IMU/1-D matrix
FILTERS_VARIO = vario.FILTERS
__all__ += [*FILTERS_VARIO, "FILTERS_VARIO", "vertical_accel"]

# ---- fixed point (csrc/fixed): int16 counts in, int32 state, profile "32" | "8"
from .fixed_1d import Complementary1DQ, Mahony1DBiasQ  # noqa: E402
from .fixed_gravity import KKQ, MultiWiiQ  # noqa: E402
from .fixed_mahony import MahonyIMUQ  # noqa: E402
from .fixed_madgwick import MadgwickIMUQ  # noqa: E402

#: every fixed-point filter, by class name (imufuse_c exports the same names)
FILTERS_FIXED = ("Complementary1DQ", "Mahony1DBiasQ", "KKQ", "MultiWiiQ",
                 "MahonyIMUQ", "MadgwickIMUQ")
__all__ += [*FILTERS_FIXED, "FILTERS_FIXED"]
