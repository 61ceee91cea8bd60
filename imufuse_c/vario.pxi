# Variometer of Nair (2016) (csrc/vario.h): the three-state Kalman filter and
# the gravity-compensated vertical acceleration.
# Hand-written (not tools/bindgen.py): update(accel, baro_alt, dt) is an input kind of its
# own, and vertical_accel() is a function, not a filter.
cdef extern from "vario.h" nogil:
    ctypedef struct imf_vario_state_t:
        pass
    ctypedef struct imf_vario_t:
        uint32_t skipped
        imf_vario_state_t x
    ctypedef struct imf_vario_settings_t:
        imf_real var_z
        imf_real var_acc
        imf_real var_bias
        imf_real p_z
        imf_real p_v
        imf_real p_b
        imf_real z0
        imf_real v0
        imf_real b0
        int z0_from_baro
        int predict
    void imf_vario_init(imf_vario_t *self, const imf_vario_settings_t *settings)
    void imf_vario_update(imf_vario_t *self, imf_real accel, imf_real baro_alt, imf_real dt)
    imf_real imf_vertical_accel(imf_real q0, imf_real q1, imf_real q2, imf_real q3,
                                imf_real ax, imf_real ay, imf_real az, imf_real sign,
                                imf_real one_g, imf_real scale)

from imufuse.reference import vario as _vario_ref


def _rebuild_vario(cls, ctor, raw):
    """Unpickle / copy a VarioKF: constructed as it was, then its whole C struct (the state,
    the skipped count and whether z0 is still to come from the first barometer sample)."""
    args, kwargs = ctor
    f = cls(*args, **kwargs)
    (<VarioKF>f)._restore_raw(raw)
    return f


cdef class VarioKF(_Filter):
    _ref = _reference.VarioKF
    cdef imf_vario_t s

    def __reduce__(self):
        _idle(self._busy, self)
        raw = (<char *>&self.s)[:sizeof(self.s)]
        return (_rebuild_vario, (type(self), self._ctor, raw))

    cdef int _restore_raw(self, bytes raw) except -1:
        if len(raw) != sizeof(self.s):
            raise ValueError("VarioKF: pickled state of another build")
        memcpy(&self.s, <const char *>raw, sizeof(self.s))
        return 0

    def __init__(self, *args, **kwargs):
        _vario_ref.check_start(kwargs)
        super().__init__(*args, **kwargs)

    cdef int _init(self) except -1:
        a = self._kw
        cdef imf_vario_settings_t st = a
        imf_vario_init(&self.s, &st)
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped, &self.s)

    def update(self, accel, baro_alt, dt):
        """One barometer sample: accel (cm/s^2, up positive), baro_alt (cm), dt (s)."""
        cdef double a, m, d
        try:
            a = accel
            m = baro_alt
            d = dt
        except TypeError:
            _vario_ref.update_inputs(accel, baro_alt, dt)
            raise
        _idle(self._busy, self)
        imf_vario_update(&self.s, <imf_real>a, <imf_real>m, <imf_real>d)

    def run(self, accel, baro_alt, dt):
        """All samples: accel, baro_alt 1-D arrays, dt scalar or array; returns
        the (N, 9) trajectory of the state."""
        _claim(&self._busy, self)
        try:
            return self._run(accel, baro_alt, dt)
        finally:
            self._busy = 0

    cdef object _run(self, accel, baro_alt, dt):
        acc_a, alt_a, dt_a = _vario_ref.inputs(DTYPE, accel, baro_alt, dt)
        cdef Py_ssize_t n_samples = acc_a.shape[0], n = self._n, k
        out = np.empty((n_samples, n), dtype=DTYPE)
        cdef const imf_real[::1] a = acc_a
        cdef const imf_real[::1] m = alt_a
        cdef const imf_real[::1] d = dt_a
        cdef imf_real[:, ::1] o = out
        with nogil:
            for k in range(n_samples):
                imf_vario_update(&self.s, a[k], m[k], d[k])
                _copy_state(&o[k, 0], self._x, n)
        return out


def vertical_accel(q, acc, convention="nwu", one_g=1.0, scale=980.0):
    """Compiled imufuse.reference.vario.vertical_accel (this build's precision)."""
    sign, g1, c = _vario_ref.vertical_params(convention, one_g, scale)
    q_a, acc_a = _vario_ref.vertical_inputs(DTYPE, q, acc)
    cdef Py_ssize_t n_samples = q_a.shape[0], k
    out = np.empty(n_samples, dtype=DTYPE)
    cdef const imf_real[:, ::1] qv = q_a
    cdef const imf_real[:, ::1] av = acc_a
    cdef imf_real[::1] o = out
    cdef imf_real s_ = sign, g_ = g1, c_ = c
    with nogil:
        for k in range(n_samples):
            o[k] = imf_vertical_accel(qv[k, 0], qv[k, 1], qv[k, 2], qv[k, 3],
                                      av[k, 0], av[k, 1], av[k, 2], s_, g_, c_)
    return _checks.canonical_nan(out)
