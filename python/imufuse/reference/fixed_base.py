"""Base class of the pure-Python fixed-point references (classes ending in Q).

A fixed-point reference mirrors its C twin in csrc/fixed/ operation for
operation on Python ints, through the C-semantics helpers of _cint.py.  The
API is that of the float filters (README.md, API) with these
differences: `profile="32" | "8"` replaces dtype; update() and run() take raw
int16 sensor counts; `state` is an int32 array; `state_float` gives the state
in the float twin's units.

Subclasses define kind, c_name (prefix of the C twin: <c_name>_t,
<c_name>_init, <c_name>_init_consts, <c_name>_update; a 3-D filter's update takes
the float update's scalars and calls its array form <c_name>_update_v, c_update_v, which
the bindings and the MCU harness call), state_names,
_params(...) (validation; returns the C init arguments, the profile last as
the int 32 or 8), _consts(*args) (the integer constants imf_<filter>_init
computes from its double arguments, as a dict in the order and with the
names of the parameters of imf_<filter>_init_consts), _init(*args) (mirror of
imf_<filter>_init), _init_consts(**consts) (mirror of
imf_<filter>_init_consts), _update(*ints) (mirror of imf_<filter>_update) and
_state_float(state).

Firmware whose double is 32 bits wide (avr-gcc) must not compute the
constants itself: c_init_args() / c_init_call() give them, computed here in
IEEE double exactly as a host's imf_<filter>_init does, for
imf_<filter>_init_consts (integer only, identical on every target).
"""
from __future__ import annotations

import copy

import numpy as np

from ..shared import checks as _checks
from . import _cint as ci

PROFILES = ("32", "8")


def check_profile(profile):
    p = str(profile)
    if p not in PROFILES:
        raise ValueError(f"profile: must be '32' or '8', got {profile!r}")
    return int(p)


def check_scale(name, value):
    return _checks.check_real(name, value, lo=0.0, lo_open=True)


def qconst(name, value, smin, smax, nonzero=False):
    """The q-scale constant C init computes from a double, with C's range
    check turned into a ValueError naming the parameter."""
    c = ci.qscale(value, name, smin=-64, smax=200) if value > 0 else ci.QScale(0, 16)
    if (nonzero and c.m == 0) or not smin <= c.s <= smax:
        raise ValueError(f"{name}={value!r} is outside the fixed-point range "
                         f"[2^{14 - smax}, 2^{15 - smin}) = [{2.0 ** (14 - smax):.3g}, "
                         f"{2.0 ** (15 - smin):.3g})")
    return c


def c_literal(value) -> str:
    """A C99 literal of an init_consts argument: a compound literal for a q-scale, a decimal
    integer (with a type that holds it on 16-bit-int targets) otherwise."""
    if isinstance(value, ci.QScale):
        return f"(imf_qscale_t){{{value.m}, {value.s}}}"
    if isinstance(value, dict):
        # a nested constants struct (RobustAHRSQ's RobustIMUQ part): its initializer list
        return "{" + ", ".join(c_literal(v) for v in value.values()) + "}"
    v = int(value)
    if not -32768 <= v <= 32767:
        return f"{v}L" if -(1 << 31) <= v < (1 << 31) else f"{v}UL"
    return str(v)


def _not_counts(name, dtype):
    return ValueError(f"{name}: expected integer sensor counts, got dtype {dtype} (give the "
                      "int16 readings of the sensor, or round physical values to them: "
                      "np.round(x / unit_per_count).astype(np.int16))")


#: rows of a wider array checked and converted at a time (bounded temporaries)
_COUNT_ROWS = 1 << 16


def as_int16(name, a, ndim):
    """``a`` as int16 counts of ``ndim`` dimensions (C-contiguous for arrays): integers, or
    floats holding whole numbers, within [-32768, 32767]; ValueError naming ``name``."""
    arr = np.asarray(a)
    if arr.dtype.kind not in "iubf":
        raise _not_counts(name, arr.dtype)
    if arr.ndim == 0 or np.can_cast(arr.dtype, np.int16):
        _check_counts(name, arr)
        if arr.ndim != ndim:
            raise ValueError(f"{name}: expected {ndim}-D counts, got shape {arr.shape}")
        return np.ascontiguousarray(arr, dtype=np.int16) if ndim else np.asarray(arr, dtype=np.int16)
    # a wider type: the copy is made first (a huge array, or a broadcast view of 10^13 rows,
    # fails there at once, as float inputs do), then checked and filled a block at a time
    if arr.ndim != ndim:
        raise ValueError(f"{name}: expected {ndim}-D counts, got shape {arr.shape}")
    out = np.empty(arr.shape, dtype=np.int16)
    for k in range(0, len(arr), _COUNT_ROWS):
        part = arr[k:k + _COUNT_ROWS]
        _check_counts(name, part)
        out[k:k + _COUNT_ROWS] = part
    return out


def _check_counts(name, arr):
    """ValueError unless every value of arr is a whole, finite count within int16."""
    if arr.dtype.kind == "f" and not (np.all(np.isfinite(arr)) and np.all(arr == np.round(arr))):
        raise _not_counts(name, arr.dtype)
    # int16 and narrower hold no count beyond the range: not scanned
    if arr.size and not np.can_cast(arr.dtype, np.int16) and (arr.min() < -32768
                                                              or arr.max() > 32767):
        raise ValueError(f"{name}: counts must be within int16 [-32768, 32767]")


