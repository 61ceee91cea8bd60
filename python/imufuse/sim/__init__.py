"""Deterministic, seeded simulation of orientation trajectories and IMU samples.

Frames and units
----------------
- Earth frame NWU: x north (magnetic), y west, z up. Gravity is ``-g e_z``; a sensor at rest
  measures the specific force ``+g e_z``, so a level sensor reads acc = (0, 0, +1 g).
- Quaternions ``[w, x, y, z]`` rotate body -> earth (``v_earth = R v_body``), see
  :mod:`imufuse.rotations`. A sensor reads earth vectors as ``R^T v_earth``.
- Gyro rad/s in the body frame; accelerometer in g (``acc_unit="m/s^2"`` for m/s^2, with
  ``g = GRAVITY``); magnetometer in the unit of ``mag_field`` (default 1: a unit field).
- Earth magnetic field ``m_earth = mag_field * (cos(dip), 0, -sin(dip))``: pointing north and,
  for positive dip (northern hemisphere), down.

Timing
------
Sample ``k`` (k = 0 .. N-1) covers the interval ``(k dt, (k+1) dt]``. The true body rate
``omega[k]`` is constant over that interval and the true orientation after it is, exactly,

    q_true[k] = q_true[k-1] (x) exp(omega[k] dt / 2)        (q_true[-1] = q0)

evaluated in float64 with :func:`imufuse.rotations.quat_from_rotvec` (no renormalisation).
``t[k] = (k+1) / rate`` is the time of ``q_true[k]``; the accelerometer and magnetometer of
sample ``k`` are read at that orientation. This matches a filter that integrates ``gyr[k]``
and then corrects with ``acc[k]``: with noise-free, bias-free data an exact integrator
reproduces ``q_true``.

Reproducibility
---------------
Every random draw comes from ``numpy.random.SeedSequence(seed)``: child 0 drives the motion,
the other children the sensor noises, so changing a noise level never changes the motion.
The same seed gives the same arrays bit for bit. ``seed=None`` draws fresh entropy and
records it in ``params["seed"]`` so the run can be repeated.

Default sensor figures (MPU-6050-class MEMS, after a rough bias calibration, 100-500 Hz)
----------------------------------------------------------------------------------------
- gyro white noise 0.005 rad/s (0.29 deg/s) per sample, residual bias about 0.01-0.02 rad/s
  per axis (:data:`GYR_BIAS`);
- accelerometer white noise 0.005 g per sample, no bias;
- magnetometer white noise 0.005 of the field strength per sample; dip 60 deg (mid-latitude
  Europe / North America).
Pass 0 for any of them to get noise-free or bias-free data.

The modules, by subject (their public names are imported here):
  imufuse.sim.common    default sensor figures, gravity, argument checks, random streams
  imufuse.sim.motion    Trajectory, `integrate`, `trajectory`
  imufuse.sim.sensors   ImuData, `imu`, `mag_earth`; Axis1D, `axis1d`
  imufuse.sim.disturb   disturbance scenarios for robust attitude filters (not imported here)
  imufuse.sim.flight    paraglider flights for the variometer (not imported here: it uses
                        imufuse.vario)
"""
from .common import (ACC_NOISE, ANGLE_NOISE, GRAVITY, GYR_BIAS, GYR_NOISE, KINDS, MAG_DIP,
                     MAG_NOISE)
from .motion import Trajectory, integrate, trajectory
from .sensors import Axis1D, ImuData, axis1d, imu, mag_earth

__all__ = [
    "GRAVITY", "GYR_NOISE", "GYR_BIAS", "ACC_NOISE", "MAG_NOISE", "MAG_DIP", "ANGLE_NOISE",
    "KINDS", "Trajectory", "ImuData", "Axis1D", "trajectory", "imu", "axis1d",
    "mag_earth", "integrate",
]
