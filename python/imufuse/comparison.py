"""Filters compared on recordings: what `imufuse compare` runs on one log or on many, and
the mean over recordings as the BROAD benchmark reports it (the mean of each recording's RMS
error: imufuse.evaluation.mean_over_trials).

    from imufuse.comparison import compare_logs
    c = compare_logs(["t1.hdf5", "t2.hdf5", "t3.hdf5"], ["MadgwickAHRS", "RobustAHRS"])
    c.logs[0].results["MadgwickAHRS"].evaluation.total   # one recording's RMS, deg
    c.means()["MadgwickAHRS"]["total"]                   # the mean over the recordings

The logs are read and run one at a time (a log is let go before the next is read), each
filter keeping only its estimate (Session.run(..., keep_states=False)): memory is one log's
and one estimate's, whatever the number of recordings. A log that cannot be read, or on
which no filter runs, or that has a reference but nothing to evaluate, stops the comparison
with its error (LogError, NothingComputed): a mean over fewer recordings than were given
would not be the mean asked for. ``log_paths`` turns files, folders and glob patterns into
the list of logs.
"""
from __future__ import annotations

import concurrent.futures as cf
import glob
import math
import os
from dataclasses import dataclass, field
from typing import (Any, Callable, Dict, Iterable, Iterator, List, Mapping, Optional,
                    Sequence, Union)

import numpy as np

from .catalogue import FUSION_AHRS, FilterError, filter_names
from .evaluation import Evaluation, mean_over_trials
from .io import ACC, GYR, MAG, LogError
from .rotations import quat_to_euler
from .session import (NothingComputed, Progress, ReadOptions, Run, RunOptions,
                      ScoreOptions, Session, StrictError, frame_q)

__all__ = ["compare_logs", "compare_log", "log_paths", "default_filters", "Comparison",
           "LogComparison", "FilterResult", "LOG_EXTENSIONS"]

#: the files a folder given as a log is read for
LOG_EXTENSIONS = (".csv", ".txt", ".tsv", ".npz", ".h5", ".hdf5", ".hdf")


def log_paths(items: Union[str, os.PathLike, Iterable[Union[str, os.PathLike]]]) -> List[str]:
    """The logs named by ``items``: files as they are, a folder's log files (LOG_EXTENSIONS,
    sorted, not its subfolders), a glob pattern's matches (sorted); a file named twice is
    taken once. LogError (kind "file") naming a file that does not exist, a pattern that
    matches nothing, or a folder without logs."""
    if isinstance(items, (str, os.PathLike)):
        items = [items]
    out: List[str] = []
    seen = set()
    for item in items:
        p = os.fspath(item)
        if os.path.isdir(p):
            found = sorted(os.path.join(p, f) for f in os.listdir(p)
                           if f.lower().endswith(LOG_EXTENSIONS)
                           and os.path.isfile(os.path.join(p, f)))
            if not found:
                raise LogError(f"{p}: a folder without logs (no {', '.join(LOG_EXTENSIONS)} "
                               "file in it)", "file")
        elif os.path.exists(p):
            found = [p]
        elif glob.has_magic(p):
            found = sorted(f for f in glob.glob(p) if os.path.isfile(f))
            if not found:
                raise LogError(f"{p}: no file matches", "file")
        else:
            raise LogError(f"{p}: no such file", "file")
        for f in found:
            key = os.path.realpath(f)
            if key not in seen:
                seen.add(key)
                out.append(f)
    if not out:
        raise LogError("no log given", "usage")
    return out


def default_filters(log: Any) -> List[str]:
    """3D filters the log can feed (AHRS ones only with a magnetometer) and x-io Fusion's
    current release (FusionAHRS13; FusionAHRS, the 1.2.3 port, when asked for), else the
    single-axis ones."""
    if log.has(*GYR, *ACC):
        return filter_names(("imu", "ahrs") if log.has(*MAG) else ("imu",)) + [FUSION_AHRS[-1]]
    return filter_names(("1d",))


@dataclass
class FilterResult:
    """One filter on one log: evaluation (imufuse.evaluation.Evaluation for 3D filters, a
    dict {'angle': (rms, max), 'n': n, ...} for single-axis ones; None without a reference
    or without an estimate), final (roll, pitch, yaw in degrees at the last sample, in the
    output frame; NaN where the filter has none), note (where the estimate came from, or
    "skipped: why")."""
    name: str
    kind: str
    evaluation: Union[None, Evaluation, Dict[str, Any]] = None
    final: Optional[np.ndarray] = None
    samples_per_second: Optional[float] = None
    note: str = ""
    run: Optional[Run] = None       # kept with compare_log(..., keep_runs=True) only

    @property
    def skipped(self) -> bool:
        return self.samples_per_second is None

    def counted(self) -> int:
        """The samples its errors count (0 without an evaluation)."""
        ev = self.evaluation
        if ev is None:
            return 0
        return int(ev["n"]) if isinstance(ev, dict) else ev.n


