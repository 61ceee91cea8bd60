"""Base class of the pure-Python reference filters.

A reference filter mirrors its C twin operation by operation. Arithmetic is
done on the type `self._R`: Python float for float64 (the same IEEE double
operations as C), numpy.float32 scalars for float32 (every operation rounded
to float32, as C float does; NumPy >= 2 keeps float32 when a Python number is
mixed in, and the code wraps every constant in R() like C's IMF_R()).

Subclasses define:
  kind         "1d", "imu" or "ahrs" (the update() signature, see _checks.KINDS)
  c_name       prefix of the C twin: <c_name>_t, <c_name>_init, <c_name>_update
  state_names  the state variables, in the order of the C state struct; each
               is an attribute of the instance
  _params(...) staticmethod: validate constructor arguments, return the tuple
               of C init arguments (shared with imufuse_c)
  _init(*args) mirror of imf_<filter>_init
  _update(*scalars) mirror of imf_<filter>_update, inputs already of type R
"""
import inspect
import math

import numpy as np

from .. import _checks

U32 = 0xFFFFFFFF


class ReferenceFilter:
    kind = "1d"
    c_name = ""
    state_names: tuple = ()

    def __init__(self, *args, dtype="float64", **kwargs):
        self.dtype = _checks.check_dtype(dtype)
        self._R = np.float32 if self.dtype == "float32" else float
        self._args = self._params(*args, **kwargs)
        self.reset()

    def reset(self):
        """Back to the state after construction (init runs again)."""
        self.skipped = 0
        with np.errstate(all="ignore"):
            self._init(*self._args)

    def _skip(self):
        # C: uint32_t skipped; skipped++ wraps modulo 2^32
        self.skipped = (self.skipped + 1) & U32

    @property
    def state(self):
        return np.array([getattr(self, n) for n in self.state_names], dtype=self.dtype)

    @state.setter
    def state(self, value):
        arr = _checks.as_state(value, len(self.state_names), self.dtype, self.state_names)
        R = self._R
        for n, v in zip(self.state_names, arr):
            setattr(self, n, R(v))

    def update(self, *args):
        vals = _checks.update_inputs(self.kind, args)
        R = self._R
        with np.errstate(all="ignore"):
            self._update(*[R(v) for v in vals])

    def run(self, *args):
        arrays = _checks.run_inputs(self.kind, self.dtype, args)
        cols = np.column_stack([a if a.ndim == 2 else a[:, None] for a in arrays])
        n = len(self.state_names)
        out = np.empty((cols.shape[0], n), dtype=self.dtype)
        rows = cols.tolist() if self.dtype == "float64" else cols
        names = self.state_names
        with np.errstate(all="ignore"):
            for k, row in enumerate(rows):
                self._update(*row)
                out[k] = [getattr(self, s) for s in names]
        return out


def isfinite(*values):
    return all(math.isfinite(v) for v in values)


_INIT_NAMES: dict = {}


def init_arguments(cls, args):
    """The C init arguments of filter class `cls` by name: the tuple `_params`
    returned, keyed by the names of `_init` (which are the C init's parameter
    names, checked by tests/test_catalogue.py). The compiled classes call the C
    init with these, by name."""
    names = _INIT_NAMES.get(cls)
    if names is None:
        names = _INIT_NAMES[cls] = tuple(inspect.signature(cls._init).parameters)[1:]
    if len(names) != len(args):
        raise AssertionError(f"{cls.__name__}._params gives {len(args)} values for "
                             f"_init{names}")
    return dict(zip(names, args))
