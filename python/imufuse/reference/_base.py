"""Base class of the pure-Python reference filters.

A reference filter mirrors its C twin operation by operation. Arithmetic is
done on the type `self._R`: Python float for float64 (the same IEEE double
operations as C), numpy.float32 scalars for float32 (every operation rounded
to float32, as C float does; NumPy >= 2 keeps float32 when a Python number is
mixed in, and the code wraps every constant in R() like C's IMF_R()).

Subclasses define:
  kind         "1d", "imu" or "ahrs" (the update() signature, see _checks.KINDS)
  c_name       prefix of the C twin: <c_name>_t, <c_name>_init, <c_name>_update; one
               prefix per family where one C type serves both forms (Madgwick, Mahony)
  c_update     the C update this class runs: <c_name>_update unless the class names
               another (a family's form without magnetometer: <c_name>_update_imu)
  state_names  the state variables, in the order of the C state struct; each
               is an attribute of the instance
  settings_type the filter's settings record (_settings.SettingsRecord): its C settings
               struct member for member, each member with the user's default and unit,
               its check and its one conversion to the C's unit
  _params(...) settings_type.keywords(): the constructor's keywords checked into a
               settings record (shared with imufuse_c, which fills the C struct from it
               by name)
  _init(s)     mirror of imf_<filter>_init with the settings record s
  _update(*scalars) mirror of imf_<filter>_update, inputs already of type R
  _set_dt(dt)  mirror of imf_<filter>_set_dt (dt of type R); _init calls it
  _set_attitude(att) 3-D filters: mirror of imf_<filter>_set_attitude

Time: run(..., dt=array) and update(..., dt=value) run those samples with
their own period (_set_dt before the update) and then restore the
constructor's dt. Start (3-D filters): init="identity" | "first" (with
init_window), q0= or state=; see _checks.check_start and attitude.py.
"""
import dataclasses
import inspect
import math

import copy

import numpy as np

from ..shared import checks as _checks
from ..shared import estimate as _estimate
from . import attitude as _attitude

U32 = 0xFFFFFFFF

#: state writes of the quaternion filters: |q|^2 within 1 +- this (the filter
#: itself keeps |q| within 1 +- 2e-3 even with the fast inverse square root)
QUAT_NORM2_TOL = 0.01


