"""`imufuse run` and `imufuse compare`: filters over a log, through imufuse.session."""
import argparse
import math
import os
import sys

import numpy as np

from .. import io, plots
from .._atomic import check_outputs
from ..catalogue import (FILTERS_FUSION, FilterError, canonical_name, filter_names,
                         reference_class)
from ..io import ACC, GYR, MAG, LogError, axis_inputs
from ..rotations import quat_to_euler
from ..session import FUSION, NothingComputed, StrictError, format_params, frame_q
from .common import (EXIT_OK, OutputError, UsageError, err, eval_options, filter_options,
                     input_files, log_options, names, open_session, pairs,
                     preprocess_options, progress,
                     run_options, score_options, scoped_params, write_output)


def _check_name(name):
    if name == "FusionOffset":
        raise UsageError("FusionOffset is the --offset option (in front of any filter), not a "
                         "filter")
    if name != FUSION and name in FILTERS_FUSION:
        raise UsageError(f"{name}: not a filter of imufuse run/compare")


def _hint(session, run, ev, sc, strict):
    hint = session.frame_hint(run, ev, sc)
    if hint and strict:
        raise StrictError(f"{session.log.path}: {hint.removeprefix('hint: ')} (--strict)")
    return hint


def _run(args):
    _check_name(args.filter)
    check_outputs(input_files(args), [("-o", args.output), ("--plot", args.plot)])
    s = open_session(args)
    ro, sc = run_options(args), score_options(args)
    n = len(s.log)
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


def _default_filters(log):
    """3D filters the log can feed (AHRS ones only with a magnetometer) and FusionAHRS, else
    the 1D ones."""
    if log.has(*GYR, *ACC):
        return filter_names({"imu", "ahrs"} if log.has(*MAG) else {"imu"}) + [FUSION]
    return filter_names({"1d"})


def compare(args):
    chosen = names(args.filters)
    for n in chosen:
        _check_name(n)
        if n != FUSION:
            reference_class(n)
    check_outputs(input_files(args), [("--plot", args.plot)])
    s = open_session(args)
    log = s.log
    chosen = chosen or _default_filters(log)
    per = scoped_params(args.param, chosen)
    ro, sc = run_options(args), score_options(args)
    rows, runs, timing, hint, computed = [], {}, None, None, 0
    for n in chosen:
        kind = s.filter_class(n).kind
        try:
            # only the estimate is kept: memory is bounded by the log, not the trajectory
            r = s.run(n, per[n], ro, progress=progress, keep_states=False)
        except LogError as e:
            if isinstance(e, StrictError):
                raise
            rows.append((n, kind, None, None, None, f"skipped: {str(e).split(': ', 1)[-1]}"))
            continue
        except FilterError as e:
            rows.append((n, kind, None, None, None, f"skipped: {e}"))
            continue
        timing = timing or r.time
        sps = len(log) / max(r.seconds, 1e-9)
        note = r.why()
        if 0 < r.rejected < len(log):
            note += f"; {r.rejected} of {len(log)} samples rejected"
        if r.notes:
            note += "; " + "; ".join(r.notes)
        est = r.estimate
        final = None
        if est is not None:
            computed += 1
            if est.angle is not None:
                final = np.array([np.degrees(est.angle[-1]), np.nan, np.nan])
            else:
                final = np.degrees(quat_to_euler(frame_q(est.q[-1:], sc.frame))[0])
                if not est.heading:
                    final[2] = np.nan
        ev = s.score(r, sc, axis=ro.axis)
        hint = hint or _hint(s, r, ev, sc, args.strict)
        if est is not None and args.plot:      # the estimates are kept for the plot only
            runs[n] = r
        rows.append((n, kind, ev, final, sps, note))
    if not computed:
        for n, _kind, _, _, _, note in rows:
            err(f"{n}: {note}")
        raise NothingComputed(f"{log.path}: no filter could run on this log ({len(log)} samples; "
                              f"columns found: {', '.join(map(repr, log.header))})")
    has_ref = log.q_ref is not None
    print(f"{log.path}: {len(log)} samples, {timing}, {ro.backend} {ro.dtype}; "
          + (f"errors against the log's q_w..q_z ({s.ref_frame(sc)}, {sc.ref_direction}), "
             "degrees RMS (BROAD definitions: e = q (x) r^-1 in the earth frame)" if has_ref
             else f"no reference orientation in the log (q_w..q_z): final attitude shown "
                  f"({sc.frame})"))
    evaluated = _table(rows, has_ref, args.heading_offset)
    if hint:
        err(hint)
    if args.plot:
        given = ", ".join(args.param) if args.param else "default gains"
        _plots(args.plot, s, runs, args, f"{', '.join(runs)} ({given}; {timing}, init "
                                         f"{getattr(args, 'init', None) or 'first'})")
    if has_ref and not evaluated:
        raise NothingComputed(f"{log.path}: nothing could be evaluated: no sample has a finite "
                              "reference inside the movement mask")
    return EXIT_OK


