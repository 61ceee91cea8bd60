"""Recovery budgets: how many samples of sane input a filter needs to return
to the right attitude after a hostile burst (docs/robustness.md).

Every catalogue entry with an attitude names one of these functions
(`Entry(..., recovery=...)`); `Entry.recovery_budget(params, dtype)` calls it
with the filter's complete constructor keywords (defaults filled in) and adds
MARGIN. tests/test_hostile.py runs every registry configuration for that many
samples after each burst and requires the attitude within 2 degrees.

A budget bounds the worst case the burst can leave behind: an attitude error
of up to pi (the state is a valid attitude after every sample, however wrong)
and, for filters with a linear memory (low-pass, integrator), a state of up to
the largest finite value of the precision, whose logarithm is LN_MAX.

Each function takes (cls, p, dt, dtype): the reference class, the keywords,
the sample interval (p["dt"] for the filters constructed with one; the Fusion
suite takes dt with every update, None if not given) and "float32" | "float64".
"""
from __future__ import annotations

import math
from typing import Any, Callable, Mapping, Optional

import numpy as np

__all__ = ["MARGIN", "LN_MAX", "Budget", "mahony", "madgwick", "multiwii", "kk", "robust",
           "linear", "fusion_ahrs", "fusion_offset", "fusion_ahrs13", "fusion_bias",
           "spectral_radius"]

#: samples added to every budget: the last transient into the 2 degree band
MARGIN = 1000
#: ln of the largest finite value (float32 3.4e38: 88.7; float64 1.8e308: 709.8), rounded up
LN_MAX = {"float32": 90.0, "float64": 710.0}

#: (reference class, constructor keywords, dt, dtype) -> samples, MARGIN excluded
Budget = Callable[[Any, Mapping[str, Any], Optional[float], str], float]


def mahony(cls: Any, p: Mapping[str, Any], dt: Any, dtype: str) -> float:
    """Mahony's PI feedback (MahonyIMU/AHRS, Mahony2D, DCM): 12 / (kp dt).

    The proportional term turns the attitude at kp sin(error) rad/s towards
    the measured one, so the error obeys de/dt = -kp sin(e): from e0 the time
    to reach e is ln(tan(e0/2) / tan(e/2)) / kp. For e = 2 degrees, 12 / kp
    seconds (12 / (kp dt) samples) cover every e0 up to 7e-4 rad short of pi
    (at pi itself the feedback has no direction, and the rounding of one
    update moves the error off it). An integral term wound up during the
    burst (at most ki dt per sample, |e| <= 1) unwinds within it."""
    return 12.0 / (p["kp"] * dt)


def madgwick(cls: Any, p: Mapping[str, Any], dt: Any, dtype: str) -> float:
    """Madgwick's gradient descent (chapter 5): pi / (beta dt).

    The correction is a step of beta dt rad per sample along the normalised
    gradient, whatever the size of the error, so the worst error, pi, takes
    pi / (beta dt) samples."""
    return math.pi / (p["beta"] * dt)


def multiwii(cls: Any, p: Mapping[str, Any], dt: Any, dtype: str) -> float:
    """MultiWii 2.2: 12 (cmpf + 1) + 2^acc_lpf_shift LN_MAX.

    The accelerometer low-pass forgets its state by (1 - 2^-shift) per
    sample, so a value of up to the largest finite number decays below one g
    within 2^shift LN_MAX samples; then the complementary filter's gravity
    vector, weighted cmpf : 1 against the accelerometer, forgets its error by
    cmpf / (cmpf + 1) per sample: e^-12 of it within 12 (cmpf + 1) samples."""
    return 12 * (p["cmpf"] + 1) + 2 ** p["acc_lpf_shift"] * LN_MAX[dtype]


def kk(cls: Any, p: Mapping[str, Any], dt: Any, dtype: str) -> float:
    """KK (Eq. 4.5 with a P controller): (LN_MAX + 10) / kp.

    Each update moves the angles by kp times their error against the
    accelerometer's: the error shrinks by (1 - kp) per sample, about e^-kp, so
    an angle of up to the largest finite value is within e^-10 of the
    accelerometer's after (LN_MAX + 10) / kp samples."""
    return (LN_MAX[dtype] + 10.0) / p["kp"]


def robust(cls: Any, p: Mapping[str, Any], dt: Any, dtype: str) -> float:
    """The recommended AHRS (docs/recommended-ahrs.md, B2): (LN_MAX + 10) sqrt(2) tau_acc / dt.

    Its gravity filter is a second-order loop of natural frequency
    omega_0 = 1 / tau_acc and damping 1/sqrt(2): a state of up to the largest
    finite value decays with the envelope exp(-t / (sqrt(2) tau_acc)), below
    e^-10 of the acceleration after (LN_MAX + 10) sqrt(2) tau_acc seconds."""
    return (LN_MAX[dtype] + 10.0) * math.sqrt(2.0) * p["tau_acc"] / dt


