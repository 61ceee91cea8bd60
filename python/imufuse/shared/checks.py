"""Validation shared by the compiled filters (imufuse_c) and the reference.

One definition of every check, so both backends accept and reject exactly the
same parameters and inputs, with the same messages.
"""
import copy
import math
import threading

import numpy as np

DTYPES = ("float32", "float64")
#: the complex types (Python's and numpy's): never a setting, a choice or an input, even
#: with a zero imaginary part (it would be dropped by float() or int())
COMPLEX = (complex, np.complexfloating)


def real_number(value):
    """float(value) for a real number (Python or NumPy int/float/bool, or
    anything with __float__ that is not complex or text); None otherwise.
    Strings are not numbers here (both backends reject "0.5"), complex values
    are rejected instead of losing their imaginary part, and an int too large
    for a double is rejected instead of raising OverflowError."""
    if isinstance(value, (str, bytes, bytearray, *COMPLEX)):
        return None
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return None


def check_dtype(dtype):
    """Return "float32" or "float64"; raise ValueError for anything else
    (None included: it is not a default here)."""
    if type(dtype) is str and dtype in DTYPES:
        return dtype    # the names themselves (np.dtype costs more than a short run)
    if dtype is None:
        raise ValueError("dtype: must be 'float32' or 'float64', got None")
    try:
        name = np.dtype(dtype).name
    except TypeError:
        name = None
    if name not in DTYPES:
        raise ValueError(f"dtype: must be 'float32' or 'float64', got {dtype!r}")
    return name


def check_real(name, value, lo=None, hi=None, lo_open=False, hi_open=False, why=""):
    """Return value as a float, requiring it finite and within [lo, hi]
    (open at an end when lo_open/hi_open)."""
    v = real_number(value)
    if v is None:
        raise ValueError(f"{name}: must be a real number, got {value!r}")
    ok = math.isfinite(v)
    if ok and lo is not None:
        ok = v > lo if lo_open else v >= lo
    if ok and hi is not None:
        ok = v < hi if hi_open else v <= hi
    if not ok:
        lo_s = "" if lo is None else f"{lo} {'<' if lo_open else '<='} "
        hi_s = "" if hi is None else f" {'<' if hi_open else '<='} {hi}"
        rng = f" and {lo_s}{name}{hi_s}" if (lo is not None or hi is not None) else ""
        extra = f" ({why})" if why else ""
        raise ValueError(f"{name}: must be finite{rng}{extra}, got {value!r}")
    return v


def check_real_in(name, value, dtype):
    """check_real, then the value finite in ``dtype`` too (a float64 beyond float32's range
    would become inf in a float32 filter's state)."""
    v = check_real(name, value)
    if check_dtype(dtype) == "float32":
        with np.errstate(over="ignore"):
            ok = bool(np.isfinite(np.float32(v)))
        if not ok:
            raise ValueError(f"{name}: must be finite in float32 (|{name}| <= "
                             f"{float(np.finfo(np.float32).max):.8g}), got {value!r}")
    return v


def check_dt(dt):
    return check_real("dt", dt, lo=0.0, lo_open=True)


def check_choice(name, value, choices):
    # 1+0j == 1 == True: a complex value is refused before the comparison
    if isinstance(value, COMPLEX) or value not in choices:
        raise ValueError(f"{name}: must be one of {', '.join(map(repr, choices))}, got {value!r}")
    return value


def check_stable2(names, det, p_minus, p_plus, why):
    """Jury test for a 2x2 update matrix with characteristic polynomial
    p(z) = z^2 - tr z + det: stable when |det| < 1, p(1) = 1 - tr + det > 0 and
    p(-1) = 1 + tr + det > 0. Callers pass p(1) and p(-1) in closed form (not
    as differences of rounded numbers); p(1) = 0 is admitted: the marginal
    case of a frozen integrator (its gain zero)."""
    if not (abs(det) < 1.0 and p_minus >= 0.0 and p_plus > 0.0):
        raise ValueError(f"{names}: outside the stable range ({why})")


