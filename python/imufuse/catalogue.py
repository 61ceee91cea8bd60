"""The filter catalogue: the one place where each filter declares what the
rest of imufuse needs, and where every harness looks it up.

An entry names a class that exists, with the same name and signature, in
imufuse_c (compiled) and imufuse.reference (pure Python). From the reference
class come, without being written twice:

  kind         "1d" | "imu" | "ahrs": the update()/run() inputs (_checks.KINDS)
  c_name       the C prefix: <c_name>_t, <c_name>_init() (one per family)
  c_update     the C update the filter runs: <c_name>_update() or <c_name>_update_imu()
  state_names  the state variables, in the order of the C state struct
  params       the constructor's keywords and their defaults (_params signature)
  init_args    the C init arguments after `self`, by name (the _init signature)

The entry itself adds what only a user of the filter needs:

  defaults      gains for the demo, the command line, the firmware and MCU
                harnesses and the benchmarks when the user gives none (dt always
                comes from the data); required for every parameter without a
                constructor default
  presets       named parameter sets (resolve_params(..., preset=NAME), the command
                line's --preset): "published" is the settings of the published code
                the filter was ported from, where it states them
  alternatives  groups of parameters that are alternative parametrisations of
                the same thing (Complementary1D: alpha or T): a user's choice of
                one drops the defaults of the others
  estimate      how the state trajectory becomes an orientation estimate (see
                imufuse.shared.estimate.ADAPTERS), or None
  recovery      the samples of sane input the filter needs to come back to the
                right attitude after a hostile burst, as a function of its
                parameters (imufuse.shared.recovery, each with its derivation);
                required for every float and Fusion entry
                (tests/test_hostile.py runs it)

A filter is declared once: its twin class (a public class with a C prefix c_name in
a module of imufuse.reference, which collects it) and its Entry in CATALOGUE below,
whose section (float, fixed, fusion, vario: Entry.section) follows from the class.
The Cython binding of the classes of reference/<family>.py is generated at every
build by tools/bindgen.py from csrc/<family>.h and the twin (Entry.binding).

A new float filter is its C pair, its reference module and one Entry in CATALOGUE
(docs/adding-a-filter.md); tests/test_catalogue.py fails until every harness finds
it. The sections FUSION and VARIO hold the filters with an API of their own (their
own harnesses, see below).
"""
from __future__ import annotations

import difflib
import inspect
from dataclasses import dataclass, field
from typing import Any, Dict, FrozenSet, Iterable, List, Mapping, Optional, Sequence, Tuple

import imufuse_c as compiled

from .reference import _fusion13
from .shared import recovery as _recovery
from . import reference
from .shared.checks import KINDS, check_dtype
from .reference._base import init_names
from .shared.estimate import ADAPTERS, Estimate

__all__ = ["Entry", "FilterError", "CATALOGUE", "FLOAT", "FIXED", "FUSION", "FILTERS_FUSION",
           "FUSION_AHRS", "VARIO", "FILTERS_VARIO",
           "ENTRIES", "ALL_ENTRIES", "FILTERS", "FILTERS_FIXED",
           "entry", "filter_names", "reference_class", "compiled_class", "param_names",
           "resolve_params", "make_filter", "estimate", "why_no_estimate", "inputs_for", "KINDS"]


class FilterError(ValueError):
    """Unknown filter or parameter, or parameters the filter rejects."""


