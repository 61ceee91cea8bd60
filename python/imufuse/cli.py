"""The imufuse command line: demo, run, compare, bench, validate.

Exit codes: 0 success; 1 a bit-exact check or a validation failed;
2 bad command line (unknown filter or parameter, bad option value);
3 file not found or unreadable; 4 bad log contents (columns, values, time);
5 firmware that cannot be compiled or bound.
"""
import argparse
import ast
import os
import sys
import time
from typing import Optional, Sequence

import numpy as np

from . import cli_vario, io, plots, preprocess, sim
from ._resources import csrc_dir
from .catalogue import (FilterError, estimate, filter_names, inputs_for, make_filter,
                        param_names, reference_class, resolve_params, why_no_estimate)
from .demo import errors_1d, errors_3d, run_demo
from .estimate import euler_of
from .firmware import Firmware, FirmwareError, csrc_firmware, validate
from .io import ACC, GYR, MAG, LogError, axis_inputs, read_log, require
from .rotations import quat_to_euler

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_FILE, EXIT_DATA, EXIT_FIRMWARE = 0, 1, 2, 3, 4, 5


class UsageError(ValueError):
    pass


def _err(msg):
    print(f"imufuse: {msg}", file=sys.stderr)


def _value(text):
    low = text.strip().lower()
    if low in ("true", "false"):
        return low == "true"
    if low in ("none", "null"):
        return None
    try:
        return ast.literal_eval(text.strip())
    except (ValueError, SyntaxError):
        return text.strip()


def _pairs(items, what="--param"):
    out = {}
    for it in items or ():
        if "=" not in it:
            raise UsageError(f"{what} {it!r}: expected NAME=VALUE")
        k, v = it.split("=", 1)
        out[k.strip()] = _value(v)
    return out


def _scoped_params(items, names):
    """--param NAME=V (every filter that has NAME) or FILTER.NAME=V -> {filter: {name: v}}."""
    out = {n: {} for n in names}
    for k, v in _pairs(items).items():
        if "." in k:
            f, p = k.split(".", 1)
            if f not in out:
                raise UsageError(f"--param {k}: filter {f!r} is not among {', '.join(names)}")
            out[f][p] = v
        else:
            hit = [n for n in names if k in param_names(n)]
            if not hit:
                raise UsageError(f"--param {k}: no selected filter has a parameter {k!r}; "
                                 + "; ".join(f"{n}: {', '.join(p for p in param_names(n) if p != 'dt')}"
                                             for n in names))
            for n in hit:
                out[n][k] = v
    return out


#: Runs at least this long (samples) report progress on stderr: the pure-Python
#: reference runs ~10^5 samples/s, the compiled filters ~10^7.
PROGRESS_MIN = {"ref": 20_000, "c": 2_000_000}


