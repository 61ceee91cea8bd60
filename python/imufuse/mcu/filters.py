"""Library filters on the emulated MCUs, generically from the reference classes.

A reference class (``imufuse.reference.X``) says everything the harness needs: ``c_name`` (the
C prefix: ``<c_name>_t``, ``<c_name>_init``; its update ``c_update``), ``kind`` (the inputs:
``1d`` rate/angle, ``imu`` gyr/acc, ``ahrs`` gyr/acc/mag), ``state_names`` (the state struct
member ``x``, in order) and ``_params(**kw)`` (the C init arguments). The C prototypes are read
from the headers under ``csrc/`` (and ``csrc/fixed/``): the init arguments are matched to the
reference ``_init`` by parameter name, written as exact literals of the C parameter type, and
the update receives the current sample as arrays or as scalars, whatever the prototype asks.
Fixed-point filters are initialised with ``<c_name>_init_consts`` and the integer constants of
the reference's ``c_init_args()`` (computed once in IEEE double, as a host's ``<c_name>_init``
does): avr-gcc's double is 32 bits, so constants computed on the target could differ.

    spec = FilterSpec.make(reference.MadgwickIMU, dict(dt=1/512, beta=0.1), "float32")
    out = run_filters("m0", [spec], inputs_for("float32", "3d", 300))
    out.states[0]      # (N, len(state)) bit patterns after every sample

Several filters share one program (one ELF per target and precision runs them all, every
filter stepping on the same sample); ``run_filters`` splits the set when a program does not fit
the target's flash. Float filters build with ``-DIMF_DOUBLE`` for float64; fixed-point filters
(integer state, int16 inputs) take a ``profile`` keyword instead of a dtype.

The prototypes are read in ``imufuse.mcu.library`` (through imufuse.shared.cproto), the inputs made
in ``imufuse.mcu.samples``, bit patterns converted in ``imufuse.shared.bits``; their names are
importable from here too.
"""

from __future__ import annotations

import dataclasses
import inspect
import shutil
import tempfile
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .. import reference as _reference
from ..reference._base import init_names
from ..shared.checks import KINDS
from ..shared.bits import as_bits, bits_as_values, f32_hex
from .driver import Driver
from .emulators import Result, run_elf
from .library import CSRC, CFilter, c_library, init_call, literal
from .programs import build
from .samples import FIXED_COUNTS, fixed_inputs, float_inputs, inputs_for
from .toolchains import HarnessError

__all__ = [
    "CSRC",
    "CFilter",
    "FilterSpec",
    "GroupResult",
    "c_library",
    "init_call",
    "run_filters",
    "run_fitting",
    "reference_states",
    "INPUT_NAMES",
    "N_MOTION_SMALL",
    "TARGET_PRECISIONS",
    "specs_from_cases",
    "groups",
    "is_fixed_class",
    "as_bits",
    "bits_as_values",
    "f32_hex",
    "FIXED_COUNTS",
    "float_inputs",
    "fixed_inputs",
    "inputs_for",
]

#: the update inputs of each kind, in order
INPUT_NAMES = {**KINDS, "vario": ("accel", "baro_alt", "dt")}   # VarioKF: scalars
_SCALAR_KINDS = ("1d", "vario")

_STATE_KIND = {np.dtype(np.float32): "f32", np.dtype(np.float64): "f64", np.dtype(np.int32): "i32",
               np.dtype(np.int16): "i16", np.dtype(np.uint32): "u32"}


# --------------------------------------------------------------------------------------------
# one filter configuration


