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
    kw = inspect.Parameter.KEYWORD_ONLY
    # how the filter starts (_checks.check_start): state= for every filter,
    # init=, init_window= and q0= for the 3-D filters
    start = [inspect.Parameter("state", kw, default=None)]
    if ref.kind != "1d":
        start = [inspect.Parameter("init", kw, default="identity"),
                 inspect.Parameter("init_window", kw, default=1),
                 inspect.Parameter("q0", kw, default=None), *start]
    params = [*sig.parameters.values(), inspect.Parameter("dtype", kw, default="float64"), *start]
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

# ---- Nair's variometer: VarioKF (dtype dispatch) and vertical_accel
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

# ---- the Fusion suite (csrc/fusion_*.h): Fusion's units (deg/s, g), dt per update
FILTERS_FUSION = _reference.FILTERS_FUSION


def _dispatch_fusion(name):
    ref = getattr(_reference, name)
    sig = inspect.signature(ref.__init__)
    params = [p for p in sig.parameters.values() if p.name != "self"]
    if "dtype" not in sig.parameters:
        params.append(inspect.Parameter("dtype", inspect.Parameter.KEYWORD_ONLY, default="float64"))
    return _Dispatch(name, (), {
        "_impl": {dt: getattr(mod, name) for dt, mod in _BUILDS.items()},
        "__doc__": ref.__doc__,
        "__signature__": sig.replace(parameters=params),
        "__module__": __name__,
        "kind": ref.kind,
        "state_names": ref.state_names,
    })


for _name in FILTERS_FUSION:
    globals()[_name] = _dispatch_fusion(_name)


def _fusion_function(cname):
    def f(*args, dtype="float64", **kwargs):
        return getattr(_BUILDS[_checks.check_dtype(dtype)], cname)(*args, **kwargs)
    f.__name__ = cname[len("fusion_"):]
    f.__doc__ = getattr(_reference.fusion, cname[len("fusion_"):]).__doc__
    return f


calibrate_inertial = _fusion_function("fusion_calibrate_inertial")
calibrate_magnetic = _fusion_function("fusion_calibrate_magnetic")
axes_apply = _fusion_function("fusion_axes_apply")
compass_heading = _fusion_function("fusion_compass_heading")
__all__ += [*FILTERS_FUSION, "FILTERS_FUSION", "calibrate_inertial", "calibrate_magnetic",
            "axes_apply", "compass_heading"]