@dataclass
class LogComparison:
    """Every filter on one log. time: how the filters were timed ("dt per sample ..."),
    hint: a frame hint (imufuse.session.Session.frame_hint) of the first filter that gave
    one; problem: why the log counts for nothing (no filter ran, or nothing evaluated), else
    None; session: the log's Session, kept with keep_runs=True only."""
    path: str
    samples: int
    header: List[str]
    has_reference: bool
    ref_frame: str
    results: Dict[str, FilterResult] = field(default_factory=dict)
    time: Optional[str] = None
    hint: Optional[str] = None
    notes: List[str] = field(default_factory=list)
    problem: Optional[str] = None
    session: Optional[Session] = None

    @property
    def computed(self) -> int:
        """The filters that gave an estimate."""
        return sum(1 for r in self.results.values() if r.final is not None)

    @property
    def evaluated(self) -> int:
        """The filters whose errors count at least one sample."""
        return sum(1 for r in self.results.values() if r.counted() > 0)


@dataclass
class Comparison:
    """Filters on several logs: one LogComparison per log, in order."""
    logs: List[LogComparison] = field(default_factory=list)

    def filters(self) -> List[str]:
        """Every filter compared, in the order of first appearance."""
        out: List[str] = []
        for lg in self.logs:
            out += [n for n in lg.results if n not in out]
        return out

    def kind(self, name: str) -> str:
        return next(lg.results[name].kind for lg in self.logs if name in lg.results)

    def evaluations(self, name: str) -> List[Any]:
        """The filter's evaluation on every log that has one, in order."""
        return [lg.results[name].evaluation for lg in self.logs
                if name in lg.results and lg.results[name].evaluation is not None]

    def counted(self, name: str) -> int:
        """The logs whose errors count for the filter's mean (something evaluated)."""
        return sum(1 for lg in self.logs if name in lg.results
                   and lg.results[name].counted() > 0)

    def means(self) -> Dict[str, Dict[str, float]]:
        """{filter: {metric: mean over the logs of its RMS}}: total, heading and inclination
        of the 3D filters (imufuse.evaluation.mean_over_trials: logs that evaluated nothing
        left out), 'angle' of the single-axis ones; NaN when no log counts."""
        out = {}
        for name in self.filters():
            evs = self.evaluations(name)
            if self.kind(name) == "1d":
                vals = [e["angle"][0] for e in evs if e["n"] > 0]
                out[name] = {"angle": float(np.mean(vals)) if vals else math.nan}
            else:
                out[name] = mean_over_trials(evs)
        return out


def _final(est: Any, frame: str) -> np.ndarray:
    if est.angle is not None:
        return np.array([np.degrees(est.angle[-1]), np.nan, np.nan])
    final = np.degrees(quat_to_euler(frame_q(est.q[-1:], frame))[0])
    if not est.heading:
        final[2] = np.nan
    return final


def compare_log(session: Session, filters: Optional[Sequence[str]] = None,
                params: Optional[Mapping[str, Mapping[str, Any]]] = None,
                run: RunOptions = RunOptions(), score: ScoreOptions = ScoreOptions(), *,
                progress: Optional[Progress] = None, keep_runs: bool = False) -> LogComparison:
    """Every filter of ``filters`` (default: `default_filters`) on the session's log, with
    its parameters ``params`` ({filter: {name: value}}), each keeping only its estimate. A
    filter that cannot run on the log is a result with note "skipped: why"; a value of
    ``params`` the filter refuses raises its FilterError. Under the
    session's strict option a frame hint is a StrictError. keep_runs: keep each Run (its
    estimate) and the session, for plots."""
    log = session.log
    names = list(filters) if filters else default_filters(log)
    params = params or {}
    out = LogComparison(os.fspath(log.path), len(log), list(log.header), log.q_ref is not None,
                        session.ref_frame(score), notes=list(session.notes))
    for n in names:
        kind = session.filter_class(n).kind
        try:
            r = session.run(n, params.get(n, {}), run, progress=progress, keep_states=False)
        except LogError as e:
            if isinstance(e, StrictError):
                raise
            out.results[n] = FilterResult(n, kind, note=f"skipped: {str(e).split(': ', 1)[-1]}")
            continue
        except FilterError as e:
            # a value the user gave that the filter refuses is the user's mistake, not the
            # log's: it stops the comparison (the command line's usage error), as `run`
            if any(str(e).startswith(f"{n}: {k}:") for k in params.get(n, {})):
                raise
            out.results[n] = FilterResult(n, kind, note=f"skipped: {e}")
            continue
        out.time = out.time or r.time
        note = r.why()
        if 0 < r.rejected < len(log):
            note += f"; {r.rejected} of {len(log)} samples rejected"
        if r.notes:
            note += "; " + "; ".join(r.notes)
        ev = session.score(r, score, axis=run.axis)
        if ev is not None and not isinstance(ev, dict) and ev.n_est_nan:
            note += f"; {ev.n_est_nan} non-finite estimates"
        if ev is not None and not isinstance(ev, dict) and score.heading_offset \
                and kind == "ahrs":
            note += f"; heading offset {ev.heading_offset:.2f} deg removed"
        hint = session.frame_hint(r, ev, score)
        if hint and session.options.strict:
            raise StrictError(f"{log.path}: {hint.removeprefix('hint: ')} (--strict)")
        out.hint = out.hint or hint
        est = r.estimate
        out.results[n] = FilterResult(
            n, kind, ev, None if est is None else _final(est, score.frame),
            len(log) / max(r.seconds, 1e-9), note, r if keep_runs and est is not None else None)
    if not out.computed:
        out.problem = (f"{log.path}: no filter could run on this log ({len(log)} samples; "
                       f"columns found: {', '.join(map(repr, log.header))})")
    elif out.has_reference and not out.evaluated:
        out.problem = (f"{log.path}: nothing could be evaluated: no sample has a finite "
                       "reference inside the movement mask")
    if keep_runs:
        out.session = session
    return out