@dataclasses.dataclass
class FilterSpec:
    """One filter configuration in one precision (float) or profile (fixed point)."""

    ref_class: Any
    params: Mapping[str, object]
    precision: str            # "float32" | "float64" | "p32" | "p8" (fixed-point profiles)
    label: str = ""
    csrc: Path = CSRC

    @classmethod
    def make(cls, ref_class, params, precision, label="", csrc=CSRC) -> "FilterSpec":
        return cls(ref_class, dict(params), precision, label or ref_class.__name__, Path(csrc))

    # -- what kind of filter
    @property
    def fixed(self) -> bool:
        return self.precision.startswith("p")

    @property
    def kind(self) -> str:
        return self.ref_class.kind

    @property
    def c(self) -> CFilter:
        # fixed point: the array form, as firmware holding its sample in arrays calls it
        update = self.ref_class.c_update_v if self.fixed else self.ref_class.c_update
        return c_library(self.ref_class.c_name, self.csrc, update)

    @property
    def defines(self) -> Dict[str, object]:
        if self.fixed:   # only this profile's update is compiled and linked
            return {"IMF_FIXED_PROFILE": int(self.precision[1:])}
        return {"IMF_DOUBLE": None} if self.precision == "float64" else {}

    @property
    def group(self) -> Tuple[str, str]:
        """Filters of one group can share a program: same build flags, same input set."""
        return (self.precision, self.kind if self.kind in _SCALAR_KINDS else "3d")

    def reference(self):
        if self.fixed:
            return self.ref_class(**self.params, profile=self.precision[1:])
        return self.ref_class(**self.params, dtype=self.precision)

    def input_dtype(self):
        if self.fixed:
            return np.int16
        return np.float32 if self.precision == "float32" else np.float64

    def state_dtype(self) -> np.dtype:
        return np.asarray(self.reference().state).dtype

    # -- C text
    @property
    def init_function(self) -> str:
        """Fixed point: <c_name>_init_consts with the integer constants the reference computes
        (a target's own double may be 32 bits: constants computed there could differ from the
        host's); float: <c_name>_init."""
        if self.fixed:
            if self.c.init_consts is None:
                raise HarnessError(f"{self.label}: {self.c.header.name} declares no "
                                   f"{self.c.c_name}_init_consts()")
            return self.c.c_name + "_init_consts"
        return self.c.c_name + "_init"

    def _init_args(self) -> List[str]:
        ref = self.ref_class
        if self.fixed:
            consts = self.reference().c_init_args()
            cparams = self.c.init_consts
            if cparams is None:
                raise HarnessError(f"{self.label}: no {self.c.c_name}_init_consts() in the headers")
            if [p.name for p in cparams] != list(consts):
                raise HarnessError(
                    f"{self.label}: C {self.init_function}({', '.join(p.name for p in cparams)}) "
                    f"does not match the reference c_init_args() ({', '.join(consts)})")
            return [literal(p, consts[p.name], "") for p in cparams]
        args = ref._params(**self.params, **({"profile": self.precision[1:]} if self.fixed else {}))
        names = list(init_names(ref))
        cparams = self.c.init
        by_name = dict(zip(names, args)) if len(names) == len(args) else {}
        if all(p.name in by_name for p in cparams):
            values = [by_name[p.name] for p in cparams]
        elif len(args) == len(cparams):
            values = list(args)
        else:
            raise HarnessError(
                f"{self.label}: cannot match C init ({', '.join(p.name for p in cparams)}) to the "
                f"reference _params ({', '.join(names)})")
        real = "double" if self.precision == "float64" else "float"
        return [literal(p, v, real) for p, v in zip(cparams, values)]

    def _update_args(self) -> List[str]:
        names = INPUT_NAMES[self.kind]
        width = {n: (1 if self.kind in _SCALAR_KINDS else 3) for n in names}
        cparams = self.c.update
        if len(cparams) == len(names):
            out = []
            for p, n in zip(cparams, names):
                if p.vector != (width[n] == 3):
                    raise HarnessError(f"{self.label}: update parameter {p.name} does not take {n}")
                out.append(n)
            return out
        scalars = [f"{n}[{j}]" if width[n] == 3 else n for n in names for j in range(width[n])]
        if len(cparams) == len(scalars) and not any(p.vector for p in cparams):
            return scalars
        raise HarnessError(f"{self.label}: update takes {len(cparams)} arguments; inputs are {names}")

    def double_init_args(self) -> List[str]:
        """Fixed point: the arguments of <c_name>_init (double parameters), as exact double
        literals of the reference's parameters (firmware that computes its constants)."""
        if not self.fixed:
            raise HarnessError(f"{self.label}: only fixed-point filters have a double init")
        p = self.ref_class._params(**self.params, profile=self.precision[1:])
        return [literal(cp, a, "double") for cp, a in zip(self.c.init, p)]

    def c_parts(self, var: str, double_init: bool = False) -> Tuple[str, str, str, List[Tuple[str, str]]]:
        """(prelude, init, step, state words) for a filter variable named ``var``; fixed point
        with ``double_init``: initialised by <c_name>_init from doubles, not _init_consts."""
        c = self.c
        n = len(self.ref_class.state_names)
        kind = _STATE_KIND[self.state_dtype()]
        ctype = {"f32": "float", "f64": "double", "i32": "int32_t", "i16": "int16_t", "u32": "uint32_t"}[kind]
        prelude = (
            f'#include "{c.header.name}"\n'
            f"static {c.c_name}_t {var};\n"
            f"typedef char {var}_state_is_{n}_words[sizeof({var}.x) == {n}u * sizeof({ctype}) ? 1 : -1];"
        )
        if double_init:
            fill, call = init_call(c.c_name + "_init", var, c.init_struct, c.init,
                             self.double_init_args())
        elif self.fixed:
            fill, call = init_call(self.init_function, var, c.init_consts_struct, c.init_consts or (),
                             self._init_args(), static=False)
        else:
            fill, call = init_call(self.init_function, var, c.init_struct, c.init, self._init_args())
        if c.init_returns != "void":
            init = f'if ({call} != 0) {{ imf_port_write("IMF_FAULT {self.label} init\\n"); }}'
        else:
            init = f"{call};"
        if fill:
            init = f"{{ {fill}\n{init} }}"
        step = f"{c.c_update}(&{var}{''.join(', ' + a for a in self._update_args())});"
        state = [(f"((const {ctype} *)(const void *)&{var}.x)[{k}]", kind) for k in range(n)]
        if c.has_skipped:
            state.append((f"{var}.skipped", "u32"))
        return prelude, init, step, state


