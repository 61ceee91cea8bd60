"""B3's noise, measured (RobustIMU and RobustAHRS): the twin of csrc/robust_b3.h, the same
functions in the same order with the same comments, mixed into reference/robust.py's filter
class; robust_blocks.py's B2 and B3 call it.

B3's rows (_bias) are the levelling's correction rate, as noisy as the linear acceleration
B2 takes for gravity: B1 calls motion an accelerometer up to rest_acc from gravity, and B3's
noise density rest_acc^2 / tau_acc is that bound. A smooth motion, a walk or a vehicle at
constant speed stays far below it, and a model at its bound learns a bias that drifts (a gyro
warming up: a few hundredths of a deg/s per K, a few K per minute) over hundreds of seconds
instead of tens. The accelerometer's deviation from B2's gravity in I (before B2's update,
the innovation it integrates) measures the linear acceleration: its square, relative to the
bound's, each sample at most 1, low-passed over tau_acc (the time over which B2 passes it
on), scales the rows' noise.
"""

#: the least noise B3 takes, relative to its bound: a consumer accelerometer's own noise
#: (400 ug/sqrt(Hz) over about 50 Hz: 3 mg per axis, 3 (3 mg)^2 = 0.01 (50 mg)^2 with the
#: default rest_acc). Also what keeps B3's covariance sound in float32: with noise-free
#: input and a bias unobservable along the axis of a long turn, 0.001 let its rounding turn
#: the covariance indefinite within two minutes (tests/test_long_rest.py's yaw spin).
#: (C: ROBUST_AN_MIN)
AN_MIN = 1.0e-2


class _RobustB3:
    """B3's noise of the Robust filters (reference/robust.py's _Robust mixes it in)."""

    def _acc_noise(self, x, ai, first, has_acc):
        # B3's noise from the linear acceleration B2 sees: ai the accelerometer in I, before
        # B2's update. The first sample: the bound (nothing measured yet); without a reading,
        # or for a calibrated gyro (gyr_bias_max 0: B3 the integral of the correction), kept.
        R = self._R
        dx, dy, dz = ai[0] - x.f[0], ai[1] - x.f[1], ai[2] - x.f[2]
        if first:
            x.an = R(1.0)
            return
        if not has_acc or not (self.s.gyr_bias_max > R(0.0)):
            return
        d2 = dx * dx + dy * dy + dz * dz
        den = self.rest_acc2 * (x.f[0] * x.f[0] + x.f[1] * x.f[1] + x.f[2] * x.f[2])
        # at most the bound (and the bound for rest_acc 0, a shock, a value not finite)
        e = d2 / den if d2 < den else R(1.0)
        x.an = x.an + self.k_acc * (e - x.an)

    def _an(self, x):
        # B3's rows' noise relative to its bound: the measured, at least AN_MIN
        R = self._R
        return x.an if x.an > R(AN_MIN) else R(AN_MIN)
