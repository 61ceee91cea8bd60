# "KK" linear small-angle filter (csrc/kk.h), article appendix / Eq. 4.5.
cdef extern from "kk.h" nogil:
    ctypedef struct imf_kk_state_t:
        imf_real pitch
        imf_real roll
    ctypedef struct imf_kk_t:
        uint32_t skipped
        imf_kk_state_t x
    void imf_kk_init(imf_kk_t *self, imf_real dt, imf_real kp)
    void imf_kk_update(imf_kk_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                       imf_real ay, imf_real az)
    void imf_kk_set_dt(imf_kk_t *self, imf_real dt)
    void imf_kk_set_attitude(imf_kk_t *self, const imf_attitude_t *att)


cdef class KK(_FilterIMU):
    _ref = _reference.KK
    cdef imf_kk_t s

    cdef int _init(self) except -1:
        a = self._kw
        imf_kk_init(&self.s, a["dt"], a["kp"])
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, const imf_real *gyr, const imf_real *acc) noexcept nogil:
        imf_kk_update(&self.s, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2])

    def angles(self):
        """(roll, pitch) in rad: the state itself, as double."""
        return <double>self.s.x.roll, <double>self.s.x.pitch

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_kk_set_dt(&self.s, dt)

    cdef void _set_attitude(self, const imf_attitude_t *att) noexcept nogil:
        imf_kk_set_attitude(&self.s, att)
