"""`imufuse run` and `imufuse compare`: filters over a log, through imufuse.session."""
import argparse
import difflib
import math
import os
import sys

import numpy as np

from .. import io, plots
from ..shared.atomic import check_outputs
from ..catalogue import FILTERS, FILTERS_FIXED, FILTERS_FUSION, canonical_name
from ..comparison import compare_logs, default_filters, log_paths
from ..io import axis_inputs
from ..rotations import quat_to_euler
from ..session import FUSIONS, NothingComputed, StrictError, format_params, frame_q
from .common import (EXIT_OK, OutputError, UsageError, err, eval_options, executor,
                     executor_spec, filter_options, input_files, log_options, names,
                     open_session, pairs, plot_available, preprocess_options, progress,
                     read_options, run_options, score_options, scoped_params, write_output)

#: the filters run and compare take: the float filters and Fusion's AHRS (1.2.3, 1.3)
VALID = (*FILTERS, *FUSIONS)


def suggestions(name, valid=VALID):
    """The valid names a mistyped one may mean: those it begins (any case: 'fusion' ->
    FusionAHRS, 'madgwick' -> MadgwickIMU, MadgwickAHRS), then the close ones."""
    low = str(name).lower()
    lower = {n.lower(): n for n in valid}
    pre = [n for n in valid if len(low) >= 3 and n.lower().startswith(low)]
    close = [lower[c] for c in difflib.get_close_matches(low, lower, n=3, cutoff=0.5)]
    return list(dict.fromkeys(pre + close))[:4]


def _check_name(name):
    """UsageError for a name run and compare do not take, naming the valid ones (FusionAHRS
    included) and the ones it may mean."""
    if name in VALID:
        return
    valid = f"valid filters: {', '.join(VALID)}"
    if name == "FusionOffset":
        raise UsageError("FusionOffset is the --offset option (in front of any filter), not a "
                         "filter")
    if name in FILTERS_FUSION:
        raise UsageError(f"{name}: not a filter of imufuse run/compare; {valid}")
    if name in FILTERS_FIXED:
        raise UsageError(f"{name}: a fixed-point filter (run and compare take the float "
                         f"filters); {valid}")
    close = suggestions(name)
    raise UsageError(f"unknown filter {name!r}"
                     + (f" (did you mean {', '.join(close)}?)" if close else "") + f"; {valid}")


def _hint(session, run, ev, sc, strict):
    hint = session.frame_hint(run, ev, sc)
    if hint and strict:
        raise StrictError(f"{session.log.path}: {hint.removeprefix('hint: ')} (--strict)")
    return hint


def _run(args):
    _check_name(args.filter)
    check_outputs(input_files(args), [("-o", args.output), ("--plot", args.plot)])
    plot_available(args.plot)
    s = open_session(args)
    ro, sc = run_options(args), score_options(args)
    n = len(s.log)
    if s.log.q_ref is not None:
        s.mask(sc)              # a --skip past the log's end: said before anything is written
    if args.plot or args.output.lower().endswith(".npz"):
        r = s.run(args.filter, pairs(args.param), ro, progress=progress)
        _all_rejected(s, args, r)
        cols, notes = r.columns(s.log.t, sc.frame)
        write_output(args.output, cols, r.float32_columns())
    else:
        r, notes = _run_streamed(s, args, ro, sc)
    for note in notes:
        err(f"note: {note}")
    err(r.describe(n) + (f" -> {args.output}" if args.output != "-" else ""))
    for note in r.notes:
        err(f"note: {note}")
    if r.rejected:
        err(f"note: {r.rejected} of {n} samples rejected by {args.filter} (non-finite values, "
            "or updates it cannot make): the state was kept through them")
    ev = s.score(r, sc, axis=ro.axis)
    if ev is not None:
        if isinstance(ev, dict):
            err(f"against the log's reference q: angle RMS {ev['angle'][0]:.3f} max "
                f"{ev['angle'][1]:.3f} deg over {ev['n']} samples")
        else:
            err(f"against the log's reference q ({s.ref_frame(sc)}): {ev.summary()}")
            hint = _hint(s, r, ev, sc, args.strict)
            if hint:
                err(hint)
    if args.plot:
        _plots(args.plot, s, {args.filter: r}, args,
               f"{args.filter} ({format_params(args.filter, r.params)})")
    return EXIT_OK


