"""imufuse_c: the compiled filters of csrc/, in float32 and float64.

Each name is a class whose constructor takes the reference signature plus
`dtype="float64" | "float32"` and returns an instance of the build of that
precision (imufuse_c._f64 or imufuse_c._f32)."""
import inspect

from imufuse import _checks
import imufuse.reference as _reference

from . import _f32, _f64

_BUILDS = {"float32": _f32, "float64": _f64}


class _Dispatch(type):
    def __call__(cls, *args, dtype="float64", **kwargs):
        return cls._impl[_checks.check_dtype(dtype)](*args, **kwargs)

    def __instancecheck__(cls, obj):
        return isinstance(obj, tuple(cls._impl.values()))


def _dispatch(name):
    ref = getattr(_reference, name)
    sig = inspect.signature(ref._params)
    params = [*sig.parameters.values(),
              inspect.Parameter("dtype", inspect.Parameter.KEYWORD_ONLY, default="float64")]
    return _Dispatch(name, (), {
        "_impl": {dt: getattr(mod, name) for dt, mod in _BUILDS.items()},
        "__doc__": ref.__doc__,
        "__signature__": sig.replace(parameters=sorted(params, key=lambda p: p.kind)),
        "__module__": __name__,
        "kind": ref.kind,
        "state_names": ref.state_names,
    })


FILTERS = _reference.FILTERS
for _name in FILTERS:
    globals()[_name] = _dispatch(_name)

__all__ = list(FILTERS)

# ---- seed 002's variometer: VarioKF (dtype dispatch) and vertical_accel
FILTERS_VARIO = _reference.FILTERS_VARIO
for _name in FILTERS_VARIO:
    globals()[_name] = _dispatch(_name)


def vertical_accel(q, acc, convention="nwu", one_g=1.0, scale=980.0, dtype="float64"):
    """Compiled imufuse.reference.vertical_accel (csrc/vario.c)."""
    return _BUILDS[_checks.check_dtype(dtype)].vertical_accel(q, acc, convention, one_g, scale)


__all__ += [*FILTERS_VARIO, "FILTERS_VARIO", "vertical_accel"]

# ---- fixed point (csrc/fixed): profile="32" | "8" instead of dtype
from . import _fixed  # noqa: E402

FILTERS_FIXED = _reference.FILTERS_FIXED
for _name in FILTERS_FIXED:
    globals()[_name] = getattr(_fixed, _name)
__all__ += [*FILTERS_FIXED, "FILTERS_FIXED"]
