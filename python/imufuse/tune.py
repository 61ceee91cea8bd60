"""Parameter search: a grid of a filter's parameters scored on logs with a reference, then
finer grids around the best point. What `imufuse tune` runs; usable from Python:

    from imufuse.session import Session
    from imufuse.tune import Tuner
    t = Tuner([Session("a.hdf5"), Session("b.hdf5")], "MadgwickIMU")
    res = t.search([("beta", [0.01, 0.03, 0.1])], refine=2)
    res.best, res.score(res.best)

The score of a parameter set is the mean over the logs of a BROAD RMS error (``metric``).
With the compiled float filters (the default), every parameter set of a round runs over each
log in compiled code and is scored there while it runs (imufuse_c.run_filters: no trajectory
is kept, the errors are imufuse.evaluation's within 1e-12); filters with a lane kernel run
their sets side by side in SIMD lanes, and (log, group of sets) tasks run in threads. Python
only chooses the sets. The reference backend and the fixed-point filters run and score each
set in Python, in threads.

Beyond one machine: ``search(..., executor=ex)`` takes any concurrent.futures.Executor (a
ProcessPoolExecutor, dask.distributed's ``Client.get_executor()``, Ray's): each round sends
one task per log, which opens the log where it runs (a path is read there, with the Tuner's
ReadOptions; a Session is sent as it is) and evaluates every set of the round on it with the
same code as the local run, so the results are the local run's to the bit. Tuner accepts
paths for this: search reads none of them on the driver (idle(), which the command line
calls, reads the first).
"""
from __future__ import annotations

import concurrent.futures as cf
import itertools
import math
import os
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

import imufuse_c

from .catalogue import ALL_ENTRIES, FLOAT, FilterError, reference_class, resolve_params
from .evaluation import METRICS, mean_over_trials, prepare_reference
from .shared.flags import in_users_terms, users_terms
from .session import (NothingComputed, ReadOptions, RunOptions, ScoreOptions, Session,
                      effective_params, is_fusion)

__all__ = ["Tuner", "TuneResult", "grid_spec", "Grid"]

Grid = List[Tuple[str, List[float]]]

#: the most parameter sets the grid, or one refinement round, may have: beyond it the search
#: would not end (RobustAHRS's 18 parameters at 9 points each: 1.5e17 sets)
MAX_SETS = 100_000
#: the default grid varies at most this many parameters (the ones whose /10 and x10 move the
#: score most); the others keep their values
DEFAULT_MOST = 3


def grid_spec(text: str) -> Tuple[str, List[float]]:
    """'beta=0.01:1:12' (log-spaced), 'beta=0.01:1:12lin', 'beta=0.02,0.05,0.1' ->
    (name, values); ValueError naming the mistake."""
    if "=" not in text:
        raise ValueError(f"--grid {text!r}: expected NAME=LO:HI:N[lin] or NAME=V1,V2,...")
    k, v = (x.strip() for x in text.split("=", 1))
    try:
        if ":" in v:
            lo, hi, n = v.split(":")
            lin = n.endswith("lin")
            num = int(n[:-3] if lin else n)
            a, b = float(lo), float(hi)
            if not (math.isfinite(a) and math.isfinite(b)):
                raise ValueError
            if num < 1 or num > 10000:
                raise ValueError(f"--grid {text}: N, the number of values, must be 1 to 10000, "
                                 f"got {num}")
            if not lin and (a <= 0 or b <= 0):
                raise OverflowError
            vals = list(np.linspace(a, b, num) if lin else np.geomspace(a, b, num))
        else:
            vals = [float(x) for x in v.split(",")]
            if not all(math.isfinite(x) for x in vals):
                raise ValueError
    except OverflowError:
        raise ValueError(f"--grid {text}: a log-spaced range needs positive ends (add 'lin' "
                         "after N for a linear one)") from None
    except ValueError as e:
        if str(e).startswith("--grid"):
            raise
        raise ValueError(f"--grid {text!r}: expected NAME=LO:HI:N[lin] or NAME=V1,V2,... "
                         "of finite numbers") from None
    return k, [float(x) for x in vals]