def _all_rejected(s, args, r):
    if r.rejected == len(s.log):
        raise NothingComputed(f"{s.log.path}: {args.filter} rejected every one of the "
                              f"{len(s.log)} samples (non-finite values, or updates it cannot "
                              "make): nothing was estimated")


def _run_streamed(s, args, ro, sc):
    """`imufuse run` to CSV, block by block: the rows of each block written as it is run,
    only the estimate kept (for the errors): memory does not grow with the trajectory. The
    file is written whole or not at all (nothing when every sample was rejected)."""
    notes = []
    t = s.log.t
    path = sys.stdout if args.output == "-" else args.output
    f32 = set(s.filter_class(args.filter).state_names) if ro.dtype == "float32" else set()
    try:
        with io.CsvBlocks(path, f32) as out:
            def block(part, k):
                cols, said = part.columns(t[k:k + len(part.states)], sc.frame)
                if not notes:
                    notes.extend(said)
                out.add(cols)
            r = s.run(args.filter, pairs(args.param), ro, progress=progress, keep_states=False,
                      on_block=block)
            _all_rejected(s, args, r)
    except OSError as e:
        if isinstance(e, BrokenPipeError):
            raise
        raise OutputError(f"-o {args.output}: cannot write: {e.strerror or e}") from None
    return r, notes


def compare(args):
    """`imufuse compare LOG...`: every log's table (one log at a time, each filter keeping
    only its estimate), then the mean over the logs when there are several."""
    chosen = names(args.filters)
    for n in chosen:
        _check_name(n)
    paths = log_paths(args.logs)
    check_outputs([*paths, args.column_map, args.calibration], [("--plot", args.plot)])
    plot_available(args.plot)
    ro, sc = run_options(args), score_options(args)
    many = len(paths) > 1
    first = [open_session(args, paths[0])]
    chosen = chosen or default_filters(first[0].log)
    per = scoped_params(args.param, chosen)

    def sessions():
        yield first.pop()                    # the first log is let go when the second is read
        for p in paths[1:]:
            yield open_session(args, p)

    shown = []

    def show(res):
        if shown:
            print()
        shown.append(res.path)
        _show_log(res, ro, sc)
        if args.plot and not many and res.computed:
            runs = {n: r.run for n, r in res.results.items() if r.run is not None}
            given = ", ".join(args.param) if args.param else "default gains"
            _plots(args.plot, res.session, runs, args,
                   f"{', '.join(runs)} ({given}; {res.time}, init "
                   f"{getattr(args, 'init', None) or 'first'})")

    if args.executor and many:
        # every log but the first read where the executor runs it: their notes are printed
        # as their results come back, in the order of the logs
        def show_with_notes(res):
            if res.path != paths[0]:
                for note in res.notes:
                    err(f"note: {res.path}: {note}")
            show(res)
        with executor(args.executor) as ex:
            c = compare_logs([first[0], *paths[1:]], chosen, per, read=read_options(args),
                             run=ro, score=sc, on_log=show_with_notes, executor=ex)
    else:
        c = compare_logs(sessions(), chosen, per, run=ro, score=sc, progress=progress,
                         on_log=show, keep_runs=bool(args.plot) and not many)
    if many:
        _means(c, args)
    return EXIT_OK


def _show_log(res, ro, sc):
    """One log's lines: its table (or why no filter ran) and a frame hint."""
    if not res.computed:
        for n, r in res.results.items():
            err(f"{n}: {r.note}")
        return
    print(f"{res.path}: {res.samples} samples, {res.time}, {ro.backend} {ro.dtype}; "
          + (f"errors against the log's q_w..q_z ({res.ref_frame}, {sc.ref_direction}), "
             "degrees RMS (BROAD definitions: e = q (x) r^-1 in the earth frame)"
             if res.has_reference
             else f"no reference orientation in the log (q_w..q_z): final attitude shown "
                  f"({sc.frame})"))
    _table(res.results.values(), res.has_reference)
    if res.hint:
        err(res.hint)


