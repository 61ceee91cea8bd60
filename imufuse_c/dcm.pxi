# Mahony DCM filter with Premerlani & Bizard re-orthogonalisation (csrc/dcm.h),
# article 4.1 and 4.3.
cdef extern from "dcm.h" nogil:
    ctypedef struct imf_dcm_state_t:
        pass
    ctypedef struct imf_dcm_t:
        uint32_t skipped
        imf_dcm_state_t x
    void imf_dcm_init(imf_dcm_t *self, imf_real dt, imf_real kp, imf_real ki)
    void imf_dcm_update(imf_dcm_t *self, imf_real gx, imf_real gy, imf_real gz, imf_real ax,
                        imf_real ay, imf_real az)
    void imf_dcm_set_dt(imf_dcm_t *self, imf_real dt)
    void imf_dcm_set_attitude(imf_dcm_t *self, const imf_attitude_t *att)
    void imf_dcm_angles(const imf_dcm_t *self, double *roll, double *pitch)


cdef class DCM(_FilterIMU):
    _ref = _reference.DCM
    cdef imf_dcm_t s

    cdef int _init(self) except -1:
        a = self._kw
        imf_dcm_init(&self.s, a["dt"], a["kp"], a["ki"])
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, const imf_real *gyr, const imf_real *acc) noexcept nogil:
        imf_dcm_update(&self.s, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2])

    def angles(self):
        """(roll, pitch) in rad (ZYX) of r_z, in double: an output, not state."""
        cdef double roll, pitch
        imf_dcm_angles(&self.s, &roll, &pitch)
        return roll, pitch

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_dcm_set_dt(&self.s, dt)

    cdef void _set_attitude(self, const imf_attitude_t *att) noexcept nogil:
        imf_dcm_set_attitude(&self.s, att)
