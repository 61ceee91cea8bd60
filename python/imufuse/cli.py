"""The imufuse command line: demo, run, compare, tune, latency, bench, validate, export,
vario, calibrate.

Exit codes (every failure is one line on stderr, "imufuse: error: ..."):
  0  success
  1  a bit-exact check or a validation failed (the firmware differs)
  2  bad command line (unknown filter or parameter, bad option value, an
     output that would overwrite the input)
  3  a file not found, unreadable, or an output that cannot be written
  4  bad log contents (columns, values, time), or nothing could be computed
     or evaluated
  5  firmware that cannot be compiled, bound or run (a crash, exit(), a
     hang past --timeout, a missing symbol)
  6  an unexpected internal error (a bug; IMUFUSE_DEBUG=1 shows the traceback)
130  interrupted (Ctrl-C)
"""
# Adding a subcommand: write `_name(args) -> exit code` and a `_parser_name(sub)` that builds
# its parser, and list it in SUBCOMMANDS.
import argparse
import ast
import inspect
import math
import os
import sys
import time
import concurrent.futures as cf
import itertools

import numpy as np

from . import __version__, io, plots, preprocess, sim
from ._atomic import check_outputs
from .arduino import export_arduino
from ._resources import csrc_dir
from .catalogue import canonical_name
from .catalogue import entry as _entry
from .catalogue import (FilterError, estimate, filter_names, inputs_for, make_filter,
                        param_names, reference_class, resolve_params,
                        why_no_estimate)
from .cli_vario import add_parsers
from .demo import run_demo
from .estimate import euler_of
from .evaluation import (METRICS, estimate_latency, evaluate, from_enu, mean_over_trials,
                         to_enu)
from .firmware import (DEFAULT_TIMEOUT, Firmware, FirmwareError, counts_for, csrc_firmware,
                       validate_isolated)
from .firmware_target import target_names
from .io import (ACC, EXAMPLE_ATTRIBUTION, GYR, LogError, MAG, axis_inputs, example_log,
                 parse_column_map, read_column_map, read_log, require)
from .preprocess import add_arguments as _preprocess_options, apply, fusion_hint
from .rotations import quat_to_euler

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_FILE, EXIT_DATA, EXIT_FIRMWARE, EXIT_INTERNAL = range(7)
EXIT_INTERRUPT = 130


class UsageError(ValueError):
    pass


class OutputError(OSError):
    """An output file that cannot be written (exit 3)."""


class NothingComputed(ValueError):
    """Nothing could be computed or evaluated (exit 4)."""


def _err(msg):
    print(f"imufuse: {msg}", file=sys.stderr)


def _value(text):
    low = text.strip().lower()
    if low in ("true", "false"):
        return low == "true"
    if low in ("none", "null"):
        return None
    try:
        v = ast.literal_eval(text.strip())
    except (ValueError, SyntaxError, MemoryError, RecursionError):
        return text.strip()
    return v


def _pairs(items, what="--param"):
    out = {}
    for it in items or ():
        if "=" not in it:
            raise UsageError(f"{what} {it!r}: expected NAME=VALUE")
        k, v = it.split("=", 1)
        out[k.strip()] = _value(v)
    return out


def _names(items):
    return [canonical_name(n.strip()) for f in items or () for n in f.split(",") if n.strip()]


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


def effective_params(name, params):
    """The constructor's keyword defaults updated by `params` (what the filter
    really runs with), dt included."""
    sig = inspect.signature(reference_class(name)._params)
    out = {p.name: p.default for p in sig.parameters.values()
           if p.default is not inspect.Parameter.empty}
    out.update(params)
    return out


def _fmt_params(name, params):
    eff = effective_params(name, params)
    s = ", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                  for k, v in eff.items() if k != "dt")
    return s or "no parameters"


# ---------------------------------------------------------------------------
# running filters: per-sample dt and the initial orientation

def supports_dt_array(name):
    """True when the filter's run() takes dt=array (per-sample periods)."""
    try:
        return "dt" in inspect.signature(reference_class(name).run).parameters
    except (TypeError, ValueError):
        return False


def supports_init(name):
    """True when the filter's constructor takes init= ("first" or a quaternion)."""
    cls = reference_class(name)
    for fn in (cls.__init__, cls._params):
        try:
            if "init" in inspect.signature(fn).parameters:
                return True
        except (TypeError, ValueError):
            pass
    return False


#: Runs at least this long (samples) report progress on stderr: the pure-Python
#: reference runs ~10^5 samples/s, the compiled filters ~10^7.
PROGRESS_MIN = {"ref": 20_000, "c": 2_000_000}