class ReferenceFilter:
    kind = "1d"
    c_name = ""
    c_update = ""
    state_names: tuple = ()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "c_update" not in cls.__dict__:
            cls.c_update = f"{cls.c_name}_update" if cls.c_name else ""


    def __copy__(self):
        """A copy is an independent filter (a shallow copy would share the state's lists)."""
        return copy.deepcopy(self)
    def __init__(self, *args, dtype="float64", init="identity", init_window=1, q0=None,
                 state=None, **kwargs):
        self.dtype = _checks.check_dtype(dtype)
        self._R = np.float32 if self.dtype == "float32" else float
        self._args = self._checked_params(self.dtype, *args, **kwargs)
        self._start = _checks.check_start(self.kind, self.state_names, self.dtype, init,
                                          init_window, q0, state,
                                          getattr(self, "own_start", None))
        self.reset()

    @classmethod
    def _checked_params(cls, dtype, *args, **kwargs):
        """_params, then every C init argument and every constant init derives
        from them checked in the filter's own precision (shared with imufuse_c)."""
        args = cls._params(*args, **kwargs)
        check_precision(cls, args, dtype)
        return args

    def reset(self):
        """Back to the state after construction (init runs again)."""
        self.skipped = 0
        with np.errstate(all="ignore"):
            call_init(self, self._args)
            self._apply_start()

    def _apply_start(self):
        # the start of the state (after init): identity, a window of first
        # readings, a given quaternion or a given state
        self._pending = None
        how = self._start[0]
        if how == "first":
            self._pending = _attitude.Window(self._R, self._start[1])
        elif how == "q":
            R = self._R
            att = _attitude.from_quat(R, *[R(v) for v in self._start[1]])
            if att is None:
                raise ValueError(f"q0: not a valid quaternion in {self.dtype}")
            self._set_attitude(att)
        elif how == "state":
            self.state = self._start[1]

    def _first(self, row):
        # init="first": one sample of the window (gyro, acc[, mag] flat, type R)
        R = self._R
        if not isfinite(*row[:3]):
            self._skip()
            return
        mag = row[6:9] if len(row) > 6 else (R(0.0), R(0.0), R(0.0))
        r, att = self._pending.add(*row[3:6], *mag)
        if r < 0:
            self._skip()
        elif r > 0:
            self._set_attitude(att)
            if self._pending.n >= self._pending.window:
                self._pending = None

    def _skip(self):
        # C: uint32_t skipped; skipped++ wraps modulo 2^32
        self.skipped = (self.skipped + 1) & U32

    def _words(self):
        """The state's words in state_names' order (a filter that keeps its state in
        arrays returns them from there, without one property call per word)."""
        return [getattr(self, n) for n in self.state_names]

    @property
    def state(self):
        return np.array(self._words(), dtype=self.dtype)

    @state.setter
    def state(self, value):
        arr = _checks.as_state(value, len(self.state_names), self.dtype, self.state_names)
        R = self._R
        with np.errstate(all="ignore"):     # an overflow in the check is its answer, no warning
            problem = self._valid_state(self._args, R, arr)
        _checks.check_valid_state(problem)
        problem = _checks.dead_state(self, arr, self.kind)
        if problem:
            raise ValueError(problem)
        for n, v in zip(self.state_names, arr):
            setattr(self, n, R(v))
        self._pending = None   # a state set by hand ends a pending init="first"

    @classmethod
    def _valid_state(cls, args, R, state):
        """Valid-attitude policy for state writes: None if `state` (finite,
        dtype R) is a valid state for a filter built with C init arguments
        `args`, else what is wrong. Shared with imufuse_c."""
        return None

    def update(self, *args, dt=_checks.UNSET, **named):
        # dt named in the signature: the session reads what run() and update() take from it
        *args, dt = _checks.bind("update", _checks.KINDS[self.kind], {"dt": None}, args,
                                 _checks.given(named, dt=dt))
        vals = _checks.update_inputs(self.kind, args)
        R = self._R
        with np.errstate(over="ignore"):    # beyond float32: inf, as C's conversion
            row = [R(v) for v in vals]
        if dt is not None:
            dt = R(_checks.dt_value(dt, self.dtype))
        with np.errstate(all="ignore"):
            if self._pending is not None:
                self._first(row)
            elif dt is None:
                self._update(*row)
            else:
                self._set_dt(dt)
                self._update(*row)
                self._set_dt(R(self._args[0]))

    def run(self, *args, dt=_checks.UNSET, outputs=_checks.UNSET, **named):
        """All samples; returns the (N, len(state)) trajectory, or for a 3-D filter with
        outputs="q" the (N, 4) quaternions sensor -> earth (imufuse.shared.estimate.run_outputs)."""
        *args, dt, outputs = _checks.bind("run", _checks.KINDS[self.kind],
                                          {"dt": None, "outputs": "state"}, args,
                                          _checks.given(named, dt=dt, outputs=outputs))
        if outputs != "state":
            if self.kind not in ("imu", "ahrs"):
                raise ValueError(f"outputs: {type(self).__name__} has no orientation "
                                 "quaternion (a single-axis filter); use the state")
            if outputs not in _estimate.OUTPUTS:
                _estimate.run_outputs(self, None, outputs)
            return _estimate.run_outputs(self, self.run(*args, dt=dt), outputs)
        arrays = _checks.run_inputs(self.kind, self.dtype, args)
        cols = np.column_stack([a if a.ndim == 2 else a[:, None] for a in arrays])
        n = len(self.state_names)
        out = np.empty((cols.shape[0], n), dtype=self.dtype)
        rows = cols.tolist() if self.dtype == "float64" else cols
        words = self._words
        dts = None
        if dt is not None:
            dts = _checks.dt_array(dt, cols.shape[0], self.dtype)
            dts = dts.tolist() if self.dtype == "float64" else dts
        with np.errstate(all="ignore"):
            for k, row in enumerate(rows):
                if self._pending is not None:
                    self._first(row)
                elif dts is None:
                    self._update(*row)
                else:
                    self._set_dt(dts[k])
                    self._update(*row)
                out[k] = words()
            if dts is not None:
                self._set_dt(self._R(self._args[0]))
        return out


def integral_problem(names, state, dt):
    """State writes of Mahony's integral term I (rad/s; ix, iy, iz): the
    correction it applies per sample, |I_k| dt, must stay within 1 rad, or the
    first-order step would be meaningless and the filter could not unwind it
    (it changes by at most ki dt per sample)."""
    for n in ("ix", "iy", "iz"):
        v = float(state[list(names).index(n)])
        if not abs(v) * dt <= 1.0:
            return f"{n} = {v!r}: the integral term must satisfy |{n}| dt <= 1 rad"
    return None


