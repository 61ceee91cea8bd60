"""One session for a log, from the file to the score: what every command and a Python user do.

    read (units, columns, time)  ->  calibration, alignment, gyro offset  ->  run a filter
    ->  orientation estimate  ->  score against the log's reference (BROAD metrics)  ->  columns

    from imufuse.session import Session, ReadOptions
    s = Session("trial.hdf5", ReadOptions(gyr_unit="deg/s"))
    r = s.run("MadgwickAHRS", {"beta": 0.1})
    print(s.score(r).summary())

The options are typed settings (dataclasses) with the command line's defaults; the command
line only turns its arguments into them and prints what comes back. Every filter of the
catalogue runs the same way, FusionAHRS included (its own units, gyroscope in deg/s and dt
with every sample, are applied here). ``notes`` lists what a user should know (unit guesses,
jittery time, samples rejected); with ``strict`` a plausibility warning is an error.
Several filters on many logs, one log at a time, and the mean over them as BROAD reports
it: imufuse.comparison.compare_logs.

Longer than 500 lines because: the options, the session and the run are one path from a
file to a score, and each step is short; splitting them would scatter that path.
"""
from __future__ import annotations

import inspect
import math
import time as _time
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

import imufuse_c

from . import io, plausible, preprocess, reference
from .catalogue import (ALL_ENTRIES, FUSION_AHRS, FilterError, estimate, make_filter, reference_class,
                        resolve_params, why_no_estimate)
from .shared.estimate import Estimate
from .shared.flags import as_python, in_users_terms, users_terms
from .evaluation import Evaluation, evaluate, from_enu, to_enu
from .io import ACC, GYR, MAG, Log, LogError, axis_inputs, read_log, require
from .reference._fusion import ALL_ALIGNMENTS, alignment_is_rotation, alignment_matrix
from .rotations import matrix_to_quat, quat_conj, quat_mul, quat_to_euler

__all__ = ["ReadOptions", "RunOptions", "ScoreOptions", "Session", "Run", "NothingComputed",
           "StrictError", "effective_params", "FUSION", "FUSIONS", "is_fusion"]

#: the filter with Fusion's own units (gyroscope deg/s, dt with every update)
#: x-io Fusion's AHRS: the 1.2.3 port (Longbin's walkthrough) and the current release, 1.3
FUSION = "FusionAHRS"
FUSIONS = FUSION_AHRS


def is_fusion(name: str) -> bool:
    """True for x-io Fusion's AHRS classes: Fusion's units (the gyroscope in deg/s), its
    settings, its outputs."""
    return name in FUSIONS


class NothingComputed(ValueError):
    """Nothing could be computed or evaluated (the command line's exit 4)."""


class StrictError(LogError):
    """A plausibility warning under ``strict=True``."""


@dataclass(frozen=True)
class ReadOptions:
    """How to read a log (imufuse.io.read_log) and what to do in front of every filter
    (imufuse.preprocess): units None = from the header (else rad/s, g, s); columns: {name:
    header}; rate: Hz, a fixed rate instead of the time column; fixed_rate: the median
    interval instead of each sample's own; calibration (a JSON file), align (e.g. "+X-Z+Y"),
    offset (FusionOffset): the preprocessing, by ``backend`` ("c" or "ref"); strict: a
    plausibility warning (a unit, time or rate that only makes sense as a mistake) is an
    error; need_time: False reads a log without time column or rate (calibration logs);
    command_line: the notes and errors name the command line's options only (imufuse's
    CLI), else each also says them as these records' fields (imufuse.shared.flags)."""
    gyr_unit: Optional[str] = None
    acc_unit: Optional[str] = None
    time_unit: Optional[str] = None
    columns: Mapping[str, str] = field(default_factory=dict)
    rate: Optional[float] = None
    fixed_rate: bool = False
    calibration: Optional[str] = None
    align: Optional[str] = None
    offset: bool = False
    strict: bool = False
    need_time: bool = True
    backend: str = "c"
    command_line: bool = False


@dataclass(frozen=True)
class RunOptions:
    """How to run a filter: backend "c" (imufuse_c) or "ref" (imufuse.reference); dtype;
    init: None (= "first" for 3-D filters; the filter's own start for those that start from
    their first sample, RobustIMU/RobustAHRS), "first", "identity" or a quaternion w, x, y, z;
    init_window: with "first", the mean of that many samples; axis: "x" or "y", the axis of a
    single-axis filter fed from gyr/acc columns; preset: a named parameter set of the
    catalogue ("published": the settings of the code the filter was ported from) in place of
    the defaults, under the parameters given."""
    backend: str = "c"
    dtype: str = "float64"
    init: Union[None, str, Sequence[float]] = None
    init_window: Optional[int] = None
    axis: str = "x"
    preset: Optional[str] = None


