"""`imufuse demo`, `imufuse latency` and `imufuse bench`."""
import argparse
import os
import sys
import time

import numpy as np

from .. import plots, sim
from ..catalogue import FilterError, filter_names, inputs_for, make_filter, reference_class
from ..catalogue import resolve_params
from ..comparison import log_paths
from ..tools.demo import run_demo
from ..latency import estimate_latency
from ..io import EXAMPLE_ATTRIBUTION, GYR, example_log, require
from ..session import NothingComputed
from . import logs
from .common import (EXIT_OK, OutputError, err, log_options, names, open_session, positive,
                     preprocess_options)


def _demo(args):
    chosen = None
    if args.filters:
        chosen = names(args.filters)
        for n in chosen:
            reference_class(n)
    if args.out and os.path.exists(args.out) and not os.path.isdir(args.out):
        raise OutputError(f"--out {args.out}: exists and is not a directory")
    rc = run_demo(out_dir=args.out, rate=args.rate, duration=args.duration, seed=args.seed,
                  plot=not args.no_plot, names=chosen, say=err)
    if args.no_real:
        return rc
    three = [n for n in (chosen or []) if reference_class(n).kind != "1d"]
    if chosen and not three:
        return rc
    print(f"\nreal data: every 3D filter against optical truth ({EXAMPLE_ATTRIBUTION})")
    argv = ["compare", example_log()] + [a for n in three for a in ("-f", n)]
    if not args.no_plot and plots.available():      # unavailable: said once, above
        os.makedirs(args.out, exist_ok=True)
        argv += ["--plot", os.path.join(args.out, "demo_real.png")]
    sys.stdout.flush()
    p = argparse.ArgumentParser(prog="imufuse")
    logs.add_parsers(p.add_subparsers())
    rc_real = logs.compare(p.parse_args(argv))
    return rc or rc_real


def add_demo(sub):
    d = sub.add_parser("demo", help="every filter on simulated data: C vs reference bit for bit, "
                       "errors against ground truth, plots")
    d.add_argument("--out", default="imufuse-demo", metavar="DIR",
                   help="directory for the plots (default ./imufuse-demo)")
    d.add_argument("--rate", type=positive(float, 1e6), default=200.0,
                   help="sample rate, Hz (default 200)")
    d.add_argument("--duration", type=positive(float, 1e5), default=20.0,
                   help="seconds of data (default 20)")
    d.add_argument("--seed", type=int, default=1)
    d.add_argument("--filter", dest="filters", action="append", metavar="NAME[,NAME]",
                   help="only these filters")
    d.add_argument("--no-plot", action="store_true")
    d.add_argument("--no-real", action="store_true",
                   help="skip the real recording (45 s of BROAD with optical truth)")
    d.set_defaults(func=_demo)


def _latency(args):
    delays, periods = [], []
    for path in log_paths(args.logs):
        log = open_session(args, path).log
        if log.q_ref is None:
            raise NothingComputed(f"{log.path}: no reference orientation (q_w..q_z): nothing to "
                                  "time the gyroscope against")
        require(log, GYR)
        t = log.t if log.dts is not None else None
        try:
            d = estimate_latency(log.gyr, log.q_ref, None if t is not None else log.dt, t=t,
                                 ref_direction=args.ref_direction, max_delay=args.max_delay)
        except ValueError as e:
            # the options that set what the message names
            why = str(e).replace(f"ref_direction={args.ref_direction!r}",
                                 f"--ref-direction {args.ref_direction}")
            if "sensor's axes" in why:
                why += " (--align turns the axes, --gyr-unit sets the unit)"
            raise NothingComputed(f"{log.path}: {why}") from None
        delays.append(d)
        periods.append(float(log.dt))
        how = "lags" if d >= 0 else "leads"
        print(f"{log.path}: the gyroscope {how} the reference by {abs(d) * 1e3:.2f} ms")
    d = float(np.mean(delays))
    if len(delays) > 1:
        print(f"mean over {len(delays)} logs: {d * 1e3:.2f} ms "
              f"({min(delays) * 1e3:.2f} to {max(delays) * 1e3:.2f})")
    if abs(d) < IN_STEP * min(periods):
        print(f"the gyroscope and the reference are in step: {abs(d) * 1e3:.2f} ms is below "
              f"{IN_STEP:.0%} of a sample, the estimate's resolution; latency stays 0")
    elif 0.0 <= d <= 0.1:
        print(f"RobustIMU / RobustAHRS: -p latency={d:.6f} predicts the output by this delay")
    elif d < 0:
        print("the gyroscope leads the reference: latency (>= 0) cannot compensate that; "
              "check the logger's timestamps")
    else:
        print("the delay is beyond latency's range (0 to 0.1 s)")
    return EXIT_OK


