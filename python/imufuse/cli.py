"""The imufuse command line: demo, run, compare, bench, validate.

Exit codes: 0 success; 1 a bit-exact check or a validation failed;
2 bad command line (unknown filter or parameter, bad option value);
3 file not found or unreadable; 4 bad log contents (columns, values, time);
5 firmware that cannot be compiled or bound.
"""
import argparse
import sys

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_FILE, EXIT_DATA, EXIT_FIRMWARE = 0, 1, 2, 3, 4, 5


def _demo(args):
    from .demo import run_demo
    return run_demo(out_dir=args.out, rate=args.rate, duration=args.duration, seed=args.seed,
                    plot=not args.no_plot)


def build_parser():
    p = argparse.ArgumentParser(prog="imufuse", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    d = sub.add_parser("demo", help="every filter on simulated data: C vs reference bit for bit, "
                       "errors against ground truth, plots")
    d.add_argument("--out", default="imufuse-demo", metavar="DIR",
                   help="directory for the plots (default ./imufuse-demo)")
    d.add_argument("--rate", type=float, default=200.0, help="sample rate, Hz (default 200)")
    d.add_argument("--duration", type=float, default=20.0, help="seconds of data (default 20)")
    d.add_argument("--seed", type=int, default=1)
    d.add_argument("--no-plot", action="store_true")
    d.set_defaults(func=_demo)
    return p


def main(argv=None):
    p = build_parser()
    args = p.parse_args(argv)
    if not getattr(args, "func", None):
        p.print_help()
        return EXIT_USAGE
    return args.func(args)
