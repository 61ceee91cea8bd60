# 2D Mahony filter (csrc/mahony2d.h), article 4.2, Eq. 4.3 / 4.4.
cdef extern from "mahony2d.h" nogil:
    ctypedef struct imf_mahony2d_state_t:
        pass
    ctypedef struct imf_mahony2d_t:
        uint32_t skipped
        imf_mahony2d_state_t x
    void imf_mahony2d_init(imf_mahony2d_t *self, imf_real dt, imf_real kp, imf_real ki,
                           int exact)
    void imf_mahony2d_update(imf_mahony2d_t *self, imf_real gx, imf_real gy, imf_real gz,
                             imf_real ax, imf_real ay, imf_real az)
    void imf_mahony2d_set_dt(imf_mahony2d_t *self, imf_real dt)
    void imf_mahony2d_set_attitude(imf_mahony2d_t *self, const imf_attitude_t *att)
    void imf_mahony2d_angles(const imf_mahony2d_t *self, double *roll, double *pitch)


cdef class Mahony2D(_FilterIMU):
    _ref = _reference.Mahony2D
    cdef imf_mahony2d_t s

    cdef int _init(self) except -1:
        a = self._kw
        imf_mahony2d_init(&self.s, a["dt"], a["kp"], a["ki"], a["exact"])
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, const imf_real *gyr, const imf_real *acc) noexcept nogil:
        imf_mahony2d_update(&self.s, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2])

    def angles(self):
        """(roll, pitch) in rad (ZYX) of d, in double: an output, not state."""
        cdef double roll, pitch
        imf_mahony2d_angles(&self.s, &roll, &pitch)
        return roll, pitch

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_mahony2d_set_dt(&self.s, dt)

    cdef void _set_attitude(self, const imf_attitude_t *att) noexcept nogil:
        imf_mahony2d_set_attitude(&self.s, att)
