# Base classes of the compiled filters, included once per precision by
# _f32.pyx / _f64.pyx (which define imf_real, DTYPE).
#
# A filter class wraps one C struct imf_<filter>_t. The base classes hold
# everything generic: parameter validation (delegated to the reference
# class, so both backends accept the same arguments), the state view (a
# memcpy of the struct's state member x), reset, and the run() loop, which
# runs without the GIL and calls the filter's _step for every sample.
from cpython.float cimport PyFloat_AsDouble
from libc.string cimport memcpy
from libc.stdint cimport uint32_t
cimport numpy as cnp

import numpy as np

cnp.import_array()

from imufuse import _checks

_R = np.float32 if DTYPE == "float32" else float


cdef inline void _copy_state(imf_real *dst, const char *x, Py_ssize_t n) noexcept nogil:
    # a short element loop: cheaper than a memcpy call for a few words per sample
    cdef const imf_real *src = <const imf_real *>x
    cdef Py_ssize_t j
    for j in range(n):
        dst[j] = src[j]


cdef int _vec3(object v, imf_real *out) except -1:
    """One 3-vector of update(): fast paths for tuples, lists and contiguous
    float64/float32 arrays; anything else through the sequence protocol. A
    conversion error raises TypeError/ValueError (update() reports it)."""
    cdef const double *d
    cdef const float *f
    cdef int i
    if (type(v) is tuple or type(v) is list) and len(v) == 3:
        for i in range(3):
            out[i] = <imf_real>PyFloat_AsDouble(v[i])
        return 0
    if cnp.PyArray_Check(v) and cnp.PyArray_NDIM(v) == 1 and cnp.PyArray_DIM(v, 0) == 3 \
            and cnp.PyArray_ISCARRAY_RO(v) and cnp.PyArray_ISNOTSWAPPED(v):
        if cnp.PyArray_TYPE(v) == cnp.NPY_DOUBLE:
            d = <const double *>cnp.PyArray_DATA(v)
            for i in range(3):
                out[i] = <imf_real>d[i]
            return 0
        if cnp.PyArray_TYPE(v) == cnp.NPY_FLOAT:
            f = <const float *>cnp.PyArray_DATA(v)
            for i in range(3):
                out[i] = <imf_real>f[i]
            return 0
    x, y, z = v
    out[0] = <imf_real><double>x
    out[1] = <imf_real><double>y
    out[2] = <imf_real><double>z
    return 0


cdef int _unbound(object f) except -1:
    """An instance whose __init__ never ran (type(f).__new__(type(f))): its C
    struct was never initialised; raise instead of touching it."""
    raise TypeError(f"{type(f).__name__}: object not initialised (__init__ was not called)")


cdef class _Filter:
    cdef char *_x
    cdef Py_ssize_t _n
    cdef uint32_t *_skipped
    cdef tuple _args
    _ref = None
    dtype = DTYPE

    def __init__(self, *args, **kwargs):
        self._args = self._ref._params(*args, **kwargs)
        self._n = len(self._ref.state_names)
        self._init()

    cdef int _init(self) except -1:
        raise NotImplementedError

    cdef int _bind(self, void *x, size_t size, uint32_t *skipped) except -1:
        if size != <size_t>self._n * sizeof(imf_real):
            raise AssertionError("state struct does not match state_names")
        self._x = <char *>x
        self._skipped = skipped
        return 0

    @property
    def kind(self):
        return self._ref.kind

    @property
    def state_names(self):
        return self._ref.state_names

    @property
    def skipped(self):
        """Samples rejected by the non-finite policy since construction or reset."""
        if self._skipped == NULL:
            _unbound(self)
        return self._skipped[0]

    @property
    def state(self):
        if self._x == NULL:
            _unbound(self)
        out = np.empty(self._n, dtype=DTYPE)
        cdef imf_real[::1] o = out
        memcpy(&o[0], self._x, self._n * sizeof(imf_real))
        return out

    @state.setter
    def state(self, value):
        if self._x == NULL:
            _unbound(self)
        arr = _checks.as_state(value, self._n, DTYPE, self._ref.state_names)
        _checks.check_valid_state(self._ref._valid_state(self._args, _R, arr))
        cdef const imf_real[::1] v = arr
        memcpy(self._x, &v[0], self._n * sizeof(imf_real))

    def reset(self):
        """Back to the state after construction (init runs again)."""
        if self._x == NULL:
            _unbound(self)
        self._init()

    def __repr__(self):
        return f"<imufuse_c {type(self).__name__} dtype={DTYPE}>"