@dataclass(frozen=True)
class ScoreOptions:
    """How to score: the reference's earth frame (None: the file's, else NWU) and direction;
    skip: seconds at the start left out; heading_offset: remove a constant heading offset;
    frame: the earth frame of the output quaternion and Euler angles."""
    ref_frame: Optional[str] = None
    ref_direction: str = "sensor-to-earth"
    skip: Optional[float] = None
    heading_offset: bool = False
    frame: str = "NWU"


def effective_params(name: str, params: Mapping[str, Any]) -> Dict[str, Any]:
    """The constructor's keyword defaults updated by ``params`` (what the filter really runs
    with), dt included."""
    sig = inspect.signature(reference_class(name)._params)
    out = {p.name: p.default for p in sig.parameters.values()
           if p.default is not inspect.Parameter.empty}
    out.update(params)
    return out


def format_params(name: str, params: Mapping[str, Any]) -> str:
    if is_fusion(name):
        return ", ".join(f"{k}={v}" for k, v in params.items()) or "defaults"
    eff = effective_params(name, params)
    s = ", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                  for k, v in eff.items() if k != "dt")
    return s or "no parameters"


def _takes(fn: Any, name: str) -> bool:
    try:
        return name in inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return False


def supports_dt_array(name: str) -> bool:
    """True when the filter's run() takes dt=array (per-sample periods)."""
    return is_fusion(name) or _takes(reference_class(name).run, "dt")


def supports_init(name: str) -> bool:
    """True when the filter's constructor takes init= ("first" or a quaternion)."""
    cls = reference_class(name)
    return _takes(cls.__init__, "init") or _takes(cls._params, "init")


def init_value(value: Union[None, str, Sequence[float]]) -> Union[None, str, List[float]]:
    """None, "first", "identity" or [w, x, y, z] from a string or a sequence."""
    if value is None or value in ("first", "identity"):
        return value
    try:
        q = [float(v) for v in (value.split(",") if isinstance(value, str) else value)]
    except (TypeError, ValueError):
        q = []
    if len(q) != 4 or not all(math.isfinite(v) for v in q) or not any(q):
        raise ValueError(f"init {value!r}: expected first, identity or a quaternion w,x,y,z")
    return q


def chunked_estimate(cls: Any, S: np.ndarray, chunk: int = 1 << 16) -> Optional[Estimate]:
    """catalogue.estimate(cls, S), block by block (the adapters' temporaries stay small for
    long logs); the same values."""
    if len(S) <= chunk:
        return estimate(cls, S)
    parts = [estimate(cls, S[k:k + chunk]) for k in range(0, len(S), chunk)]
    if parts[0] is None:
        return None
    e: Any = parts[0]
    if e.angle is not None:
        e.angle = np.concatenate([p.angle for p in parts])          # type: ignore[union-attr]
    else:
        e.q = np.concatenate([p.q for p in parts])                  # type: ignore[union-attr]
    return e


def euler_deg(q: np.ndarray, chunk: int = 65536) -> np.ndarray:
    """(N, 3) roll, pitch, yaw in degrees, computed in chunks (bounded memory)."""
    out = np.empty((len(q), 3))
    for k in range(0, len(q), chunk):
        out[k:k + chunk] = np.degrees(quat_to_euler(q[k:k + chunk]))
    return out


def frame_q(q: np.ndarray, frame: str) -> np.ndarray:
    """NWU quaternions expressed in the earth frame ``frame``."""
    return q if frame == "NWU" else from_enu(to_enu(q, "NWU"), frame)


#: runs at least this long (samples) report progress: the pure-Python reference runs
#: ~10^5 samples/s, the compiled filters ~10^7
PROGRESS_MIN = {"ref": 20_000, "c": 2_000_000}

Progress = Callable[[str, int, int], None]

#: samples per block when a run keeps only its estimate (Session.run(keep_states=False))
STREAM_BLOCK = 1 << 14
#: frame_hint ranks the other frames on at most this many samples of a log (a frame or
# direction mistake is in every sample), then scores the best of them on the whole log
HINT_SAMPLES = 50_000
#: a frame hint whose best frame leaves more than this (deg) names the sensor's axes too
HINT_LEFT = 10.0
#: the turns of the sensor's axes (23, in each of the six readings of the reference) are
#: ranked on at most this many samples, then the best of them scored on the whole log
HINT_TURN_SAMPLES = 5_000


#: the 23 proper turns of --align (body = M sensor; its reflections cannot be a turned
#: mounting) and their quaternions, for the frame hint
_TURNS = [(a, matrix_to_quat(alignment_matrix(a))) for a in ALL_ALIGNMENTS
          if alignment_is_rotation(a) and a != "+X+Y+Z"]