@dataclass(frozen=True)
class Entry:
    """One filter of the catalogue (see the module documentation)."""
    name: str
    defaults: Mapping[str, Any] = field(default_factory=dict)
    alternatives: Tuple[FrozenSet[str], ...] = ()
    estimate: Optional[str] = None
    recovery: Optional[_recovery.Budget] = None
    presets: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    # ---- derived from the reference class: one source for each fact
    @property
    def reference(self) -> Any:
        return getattr(reference, self.name)

    @property
    def compiled(self) -> Any:
        return getattr(compiled, self.name)

    @property
    def section(self) -> str:
        """"float", "fixed", "fusion" or "vario": what the class is (reference.section)."""
        return str(reference.section(self.reference))

    @property
    def fixed(self) -> bool:
        return self.section == "fixed"

    @property
    def kind(self) -> str:
        return self.reference.kind

    @property
    def inputs(self) -> Tuple[str, ...]:
        return KINDS[self.kind]

    @property
    def c_name(self) -> str:
        return self.reference.c_name

    @property
    def c_update(self) -> str:
        return self.reference.c_update

    @property
    def state_names(self) -> Tuple[str, ...]:
        return tuple(self.reference.state_names)

    @property
    def params(self) -> Dict[str, Any]:
        """Constructor keywords -> default (inspect.Parameter.empty: required)."""
        sig = inspect.signature(self.reference._params)
        return {p.name: p.default for p in sig.parameters.values()}

    @property
    def init_args(self) -> Tuple[str, ...]:
        """The C init arguments after `self`, in order: the names of _params' result."""
        return init_names(self.reference)

    @property
    def family(self) -> str:
        """The module of imufuse.reference that declares the filter; a float family's C
        pair is csrc/<family>.c and .h."""
        return str(self.reference.__module__.rpartition(".")[2])

    @property
    def binding(self) -> str:
        """The Cython binding, by the name setup.py includes: fixed_filters.pxi for the
        fixed-point classes and <family>.pxi for a float family. A hand-written binding
        (Fusion, the variometer: APIs of their own) is this file in the checkout; the
        others are generated at every build by tools/bindgen.py from the headers and the
        twins (into build/imufuse_units/ under the same name; `python tools/bindgen.py
        <family>` prints one)."""
        return f"imufuse_c/{'fixed_filters' if self.fixed else self.family}.pxi"

    def full_params(self, params: Mapping[str, Any]) -> Dict[str, Any]:
        """params completed with the constructor's defaults (TypeError for
        unknown or missing keywords)."""
        bound = inspect.signature(self.reference._params).bind(**params)
        bound.apply_defaults()
        return dict(bound.arguments)

    def recovery_budget(self, params: Mapping[str, Any], dtype: str, dt: Optional[float] = None) -> int:
        """Samples of sane input after which the filter constructed with params
        is back at the right attitude (imufuse.shared.recovery); dt: the sample interval
        of filters that take it with every update (the Fusion suite)."""
        if self.recovery is None:
            raise FilterError(f"{self.name}: no recovery budget in the catalogue")
        p = self.full_params(params)
        try:
            n = self.recovery(self.reference, p, p.get("dt", dt), check_dtype(dtype))
        except ValueError as err:
            raise FilterError(f"{self.name}: {err}") from None
        return int(n) + _recovery.MARGIN

    def make(self, backend: str = "c", **kwargs: Any) -> Any:
        """An instance on backend "c" (imufuse_c) or "ref" (imufuse.reference)."""
        if backend not in ("c", "ref"):
            raise FilterError(f"backend: must be 'c' or 'ref', got {backend!r}")
        cls = self.compiled if backend == "c" else self.reference
        return cls(**kwargs)


def _alt(*groups: Iterable[str]) -> Tuple[FrozenSet[str], ...]:
    return tuple(frozenset(g) for g in groups)


_LINEAR = _recovery.linear   # the single-axis filters: linear, budget from the update matrix

