"""The variometer pipeline of Hari Nair (2016), host side.

    IMU (200-250 Hz) -> quaternion filter (any imufuse IMU/AHRS filter, with
    the accelerometer gate) -> gravity-compensated vertical acceleration ->
    low-pass and down-sample to the barometer rate (the mean over the
    barometer interval) -> VarioKF once per barometer sample.

Barometric altitude comes from pressure by the standard atmosphere
(:func:`pressure_to_altitude`, reference pressure configurable). The Kalman
filter works in Nair's units (cm, cm/s, cm/s^2); results are given in
m, m/s and m/s^2.

Also here, for the measurements of docs/vario.md: the barometer-only
two-state Kalman filter of Nair's starting point (:func:`baro_kf`, the
Wikipedia constant-acceleration example) and Nair's rejected
alternative ``|a| - 1`` (:func:`norm_accel`).

The modules, by subject (their public names are imported here):
  imufuse.vario.pipeline   the pipeline over arrays (`run`), the standard atmosphere, the
                           vertical acceleration, `decimate`, `baro_kf`, VarioResult
  imufuse.vario.log        `imufuse vario` over a log: `read_vario_log`, `run_log`,
                           `plot_vario`, VarioLogError
The bit-exact twin of the C VarioKF is imufuse.reference.vario.
"""
from .log import BARO_NAMES, VarioLogError, plot_vario, read_vario_log, run_log
from .pipeline import (GRAVITY, P_REF, VarioResult, altitude_to_pressure, baro_kf, decimate,
                       norm_accel, pressure_to_altitude, run, vertical_acceleration)

__all__ = ["P_REF", "pressure_to_altitude", "altitude_to_pressure", "VarioResult",
           "vertical_acceleration", "norm_accel", "decimate", "baro_kf", "run",
           "read_vario_log", "run_log", "plot_vario", "VarioLogError", "BARO_NAMES", "GRAVITY"]
