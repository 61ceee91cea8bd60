"""`imufuse tune`: the printing around imufuse.tune.Tuner."""
import argparse
import glob
import os
import sys

from ..catalogue import canonical_name
from ..comparison import log_paths
from ..tune import Tuner, grid_spec
from .common import (EXIT_OK, UsageError, err, eval_options, executor, executor_spec,
                     filter_options, log_options, open_session, pairs, positive, nonneg_int,
                     preprocess_options, read_options, run_options, score_options)


def _tune(args):
    grids, given = [], {}
    fixed = pairs(args.param)
    for g in args.grid or ():
        try:
            k, vals = grid_spec(g)
        except ValueError as e:
            raise UsageError(str(e)) from None
        if k in given:
            raise UsageError(f"--grid {k}: given twice (--grid {given[k]}, --grid {g}); give "
                             f"every value in one --grid {k}=V1,V2,...")
        if k in fixed:
            raise UsageError(f"--grid {k}: {k} is also fixed by --param; give it once")
        grids.append((k, vals))
        given[k] = g
    # files, folders of logs, glob patterns; with an executor a name that is not here is
    # passed on as it is (read where the executor runs it)
    args.logs = [p for x in args.logs for p in (
        log_paths([x]) if not args.executor or os.path.exists(x) or glob.has_magic(x) else [x])]
    try:
        # with an executor, the logs are read where the executor runs them (the first one
        # here too, for the default grid); else here, with their notes
        sessions = ([open_session(args, args.logs[0]), *args.logs[1:]] if args.executor
                    else [open_session(args, p) for p in args.logs])
        t = Tuner(sessions, args.filter, fixed, args.metric, run_options(args),
                  score_options(args), read=read_options(args))
        if not grids:
            # the default grid leaves out what does nothing with these settings (acc_1g with
            # the gate off) without a word: nobody asked for it
            grids = t.default_grid(args.points)
            if not grids:
                raise UsageError(f"tune: no parameter of {args.filter} acts with these "
                                 f"settings ({', '.join(t.idle_out)} do nothing); give --grid")
            if t.left_out:
                err(f"note: the default grid varies the {len(grids)} parameters of "
                    f"{args.filter} whose /10 and x10 move the {t.metric} most on the first log "
                    f"({', '.join(k for k, _ in grids)}); {', '.join(t.left_out)} keep their "
                    "values: give --grid to choose")
        else:
            idle = t.idle(grids, own_values=True)
            if idle:
                err(f"note: --grid {', '.join(idle)}: no effect with these settings (every "
                    "value gives the same result)")
    except ValueError as e:
        if type(e) is ValueError:
            raise UsageError(str(e)) from None
        raise

    def bar(done, total):
        # a bar redrawn with carriage returns: on a terminal only (a file or a pipe would
        # keep every redraw)
        if not args.quiet and sys.stderr.isatty():
            print(f"\rimufuse: tune: [{'#' * (30 * done // total):30s}] {done}/{total}",
                  end="", file=sys.stderr, flush=True)
            if done == total:
                print(file=sys.stderr)
    with executor(args.executor) as ex:
        res = t.search(grids, refine=args.refine, jobs=args.jobs, progress=bar, executor=ex)
    paths = [s.log.path if hasattr(s, "log") else s for s in sessions]
    metric, keys = res.metric, res.names
    print(f"{args.filter} on {len(paths)} log{'s' if len(paths) > 1 else ''}: mean over logs of "
          f"the {metric} RMS (deg); {len(res.results)} parameter sets, best first")
    w = [max(len(os.path.basename(lg)), 8) for lg in paths]
    kw = [max(len(k), 10) for k in keys]
    head = "  ".join(f"{k:>{wi}s}" for k, wi in zip(keys, kw)) + f"  {metric:>11s}" + "".join(
        f"  {os.path.basename(lg):>{wi}s}" for lg, wi in zip(paths, w))
    print(head)
    print("-" * len(head))
    ranked = res.ranked()
    refused = [p for p in res.results if p not in ranked]
    if refused:
        p = refused[0]
        err(f"note: {len(refused)} of {len(res.results)} parameter sets refused by "
            f"{args.filter}, not in the table (e.g. "
            f"{', '.join(f'{k}={v:.4g}' for k, v in zip(keys, p))}: {res.results[p][1]})")
    for p in ranked if args.all else ranked[:args.top]:
        s, evs = res.results[p]
        print("  ".join(f"{v:{wi}.4g}" for v, wi in zip(p, kw)) + f"  {s:11.3f}" + "".join(
            f"  {getattr(e, metric):{wi}.3f}" for e, wi in zip(evs, w))
            + ("  <- best" if p == res.best else ""))
    best = res.best
    print(f"best: {', '.join(f'{k}={v:.4g}' for k, v in zip(keys, best))} "
          f"({metric} {res.score(best):.3f} deg)")
    # a best value at the end of its grid: the best may lie beyond it
    for (k, vals), v in zip(grids, best):
        if len(set(vals)) > 2 and v in (min(vals), max(vals)):
            side = "lowest" if v == min(vals) else "highest"
            err(f"note: the best {k}={v:.4g} is the {side} value of its grid: the best may lie "
                f"{'below' if side == 'lowest' else 'above'} it; extend --grid {k}")
    return EXIT_OK


