"""`imufuse vario` and `imufuse calibrate`: the variometer and the sensor calibrations of
Hari Nair, "IMU modules, AHRS and a Kalman filter for sensor fusion" (2016). The work is
done in imufuse.vario and imufuse.calibration, which read logs through imufuse.session."""
import os

from .. import plots, vario
from ..calibration import log as calibration_log
from ..shared.atomic import check_outputs
from .common import (EXIT_OK, UsageError, column_map, err, pairs, plot_available, strict_option,
                     unit_options)


def _vario(args):
    params = pairs(args.param, "--param")
    kf = pairs(args.kf, "--kf")
    if args.acc_gate:
        if "acc_gate" in params:
            raise UsageError("--acc-gate: the gate is also given by --param acc_gate; give it "
                             "once")
        params["acc_gate"] = tuple(args.acc_gate)
    out = args.out or os.path.splitext(args.log)[0] + "-vario.csv"
    if args.plot and args.no_plot:
        raise UsageError("--plot and --no-plot: give one")
    plot_available(args.plot)          # a --plot asked for is written, or exit 3
    plot = None if args.no_plot or not plots.available() else (
        args.plot or os.path.splitext(out)[0] + ".png")
    check_outputs([args.log, args.column_map], [("-o", out), ("--plot", plot)])
    res = vario.run_log(args.log, out, plot=plot, gyr_unit=args.gyr_unit,
                        acc_unit=args.acc_unit, p_ref=args.p_ref, filter=args.filter,
                        filter_params=params, kf_params=kf, convention=args.convention,
                        columns=column_map(args), time_unit=args.time_unit,
                        strict=args.strict)
    for note in res.notes:
        err(f"note: {note}")
    print(f"{len(res.t)} barometer samples -> {out}" + (f", plot {plot}" if plot else ""))
    print(f"altitude {res.altitude[-1]:.2f} m, climb {res.climb[-1]:+.2f} m/s, "
          f"accelerometer bias {res.bias[-1]:+.3f} m/s^2 at the end")
    if res.imu_skipped or res.kf_skipped:
        err(f"note: rejected (non-finite input, state kept): {res.imu_skipped} IMU samples by "
            f"{args.filter}, {res.kf_skipped} of {len(res.t)} barometer samples by the Kalman "
            "filter")
    return EXIT_OK


def _calibrate(args):
    check_outputs([args.log, args.column_map], [("-o", args.output)])
    res = calibration_log.run_log(args.sensor, args.log, args.output, gyr_unit=args.gyr_unit,
                            acc_unit=args.acc_unit, ranges=args.ranges,
                            threshold=args.threshold, method=args.method,
                            longest_still=args.longest_still, columns=column_map(args),
                            strict=args.strict)
    for note in res.notes:
        err(f"note: {note}")
    print(calibration_log.describe(args.sensor, res))
    print(f"-> {args.output}")
    return EXIT_OK


def add_parsers(sub):
    v = sub.add_parser("vario", help="altitude, climb rate and accelerometer bias over a log "
                       "with a barometer column (the variometer) -> CSV and plot")
    v.add_argument("log", help="CSV: time, gyr_*, acc_*, optional mag_* (the headers every "
                   "command reads, e.g. 'Gyroscope X (deg/s)'), and pressure (Pa, or hPa/kPa "
                   "by its header) or baro_alt (m) on the rows where the barometer sampled, "
                   "empty elsewhere")
    v.add_argument("-o", "--out", metavar="CSV", help="output (default LOG-vario.csv)")
    v.add_argument("--plot", metavar="PNG", help="plot path (default next to the output)")
    v.add_argument("--no-plot", action="store_true")
    unit_options(v)
    strict_option(v)
    v.add_argument("--p-ref", type=float, default=101325.0, metavar="PA",
                   help="reference pressure of altitude 0, Pa (default 101325)")
    v.add_argument("--filter", default="MadgwickIMU",
                   help="attitude filter (an imufuse IMU or AHRS filter; default MadgwickIMU)")
    v.add_argument("--param", "-p", action="append", metavar="NAME=VALUE",
                   help="attitude filter parameter (repeatable); dt comes from the rate")
    v.add_argument("--acc-gate", nargs=2, type=float, metavar=("LO", "HI"),
                   help="accelerometer gate of the attitude filter, in g (the document's: "
                        "0.6 1.4)")
    v.add_argument("--kf", action="append", metavar="NAME=VALUE",
                   help="VarioKF parameter (repeatable): var_z, var_acc, var_bias, predict, ...")
    v.add_argument("--convention", choices=("nwu", "enu", "ned", "ned_seed"), default="nwu",
                   help="frame of the attitude filter's output and sign of the accelerometer")
    v.set_defaults(func=_vario)

    c = sub.add_parser("calibrate", help="sensor calibration from a recording -> JSON "
                       "(gyroscope offset, accelerometer six-position, magnetometer ellipsoid)")
    c.add_argument("sensor", choices=("gyro", "accel", "mag"))
    c.add_argument("log", help="a log with gyr_*, acc_* or mag_* columns (the headers every "
                   "command reads; no time column needed)")
    c.add_argument("-o", "--output", required=True, metavar="JSON",
                   help="calibration file (merged into it if it exists)")
    unit_options(c, time=False)
    strict_option(c)
    c.add_argument("--ranges", metavar="A:B,...",
                   help="accel: the six still phases as row ranges (default: found)")
    c.add_argument("--threshold", type=float, metavar="X",
                   help="gyro: largest reading at rest, rad/s (motion check); accel: "
                        "stillness threshold")
    c.add_argument("--longest-still", action="store_true",
                   help="gyro: use the longest still stretch of a recording that moved")
    c.add_argument("--method", choices=("ellipsoid", "minmax", "sphere"), default="ellipsoid",
                   help="mag: least-squares ellipsoid (soft and hard iron), min/max "
                   "(hard iron and per-axis scale) or sphere (hard iron only: the offset "
                   "RobustAHRS holds, imufuse.calibration.mag_offset)")
    c.set_defaults(func=_calibrate)