# --------------------------------------------------------------------------------------------
# programs of several filters


@dataclasses.dataclass
class GroupResult:
    """The run of a list of FilterSpecs on one target."""

    target: str
    specs: List[FilterSpec]
    states: List[np.ndarray]              # per spec: (N, n_state) bit patterns (uint32/uint64)
    skipped: List[Optional[np.ndarray]]   # per spec: (N,) skipped counter, if the C has one
    results: List[Result]                 # the programs run (several if the set was split)
    programs: List[List[int]]             # spec indices of each program
    cflags: Tuple[str, ...] = ()          # run_filters' extra_cflags (run_fitting's -Os)

    @property
    def seconds(self) -> float:
        return sum(r.seconds for r in self.results)


def _driver(specs: Sequence[FilterSpec], double_init: bool = False) -> Tuple[Driver, List[Tuple[int, int, bool]]]:
    preludes: List[str] = []
    inits: List[str] = []
    steps: List[str] = []
    state: List[Tuple[str, str]] = []
    layout = []
    seen_headers = set()
    for i, s in enumerate(specs):
        pre, ini, stp, st = s.c_parts(f"imf_f{i}", double_init)
        lines = pre.splitlines()
        if lines[0] in seen_headers:
            lines = lines[1:]
        seen_headers.add(pre.splitlines()[0])
        preludes.append("\n".join(lines))
        inits.append(ini)
        steps.append(stp)
        layout.append((len(state), len(st), s.c.has_skipped))
        state.extend(st)
    return Driver(prelude="\n".join(preludes), init="\n".join(inits), step="\n".join(steps),
                  state=state), layout


def _inputs_of(specs: Sequence[FilterSpec], inputs: Mapping[str, np.ndarray]) -> Dict[str, np.ndarray]:
    need = []
    for s in specs:
        for n in INPUT_NAMES[s.kind]:
            if n not in need:
                need.append(n)
    dt = specs[0].input_dtype()
    out = {}
    for n in need:
        a = np.asarray(inputs[n])
        if a.dtype != dt:
            raise HarnessError(f"input {n}: dtype {a.dtype}, the filters take {np.dtype(dt)}")
        out[n] = np.ascontiguousarray(a)
    return out


