"""Library filters on the emulated MCUs, generically from the reference classes.

A reference class (``imufuse.reference.X``) says everything the harness needs: ``c_name`` (the
C prefix: ``<c_name>_t``, ``<c_name>_init``, ``<c_name>_update``), ``kind`` (the inputs:
``1d`` rate/angle, ``imu`` gyr/acc, ``ahrs`` gyr/acc/mag), ``state_names`` (the state struct
member ``x``, in order) and ``_params(**kw)`` (the C init arguments). The C prototypes are read
from the headers under ``csrc/`` (and ``csrc/fixed/``): the init arguments are matched to the
reference ``_init`` by parameter name, written as exact literals of the C parameter type, and
the update receives the current sample as arrays or as scalars, whatever the prototype asks.
Fixed-point filters are initialised with ``<c_name>_init_consts`` and the integer constants of
the reference's ``c_init_args()`` (computed once in IEEE double, as a host's ``<c_name>_init``
does): avr-gcc's double is 32 bits, so constants computed on the target could differ.

    spec = FilterSpec.make(reference.MadgwickIMU, dict(dt=1/512, beta=0.1), "float32")
    out = run_filters("m0", [spec], inputs_for([spec], n=300))
    out.states[0]      # (N, len(state)) bit patterns after every sample

Several filters share one program (one ELF per target and precision runs them all, every
filter stepping on the same sample); ``run_filters`` splits the set when a program does not fit
the target's flash. Float filters build with ``-DIMF_DOUBLE`` for float64; fixed-point filters
(integer state, int16 inputs) take a ``profile`` keyword instead of a dtype.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import re
import struct
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .. import reference as _reference
from .. import sim
from ..sim import flight as sim_flight
from .._checks import KINDS
from .._resources import csrc_dir
from ..cproto import CParam, PrototypeError, find_prototype, init_params, strip_comments
from .driver import Driver
from .emulators import Result, run_elf
from .programs import build
from .toolchains import HarnessError

__all__ = [
    "CSRC",
    "FilterSpec",
    "GroupResult",
    "c_library",
    "init_call",
    "run_filters",
    "INPUT_NAMES",
]

#: csrc/ as shipped in the package (imufuse/csrc)
CSRC = csrc_dir()

#: the update inputs of each kind, in order
INPUT_NAMES = {**KINDS, "vario": ("accel", "baro_alt", "dt")}   # VarioKF: scalars
_SCALAR_KINDS = ("1d", "vario")

_STATE_KIND = {np.dtype(np.float32): "f32", np.dtype(np.float64): "f64", np.dtype(np.int32): "i32",
               np.dtype(np.int16): "i16", np.dtype(np.uint32): "u32"}


# --------------------------------------------------------------------------------------------
# C headers


@dataclasses.dataclass(frozen=True)
class CFilter:
    """What the headers say about one C filter."""

    c_name: str
    header: Path
    source: Path
    init: Tuple[CParam, ...]     # the values init takes (the settings struct's members)
    init_returns: str            # "void" or an integer type (fixed point: 0 = ok)
    update: Tuple[CParam, ...]   # without self
    has_skipped: bool
    init_consts: Optional[Tuple[CParam, ...]] = None  # fixed point: <c_name>_init_consts
    init_struct: Optional[str] = None         # init(self, const T *settings): T
    init_consts_struct: Optional[str] = None  # init_consts(self, const T *consts): T


def _prototype(text: str, func: str) -> Tuple[str, Tuple[CParam, ...]]:
    try:
        p = find_prototype(text, func)
    except PrototypeError as e:
        raise HarnessError(str(e)) from None
    if p is None:
        raise HarnessError(f"no prototype of {func}()")
    if not p.params or not p.params[0].pointer:
        raise HarnessError(f"{func}(): the first parameter must be the filter pointer")
    return p.returns, p.params[1:]


def _init_values(text: str, func: str) -> Tuple[str, Optional[str], Tuple[CParam, ...]]:
    """(returns, settings struct or None, the values): an init that takes a settings
    struct takes its members."""
    ret, _ = _prototype(text, func)
    try:
        got = init_params(text, func)
    except PrototypeError as e:
        raise HarnessError(str(e)) from None
    assert got is not None
    return ret, got[0], got[1]


def init_call(func: str, var: str, struct: Optional[str], params: Sequence[CParam],
              args: Sequence[str]) -> Tuple[str, str]:
    """(declarations, call expression) of init ``func`` on ``&var`` with ``args``:
    positional (no declarations), or (``struct``) through a settings struct ``<var>_set``
    filled member by member (valid C and C++)."""
    if struct is None:
        return "", f"{func}(&{var}{''.join(', ' + a for a in args)})"
    fill = "".join(f" {var}_set.{p.name} = {a};" for p, a in zip(params, args))
    return f"{struct} {var}_set;{fill}", f"{func}(&{var}, &{var}_set)"


def _headers(csrc: Path) -> List[Path]:
    return sorted(csrc.glob("*.h")) + sorted((csrc / "fixed").glob("*.h"))


_HEADER_CACHE: Dict[Tuple[str, str], CFilter] = {}


def c_library(c_name: str, csrc: Path = CSRC) -> CFilter:
    """Find ``<c_name>_init`` in the headers of ``csrc`` and read the filter's prototypes."""
    key = (str(csrc), c_name)
    if key in _HEADER_CACHE:
        return _HEADER_CACHE[key]
    for h in _headers(Path(csrc)):
        text = strip_comments(h.read_text())
        if not re.search(r"\b" + re.escape(c_name) + r"_init\s*\(", text):
            continue
        ret, init_struct, init = _init_values(text, c_name + "_init")
        _, update = _prototype(text, c_name + "_update")
        init_consts, consts_struct = None, None
        if re.search(r"\b" + re.escape(c_name) + r"_init_consts\s*\(", text):
            _, consts_struct, init_consts = _init_values(text, c_name + "_init_consts")
        m = re.search(r"typedef\s+struct\s*\{((?:(?!typedef).)*?)\}\s*" + re.escape(c_name) + r"_t\s*;",
                      text, flags=re.S)
        has_skipped = bool(m and re.search(r"\bskipped\b", m.group(1)))
        src = h.with_suffix(".c")
        if not src.is_file():
            raise HarnessError(f"{c_name}: {h} has no {src.name} next to it")
        cf = CFilter(c_name, h, src, init, ret.replace("static", "").replace("inline", "").strip(),
                     update, has_skipped, init_consts, init_struct, consts_struct)
        _HEADER_CACHE[key] = cf
        return cf
    raise HarnessError(f"no header under {csrc} declares {c_name}_init()")