# Gains for 100-500 Hz MEMS data. The Mahony family (4.1, 4.2, 4.3) runs at the gains of the
# published Mahony code (Madgwick's MahonyAHRS.c: twoKp = 2 * 0.5, twoKi = 0): the same PI
# correction in every representation. On the seven BROAD development trials they give a
# third of the inclination error of kp 2, ki 0.5 (README table); ki > 0 learns a constant
# gyro bias but winds up during long accelerations, so it stays the user's choice.
_MAHONY = dict(kp=0.5, ki=0.0)
_PUBLISHED_MAHONY = {"published": _MAHONY}
_GYR = 1.0642e-3   # rad/s per count: a 16-bit gyroscope at 2000 deg/s
# Every filter, once; the sections (FLOAT, FIXED, FUSION, VARIO below) follow from each
# class (imufuse.reference.section).
CATALOGUE: Tuple[Entry, ...] = (
    # ---- float filters
    # chapter 2: single axis, Eq. 2.2, 2.5, 2.8
    Entry("Complementary1D", dict(T=0.5), _alt({"alpha", "T"}), estimate="angle", recovery=_LINEAR),
    Entry("Kalman1D", dict(k0=0.01), estimate="angle", recovery=_LINEAR),
    Entry("Mahony1D", dict(kp=2.0), estimate="angle", recovery=_LINEAR),
    # chapter 3: single axis with gyro bias, Eq. 3.3, 3.6/3.9, 3.10-3.12
    Entry("Kalman1DBias", dict(k0=0.01, k1=-0.02), estimate="angle", recovery=_LINEAR),
    Entry("Mahony1DBias", dict(kp=2.0, ki=0.3), estimate="angle", recovery=_LINEAR),
    Entry("Complementary1DBias", dict(kp=2.0, ki=0.3),
          _alt({"kp", "omega0"}, {"ki", "xi"}, {"kp", "xi"}, {"ki", "omega0"}), estimate="angle",
          recovery=_LINEAR),
    # 4.1 and appendix: Mahony in quaternion form; chapter 5: Madgwick
    Entry("MahonyIMU", _MAHONY, estimate="quaternion", recovery=_recovery.mahony,
          presets=_PUBLISHED_MAHONY),
    Entry("MahonyAHRS", _MAHONY, estimate="quaternion", recovery=_recovery.mahony,
          presets=_PUBLISHED_MAHONY),
    # Madgwick's MadgwickAHRS.c: betaDef 0.1 (the constructor's default)
    Entry("MadgwickIMU", estimate="quaternion", recovery=_recovery.madgwick,
          presets={"published": dict(beta=0.1)}),
    Entry("MadgwickAHRS", estimate="quaternion", recovery=_recovery.madgwick,
          presets={"published": dict(beta=0.1)}),
    # appendix: MultiWii 2.2 (its firmware's constants are the constructor's defaults), KK;
    # 4.2 Mahony2D; 4.3 DCM
    Entry("MultiWii", estimate="gravity", recovery=_recovery.multiwii, presets={"published": {}}),
    Entry("KK", dict(kp=0.01), estimate="euler", recovery=_recovery.kk),
    Entry("Mahony2D", _MAHONY, estimate="gravity", recovery=_recovery.mahony),
    Entry("DCM", _MAHONY, estimate="matrix", recovery=_recovery.mahony),
    # imufuse's recommended AHRS (docs/recommended-ahrs.md): its defaults are its own
    Entry("RobustIMU", estimate="quaternion", recovery=_recovery.robust),
    Entry("RobustAHRS", estimate="quaternion", recovery=_recovery.robust),
    # ---- fixed point (csrc/fixed): the float twin's keywords plus the sensor scales
    # and profile; the defaults are those of a 16-bit MEMS IMU (2000 deg/s, 8 g, _GYR below)
    Entry("Complementary1DQ", dict(T=0.5, gyr_scale=_GYR, angle_scale=1e-4),
          _alt({"alpha", "T"}), estimate="angle"),
    Entry("Mahony1DBiasQ", dict(kp=2.0, ki=0.3, gyr_scale=_GYR, angle_scale=1e-4),
          estimate="angle"),
    Entry("KKQ", dict(kp=0.01, gyr_scale=_GYR), estimate="euler"),
    Entry("MultiWiiQ", dict(acc_1g=4096, gyr_scale=_GYR), estimate="gravity"),
    Entry("MahonyIMUQ", dict(kp=1.0, ki=0.05, gyr_scale=_GYR), estimate="quaternion"),
    Entry("MadgwickIMUQ", dict(gyr_scale=_GYR), estimate="quaternion"),
    Entry("RobustIMUQ", dict(gyr_scale=_GYR), estimate="quaternion"),
    Entry("RobustAHRSQ", dict(gyr_scale=_GYR), estimate="quaternion"),
    # ---- the Fusion suite (Longbin's Fusion walkthrough; imufusion 1.2.3): its own API.
    # The generic harnesses construct a filter with dt at init and feed rad/s through
    # update(gyr, acc[, mag]); FusionAHRS takes Fusion's units (deg/s, g), dt with every
    # update and three update forms, FusionOffset returns the corrected gyroscope.
    # tests/test_fusion.py and tests/test_fusion_oracle.py drive them; the command line
    # runs FusionAHRS through imufuse.preprocess.
    Entry("FusionAHRS", dict(convention="NWU", gain=0.5, gyroscope_range=0.0,
                             acceleration_rejection=90.0, magnetic_rejection=90.0,
                             recovery_trigger_period=0), estimate="quaternion",
          recovery=_recovery.fusion_ahrs),
    Entry("FusionOffset", dict(sample_rate=100), recovery=_recovery.fusion_offset),
    # Fusion's current release (1.3; imufusion 1.3.3) beside 1.2.3: the sample period is a
    # setting (sample_rate) that set_sample_period (or run's dt) replaces before an update;
    # start-up can be skipped; FusionBias replaces FusionOffset. tests/test_fusion13.py.
    Entry("FusionAHRS13", dict(sample_rate=100.0, convention="NWU", gain=0.5,
                               gyroscope_range=0.0, acceleration_rejection=0.0,
                               magnetic_rejection=0.0, rejection_timeout=0.0),
          estimate="quaternion", recovery=_recovery.fusion_ahrs13,
          presets={"advanced": dict(_fusion13.ADVANCED)}),
    Entry("FusionBias", dict(sample_rate=100.0, stationary_threshold=3.0, stationary_period=3.0),
          recovery=_recovery.fusion_bias),
    # ---- Nair's variometer: update(accel, baro_alt, dt), its own input kind ("vario"),
    # no attitude. tests/test_vario.py drives it (C vs twin, hostile input, Nair's
    # claims), the MCU runner runs it, bench/test_bench_vario.py times it.
    Entry("VarioKF"),
)

