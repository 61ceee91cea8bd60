# Base classes of the compiled fixed-point filters (csrc/fixed), included by
# _fixed.pyx.  Like _base.pxi for the float filters, with integer data:
# update()/run() take int16 counts (validated by the reference's helpers, so
# both backends accept and reject the same inputs), the state is the C
# struct's int32 member x, and state_float converts it with the reference's
# formula.
from libc.string cimport memcpy
from libc.stdint cimport int16_t, int32_t

import numpy as np

include "_stateout.pxi"
include "_guard.pxi"

from imufuse.reference import fixed_base as _fb
from imufuse.reference._base import init_arguments as _init_arguments


cdef int _unbound(object f) except -1:
    """An instance whose __init__ never ran (type(f).__new__(type(f)))."""
    raise TypeError(f"{type(f).__name__}: object not initialised (__init__ was not called)")


def _rebuild_fixed(cls, ctor, x):
    """Unpickle / copy a fixed-point filter: constructed as it was, its state bytes restored."""
    args, kwargs = ctor
    f = cls(*args, **kwargs)
    (<_FixedFilter>f)._restore(x)
    return f


cdef class _FixedFilter:
    cdef tuple _ctor
    cdef int32_t *_x
    cdef Py_ssize_t _n
    cdef tuple _args
    cdef dict _kw
    cdef object _conv
    cdef _StateOut _out
    cdef int _busy          # run() in progress in some thread (_guard.pxi)
    _ref = None
    dtype = "int32"

    def __init__(self, *args, profile="32", **kwargs):
        ctor = (args, dict(kwargs, profile=profile))
        # the reference instance validates the arguments and converts states
        conv = self._ref(*args, profile=profile, **kwargs)
        # the C init arguments by name (the reference _init's = the C init's names)
        kw = _init_arguments(self._ref, conv._args)
        n = len(self._ref.state_names)
        out = _StateOut(n, cnp.NPY_INT32)
        _idle(self._busy, self)     # everything checked: no Python code until the C init
        self._ctor, self._conv, self._args, self._kw, self._n, self._out = \
            ctor, conv, conv._args, kw, n, out
        self._init()

    cdef int _init(self) except -1:
        raise NotImplementedError

    def __reduce__(self):
        if self._x == NULL:
            raise TypeError(f"{type(self).__name__}: object not initialised")
        _idle(self._busy, self)
        x = (<char *>self._x)[:self._n * sizeof(int32_t)]
        return (_rebuild_fixed, (type(self), self._ctor, x))

    def __copy__(self):
        fn, args = self.__reduce__()
        return fn(*args)

    def __deepcopy__(self, memo):
        return self.__copy__()

    cdef int _restore(self, bytes x) except -1:
        if len(x) != self._n * <Py_ssize_t>sizeof(int32_t):
            raise ValueError(f"{type(self).__name__}: pickled state of another build")
        memcpy(self._x, <const char *>x, len(x))
        return 0

    cdef int _bind(self, void *x, size_t size, int rc) except -1:
        if rc != 0:
            raise AssertionError("C init rejected parameters the reference accepted")
        if size != <size_t>self._n * sizeof(int32_t):
            raise AssertionError("state struct does not match state_names")
        self._x = <int32_t *>x
        return 0

    @property
    def kind(self):
        return self._ref.kind

    @property
    def state_names(self):
        return self._ref.state_names

    @property
    def profile(self):
        if self._x == NULL:
            _unbound(self)
        return self._conv.profile

    @property
    def state(self):
        if self._x == NULL:
            _unbound(self)
        out = self._out.take()          # a new copy for every read (_stateout.pxi)
        _idle(self._busy, self)
        memcpy(cnp.PyArray_DATA(<cnp.ndarray>out), self._x, self._n * sizeof(int32_t))
        return out

    @state.setter
    def state(self, value):
        if self._x == NULL:
            _unbound(self)
        self._conv.state = value          # same validation as the reference
        arr = np.ascontiguousarray(self._conv.state, dtype=np.int32)
        cdef const int32_t[::1] v = arr
        _idle(self._busy, self)
        memcpy(self._x, &v[0], self._n * sizeof(int32_t))

    @property
    def state_float(self):
        if self._x == NULL:
            _unbound(self)
        """The state in the float twin's units (float64)."""
        return np.asarray(self._conv._state_float([int(v) for v in self.state]), dtype=float)

    def state_to_float(self, states):
        if self._x == NULL:
            _unbound(self)
        return self._conv.state_to_float(states)

    def reset(self):
        """Back to the state after construction (init runs again)."""
        if self._x == NULL:
            _unbound(self)
        _idle(self._busy, self)
        self._init()

    def __repr__(self):
        if self._x == NULL:
            return f"<imufuse_c {type(self).__name__} (not initialised)>"
        return f"<imufuse_c {type(self).__name__} profile={self.profile}>"


    @classmethod
    def run_many(cls, params, *inputs, threads=None):
        """One filter per parameter set of ``params`` (constructor keyword dicts) over one
        log, each run() (which releases the GIL) in a thread: a list of their trajectories,
        each bit for bit its own run()'s."""
        from imufuse_c import _run_many_each
        return _run_many_each(cls, params, inputs, threads, {})