# --------------------------------------------------------------------------------------------
# literals


def _hex_f32(v: float) -> str:
    v32 = float(np.float32(v))
    if not math.isfinite(v32):
        raise HarnessError(f"non-finite init argument {v!r}")
    return f"{v32.hex()}f" if v32 != 0 else ("-0.0f" if math.copysign(1, v32) < 0 else "0.0f")


def _hex_f64(v: float) -> str:
    if not math.isfinite(v):
        raise HarnessError(f"non-finite init argument {v!r}")
    return v.hex() if v != 0 else ("-0.0" if math.copysign(1, v) < 0 else "0.0")


def _literal(param: CParam, value, real: str) -> str:
    t = param.ctype.replace("const", "").strip()
    if t == "imf_qscale_t":
        m, s = (int(v) for v in (value.m, value.s))
        return f"(imf_qscale_t){{(int16_t){m}, (int16_t)({s})}}"
    if t == "imf_real":
        t = real
    if t == "float":
        return _hex_f32(float(value))
    if t == "double":
        # On AVR double is float: the compiler rounds the exact double literal once, as C's
        # conversion of a double argument would.
        return _hex_f64(float(value))
    if re.fullmatch(r"(unsigned\s+)?(int|long|short|char|u?int(8|16|32|64)_t)", t) or t == "unsigned":
        iv = int(value)
        if iv != value:
            raise HarnessError(f"{param.name}: integer parameter got {value!r}")
        return f"({t}){iv}" if iv >= 0 else f"({t})({iv})"
    raise HarnessError(f"{param.name}: unsupported C parameter type {param.ctype!r}")


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
        return c_library(self.ref_class.c_name, self.csrc)

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
            return [_literal(p, consts[p.name], "") for p in cparams]
        args = ref._params(**self.params, **({"profile": self.precision[1:]} if self.fixed else {}))
        names = list(inspect.signature(ref._init).parameters)[1:]  # drop self
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
        return [_literal(p, v, real) for p, v in zip(cparams, values)]

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
        return [_literal(cp, a, "double") for cp, a in zip(self.c.init, p)]

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
                             self._init_args())
        else:
            fill, call = init_call(self.init_function, var, c.init_struct, c.init, self._init_args())
        if c.init_returns != "void":
            init = f'if ({call} != 0) {{ imf_port_write("IMF_FAULT {self.label} init\\n"); }}'
        else:
            init = f"{call};"
        if fill:
            init = f"{{ {fill}\n{init} }}"
        step = f"{c.c_name}_update(&{var}{''.join(', ' + a for a in self._update_args())});"
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
                max_per_program: Optional[int] = None) -> GroupResult:
    """Run every spec (one group: same precision and input set) on ``target``.

    All filters of a program step on the same sample; the set is split in halves until each
    program fits the target (AVR flash) or has at most ``max_per_program`` filters.
    """
    import shutil
    import tempfile

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
                            defines=specs[0].defines, driver=drv, inputs=ins, n=n, workdir=wd)
            except HarnessError as e:
                if "does not fit" in str(e) and len(idx) > 1:
                    h = len(idx) // 2
                    todo[:0] = [idx[:h], idx[h:]]
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
        done = [s for s in states if s is not None]
        if len(done) != len(specs):
            raise HarnessError(f"{target}: {len(specs) - len(done)} filters produced no state")
        return GroupResult(target, specs, done, skipped, results, programs)
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
    does not fit the target's flash with the larger set stored in it. Returns the result and
    the inputs it ran on (the same object as ``inputs`` when those fitted)."""
    specs = list(specs)
    if inputs is None:
        inputs = inputs_for(specs[0].precision, specs[0].group[1], n_motion)
    try:
        return run_filters(target, specs, inputs, **kw), inputs
    except HarnessError as e:
        if "does not fit" not in str(e):
            raise
    small = inputs_for(specs[0].precision, specs[0].group[1], n_small)
    return run_filters(target, specs, small, **kw), small


def reference_states(spec: FilterSpec, inputs: Mapping[str, np.ndarray]) -> Tuple[np.ndarray, int]:
    """The reference trajectory as bit patterns (uint32/uint64) and its final skipped count."""
    f = spec.reference()
    args = [np.asarray(inputs[n]) for n in INPUT_NAMES[spec.kind]]
    out = np.asarray(f.run(*args))
    return as_bits(out), int(getattr(f, "skipped", -1))


def as_bits(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype == np.float64:
        return a.view(np.uint64)
    if a.dtype == np.float32:
        return a.view(np.uint32)
    if a.dtype.kind == "i":
        return a.astype(np.int64).astype(np.uint32)  # two's complement, as the dumpers print
    return a.astype(np.uint32)


def bits_as_values(bits: np.ndarray, state_dtype) -> np.ndarray:
    dt = np.dtype(state_dtype)
    if dt == np.float64:
        return bits.astype(np.uint64).view(np.float64)
    if dt == np.float32:
        return bits.astype(np.uint32).view(np.float32)
    return bits.astype(np.uint32).view(np.int32)


def f32_hex(v: float) -> str:
    return struct.pack(">f", v).hex()


# --------------------------------------------------------------------------------------------
# inputs


def _rows(n_rows, fill):
    return np.tile(np.asarray(fill, dtype=np.float64), (n_rows, 1))


def float_inputs(group: str, n_motion: int = 300, seed: int = 5) -> Dict[str, np.ndarray]:
    """Float64 inputs of a group ("1d" or "3d"): realistic motion from imufuse.sim, then the
    corners (zero accelerometer/magnetometer, all zero, NaN/Inf in each input, overflow,
    tiny and subnormal values), then motion again. Cast to float32 for the float32 builds."""
    tail = 20
    if group == "1d":
        d = sim.axis1d("fast", rate=100.0, duration=(n_motion + tail) / 100.0, seed=seed,
                       disturbance=0.05)
        rate, angle = np.asarray(d.gyr, float), np.asarray(d.acc_angle, float)
        head_r, head_a = rate[:n_motion], angle[:n_motion]
        tail_r, tail_a = rate[n_motion:], angle[n_motion:]
        cr = [0.0] * 6 + [np.nan, 0.3, -np.inf, np.inf, np.nan, 0.2, 0.1, -0.1] \
            + [3e38, -3e38, 1e30, 1.0] + [1e-40, -3e-42, 1e-30, 0.0] + [1e5, -1e5]
        ca = [0.0] * 6 + [0.1, np.inf, 0.2, -0.3, np.nan, -np.inf, np.nan, 0.05] \
            + [-3e38, 3e38, -1e30, 3e38] + [-1e-40, 1e-45, -1e-30, 1e-38] + [3.0, -3.0]
        return {"rate": np.concatenate([head_r, cr, tail_r]),
                "angle": np.concatenate([head_a, ca, tail_a])}
    if group == "vario":
        return _vario_inputs(n_motion, seed, tail)
    if group != "3d":
        raise ValueError(f"group must be '1d', 'vario' or '3d', got {group!r}")
    d = sim.imu("fast", rate=100.0, duration=(n_motion + tail) / 100.0, seed=seed, lin_acc=1.0,
                amplitude=3.0)
    gyr, acc, mag = (np.asarray(a, float) for a in (d.gyr, d.acc, d.mag))
    g0, a0, m0 = gyr[n_motion - 1], acc[n_motion - 1], mag[n_motion - 1]
    cg, ca, cm = [], [], []

    def add(k, g=None, a=None, m=None):
        cg.append(_rows(k, g0 if g is None else g))
        ca.append(_rows(k, a0 if a is None else a))
        cm.append(_rows(k, m0 if m is None else m))

    add(6, a=[0, 0, 0])                      # zero accelerometer: the guard
    add(6, m=[0, 0, 0])                      # zero magnetometer
    add(3, g=[0, 0, 0], a=[0, 0, 0], m=[0, 0, 0])
    add(1, g=[np.nan, 0.1, 0.2])
    add(1, a=[0.1, np.inf, 1.0])
    add(1, m=[0.3, 0.1, -np.inf])
    add(1, a=[np.nan, 0.0, 1.0])
    add(1, g=[np.inf, -np.inf, 0.0], m=[np.nan, 0, 0])
    add(2, a=[3e38, -3e38, 3e38], m=[-3e38, 3e38, 3e38])   # overflow in the norms
    add(2, g=[1e30, -1e30, 1e30])
    add(2, a=[1e-20, -1e-20, 1e-20], m=[1e-20, 1e-20, -1e-20])  # squares underflow
    add(2, a=[1e-40, 0, 3e-41], m=[0, -1e-40, 0])             # subnormal components
    add(2, g=[25.0, -30.0, 35.0])                             # fast spin
    add(3, a=[1.0, 0.0, 1e-3])                                # nearly vertical
    return {"gyr": np.concatenate([gyr[:n_motion], *cg, gyr[n_motion:]]),
            "acc": np.concatenate([acc[:n_motion], *ca, acc[n_motion:]]),
            "mag": np.concatenate([mag[:n_motion], *cm, mag[n_motion:]])}


def _vario_inputs(n_motion, seed, tail):
    """Nair's variometer: a simulated flight at the barometer rate (vertical
    acceleration cm/s^2, barometer altitude cm, dt s), then the corners (NaN/Inf
    in each input, dt <= 0, overflow, tiny values), then the flight again."""
    fl = sim_flight.flight(duration=(n_motion + tail) / 50.0 + 1.0, seed=seed)
    idx = fl.baro_idx[:n_motion + tail]
    acc = np.diff(fl.climb, prepend=fl.climb[0])[idx] * fl.rate * 100.0 + 20.0
    alt = fl.baro_alt[:n_motion + tail] * 100.0
    dt = np.full(n_motion + tail, 0.02)
    ca = [np.nan, 1.0, 2.0, np.inf, 0.0, 0.0, 3e38, -3e38, 1e-40, 0.0, 5.0, -5.0]
    cz = [alt[n_motion - 1], np.nan, 1e5, 1e5, -np.inf, 1e5, 3e38, 1e5, 1e-40, 1e5, 1e5, 1e5]
    cd = [0.02, 0.02, -np.inf, 0.02, 0.02, 0.0, 0.02, 1e30, 1e-30, -0.02, 0.5, 0.001]
    return {"accel": np.concatenate([acc[:n_motion], ca, acc[n_motion:]]),
            "baro_alt": np.concatenate([alt[:n_motion], cz, alt[n_motion:]]),
            "dt": np.concatenate([dt[:n_motion], cd, dt[n_motion:]])}


#: int16 counts per unit of the fixed-point inputs (gyro +-2000 deg/s, acc +-8 g, angle +-pi)
FIXED_COUNTS = {"rate": 32768 / math.radians(2000.0), "gyr": 32768 / math.radians(2000.0),
                "angle": 32768 / math.pi, "acc": 4096.0, "mag": 1000.0}


def fixed_inputs(group: str, n_motion: int = 300, seed: int = 5) -> Dict[str, np.ndarray]:
    """int16 counts of the same motion (scales FIXED_COUNTS), with the corners: zero vectors,
    full-scale and minimum counts."""
    src = float_inputs(group, n_motion, seed)
    out = {}
    for name, a in src.items():
        a = a.copy()
        a[~np.isfinite(a)] = 0.0
        c = np.clip(np.rint(a * FIXED_COUNTS[name]), -32768, 32767)
        out[name] = c.astype(np.int16)
    k = n_motion
    for name, a in out.items():          # extremes right after the float corners' place
        ext = np.full((6,) + a.shape[1:], 32767, np.int16)
        ext[1::2] = -32768
        out[name] = np.concatenate([a[:k], ext, a[k:]])
    return out


def inputs_for(precision: str, group: str, n_motion: int = 300, seed: int = 5) -> Dict[str, np.ndarray]:
    """The inputs of a (precision, group) in the dtype the builds take."""
    if precision.startswith("p"):
        return fixed_inputs(group, n_motion, seed)
    dt = np.float32 if precision == "float32" else np.float64
    with np.errstate(over="ignore", under="ignore"):
        return {k: v.astype(dt) for k, v in float_inputs(group, n_motion, seed).items()}


# --------------------------------------------------------------------------------------------
# the registry


#: precisions each target runs: AVR's double is 32 bits, so no float64 there
TARGET_PRECISIONS = {
    "host": ("float32", "float64", "p32", "p8"),
    "m4f": ("float32", "float64", "p32", "p8"),
    "m0": ("float32", "float64", "p32", "p8"),
    "avr": ("float32", "p32", "p8"),
}


def is_fixed_class(ref_class) -> bool:
    """Fixed-point reference classes take ``profile`` instead of ``dtype``."""
    return "profile" in inspect.signature(ref_class._params).parameters


def specs_from_cases(cases, reference=None, csrc: Path = CSRC) -> List[FilterSpec]:
    """FilterSpecs of registry cases (objects with ``name``, ``params`` and ``id``): float
    classes in float32 and float64, fixed-point classes in their ``profile`` if the case gives
    one, else in both profiles."""
    if reference is None:
        reference = _reference
    out = []
    for case in cases:
        cls = getattr(reference, case.name)
        params = dict(case.params)
        if is_fixed_class(cls):
            profiles = [str(params.pop("profile"))] if "profile" in params else ["32", "8"]
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