#: the sections: the generic float harnesses, fixed point, the Fusion suite, the variometer
FLOAT: Tuple[Entry, ...] = tuple(e for e in CATALOGUE if e.section == "float")
FIXED: Tuple[Entry, ...] = tuple(e for e in CATALOGUE if e.section == "fixed")
FUSION: Tuple[Entry, ...] = tuple(e for e in CATALOGUE if e.section == "fusion")
VARIO: Tuple[Entry, ...] = tuple(e for e in CATALOGUE if e.section == "vario")
#: the Fusion suite's classes
FILTERS_FUSION: Tuple[str, ...] = tuple(e.name for e in FUSION)
#: x-io Fusion's AHRS: the 1.2.3 port (Longbin's walkthrough) and the current release, 1.3
#: (the one the commands pick by default: compare's default filters)
FUSION_AHRS: Tuple[str, ...] = ("FusionAHRS", "FusionAHRS13")
#: the variometer's classes
FILTERS_VARIO: Tuple[str, ...] = tuple(e.name for e in VARIO)

ENTRIES: Dict[str, Entry] = {e.name: e for e in (*FLOAT, *FIXED)}
#: every entry of every section (the Fusion suite and the variometer included)
ALL_ENTRIES: Dict[str, Entry] = {e.name: e for e in CATALOGUE}
#: every float filter, in catalogue order (imufuse_c and imufuse.reference export them)
FILTERS: Tuple[str, ...] = tuple(e.name for e in FLOAT)
#: every fixed-point filter
FILTERS_FIXED: Tuple[str, ...] = tuple(e.name for e in FIXED)


# ---------------------------------------------------------------------------
# lookup and construction (the command line, demo and harnesses)

def entry(name: str) -> Entry:
    """The catalogue entry of a filter; FilterError naming close matches."""
    try:
        return ENTRIES[name]
    except (KeyError, TypeError):
        if isinstance(name, str) and name in ALL_ENTRIES:
            section = "FUSION" if name in FILTERS_FUSION else "VARIO"
            raise FilterError(f"{name}: has an API of its own (catalogue.{section}), which the "
                              f"generic harnesses cannot drive; valid filters: "
                              f"{', '.join(FILTERS)}") from None
        # suggestions from the names the message lists (and the fixed-point ones after
        # them), compared without case
        listed = list(FILTERS) + list(FILTERS_FIXED)
        lower = {n.lower(): n for n in listed}
        close = [lower[c] for c in difflib.get_close_matches(str(name).lower(), lower, n=3,
                                                             cutoff=0.5)]
        hint = f" (did you mean {', '.join(close)}?)" if close else ""
        raise FilterError(f"unknown filter {name!r}{hint}; valid filters: "
                          f"{', '.join(FILTERS)}; fixed point: {', '.join(FILTERS_FIXED)}") from None