def run_with_progress(f: Any, inputs: Sequence[np.ndarray], label: str, backend: str,
                      dts: Any = None, progress: Optional[Progress] = None) -> np.ndarray:
    """f.run(*inputs[, dt=dts]), in about 20 chunks calling progress(label, done, n) when the
    run is long. The state carries over between run() calls: the same trajectory, bit for
    bit."""
    n = len(inputs[0])

    def kw(a: int, b: int) -> Dict[str, Any]:
        return {} if dts is None else {"dt": dts if np.ndim(dts) == 0 else dts[a:b]}
    if progress is None or n < PROGRESS_MIN.get(backend, PROGRESS_MIN["c"]):
        return f.run(*inputs, **kw(0, n))
    step = -(-n // 20)
    parts = []
    for k in range(0, n, step):
        parts.append(f.run(*[x[k:k + step] for x in inputs], **kw(k, k + step)))
        progress(label, min(k + step, n), n)
    return np.concatenate(parts)


class _FusionKind:
    """What the session needs of a Fusion AHRS class (outside the float catalogue)."""

    def __init__(self, has_mag: bool, name: str = FUSION) -> None:
        self.__name__ = name
        self.kind = "ahrs" if has_mag else "imu"
        self.state_names = tuple(getattr(reference, name).state_names)


@dataclass
class Run:
    """One filter run over a session's log. states: (N, len(state)); estimate: the
    orientation (or None, see why); rejected: samples the filter rejected (state kept)."""
    name: str
    cls: Any
    params: Dict[str, Any]
    states: np.ndarray
    estimate: Optional[Estimate]
    rejected: int
    seconds: float
    time: str
    init: Optional[str]
    inputs: str
    notes: List[str] = field(default_factory=list)
    extra: Dict[str, np.ndarray] = field(default_factory=dict)
    backend: str = "c"
    dtype: str = "float64"
    samples: int = -1        # samples run (-1: len(states))

    @property
    def kind(self) -> str:
        return self.cls.kind

    @property
    def n(self) -> int:
        """The number of samples the filter ran over (states may be empty: run(...,
        keep_states=False))."""
        return len(self.states) if self.samples < 0 else self.samples

    def why(self) -> str:
        """Why there is no estimate, or where it came from."""
        if self.rejected and self.rejected >= self.n:
            return f"every one of the {self.n} samples rejected: nothing estimated"
        return why_no_estimate(self.cls) if self.estimate is None else self.estimate.source

    def columns(self, t: np.ndarray, frame: str = "NWU") -> Tuple[Dict[str, np.ndarray],
                                                                   List[str]]:
        """The output columns (time, the state, then what derives from it: angle_deg, or
        [q_w..q_z,] roll_deg, pitch_deg[, yaw_deg] in ``frame``) and notes."""
        cols: Dict[str, np.ndarray] = {"time": t}
        notes = []
        for j, n in enumerate(self.cls.state_names):
            cols[n] = self.states[:, j]
        est: Any = self.estimate
        if est is None:
            notes.append(f"{why_no_estimate(self.cls)}; writing the state only")
        elif est.angle is not None:
            cols["angle_deg"] = np.degrees(est.angle)
        else:
            q = frame_q(est.q, frame)
            if est.source != "q0..q3" or frame != "NWU" or is_fusion(self.name):
                for j, n in enumerate(io.QUAT):
                    cols[n] = q[:, j]
            e = euler_deg(q)
            cols["roll_deg"], cols["pitch_deg"] = e[:, 0], e[:, 1]
            if est.heading:
                cols["yaw_deg"] = e[:, 2]
            else:
                notes.append(f"no heading from {self.name} ({est.source}): yaw omitted")
        cols.update(self.extra)
        return cols, notes

    def float32_columns(self) -> set:
        return set(self.cls.state_names) if self.dtype == "float32" else set()

    def describe(self, samples: int) -> str:
        init = f", init={self.init}" if self.init else ""
        return (f"{self.name} ({self.backend}, {self.dtype}, {self.time}{init}; "
                f"{format_params(self.name, self.params)}): {samples} samples from {self.inputs}")


def _fusion_extra(f: Any, S: np.ndarray) -> Dict[str, np.ndarray]:
    """FusionAHRS's outputs of states S as output columns."""
    extra: Dict[str, np.ndarray] = {}
    out = f.outputs_batch(S)
    # Fusion's own Euler angles, in its convention (roll_deg.. are in the output frame)
    for j, ax in enumerate(("roll", "pitch", "yaw")):
        extra[f"fusion_{ax}_deg"] = out["euler"][:, j]
    for key in ("earth_acceleration", "linear_acceleration"):
        for j, ax in enumerate("xyz"):
            extra[f"{key}_{ax}"] = out[key][:, j]
    for key in ("acceleration_error", "magnetic_error"):
        extra[key + "_deg"] = out[key]
    for key in ("initialising", "angular_rate_recovery", "acceleration_recovery",
                "magnetic_recovery"):
        extra[key] = out[key].astype(np.float64)
    return extra


class Session:
    """A log read once, with its preprocessing; run filters over it and score them.

    log: a path or an imufuse.io.Log (used as it is: its columns are not preprocessed
    again). notes: what reading and preprocessing said (one line each)."""

    def __init__(self, log: Union[str, "Log", Any], read: ReadOptions = ReadOptions()) -> None:
        self.options = read
        self.notes: List[str] = []
        if isinstance(log, Log):
            self.log = log
            return
        with self._said():
            self.log = read_log(log, gyr_unit=read.gyr_unit, acc_unit=read.acc_unit,
                                rate=read.rate, columns=dict(read.columns),
                                fixed_rate=read.fixed_rate, time_unit=read.time_unit,
                                need_time=read.need_time)
            # --calibration, --align, --offset, in this order
            done = preprocess.apply(self.log, calibration=read.calibration, align=read.align,
                                    offset=read.offset, backend=read.backend)
        if any(n.startswith("gyroscope calibrated") for n in done):
            # the gyroscope's axes as calibrated (a file mapping them, as the note says)
            lg = self.log
            lg.suspicions = [w for w in lg.suspicions if not w.startswith(plausible.AXES_NOTE)]
            lg.warnings = [w for w in lg.warnings if not w.startswith(plausible.AXES_NOTE)]
            applied = preprocess.load_calibration(read.calibration).params("gyroscope")["M"]
            note = plausible.gyro_axes_note(lg, applied)
            if note:
                lg.suspicions.append(note)
                lg.warnings.append(note)
        if read.strict and self.log.suspicions:
            raise StrictError(self.say(f"{self.log.path}: {self.log.suspicions[0]} (--strict)"))
        self.notes += [self.say(n) for n in self.log.warnings + done]

    def say(self, message: str) -> str:
        """A note or an error in the user's terms: the command line's options, and for a
        Python user (ReadOptions.command_line False) the fields they are (shared.flags)."""
        return message if self.options.command_line else as_python(message)

    def _said(self) -> Any:
        # a ValueError (LogError, StrictError) raised inside, in the user's terms
        return in_users_terms(self.options.command_line)

    @property
    def _command_line(self) -> bool:
        return self.options.command_line

    # ---- what the log offers
    @users_terms
    def inputs(self, name: str, axis: str = "x") -> Tuple[Tuple[np.ndarray, ...], str]:
        """run() arguments of a filter from the log, and a description (LogError naming the
        missing columns)."""
        log = self.log
        if is_fusion(name):
            require(log, GYR + ACC)
            gyr = np.degrees(log.gyr)          # Fusion's unit
            if log.has(*MAG):
                return (gyr, log.acc, log.mag), "gyr, acc, mag (update), gyroscope in deg/s"
            return (gyr, log.acc), "gyr, acc (update_no_magnetometer), gyroscope in deg/s"
        cls = reference_class(name)
        if cls.kind == "1d":
            rate, angle, src = axis_inputs(log, axis)
            return (rate, angle), src
        require(log, GYR + ACC)
        if cls.kind == "ahrs":
            require(log, MAG, f"({cls.__name__} is an AHRS filter and needs a magnetometer; "
                              "use an IMU filter without one)")
            return (log.gyr, log.acc, log.mag), "gyr, acc, mag"
        return (log.gyr, log.acc), "gyr, acc"

    def filter_class(self, name: str) -> Any:
        return _FusionKind(self.log.has(*MAG), name) if is_fusion(name) else reference_class(name)

    # ---- running
    @users_terms
    def make(self, name: str, params: Optional[Mapping[str, Any]] = None,
             options: RunOptions = RunOptions()) -> Tuple[Any, Dict[str, Any], Any, Optional[str],
                                                          List[str]]:
        """(filter instance, its parameters, dt for run(), init description, notes)."""
        log, notes = self.log, []  # type: Log, List[str]
        if is_fusion(name):
            mod = imufuse_c if options.backend == "c" else reference
            given = dict(params or {})
            presets = {"published": {}, **ALL_ENTRIES[name].presets}
            if options.preset not in (None, *presets):
                raise FilterError(f"{name}: no preset {options.preset!r}; presets: "
                                  + ", ".join(presets) + " (published: its defaults)")
            params = {**presets.get(options.preset or "published", {}), **given}
            if name != FUSION and "sample_rate" not in given:
                # the log's rate, also over a preset's (the advanced example's 100 Hz): the
                # rate sets the rejection timeout's samples; run's dt replaces it per sample
                params["sample_rate"] = 1.0 / self.dt()
            try:
                f = getattr(mod, name)(**params, dtype=options.dtype)
            except TypeError as e:
                raise FilterError(f"{name}: {e}") from None
            except ValueError as e:
                raise FilterError(f"{name}: {e}") from None
            dts = log.dts if log.dts is not None else log.dt
            return f, params, dts, None, notes
        cls = reference_class(name)
        full = resolve_params(name, self.dt(), params, options.preset)
        dts = None
        if not log.fixed_rate and log.dts is not None:
            if supports_dt_array(name):
                dts = log.dts
            elif np.max(np.abs(log.dts - self.dt())) > 1e-6 * self.dt():
                notes.append(f"fixed dt {self.dt():.6g} s (this build has no per-sample dt)")
        init = init_value(options.init)
        kw: Dict[str, Any] = {}
        desc: Optional[str] = None
        if (cls.kind != "1d" and init is None and getattr(cls, "own_start", None)
                and not (options.init_window and options.init_window > 1)):
            # a filter that starts from its first sample by itself (RobustIMU/AHRS) keeps its
            # own start: init="first" would set the same attitude in another frame I and run
            # another, equally valid, trajectory (BROAD trial 31: 0.88 / 1.12 deg heading)
            desc = "its own (the first sample)"
        elif cls.kind != "1d":
            if init is None:
                init = "first"          # the default for logs
            if not supports_init(name):
                if init != "identity":
                    notes.append(f"init={init} unsupported by this build: started from identity")
                init = "identity"
            elif isinstance(init, list):
                kw["q0"] = init
            elif init == "first":
                kw["init"] = "first"
                w = options.init_window
                if w and w > 1:
                    kw["init_window"] = w
                    init = f"first (mean of {w} samples)"
                    if w >= len(log):
                        # the window never ends: every output is the window's mean
                        notes.append(f"init window {w} >= the log's {len(log)} samples: "
                                     "the filter never runs (no gyro in the window; every "
                                     "output is the mean direction so far)")
            desc = ("q0=" + ",".join(f"{v:g}" for v in init) if isinstance(init, list)
                    else str(init))
        f = make_filter(name, options.backend, options.dtype, {**full, **kw})
        eff = effective_params(name, full)
        limit = eff.get("gyr_bias_max")
        if limit:
            notes += self._beyond_bias_range(name, float(limit))
        if "window" in eff and "acc_1g" in eff and cls.kind != "1d":
            notes += self._outside_window(name, float(eff["acc_1g"]), float(eff["window"]))
        return f, full, dts, desc, [self.say(n) for n in notes]

    def _outside_window(self, name: str, acc_1g: float, window: float) -> List[str]:
        """The note when no accelerometer reading of the log falls in a filter's window of
        1 g (MultiWii: acc_1g (1 +- window), in the unit the filter is given, g): it runs on
        the gyro alone, without a word."""
        n = np.linalg.norm(self.log.acc, axis=1)
        n = n[np.isfinite(n)]
        if not n.size or np.any(np.abs(n - acc_1g) <= window * acc_1g):
            return []
        med = float(np.median(n))
        return [f"no accelerometer reading falls in {name}'s window of 1 g (acc_1g {acc_1g:g} "
                f"+- {window:.0%}: the median |acc| is {med:.4g}, in g): it corrects nothing "
                f"and integrates the gyro alone; give -p acc_1g={med:.4g} (the sensor's 1 g in "
                "the unit it is given), or read the accelerometer in g (--acc-unit)"]

    def _beyond_bias_range(self, name: str, limit: float) -> List[str]:
        """The note when the gyroscope reads beyond a filter's gyr_bias_max (deg/s) while
        the other sensors are still (plausible.still_gyro, once per log)."""
        if not hasattr(self, "_still"):
            self._still = plausible.still_gyro(self.log)
        if self._still is None:
            return []
        med, t0, t1, mag = self._still
        deg = np.degrees(med)
        if not np.abs(deg).max() > limit:
            return []
        return [f"the gyroscope reads ({', '.join(f'{v:.3g}' for v in deg)}) deg/s while the "
                f"accelerometer{' and the magnetometer' if mag else ''} stay still "
                f"({t0:.1f} to {t1:.1f} s): an offset beyond {name}'s gyr_bias_max "
                f"({limit:g} deg/s), which bounds its bias estimate"
                + ("" if mag else " (or a turn about the vertical at that rate)")
                + f"; give -p gyr_bias_max={math.ceil(1.5 * np.abs(deg).max()):g}, or "
                "calibrate the gyroscope (imufuse calibrate gyro, --calibration)"]

    def dt(self) -> float:
        """The log's sample period (LogError for a log read without time or rate)."""
        if self.log.dt is None:
            raise LogError(self.say(f"{self.log.path}: no time column and no rate: give "
                                    "--rate HZ"))
        return float(self.log.dt)

    def describe_time(self, dts: Any) -> str:
        if dts is not None and np.ndim(dts):
            d = np.asarray(dts)[1:]
            return (f"dt per sample from the time column ({d.min():.6g}..{d.max():.6g} s)"
                    if d.size else f"dt={self.log.dt:.6g} s")
        return f"dt={self.log.dt:.6g} s"

    @users_terms
    def run(self, name: str, params: Optional[Mapping[str, Any]] = None,
            options: RunOptions = RunOptions(), *, progress: Optional[Progress] = None,
            keep_states: bool = True, on_block: Optional[Callable[..., None]] = None) -> Run:
        """Run one filter (a catalogue name or FusionAHRS) over the log. keep_states=False:
        the filter runs block by block and only its estimate is kept (Run.states is empty;
        memory is the estimate's, never the trajectory's); on_block(Run of the block, first
        sample) is called with each block's states, estimate and Fusion outputs (what `imufuse
        run` writes out block by block)."""
        inputs, src = self.inputs(name, options.axis)
        f, full, dts, init, notes = self.make(name, params, options)
        cls = self.filter_class(name)
        n = len(self.log)
        extra: Dict[str, np.ndarray] = {}
        if not keep_states:
            t0 = _time.perf_counter()
            est = self.streamed_estimate(f, cls, name, full, inputs, options.backend, dts,
                                          progress, on_block=on_block)
            seconds = _time.perf_counter() - t0
            rejected = min(int(getattr(f, "skipped", 0)), n)
            S0 = np.empty((0, len(cls.state_names)))
            return Run(name, cls, full, S0, est if rejected < n else None, rejected, seconds,
                       self.describe_time(dts), init, src, notes, extra, options.backend,
                       options.dtype, samples=n)
        t0 = _time.perf_counter()
        S = run_with_progress(f, inputs, name, options.backend, dts, progress)
        seconds = _time.perf_counter() - t0
        rejected = min(int(getattr(f, "skipped", 0)), n)
        if is_fusion(name):
            est = None if rejected >= n else self._fusion_estimate(S, full)
            extra = _fusion_extra(f, S)
        else:
            est = chunked_estimate(cls, S) if rejected < n else None
        return Run(name, cls, full, S, est, rejected, seconds, self.describe_time(dts), init,
                   src, notes, extra, options.backend, options.dtype, samples=n)

    def streamed_estimate(self, f: Any, cls: Any, name: str, params: Mapping[str, Any],
                           inputs: Sequence[np.ndarray], backend: str, dts: Any,
                           progress: Optional[Progress], block: int = STREAM_BLOCK,
                           on_block: Optional[Callable[..., None]] = None
                           ) -> Optional[Estimate]:
        """f over the log in blocks of ``block`` samples (the state carries over: the same
        trajectory, bit for bit), each block's estimate written into one array: memory is
        the estimate's (32 bytes a sample) and one block's states. on_block: see run()."""
        n = len(inputs[0])
        first: Any = None
        out: Optional[np.ndarray] = None
        report = progress is not None and n >= PROGRESS_MIN.get(backend, PROGRESS_MIN["c"])
        if report:
            block = min(block, -(-n // 20))         # about 20 reports
        every = max(block, -(-n // 20))
        next_report = every
        # the compiled 3-D filters keep only the words their quaternion is read from while
        # they run (run(outputs="q"): the same quaternions as estimate() of the states)
        quat = (on_block is None and backend == "c" and not is_fusion(name)
                and cls.kind != "1d" and estimate(cls, np.zeros((0, len(cls.state_names))))
                is not None)
        for k in range(0, max(n, 1), block):
            kw = {} if dts is None else {"dt": dts if np.ndim(dts) == 0 else dts[k:k + block]}
            if quat:
                q = f.run(*[x[k:k + block] for x in inputs], **kw, outputs="q")
                if first is None:
                    meta = estimate(cls, np.zeros((0, len(cls.state_names))))
                    assert meta is not None
                    first, out = Estimate(heading=meta.heading, source=meta.source), np.empty((n, 4))
                assert out is not None
                out[k:k + len(q)] = q
                if report and progress is not None and (k + len(q) >= next_report
                                                        or k + len(q) == n):
                    progress(name, k + len(q), n)
                    next_report += every
                continue
            part = f.run(*[x[k:k + block] for x in inputs], **kw)
            e = self._fusion_estimate(part, params) if is_fusion(name) else estimate(cls, part)
            if on_block is not None:
                on_block(Run(name, cls, dict(params), part, e, 0, 0.0, "", None, "", [],
                             _fusion_extra(f, part) if is_fusion(name) else {}), k)
            if e is None:
                continue            # no orientation in this filter's state: run on for skipped
            if first is None:
                first = e
                shape = (n,) if e.angle is not None else (n, 4)
                out = np.empty(shape)
            assert out is not None
            out[k:k + len(part)] = e.angle if e.angle is not None else e.q
            if report and progress is not None and (k + len(part) >= next_report
                                                    or k + len(part) == n):
                progress(name, k + len(part), n)
                next_report += every
        if first is None:
            return None
        if first.angle is not None:
            first.angle = out
        else:
            first.q = out
        return first

    def _fusion_estimate(self, S: np.ndarray, params: Mapping[str, Any]) -> Estimate:
        """FusionAHRS's quaternion (its `convention`'s earth frame) as an NWU estimate."""
        with np.errstate(all="ignore"):
            q = np.asarray(S[:, :4], dtype=np.float64)
            q = q / np.linalg.norm(q, axis=1, keepdims=True)
        conv = str(params.get("convention", "NWU")).upper()
        if conv != "NWU":
            q = from_enu(to_enu(q, conv), "NWU")
        return Estimate(q=q, heading=self.log.has(*MAG), source="q0..q3")

    # ---- scoring
    def ref_frame(self, options: ScoreOptions = ScoreOptions()) -> str:
        return options.ref_frame or self.log.ref_frame or "NWU"

    @users_terms
    def mask(self, options: ScoreOptions = ScoreOptions()) -> Optional[np.ndarray]:
        """The samples that count for errors: the movement column and ``skip``."""
        log = self.log
        mask = log.movement
        if options.skip:
            late = log.t >= log.t[0] + options.skip
            if not late.any():
                # else "nothing could be evaluated ... inside the movement mask", or nothing
                raise LogError(self.say(f"{log.path}: --skip {options.skip:g} s leaves no "
                                        "sample: the log lasts "
                                        f"{float(log.t[-1] - log.t[0]):.6g} s"))
            mask = late if mask is None else (mask & late)
        return mask

    def reference_angle(self, axis: str, options: ScoreOptions = ScoreOptions()
                        ) -> Optional[np.ndarray]:
        """Reference angle of the single-axis filters (roll or pitch of the reference, NWU)."""
        q = self.log.q_ref
        if q is None:
            return None
        q = from_enu(to_enu(q, self.ref_frame(options), options.ref_direction), "NWU")
        return quat_to_euler(q)[:, 0 if axis == "x" else 1]

    def reference_euler(self, options: ScoreOptions = ScoreOptions()) -> Optional[np.ndarray]:
        """(N, 3) roll, pitch, yaw (rad) of the reference in the output frame."""
        q = self.log.q_ref
        if q is None:
            return None
        return quat_to_euler(frame_q(from_enu(to_enu(q, self.ref_frame(options),
                                                     options.ref_direction), "NWU"),
                                     options.frame))

    @users_terms
    def score(self, run: Run, options: ScoreOptions = ScoreOptions(), *, axis: str = "x",
              per_sample: bool = False) -> Union[None, Evaluation, Dict[str, Any]]:
        """The BROAD evaluation (3-D) or {'angle': (rms, max), 'n': n, 'n_ref_nan': k} (1-D)
        against the log's reference; None without a reference or an estimate."""
        return self.score_estimate(run.cls, run.estimate, options, axis=axis,
                                   per_sample=per_sample)

    @users_terms
    def score_estimate(self, cls: Any, est: Optional[Estimate],
                       options: ScoreOptions = ScoreOptions(), *, axis: str = "x",
                       per_sample: bool = False) -> Union[None, Evaluation, Dict[str, Any]]:
        log = self.log
        if est is None or log.q_ref is None:
            return None
        mask = self.mask(options)
        if cls.kind == "1d":
            ref: Any = self.reference_angle(axis, options)
            use = np.isfinite(ref) & (mask if mask is not None else True)
            e = np.degrees(np.abs(est.angle - ref))[use]
            n = int(np.count_nonzero(use))
            return {"angle": (float(np.sqrt(np.mean(e * e))) if n else math.nan,
                              float(e.max()) if n else math.nan), "n": n,
                    "n_ref_nan": int(np.count_nonzero(~np.isfinite(ref)))}
        ev = evaluate(est.q, log.q_ref, est_frame="NWU", ref_frame=self.ref_frame(options),
                      ref_direction=options.ref_direction, movement=mask,
                      remove_heading_offset=options.heading_offset, per_sample=per_sample)
        ev.has_heading = bool(est.heading)
        return ev

    def frame_hint(self, run: Run, ev: Any, options: ScoreOptions = ScoreOptions()
                   ) -> Optional[str]:
        """A hint when the errors point at a frame or direction mistake: an inclination or
        heading error near 90 or 180 degrees that another reference frame or direction takes
        down by more than half (an ENU reference read as NWU gives ~90 deg of heading, read as
        NED ~180 deg of inclination). Said also when the frame was given: the option may be
        the mistake."""
        if run.kind == "1d" or ev is None or isinstance(ev, dict) or not ev.n:
            return None
        heading = run.kind == "ahrs"
        worst = max(ev.inclination, ev.heading if heading else 0.0)
        if not worst > 45.0:
            return None
        cur = (self.ref_frame(options), options.ref_direction)
        mask = self.mask(options)
        q: Any = run.estimate.q if run.estimate is not None else None
        ref = self.log.q_ref

        def score(fr: str, dr: str, step: int, turn: Any = None) -> float:
            qs = q[::step] if turn is None else quat_mul(q[::step], quat_conj(turn))
            e = evaluate(qs, ref[::step], est_frame="NWU", ref_frame=fr,
                         ref_direction=dr, movement=None if mask is None else mask[::step],
                         remove_heading_offset=options.heading_offset, per_sample=False)
            return max(e.inclination, e.heading if heading else 0.0)

        # the five other readings ranked on every step-th sample (a frame mistake is in
        # every sample; at most HINT_SAMPLES of them), the best one scored on all
        step = max(1, len(ref) // HINT_SAMPLES)
        others = [(fr, dr) for fr in ("NWU", "ENU", "NED")
                  for dr in ("sensor-to-earth", "earth-to-sensor") if (fr, dr) != cur]
        scores = {o: score(*o, step) for o in others}
        ranked = min(others, key=lambda o: scores[o] if scores[o] == scores[o] else math.inf)
        best = (score(*ranked, 1) if step > 1 else scores[ranked], *ranked)
        framed = best[0] < 0.5 * worst
        said = ("given" if options.ref_frame else
                "from the file" if self.log.ref_frame else "assumed")
        if not (framed and best[0] <= HINT_LEFT):
            # the sensor's axes turned against the reference's body (mounted turned, or
            # wired so): the estimate turned back by each of the 23 turns of --align, against
            # the reference in each of the six readings (a turned sensor and a frame mistake
            # together: a CSV's reference is assumed NWU), ranked on every tstep-th sample;
            # the filter's run on the aligned log gives what the turned estimate does (the
            # filters are the same in any body axes)
            tstep = max(1, len(ref) // HINT_TURN_SAMPLES)
            turns = {(a, fr): score(fr[0], fr[1], tstep, t)
                     for a, t in _TURNS for fr in [cur, *others]}
            # ties (within 0.1 deg) to the reference as read: an IMU filter's inclination is
            # the same in NWU and ENU
            a, fr = min(turns, key=lambda k: (round(turns[k], 1) if turns[k] == turns[k]
                                              else math.inf, k[1] != cur))
            left = score(fr[0], fr[1], 1, dict(_TURNS)[a]) if tstep > 1 else turns[(a, fr)]
            if left < 0.5 * worst and not (framed and left >= best[0]):
                opts = f"--align {a}" + (
                    "" if fr == cur else f" --ref-frame {fr[0]}" +
                    (f" --ref-direction {fr[1]}" if fr[1] != cur[1] else ""))
                return self.say(
                    f"hint: against the reference as {cur[0]} ({said}), {cur[1]}, the error "
                    f"reaches {worst:.1f} deg; with {opts} it would be about {left:.1f} deg: "
                    "are the sensor's axes turned against the reference's body (mounted "
                    "turned, or its axes named otherwise)?")
        if not framed:
            return None
        opts = (f"--ref-frame {best[1]}" +
                (f" --ref-direction {best[2]}" if best[2] != cur[1] else ""))
        hint = (f"hint: against the reference as {cur[0]} ({said}), {cur[1]}, the error "
                f"reaches {worst:.1f} deg; with {opts} it would be {best[0]:.1f} deg: is the "
                f"reference in {best[1]}{', ' + best[2] if best[2] != cur[1] else ''}?")
        if best[0] > HINT_LEFT:
            # no frame explains it: the sensor's axes may differ from the reference's body's
            hint += (f" ({best[0]:.1f} deg is still far off: the sensor's axes may differ from "
                     "the reference's, which --align turns, docs/logs.md)")
        return self.say(hint)
