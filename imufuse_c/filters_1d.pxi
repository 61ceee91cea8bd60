# Single-axis filters (csrc/filters_1d.h), article chapters 2 and 3.
cdef extern from "filters_1d.h" nogil:
    ctypedef struct imf_complementary1d_state_t:
        pass
    ctypedef struct imf_complementary1d_t:
        uint32_t skipped
        imf_complementary1d_state_t x
    void imf_complementary1d_init(imf_complementary1d_t *self, imf_real dt, imf_real alpha)
    void imf_complementary1d_update(imf_complementary1d_t *self, imf_real rate, imf_real angle)
    void imf_complementary1d_set_dt(imf_complementary1d_t *self, imf_real dt)

    ctypedef struct imf_kalman1d_state_t:
        pass
    ctypedef struct imf_kalman1d_t:
        uint32_t skipped
        imf_kalman1d_state_t x
    void imf_kalman1d_init(imf_kalman1d_t *self, imf_real dt, imf_real k0)
    void imf_kalman1d_update(imf_kalman1d_t *self, imf_real rate, imf_real angle)
    void imf_kalman1d_set_dt(imf_kalman1d_t *self, imf_real dt)

    ctypedef struct imf_mahony1d_state_t:
        pass
    ctypedef struct imf_mahony1d_t:
        uint32_t skipped
        imf_mahony1d_state_t x
    void imf_mahony1d_init(imf_mahony1d_t *self, imf_real dt, imf_real kp)
    void imf_mahony1d_update(imf_mahony1d_t *self, imf_real rate, imf_real angle)
    void imf_mahony1d_set_dt(imf_mahony1d_t *self, imf_real dt)

    ctypedef struct imf_kalman1d_bias_state_t:
        pass
    ctypedef struct imf_kalman1d_bias_t:
        uint32_t skipped
        imf_kalman1d_bias_state_t x
    void imf_kalman1d_bias_init(imf_kalman1d_bias_t *self, imf_real dt, imf_real k0,
                                imf_real k1, int bias_sign)
    void imf_kalman1d_bias_update(imf_kalman1d_bias_t *self, imf_real rate, imf_real angle)
    void imf_kalman1d_bias_set_dt(imf_kalman1d_bias_t *self, imf_real dt)

    ctypedef struct imf_mahony1d_bias_state_t:
        pass
    ctypedef struct imf_mahony1d_bias_t:
        uint32_t skipped
        imf_mahony1d_bias_state_t x
    void imf_mahony1d_bias_init(imf_mahony1d_bias_t *self, imf_real dt, imf_real kp,
                                imf_real ki, int integrate_first)
    void imf_mahony1d_bias_update(imf_mahony1d_bias_t *self, imf_real rate, imf_real angle)
    void imf_mahony1d_bias_set_dt(imf_mahony1d_bias_t *self, imf_real dt)

    ctypedef struct imf_complementary1d_bias_state_t:
        pass
    ctypedef struct imf_complementary1d_bias_t:
        uint32_t skipped
        imf_complementary1d_bias_state_t x
    void imf_complementary1d_bias_init(imf_complementary1d_bias_t *self, imf_real dt,
                                       imf_real kp, imf_real ki)
    void imf_complementary1d_bias_update(imf_complementary1d_bias_t *self, imf_real rate,
                                         imf_real angle)
    void imf_complementary1d_bias_set_dt(imf_complementary1d_bias_t *self, imf_real dt)


cdef class Complementary1D(_Filter1D):
    _ref = _reference.Complementary1D
    cdef imf_complementary1d_t s

    cdef int _init(self) except -1:
        a = self._kw
        imf_complementary1d_init(&self.s, a["dt"], a["alpha"])
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, imf_real rate, imf_real angle) noexcept nogil:
        imf_complementary1d_update(&self.s, rate, angle)

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_complementary1d_set_dt(&self.s, dt)


cdef class Kalman1D(_Filter1D):
    _ref = _reference.Kalman1D
    cdef imf_kalman1d_t s

    cdef int _init(self) except -1:
        a = self._kw
        imf_kalman1d_init(&self.s, a["dt"], a["k0"])
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, imf_real rate, imf_real angle) noexcept nogil:
        imf_kalman1d_update(&self.s, rate, angle)

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_kalman1d_set_dt(&self.s, dt)


cdef class Mahony1D(_Filter1D):
    _ref = _reference.Mahony1D
    cdef imf_mahony1d_t s

    cdef int _init(self) except -1:
        a = self._kw
        imf_mahony1d_init(&self.s, a["dt"], a["kp"])
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, imf_real rate, imf_real angle) noexcept nogil:
        imf_mahony1d_update(&self.s, rate, angle)

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_mahony1d_set_dt(&self.s, dt)


cdef class Kalman1DBias(_Filter1D):
    _ref = _reference.Kalman1DBias
    cdef imf_kalman1d_bias_t s

    cdef int _init(self) except -1:
        a = self._kw
        imf_kalman1d_bias_init(&self.s, a["dt"], a["k0"], a["k1"], a["bias_sign"])
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, imf_real rate, imf_real angle) noexcept nogil:
        imf_kalman1d_bias_update(&self.s, rate, angle)

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_kalman1d_bias_set_dt(&self.s, dt)


cdef class Mahony1DBias(_Filter1D):
    _ref = _reference.Mahony1DBias
    cdef imf_mahony1d_bias_t s

    cdef int _init(self) except -1:
        a = self._kw
        imf_mahony1d_bias_init(&self.s, a["dt"], a["kp"], a["ki"], a["integrate_first"])
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, imf_real rate, imf_real angle) noexcept nogil:
        imf_mahony1d_bias_update(&self.s, rate, angle)

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_mahony1d_bias_set_dt(&self.s, dt)


cdef class Complementary1DBias(_Filter1D):
    _ref = _reference.Complementary1DBias
    cdef imf_complementary1d_bias_t s

    cdef int _init(self) except -1:
        a = self._kw
        imf_complementary1d_bias_init(&self.s, a["dt"], a["kp"], a["ki"])
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, imf_real rate, imf_real angle) noexcept nogil:
        imf_complementary1d_bias_update(&self.s, rate, angle)

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_complementary1d_bias_set_dt(&self.s, dt)