def _as_real_array(name, a, dtype):
    """A contiguous array of dtype from real numbers only (no strings, no
    complex values, no sets or dicts), else ValueError naming the input."""
    if isinstance(a, (str, bytes, set, frozenset, dict)):
        raise ValueError(f"run(): {name} must be an array of real numbers, got {type(a).__name__}")
    arr = np.asarray(a)
    if arr.dtype.kind not in "biuf":
        raise ValueError(f"run(): {name} must be an array of real numbers, got dtype {arr.dtype}")
    with np.errstate(over="ignore"):      # float64 beyond float32: inf, a rejected sample
        return np.ascontiguousarray(arr, dtype=dtype)


def as_1d(dtype, **arrays):
    """Convert equally long 1-D inputs to contiguous arrays of dtype."""
    out = [_as_real_array(name, a, dtype) for name, a in arrays.items()]
    shapes = {name: arr.shape for name, arr in zip(arrays, out)}
    if any(arr.ndim != 1 for arr in out) or len({arr.shape for arr in out}) != 1:
        seen = ", ".join(f"{k}{v}" for k, v in shapes.items())
        raise ValueError(f"run(): expected 1-D arrays of equal length, got shapes {seen}")
    return out


def as_nx3(dtype, **arrays):
    """Convert (N, 3) inputs with a common N to contiguous arrays of dtype."""
    out = [_as_real_array(name, a, dtype) for name, a in arrays.items()]
    shapes = {name: arr.shape for name, arr in zip(arrays, out)}
    if any(arr.ndim != 2 or arr.shape[1] != 3 for arr in out) or len({arr.shape for arr in out}) != 1:
        seen = ", ".join(f"{k}{v}" for k, v in shapes.items())
        raise ValueError(f"run(): expected (N, 3) arrays with the same N, got shapes {seen}")
    return out


def as_vec3(name, v):
    """One 3-vector for update(): any sequence or array of three numbers."""
    try:
        if isinstance(v, (str, bytes, set, frozenset, dict)):
            raise TypeError
        x, y, z = v
        out = real_number(x), real_number(y), real_number(z)
    except (TypeError, ValueError):
        shape = np.shape(v) if not isinstance(v, str) else "str"
        raise ValueError(f"update(): {name} must be a 3-vector, got shape {shape}") from None
    if None in out:
        raise ValueError(f"update(): {name} must hold three real numbers, got {v!r}")
    return out


def as_state(value, n, dtype, names):
    arr = np.asarray(value, dtype=dtype)
    if arr.shape != (n,):
        raise ValueError(f"state: expected shape ({n},) for {names}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("state: must be finite (the state never becomes non-finite)")
    return np.ascontiguousarray(arr)


def canonical_nan(out):
    """Every NaN of the float array ``out`` (in place) made the one quiet NaN of its dtype
    (positive, no payload), and ``out`` returned. IEEE 754 leaves a NaN's sign and payload
    to the hardware and the order of operations, so the C and the twin differ there; the
    free functions of both backends return this one NaN."""
    m = np.isnan(out)
    if m.any():
        out[m] = np.nan
    return out


#: a state write is tried with still samples in four orientations (gravity along +z, +x,
#: +y, -z, a field across it): a filter that rejects any of them cannot continue from it
PROBE_SAMPLES = 100
_GRAVITY = ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, -1.0))
_FIELD = ((0.5, 0.0, -0.8), (-0.8, 0.5, 0.0), (0.5, -0.8, 0.0), (0.5, 0.0, 0.8))
DEAD_STATE = ("state: the filter cannot continue from it: {k} of {n} still samples after the "
              "write ({g}) were rejected (the update overflows, cannot "
              "normalise, or leaves an invalid state); write a state the filter can continue "
              "from")
_PROBING = threading.local()


def _probe_runs(style, state):
    """(args, kwargs, what) of the run() calls a state write of a ``style`` filter is tried
    with: "1d", "imu", "ahrs", "vario" (run(accel, baro_alt, dt)) or "fusion"."""
    n = PROBE_SAMPLES
    if style == "1d":
        for angle in (0.0, 1.0):
            yield (np.zeros(n), np.full(n, angle)), {}, f"rate 0, angle {angle:g}"
        return
    if style == "vario":
        z = float(state[0])
        yield (np.zeros(n), np.full(n, z), np.full(n, 0.01)), {}, "the barometer steady at z"
        return
    for g, m in zip(_GRAVITY, _FIELD):
        args = (np.zeros((n, 3)), np.tile(g, (n, 1)))
        if style in ("ahrs", "fusion"):
            args += (np.tile(m, (n, 1)),)
        yield args, ({"dt": 0.01} if style == "fusion" else {}), f"gravity along {g}"