def run_filters(target: str, specs: Sequence[FilterSpec], inputs: Mapping[str, np.ndarray],
                count: bool = False, workdir: Optional[Path] = None, timeout: float = 300.0,
                max_per_program: Optional[int] = None,
                extra_cflags: Sequence[str] = (), unfit: Optional[List[FilterSpec]] = None,
                objects: Optional[Dict[Any, Any]] = None) -> GroupResult:
    """Run every spec (one group: same precision and input set) on ``target``.

    All filters of a program step on the same sample; the set is split in halves until each
    program fits the target (AVR flash) or has at most ``max_per_program`` filters.
    extra_cflags: after the harness flags, for every source (run_fitting's -Os).
    unfit: a list: a filter whose program does not fit even alone is appended to it and left
    out of the result (its ``specs`` are those that ran) instead of failing the call.
    objects: the sources compiled so far ({}; programs.build), shared by the programs of the
    call (a set split in halves compiles each source once) and by calls given the same dict.
    """
    specs = list(specs)
    if not specs:
        raise ValueError("no filters")
    if len({s.group for s in specs}) != 1:
        raise ValueError(f"filters of different groups: {sorted({s.group for s in specs})}")
    ins = _inputs_of(specs, inputs)
    n = len(next(iter(ins.values())))
    own = workdir is None
    base = Path(tempfile.mkdtemp(prefix=f"imf_filters_{target}_")) if workdir is None else Path(workdir)
    states: List[Optional[np.ndarray]] = [None] * len(specs)
    skipped: List[Optional[np.ndarray]] = [None] * len(specs)
    results: List[Result] = []
    programs: List[List[int]] = []
    objects = {} if objects is None else objects
    left_out: List[int] = []
    try:
        todo = [list(range(len(specs)))]
        if max_per_program:
            todo = [todo[0][k:k + max_per_program] for k in range(0, len(specs), max_per_program)]
        while todo:
            idx = todo.pop(0)
            drv, layout = _driver([specs[i] for i in idx])
            wd = base / f"p{len(programs) + len(todo)}_{idx[0]}_{len(idx)}"
            try:
                elf = build(target, sources=sorted({str(specs[i].c.source) for i in idx}),
                            include_dirs=[specs[0].csrc, specs[0].csrc / "fixed"],
                            defines=specs[0].defines, driver=drv, inputs=ins, n=n, workdir=wd,
                            extra_cflags=extra_cflags, objects=objects)
            except HarnessError as e:
                if "does not fit" in str(e) and len(idx) > 1:
                    h = len(idx) // 2
                    todo[:0] = [idx[:h], idx[h:]]
                    continue
                if "does not fit" in str(e) and unfit is not None:
                    left_out += idx
                    continue
                raise
            res = run_elf(target, elf, n, count=count, timeout=timeout, driver=drv)
            results.append(res)
            programs.append(idx)
            for i, (start, width, has_sk) in zip(idx, layout):
                cols = res.state[:, start:start + width]
                if has_sk:
                    skipped[i] = cols[:, -1].astype(np.uint32)
                    cols = cols[:, :-1]
                states[i] = cols
        done = {i: s for i, s in enumerate(states) if s is not None}
        if len(done) + len(left_out) != len(specs):
            raise HarnessError(f"{target}: {len(specs) - len(done)} filters produced no state")
        if unfit is not None:
            unfit += [specs[i] for i in sorted(left_out)]
        at = {i: k for k, i in enumerate(done)}   # program indices into the specs that ran
        return GroupResult(target, [specs[i] for i in done], list(done.values()),
                           [skipped[i] for i in done], results,
                           [[at[i] for i in p] for p in programs], tuple(extra_cflags))
    finally:
        if own:
            shutil.rmtree(base, ignore_errors=True)


#: samples of motion for a filter whose program does not fit the target's flash with the
#: usual number stored in it (AVR: RobustIMU/RobustAHRS beside 200 samples)
N_MOTION_SMALL = 60


