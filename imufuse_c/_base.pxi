# Base classes of the compiled filters, included once per precision by
# _f32.pyx / _f64.pyx (which define imf_real, DTYPE).
#
# A filter class wraps one C struct imf_<filter>_t. The base classes hold
# everything generic: parameter validation (delegated to the reference
# class, so both backends accept the same arguments), the state view (a
# memcpy of the struct's state member x), reset, and the run() loop, which
# runs without the GIL and calls the filter's _step for every sample.
from libc.string cimport memcpy
from libc.stdint cimport uint32_t

import numpy as np

from imufuse import _checks


cdef inline void _copy_state(imf_real *dst, const char *x, Py_ssize_t n) noexcept nogil:
    # a short element loop: cheaper than a memcpy call for a few words per sample
    cdef const imf_real *src = <const imf_real *>x
    cdef Py_ssize_t j
    for j in range(n):
        dst[j] = src[j]


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
        return self._skipped[0]

    @property
    def state(self):
        out = np.empty(self._n, dtype=DTYPE)
        cdef imf_real[::1] o = out
        memcpy(&o[0], self._x, self._n * sizeof(imf_real))
        return out

    @state.setter
    def state(self, value):
        arr = _checks.as_state(value, self._n, DTYPE, self._ref.state_names)
        cdef const imf_real[::1] v = arr
        memcpy(self._x, &v[0], self._n * sizeof(imf_real))

    def reset(self):
        """Back to the state after construction (init runs again)."""
        self._init()

    def __repr__(self):
        return f"<imufuse_c {type(self).__name__} dtype={DTYPE}>"


cdef class _Filter1D(_Filter):
    cdef void _step(self, imf_real rate, imf_real angle) noexcept nogil:
        pass

    def update(self, rate, angle):
        """One sample: rate (rad/s), angle (rad)."""
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
        cdef double g[3]
        cdef double a[3]
        cdef imf_real gr[3]
        cdef imf_real ar[3]
        try:
            g[0], g[1], g[2] = gyr
            a[0], a[1], a[2] = acc
        except (TypeError, ValueError):
            _checks.update_inputs("imu", (gyr, acc))
            raise
        for i in range(3):
            gr[i] = <imf_real>g[i]
            ar[i] = <imf_real>a[i]
        self._step(gr, ar)

    def run(self, gyr, acc):
        """All samples: gyr, acc (N, 3) arrays; returns the (N, len(state)) trajectory."""
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
        cdef double g[3]
        cdef double a[3]
        cdef double m[3]
        cdef imf_real gr[3]
        cdef imf_real ar[3]
        cdef imf_real mr[3]
        try:
            g[0], g[1], g[2] = gyr
            a[0], a[1], a[2] = acc
            m[0], m[1], m[2] = mag
        except (TypeError, ValueError):
            _checks.update_inputs("ahrs", (gyr, acc, mag))
            raise
        for i in range(3):
            gr[i] = <imf_real>g[i]
            ar[i] = <imf_real>a[i]
            mr[i] = <imf_real>m[i]
        self._step(gr, ar, mr)

    def run(self, gyr, acc, mag):
        """All samples: gyr, acc, mag (N, 3) arrays; returns the (N, len(state)) trajectory."""
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
