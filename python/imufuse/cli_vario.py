"""Subcommands of seed 002: `imufuse vario` and `imufuse calibrate`.

Registered by imufuse.cli.build_parser; the work is done in imufuse.vario
and imufuse.calibrate."""
import ast
import os
import sys

from . import calibrate, plots, vario
from ._atomic import check_outputs


def _pairs(items, what):
    """NAME=VALUE strings -> dict; values as Python literals, else strings."""
    out = {}
    for it in items or ():
        if "=" not in it:
            raise ValueError(f"{what} {it!r}: expected NAME=VALUE")
        k, v = it.split("=", 1)
        try:
            out[k.strip()] = ast.literal_eval(v.strip())
        except (ValueError, SyntaxError):
            out[k.strip()] = v.strip()
    return out


def _vario(args):
    params = _pairs(args.param, "--param")
    kf = _pairs(args.kf, "--kf")
    if args.acc_gate:
        params["acc_gate"] = tuple(args.acc_gate)
    out = args.out or os.path.splitext(args.log)[0] + "-vario.csv"
    plot = None if args.no_plot or not plots.available() else (
        args.plot or os.path.splitext(out)[0] + ".png")
    check_outputs([args.log], [("-o", out), ("--plot", plot)])
    res = vario.run_log(args.log, out, plot=plot, gyr_unit=args.gyr_unit,
                        acc_unit=args.acc_unit, p_ref=args.p_ref, filter=args.filter,
                        filter_params=params, kf_params=kf, convention=args.convention)
    print(f"{len(res.t)} barometer samples -> {out}" + (f", plot {plot}" if plot else ""))
    print(f"altitude {res.altitude[-1]:.2f} m, climb {res.climb[-1]:+.2f} m/s, "
          f"accelerometer bias {res.bias[-1]:+.3f} m/s^2 at the end")
    if res.imu_skipped or res.kf_skipped:
        print(f"imufuse: note: rejected (non-finite input, state kept): {res.imu_skipped} IMU "
              f"samples by {args.filter}, {res.kf_skipped} of {len(res.t)} barometer samples "
              "by the Kalman filter", file=sys.stderr)
    return 0


def _calibrate(args):
    check_outputs([args.log], [("-o", args.output)])
    res = calibrate.run_log(args.sensor, args.log, args.output, gyr_unit=args.gyr_unit,
                            ranges=args.ranges, threshold=args.threshold, method=args.method,
                            longest_still=args.longest_still)
    print(calibrate.describe(args.sensor, res))
    print(f"-> {args.output}")
    return 0


def add_parsers(sub):
    v = sub.add_parser("vario", help="seed 002's variometer over a log with a barometer "
                       "column: altitude, climb rate, accelerometer bias -> CSV and plot")
    v.add_argument("log", help="CSV: time, gyr_*, acc_*, optional mag_*, and pressure (Pa) or "
                   "baro_alt (m) on the rows where the barometer sampled, empty elsewhere")
    v.add_argument("-o", "--out", metavar="CSV", help="output (default LOG-vario.csv)")
    v.add_argument("--plot", metavar="PNG", help="plot path (default next to the output)")
    v.add_argument("--no-plot", action="store_true")
    v.add_argument("--gyr-unit", choices=("rad/s", "deg/s"), default="rad/s")
    v.add_argument("--acc-unit", choices=("g", "m/s2", "m/s^2"), default="g")
    v.add_argument("--p-ref", type=float, default=101325.0, metavar="PA",
                   help="reference pressure of altitude 0, Pa (default 101325)")
    v.add_argument("--filter", default="MadgwickIMU",
                   help="attitude filter (an imufuse IMU or AHRS filter; default MadgwickIMU)")
    v.add_argument("--param", "-p", action="append", metavar="NAME=VALUE",
                   help="attitude filter parameter (repeatable); dt comes from the rate")
    v.add_argument("--acc-gate", nargs=2, type=float, metavar=("LO", "HI"),
                   help="accelerometer gate of the attitude filter, in g (seed: 0.6 1.4)")
    v.add_argument("--kf", action="append", metavar="NAME=VALUE",
                   help="VarioKF parameter (repeatable): var_z, var_acc, var_bias, predict, ...")
    v.add_argument("--convention", choices=("nwu", "enu", "ned", "ned_seed"), default="nwu",
                   help="frame of the attitude filter's output and sign of the accelerometer")
    v.set_defaults(func=_vario)

    c = sub.add_parser("calibrate", help="sensor calibration from a recording -> JSON "
                       "(gyroscope offset, accelerometer six-position, magnetometer ellipsoid)")
    c.add_argument("sensor", choices=("gyro", "accel", "mag"))
    c.add_argument("log", help="CSV with gyr_*, acc_* or mag_* columns (raw units)")
    c.add_argument("-o", "--output", required=True, metavar="JSON",
                   help="calibration file (merged into it if it exists)")
    c.add_argument("--gyr-unit", choices=("rad/s", "deg/s"), default="rad/s")
    c.add_argument("--ranges", metavar="A:B,...",
                   help="accel: the six still phases as row ranges (default: found)")
    c.add_argument("--threshold", type=float, metavar="X",
                   help="gyro: largest reading at rest (motion check); accel: stillness "
                   "threshold")
    c.add_argument("--longest-still", action="store_true",
                   help="gyro: use the longest still stretch of a recording that moved")
    c.add_argument("--method", choices=("ellipsoid", "minmax"), default="ellipsoid",
                   help="mag: least-squares ellipsoid (soft and hard iron) or the seed's "
                   "min/max (hard iron and per-axis scale)")
    c.set_defaults(func=_calibrate)