def run_fitting(target: str, specs: Sequence[FilterSpec], n_motion: int,
                n_small: int = N_MOTION_SMALL,
                inputs: Optional[Mapping[str, np.ndarray]] = None,
                **kw) -> Tuple[GroupResult, Mapping[str, np.ndarray]]:
    """``run_filters`` on ``n_motion`` samples of motion (``inputs`` if given, else
    ``inputs_for`` the specs' group), or on ``n_small`` samples where a program of one filter
    does not fit the target's flash with the larger set stored in it; where that does not fit
    either, the same built with -Os after the harness's -O2, as the Arduino IDE builds (the
    same IEEE operations at any optimisation level: RobustAHRS float32 beside its 113 input
    rows on the ATmega328P). Returns the result and the inputs it ran on (the same object as
    ``inputs`` when those fitted)."""
    specs = list(specs)
    if inputs is None:
        inputs = inputs_for(specs[0].precision, specs[0].group[1], n_motion)
    kw.setdefault("objects", {})      # the sources compiled once for the tries below
    try:
        return run_filters(target, specs, inputs, **kw), inputs
    except HarnessError as e:
        if "does not fit" not in str(e):
            raise
    small = inputs_for(specs[0].precision, specs[0].group[1], n_small)
    try:
        return run_filters(target, specs, small, **kw), small
    except HarnessError as e:
        if "does not fit" not in str(e) or kw.get("extra_cflags"):
            raise
    return run_filters(target, specs, small, **kw, extra_cflags=("-Os",)), small


def reference_states(spec: FilterSpec, inputs: Mapping[str, np.ndarray]) -> Tuple[np.ndarray, int]:
    """The reference trajectory as bit patterns (uint32/uint64) and its final skipped count."""
    f = spec.reference()
    args = [np.asarray(inputs[n]) for n in INPUT_NAMES[spec.kind]]
    out = np.asarray(f.run(*args))
    return as_bits(out), int(getattr(f, "skipped", -1))


# --------------------------------------------------------------------------------------------
# the registry


#: precisions each target runs: AVR's double is 32 bits, so no float64 there
TARGET_PRECISIONS = {
    "host": ("float32", "float64", "p32", "p8"),
    "m4f": ("float32", "float64", "p32", "p8"),
    "m0": ("float32", "float64", "p32", "p8"),
    "m3": ("float32", "float64", "p32", "p8"),
    "m7": ("float32", "float64", "p32", "p8"),
    "m33": ("float32", "float64", "p32", "p8"),
    "m55": ("float32", "float64", "p32", "p8"),
    "rv32imac": ("float32", "float64", "p32", "p8"),
    "rv32imafc": ("float32", "float64", "p32", "p8"),
    "avr": ("float32", "p32", "p8"),
}


def is_fixed_class(ref_class) -> bool:
    """Fixed-point reference classes take ``profile`` instead of ``dtype``."""
    return "profile" in inspect.signature(ref_class._params).parameters


def specs_from_cases(cases, reference=None, csrc: Path = CSRC) -> List[FilterSpec]:
    """FilterSpecs of registry cases (objects with ``name``, ``params`` and ``id``): float
    classes in float32 and float64, fixed-point classes in their ``profile`` if the case gives
    one, else in every profile the class is built in (its ``profiles``)."""
    if reference is None:
        reference = _reference
    out = []
    for case in cases:
        cls = getattr(reference, case.name)
        params = dict(case.params)
        if is_fixed_class(cls):
            profiles = ([str(params.pop("profile"))] if "profile" in params
                        else list(getattr(cls, "profiles", ("32", "8"))))
            precisions = ["p" + p for p in profiles]
        else:
            precisions = ["float32", "float64"]
        for p in precisions:
            out.append(FilterSpec.make(cls, params, p, f"{case.id}-{p}", csrc))
    return out


def groups(specs: Sequence[FilterSpec]) -> Dict[Tuple[str, str], List[FilterSpec]]:
    out: Dict[Tuple[str, str], List[FilterSpec]] = {}
    for s in specs:
        out.setdefault(s.group, []).append(s)
    return out
