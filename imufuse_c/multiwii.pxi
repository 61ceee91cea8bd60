# MultiWii 2.2 attitude estimate (csrc/multiwii.h), article appendix.
cdef extern from "multiwii.h" nogil:
    ctypedef struct imf_multiwii_state_t:
        pass
    ctypedef struct imf_multiwii_t:
        uint32_t skipped
        imf_multiwii_state_t x
    ctypedef struct imf_multiwii_settings_t:
        imf_real dt
        imf_real cmpf
        int acc_lpf_shift
        imf_real acc_1g
        imf_real window
    void imf_multiwii_init(imf_multiwii_t *self, const imf_multiwii_settings_t *settings)
    void imf_multiwii_update(imf_multiwii_t *self, imf_real gx, imf_real gy, imf_real gz,
                             imf_real ax, imf_real ay, imf_real az)
    void imf_multiwii_set_dt(imf_multiwii_t *self, imf_real dt)
    void imf_multiwii_set_attitude(imf_multiwii_t *self, const imf_attitude_t *att)
    void imf_multiwii_angles(const imf_multiwii_t *self, double *roll, double *pitch)


cdef class MultiWii(_FilterIMU):
    _ref = _reference.MultiWii
    cdef imf_multiwii_t s

    cdef int _init(self) except -1:
        a = self._kw
        cdef imf_multiwii_settings_t st = a
        imf_multiwii_init(&self.s, &st)
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, const imf_real *gyr, const imf_real *acc) noexcept nogil:
        imf_multiwii_update(&self.s, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2])

    def angles(self):
        """(roll, pitch) in rad (ZYX) of d, in double: an output, not state."""
        cdef double roll, pitch
        imf_multiwii_angles(&self.s, &roll, &pitch)
        return roll, pitch

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_multiwii_set_dt(&self.s, dt)

    cdef void _set_attitude(self, const imf_attitude_t *att) noexcept nogil:
        imf_multiwii_set_attitude(&self.s, att)
