"""Log files: reading IMU logs (CSV, NPZ, HDF5) and writing filter outputs.

A CSV log has a header row; columns by name, any order, extra columns ignored:
  time                     s (or ms, us: a unit in the header, or time_unit)
  gyr_x gyr_y gyr_z        rad/s or deg/s
  acc_x acc_y acc_z        g or m/s^2
  mag_x mag_y mag_z        optional, any unit (the filters normalise it)
  q_w q_x q_y q_z          optional reference orientation, sensor -> earth
  movement                 optional mask (0/1) of the samples that count for errors
  rate angle               optional single-axis inputs (rad/s, rad) for the 1D filters

Headers are recognised (`recognise`): imufuse's names, and common spellings,
starting with x-io's ("Time (s)", "Gyroscope X (deg/s)", "Accelerometer X (g)",
"Magnetometer X (uT)"), also gx/gyro_x/accel_x/ax/qw/quat_w ..., in any case.
A unit in parentheses or brackets after the name is read ("(deg/s)", "[m/s^2]"), or after
an underscore ("AccX_g"). A sensor's word after other words is recognised ("IMU Gyroscope
X", "Vicon Orientation W"). Headers over two or three rows, as motion-capture and logging
tools export them (a group row spanning empty cells, an axis row, a unit row), are combined
into one name per column (imufuse.io.headers).
A column map ({name: header}) names columns explicitly; it wins over recognition.

Units: an explicit gyr_unit / acc_unit (the command line's --gyr-unit,
--acc-unit) wins; else the header's unit; else rad/s and g. A header unit that
contradicts an explicit one gives a warning.

Delimiter (",", ";", tab, "|" or whitespace) and a byte-order mark (UTF-8,
UTF-16) are detected. Decimal commas ("0,25") are read when the delimiter is
not a comma (with a note); with a comma delimiter they are an error that says so.

Values are read with numpy's C parser (numpy.loadtxt); a row that it cannot
read is located again line by line, so errors name the line: "log.csv:7:
column gyr_x: not a number: 'abc'". "nan" and "inf" are numbers (the filters
skip such samples). Time must increase strictly.

Sample period: the filters use the time column's real intervals (Log.dts,
sample k integrated over t[k] - t[k-1]; the first sample over the median
interval), or with a given rate or fixed_rate=True one fixed period: 1/rate,
or 1/(1/median interval rounded to 9 significant digits) (Log.dt).

NPZ / HDF5 logs hold arrays in the layout of the BROAD dataset: gyr (N, 3)
rad/s, acc (N, 3) m/s^2, mag (N, 3) uT, quat_ref (N, 4) sensor -> ENU with
NaN rows, movement (N,) bool, rate () Hz; optionally time (N,) s. The HDF5
files of BROAD name them imu_gyr, imu_acc, imu_mag, opt_quat, movement,
sampling_rate (h5py is needed for HDF5).

Single-axis filters read `rate` and `angle` when both are present; otherwise
they are derived (axis "x": rate = gyr_x, angle = atan2(acc_y, acc_z), the
roll; axis "y": rate = gyr_y, angle = atan2(-acc_x, acc_z), the pitch; both
exact for rotation about that axis alone).

The modules, by subject:
  imufuse.io.log       the column names, the units logs are read in, Log, LogError
  imufuse.io.columns   header recognition, units in headers, column maps, `require`
  imufuse.io.text      CSV text: encodings, NUL-filled tails, the delimiter, the numbers
  imufuse.io.headers   headers over two or three rows (group, axis, unit) as tools export them
  imufuse.io.arrays    NPZ and HDF5 logs (BROAD layout)
  imufuse.io.read      `read_log`, `describe`, `axis_inputs`
  imufuse.io.write     the writers (CSV, NPZ, the log format) and the shipped example log
Their public names are imported here: imufuse.io.X is the way to reach them.
"""
from .columns import (_norm, duplicate_columns, parse_column_map, read_column_map, recognise,
                      require, split_unit)
from .log import ACC, ACC_UNITS, GRAVITY, GYR, GYR_UNITS, KNOWN, MAG, QUAT, TIME_UNITS, Log, LogError
from .read import axis_inputs, describe, read_log
from .text import read_csv_rows
from .write import (EXAMPLE, EXAMPLE_ATTRIBUTION, CsvBlocks, example_log, npz_to_csv, write_csv,
                    write_log, write_npz)

__all__ = ["ACC", "ACC_UNITS", "CsvBlocks", "EXAMPLE", "EXAMPLE_ATTRIBUTION", "GRAVITY", "GYR", "GYR_UNITS",
           "KNOWN", "MAG", "QUAT", "TIME_UNITS", "Log", "LogError", "axis_inputs", "describe",
           "duplicate_columns", "example_log", "npz_to_csv", "parse_column_map", "read_column_map",
           "read_csv_rows", "read_log", "recognise", "require", "split_unit", "write_csv",
           "write_log", "write_npz", "_norm"]