def linear(cls: Any, p: Mapping[str, Any], dt: Any, dtype: str) -> float:
    """Single-axis filters (chapters 2 and 3): 2 (LN_MAX + 5) / -ln(rho).

    The filters are linear: with rate = angle = 0 the update is a matrix M
    (spectral_radius), and the state's distance to the right one shrinks by
    rho = max |eig(M)| per sample in the long run. From a state of up to the
    largest finite value, e^-5 of it remains after (LN_MAX + 5) / -ln(rho)
    samples; the factor 2 covers the transient growth of a non-normal M
    (e.g. Complementary1D alpha = 0.98: rho = 0.98, 10 404 / 71 782 samples
    in float32 / float64, margin included)."""
    return 2.0 * (LN_MAX[dtype] + 5.0) / -math.log(spectral_radius(cls, p))


def spectral_radius(cls: Any, p: Mapping[str, Any]) -> float:
    """Spectral radius of a single-axis filter's homogeneous update matrix:
    column j is the reference's update (rate = angle = 0) of unit state j."""
    f = cls(**p, dtype="float64")
    n = len(f.state_names)
    M = np.empty((n, n))
    for j in range(n):
        f.reset()
        for i, name in enumerate(f.state_names):
            setattr(f, name, 1.0 if i == j else 0.0)
        f._update(0.0, 0.0)
        M[:, j] = f.state
    return float(max(abs(np.linalg.eigvals(M))))


def fusion_ahrs(cls: Any, p: Mapping[str, Any], dt: Any, dtype: str) -> float:
    """FusionAHRS: 12 / (gain dt) + 3 s / dt + recovery_trigger_period.

    The feedback turns q at gain sin(error) rad/s, as Mahony's kp (mahony);
    a gyroscope overrange restarts the 3 s startup ramp, and a feedback the
    rejection thresholds refuse is forced back on after
    recovery_trigger_period samples."""
    if dt is None:
        raise ValueError("dt: the budget needs the interval of the updates")
    return 12.0 / (p["gain"] * dt) + 3.0 / dt + p["recovery_trigger_period"]


def fusion_offset(cls: Any, p: Mapping[str, Any], dt: Any, dtype: str) -> float:
    """FusionOffset (to hold the gyroscope bias within 0.01 deg/s again):
    5 sample_rate + ln(4.2 / 0.01) / (2 pi 0.02 / sample_rate).

    A huge reading is motion and restarts the 5 s rest timeout; then the
    0.02 Hz low-pass (coefficient 2 pi 0.02 / sample_rate per sample) starts
    from an offset at most 3 deg/s beyond the largest rest reading (4.2 deg/s
    from the bias for the 1.2 deg/s of tests/test_hostile.py)."""
    rate = p["sample_rate"]
    return 5 * rate + math.log(4.2 / 0.01) / (2.0 * math.pi * 0.02 / rate)


def fusion_ahrs13(cls: Any, p: Mapping[str, Any], dt: Any, dtype: str) -> float:
    """FusionAHRS13 (Fusion 1.3): 12 / (gain T) + 3 s / T + sample_rate rejection_timeout.

    As fusion_ahrs, with T the period of the updates (dt if given, else the settings'
    1 / sample_rate) and the rejection timeout given in seconds (sample_rate times it in
    samples): the feedback turns q at gain sin(error) rad/s, an overrange restarts the 3 s
    start-up, and a refused feedback is forced back on after the timeout."""
    period = 1.0 / p["sample_rate"] if dt is None else dt
    return 12.0 / (p["gain"] * period) + 3.0 / period + p["sample_rate"] * p["rejection_timeout"]


def fusion_bias(cls: Any, p: Mapping[str, Any], dt: Any, dtype: str) -> float:
    """FusionBias (Fusion 1.3), to hold the gyroscope bias within 0.01 deg/s again:
    stationary_period sample_rate + ln(4.2 / 0.01) / (2 pi 0.02 / sample_rate).

    As fusion_offset, with the stationary period a setting (seconds) instead of 1.2.3's
    fixed 5 s: a huge reading is motion and restarts the stationary timer, then the
    0.02 Hz filter starts from an offset at most 3 deg/s beyond the largest rest reading."""
    rate = p["sample_rate"]
    return (p["stationary_period"] * rate
            + math.log(4.2 / 0.01) / (2.0 * math.pi * 0.02 / rate))