cdef class _Filter1D(_Filter):
    cdef void _step(self, imf_real rate, imf_real angle) noexcept nogil:
        pass

    def update(self, rate, angle):
        """One sample: rate (rad/s), angle (rad)."""
        if self._x == NULL:
            _unbound(self)
        cdef double w, a
        try:
            w = rate
            a = angle
        except TypeError:
            _checks.update_inputs("1d", (rate, angle))
            raise
        self._step(<imf_real>w, <imf_real>a)

    def run(self, rate, angle):
        """All samples: rate, angle 1-D arrays; returns the (N, len(state)) trajectory."""
        if self._x == NULL:
            _unbound(self)
        rate_a, angle_a = _checks.run_inputs("1d", DTYPE, (rate, angle))
        cdef Py_ssize_t n_samples = rate_a.shape[0], n = self._n, k
        out = np.empty((n_samples, n), dtype=DTYPE)
        cdef const imf_real[::1] w = rate_a
        cdef const imf_real[::1] a = angle_a
        cdef imf_real[:, ::1] o = out
        with nogil:
            for k in range(n_samples):
                self._step(w[k], a[k])
                _copy_state(&o[k, 0], self._x, n)
        return out


cdef class _FilterIMU(_Filter):
    cdef void _step(self, const imf_real *gyr, const imf_real *acc) noexcept nogil:
        pass

    def update(self, gyr, acc):
        """One sample: gyr (3,) rad/s, acc (3,) any unit."""
        if self._x == NULL:
            _unbound(self)
        cdef imf_real g[3]
        cdef imf_real a[3]
        try:
            _vec3(gyr, g)
            _vec3(acc, a)
        except (TypeError, ValueError):
            _checks.update_inputs("imu", (gyr, acc))
            raise
        self._step(g, a)

    def run(self, gyr, acc):
        """All samples: gyr, acc (N, 3) arrays; returns the (N, len(state)) trajectory."""
        if self._x == NULL:
            _unbound(self)
        gyr_a, acc_a = _checks.run_inputs("imu", DTYPE, (gyr, acc))
        cdef Py_ssize_t n_samples = gyr_a.shape[0], n = self._n, k
        out = np.empty((n_samples, n), dtype=DTYPE)
        cdef const imf_real[:, ::1] g = gyr_a
        cdef const imf_real[:, ::1] a = acc_a
        cdef imf_real[:, ::1] o = out
        with nogil:
            for k in range(n_samples):
                self._step(&g[k, 0], &a[k, 0])
                _copy_state(&o[k, 0], self._x, n)
        return out


cdef class _FilterAHRS(_Filter):
    cdef void _step(self, const imf_real *gyr, const imf_real *acc,
                    const imf_real *mag) noexcept nogil:
        pass

    def update(self, gyr, acc, mag):
        """One sample: gyr (3,) rad/s, acc (3,) and mag (3,) any unit."""
        if self._x == NULL:
            _unbound(self)
        cdef imf_real g[3]
        cdef imf_real a[3]
        cdef imf_real m[3]
        try:
            _vec3(gyr, g)
            _vec3(acc, a)
            _vec3(mag, m)
        except (TypeError, ValueError):
            _checks.update_inputs("ahrs", (gyr, acc, mag))
            raise
        self._step(g, a, m)

    def run(self, gyr, acc, mag):
        """All samples: gyr, acc, mag (N, 3) arrays; returns the (N, len(state)) trajectory."""
        if self._x == NULL:
            _unbound(self)
        gyr_a, acc_a, mag_a = _checks.run_inputs("ahrs", DTYPE, (gyr, acc, mag))
        cdef Py_ssize_t n_samples = gyr_a.shape[0], n = self._n, k
        out = np.empty((n_samples, n), dtype=DTYPE)
        cdef const imf_real[:, ::1] g = gyr_a
        cdef const imf_real[:, ::1] a = acc_a
        cdef const imf_real[:, ::1] m = mag_a
        cdef imf_real[:, ::1] o = out
        with nogil:
            for k in range(n_samples):
                self._step(&g[k, 0], &a[k, 0], &m[k, 0])
                _copy_state(&o[k, 0], self._x, n)
        return out