def run_with_progress(f, inputs, label, backend):
    """f.run(*inputs), in about 20 chunks with a progress line on stderr when
    the run is long. The state carries over between run() calls, so the
    result is the same trajectory, bit for bit."""
    n = len(inputs[0])
    if n < PROGRESS_MIN[backend]:
        return f.run(*inputs)
    step = -(-n // 20)
    parts = []
    for k in range(0, n, step):
        parts.append(f.run(*[x[k:k + step] for x in inputs]))
        done = min(k + step, n)
        _err(f"{label}: {100 * done // n}% ({done}/{n} samples)")
    return np.concatenate(parts)


def _load(args):
    log = read_log(args.log, gyr_unit=args.gyr_unit, acc_unit=args.acc_unit, rate=args.rate)
    for w in log.warnings:
        _err(f"warning: {w}")
    for note in preprocess.apply(log, args, getattr(args, "backend", "c")):  # --calibration, --align, --offset
        _err(f"note: {note}")
    return log


def _inputs(cls, log, axis):
    """run() arguments of a filter from a log, and a description."""
    if cls.kind == "1d":
        rate, angle, src = axis_inputs(log, axis)
        return (rate, angle), src
    require(log, GYR + ACC)
    if cls.kind == "ahrs":
        require(log, MAG, f"({cls.__name__} is an AHRS filter and needs a magnetometer; "
                          "use an IMU filter without one)")
        return (log.gyr, log.acc, log.mag), "gyr, acc, mag"
    return (log.gyr, log.acc), "gyr, acc"


def _ref_angle(log, axis):
    q = log.q_ref
    if q is None:
        return None
    return quat_to_euler(q)[:, 0 if axis == "x" else 1]


def _errors(cls, est, log, axis):
    if est is None or log.q_ref is None:
        return None
    mask = np.ones(len(log), dtype=bool)
    if cls.kind == "1d":
        return errors_1d(est, _ref_angle(log, axis), mask)
    return errors_3d(est, log.q_ref, mask)


def _fmt_errors(e):
    return ", ".join(f"{k} RMS {v[0]:.3f} max {v[1]:.3f} deg" for k, v in e.items())


# ---------------------------------------------------------------------------
def _demo(args):
    names = None
    if args.filters:
        names = [n for f in args.filters for n in f.split(",") if n]
        for n in names:
            reference_class(n)
    return run_demo(out_dir=args.out, rate=args.rate, duration=args.duration, seed=args.seed,
                    plot=not args.no_plot, names=names)


def _run(args):
    _fusion_hint(args.filter, "run")
    if preprocess.is_fusion(args.filter):  # Fusion's units and dt per sample
        cols, msg, f32 = preprocess.run_fusion(args, _load(args), _pairs(args.param))
        io.write_csv(sys.stdout if args.output == "-" else args.output, cols, float32=f32)
        _err(msg)
        return EXIT_OK
    cls = reference_class(args.filter)
    overrides = _pairs(args.param)
    log = _load(args)
    params = resolve_params(args.filter, log.dt, overrides)
    f = make_filter(args.filter, args.backend, args.dtype, params)
    inputs, src = _inputs(cls, log, args.axis)
    S = run_with_progress(f, inputs, args.filter, args.backend)
    cols = {"time": log.t}
    for j, n in enumerate(cls.state_names):
        cols[n] = S[:, j]
    est = estimate(cls, S)
    if est is None:
        _err(f"note: {why_no_estimate(cls)}; writing the state only")
    elif est.angle is not None:
        cols["angle_deg"] = np.degrees(est.angle)
    else:
        for j, n in enumerate(io.QUAT):
            cols[n] = est.q[:, j]
        e = np.degrees(euler_of(est))
        cols["roll_deg"], cols["pitch_deg"] = e[:, 0], e[:, 1]
        if est.heading:
            cols["yaw_deg"] = e[:, 2]
        else:
            _err(f"note: no heading from {cls.__name__} ({est.source}): yaw omitted")
    f32 = set(cls.state_names) if args.dtype == "float32" else set()
    io.write_csv(sys.stdout if args.output == "-" else args.output, cols, float32=f32)
    msg = (f"{cls.__name__} ({args.backend}, {args.dtype}, dt={log.dt:.6g} s, "
           f"{', '.join(f'{k}={v}' for k, v in params.items() if k != 'dt')}): "
           f"{len(log)} samples from {src}")
    if args.output != "-":
        msg += f" -> {args.output}"
    _err(msg)
    errs = _errors(cls, est, log, args.axis)
    if errs:
        _err(f"against the log's reference q: {_fmt_errors(errs)}")
    if args.plot:
        _plot_run(args.plot, cls, log, S, est, inputs, args.axis)
    return EXIT_OK


def _plot_run(path, cls, log, S, est, inputs, axis):
    if not plots.available():
        _err("plots unavailable: matplotlib is not installed (pip install 'imufuse[plot]')")
        return
    if est is None:
        plots.plot_states(path, log.t, S, cls.state_names, cls.__name__)
    elif est.angle is not None:
        plots.plot_1d(path, log.t, _ref_angle(log, axis), {cls.__name__: est.angle}, inputs[1])
    else:
        ref = quat_to_euler(log.q_ref) if log.q_ref is not None else None
        plots.plot_euler(path, log.t, {cls.__name__: euler_of(est)}, ref)
    _err(f"plot: {path}")


def _fusion_hint(name, command):
    hint = preprocess.fusion_hint(name, command)
    if hint:
        raise UsageError(hint)


def _compare(args):
    log = _load(args)
    if args.filters:
        names = [n for f in args.filters for n in f.split(",") if n]
        for n in names:
            _fusion_hint(n, "compare")
            reference_class(n)
    else:
        kinds = {"imu", "ahrs"} if log.mag is not None else {"imu"}
        names = filter_names(kinds) or filter_names({"1d"})
    scoped = _scoped_params(args.param, names)
    rows, ests = [], {}
    for n in names:
        cls = reference_class(n)
        try:
            inputs, _ = _inputs(cls, log, args.axis)
        except Exception as e:
            if args.filters:
                raise
            rows.append((n, cls.kind, None, None, None, f"skipped: {e}"))
            continue
        params = resolve_params(n, log.dt, scoped[n])
        f = make_filter(n, args.backend, args.dtype, params)
        t0 = time.perf_counter()
        S = run_with_progress(f, inputs, n, args.backend)
        sps = len(log) / max(time.perf_counter() - t0, 1e-9)
        est = estimate(cls, S)
        note = why_no_estimate(cls) if est is None else est.source
        if est is not None:
            ests[n] = est
        errs = _errors(cls, est, log, args.axis)
        final = None
        if est is not None:
            final = (np.array([np.degrees(est.angle[-1]), np.nan, np.nan])
                     if est.angle is not None else np.degrees(euler_of(est)[-1]))
        rows.append((n, cls.kind, errs, final, sps, note))
    has_ref = log.q_ref is not None
    print(f"{len(log)} samples, dt={log.dt:.6g} s, {args.backend} {args.dtype}; "
          + ("errors against the log's q_w..q_z, degrees, whole log" if has_ref
             else "no reference orientation in the log (q_w..q_z): final attitude shown"))
    if has_ref:
        head = (f"{'filter':22s} {'kind':4s} {'angle/tilt rms    max':>21s} {'heading rms    max':>19s} "
                f"{'samples/s':>10s}  estimate from")
    else:
        head = f"{'filter':22s} {'kind':4s} {'final roll/angle  pitch    yaw':>31s} {'samples/s':>10s}  estimate from"
    print(head)
    print("-" * len(head))
    for n, kind, errs, final, sps, note in rows:
        sp = f"{sps:10.3g}" if sps else f"{'-':>10s}"
        if has_ref:
            er = errs or {}
            m = er.get("angle", er.get("tilt"))
            h = er.get("heading")
            ms = f"{m[0]:10.3f} {m[1]:10.3f}" if m else f"{'-':>21s}"
            hs = f"{h[0]:9.3f} {h[1]:9.3f}" if h else f"{'-':>19s}"
            print(f"{n:22s} {kind:4s} {ms:>21s} {hs:>19s} {sp}  {note}")
        else:
            fs = "-" if final is None else "  ".join(
                f"{'-':>7s}" if np.isnan(v) else f"{v:7.2f}" for v in final)
            print(f"{n:22s} {kind:4s} {fs:>31s} {sp}  {note}")
    if args.plot:
        if not plots.available():
            _err("plots unavailable: matplotlib is not installed (pip install 'imufuse[plot]')")
        else:
            one = {n: e.angle for n, e in ests.items() if e.angle is not None}
            three = {n: euler_of(e) for n, e in ests.items() if e.q is not None}
            base, ext = os.path.splitext(args.plot)
            if one and three:
                p1, p3 = f"{base}_1d{ext}", f"{base}_3d{ext}"
            else:
                p1 = p3 = args.plot
            if one:
                plots.plot_1d(p1, log.t, _ref_angle(log, args.axis), one,
                              _inputs(reference_class(next(iter(one))), log, args.axis)[0][1])
                _err(f"plot: {p1}")
            if three:
                plots.plot_euler(p3, log.t, three, quat_to_euler(log.q_ref) if has_ref else None)
                _err(f"plot: {p3}")
    return EXIT_OK


def _bench(args):
    names = ([n for f in args.filters for n in f.split(",") if n] if args.filters
             else filter_names())
    for n in names:
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
    for n in names:
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
                res[backend, dtype] = len(arrs[0]) / best
        print(f"{n:22s} {res['c', 'float32']:11.3g} {res['c', 'float64']:11.3g} "
              f"{res['ref', 'float32']:12.3g} {res['ref', 'float64']:12.3g} "
              f"{res['c', 'float64'] / res['ref', 'float64']:9.0f}x")
    return EXIT_OK


def _validate(args):
    cls = reference_class(args.filter)
    overrides = _pairs(args.param)
    defines = {}
    for d in args.define or ():
        k, _, v = d.partition("=")
        defines[k] = v if v else None
    cflags = args.cflags.split() if args.cflags is not None else None
    if args.csrc:
        dtype = args.dtype or "float32"
        fw = csrc_firmware(args.filter, args.csrc, dtype, cflags=cflags)
    else:
        if not args.sources:
            raise UsageError("validate: give the firmware's C sources (or --csrc DIR)")
        for s in args.sources:
            if not os.path.isfile(s):
                raise LogError(f"{s}: no such file", "file")
        if not args.update:
            raise UsageError("validate: give --update (the update function's prototype or name)")
        state = _pairs(args.state, "--state") or None
        fw = Firmware(args.sources, init=args.init, update=args.update, state=state,
                      state_names=cls.state_names, headers=args.header or (),
                      include_dirs=args.include or (), defines=defines, cflags=cflags,
                      init_args=_pairs(args.init_arg, "--init-arg"))
    if args.log:
        log = _load(args)
        dt = log.dt
        inputs, src = _inputs(cls, log, args.axis)
        t = log.t
    else:
        rate = args.rate or 200.0
        data = (sim.axis1d("slow", rate=rate, duration=args.duration, seed=args.seed)
                if cls.kind == "1d" else
                sim.imu("slow", rate=rate, duration=args.duration, seed=args.seed))
        dt, inputs, t = data.dt, inputs_for(cls.kind, data), data.t
        src = f"simulated 'slow' motion, {rate:g} Hz, {args.duration:g} s, seed {args.seed}"
    params = resolve_params(args.filter, dt, overrides)
    v = validate(fw, args.filter, params, inputs, backend=args.backend, dtype=args.dtype)
    print(f"inputs: {src}; {args.filter} "
          f"{', '.join(f'{k}={val}' for k, val in params.items())}")
    print(v.text())
    if args.plot:
        if not plots.available():
            _err("plots unavailable: matplotlib is not installed (pip install 'imufuse[plot]')")
        else:
            plots.plot_divergence(args.plot, t, v.got, v.want, v.comparison.names,
                                  v.comparison.first_sample,
                                  f"firmware vs imufuse {args.filter} ({v.comparison.dtype})")
            _err(f"plot: {args.plot}")
    return EXIT_OK if v.bit_exact else EXIT_FAIL


# ---------------------------------------------------------------------------
def _log_options(p, rate_help="sample rate, Hz (default: from the time column)"):
    p.add_argument("--gyr-unit", choices=("rad/s", "deg/s"), default="rad/s",
                   help="unit of gyr_x..z (default rad/s)")
    p.add_argument("--acc-unit", choices=("g", "m/s2", "m/s^2"), default="g",
                   help="unit of acc_x..z (default g)")
    p.add_argument("--rate", type=float, metavar="HZ", help=rate_help)
    p.add_argument("--axis", choices=("x", "y"), default="x",
                   help="single-axis filters without rate/angle columns: x = roll from gyr_x and "
                        "atan2(acc_y, acc_z); y = pitch from gyr_y and atan2(-acc_x, acc_z)")


def _filter_options(p):
    p.add_argument("--param", "-p", action="append", metavar="NAME=VALUE",
                   help="filter parameter (repeatable); dt comes from the rate")
    p.add_argument("--dtype", choices=("float32", "float64"), default="float64")
    p.add_argument("--backend", choices=("c", "ref"), default="c",
                   help="c: imufuse_c (compiled); ref: imufuse.reference (pure Python)")


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
    d.add_argument("--filter", dest="filters", action="append", metavar="NAME[,NAME]",
                   help="only these filters")
    d.add_argument("--no-plot", action="store_true")
    d.set_defaults(func=_demo)

    r = sub.add_parser("run", help="one filter over a CSV log -> CSV of states, quaternion, Euler "
                       "angles", formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Run one filter over a log (see imufuse.io for the format).\n"
                       "Output columns: time, the filter's state, then what can be derived:\n"
                       "angle_deg (single-axis), or q_w..q_z, roll_deg, pitch_deg[, yaw_deg].")
    r.add_argument("log", metavar="LOG.csv")
    r.add_argument("--filter", "-f", required=True)
    r.add_argument("-o", "--output", default="-", metavar="OUT.csv", help="default: stdout")
    r.add_argument("--plot", metavar="PNG")
    _log_options(r)
    _filter_options(r)
    preprocess.add_arguments(r)
    r.set_defaults(func=_run)

    c = sub.add_parser("compare", help="several filters on one log: table (errors when the log "
                       "has q_w..q_z) and plot")
    c.add_argument("log", metavar="LOG.csv")
    c.add_argument("--filter", "-f", dest="filters", action="append", metavar="NAME[,NAME]",
                   help="filters to compare (default: every 3D filter the log can feed, or the "
                        "single-axis ones when there are none)")
    c.add_argument("--plot", metavar="PNG")
    _log_options(c)
    _filter_options(c)
    preprocess.add_arguments(c)
    c.set_defaults(func=_compare)

    b = sub.add_parser("bench", help="speed table: C run() vs reference, samples per second")
    b.add_argument("--filter", "-f", dest="filters", action="append", metavar="NAME[,NAME]")
    b.add_argument("--samples", type=int, default=100000, help="C run length (default 100000)")
    b.add_argument("--ref-samples", type=int, default=2000, help="reference run length (default 2000)")
    b.add_argument("--repeat", type=int, default=3)
    b.set_defaults(func=_bench)

    v = sub.add_parser("validate", help="compile firmware C with cffi and compare it with an "
                       "imufuse filter bit for bit", formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Validate firmware filter code against imufuse (see "
                       "imufuse.firmware).\n\nexample:\n  imufuse validate fw/att.c -I fw --header att.h "
                       "--filter Kalman1D \\\n     --init 'void att_init(att_t *s, float dt, float k0)' "
                       "\\\n     --update 'void att_update(att_t *s, float rate, float angle)' \\\n"
                       "     --state theta=x.theta --param k0=0.01\n"
                       "  imufuse validate --csrc --filter Kalman1D --dtype float32")
    v.add_argument("sources", nargs="*", metavar="SOURCE.c")
    v.add_argument("--filter", "-f", required=True, help="the imufuse filter to compare with")
    v.add_argument("--csrc", metavar="DIR", nargs="?", const=str(csrc_dir()),
                   help="validate imufuse's own sources in DIR (default: the C library "
                        "installed with imufuse)")
    v.add_argument("-I", "--include", action="append", metavar="DIR")
    v.add_argument("-D", "--define", action="append", metavar="NAME[=VALUE]")
    v.add_argument("--header", action="append", metavar="FILE.h", help="header(s) to include")
    v.add_argument("--init", metavar="PROTOTYPE|NAME")
    v.add_argument("--update", metavar="PROTOTYPE|NAME")
    v.add_argument("--state", action="append", metavar="NAME=EXPR",
                   help="imufuse state variable = member path or '=C expression' "
                        "(default x.NAME for every state variable)")
    v.add_argument("--init-arg", action="append", metavar="NAME=VALUE")
    v.add_argument("--cflags", metavar="FLAGS",
                   help="compiler flags replacing '-std=c99 -O2 -ffp-contract=off'")
    v.add_argument("--param", "-p", action="append", metavar="NAME=VALUE")
    v.add_argument("--dtype", choices=("float32", "float64"),
                   help="precision (default: the firmware's, from sizeof of its state)")
    v.add_argument("--backend", choices=("c", "ref"), default="c")
    v.add_argument("--log", metavar="LOG.csv", help="inputs from a log (default: simulated)")
    v.add_argument("--gyr-unit", choices=("rad/s", "deg/s"), default="rad/s")
    v.add_argument("--acc-unit", choices=("g", "m/s2", "m/s^2"), default="g")
    v.add_argument("--axis", choices=("x", "y"), default="x")
    v.add_argument("--rate", type=float, metavar="HZ")
    v.add_argument("--duration", type=float, default=10.0)
    v.add_argument("--seed", type=int, default=1)
    v.add_argument("--plot", metavar="PNG", help="divergence plot")
    v.set_defaults(func=_validate)

    cli_vario.add_parsers(sub)  # seed 002: vario, calibrate
    return p


def main(argv: Optional[Sequence[str]] = None) -> int:
    p = build_parser()
    args = p.parse_args(argv)
    if not getattr(args, "func", None):
        p.print_help()
        return EXIT_USAGE
    try:
        return args.func(args)
    except LogError as e:
        _err(f"error: {e}")
        return EXIT_FILE if e.kind == "file" else EXIT_DATA
    except FirmwareError as e:
        _err(f"error: {e}")
        return EXIT_FIRMWARE
    except (UsageError, FilterError, ValueError) as e:
        _err(f"error: {e}")
        return EXIT_USAGE
    except BrokenPipeError:
        return EXIT_OK
