"""imufuse_c: the compiled filters of csrc/, in float32 and float64.

Each name is a class whose constructor takes the reference signature plus
`dtype="float64" | "float32"` and returns an instance of the build of that
precision (imufuse_c._f64 or imufuse_c._f32)."""
import inspect

from imufuse.shared import checks as _checks
import imufuse.reference as _reference

from . import _f32, _f64

_BUILDS = {"float32": _f32, "float64": _f64}


def _run_many_each(make, params, inputs, threads, run_kwargs):
    """run_many of a filter without a compiled batch path (single-axis, fixed point, Fusion,
    the variometer): one instance per parameter set, each run() (which releases the GIL) in a
    thread; a list of what each run() returns."""
    import concurrent.futures as cf
    import os

    filters = []
    for i, p in enumerate(params):
        try:
            filters.append(make(**dict(p)))
        except (TypeError, ValueError) as e:
            raise type(e)(f"parameter set {i} ({dict(p)}): {e}") from None
    workers = max(1, min(threads or os.cpu_count() or 1, len(filters)))
    if workers == 1:
        return [f.run(*inputs, **run_kwargs) for f in filters]
    with cf.ThreadPoolExecutor(max_workers=workers) as ex:
        return list(ex.map(lambda f: f.run(*inputs, **run_kwargs), filters))


def _check_param_sets(params):
    """run_many's parameter sets: mappings of constructor keywords; the precision is
    run_many's own dtype=, never a set's."""
    if isinstance(params, (str, bytes)) or not hasattr(params, "__iter__"):
        raise TypeError(f"run_many: params must be a sequence of parameter dicts, got "
                        f"{type(params).__name__}")
    params = list(params)
    for i, p in enumerate(params):
        if not hasattr(p, "keys"):
            raise TypeError(f"run_many: parameter set {i} must be a dict of constructor "
                            f"keywords, got {type(p).__name__} {p!r}")
        if "dtype" in p:
            raise TypeError(f"run_many: parameter set {i} gives dtype={p['dtype']!r}: the "
                            "precision of every set is run_many's own dtype= argument")
    return params


def _run_many(cls, params, *inputs, dtype="float64", threads=None, **run_kwargs):
    """Run one filter per parameter set of ``params`` (constructor keyword dicts) over one
    log in one call; each set's result is bit for bit its own run()'s. 3-D float filters:
    imufuse_c.run_filters (lanes, scores; a (P, N, len(state)) array or Evaluations); the
    others: a list of what each run() returns (run keywords such as dt= are passed on)."""
    impl = cls._impl[_checks.check_dtype(dtype)]
    params = _check_param_sets(params)
    if hasattr(impl, "run_many") and cls.kind in ("imu", "ahrs"):
        return impl.run_many(params, *inputs, threads=threads, **run_kwargs)
    return _run_many_each(impl, params, inputs, threads, run_kwargs)


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
        "run_many": classmethod(_run_many),
    })


FILTERS = _reference.FILTERS
for _name in FILTERS:
    globals()[_name] = _dispatch(_name)

__all__ = list(FILTERS)


def _batch_build(i, f):
    """The compiled build (_f32 or _f64) a run_filters entry belongs to; TypeError naming
    the entry and what it is when it has no compiled batch path."""
    for b in _BUILDS.values():
        if isinstance(f, b._Filter):
            return b
    t = type(f)
    what = f"{t.__module__}.{t.__qualname__}"
    if t.__module__.startswith("imufuse.reference"):
        why = "a pure-Python reference filter; make it with imufuse_c (same arguments)"
    elif getattr(f, "profile", None) is not None or t.__name__ in FILTERS_FIXED:
        why = "a fixed-point filter, which has no batch path; run it with its own run()"
    else:
        why = "not a compiled float filter"
    raise TypeError(f"run_filters: filters[{i}] is {what}: {why}")


def run_filters(filters, *inputs, **kwargs):
    """Many filters of one 3-D float class and precision over one log in one compiled call
    (imufuse_c._f64.run_filters: lanes, threads, scores computed while they run)."""
    if isinstance(filters, (str, bytes)) or not hasattr(filters, "__iter__"):
        raise TypeError(f"run_filters: filters must be a sequence of filters, got "
                        f"{type(filters).__name__}")
    filters = list(filters)
    if not filters:
        raise ValueError("run_filters: no filter given")
    builds = [_batch_build(i, f) for i, f in enumerate(filters)]
    if any(b is not builds[0] for b in builds):
        i = next(i for i, b in enumerate(builds) if b is not builds[0])
        raise TypeError(f"run_filters: filters[0] is {filters[0].dtype} and filters[{i}] "
                        f"{filters[i].dtype}: every filter must be of one class and precision")
    return builds[0].run_filters(filters, *inputs, **kwargs)


def lane_widths(dtype="float64"):
    """{width: instruction set} of the lane kernels this CPU runs, widest first."""
    return _BUILDS[_checks.check_dtype(dtype)].lane_widths()


def has_lanes(name, dtype="float64"):
    """Whether filter ``name`` has a lane kernel (run_filters runs its sets in SIMD lanes)."""
    b = _BUILDS[_checks.check_dtype(dtype)]
    return b.has_lanes(getattr(b, name))


__all__ += ["run_filters", "lane_widths", "has_lanes"]

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
        "run_many": classmethod(_run_many),
    })


for _name in FILTERS_FUSION:
    globals()[_name] = _dispatch_fusion(_name)


def _fusion_function(cname, twin=_reference.fusion):
    def f(*args, dtype="float64", **kwargs):
        return getattr(_BUILDS[_checks.check_dtype(dtype)], cname)(*args, **kwargs)
    f.__name__ = cname[len("fusion_"):]
    f.__doc__ = getattr(twin, cname[len("fusion_"):]).__doc__
    return f


calibrate_inertial = _fusion_function("fusion_calibrate_inertial")
calibrate_magnetic = _fusion_function("fusion_calibrate_magnetic")
axes_apply = _fusion_function("fusion_axes_apply")
compass_heading = _fusion_function("fusion_compass_heading")
# Fusion 1.3's names (csrc/fusion13.h: the same C as the 1.2.3 models and alignment)
remap = _fusion_function("fusion_remap", _reference.fusion13)
model_inertial = _fusion_function("fusion_model_inertial", _reference.fusion13)
model_magnetic = _fusion_function("fusion_model_magnetic", _reference.fusion13)
__all__ += [*FILTERS_FUSION, "FILTERS_FUSION", "calibrate_inertial", "calibrate_magnetic",
            "axes_apply", "compass_heading", "remap", "model_inertial", "model_magnetic"]