def fixed_run_inputs(kind, args):
    names = _checks.KINDS[kind]
    if len(args) != len(names):
        raise ValueError(f"run(): expected {len(names)} arrays ({', '.join(names)}), got {len(args)}")
    ndim = 1 if kind == "1d" else 2
    arrs = [as_int16(n, a, ndim) for n, a in zip(names, args)]
    shapes = {arr.shape for arr in arrs}
    if len(shapes) != 1 or (ndim == 2 and arrs[0].shape[1] != 3):
        seen = ", ".join(f"{n}{a.shape}" for n, a in zip(names, arrs))
        want = "1-D arrays of equal length" if ndim == 1 else "(N, 3) arrays with the same N"
        raise ValueError(f"run(): expected {want}, got shapes {seen}")
    return arrs


def fixed_update_inputs(kind, args):
    names = _checks.KINDS[kind]
    if len(args) != len(names):
        raise ValueError(f"update(): expected {len(names)} arguments ({', '.join(names)}), got {len(args)}")
    ndim = 0 if kind == "1d" else 1
    out = []
    for n, a in zip(names, args):
        arr = as_int16(n, a, ndim)
        if ndim == 1 and arr.shape != (3,):
            raise ValueError(f"update(): {n} must be a 3-vector, got shape {arr.shape}")
        out.append(int(arr) if ndim == 0 else [int(v) for v in arr])
    return out


class FixedFilter:
    kind = "1d"
    c_name = ""
    c_update = ""   # <c_name>_update (as the float filters' c_update)
    #: the update the bindings and harnesses call: a 3-D filter's array form <c_update>_v
    #: (c_update is a static inline wrapper taking the scalars), a single-axis one's c_update
    c_update_v = ""
    #: the profiles the class is built in (a class with one arithmetic refuses the other)
    profiles: tuple = PROFILES
    state_names: tuple = ()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "c_update" not in cls.__dict__:
            cls.c_update = f"{cls.c_name}_update" if cls.c_name else ""
        if "c_update_v" not in cls.__dict__:
            cls.c_update_v = cls.c_update + "_v" if cls.c_update and cls.kind != "1d" else cls.c_update
    dtype = "int32"


    def __copy__(self):
        """A copy is an independent filter (a shallow copy would share the state's lists)."""
        return copy.deepcopy(self)
    def c_init_args(self) -> dict:
        """The arguments of <c_name>_init_consts after the filter pointer, by C parameter
        name: ints, and ci.QScale for imf_qscale_t.  The same constants the host's
        <c_name>_init computes from this filter's parameters."""
        return self._consts(*self._args)  # type: ignore[attr-defined]

    def c_init_call(self, var: str) -> str:
        """C99 statement initialising the filter variable ``var`` (an ``<c_name>_t``) from
        the constants, e.g. for firmware: ``imf_mahony_imu_q_init_consts(&f,
        (imf_qscale_t){...}, ...);`` (integer only; returns 0 in C). More than four constants
        go in the filter's ``<c_name>_consts_t`` (``&(<c_name>_consts_t){...}``)."""
        values = [c_literal(v) for v in self.c_init_args().values()]
        if len(values) > 4:
            return (f"{self.c_name}_init_consts(&{var}, &({self.c_name}_consts_t)"
                    f"{{{', '.join(values)}}});")
        return f"{self.c_name}_init_consts(&{var}{''.join(', ' + v for v in values)});"

    def __init__(self, *args, profile="32", **kwargs):
        self._args = self._params(*args, profile=profile, **kwargs)
        self.profile = str(self._args[-1])
        self.reset()

    def reset(self):
        """Back to the state after construction (init runs again)."""
        self._init(*self._args)

    # state: the C state struct's int32 members, in declaration order
    def _get_state(self):
        raise NotImplementedError

    def _set_state(self, values):
        raise NotImplementedError

    @property
    def state(self):
        return np.array(self._get_state(), dtype=np.int32)

    @state.setter
    def state(self, value):
        arr = np.asarray(value)
        n = len(self.state_names)
        if arr.shape != (n,):
            raise ValueError(f"state: expected shape ({n},) for {self.state_names}, got {arr.shape}")
        if arr.dtype.kind not in "iu" or arr.min() < ci.INT32_MIN or arr.max() > ci.INT32_MAX:
            raise ValueError("state: expected int32 values")
        self._set_state([int(v) for v in arr])

    @property
    def state_float(self):
        """The state in the float twin's units (float64)."""
        return np.asarray(self._state_float([int(v) for v in self._get_state()]), dtype=float)

    def state_to_float(self, states):
        """state_float for a (N, len(state)) trajectory as returned by run()."""
        return np.array([self._state_float([int(v) for v in row]) for row in np.asarray(states)],
                        dtype=float).reshape(len(states), -1)

    def update(self, *args, **named):
        args = _checks.bind("update", _checks.KINDS[self.kind], {}, args, named)
        self._update(*fixed_update_inputs(self.kind, args))

    def run(self, *args, **named):
        args = _checks.bind("run", _checks.KINDS[self.kind], {}, args, named)
        arrays = fixed_run_inputs(self.kind, args)
        n = len(self.state_names)
        rows = [a.tolist() for a in arrays]
        out = np.empty((len(rows[0]), n), dtype=np.int32)
        for k, sample in enumerate(zip(*rows)):
            self._update(*sample)
            out[k] = self._get_state()
        return out
