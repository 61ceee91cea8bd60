# The fixed-point filters of csrc/fixed (one class per C filter; the profile
# given to init selects imf_<filter>_q_update_p32 or _p8 where they differ).
cdef extern from "imf_fixed.h" nogil:
    ctypedef struct imf_qscale_t:
        pass

cdef extern from "filters_1d_q.h" nogil:
    ctypedef struct imf_complementary1d_q_state_t:
        pass
    ctypedef struct imf_complementary1d_q_t:
        imf_complementary1d_q_state_t x
    int imf_complementary1d_q_init(imf_complementary1d_q_t *self, double dt, double alpha,
                                   double gyr_scale, double angle_scale)
    void imf_complementary1d_q_update(imf_complementary1d_q_t *self, int16_t rate, int16_t angle)

    ctypedef struct imf_mahony1d_bias_q_state_t:
        pass
    ctypedef struct imf_mahony1d_bias_q_t:
        imf_mahony1d_bias_q_state_t x
    ctypedef struct imf_mahony1d_bias_q_settings_t:
        double dt
        double kp
        double ki
        int integrate_first
        double gyr_scale
        double angle_scale
    int imf_mahony1d_bias_q_init(imf_mahony1d_bias_q_t *self, const imf_mahony1d_bias_q_settings_t *settings)
    void imf_mahony1d_bias_q_update(imf_mahony1d_bias_q_t *self, int16_t rate, int16_t angle)

cdef extern from "gravity_q.h" nogil:
    ctypedef struct imf_kk_q_state_t:
        pass
    ctypedef struct imf_kk_q_t:
        imf_kk_q_state_t x
    int imf_kk_q_init(imf_kk_q_t *self, double dt, double kp, double gyr_scale)
    void imf_kk_q_update(imf_kk_q_t *self, const int16_t *gyr, const int16_t *acc)

    ctypedef struct imf_multiwii_q_state_t:
        pass
    ctypedef struct imf_multiwii_q_t:
        imf_multiwii_q_state_t x
    ctypedef struct imf_multiwii_q_settings_t:
        double dt
        double cmpf
        int acc_lpf_shift
        double acc_1g
        double window
        double gyr_scale
    int imf_multiwii_q_init(imf_multiwii_q_t *self, const imf_multiwii_q_settings_t *settings)
    void imf_multiwii_q_update(imf_multiwii_q_t *self, const int16_t *gyr, const int16_t *acc)

cdef extern from "mahony_q.h" nogil:
    ctypedef struct imf_mahony_imu_q_state_t:
        pass
    ctypedef struct imf_mahony_imu_q_t:
        imf_mahony_imu_q_state_t x
    ctypedef struct imf_mahony_imu_q_settings_t:
        double dt
        double kp
        double ki
        double gyr_scale
        int profile
    int imf_mahony_imu_q_init(imf_mahony_imu_q_t *self, const imf_mahony_imu_q_settings_t *settings)
    void imf_mahony_imu_q_update(imf_mahony_imu_q_t *self, const int16_t *gyr, const int16_t *acc)

cdef extern from "madgwick_q.h" nogil:
    ctypedef struct imf_madgwick_imu_q_state_t:
        pass
    ctypedef struct imf_madgwick_imu_q_t:
        imf_madgwick_imu_q_state_t x
    int imf_madgwick_imu_q_init(imf_madgwick_imu_q_t *self, double dt, double beta,
                                double gyr_scale, int profile)
    void imf_madgwick_imu_q_update(imf_madgwick_imu_q_t *self, const int16_t *gyr,
                                   const int16_t *acc)


cdef class Complementary1DQ(_Fixed1D):
    _ref = _reference.Complementary1DQ
    cdef imf_complementary1d_q_t s

    cdef int _init(self) except -1:
        a = self._kw
        rc = imf_complementary1d_q_init(&self.s, a["dt"], a["alpha"], a["gyr_scale"],
                                        a["angle_scale"])
        return self._bind(&self.s.x, sizeof(self.s.x), rc)

    cdef void _step(self, int16_t rate, int16_t angle) noexcept nogil:
        imf_complementary1d_q_update(&self.s, rate, angle)


cdef class Mahony1DBiasQ(_Fixed1D):
    _ref = _reference.Mahony1DBiasQ
    cdef imf_mahony1d_bias_q_t s

    cdef int _init(self) except -1:
        a = self._kw
        cdef imf_mahony1d_bias_q_settings_t st = a
        rc = imf_mahony1d_bias_q_init(&self.s, &st)
        return self._bind(&self.s.x, sizeof(self.s.x), rc)

    cdef void _step(self, int16_t rate, int16_t angle) noexcept nogil:
        imf_mahony1d_bias_q_update(&self.s, rate, angle)


cdef class KKQ(_FixedIMU):
    _ref = _reference.KKQ
    cdef imf_kk_q_t s

    cdef int _init(self) except -1:
        a = self._kw
        rc = imf_kk_q_init(&self.s, a["dt"], a["kp"], a["gyr_scale"])
        return self._bind(&self.s.x, sizeof(self.s.x), rc)

    cdef void _step(self, const int16_t *gyr, const int16_t *acc) noexcept nogil:
        imf_kk_q_update(&self.s, gyr, acc)


cdef class MultiWiiQ(_FixedIMU):
    _ref = _reference.MultiWiiQ
    cdef imf_multiwii_q_t s

    cdef int _init(self) except -1:
        a = self._kw
        cdef imf_multiwii_q_settings_t st = a
        rc = imf_multiwii_q_init(&self.s, &st)
        return self._bind(&self.s.x, sizeof(self.s.x), rc)

    cdef void _step(self, const int16_t *gyr, const int16_t *acc) noexcept nogil:
        imf_multiwii_q_update(&self.s, gyr, acc)


cdef class MahonyIMUQ(_FixedIMU):
    _ref = _reference.MahonyIMUQ
    cdef imf_mahony_imu_q_t s

    cdef int _init(self) except -1:
        a = self._kw
        cdef imf_mahony_imu_q_settings_t st = a
        rc = imf_mahony_imu_q_init(&self.s, &st)
        return self._bind(&self.s.x, sizeof(self.s.x), rc)

    cdef void _step(self, const int16_t *gyr, const int16_t *acc) noexcept nogil:
        imf_mahony_imu_q_update(&self.s, gyr, acc)


cdef class MadgwickIMUQ(_FixedIMU):
    _ref = _reference.MadgwickIMUQ
    cdef imf_madgwick_imu_q_t s

    cdef int _init(self) except -1:
        a = self._kw
        rc = imf_madgwick_imu_q_init(&self.s, a["dt"], a["beta"], a["gyr_scale"], a["profile"])
        return self._bind(&self.s.x, sizeof(self.s.x), rc)

    cdef void _step(self, const int16_t *gyr, const int16_t *acc) noexcept nogil:
        imf_madgwick_imu_q_update(&self.s, gyr, acc)
