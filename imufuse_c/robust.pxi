# Filter family robust (csrc/robust.h): imufuse's recommended AHRS.
cdef extern from "robust.h" nogil:
    ctypedef struct imf_robust_state_t:
        pass
    ctypedef struct imf_robust_imu_t:
        uint32_t skipped
        imf_robust_state_t x
    ctypedef struct imf_robust_ahrs_t:
        uint32_t skipped
        imf_robust_state_t x
    ctypedef struct imf_robust_imu_settings_t:
        imf_real dt
        imf_real tau_acc
        imf_real rate_ref
        imf_real tau_bias
        imf_real tau_bias_rest
        imf_real rest_gyr
        imf_real rest_acc
        imf_real rest_time
        imf_real tau_rest
        imf_real latency
    void imf_robust_imu_init(imf_robust_imu_t *self, const imf_robust_imu_settings_t *settings)
    void imf_robust_imu_update(imf_robust_imu_t *self, imf_real gx, imf_real gy, imf_real gz,
                               imf_real ax, imf_real ay, imf_real az)
    void imf_robust_imu_set_dt(imf_robust_imu_t *self, imf_real dt)
    void imf_robust_imu_set_attitude(imf_robust_imu_t *self, const imf_attitude_t *att)
    ctypedef struct imf_robust_ahrs_settings_t:
        imf_real dt
        imf_real tau_acc
        imf_real rate_ref
        imf_real tau_bias
        imf_real tau_bias_rest
        imf_real rest_gyr
        imf_real rest_acc
        imf_real rest_time
        imf_real tau_rest
        imf_real latency
        imf_real tau_mag
        imf_real mag_norm
        imf_real mag_dip
        imf_real tau_mag_ref
        imf_real mag_new_time
        imf_real mag_hold
    void imf_robust_ahrs_init(imf_robust_ahrs_t *self, const imf_robust_ahrs_settings_t *settings)
    void imf_robust_ahrs_update(imf_robust_ahrs_t *self, imf_real gx, imf_real gy, imf_real gz,
                                imf_real ax, imf_real ay, imf_real az,
                                imf_real mx, imf_real my, imf_real mz)
    void imf_robust_ahrs_set_dt(imf_robust_ahrs_t *self, imf_real dt)
    void imf_robust_ahrs_set_attitude(imf_robust_ahrs_t *self, const imf_attitude_t *att)


cdef class RobustIMU(_FilterIMU):
    _ref = _reference.RobustIMU
    cdef imf_robust_imu_t s

    cdef int _init(self) except -1:
        a = self._kw
        cdef imf_robust_imu_settings_t st = a
        imf_robust_imu_init(&self.s, &st)
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, const imf_real *gyr, const imf_real *acc) noexcept nogil:
        imf_robust_imu_update(&self.s, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2])

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_robust_imu_set_dt(&self.s, dt)

    cdef void _set_attitude(self, const imf_attitude_t *att) noexcept nogil:
        imf_robust_imu_set_attitude(&self.s, att)


cdef class RobustAHRS(_FilterAHRS):
    _ref = _reference.RobustAHRS
    cdef imf_robust_ahrs_t s

    cdef int _init(self) except -1:
        a = self._kw
        cdef imf_robust_ahrs_settings_t st = a
        imf_robust_ahrs_init(&self.s, &st)
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, const imf_real *gyr, const imf_real *acc,
                    const imf_real *mag) noexcept nogil:
        imf_robust_ahrs_update(&self.s, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2],
                               mag[0], mag[1], mag[2])

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_robust_ahrs_set_dt(&self.s, dt)

    cdef void _set_attitude(self, const imf_attitude_t *att) noexcept nogil:
        imf_robust_ahrs_set_attitude(&self.s, att)
