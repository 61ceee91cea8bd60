/*
 * B3's noise, measured (imufuse's recommended AHRS): a private part of robust.c, included by
 * it once before robust_blocks.h, whose B2 and B3 call it. The pure-Python twin is
 * python/imufuse/reference/robust_b3.py; the host's lane twin imufuse_c/host/lanes_robust.h
 * (change both).
 *
 * B3's rows (robust_bias) are the levelling's correction rate, as noisy as the linear
 * acceleration B2 takes for gravity: B1 calls motion an accelerometer up to rest_acc from
 * gravity, and B3's noise density rest_acc^2 / tau_acc is that bound. A smooth motion, a
 * walk or a vehicle at constant speed stays far below it, and a model at its bound learns a
 * bias that drifts (a gyro warming up: a few hundredths of a deg/s per K, a few K per
 * minute) over hundreds of seconds instead of tens. The accelerometer's deviation from B2's
 * gravity in I (before B2's update, the innovation it integrates) measures the linear
 * acceleration: its square, relative to the bound's, each sample at most 1, low-passed over
 * tau_acc (the time over which B2 passes it on), scales the rows' noise.
 */
#ifndef IMF_ROBUST_B3_H
#define IMF_ROBUST_B3_H

/* the least noise B3 takes, relative to its bound: a consumer accelerometer's own noise
   (400 ug/sqrt(Hz) over about 50 Hz: 3 mg per axis, 3 (3 mg)^2 = 0.01 (50 mg)^2 with the
   default rest_acc). Also what keeps B3's covariance sound in float32: with noise-free
   input and a bias unobservable along the axis of a long turn, 0.001 let its rounding turn
   the covariance indefinite within two minutes (tests/test_long_rest.py's yaw spin). */
#define ROBUST_AN_MIN IMF_R(1.0e-2)

/* B3's noise from the linear acceleration B2 sees: ai the accelerometer in I, before B2's
   update. The first sample: the bound (nothing measured yet); without a reading, or for a
   calibrated gyro (gyr_bias_max 0: B3 the integral of the correction), kept. */
static inline void robust_acc_noise(const imf_robust_consts_t *const set,
                                    imf_robust_state_t *const x, const imf_real *const ai,
                                    const int first, const int has_acc)
{
    const imf_real dx = ai[0] - x->f[0], dy = ai[1] - x->f[1], dz = ai[2] - x->f[2];
    imf_real d2, den, e;
    if (first) {
        x->an = IMF_R(1.0);
        return;
    }
    if (!has_acc || !(set->s.gyr_bias_max > IMF_R(0.0))) {
        return;
    }
    d2 = dx * dx + dy * dy + dz * dz;
    den = set->rest_acc2 * (x->f[0] * x->f[0] + x->f[1] * x->f[1] + x->f[2] * x->f[2]);
    /* at most the bound (and the bound for rest_acc 0, a shock, a value not finite) */
    e = d2 < den ? d2 / den : IMF_R(1.0);
    x->an = x->an + set->k_acc * (e - x->an);
}

/* B3's rows' noise relative to its bound: the measured, at least ROBUST_AN_MIN */
static inline imf_real robust_an(const imf_robust_state_t *const x)
{
    return x->an > ROBUST_AN_MIN ? x->an : ROBUST_AN_MIN;
}

#endif /* IMF_ROBUST_B3_H */