def run_with_progress(f, inputs, label, backend, dts=None):
    """f.run(*inputs[, dt=dts]), in about 20 chunks with a progress line on
    stderr when the run is long. The state carries over between run() calls,
    so the result is the same trajectory, bit for bit."""
    n = len(inputs[0])
    kw = (lambda a, b: {}) if dts is None else (lambda a, b: {"dt": dts[a:b]})
    if n < PROGRESS_MIN[backend]:
        return f.run(*inputs, **kw(0, n))
    step = -(-n // 20)
    parts = []
    for k in range(0, n, step):
        parts.append(f.run(*[x[k:k + step] for x in inputs], **kw(k, k + step)))
        done = min(k + step, n)
        _err(f"{label}: {100 * done // n}% ({done}/{n} samples)")
    return np.concatenate(parts)


def _init_value(text):
    if text in (None, "first", "identity"):
        return text
    try:
        q = [float(v) for v in text.split(",")]
    except ValueError:
        q = []
    if len(q) != 4 or not all(math.isfinite(v) for v in q) or not any(q):
        raise UsageError(f"--init {text!r}: expected first, identity or a quaternion w,x,y,z")
    return q


class Runner:
    """One filter, configured from the command line, run over a log."""

    def __init__(self, name, log, args, overrides):
        self.name, self.cls, self.log = name, reference_class(name), log
        self.params = resolve_params(name, log.dt, overrides)
        self.backend, self.dtype = args.backend, args.dtype
        self.notes = []
        self.dts = None
        if not log.fixed_rate and log.dts is not None:
            if supports_dt_array(name):
                self.dts = log.dts
            elif np.max(np.abs(log.dts - log.dt)) > 1e-6 * log.dt:
                self.notes.append(f"fixed dt {log.dt:.6g} s (this build has no per-sample dt)")
        init = _init_value(getattr(args, "init", None))
        kw = {}
        if self.cls.kind != "1d":
            if init is None:
                init = "first"          # the default for logs
            if not supports_init(name):
                if init != "identity":
                    self.notes.append(f"init={init} unsupported by this build: started from "
                                      "identity")
                init = "identity"
            elif isinstance(init, list):
                kw["q0"] = init
            elif init == "first":
                kw["init"] = "first"
                w = getattr(args, "init_window", None)
                if w and w > 1:
                    kw["init_window"] = w
                    init = f"first (mean of {w} samples)"
        self.init = (None if self.cls.kind == "1d" else
                     "q0=" + ",".join(f"{v:g}" for v in init) if isinstance(init, list) else init)
        self.filter = make_filter(name, self.backend, self.dtype, {**self.params, **kw})

    def run(self, inputs, label=None):
        return run_with_progress(self.filter, inputs, label or self.name, self.backend, self.dts)

    def describe_time(self):
        if self.dts is not None:
            d = self.dts[1:]
            return (f"dt per sample from the time column ({d.min():.6g}..{d.max():.6g} s)"
                    if d.size else f"dt={self.log.dt:.6g} s")
        return f"dt={self.log.dt:.6g} s"


# ---------------------------------------------------------------------------
# logs

def _column_map(args):
    cmap = {}
    if getattr(args, "column_map", None):
        cmap.update(read_column_map(args.column_map))
    for item in getattr(args, "columns", None) or ():
        cmap.update(parse_column_map(item))
    return cmap


def _load(args, path=None):
    log = read_log(path or args.log, gyr_unit=args.gyr_unit, acc_unit=args.acc_unit,
                   rate=args.rate, columns=_column_map(args),
                   fixed_rate=getattr(args, "fixed_rate", False),
                   time_unit=getattr(args, "time_unit", None))
    for w in log.warnings:
        _err(f"note: {w}")
    for note in apply(log, args, getattr(args, "backend", "c")):  # --calibration, --align, --offset
        _err(f"note: {note}")
    return log


def _input_files(args):
    """Every file a log command reads: the log, a column map, a calibration."""
    return [getattr(args, "log", None), getattr(args, "column_map", None),
            getattr(args, "calibration", None)]


def _headers(args):
    out = []
    for h in args.header or ():
        for d in ["", *(args.include or ())]:
            p = os.path.join(d, h) if d else h
            if os.path.isfile(p):
                out.append(p)
    return out


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


def _ref_frame(args, log):
    return getattr(args, "ref_frame", None) or log.ref_frame or "NWU"


def _ref_angle(log, axis, args):
    """Reference angle of the single-axis filters (roll or pitch of the reference, NWU)."""
    q = log.q_ref
    if q is None:
        return None
    q = from_enu(to_enu(q, _ref_frame(args, log), args.ref_direction), "NWU")
    return quat_to_euler(q)[:, 0 if axis == "x" else 1]


def _mask(log, args):
    """The samples that count for errors: the movement column and --skip."""
    mask = log.movement
    skip = getattr(args, "skip", None)
    if skip:
        t = log.t
        late = t >= t[0] + skip
        mask = late if mask is None else (mask & late)
    return mask


def _evaluate(cls, est, log, args, per_sample=False):
    """Evaluation (3D) or {'angle': (rms, max), 'n': n} (1D) against the log's
    reference, or None without a reference or estimate."""
    if est is None or log.q_ref is None:
        return None
    mask = _mask(log, args)
    if cls.kind == "1d":
        ref = _ref_angle(log, args.axis, args)
        use = np.isfinite(ref) & (mask if mask is not None else True)
        e = np.degrees(np.abs(est.angle - ref))[use]
        n = int(np.count_nonzero(use))
        return {"angle": (float(np.sqrt(np.mean(e * e))) if n else math.nan,
                          float(e.max()) if n else math.nan), "n": n,
                "n_ref_nan": int(np.count_nonzero(~np.isfinite(ref)))}
    return evaluate(est.q, log.q_ref, est_frame="NWU", ref_frame=_ref_frame(args, log),
                    ref_direction=args.ref_direction, movement=mask,
                    remove_heading_offset=args.heading_offset, per_sample=per_sample)


def _estimate(cls, S, chunk=1 << 16):
    """catalogue.estimate(cls, S), block by block (the adapters' temporaries
    stay small for long logs); the same values."""
    if len(S) <= chunk:
        return estimate(cls, S)
    parts = [estimate(cls, S[k:k + chunk]) for k in range(0, len(S), chunk)]
    if parts[0] is None:
        return None
    e = parts[0]
    if e.angle is not None:
        e.angle = np.concatenate([p.angle for p in parts])
    else:
        e.q = np.concatenate([p.q for p in parts])
    return e


def _euler_deg(q, chunk=65536):
    """(N, 3) roll, pitch, yaw in degrees, computed in chunks (bounded memory)."""
    out = np.empty((len(q), 3))
    for k in range(0, len(q), chunk):
        out[k:k + chunk] = np.degrees(quat_to_euler(q[k:k + chunk]))
    return out


def _frame_hint(cls, est, log, args, ev):
    """A hint when the errors point at a frame or direction mistake: an inclination or
    heading error near 90 or 180 degrees that another reference frame or direction takes
    down by more than half (an ENU reference read as NWU gives ~90 deg of heading, read as
    NED ~180 deg of inclination). Said also when the frame was given: the option may be the
    mistake."""
    if cls.kind == "1d" or ev is None or isinstance(ev, dict) or not ev.n:
        return None
    heading = cls.kind == "ahrs"
    worst = max(ev.inclination, ev.heading if heading else 0.0)
    if not worst > 45.0:
        return None
    cur = (_ref_frame(args, log), args.ref_direction)
    mask = _mask(log, args)
    best = None
    for fr in ("NWU", "ENU", "NED"):
        for dr in ("sensor-to-earth", "earth-to-sensor"):
            if (fr, dr) == cur:
                continue
            e = evaluate(est.q, log.q_ref, est_frame="NWU", ref_frame=fr, ref_direction=dr,
                         movement=mask, remove_heading_offset=args.heading_offset,
                         per_sample=False)
            score = max(e.inclination, e.heading if heading else 0.0)
            if best is None or score < best[0]:
                best = (score, fr, dr)
    if best is None or not best[0] < 0.5 * worst:
        return None
    said = ("given" if getattr(args, "ref_frame", None) else
            "from the file" if log.ref_frame else "assumed")
    opts = (f"--ref-frame {best[1]}" +
            (f" --ref-direction {best[2]}" if best[2] != cur[1] else ""))
    return (f"hint: against the reference as {cur[0]} ({said}), {cur[1]}, the error reaches "
            f"{worst:.1f} deg; with {opts} it would be {best[0]:.1f} deg: is the reference in "
            f"{best[1]}{', ' + best[2] if best[2] != cur[1] else ''}?")


def _frame_q(q, frame):
    return q if frame == "NWU" else from_enu(to_enu(q, "NWU"), frame)


# ---------------------------------------------------------------------------
# demo

def _demo(args):
    names = None
    if args.filters:
        names = _names(args.filters)
        for n in names:
            reference_class(n)
    if args.out and os.path.exists(args.out) and not os.path.isdir(args.out):
        raise OutputError(f"--out {args.out}: exists and is not a directory")
    rc = run_demo(out_dir=args.out, rate=args.rate, duration=args.duration, seed=args.seed,
                  plot=not args.no_plot, names=names)
    if args.no_real:
        return rc
    three = [n for n in (names or []) if reference_class(n).kind != "1d"]
    if names and not three:
        return rc
    print(f"\nreal data: every 3D filter against optical truth ({EXAMPLE_ATTRIBUTION})")
    argv = ["compare", example_log()] + [a for n in three for a in ("-f", n)]
    if not args.no_plot:
        os.makedirs(args.out, exist_ok=True)
        argv += ["--plot", os.path.join(args.out, "demo_real.png")]
    sys.stdout.flush()
    rc_real = _compare(build_parser().parse_args(argv))
    return rc or rc_real


def _parser_demo(sub):
    d = sub.add_parser("demo", help="every filter on simulated data: C vs reference bit for bit, "
                       "errors against ground truth, plots")
    d.add_argument("--out", default="imufuse-demo", metavar="DIR",
                   help="directory for the plots (default ./imufuse-demo)")
    d.add_argument("--rate", type=_positive(float, 1e6), default=200.0,
                   help="sample rate, Hz (default 200)")
    d.add_argument("--duration", type=_positive(float, 1e5), default=20.0,
                   help="seconds of data (default 20)")
    d.add_argument("--seed", type=int, default=1)
    d.add_argument("--filter", dest="filters", action="append", metavar="NAME[,NAME]",
                   help="only these filters")
    d.add_argument("--no-plot", action="store_true")
    d.add_argument("--no-real", action="store_true",
                   help="skip the real recording (45 s of BROAD with optical truth)")
    d.set_defaults(func=_demo)


# ---------------------------------------------------------------------------
# run

def _rejected(runner, log):
    """Samples the runner's filter rejected (fixed-point filters reject none)."""
    return min(int(getattr(runner.filter, "skipped", 0)), len(log))


def _run(args):
    _fusion_hint(args.filter, "run")
    check_outputs(_input_files(args), [("-o", args.output), ("--plot", args.plot)])
    if preprocess.is_fusion(args.filter):  # Fusion's units and dt per sample
        cols, msg, f32 = preprocess.run_fusion(args, _load(args), _pairs(args.param))
        _write_output(args.output, cols, f32)
        _err(msg)
        return EXIT_OK
    cls = reference_class(args.filter)
    log = _load(args)
    r = Runner(args.filter, log, args, _pairs(args.param))
    inputs, src = _inputs(cls, log, args.axis)
    S = r.run(inputs)
    rejected = _rejected(r, log)
    if rejected == len(log):
        raise NothingComputed(f"{log.path}: {cls.__name__} rejected every one of the "
                              f"{len(log)} samples (non-finite values, or updates it cannot "
                              "make): nothing was estimated")
    cols = {"time": log.t}
    for j, n in enumerate(cls.state_names):
        cols[n] = S[:, j]
    est = _estimate(cls, S)
    if est is None:
        _err(f"note: {why_no_estimate(cls)}; writing the state only")
    elif est.angle is not None:
        cols["angle_deg"] = np.degrees(est.angle)
    else:
        q = _frame_q(est.q, args.frame)
        if est.source != "q0..q3" or args.frame != "NWU":
            for j, n in enumerate(io.QUAT):
                cols[n] = q[:, j]
        e = _euler_deg(q)
        cols["roll_deg"], cols["pitch_deg"] = e[:, 0], e[:, 1]
        if est.heading:
            cols["yaw_deg"] = e[:, 2]
        else:
            _err(f"note: no heading from {cls.__name__} ({est.source}): yaw omitted")
    f32 = set(cls.state_names) if args.dtype == "float32" else set()
    _write_output(args.output, cols, f32)
    init = f", init={r.init}" if r.init else ""
    msg = (f"{cls.__name__} ({args.backend}, {args.dtype}, {r.describe_time()}{init}; "
           f"{_fmt_params(args.filter, r.params)}): {len(log)} samples from {src}")
    if args.output != "-":
        msg += f" -> {args.output}"
    _err(msg)
    for n in r.notes:
        _err(f"note: {n}")
    if rejected:
        _err(f"note: {rejected} of {len(log)} samples rejected by {cls.__name__} (non-finite "
             "values, or updates it cannot make): the state was kept through them")
    ev = _evaluate(cls, est, log, args)
    if ev is not None:
        if isinstance(ev, dict):
            _err(f"against the log's reference q: angle RMS {ev['angle'][0]:.3f} max "
                 f"{ev['angle'][1]:.3f} deg over {ev['n']} samples")
        else:
            _err(f"against the log's reference q ({_ref_frame(args, log)}): {ev.summary()}")
            hint = _frame_hint(cls, est, log, args, ev)
            if hint:
                _err(hint)
    if args.plot:
        _plots(args.plot, log, {args.filter: (cls, est)}, args,
               f"{args.filter} ({_fmt_params(args.filter, r.params)})")
    return EXIT_OK


def _write_output(path, cols, f32=()):
    """CSV to stdout ("-") or a file, or NPZ for OUT.npz; OutputError when it cannot be written."""
    try:
        if path == "-":
            io.write_csv(sys.stdout, cols, float32=f32)
        elif path.lower().endswith(".npz"):
            io.write_npz(path, cols)
        else:
            io.write_csv(path, cols, float32=f32)
    except OSError as e:
        if isinstance(e, BrokenPipeError):
            raise
        raise OutputError(f"-o {path}: cannot write: {e.strerror or e}") from None


def _parser_run(sub):
    r = sub.add_parser("run", help="one filter over a log -> CSV of states, quaternion, Euler "
                       "angles", formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Run one filter over a log (see imufuse.io for the formats).\n"
                       "Output columns: time, the filter's state, then what can be derived:\n"
                       "angle_deg (single-axis), or [q_w..q_z when the state is not already the\n"
                       "quaternion,] roll_deg, pitch_deg[, yaw_deg]. OUT.npz writes NumPy arrays.")
    r.add_argument("log", metavar="LOG")
    r.add_argument("--filter", "-f", required=True, type=canonical_name)
    r.add_argument("-o", "--output", default="-", metavar="OUT.csv", help="default: stdout")
    r.add_argument("--plot", metavar="PNG")
    _log_options(r)
    _filter_options(r)
    _eval_options(r)
    _preprocess_options(r)
    r.set_defaults(func=_run)


# ---------------------------------------------------------------------------
# compare

def _default_filters(log):
    """3D filters the log can feed (AHRS ones only with a magnetometer), else the 1D ones."""
    if log.has(*GYR, *ACC):
        return filter_names({"imu", "ahrs"} if log.has(*MAG) else {"imu"}) or filter_names({"1d"})
    return filter_names({"1d"})


def _fusion_hint(name, command):
    hint = fusion_hint(name, command)
    if hint:
        raise UsageError(hint)


def _compare(args):
    names = _names(args.filters)
    for n in names:
        _fusion_hint(n, "compare")
        reference_class(n)
    check_outputs(_input_files(args), [("--plot", args.plot)])
    log = _load(args)
    if not names:
        names = _default_filters(log)
    per = _scoped_params(args.param, names)
    rows, ests, timing, hint, computed = [], {}, None, None, 0
    for n in names:
        cls = reference_class(n)
        try:
            inputs, src = _inputs(cls, log, args.axis)
        except LogError as e:
            rows.append((n, cls.kind, None, None, None, f"skipped: {str(e).split(': ', 1)[-1]}"))
            continue
        try:
            r = Runner(n, log, args, per[n])
        except FilterError as e:
            rows.append((n, cls.kind, None, None, None, f"skipped: {e}"))
            continue
        timing = timing or r.describe_time()
        t0 = time.perf_counter()
        S = r.run(inputs)
        sps = len(log) / max(time.perf_counter() - t0, 1e-9)
        rejected = _rejected(r, log)
        est = _estimate(cls, S) if rejected < len(log) else None
        del S
        note = why_no_estimate(cls) if est is None else est.source
        if rejected == len(log):
            note = f"every one of the {len(log)} samples rejected: nothing estimated"
        elif rejected:
            note += f"; {rejected} of {len(log)} samples rejected"
        if r.notes:
            note += "; " + "; ".join(r.notes)
        if est is not None:
            computed += 1
            if args.plot:               # kept for the plot only: long logs stay small
                ests[n] = (cls, est)
        final = None
        if est is not None:
            if est.angle is not None:
                final = np.array([np.degrees(est.angle[-1]), np.nan, np.nan])
            else:
                final = np.degrees(quat_to_euler(_frame_q(est.q[-1:], args.frame))[0])
                if not est.heading:
                    final[2] = np.nan
        ev = _evaluate(cls, est, log, args)
        hint = hint or _frame_hint(cls, est, log, args, ev)
        rows.append((n, cls.kind, ev, final, sps, note))
    if not computed:
        for n, _kind, _, _, _, note in rows:
            _err(f"{n}: {note}")
        raise NothingComputed(f"{log.path}: no filter could run on this log ({len(log)} samples; "
                              f"columns found: {', '.join(map(repr, log.header))})")
    has_ref = log.q_ref is not None
    frame = _ref_frame(args, log)
    print(f"{log.path}: {len(log)} samples, {timing}, "
          f"{args.backend} {args.dtype}; "
          + (f"errors against the log's q_w..q_z ({frame}, {args.ref_direction}), degrees RMS "
             "(BROAD definitions: e = q (x) r^-1 in the earth frame)" if has_ref
             else f"no reference orientation in the log (q_w..q_z): final attitude shown "
                  f"({args.frame})"))
    evaluated = 0
    if has_ref:
        head = (f"{'filter':22s} {'kind':4s} {'incl/angle':>10s} {'heading':>9s} {'total':>9s} "
                f"{'samples':>8s} {'samples/s':>10s}  estimate from")
    else:
        head = (f"{'filter':22s} {'kind':4s} {'final roll/angle  pitch    yaw':>31s} "
                f"{'samples/s':>10s}  estimate from")
    print(head)
    print("-" * len(head))
    excluded = None
    for n, kind, ev, final, sps, note in rows:
        sp = f"{sps:10.3g}" if sps else f"{'-':>10s}"
        if has_ref:
            if ev is None:
                print(f"{n:22s} {kind:4s} {'-':>10s} {'-':>9s} {'-':>9s} {'-':>8s} {sp}  {note}")
                continue
            if isinstance(ev, dict):
                m, h, t, cnt = ev["angle"][0], math.nan, math.nan, ev["n"]
            else:
                m, h, t, cnt = ev.inclination, ev.heading, ev.total, ev.n
                excluded = ev
                if kind != "ahrs":          # 6-DOF: inclination only
                    h = t = math.nan
                if ev.n_est_nan:
                    note += f"; {ev.n_est_nan} non-finite estimates"
                if args.heading_offset and kind == "ahrs":
                    note += f"; heading offset {ev.heading_offset:.2f} deg removed"
            evaluated += cnt > 0
            f = lambda v, w: f"{'-':>{w}s}" if math.isnan(v) else f"{v:{w}.3f}"  # noqa: E731
            print(f"{n:22s} {kind:4s} {f(m, 10)} {f(h, 9)} {f(t, 9)} {cnt:8d} {sp}  {note}")
        else:
            fs = "-" if final is None else "  ".join(
                f"{'-':>7s}" if np.isnan(v) else f"{v:7.2f}" for v in final)
            print(f"{n:22s} {kind:4s} {fs:>31s} {sp}  {note}")
    if excluded is not None and (excluded.n_ref_nan or excluded.n_outside_mask):
        print(f"excluded: {excluded.n_outside_mask} samples outside the movement mask, "
              f"{excluded.n_ref_nan} with a NaN reference")
    if hint:
        _err(hint)
    if args.plot:
        given = ", ".join(args.param) if args.param else "default gains"
        _plots(args.plot, log, ests, args, f"{', '.join(ests)} ({given}; {timing}, init "
                                           f"{getattr(args, 'init', None) or 'first'})")
    if has_ref and not evaluated:
        raise NothingComputed(f"{log.path}: nothing could be evaluated: no sample has a finite "
                              "reference inside the movement mask")
    return EXIT_OK


def _plots(path, log, ests, args, what):
    if not plots.available():
        _err("plots unavailable: matplotlib is not installed (pip install 'imufuse[plot]')")
        return
    one = {n: e.angle for n, (c, e) in ests.items() if e.angle is not None}
    three = {n: e for n, (c, e) in ests.items() if e.q is not None}
    base, ext = os.path.splitext(path)
    p1, p3 = (f"{base}_1d{ext}", f"{base}_3d{ext}") if one and three else (path, path)
    title = f"{os.path.basename(log.path)}: {what}"
    try:
        if one:
            plots.plot_1d(p1, log.t, _ref_angle(log, args.axis, args), one,
                          axis_inputs(log, args.axis)[1], title=title)
            _err(f"plot: {p1}")
        if three:
            ref, errors = None, None
            if log.q_ref is not None:
                ref = quat_to_euler(from_enu(to_enu(log.q_ref, _ref_frame(args, log),
                                                    args.ref_direction), "NWU"))
                errors = {}
                for n, e in three.items():
                    ev = _evaluate(ests[n][0], e, log, args, per_sample=True)
                    errors[n] = ev.per_sample["total" if e.heading else "inclination"]
            plots.plot_euler(p3, log.t, {n: _euler_nwu(e) for n, e in three.items()}, ref,
                             title=title, errors=errors,
                             error_label="error (deg): total (AHRS), inclination (IMU)")
            _err(f"plot: {p3}")
    except OSError as e:
        raise OutputError(f"--plot {path}: cannot write: {e.strerror or e}") from None


def _euler_nwu(est):
    return euler_of(est)


def _parser_compare(sub):
    c = sub.add_parser("compare", help="several filters on one log: error table (BROAD metrics "
                       "when the log has a reference orientation) and plot")
    c.add_argument("log", metavar="LOG")
    c.add_argument("--filter", "-f", dest="filters", action="append", metavar="NAME[,NAME]",
                   help="filters to compare (default: every 3D filter the log can feed, or the "
                        "single-axis ones when there are none)")
    c.add_argument("--plot", metavar="PNG")
    _log_options(c)
    _filter_options(c)
    _eval_options(c)
    _preprocess_options(c)
    c.set_defaults(func=_compare)


# ---------------------------------------------------------------------------
# tune

def _grid_spec(text, default):
    """'beta=0.01:1:12' (log-spaced), 'beta=0.01:1:12lin', 'beta=0.02,0.05,0.1' -> (name, values)."""
    if "=" not in text:
        raise UsageError(f"--grid {text!r}: expected NAME=LO:HI:N or NAME=V1,V2,...")
    k, v = text.split("=", 1)
    k, v = k.strip(), v.strip()
    try:
        if ":" in v:
            lo, hi, n = v.split(":")
            lin = n.endswith("lin")
            n = int(n[:-3] if lin else n)
            lo, hi = float(lo), float(hi)
            if n < 1 or n > 10000 or not (math.isfinite(lo) and math.isfinite(hi)):
                raise ValueError
            if not lin and (lo <= 0 or hi <= 0):
                raise UsageError(f"--grid {text}: a log-spaced range needs positive ends "
                                 "(add 'lin' after N for a linear one)")
            vals = np.linspace(lo, hi, n) if lin else np.geomspace(lo, hi, n)
        else:
            vals = [float(x) for x in v.split(",")]
    except UsageError:
        raise
    except ValueError:
        raise UsageError(f"--grid {text!r}: expected NAME=LO:HI:N[lin] or NAME=V1,V2,...") from None
    return k, [float(x) for x in vals]


def _tune(args):
    name = args.filter
    cls = reference_class(name)
    if cls.kind == "1d":
        raise UsageError(f"tune: {name} is a single-axis filter; tune evaluates 3D filters "
                         "against a reference orientation")
    metric = args.metric or ("total" if cls.kind == "ahrs" else "inclination")
    if metric not in METRICS:
        raise UsageError(f"--metric: one of {', '.join(METRICS)}")
    if cls.kind != "ahrs" and metric != "inclination":
        raise UsageError(f"--metric {metric}: {name} has no heading reference; use inclination")
    logs = [_load(args, p) for p in args.logs]
    for lg in logs:
        if lg.q_ref is None:
            raise NothingComputed(f"{lg.path}: no reference orientation (q_w..q_z): nothing to "
                                  "tune against")
    fixed = _pairs(args.param)
    grids = [_grid_spec(g, None) for g in args.grid or ()]
    if not grids:
        # every float parameter with a default: x1/10 .. x10 around it, log-spaced
        eff = effective_params(name, resolve_params(name, 0.01, fixed))
        grids = [(k, list(np.geomspace(v / 10, v * 10, args.points)))
                 for k, v in eff.items()
                 if k != "dt" and k not in fixed and isinstance(v, float) and v > 0]
        if not grids:
            raise UsageError(f"tune: {name} has no positive float parameter to tune; give --grid")
    names = [k for k, _ in grids]
    resolve_params(name, logs[0].dt, {**fixed, **{k: v[0] for k, v in grids}})  # names exist
    inputs = [_inputs(cls, lg, "x")[0] for lg in logs]
    if not args.grid:
        # vary only what acts: a parameter whose x10 leaves the first log's states unchanged
        # (acc_1g with the accelerometer gate off) is left at its default, and said so
        head = [np.asarray(a)[:4000] for a in inputs[0]]
        eff = effective_params(name, resolve_params(name, 0.01, fixed))

        def states(over):
            r = Runner(name, logs[0], args, {**fixed, **over})
            return r.filter.run(*head)
        base = states({})
        idle = []
        for k in names:
            try:
                same = np.array_equal(states({k: eff[k] * 10.0}), base, equal_nan=True)
            except FilterError:
                same = False
            if same:
                idle.append(k)
        if idle:
            _err(f"note: not varied (no effect with these settings): {', '.join(idle)}")
            grids = [(k, v) for k, v in grids if k not in idle]
            names = [k for k, _ in grids]
            if not grids:
                raise UsageError(f"tune: no parameter of {name} acts with these settings; "
                                 "give --grid")

    def score(values):
        over = {**fixed, **dict(zip(names, values))}
        evs = []
        for lg, inp in zip(logs, inputs):
            r = Runner(name, lg, args, over)
            S = r.filter.run(*inp, **({} if r.dts is None else {"dt": r.dts}))
            evs.append(_evaluate(cls, _estimate(cls, S), lg, args))
        return mean_over_trials(evs)[metric], evs

    def search(points):
        results = {}
        total = len(points)
        workers = max(1, args.jobs or os.cpu_count() or 1)
        done = 0
        with cf.ThreadPoolExecutor(max_workers=workers) as ex:
            futs = {ex.submit(score, p): p for p in points}
            for fu in cf.as_completed(futs):
                p = futs[fu]
                try:
                    results[p] = fu.result()
                except FilterError as e:
                    results[p] = (math.nan, str(e))
                done += 1
                if not args.quiet:
                    bar = "#" * (30 * done // total)
                    print(f"\rtune: [{bar:30s}] {done}/{total}", end="", file=sys.stderr,
                          flush=True)
        if not args.quiet:
            print(file=sys.stderr)
        return results

    points = [tuple(p) for p in itertools.product(*[v for _, v in grids])]
    res = search(points)
    for _ in range(args.refine):
        good = [p for p in res if math.isfinite(res[p][0])]
        if not good:
            break
        best = min(good, key=lambda p: res[p][0])
        axes = []
        for j in range(len(grids)):
            vs = sorted({p[j] for p in res})
            i = vs.index(best[j])
            lo, hi = vs[max(i - 1, 0)], vs[min(i + 1, len(vs) - 1)]
            axes.append(np.geomspace(lo, hi, 5) if lo > 0 else np.linspace(lo, hi, 5))
        new = [tuple(float(x) for x in p) for p in itertools.product(*axes)]
        res.update(search([p for p in new if p not in res]))
    good = sorted((p for p in res if math.isfinite(res[p][0])), key=lambda p: res[p][0])
    if not good:
        why = next((v[1] for v in res.values() if isinstance(v[1], str)), "")
        raise NothingComputed(f"tune: no parameter set could be evaluated ({len(res)} tried)"
                              + (f"; e.g. {why}" if why else ""))
    print(f"{name} on {len(logs)} log{'s' if len(logs) > 1 else ''}: mean over logs of the "
          f"{metric} RMS (deg); {len(res)} parameter sets")
    # the best first; every log by its full name
    w = [max(len(os.path.basename(lg.path)), 8) for lg in logs]
    head = "  ".join(f"{k:>10s}" for k in names) + f"  {metric:>11s}" + "".join(
        f"  {os.path.basename(lg.path):>{wi}s}" for lg, wi in zip(logs, w))
    print(head)
    print("-" * len(head))
    show = good if args.all else good[:args.top]
    for p in show:
        s, evs = res[p]
        print("  ".join(f"{v:10.4g}" for v in p) + f"  {s:11.3f}" + "".join(
            f"  {getattr(e, metric):{wi}.3f}" for e, wi in zip(evs, w))
            + ("  <- best" if p == good[0] else ""))
    best = good[0]
    print(f"best: {', '.join(f'{k}={v:.4g}' for k, v in zip(names, best))} "
          f"({metric} {res[best][0]:.3f} deg)")
    return EXIT_OK


def _parser_tune(sub):
    t = sub.add_parser("tune", help="tune a filter's parameters on logs with a reference "
                       "orientation (grid with refinement, parallel)",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Grid search (then --refine rounds of a finer grid around the "
                       "best point) of a\nfilter's parameters; the score is the mean over the logs "
                       "of the BROAD RMS error\n(--metric). Runs in parallel threads (run() "
                       "releases the GIL).\n\nexample:\n  imufuse tune trial1.npz trial2.npz -f "
                       "MadgwickIMU --grid beta=0.005:1:15")
    t.add_argument("logs", nargs="+", metavar="LOG")
    t.add_argument("--filter", "-f", required=True, type=canonical_name)
    t.add_argument("--grid", "-g", action="append", metavar="NAME=LO:HI:N[lin]|V1,V2,..",
                   help="values of a parameter (repeatable; log-spaced unless 'lin'); default: "
                        "every gain, /10 .. x10 around its default")
    t.add_argument("--points", type=_positive(int, 1000), default=9,
                   help="grid points per parameter for the default grid (default 9)")
    t.add_argument("--refine", type=_nonneg_int, default=2,
                   help="rounds of a finer grid around the best point (default 2)")
    t.add_argument("--metric", choices=("total", "heading", "inclination"),
                   help="default: total for AHRS, inclination for IMU filters")
    t.add_argument("--jobs", "-j", type=_positive(int, 1024), help="threads (default: cores)")
    t.add_argument("--top", type=_positive(int, 10**6), default=15, help="rows shown (default 15)")
    t.add_argument("--all", action="store_true", help="show every parameter set")
    t.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    _log_options(t)
    _filter_options(t)
    _eval_options(t)
    t.set_defaults(func=_tune)


# ---------------------------------------------------------------------------
# bench

def _bench(args):
    names = _names(args.filters) or filter_names()
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
                res[backend, dtype] = len(arrs[0]) / max(best, 1e-9)
        print(f"{n:22s} {res['c', 'float32']:11.3g} {res['c', 'float64']:11.3g} "
              f"{res['ref', 'float32']:12.3g} {res['ref', 'float64']:12.3g} "
              f"{res['c', 'float64'] / res['ref', 'float64']:9.0f}x")
    return EXIT_OK


def _parser_bench(sub):
    b = sub.add_parser("bench", help="speed table: C run() vs reference, samples per second")
    b.add_argument("--filter", "-f", dest="filters", action="append", metavar="NAME[,NAME]")
    b.add_argument("--samples", type=_positive(int, 10**8), default=100000,
                   help="C run length (default 100000)")
    b.add_argument("--ref-samples", type=_positive(int, 10**7), default=2000,
                   help="reference run length (default 2000)")
    b.add_argument("--repeat", type=_positive(int, 1000), default=3)
    b.set_defaults(func=_bench)


# ---------------------------------------------------------------------------
# validate

def _validate(args):
    cls = reference_class(args.filter) if not _entry(args.filter).fixed else \
        _entry(args.filter).reference
    overrides = _pairs(args.param)
    check_outputs([args.log, *(args.sources or ()), *_headers(args)], [("--plot", args.plot)])
    defines = {}
    for d in args.define or ():
        k, _, v = d.partition("=")
        defines[k] = v if v else None
    cflags = args.cflags.split() if args.cflags is not None else None
    if args.csrc:
        if not os.path.isdir(args.csrc):
            raise LogError(f"--csrc {args.csrc}: no such directory", "file")
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
    if _entry(args.filter).fixed:
        inputs = counts_for(cls.kind, params, inputs)
        src += f"; int16 counts (gyr_scale {params['gyr_scale']:g} rad/s, acc 4096 per g)"
    v = validate_isolated(fw, args.filter, params, inputs, backend=args.backend, dtype=args.dtype,
                          timeout=args.timeout, target=args.target)
    print(f"inputs: {src}; {args.filter} "
          f"{', '.join(f'{k}={val}' for k, val in params.items())}")
    print(v.text())
    if args.plot:
        if not plots.available():
            _err("plots unavailable: matplotlib is not installed (pip install 'imufuse[plot]')")
        else:
            try:
                plots.plot_divergence(args.plot, t, v.got, v.want, v.comparison.names,
                                      v.comparison.first_sample,
                                      f"firmware vs imufuse {args.filter} ({v.comparison.dtype})")
            except OSError as e:
                raise OutputError(f"--plot {args.plot}: cannot write: {e.strerror or e}") from None
            _err(f"plot: {args.plot}")
    return EXIT_OK if v.bit_exact else EXIT_FAIL


def _parser_validate(sub):
    v = sub.add_parser("validate", help="compile firmware C (for the host, or for an emulated "
                       "MCU with your flags) and compare it with an imufuse filter bit for "
                       "bit", formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Validate firmware filter code against imufuse (see "
                       "imufuse.firmware).\nThe firmware runs in a child process: a crash, exit() "
                       "or hang is reported (exit 5).\n\nexample:\n  imufuse validate fw/att.c -I fw "
                       "--header att.h --filter Kalman1D \\\n     --init 'void att_init(att_t *s, "
                       "float dt, float k0)' \\\n     --update 'void att_update(att_t *s, float rate, "
                       "float angle)' \\\n     --state theta=x.theta --param k0=0.01\n"
                       "  imufuse validate --csrc --filter Kalman1D --dtype float32\n"
                       "  imufuse validate fw/cf.c --header cf.h --filter Complementary1D "
                       "--init cf_init \\\n     --update cf_update --state theta=theta "
                       "--target cortex-m4f --cflags '-O2 -ffp-contract=off'")
    v.add_argument("sources", nargs="*", metavar="SOURCE.c")
    v.add_argument("--filter", "-f", required=True, help="the imufuse filter to compare with", type=canonical_name)
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
    v.add_argument("--target", choices=target_names(), default="host",
                   help="where the firmware runs: host (cffi, this machine) or an emulated MCU "
                        "built with its cross compiler and your --cflags: cortex-m4f (QEMU "
                        "mps2-an386), cortex-m0 (QEMU microbit), atmega328p (simavr). The report "
                        "adds the cause of a divergence and the cost per update")
    v.add_argument("--cflags", metavar="FLAGS",
                   help="your compiler flags (the target adds only -mcpu/-mfpu/-mfloat-abi or "
                        "-mmcu); default '-std=c99 -O2 -ffp-contract=off' on the host, '-O2' on "
                        "an MCU target (the compiler's default standard, as a firmware build)")
    v.add_argument("--param", "-p", action="append", metavar="NAME=VALUE")
    v.add_argument("--dtype", choices=("float32", "float64"),
                   help="precision (default: the firmware's, from sizeof of its state)")
    v.add_argument("--backend", choices=("c", "ref"), default="c")
    v.add_argument("--timeout", type=_positive(float, 1e6), default=DEFAULT_TIMEOUT, metavar="S",
                   help=f"seconds the firmware may run (default {DEFAULT_TIMEOUT:g})")
    v.add_argument("--log", metavar="LOG", help="inputs from a log (default: simulated)")
    v.add_argument("--gyr-unit", choices=("rad/s", "deg/s"))
    v.add_argument("--acc-unit", choices=("g", "m/s2", "m/s^2"))
    v.add_argument("--axis", choices=("x", "y"), default="x")
    v.add_argument("--rate", type=_positive(float, 1e9, 1e-3), metavar="HZ")
    v.add_argument("--duration", type=_positive(float, 1e5), default=10.0)
    v.add_argument("--seed", type=int, default=1)
    v.add_argument("--plot", metavar="PNG", help="divergence plot")
    v.set_defaults(func=_validate, fixed_rate=True)


# ---------------------------------------------------------------------------
# export

def _export(args):
    lib = export_arduino(args.dir, make_zip=args.zip)
    print(f"Arduino library: {lib}")
    if args.zip:
        print(f"zip for the IDE (Sketch > Include Library > Add .ZIP Library): "
              f"{lib.parent / f'imufuse-{__version__}.zip'}")
    return EXIT_OK


def _parser_export(sub):
    e = sub.add_parser("export", help="write the C library in a form firmware projects take",
                       description="imufuse export arduino DIR: an Arduino library in DIR/imufuse "
                       "(library.properties, src/, keywords.txt, example sketches for an Uno and "
                       "ARM boards); --zip also writes DIR/imufuse-VERSION.zip for the Arduino "
                       "IDE's 'Add .ZIP Library'. See docs/firmware.md.")
    e.add_argument("what", choices=("arduino",))
    e.add_argument("dir", metavar="DIR")
    e.add_argument("--zip", action="store_true", help="also write the .zip the IDE installs")
    e.set_defaults(func=_export)


# ---------------------------------------------------------------------------
# options shared by several subcommands

def _positive(typ, hi, lo=0):
    def conv(text):
        try:
            v = typ(text)
        except (ValueError, OverflowError):
            raise argparse.ArgumentTypeError(f"expected a {typ.__name__}, got {text!r}") from None
        if not (v > 0 and lo <= v <= hi) or (typ is float and not math.isfinite(v)):
            raise argparse.ArgumentTypeError(f"must be in [{lo:g}, {hi:g}] and > 0, got {text}")
        return v
    conv.__name__ = typ.__name__
    return conv


def _nonneg_int(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if not 0 <= v <= 100:
        raise argparse.ArgumentTypeError(f"must be 0..100, got {v}")
    return v


def _log_options(p):
    g = p.add_argument_group("log")
    g.add_argument("--gyr-unit", choices=("rad/s", "deg/s"),
                   help="unit of gyr_x..z (default: from the header, else rad/s)")
    g.add_argument("--acc-unit", choices=("g", "m/s2", "m/s^2"),
                   help="unit of acc_x..z (default: from the header, else g)")
    g.add_argument("--time-unit", choices=("s", "ms", "us", "ns"),
                   help="unit of the time column (default: from the header, else s)")
    g.add_argument("--columns", "-c", action="append", metavar='NAME="HEADER",...',
                   help='name the log\'s columns, e.g. gyr_x="Gyro X",acc_x="Acc X" (repeatable)')
    g.add_argument("--column-map", metavar="FILE",
                   help="a file of NAME = HEADER lines (or a JSON object) naming the columns")
    g.add_argument("--rate", type=_positive(float, 1e9, 1e-3), metavar="HZ",
                   help="fixed sample rate, Hz (default: the time column's intervals)")
    g.add_argument("--fixed-rate", action="store_true",
                   help="run at the median interval of the time column instead of each "
                        "sample's own interval")
    g.add_argument("--axis", choices=("x", "y"), default="x",
                   help="single-axis filters without rate/angle columns: x = roll from gyr_x and "
                        "atan2(acc_y, acc_z); y = pitch from gyr_y and atan2(-acc_x, acc_z)")


def _filter_options(p):
    g = p.add_argument_group("filter")
    g.add_argument("--param", "-p", action="append", metavar="NAME=VALUE",
                   help="filter parameter (repeatable); dt comes from the log")
    g.add_argument("--init", metavar="first|identity|W,X,Y,Z",
                   help="initial orientation of 3D filters (default first: from the first "
                        "accelerometer [and magnetometer] sample)")
    g.add_argument("--init-window", type=_positive(int, 10**6), metavar="N",
                   help="with --init first: average the first N samples (default 1)")
    g.add_argument("--dtype", choices=("float32", "float64"), default="float64")
    g.add_argument("--backend", choices=("c", "ref"), default="c",
                   help="c: imufuse_c (compiled); ref: imufuse.reference (pure Python)")


def _eval_options(p):
    g = p.add_argument_group("reference and output frames")
    g.add_argument("--ref-frame", choices=("NWU", "ENU", "NED"),
                   help="earth frame of the log's q_w..q_z (default: NWU; ENU for BROAD files)")
    g.add_argument("--ref-direction", choices=("sensor-to-earth", "earth-to-sensor"),
                   default="sensor-to-earth", help="what the reference quaternion rotates")
    g.add_argument("--skip", type=_positive(float, 1e9), metavar="S",
                   help="leave the first S seconds out of the errors (the start-up), on top of "
                        "a movement column")
    g.add_argument("--heading-offset", action="store_true",
                   help="remove the mean heading offset between the reference and the filter "
                        "before the heading and total errors")
    g.add_argument("--frame", choices=("NWU", "ENU", "NED"), default="NWU",
                   help="earth frame of the output quaternion and Euler angles (default NWU); "
                        "the sensor axes stay as logged (a z-up sensor in NED reads roll 180 "
                        "deg when level: align the axes first with --align)")


def _latency(args):
    delays = []
    for path in args.logs:
        log = _load(args, path)
        if log.q_ref is None:
            raise NothingComputed(f"{log.path}: no reference orientation (q_w..q_z): nothing to "
                                  "time the gyroscope against")
        require(log, GYR)
        t = log.t if log.dts is not None else None
        try:
            d = estimate_latency(log.gyr, log.q_ref, None if t is not None else log.dt, t=t,
                                 ref_direction=args.ref_direction, max_delay=args.max_delay)
        except ValueError as e:
            raise NothingComputed(f"{log.path}: {e}") from None
        delays.append(d)
        how = "lags" if d >= 0 else "leads"
        print(f"{log.path}: the gyroscope {how} the reference by {abs(d) * 1e3:.2f} ms")
    d = float(np.mean(delays))
    if len(delays) > 1:
        print(f"mean over {len(delays)} logs: {d * 1e3:.2f} ms "
              f"({min(delays) * 1e3:.2f} to {max(delays) * 1e3:.2f})")
    if 0.0 <= d <= 0.1:
        print(f"RobustIMU / RobustAHRS: -p latency={d:.6f} predicts the output by this delay")
    elif d < 0:
        print("the gyroscope leads the reference: latency (>= 0) cannot compensate that; "
              "check the logger's timestamps")
    else:
        print("the delay is beyond latency's range (0 to 0.1 s)")
    return EXIT_OK


def _parser_latency(sub):
    d = sub.add_parser("latency", help="delay of the gyroscope behind a log's reference "
                       "orientation (RobustIMU's latency), from the rates alone")
    d.add_argument("logs", nargs="+", metavar="LOG")
    d.add_argument("--max-delay", type=_positive(float, 1.0), default=0.05, metavar="S",
                   help="search shifts within +-S seconds (default 0.05)")
    d.add_argument("--ref-direction", choices=("sensor-to-earth", "earth-to-sensor"),
                   default="sensor-to-earth", help="what the reference quaternion rotates")
    _log_options(d)
    d.set_defaults(func=_latency)


SUBCOMMANDS = [_parser_demo, _parser_run, _parser_compare, _parser_tune, _parser_latency,
               _parser_bench, _parser_validate, _parser_export]


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.print_usage(sys.stderr)
        self.exit(EXIT_USAGE, f"imufuse: error: {message}\n")


def build_parser():
    p = _Parser(prog="imufuse", description=__doc__,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"imufuse {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for add in SUBCOMMANDS:
        add(sub)
    add_parsers(sub)
    return p


def _join_flag_values(argv):
    """`--cflags -O2` as `--cflags=-O2`: argparse would take a value starting with '-' for an
    option, and compiler flags always start with one."""
    out, it = [], iter(argv)
    for a in it:
        if a == "--cflags":
            nxt = next(it, None)
            out.append(a if nxt is None else f"--cflags={nxt}")
        else:
            out.append(a)
    return out


def main(argv=None):
    p = build_parser()
    try:
        args = p.parse_args(_join_flag_values(sys.argv[1:] if argv is None else list(argv)))
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else EXIT_USAGE
    if not getattr(args, "func", None):
        p.print_help()
        return EXIT_USAGE
    try:
        return args.func(args)
    except LogError as e:
        _err(f"error: {e}")
        return {"file": EXIT_FILE, "usage": EXIT_USAGE}.get(e.kind, EXIT_DATA)
    except NothingComputed as e:
        _err(f"error: {e}")
        return EXIT_DATA
    except FirmwareError as e:
        _err(f"error: {e}")
        return EXIT_FIRMWARE
    except (UsageError, FilterError) as e:
        _err(f"error: {e}")
        return EXIT_USAGE
    except BrokenPipeError:
        # the reader went away (| head): not an error; silence the final flush
        try:
            fd = os.open(os.devnull, os.O_WRONLY)
            os.dup2(fd, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return EXIT_OK
    except OutputError as e:
        _err(f"error: {e}")
        return EXIT_FILE
    except OSError as e:
        _err(f"error: {e.filename + ': ' if e.filename else ''}{e.strerror or e}")
        return EXIT_FILE
    except KeyboardInterrupt:
        _err("interrupted")
        return EXIT_INTERRUPT
    except MemoryError:
        _err("error: out of memory")
        return EXIT_DATA
    except ValueError as e:
        _err(f"error: {e}")
        return EXIT_USAGE
    except Exception as e:  # noqa: BLE001 - the documented last resort, exit 6
        if os.environ.get("IMUFUSE_DEBUG"):
            raise
        msg = " ".join(str(e).split())
        _err(f"internal error: {type(e).__name__}: {msg[:300]} (IMUFUSE_DEBUG=1 shows the "
             "traceback; please report it)")
        return EXIT_INTERNAL
