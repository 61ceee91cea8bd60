"""Pure-Python twins of the compiled filters in imufuse_c: same names, same
signatures, same state, bit for bit the same results.

Every public module of this package (one per csrc/<family>.c, fixed_<family>
per csrc/fixed/<family>_q.c) lists its float classes in FILTERS and its
fixed-point classes in FILTERS_FIXED; they are collected here, so a new family
module needs no edit of this file. imufuse.catalogue describes each filter.
"""
import importlib
import pkgutil

from ._base import ReferenceFilter
from .filters_1d import tuning

FILTERS: tuple = ()          # every float filter, by class name (imufuse_c exports the same)
FILTERS_FIXED: tuple = ()    # every fixed-point filter (int16 counts in, integer state)
FILTERS_FUSION: tuple = ()   # the Fusion suite: Fusion's units (deg/s, g), dt per update
FILTERS_VARIO: tuple = ()    # Nair's variometer: update(accel, baro_alt, dt)

for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _info.name.startswith("_"):
        continue
    _mod = importlib.import_module(f"{__name__}.{_info.name}")
    for _name in getattr(_mod, "FILTERS", ()):
        globals()[_name] = getattr(_mod, _name)
        FILTERS += (_name,)
    for _name in getattr(_mod, "FILTERS_FIXED", ()):
        globals()[_name] = getattr(_mod, _name)
        FILTERS_FIXED += (_name,)
    for _name in getattr(_mod, "FILTERS_FUSION", ()):
        globals()[_name] = getattr(_mod, _name)
        FILTERS_FUSION += (_name,)
    for _name in getattr(_mod, "FILTERS_VARIO", ()):
        globals()[_name] = getattr(_mod, _name)
        FILTERS_VARIO += (_name,)

FILTERS_1D = tuple(n for n in FILTERS if globals()[n].kind == "1d")

from .vario import vertical_accel  # noqa: E402  (Nair 2016)

__all__ = ["ReferenceFilter", "FILTERS", "FILTERS_FIXED", "FILTERS_FUSION", "FILTERS_1D",
           "FILTERS_VARIO", "tuning", "vertical_accel", *FILTERS, *FILTERS_FIXED,
           *FILTERS_FUSION, *FILTERS_VARIO]