#: a delay below this share of a sample is no delay: the estimate's resolution (a
#: simulated log in step measures 0.8 % of a sample)
IN_STEP = 0.02


def add_latency(sub):
    d = sub.add_parser("latency", help="delay of the gyroscope behind a log's reference "
                       "orientation (RobustIMU's latency), from the rates alone")
    d.add_argument("logs", nargs="+", metavar="LOG",
                   help="logs: files, folders of logs, glob patterns (as compare)")
    d.add_argument("--max-delay", type=positive(float, 1.0), default=0.05, metavar="S",
                   help="search shifts within +-S seconds (default 0.05)")
    d.add_argument("--ref-direction", choices=("sensor-to-earth", "earth-to-sensor"),
                   default="sensor-to-earth", help="what the reference quaternion rotates")
    log_options(d)
    preprocess_options(d)
    d.set_defaults(func=_latency)


def _bench(args):
    chosen = names(args.filters) or filter_names()
    for n in chosen:
        reference_class(n)
    rate = 200.0
    d1 = sim.axis1d("slow", rate=rate, duration=args.samples / rate, seed=0)
    d3 = None
    print(f"samples per second (C: run() over {args.samples} samples, best of {args.repeat}; "
          f"reference: run() over {args.ref_samples} samples)")
    head = (f"{'filter':22s} {'C float32':>11s} {'C float64':>11s} {'ref float32':>12s} "
            f"{'ref float64':>12s} {'C/ref f64':>10s}")
    print(head)
    print("-" * len(head))
    for n in chosen:
        cls = reference_class(n)
        if cls.kind != "1d" and d3 is None:
            d3 = sim.imu("slow", rate=rate, duration=args.samples / rate, seed=0)
        data = d1 if cls.kind == "1d" else d3
        try:
            params = resolve_params(n, data.dt)
        except FilterError as e:
            print(f"{n:22s} skipped: {e}")
            continue
        full = inputs_for(cls.kind, data)
        short = [a[:args.ref_samples] for a in full]
        res = {}
        for backend, inp, reps in (("c", full, args.repeat), ("ref", short, 1)):
            for dtype in ("float32", "float64"):
                f = make_filter(n, backend, dtype, params)
                arrs = [np.ascontiguousarray(a, dtype=dtype) for a in inp]
                best = np.inf
                for _ in range(reps):
                    f.reset()
                    t0 = time.perf_counter()
                    f.run(*arrs)
                    best = min(best, time.perf_counter() - t0)
                res[backend, dtype] = len(arrs[0]) / max(best, 1e-9)
        print(f"{n:22s} {res['c', 'float32']:11.3g} {res['c', 'float64']:11.3g} "
              f"{res['ref', 'float32']:12.3g} {res['ref', 'float64']:12.3g} "
              f"{res['c', 'float64'] / res['ref', 'float64']:9.0f}x")
    return EXIT_OK


def add_bench(sub):
    b = sub.add_parser("bench", help="speed table: C run() vs reference, samples per second")
    b.add_argument("--filter", "-f", dest="filters", action="append", metavar="NAME[,NAME]")
    b.add_argument("--samples", type=positive(int, 10**8), default=100000,
                   help="C run length (default 100000)")
    b.add_argument("--ref-samples", type=positive(int, 10**7), default=2000,
                   help="reference run length (default 2000)")
    b.add_argument("--repeat", type=positive(int, 1000), default=3)
    b.set_defaults(func=_bench)