def _sessions(logs: Iterable[Union[str, os.PathLike, Session]], read: ReadOptions,
              open_log: Optional[Callable[[str], Session]]) -> Iterator[Session]:
    for item in logs:
        if isinstance(item, Session):
            yield item
        else:
            yield (open_log or (lambda p: Session(p, read)))(os.fspath(item))


def compare_logs(logs: Union[str, os.PathLike, Iterable[Union[str, os.PathLike, Session]]],
                 filters: Optional[Sequence[str]] = None,
                 params: Optional[Mapping[str, Mapping[str, Any]]] = None,
                 read: ReadOptions = ReadOptions(), run: RunOptions = RunOptions(),
                 score: ScoreOptions = ScoreOptions(), *, progress: Optional[Progress] = None,
                 on_log: Optional[Callable[[LogComparison], None]] = None,
                 open_log: Optional[Callable[[str], Session]] = None,
                 keep_runs: bool = False,
                 executor: Optional[cf.Executor] = None) -> Comparison:
    """The filters on every log, one log at a time (`compare_log` on each), and the means
    over them (Comparison.means()). logs: paths (a folder or a glob pattern as well, see
    `log_paths`) or Sessions (a generator of them keeps one log in memory at a time);
    filters: default the `default_filters` of the first log, for every log; read: how to
    read each path (open_log(path) -> Session instead, e.g. to print its notes); on_log:
    called with each log's result as soon as it is done, before a problem is raised.
    Raises the first log's LogError that cannot be read, NothingComputed for a log with
    nothing computed or evaluated (LogComparison.problem). executor: any
    concurrent.futures.Executor (a process pool, dask.distributed's Client.get_executor()):
    each log is read and compared where the executor runs it (the first log is also read
    here when ``filters`` is not given; open_log is then used for it alone), with the
    local run's code and results."""
    if isinstance(logs, (str, os.PathLike)):
        logs = [logs]
    items = list(logs) if isinstance(logs, (list, tuple)) else logs
    if isinstance(items, list) and not any(isinstance(x, Session) for x in items):
        items = log_paths(items)
    out = Comparison()
    chosen = list(filters) if filters else None
    if executor is not None:
        items = list(items)
        if chosen is None and items:
            first = next(_sessions(items[:1], read, open_log))
            chosen = default_filters(first.log)
        futs = [executor.submit(_compare_one, item, read, chosen, params, run, score)
                for item in items]
        for fu in futs:
            res = fu.result()
            out.logs.append(res)
            if on_log is not None:
                on_log(res)
            if res.problem:
                for f in futs:
                    f.cancel()
                raise NothingComputed(res.problem)
        return out
    for s in _sessions(items, read, open_log):
        chosen = chosen or default_filters(s.log)
        res = compare_log(s, chosen, params, run, score, progress=progress,
                          keep_runs=keep_runs)
        del s
        out.logs.append(res)
        if on_log is not None:
            on_log(res)
        if res.problem:
            raise NothingComputed(res.problem)
    return out


def _compare_one(item: Union[str, "os.PathLike[str]", Session], read: ReadOptions,
                 filters: Optional[Sequence[str]],
                 params: Optional[Mapping[str, Mapping[str, Any]]], run: RunOptions,
                 score: ScoreOptions) -> LogComparison:
    """One log read and compared where an executor runs it (compare_logs(executor=...))."""
    s = item if isinstance(item, Session) else Session(os.fspath(item), read)
    return compare_log(s, filters or default_filters(s.log), params, run, score)