def _bare(cls, dtype):
    obj = cls.__new__(cls)
    obj.dtype = dtype
    obj._R = np.float32 if dtype == "float32" else float
    obj.skipped = 0
    return obj


def _bad_constant(v, v64, tiny):
    v = float(v)
    return not math.isfinite(v) or bool(v64 and abs(v) < tiny)


def _culprits(cls, names, args, dtype, key, tiny):
    """The real arguments a bad derived constant depends on: those whose
    replacement by 1.0 makes it representable (all of them if none does)."""
    real = [i for i, a in enumerate(args) if isinstance(a, float)]
    out = []
    for i in real:
        trial = list(args)
        trial[i] = 1.0
        if dataclasses.is_dataclass(args):
            trial = dataclasses.replace(args, **{names[i]: 1.0})
        mine, wide = _bare(cls, dtype), _bare(cls, "float64")
        try:
            with np.errstate(all="ignore"):
                call_init(mine, trial)
                call_init(wide, trial)
        except Exception:       # noqa: BLE001 - a trial value init cannot take
            continue
        if not _bad_constant(getattr(mine, key), getattr(wide, key), tiny):
            out.append(names[i])
    return out or [names[i] for i in real]


def check_precision(cls, args, dtype):
    """Validate C init arguments in the filter's own precision: every real
    argument must be finite and, unless zero, a normal number in dtype (dt =
    1e-50 must not become 0, acc_1g = 1e39 must not become inf in float32);
    every constant that init derives (settings and initial state, computed
    by the reference's _init in dtype) must be finite, and non-zero and
    normal wherever its float64 value is non-zero. Raises ValueError naming
    the parameters."""
    names = list(init_names(cls))
    fi = np.finfo(dtype)
    tiny = float(fi.tiny)
    for name, v in zip(names, args):
        if isinstance(v, float):
            with np.errstate(all="ignore"):
                r = float(np.float32(v)) if dtype == "float32" else v
            if not math.isfinite(r):
                raise ValueError(f"{name}: {v!r} is not representable in {dtype} "
                                 f"(largest {float(fi.max):g})")
            if v != 0.0 and abs(r) < tiny:
                raise ValueError(f"{name}: {v!r} is too small for {dtype} (below the "
                                 f"smallest normal number {tiny:g})")
    mine, wide = _bare(cls, dtype), _bare(cls, "float64")
    with np.errstate(all="ignore"):
        call_init(mine, args)
        call_init(wide, args)
    for key, v in vars(mine).items():
        if key.startswith("_") or isinstance(v, (bool, int)) or \
                not isinstance(v, (float, np.floating)):
            continue
        v64 = getattr(wide, key, None)
        v = float(v)
        if _bad_constant(v, v64, tiny):
            what = ", ".join(_culprits(cls, names, args, dtype, key, tiny))
            raise ValueError(f"{what}: the constant {key} = {v64!r} derived from them is not "
                             f"representable in {dtype} (it becomes {v!r})")


def isfinite(*values):
    return all(map(math.isfinite, values))


def init_names(cls):
    """The names of filter class `cls`'s C init arguments, in order: the members of its
    settings record (settings_type) if it declares one, else its _init's parameters."""
    record = getattr(cls, "settings_type", None)
    if record is not None:
        return tuple(f.name for f in dataclasses.fields(record))
    return tuple(inspect.signature(cls._init).parameters)[1:]


def call_init(obj, args):
    """obj._init with what _params gave: its settings record, or the C init's arguments."""
    if dataclasses.is_dataclass(args):
        obj._init(args)
    else:
        obj._init(*args)


_INIT_NAMES: dict = {}


def init_arguments(cls, args):
    """The C init arguments of filter class `cls` by name: the tuple `_params`
    returned, keyed by the names of `_init` (which are the C init's parameter
    names, checked by tests/test_catalogue.py). The compiled classes call the C
    init with these, by name."""
    names = _INIT_NAMES.get(cls)
    if names is None:
        names = _INIT_NAMES[cls] = init_names(cls)
    if len(names) != len(args):
        raise AssertionError(f"{cls.__name__}._params gives {len(args)} values for "
                             f"_init{names}")
    return dict(zip(names, args))