def _table(rows, has_ref, heading_offset):
    """Print compare's table; the number of filters evaluated."""
    if has_ref:
        head = (f"{'filter':22s} {'kind':4s} {'incl/angle':>10s} {'heading':>9s} {'total':>9s} "
                f"{'samples':>8s} {'samples/s':>10s}  estimate from")
    else:
        head = (f"{'filter':22s} {'kind':4s} {'final roll/angle  pitch    yaw':>31s} "
                f"{'samples/s':>10s}  estimate from")
    print(head)
    print("-" * len(head))
    evaluated, excluded = 0, None

    def f(v, w):
        return f"{'-':>{w}s}" if math.isnan(v) else f"{v:{w}.3f}"
    for n, kind, ev, final, sps, note in rows:
        sp = f"{sps:10.3g}" if sps else f"{'-':>10s}"
        if not has_ref:
            fs = "-" if final is None else "  ".join(
                f"{'-':>7s}" if np.isnan(v) else f"{v:7.2f}" for v in final)
            print(f"{n:22s} {kind:4s} {fs:>31s} {sp}  {note}")
            continue
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
            if heading_offset and kind == "ahrs":
                note += f"; heading offset {ev.heading_offset:.2f} deg removed"
        evaluated += cnt > 0
        print(f"{n:22s} {kind:4s} {f(m, 10)} {f(h, 9)} {f(t, 9)} {cnt:8d} {sp}  {note}")
    if excluded is not None and (excluded.n_ref_nan or excluded.n_outside_mask):
        print(f"excluded: {excluded.n_outside_mask} samples outside the movement mask, "
              f"{excluded.n_ref_nan} with a NaN reference")
    return evaluated


def _plots(path, s, runs, args, what):
    """Estimates and errors against the reference, in the output frame (--frame)."""
    if not plots.available():
        err("plots unavailable: matplotlib is not installed (pip install 'imufuse[plot]')")
        return
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
            errors = None
            if log.q_ref is not None:
                errors = {}
                for n, r in three.items():
                    ev = s.score(r, sc, per_sample=True)
                    errors[n] = ev.per_sample["total" if r.estimate.heading else "inclination"]
            series = {}
            for n, r in three.items():
                e = quat_to_euler(frame_q(r.estimate.q, sc.frame))
                if not r.estimate.heading:
                    e[:, 2] = np.nan
                series[n] = e
            plots.plot_euler(p3, log.t, series, s.reference_euler(sc), title=title,
                             errors=errors, frame=sc.frame,
                             error_label="error (deg): total (AHRS), inclination (IMU)")
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

    c = sub.add_parser("compare", help="several filters on one log: error table (BROAD metrics "
                       "when the log has a reference orientation) and plot")
    c.add_argument("log", metavar="LOG")
    c.add_argument("--filter", "-f", dest="filters", action="append", metavar="NAME[,NAME]",
                   help="filters to compare (default: every 3D filter the log can feed, "
                        "FusionAHRS included, or the single-axis ones when there are none); "
                        "--param FILTER.NAME=V sets one filter's parameter")
    c.add_argument("--plot", metavar="PNG")
    log_options(c)
    filter_options(c)
    eval_options(c)
    preprocess_options(c)
    c.set_defaults(func=compare)
