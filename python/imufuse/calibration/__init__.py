"""Sensor calibration: the calibration files and fitting their parameters from recordings.

The models of Longbin's walkthrough (x-io Fusion), with the parameters of Nair (2016):

    gyroscope, accelerometer:  i_c = M s (i_u - b)
    magnetometer:              m_c = S (m_u - h)

The modules, by subject:
  imufuse.preprocess.calibration
                               the calibration file (JSON): Calibration (the parameters per
                               sensor), CalibrationError, from_dict, load_calibration,
                               save_calibration, is_identity, mag_offset (the offset
                               RobustAHRS holds), gyr_bias (the gyro bias the Robust
                               filters hold); on the preprocessing floor, which applies
                               it to logs (`imufuse run --calibration`); re-exported here
  imufuse.calibration.fit      the fits from arrays: gyro_offset, still_phases,
                               accel_six_position, mag_minmax, mag_ellipsoid, mag_sphere
                               (hard iron only); each returns a
                               fit.Calibration (sensor, params, figures), not the file's
  imufuse.calibration.log      `imufuse calibrate` over a log: run_log, save (merge into the
                               file), save_mag_offset (a filter's learnt offset),
                               save_gyr_bias (its learnt gyro bias), describe.
                               Not imported here: it reads logs through imufuse.session.

Here: the models' public names and the fits.
"""
from ..preprocess.calibration import (Calibration, CalibrationError, from_dict, gyr_bias,
                                      is_identity, load_calibration, mag_offset,
                                      save_calibration)
from .fit import (accel_six_position, gyro_offset, mag_ellipsoid, mag_minmax, mag_sphere,
                  still_phases)

__all__ = ["Calibration", "CalibrationError", "from_dict", "load_calibration",
           "save_calibration", "is_identity", "mag_offset", "gyr_bias", "gyro_offset", "still_phases",
           "accel_six_position", "mag_minmax", "mag_ellipsoid", "mag_sphere"]