def _table(results, has_ref):
    """Print compare's table of one log."""
    if has_ref:
        head = (f"{'filter':22s} {'kind':4s} {'incl/angle':>10s} {'heading':>9s} {'total':>9s} "
                f"{'samples':>8s} {'samples/s':>10s}  estimate from")
    else:
        head = (f"{'filter':22s} {'kind':4s} {'final roll/angle  pitch    yaw':>31s} "
                f"{'samples/s':>10s}  estimate from")
    print(head)
    print("-" * len(head))
    excluded = None
    for r in results:
        n, kind, ev, note = r.name, r.kind, r.evaluation, r.note
        sp = f"{r.samples_per_second:10.3g}" if r.samples_per_second else f"{'-':>10s}"
        if not has_ref:
            fs = "-" if r.final is None else "  ".join(
                f"{'-':>7s}" if np.isnan(v) else f"{v:7.2f}" for v in r.final)
            print(f"{n:22s} {kind:4s} {fs:>31s} {sp}  {note}")
            continue
        if ev is None:
            print(f"{n:22s} {kind:4s} {'-':>10s} {'-':>9s} {'-':>9s} {'-':>8s} {sp}  {note}")
            continue
        m, h, t = _errors(kind, ev)
        if not isinstance(ev, dict):
            excluded = ev
        print(f"{n:22s} {kind:4s} {_num(m, 10)} {_num(h, 9)} {_num(t, 9)} {r.counted():8d} "
              f"{sp}  {note}")
    if excluded is not None and (excluded.n_ref_nan or excluded.n_outside_mask):
        print(f"excluded: {excluded.n_outside_mask} samples outside the movement mask, "
              f"{excluded.n_ref_nan} with a NaN reference")


def _num(v, w):
    return f"{'-':>{w}s}" if math.isnan(v) else f"{v:{w}.3f}"


def _errors(kind, ev):
    """(inclination or angle, heading, total) as the table shows them: a 6-DOF filter's
    inclination only."""
    if isinstance(ev, dict):
        return ev["angle"][0], math.nan, math.nan
    if kind != "ahrs":
        return ev.inclination, math.nan, math.nan
    return ev.inclination, ev.heading, ev.total


def _means(c, args):
    """The mean over the logs of each filter's RMS errors (BROAD's mean over trials), and
    the bar chart of every log's errors (--plot)."""
    means = c.means()
    n = len(c.logs)
    print(f"\nmean over {n} logs of each log's RMS error (as BROAD reports its trials), "
          "degrees")
    head = (f"{'filter':22s} {'kind':4s} {'incl/angle':>10s} {'heading':>9s} {'total':>9s} "
            f"{'logs':>5s}")
    print(head)
    print("-" * len(head))
    for name, m in means.items():
        kind = c.kind(name)
        if "angle" in m:
            row = (m["angle"], math.nan, math.nan)
        elif kind != "ahrs":
            row = (m["inclination"], math.nan, math.nan)
        else:
            row = (m["inclination"], m["heading"], m["total"])
        k = c.counted(name)
        print(f"{name:22s} {kind:4s} {_num(row[0], 10)} {_num(row[1], 9)} {_num(row[2], 9)} "
              f"{k:5d}" + (f"  ({n - k} of {n} logs without errors: left out)" if k < n else ""))
    if args.plot:
        _bars(args.plot, c, means)


def _bars(path, c, means):
    """Every log's RMS errors as bars, the mean last (matplotlib)."""
    errors = {"inclination / angle": {}, "total": {}}
    mean = {"inclination / angle": {}, "total": {}}
    for name, m in means.items():
        kind = c.kind(name)
        rows = [lg.results.get(name) for lg in c.logs]
        vals = [_errors(kind, r.evaluation) if r is not None and r.counted() else
                (math.nan,) * 3 for r in rows]
        errors["inclination / angle"][name] = [v[0] for v in vals]
        mean["inclination / angle"][name] = m.get("angle", m.get("inclination"))
        if kind == "ahrs":
            errors["total"][name] = [v[2] for v in vals]
            mean["total"][name] = m["total"]
    try:
        plots.plot_recordings(path, [lg.path for lg in c.logs], errors, mean,
                              title=f"RMS errors on {len(c.logs)} logs and their mean")
    except OSError as e:
        raise OutputError(f"--plot {path}: cannot write: {e.strerror or e}") from None
    err(f"plot: {path}")


def _own_start(log, r):
    """The first sample a plot draws of a filter's angles: FusionAHRS takes no init, starts
    from the identity and turns to the sensor's attitude while `initialising` (its gain
    ramped down from 10 over 3 s of dt; none with gain 0): from the sample that clears it
    (its state, or 3 s of dt when compare kept only the estimate); the others from 0."""
    if r.name not in FUSIONS:
        return 0
    names = list(r.cls.state_names)
    flag = "initialising" if "initialising" in names else "startup"      # 1.2.3, 1.3
    if len(r.states) and flag in names:
        done = np.flatnonzero(r.states[:, names.index(flag)] == 0)
        return int(done[0]) if done.size else len(log)
    if float(r.params.get("gain", 0.5)) == 0.0:
        return 0
    dts = log.dts if log.dts is not None else np.full(len(log), log.dt)
    return int(np.searchsorted(np.cumsum(dts), 3.0, side="right"))