@dataclass
class TuneResult:
    """Every parameter set tried: {values: (score, [evaluation per log])}, NaN score with
    the reason for sets the filter refused."""
    names: List[str]
    metric: str
    results: Dict[Tuple[float, ...], Tuple[float, Any]] = field(default_factory=dict)

    def ranked(self) -> List[Tuple[float, ...]]:
        """The sets that could be scored, best first."""
        good = [p for p in self.results if math.isfinite(self.results[p][0])]
        return sorted(good, key=lambda p: self.results[p][0])

    @property
    def best(self) -> Optional[Tuple[float, ...]]:
        r = self.ranked()
        return r[0] if r else None

    def score(self, p: Tuple[float, ...]) -> float:
        return self.results[p][0]


class Tuner:
    """Score parameter sets of one 3-D filter on sessions with a reference orientation."""

    def __init__(self, sessions: Sequence[Union[Session, str, "os.PathLike[str]"]], name: str,
                 fixed: Optional[Mapping[str, Any]] = None, metric: Optional[str] = None,
                 run: RunOptions = RunOptions(), score: ScoreOptions = ScoreOptions(), *,
                 read: ReadOptions = ReadOptions()) -> None:
        """sessions: Sessions, or paths of logs read with ``read`` (opened on first use here,
        or where an executor runs them: search(executor=...))."""
        self.read = read
        with in_users_terms(read.command_line):
            self._init(sessions, name, fixed, metric, run, score)

    @property
    def _command_line(self) -> bool:
        return self.read.command_line

    def _init(self, sessions: Sequence[Union[Session, str, "os.PathLike[str]"]], name: str,
              fixed: Optional[Mapping[str, Any]], metric: Optional[str], run: RunOptions,
              score: ScoreOptions) -> None:
        cls = _FusionTuned(name) if is_fusion(name) else reference_class(name)
        if cls.kind == "1d":
            raise ValueError(f"tune: {name} is a single-axis filter; tune evaluates 3D filters "
                             "against a reference orientation")
        self.metric = metric or ("total" if cls.kind == "ahrs" else "inclination")
        if self.metric not in METRICS:
            raise ValueError(f"--metric: one of {', '.join(METRICS)}")
        if cls.kind != "ahrs" and self.metric != "inclination":
            raise ValueError(f"--metric {self.metric}: {name} has no heading reference; use "
                             "inclination")
        if not sessions:
            raise ValueError("tune: no log given")
        self.sources = [s if isinstance(s, Session) else os.fspath(s) for s in sessions]
        for s in self.sources:
            if isinstance(s, Session):
                _require_reference(s)
        self.name, self.cls = name, cls
        self.fixed = dict(fixed or {})
        self.run_options, self.score_options = run, score
        #: compiled batches (run_filters), else each set run and scored in Python
        self.batch = run.backend == "c" and name in {e.name for e in FLOAT}
        self._sessions: Dict[int, Session] = {}
        self._refs: Optional[list] = None
        self._inputs: Optional[list] = None
        #: the parameters default_grid left at their values: those that moved the score least,
        #: and those that do nothing with these settings
        self.left_out: List[str] = []
        self.idle_out: List[str] = []
        if is_fusion(name):
            self.batch = False          # Fusion has no compiled batch: sets scored in Python

    def _session(self, i: int) -> Session:
        if i not in self._sessions:
            src = self.sources[i]
            self._sessions[i] = src if isinstance(src, Session) else \
                _require_reference(Session(src, self.read))
        return self._sessions[i]

    @property
    def sessions(self) -> List[Session]:
        """Every log as a Session (paths are read here, once)."""
        return [self._session(i) for i in range(len(self.sources))]

    @property
    def inputs(self) -> list:
        if self._inputs is None:
            self._inputs = [s.inputs(self.name)[0] for s in self.sessions]
        return self._inputs

    def references(self) -> list:
        """Each session's reference prepared for the compiled scorer, and sealed (once: every
        group of sets on a log is scored against the one read-only copy)."""
        if self._refs is None:
            o = self.score_options
            refs = [_reference(s, o) for s in self.sessions]
            self._refs = [r.sealed(r.n_samples) for r in refs]
        return self._refs

    def _effective(self, over: Optional[Mapping[str, Any]] = None) -> Dict[str, Any]:
        """The parameters the filter runs with (defaults or preset, the fixed ones, ``over``);
        FilterError for a name the filter does not have."""
        over = {**self.fixed, **dict(over or {})}
        if is_fusion(self.name):
            return self.cls.settings(over, self.run_options.preset)
        return effective_params(self.name, resolve_params(self.name, 0.01, over,
                                                          self.run_options.preset))

    @users_terms
    def default_grid(self, points: int, most: int = DEFAULT_MOST) -> Grid:
        """Every positive float parameter with a default that acts with these settings
        (the others in ``self.idle_out``), /10 .. x10 around it, log-spaced; of more than
        ``most``, the ``most`` whose /10 and x10 (one at a time) move the score furthest
        from the defaults' on the first log (the others, by that order, in
        ``self.left_out``). Empty when none acts."""
        eff = self._effective()
        grid = [(k, list(np.geomspace(v / 10, v * 10, points))) for k, v in eff.items()
                if k not in ("dt", "sample_rate") and k not in self.fixed
                and isinstance(v, float) and v > 0]
        if not grid:
            raise ValueError(f"tune: {self.name} has no positive float parameter to tune; "
                             "give --grid")
        # what does nothing with these settings (acc_1g with the gate off) goes first
        self.idle_out = self.idle(grid)
        grid = [(k, v) for k, v in grid if k not in self.idle_out]
        self.left_out = []
        if len(grid) > most:
            # on the first log, as idle(): with an executor the others are read where it runs
            first = Tuner([self._session(0)], self.name, self.fixed, self.metric,
                          self.run_options, self.score_options, read=self.read)
            base = first.score_set([], [])[0]
            moved = {}
            for k, vals in grid:
                d = 0.0
                for v in (vals[0], vals[-1]):
                    try:
                        sc = first.score_set([k], [v])[0]
                    except FilterError:
                        continue                  # a value the filter refuses says nothing
                    if math.isfinite(sc):
                        d = max(d, abs(sc - base))
                moved[k] = d
            order = sorted(moved, key=lambda k: -moved[k])
            self.left_out = order[most:]
            grid = [(k, v) for k, v in grid if k in order[:most]]
        return grid

    @users_terms
    def idle(self, grid: Grid, samples: int = 4000, *, own_values: bool = False) -> List[str]:
        """The parameters of ``grid`` whose x10 leaves the first log's first states unchanged
        (acc_1g with the accelerometer gate off): varying them only costs time. own_values:
        those whose first and last values of the grid give the same states (a grid given by
        the user; a single value is never idle)."""
        head = [np.asarray(a)[:samples] for a in self._session(0).inputs(self.name)[0]]
        eff = self._effective()
        s0 = self._session(0)

        def states(over: Mapping[str, Any]) -> np.ndarray:
            f, _, dts, _, _ = s0.make(self.name, {**self.fixed, **over}, self.run_options)
            kw = {} if dts is None else {"dt": dts if np.ndim(dts) == 0 else dts[:samples]}
            return f.run(*head, **kw)
        base = states({})
        out = []
        for k, vals in grid:
            try:
                if own_values:
                    same = len(vals) > 1 and np.array_equal(states({k: vals[0]}),
                                                            states({k: vals[-1]}),
                                                            equal_nan=True)
                else:
                    same = np.array_equal(states({k: eff[k] * 10.0}), base, equal_nan=True)
            except (FilterError, KeyError, TypeError):
                same = False
            if same:
                out.append(k)
        return out

    def score_set(self, names: Sequence[str], values: Sequence[float]) -> Tuple[float, list]:
        over = {**self.fixed, **dict(zip(names, values))}
        evs = []
        for s, inp in zip(self.sessions, self.inputs):
            f, full, dts, _, _ = s.make(self.name, over, self.run_options)
            est = s.streamed_estimate(f, self.cls, self.name, full, inp,
                                      self.run_options.backend, dts, None)
            evs.append(s.score_estimate(self.cls, est, self.score_options))
        return mean_over_trials(evs)[self.metric], evs

    def _run_batch(self, names: Sequence[str], points: List[Tuple[float, ...]],
                   res: TuneResult, workers: int,
                   progress: Optional[Callable[[int, int], None]]) -> None:
        """Every point on every log through imufuse_c.run_filters: tasks of (log, a group of
        sets as wide as the lanes) in ``workers`` threads."""
        refs = self.references()
        made: Dict[Tuple[float, ...], list] = {}
        for p in points:
            over = {**self.fixed, **dict(zip(names, p))}
            try:
                made[p] = [s.make(self.name, over, self.run_options) for s in self.sessions]
            except FilterError as e:
                res.results[p] = (math.nan, str(e))
        good = list(made)
        spans = _spans(self.name, [made[p][0][0] for p in good])
        evs: Dict[Tuple[float, ...], list] = {p: [None] * len(self.sessions) for p in good}
        tasks = [(i, a, b) for i in range(len(self.sessions)) for a, b in spans]

        def task(t: Tuple[int, int, int]) -> Tuple[int, int, int, list]:
            i, a, b = t
            return i, a, b, _run_group([made[p][i] for p in good[a:b]], self.inputs[i],
                                       refs[i])
        done, n_logs = 0, len(self.sessions)
        with cf.ThreadPoolExecutor(max_workers=max(1, min(workers, len(tasks) or 1))) as ex:
            for fu in cf.as_completed([ex.submit(task, t) for t in tasks]):
                i, a, b, out = fu.result()
                for p, ev in zip(good[a:b], out):
                    evs[p][i] = ev
                done += b - a
                if progress:
                    progress(done // n_logs, len(good))
        for p in good:
            res.results[p] = (mean_over_trials(evs[p])[self.metric], evs[p])

    def _run_executor(self, executor: cf.Executor, names: Sequence[str],
                      points: List[Tuple[float, ...]], res: TuneResult,
                      progress: Optional[Callable[[int, int], None]]) -> None:
        """Every point on every log: one task per log (_evaluate_log) in ``executor``."""
        tasks = [_LogTask(src, self.read, self.name, self.fixed, self.run_options,
                          self.score_options, tuple(names), tuple(points), self.batch)
                 for src in self.sources]
        futs = {executor.submit(_evaluate_log, t): i for i, t in enumerate(tasks)}
        per_log: List[list] = [[] for _ in tasks]
        for n, fu in enumerate(cf.as_completed(futs), 1):
            per_log[futs[fu]] = fu.result()
            if progress:
                progress(n, len(tasks))
        for j, p in enumerate(points):
            why = next((r[j] for r in per_log if isinstance(r[j], str)), None)
            if why is not None:
                res.results[p] = (math.nan, why)
            else:
                evs = [r[j] for r in per_log]
                res.results[p] = (mean_over_trials(evs)[self.metric], evs)

    @users_terms
    def search(self, grid: Grid, refine: int = 2, jobs: Optional[int] = None,
               progress: Optional[Callable[[int, int], None]] = None,
               executor: Optional[cf.Executor] = None) -> TuneResult:
        """The grid, then ``refine`` rounds of a 5-point grid per parameter between the best
        point's neighbours. executor: run each round as one task per log there (any
        concurrent.futures.Executor; progress counts logs done)."""
        names = [k for k, _ in grid]
        self._effective({k: v[0] for k, v in grid})                      # names exist
        sets = math.prod(len(v) for _, v in grid)
        per_round = 5 ** sum(len(set(v)) > 1 for _, v in grid) if refine else 0
        if max(sets, per_round) > MAX_SETS:
            raise ValueError(
                f"tune: {sets:.3g} parameter sets in the grid "
                f"({' x '.join(f'{len(v)} {k}' for k, v in grid)})"
                + (f", {per_round:.3g} in each refinement round" if per_round > MAX_SETS else "")
                + f"; at most {MAX_SETS}: give --grid for the parameters to tune (fewer values)"
                + (", or --refine 0" if sets <= MAX_SETS else ""))
        res = TuneResult(names, self.metric)
        workers = max(1, jobs or os.cpu_count() or 1)

        def run(points: List[Tuple[float, ...]]) -> None:
            if executor is not None:
                self._run_executor(executor, names, points, res, progress)
                return
            if self.batch:
                self._run_batch(names, points, res, workers, progress)
                return
            done = 0
            with cf.ThreadPoolExecutor(max_workers=workers) as ex:
                futs = {ex.submit(self.score_set, names, p): p for p in points}
                for fu in cf.as_completed(futs):
                    p = futs[fu]
                    try:
                        res.results[p] = fu.result()
                    except FilterError as e:
                        res.results[p] = (math.nan, str(e))
                    done += 1
                    if progress:
                        progress(done, len(points))

        run([tuple(p) for p in itertools.product(*[v for _, v in grid])])
        for _ in range(refine):
            best = res.best
            if best is None:
                break
            axes = []
            for j in range(len(grid)):
                vs = sorted({p[j] for p in res.results})
                i = vs.index(best[j])
                lo, hi = vs[max(i - 1, 0)], vs[min(i + 1, len(vs) - 1)]
                axes.append([lo] if lo == hi else
                            np.geomspace(lo, hi, 5) if lo > 0 else np.linspace(lo, hi, 5))
            new = [tuple(float(x) for x in p) for p in itertools.product(*axes)]
            run([p for p in new if p not in res.results])
        if res.best is None:
            why = next((v[1] for v in res.results.values() if isinstance(v[1], str)), "")
            why = f"; e.g. {why}" if why else ""
            if not why and all(getattr(e, "n", 1) == 0 for v in res.results.values()
                               for e in v[1] or ()):
                # every set scored NaN over 0 samples (it read only "(9 tried)")
                why = ": no sample has a finite reference inside the movement mask"
            raise NothingComputed(f"tune: no parameter set could be evaluated "
                                  f"({len(res.results)} tried){why}")
        return res


def _require_reference(s: Session) -> Session:
    if s.log.q_ref is None:
        raise NothingComputed(f"{s.log.path}: no reference orientation (q_w..q_z): "
                              "nothing to tune against")
    return s


def _reference(s: Session, o: ScoreOptions) -> Any:
    """A session's reference prepared for the compiled scorer."""
    return prepare_reference(s.log.q_ref, ref_frame=s.ref_frame(o), ref_direction=o.ref_direction,
                             movement=s.mask(o), remove_heading_offset=o.heading_offset)


def _spans(name: str, filters: Sequence[Any]) -> List[Tuple[int, int]]:
    """The filters split into groups as wide as the lanes of their kernel (one each without)."""
    width = 1
    if filters and imufuse_c.has_lanes(name, filters[0].dtype):
        width = max(imufuse_c.lane_widths(filters[0].dtype))
    count = -(-len(filters) // width) if filters else 0
    return [(len(filters) * j // count, len(filters) * (j + 1) // count) for j in range(count)]


def _run_group(made: Sequence[Any], inputs: Sequence[Any], ref: Any) -> list:
    """One group of made filters (Session.make's tuples) run and scored on a log's inputs in
    compiled code: their evaluations."""
    return imufuse_c.run_filters([m[0] for m in made], *inputs, dt=made[0][2], score=ref,
                                 threads=1)


@dataclass(frozen=True)
class _LogTask:
    """What a worker needs to evaluate a round's sets on one log (picklable)."""
    source: Any                      # a Session, or the path of a log read with ``read``
    read: ReadOptions
    name: str
    fixed: Mapping[str, Any]
    run: RunOptions
    score: ScoreOptions
    names: Tuple[str, ...]
    points: Tuple[Tuple[float, ...], ...]
    batch: bool


def _evaluate_log(task: _LogTask) -> list:
    """Every set of ``task`` on its log: the evaluation of each, or the filter's refusal
    (a message); the local run's code (Tuner._run_batch, Tuner.score_set) on one log."""
    t = Tuner([task.source], task.name, task.fixed, None, task.run, task.score, read=task.read)
    s = t._session(0)
    out: list = []
    made: list = []
    for p in task.points:
        try:
            made.append(s.make(task.name, {**task.fixed, **dict(zip(task.names, p))}, task.run))
        except FilterError as e:
            made.append(str(e))
    good = [j for j, m in enumerate(made) if not isinstance(m, str)]
    out = list(made)
    if task.batch:
        ref = t.references()[0]
        for a, b in _spans(task.name, [made[j][0] for j in good]):
            for j, ev in zip(good[a:b], _run_group([made[j] for j in good[a:b]], t.inputs[0],
                                                   ref)):
                out[j] = ev
    else:
        for j in good:
            out[j] = t.score_set(task.names, task.points[j])[1][0]
    return out


class _FusionTuned:
    """What Tuner needs of x-io Fusion's AHRS (outside the float catalogue): its kind (AHRS:
    it runs without a magnetometer as Fusion's update_no_magnetometer), its state and its
    settings (the catalogue's defaults or preset)."""
    kind = "ahrs"

    def __init__(self, name: str) -> None:
        self.__name__ = name
        self.entry = ALL_ENTRIES[name]
        self.state_names = tuple(self.entry.reference.state_names)

    def settings(self, over: Mapping[str, Any], preset: Optional[str]) -> Dict[str, Any]:
        presets = {"published": {}, **self.entry.presets}
        if preset not in (None, *presets):
            raise FilterError(f"{self.__name__}: no preset {preset!r}; presets: "
                              + ", ".join(presets))
        out = {**self.entry.defaults, **presets.get(preset or "published", {})}
        for k in over:
            if k not in out and k != "invsqrt":
                raise FilterError(f"{self.__name__}: unknown setting {k!r}; settings: "
                                  + ", ".join(out))
        return {**out, **over}