def canonical_name(name: str) -> str:
    """The catalogue's spelling of a filter name given in any case (madgwickahrs ->
    MadgwickAHRS); an unknown name comes back unchanged (entry() then reports it)."""
    if name in ALL_ENTRIES:
        return name
    lower = {n.lower(): n for n in ALL_ENTRIES}
    return lower.get(str(name).lower(), name)


def filter_names(kinds: Optional[Sequence[str]] = None) -> List[str]:
    """Names of the float filters, optionally of some kinds."""
    return [e.name for e in FLOAT if kinds is None or e.kind in kinds]


def reference_class(name: str) -> Any:
    """The pure-Python class of a float filter (FilterError for unknown names)."""
    e = entry(name)
    if e.fixed:
        raise FilterError(f"{name}: a fixed-point filter; valid filters: {', '.join(FILTERS)}")
    return e.reference


def compiled_class(name: str) -> Any:
    return entry(name).compiled


def param_names(name: str) -> List[str]:
    """Keyword parameters of a filter's constructor, dt included."""
    return [p for p in entry(name).params if p != "profile"]


#: keywords of a filter's constructor that runs set as options, not parameters
_RUN_OPTIONS = {"dtype": "--dtype (RunOptions(dtype=))",
                "init": "--init (RunOptions(init=))",
                "init_window": "--init-window (RunOptions(init_window=))",
                "q0": "--init W,X,Y,Z (RunOptions(init=[w, x, y, z]))"}


def resolve_params(name: str, dt: float, overrides: Optional[Mapping[str, Any]] = None,
                   preset: Optional[str] = None) -> Dict[str, Any]:
    """dt plus the entry's defaults (or the named preset's parameters) updated by
    overrides; checks the names."""
    e = entry(name)
    if preset is not None and preset not in e.presets:
        raise FilterError(f"{name}: no preset {preset!r}; "
                          + (f"presets: {', '.join(e.presets)}" if e.presets else
                             "it has no presets"))
    valid = param_names(name)
    overrides = dict(overrides or {})
    for k in overrides:
        if k == "dt":
            raise FilterError("dt: set by the sample rate (--rate or the log's time column)")
        if k not in valid and k in _RUN_OPTIONS and (k == "dtype" or e.kind != "1d"):
            # it read "unknown parameter 'dtype'"
            raise FilterError(f"{name}: {k} is not a parameter but an option of the run: "
                              f"{_RUN_OPTIONS[k]}")
        if k not in valid:
            raise FilterError(f"{name}: unknown parameter {k!r}; valid parameters: "
                              f"{', '.join(v for v in valid if v != 'dt')}")
    params = dict(e.defaults if preset is None else e.presets[preset])
    # a user's alternative parametrisation replaces the default one
    for k in overrides:
        for alt in e.alternatives:
            if k in alt:
                for other in alt - {k}:
                    params.pop(other, None)
    params.update(overrides)
    return {"dt": dt, **params}


def make_filter(name: str, backend: str, dtype: str, params: Mapping[str, Any]) -> Any:
    """A float filter instance: backend "c" (imufuse_c) or "ref" (imufuse.reference)."""
    e = entry(name)
    reference_class(name)
    try:
        return e.make(backend, **params, dtype=check_dtype(dtype))
    except TypeError as err:
        raise FilterError(f"{name}: {err}; valid parameters: "
                          f"{', '.join(v for v in param_names(name) if v != 'dt')}") from None
    except ValueError as err:
        raise FilterError(f"{name}: {err}") from None


# ---------------------------------------------------------------------------
# state -> estimate

def estimate(cls: Any, states: Any) -> Optional[Estimate]:
    """Estimate from the (N, len(state)) trajectory of a filter (class or
    instance, either backend), or None (see why_no_estimate)."""
    e = entry(cls.__name__ if isinstance(cls, type) else type(cls).__name__)
    if e.estimate is None:
        return None
    return ADAPTERS[e.estimate](e.state_names, e.kind, states)


def why_no_estimate(cls: Any) -> str:
    return (f"no orientation estimate derivable from state {', '.join(cls.state_names)} "
            "(see imufuse.shared.estimate)")


def inputs_for(kind: str, data: Any) -> tuple:
    """The run() inputs of a filter kind from simulated data (imufuse.sim)."""
    if kind == "1d":
        return (data.gyr, data.acc_angle)
    if kind == "imu":
        return (data.gyr, data.acc)
    return (data.gyr, data.acc, data.mag)