def add_parsers(sub):
    t = sub.add_parser("tune", help="tune a filter's parameters on logs with a reference "
                       "orientation (grid with refinement, parallel)",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Grid search (then --refine rounds of a finer grid around the "
                       "best point) of a\nfilter's parameters; the score is the mean over the logs "
                       "of the BROAD RMS error\n(--metric). Runs in parallel threads (run() "
                       "releases the GIL). The table is sorted\nby score, best first.\n\n"
                       "example:\n  imufuse tune trial1.npz trial2.npz -f "
                       "MadgwickIMU --grid beta=0.005:1:15")
    t.add_argument("logs", nargs="+", metavar="LOG",
                   help="logs: files, folders of logs, glob patterns (as compare)")
    t.add_argument("--filter", "-f", required=True, type=canonical_name)
    t.add_argument("--grid", "-g", action="append", metavar="NAME=LO:HI:N[lin]|V1,V2,..",
                   help="values of a parameter (repeatable; log-spaced unless 'lin'); default: "
                        "every gain that acts, /10 .. x10 around its default; of more than 3, "
                        "the 3 whose /10 and x10 move the score most on the first log")
    t.add_argument("--points", type=positive(int, 1000), default=9,
                   help="grid points per parameter for the default grid (default 9)")
    t.add_argument("--refine", type=nonneg_int, default=2,
                   help="rounds of a finer grid around the best point (default 2)")
    t.add_argument("--metric", choices=("total", "heading", "inclination"),
                   help="default: total for AHRS, inclination for IMU filters")
    t.add_argument("--jobs", "-j", type=positive(int, 1024), help="threads (default: cores)")
    t.add_argument("--executor", metavar="SPEC", type=executor_spec,
                   help="run each round as one task per log in an executor, where the logs are "
                        "read: processes[:N] (worker processes here), dask:ADDRESS (a "
                        "dask.distributed scheduler, e.g. dask:tcp://10.0.0.5:8786), "
                        "dask-local[:N] (a local dask cluster of N worker processes)")
    t.add_argument("--top", type=positive(int, 10**6), default=15, help="rows shown (default 15)")
    t.add_argument("--all", action="store_true", help="show every parameter set")
    t.add_argument("--quiet", "-q", action="store_true",
                   help="no progress bar (there is none when stderr is not a terminal)")
    log_options(t)
    preprocess_options(t)
    filter_options(t)
    eval_options(t)
    t.set_defaults(func=_tune)
