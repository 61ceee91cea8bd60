# Filter family mahony (csrc/mahony.h): article 4.1 and appendix.
cdef extern from "mahony.h" nogil:
    ctypedef struct imf_mahony_state_t:
        pass
    ctypedef struct imf_mahony_imu_t:
        uint32_t skipped
        imf_mahony_state_t x
    ctypedef struct imf_mahony_ahrs_t:
        uint32_t skipped
        imf_mahony_state_t x
    ctypedef struct imf_mahony_imu_settings_t:
        imf_real dt
        imf_real kp
        imf_real ki
        int invsqrt
        imf_real acc_gate_lo
        imf_real acc_gate_hi
        imf_real acc_1g
    void imf_mahony_imu_init(imf_mahony_imu_t *self, const imf_mahony_imu_settings_t *settings)
    void imf_mahony_imu_update(imf_mahony_imu_t *self, imf_real gx, imf_real gy, imf_real gz,
                               imf_real ax, imf_real ay, imf_real az)
    void imf_mahony_imu_set_dt(imf_mahony_imu_t *self, imf_real dt)
    void imf_mahony_imu_set_attitude(imf_mahony_imu_t *self, const imf_attitude_t *att)
    ctypedef struct imf_mahony_ahrs_settings_t:
        imf_real dt
        imf_real kp
        imf_real ki
        int invsqrt
        imf_real acc_gate_lo
        imf_real acc_gate_hi
        imf_real acc_1g
    void imf_mahony_ahrs_init(imf_mahony_ahrs_t *self, const imf_mahony_ahrs_settings_t *settings)
    void imf_mahony_ahrs_update(imf_mahony_ahrs_t *self, imf_real gx, imf_real gy, imf_real gz,
                                imf_real ax, imf_real ay, imf_real az,
                                imf_real mx, imf_real my, imf_real mz)
    void imf_mahony_ahrs_set_dt(imf_mahony_ahrs_t *self, imf_real dt)
    void imf_mahony_ahrs_set_attitude(imf_mahony_ahrs_t *self, const imf_attitude_t *att)


cdef class MahonyIMU(_FilterIMU):
    _ref = _reference.MahonyIMU
    cdef imf_mahony_imu_t s

    cdef int _init(self) except -1:
        a = self._kw
        cdef imf_mahony_imu_settings_t st = a
        imf_mahony_imu_init(&self.s, &st)
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, const imf_real *gyr, const imf_real *acc) noexcept nogil:
        imf_mahony_imu_update(&self.s, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2])

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_mahony_imu_set_dt(&self.s, dt)

    cdef void _set_attitude(self, const imf_attitude_t *att) noexcept nogil:
        imf_mahony_imu_set_attitude(&self.s, att)


cdef class MahonyAHRS(_FilterAHRS):
    _ref = _reference.MahonyAHRS
    cdef imf_mahony_ahrs_t s

    cdef int _init(self) except -1:
        a = self._kw
        cdef imf_mahony_ahrs_settings_t st = a
        imf_mahony_ahrs_init(&self.s, &st)
        return self._bind(&self.s.x, sizeof(self.s.x), &self.s.skipped)

    cdef void _step(self, const imf_real *gyr, const imf_real *acc,
                    const imf_real *mag) noexcept nogil:
        imf_mahony_ahrs_update(&self.s, gyr[0], gyr[1], gyr[2], acc[0], acc[1], acc[2],
                               mag[0], mag[1], mag[2])

    cdef void _set_dt(self, imf_real dt) noexcept nogil:
        imf_mahony_ahrs_set_dt(&self.s, dt)

    cdef void _set_attitude(self, const imf_attitude_t *att) noexcept nogil:
        imf_mahony_ahrs_set_attitude(&self.s, att)