def _plots(path, s, runs, args, what):
    """Estimates and errors against the reference, in the output frame (--frame)."""
    sc, axis = score_options(args), getattr(args, "axis", "x")
    log = s.log
    one = {n: r.estimate.angle for n, r in runs.items() if r.estimate.angle is not None}
    three = {n: r for n, r in runs.items() if r.estimate.q is not None}
    base, ext = os.path.splitext(path)
    p1, p3 = (f"{base}_1d{ext}", f"{base}_3d{ext}") if one and three else (path, path)
    title = f"{os.path.basename(log.path)}: {what}"
    try:
        if one:
            plots.plot_1d(p1, log.t, s.reference_angle(axis, sc), one,
                          axis_inputs(log, axis)[1], title=title)
            err(f"plot: {p1}")
        if three:
            # one quantity per panel: inclination for every filter, heading and total for
            # the AHRS filters
            errors = {}
            if log.q_ref is not None:
                errors = {"inclination": {}, "heading": {}, "total": {}}
                for n, r in three.items():
                    ev = s.score(r, sc, per_sample=True)
                    for m in ("inclination", "heading", "total") if r.estimate.heading \
                            else ("inclination",):
                        errors[m][n] = ev.per_sample[m]
            series = {}
            for n, r in three.items():
                e = quat_to_euler(frame_q(r.estimate.q, sc.frame))
                if not r.estimate.heading:
                    e[:, 2] = np.nan
                series[n] = e
            plots.plot_euler(p3, log.t, series, s.reference_euler(sc), title=title,
                             errors=errors, frame=sc.frame,
                             starts={n: (_own_start(log, r), "its start-up from the identity")
                                     for n, r in three.items()})
            err(f"plot: {p3}")
    except OSError as e:
        raise OutputError(f"--plot {path}: cannot write: {e.strerror or e}") from None


def add_parsers(sub):
    r = sub.add_parser("run", help="one filter over a log -> CSV of states, quaternion, Euler "
                       "angles", formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Run one filter over a log (see imufuse.io for the formats).\n"
                       "Output columns: time, the filter's state, then what can be derived:\n"
                       "angle_deg (single-axis), or [q_w..q_z when the state is not already the\n"
                       "quaternion,] roll_deg, pitch_deg[, yaw_deg]. OUT.npz writes NumPy arrays.\n"
                       "FusionAHRS adds its outputs (earth and linear acceleration, errors,\n"
                       "recovery flags).")
    r.add_argument("log", metavar="LOG")
    r.add_argument("--filter", "-f", required=True, type=canonical_name)
    r.add_argument("-o", "--output", default="-", metavar="OUT.csv", help="default: stdout")
    r.add_argument("--plot", metavar="PNG")
    log_options(r)
    filter_options(r)
    eval_options(r)
    preprocess_options(r)
    r.set_defaults(func=_run)

    c = sub.add_parser("compare", help="several filters on one log or many: error table (BROAD "
                       "metrics when the log has a reference orientation; the mean over the "
                       "logs) and plot")
    c.add_argument("logs", nargs="+", metavar="LOG",
                   help="a log, or several (files, folders of logs, glob patterns): each "
                        "log's table, then the mean over the logs of each filter's RMS errors")
    c.add_argument("--filter", "-f", dest="filters", action="append", metavar="NAME[,NAME]",
                   help="filters to compare (default: every 3D filter the (first) log can "
                        "feed and x-io Fusion's current release (FusionAHRS13; FusionAHRS, its 1.2.3 "
                        "port, when named), or the single-axis ones when there are "
                        "none); "
                        "--param FILTER.NAME=V sets one filter's parameter")
    c.add_argument("--plot", metavar="PNG",
                   help="one log: estimates and errors over time; several: every log's RMS "
                        "errors as bars (matplotlib)")
    c.add_argument("--executor", metavar="SPEC", type=executor_spec,
                   help="compare the logs in an executor, each read where it runs: "
                        "processes[:N], dask:ADDRESS (a dask.distributed scheduler) or "
                        "dask-local[:N] (see imufuse tune --help)")
    log_options(c)
    filter_options(c)
    eval_options(c)
    preprocess_options(c)
    c.set_defaults(func=compare)