def dead_state(filt, state, style):
    """None if the filter ``filt`` (either backend) can continue from ``state``, else the
    ValueError message: the state is written on a copy and tried with still samples in four
    orientations (_probe_runs); any rejected sample refuses it. The write on the copy does
    not try again (no recursion)."""
    if getattr(_PROBING, "active", False):
        return None
    _PROBING.active = True
    try:
        base = copy.copy(filt)
        base.state = state
        for args, kw, what in _probe_runs(style, state):
            p = copy.copy(base)
            before = p.skipped
            with np.errstate(all="ignore"):
                p.run(*args, **kw)
            k = (p.skipped - before) & 0xFFFFFFFF
            if k:
                return DEAD_STATE.format(k=k, n=PROBE_SAMPLES, g=what)
        return None
    finally:
        _PROBING.active = False


def check_valid_state(problem):
    """Raise the ValueError of a state write that is not a valid attitude."""
    if problem is not None:
        raise ValueError(f"state: not a valid attitude ({problem})")


# Per-sample inputs of each kind of filter: update() argument names, and
# whether run() takes 1-D arrays or (N, 3) arrays.
KINDS = {
    "1d": ("rate", "angle"),
    "imu": ("gyr", "acc"),
    "ahrs": ("gyr", "acc", "mag"),
}


UNSET = type("Unset", (), {"__repr__": lambda self: "<not given>"})()


def given(named, **explicit):
    """The keywords of a call: `named` and those of `explicit` not UNSET (the parameters a
    signature names, to be bound by bind() with the others)."""
    return {**named, **{k: v for k, v in explicit.items() if v is not UNSET}}


def bind(what, names, optional, args, named):
    """The arguments of a compiled filter's update()/run() bound as Cython binds them, with
    its TypeErrors word for word, so that the twin accepts and refuses the same calls:
    `names` required, then `optional` ({name: default}, in order), each by position or by
    name (update(gyr, acc, 0.01) and update(gyr=g, acc=a, dt=0.01) alike). Returns the
    values in the order of the parameters."""
    params = [*names, *optional]
    n, m = len(names), len(params)
    if len(args) > m:
        raise TypeError(f"{what}() takes {'exactly' if n == m else 'at most'} {m} positional "
                        f"argument{'s' if m != 1 else ''} ({len(args)} given)")
    vals = dict(zip(params, args))
    for k, v in named.items():
        if k not in params:
            raise TypeError(f"{what}() got an unexpected keyword argument '{k}'")
        if k in vals:
            raise TypeError(f"{what}() got multiple values for keyword argument '{k}'")
        vals[k] = v
    for i, k in enumerate(names):
        if k not in vals:
            raise TypeError(f"{what}() takes {'exactly' if n == m else 'at least'} {n} "
                            f"positional argument{'s' if n != 1 else ''} ({i} given)")
    return [vals[k] if k in vals else optional[k] for k in params]


def run_inputs(kind, dtype, args):
    """Validate run() arguments for a filter kind; return contiguous arrays."""
    names = KINDS[kind]
    if len(args) != len(names):
        raise TypeError(f"run(): expected {len(names)} arrays ({', '.join(names)}), got {len(args)}")
    conv = as_1d if kind == "1d" else as_nx3
    return conv(dtype, **dict(zip(names, args)))


def update_inputs(kind, args):
    """Validate update() arguments for a filter kind; return a flat tuple of floats."""
    names = KINDS[kind]
    if len(args) != len(names):
        raise TypeError(f"update(): expected {len(names)} arguments ({', '.join(names)}), got {len(args)}")
    if kind == "1d":
        return tuple(check_scalar(n, a) for n, a in zip(names, args))
    return sum((as_vec3(n, a) for n, a in zip(names, args)), ())


def check_scalar(name, v):
    x = real_number(v)
    if x is None:
        raise ValueError(f"update(): {name} must be a real number, got {v!r}")
    return x


# ---- time: per-sample dt (run(..., dt=array), update(..., dt=value)) ----------

def _dt_problem(v, conv, dtype):
    if not math.isfinite(v):
        return "not finite"
    if not v > 0.0:
        return "not > 0"
    return f"not representable in {dtype} (it rounds to {float(conv)!r})"