cdef class _Fixed1D(_FixedFilter):
    cdef void _step(self, int16_t rate, int16_t angle) noexcept nogil:
        pass

    def update(self, rate, angle):
        """One sample: rate, angle in counts (int16)."""
        if self._x == NULL:
            _unbound(self)
        w, a = _fb.fixed_update_inputs("1d", (rate, angle))
        _idle(self._busy, self)
        self._step(<int16_t>w, <int16_t>a)

    def run(self, rate, angle):
        """All samples: rate, angle 1-D int16 counts; returns the (N, len(state)) int32 trajectory."""
        if self._x == NULL:
            _unbound(self)
        _claim(&self._busy, self)
        try:
            return self._run(rate, angle)
        finally:
            self._busy = 0

    cdef object _run(self, rate, angle):
        rate_a, angle_a = _fb.fixed_run_inputs("1d", (rate, angle))
        cdef Py_ssize_t n_samples = rate_a.shape[0], n = self._n, k
        out = np.empty((n_samples, n), dtype=np.int32)
        cdef const int16_t[::1] w = rate_a
        cdef const int16_t[::1] a = angle_a
        cdef int32_t[:, ::1] o = out
        with nogil:
            for k in range(n_samples):
                self._step(w[k], a[k])
                memcpy(&o[k, 0], self._x, n * sizeof(int32_t))
        return out


cdef class _FixedIMU(_FixedFilter):
    cdef void _step(self, const int16_t *gyr, const int16_t *acc) noexcept nogil:
        pass

    def update(self, gyr, acc):
        """One sample: gyr (3,), acc (3,) in counts (int16)."""
        if self._x == NULL:
            _unbound(self)
        cdef int16_t g[3]
        cdef int16_t a[3]
        gl, al = _fb.fixed_update_inputs("imu", (gyr, acc))
        for i in range(3):
            g[i] = <int16_t>gl[i]
            a[i] = <int16_t>al[i]
        _idle(self._busy, self)
        self._step(g, a)

    def run(self, gyr, acc):
        """All samples: gyr, acc (N, 3) int16 counts; returns the (N, len(state)) int32 trajectory."""
        if self._x == NULL:
            _unbound(self)
        _claim(&self._busy, self)
        try:
            return self._run(gyr, acc)
        finally:
            self._busy = 0

    cdef object _run(self, gyr, acc):
        gyr_a, acc_a = _fb.fixed_run_inputs("imu", (gyr, acc))
        cdef Py_ssize_t n_samples = gyr_a.shape[0], n = self._n, k
        out = np.empty((n_samples, n), dtype=np.int32)
        cdef const int16_t[:, ::1] g = gyr_a
        cdef const int16_t[:, ::1] a = acc_a
        cdef int32_t[:, ::1] o = out
        with nogil:
            for k in range(n_samples):
                self._step(&g[k, 0], &a[k, 0])
                memcpy(&o[k, 0], self._x, n * sizeof(int32_t))
        return out


cdef class _FixedAHRS(_FixedFilter):
    cdef void _step(self, const int16_t *gyr, const int16_t *acc, const int16_t *mag) noexcept nogil:
        pass

    def update(self, gyr, acc, mag):
        """One sample: gyr (3,), acc (3,), mag (3,) in counts (int16)."""
        if self._x == NULL:
            _unbound(self)
        cdef int16_t g[3]
        cdef int16_t a[3]
        cdef int16_t m[3]
        gl, al, ml = _fb.fixed_update_inputs("ahrs", (gyr, acc, mag))
        for i in range(3):
            g[i] = <int16_t>gl[i]
            a[i] = <int16_t>al[i]
            m[i] = <int16_t>ml[i]
        _idle(self._busy, self)
        self._step(g, a, m)

    def run(self, gyr, acc, mag):
        """All samples: gyr, acc, mag (N, 3) int16 counts; returns the (N, len(state)) int32
        trajectory."""
        if self._x == NULL:
            _unbound(self)
        _claim(&self._busy, self)
        try:
            return self._run(gyr, acc, mag)
        finally:
            self._busy = 0

    cdef object _run(self, gyr, acc, mag):
        gyr_a, acc_a, mag_a = _fb.fixed_run_inputs("ahrs", (gyr, acc, mag))
        cdef Py_ssize_t n_samples = gyr_a.shape[0], n = self._n, k
        out = np.empty((n_samples, n), dtype=np.int32)
        cdef const int16_t[:, ::1] g = gyr_a
        cdef const int16_t[:, ::1] a = acc_a
        cdef const int16_t[:, ::1] m = mag_a
        cdef int32_t[:, ::1] o = out
        with nogil:
            for k in range(n_samples):
                self._step(&g[k, 0], &a[k, 0], &m[k, 0])
                memcpy(&o[k, 0], self._x, n * sizeof(int32_t))
        return out
