"""Pure-Python twins of the compiled filters in imufuse_c: same names, same
signatures, same state, bit for bit the same results.

A filter is declared once, by its class: every public class with a C prefix
(`c_name`) in a public module of this package (one per csrc/<family>.c,
fixed_<family> per csrc/fixed/<family>_q.c) is collected here, in the section its
class says (`section`): float filters (1d, imu, ahrs), fixed point (FixedFilter),
the Fusion suite (kind fusion*) and the variometer (kind vario). A new family module
needs no edit of this file; imufuse.catalogue adds what users need (defaults,
estimate, recovery) and setup.py binds the same classes (tools/bindgen.py).
"""
import importlib
import pkgutil

from ._base import ReferenceFilter
from .filters_1d import tuning
from .fixed_base import FixedFilter

FILTERS: tuple = ()          # every float filter, by class name (imufuse_c exports the same)
FILTERS_FIXED: tuple = ()    # every fixed-point filter (int16 counts in, integer state)
FILTERS_FUSION: tuple = ()   # the Fusion suite: Fusion's units (deg/s, g), dt per update
FILTERS_VARIO: tuple = ()    # Nair's variometer: update(accel, baro_alt, dt)


def section(cls) -> str:
    """The section of a filter class: "float", "fixed", "fusion" or "vario"."""
    if isinstance(cls, type) and issubclass(cls, FixedFilter):
        return "fixed"
    kind = getattr(cls, "kind", "")
    return "fusion" if kind.startswith("fusion") else "vario" if kind == "vario" else "float"


def _declared(mod):
    """The filter classes a module declares: its public classes with a C prefix, in the
    order they are defined."""
    return [v for k, v in vars(mod).items() if isinstance(v, type) and not k.startswith("_")
            and v.__module__ == mod.__name__ and getattr(v, "c_name", "")]


_SECTIONS = {"float": "FILTERS", "fixed": "FILTERS_FIXED", "fusion": "FILTERS_FUSION",
             "vario": "FILTERS_VARIO"}
for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _info.name.startswith("_"):
        continue
    _mod = importlib.import_module(f"{__name__}.{_info.name}")
    for _cls in _declared(_mod):
        globals()[_cls.__name__] = _cls
        _key = _SECTIONS[section(_cls)]
        globals()[_key] = globals()[_key] + (_cls.__name__,)

FILTERS_1D = tuple(n for n in FILTERS if globals()[n].kind == "1d")

from .vario import vertical_accel  # noqa: E402  (Nair 2016)

__all__ = ["ReferenceFilter", "FixedFilter", "section", "FILTERS", "FILTERS_FIXED", "FILTERS_FUSION", "FILTERS_1D",
           "FILTERS_VARIO", "tuning", "vertical_accel", *FILTERS, *FILTERS_FIXED,
           *FILTERS_FUSION, *FILTERS_VARIO]