def _vector_as_dt(dt, shape):
    """The hint for 3-vectors (update) or (N, 3) arrays (run) where dt goes: an IMU filter's
    update(gyr, acc, mag) binds the magnetometer to dt, its third parameter."""
    try:
        seen = np.shape(dt)
    except ValueError:
        return ""
    if seen != (shape if isinstance(shape, tuple) else (shape,)):
        return ""
    return " (3-vectors where dt goes: a magnetometer given to a filter that takes none?)"


def dt_value(dt, dtype):
    """One sample period (s) for update(..., dt=...): finite, > 0 and still
    finite and > 0 once rounded to the filter's precision."""
    try:
        v = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt: must be a real number (s), got {dt!r}{_vector_as_dt(dt, 3)}") \
            from None
    with np.errstate(over="ignore", under="ignore"):
        conv = np.dtype(dtype).type(v)
    if not (math.isfinite(v) and v > 0.0 and np.isfinite(conv) and conv > 0):
        raise ValueError(f"dt: must be finite and > 0 s, representable in {dtype}; "
                         f"{v!r} is {_dt_problem(v, conv, dtype)}")
    return v


def dt_array(dt, n, dtype):
    """Per-sample periods for run(..., dt=...): shape (n,), every value finite,
    > 0 and representable in dtype. Returns a contiguous array of dtype."""
    try:
        arr = np.asarray(dt, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"dt: must be an array of {n} sample periods (s), got {type(dt).__name__}") from None
    if arr.shape != (n,):
        raise ValueError(f"dt: expected shape ({n},), one period per sample, got {arr.shape}"
                         f"{_vector_as_dt(arr, (n, 3))}")
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        conv = arr.astype(dtype)
        bad = ~(np.isfinite(arr) & (arr > 0.0) & np.isfinite(conv) & (conv > 0))
    if bad.any():
        k = int(np.argmax(bad))
        raise ValueError(f"dt: sample {k} is {float(arr[k])!r}, {_dt_problem(float(arr[k]), conv[k], dtype)}; "
                         f"every dt must be finite and > 0 s, representable in {dtype}")
    return np.ascontiguousarray(conv)


# ---- initial orientation (init="identity" | "first", q0=, state=) --------------

INITS = ("identity", "first")


def check_start(kind, names, dtype, init="identity", init_window=1, q0=None, state=None,
                own_start=None):
    """How a filter starts: ("identity",), ("first", window), ("q", (w, x, y, z))
    or ("state", array). init, init_window and q0 are for 3-D filters; state
    (the full state vector) for every filter. At most one of init="first",
    q0 and state. own_start: why the filter refuses q0 (it starts from its first sample
    whatever q0 says), or None."""
    if q0 is not None and own_start:
        raise ValueError(f"q0: {own_start}")
    if kind == "1d" and (init != "identity" or init_window != 1 or q0 is not None):
        raise ValueError("init, init_window, q0: only 3-D filters have an initial orientation "
                         "(single-axis filters take state=)")
    check_choice("init", init, INITS)
    given = [n for n, v in (("init='first'", init == "first"), ("q0", q0 is not None),
                            ("state", state is not None)) if v]
    if len(given) > 1:
        raise ValueError(f"{', '.join(given)}: give at most one way to start")
    if isinstance(init_window, bool) or not isinstance(init_window, (int, np.integer)) \
            or not 1 <= init_window <= 0xFFFFFFFF:
        raise ValueError(f"init_window: must be an integer >= 1 (samples averaged), got {init_window!r}")
    if init_window != 1 and init != "first":
        raise ValueError("init_window: only with init='first'")
    if init == "first":
        return ("first", int(init_window))
    if q0 is not None:
        try:
            q = np.asarray(q0, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"q0: must be a quaternion (w, x, y, z), got {q0!r}") from None
        with np.errstate(over="ignore"):
            qr = q.astype(dtype)
        if q.shape != (4,) or not np.all(np.isfinite(qr)) or not np.any(qr != 0):
            raise ValueError(f"q0: must be a finite, non-zero quaternion (w, x, y, z) "
                             f"in {dtype}, got {q0!r}")
        return ("q", tuple(float(v) for v in q))
    if state is not None:
        return ("state", as_state(state, len(names), dtype, names))
    return ("identity",)
