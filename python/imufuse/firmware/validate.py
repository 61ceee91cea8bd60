"""Running the user's firmware and the imufuse filter on the same inputs and comparing them
(``validate``): on the host (imufuse.firmware.host) or on an emulated MCU
(imufuse.firmware.target_build, target_run). When they differ: the largest orientation
difference, and the build causes found (imufuse.firmware.causes), each confirmed by rebuilding
with its fix.
"""
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any, List, Mapping, Optional, Sequence

import numpy as np

import imufuse_c

from .. import reference
from ..shared.bits import compare_states, integer_label
from ..catalogue import FUSION_AHRS as FUSIONS
from ..catalogue import entry, make_filter
from ..mcu import toolchains as _tc
from .causes import (Cause, angle_divergence_deg, double_promotions, find_causes,
                     quaternion_angles_deg)
from .declaration import FirmwareError
from .diagnostics import explain_source
from .hil import DEFAULT_BAUD, BoardCost, Link
from .host import Firmware
from .results import Cost, Validation
from .sanitize import RunInputs
from .target_build import _tool_prefix, build_program
from .target_run import run_program
from .targets import DEFAULT_TARGET_CFLAGS, TargetError, harness_target, speed_note

__all__ = ["validate", "counts_for", "mag_counts_scale"]


def mag_counts_scale(mag: Any) -> float:
    """Counts per unit of a magnetometer log for a fixed-point filter (any unit: B4 compares
    the field with its own reference): 4096, halved until the largest finite reading is below
    2^14 counts (a log in uT, 25-65 uT, would saturate int16 at 4096 per unit)."""
    a = np.abs(np.asarray(mag, dtype=np.float64))
    peak = float(a[np.isfinite(a)].max()) if np.isfinite(a).any() else 0.0
    scale = 4096.0
    while peak * scale >= 16384.0 and scale > 2.0 ** -40:
        scale /= 2.0
    return scale


def counts_for(kind: str, params: Mapping[str, Any], inputs: Sequence[Any]) -> List[np.ndarray]:
    """int16 counts of float inputs for a fixed-point filter: the gyro by params' gyr_scale
    (rad/s per count), angles by angle_scale (rad per count), the accelerometer (any unit:
    it is normalised; g in logs) at 4096 counts per unit, the magnetometer by
    mag_counts_scale."""
    out = []
    for k, a in enumerate(inputs):
        a = np.asarray(a, dtype=np.float64)
        if k == 0:
            c = a / params["gyr_scale"]
        elif kind == "1d":
            c = a / params["angle_scale"]
        elif k == 2:
            c = a * mag_counts_scale(a)
        else:
            c = a * 4096.0
        out.append(np.clip(np.rint(c), -32768, 32767).astype(np.int16))
    return out


def _state_names(fw, name, e):
    """The firmware's state names, which must be the imufuse filter's."""
    names = tuple(fw.state)
    if getattr(fw, "partial_state", False) and names and set(names) <= set(e.state_names):
        return names            # a declared API may expose part of the state
    if set(names) != set(e.state_names):
        raise FirmwareError(f"state mapping names {list(names)}; {name} has state "
                            f"{list(e.state_names)}")
    return names


def _strip_arch(flags):
    return [f for f in flags if not f.startswith(("-mmcu", "-mcpu", "-mfpu", "-mfloat-abi",
                                                  "-mthumb", "-march", "-mtune"))]


def _defs_incs(fw):
    defs = [f"-D{k}" if v is None else f"-D{k}={v}" for k, v in fw.defines.items()]
    return defs + [f"-I{d}" for d in fw.include_dirs] + \
        [f"-I{d}" for d in sorted({os.path.dirname(s) for s in fw.sources})]


class _FusionEntry:
    """x-io Fusion's AHRS for validate (outside the float catalogue): FusionAHRS (1.2.3) or
    FusionAHRS13 (1.3). Fusion's units (the gyroscope in deg/s, as Fusion's C takes it), the
    period from params' dt with every update (1.3: its sample period set before each update),
    every setting a C init value by name; the orientation from q0..q3."""
    kind = "ahrs"
    fixed = False

    def __init__(self, name="FusionAHRS"):
        self.name = name
        self.reference = getattr(reference, name)
        self.state_names = tuple(self.reference.state_names)

    @staticmethod
    def settings(params):
        return {k: v for k, v in params.items() if k != "dt"}

    def make(self, backend, dtype, params):
        mod = imufuse_c if backend == "c" else reference
        try:
            return getattr(mod, self.name)(**self.settings(params), dtype=dtype)
        except (TypeError, ValueError) as err:
            raise FirmwareError(f"{self.name}: {err}") from None


_FUSION: dict = {}


def _filter_entry(name):
    if name in FUSIONS:
        if name not in _FUSION:
            _FUSION[name] = _FusionEntry(name)
        return _FUSION[name]
    return entry(name)


class _FusionRun:
    """A FusionAHRS whose run() takes dt from params, as the generic filters do."""

    def __init__(self, f, dt):
        self.f, self.dt = f, dt

    @property
    def state(self):
        return self.f.state

    def run(self, *inputs):
        return self.f.run(*inputs, dt=self.dt)


def _make(name, backend, dtype, params):
    e = _filter_entry(name)
    if isinstance(e, _FusionEntry):
        if "dt" not in params:
            raise FirmwareError(f"{name}: give dt (the sample period; Fusion takes it with "
                                "every update)")
        return _FusionRun(e.make(backend, dtype, params), params["dt"])
    if e.fixed:
        try:
            return e.make(backend, **params)
        except (TypeError, ValueError) as err:
            raise FirmwareError(f"{name}: {err}") from None
    return make_filter(name, backend, dtype, params)


def _reference_run(name, params, inputs, backend, dtype):
    """The imufuse filter's trajectory on the inputs (rounded to dtype first, as run() does);
    returns (inputs as given to both, want, initial state)."""
    e = _filter_entry(name)
    if e.fixed:
        inputs = [np.asarray(a) for a in inputs]
        for a in inputs:
            if a.dtype.kind not in "iu" or np.any(a < -32768) or np.any(a > 32767):
                raise FirmwareError(f"{name} takes int16 counts; got {a.dtype} inputs")
        inputs = [a.astype(np.int16) for a in inputs]
    else:
        inputs = [np.asarray(a, dtype=dtype) for a in inputs]
    f = _make(name, backend, dtype, params)
    state0 = np.asarray(f.state).astype(np.float64)
    want = np.asarray(f.run(*inputs))
    return inputs, want, state0


def validate(fw: "Firmware", name: str, params: Mapping[str, Any], inputs: Sequence[Any],
             backend: str = "c", dtype: Optional[str] = None, target: str = "host",
             timeout: float = 60.0, explain: bool = True, port: Optional[str] = None,
             baud: int = DEFAULT_BAUD) -> "Validation":
    """Run firmware `fw` and the imufuse filter `name` (constructor keywords
    `params`, dt included) on the same inputs; return a Validation. dtype:
    the imufuse precision; default the firmware's (from sizeof of its state);
    the inputs are rounded to it first, as imufuse's run() does. A fixed-point
    filter (`...Q`) is compared as integers, on int16 count inputs.

    target: "host" (cffi, in this process) or an emulated MCU ("cortex-m4f",
    "cortex-m0", "atmega328p"): built there with the firmware's flags (default
    "-O2" for a cross target), run sample by sample on the emulator (logs of any
    length), with the cost per update. explain: when not bit-exact, look for the
    cause in what was built and confirm it by rebuilding with its fix.

    port: a serial port of a board whose firmware runs the HIL runner (csrc/hil/imf_hil.h) at
    `baud`: the states and counts come from the board (imufuse.firmware.hil); the causes of a
    divergence from the same sources built for `target` (when not "host") with the flags."""
    if port is not None:
        return _validate_port(fw, name, params, inputs, backend, dtype, target, timeout,
                              explain, port, baud)
    if target != "host":
        return _validate_target(fw, name, params, inputs, backend, dtype, target, timeout, explain)
    e = _filter_entry(name)
    c_args = _c_values(e, params)
    names = _state_names(fw, name, e)
    fw_dtype = fw.dtype(e.kind, c_args, params)
    integer = np.dtype(fw_dtype).kind in "iu"
    if integer != e.fixed:
        raise FirmwareError(
            f"the firmware's state is {fw_dtype}; {name}'s state is "
            f"{'integer' if e.fixed else 'floating point'}, so they cannot be equal bit for bit "
            "(an integer state is compared as integers, with a fixed-point filter ...Q)")
    if not integer:
        dtype = dtype or fw_dtype
        if dtype != fw_dtype:
            raise FirmwareError(f"the firmware's state is {fw_dtype}, asked to compare with {dtype}")
    inputs, want, state0 = _reference_run(name, params, inputs, backend, dtype)
    order = [e.state_names.index(n) for n in names]
    want = want[:, order]
    got = fw.run(e.kind, inputs, params["dt"], c_args, params, state0[order])
    label = got.dtype.name          # the firmware's integer type, compared as int64
    if integer:
        got, want = got.astype(np.int64), want.astype(np.int64)
    v = Validation(name, backend, compare_states(got, want, names, label), got, want, "host",
                   tuple(fw.cflags))
    if not v.bit_exact:
        v.max_angle_deg = _angle(name, params, got, want, names)
        if explain and not integer:
            _explain_host(v, fw, name, params, inputs, backend, dtype)
    return v


def _angle(name, params, got, want, names):
    e = _filter_entry(name)
    if tuple(names) != tuple(e.state_names):
        order = [list(names).index(n) for n in e.state_names]
        got, want = got[:, order], want[:, order]
    if isinstance(e, _FusionEntry):
        return float(np.max(quaternion_angles_deg(got[:, :4], want[:, :4]), initial=0.0))
    try:
        return angle_divergence_deg(name, dict(params), got, want, e.fixed)
    except Exception:  # noqa: BLE001 - the angle is extra information, never a failure
        return None


def _explain_host(v, fw, name, params, inputs, backend, dtype):
    """Compile the sources with the firmware's flags, look at the objects, confirm; then what
    the source and its runs say (imufuse.firmware.diagnostics: the code run up to the
    divergence, undefined behaviour, the data model, a changed constant, the warnings)."""
    cc = os.environ.get("CC", "cc")
    if shutil.which(cc) is None:
        return
    wd = Path(tempfile.mkdtemp(prefix="imf_fw_explain_"))
    try:
        incs = [f"-I{d}" for d in fw.include_dirs] + \
            [f"-I{d}" for d in sorted({os.path.dirname(s) for s in fw.sources})]
        defs = [f"-D{k}" if val is None else f"-D{k}={val}" for k, val in fw.defines.items()]
        cmd = [cc, *fw.cflags, *defs, *incs]
        objs = []
        for i, src in enumerate(fw.sources):
            obj = wd / f"fw{i}.o"
            if subprocess.run([*cmd, "-c", src, "-o", str(obj)], capture_output=True).returncode == 0:
                objs.append(obj)
        v.causes = find_causes("objdump", objs, fw.sources, fw.cflags, cmd, v.comparison.dtype,
                               "host", False, wd)

        def rerun(extra, sources=None, include_dirs=()):
            fixed = type(fw).__new__(type(fw))
            fixed.__dict__.update(fw.__dict__)
            fixed.cflags = [*fw.cflags, *extra]
            if sources is not None:
                fixed.sources = list(sources)
                fixed.include_dirs = list(include_dirs)
            fixed._lib = None
            return validate(fixed, name, params, inputs, backend, dtype, explain=False).bit_exact

        _confirm(v.causes, rerun)
        _explain_source(v, fw, name, params, inputs, backend, dtype, cmd, wd,
                        lambda srcs, dirs: rerun([], srcs, dirs))
    finally:
        shutil.rmtree(wd, ignore_errors=True)


def _explain_source(v, fw, name, params, inputs, backend, dtype, cmd, wd, rerun_sources):
    """What the source and its runs on the host say (imufuse.firmware.diagnostics): source
    causes, the same wherever the firmware ran (undefined behaviour is undefined on every
    target; the data model names what differs between them). cmd: the host compiler with
    the firmware's flags; rerun_sources(sources, include_dirs): the validation where it ran,
    rebuilt from other sources (bit-exact or not)."""
    e = _filter_entry(name)
    s0 = np.asarray(_make(name, backend, dtype, params).state, dtype=np.float64)
    run = RunInputs.of(fw, e.kind, _c_values(e, params), params,
                       s0[[e.state_names.index(n) for n in fw.state]], inputs)
    try:
        explain_source(v, fw, params, run, cmd, wd, rerun_sources)
    except Exception as err:  # noqa: BLE001 - the diagnostics add to the report, never fail it
        v.notes.append(f"the source's diagnostics failed: {type(err).__name__}: {err}")


def _confirm(causes, rerun):
    """Rebuild with each cause's fix (and with all of them when none suffices alone)."""
    fixes = [c for c in causes if c.fix]
    for c in fixes:
        try:
            c.confirmed = rerun([c.fix])
        except FirmwareError:
            c.confirmed = None
    if len(fixes) > 1 and not any(c.confirmed for c in fixes):
        flags = " ".join(c.fix for c in fixes)
        try:
            causes.append(Cause("together", "", flags, rerun([c.fix for c in fixes])))
        except FirmwareError:
            pass


def _c_values(e, params):
    """The imufuse filter's C init values by name, in the C init's order."""
    if isinstance(e, _FusionEntry):
        return e.settings(params)
    args = e.reference._params(**params)
    names = list(e.init_args)
    if len(names) != len(args):
        return tuple(args)
    return dict(zip(names, args))


def _validate_target(fw, name, params, inputs, backend, dtype, target, timeout, explain,
                     cflags=None):
    e = _filter_entry(name)
    c_args = _c_values(e, params)
    names = _state_names(fw, name, e)
    flags = list(cflags if cflags is not None else
                 (fw.cflags_given if fw.cflags_given is not None else DEFAULT_TARGET_CFLAGS))
    init_values = fw._init_values(c_args, params) if fw.init else []
    if hasattr(fw, "bind"):            # a declared API: its init literals
        fw.bind(c_args, params)
    ref0 = _make(name, backend, dtype or "float32", params)
    state0_all = np.asarray(ref0.state).astype(np.float64)
    order = [e.state_names.index(n) for n in names]
    c89 = any(f in ("-ansi", "-std=c89", "-std=c90", "-std=iso9899:1990", "-std=iso9899:199409")
              for f in flags)
    driver = fw.target_source(e.kind, init_values, params["dt"], state0_all[order], c89)
    _, row = fw._update_plan(e.kind)
    in_dtype = np.dtype(np.int16) if e.fixed else (np.dtype(dtype) if dtype else None)
    try:
        prog = build_program(fw, target, e.kind, driver, row, flags, in_dtype)
    except (_tc.ToolchainMissing, TargetError) as err:
        raise FirmwareError(str(err)) from None
    # every refusal below, and the comparison, leave no build behind
    try:
        types = prog.types
        integer = {t.integer for t in types}
        if len(integer) > 1:
            raise FirmwareError("state expressions mix integer and floating-point types on the "
                                f"{target}")
        integer_state = integer == {True}
        if integer_state != e.fixed:
            raise FirmwareError(
                f"the firmware's state is {'integer' if integer_state else 'floating point'} on the "
                f"{target}; {name}'s is {'integer' if e.fixed else 'floating point'}: compare an "
                "integer firmware with a fixed-point filter (...Q)")
        notes = [speed_note(target)]
        arch = [f for f in flags if f.startswith(("-mcpu", "-mfpu", "-mfloat-abi", "-mmcu", "-march"))]
        if arch:
            tgt_flags = " ".join(_tc.TARGETS[harness_target(target)].arch_flags)
            notes.append(f"your --cflags set the architecture ({' '.join(arch)}) after the "
                         f"target's ({tgt_flags}); the emulator models the {target}")
        if not integer_state:
            sizes = {t.size for t in types}
            if len(sizes) > 1:
                raise FirmwareError(f"state expressions must all be float or all double; sizes "
                                    f"{sorted(sizes)} on the {target}")
            fw_dtype = "float32" if sizes == {4} else "float64"
            if dtype and dtype != fw_dtype:
                raise FirmwareError(f"the firmware's state is {fw_dtype} on the {target}, asked to "
                                    f"compare with {dtype}")
            dtype = fw_dtype
            if np.dtype(dtype) != prog.in_dtype:
                shutil.rmtree(prog.workdir, ignore_errors=True)
                try:
                    prog = build_program(fw, target, e.kind, driver, row, flags, np.dtype(dtype))
                except TargetError as err:
                    raise FirmwareError(str(err)) from None
            if target == "atmega328p":
                if any(t.double for t in types):
                    notes.append("the firmware's state is declared double, which avr-gcc makes 32 "
                                 "bits: it is compared with imufuse in float32")
                # what the host compiler (64-bit double) says about the same sources
                host = [os.environ.get("CC", "cc"), *_strip_arch(flags), *_defs_incs(fw)]
                promo = double_promotions(host, fw.sources, prog.workdir)
                if promo:
                    notes.append("the firmware computes in double at " + ", ".join(promo[:4]) +
                                 (f" (+{len(promo) - 4} more)" if len(promo) > 4 else "") +
                                 ": avr-gcc's double is 32 bits, so here that is float32 arithmetic; "
                                 "built where double is 64 bits (Cortex-M4F, a PC) it rounds "
                                 "differently (-fsingle-precision-constant or float literals 0.5f)")
        return _finish_target(fw, name, params, inputs, backend, dtype, target, timeout, explain,
                              flags, prog, types, integer_state, notes, order, names, row, e)
    finally:
        shutil.rmtree(prog.workdir, ignore_errors=True)


def _finish_target(fw, name, params, inputs, backend, dtype, target, timeout, explain, flags,
                   prog, types, integer_state, notes, order, names, row, e):
    inputs, want, state0 = _reference_run(name, params, inputs, backend, dtype)
    want = want[:, order]
    x = np.column_stack([np.asarray(a).reshape(len(a), -1) for a in inputs]) if len(inputs[0]) \
        else np.zeros((0, row), dtype=prog.in_dtype)
    try:
        run = run_program(prog, x, timeout)
    except TargetError as err:
        raise FirmwareError(str(err)) from None
    if integer_state:
        got = np.column_stack(run.states) if run.states else np.zeros((len(x), 0), np.int64)
        want = want.astype(np.int64)
    else:
        got = np.column_stack(run.states).astype(dtype) if run.states else \
            np.zeros((len(x), 0), dtype)
    counts = run.counts
    cost = Cost(run.count_unit, int(counts.min()) if counts.size else 0,
                float(np.median(counts)) if counts.size else 0.0,
                int(counts.max()) if counts.size else 0, prog.flash, prog.ram, run.stack,
                prog.library, prog.library_flash, counts)
    label = integer_label([(t.size, t.signed) for t in prog.types]) if integer_state else None
    v = Validation(name, backend, compare_states(got, want, names, label), got, want, target,
                   tuple(flags), notes=notes, cost=cost,
                   timing=dict(build=prog.build_seconds,
                               build_cached=1.0 if prog.cached else 0.0,
                               emulator=run.emulator_seconds,
                               parse=run.parse_seconds, chunks=run.chunks,
                               samples=float(len(x))))
    if not v.bit_exact:
        v.max_angle_deg = _angle(name, params, got, want, names)
    if explain and not v.bit_exact and not integer_state:
        tgt = _tc.TARGETS[harness_target(target)]
        v.causes = find_causes(_tool_prefix(tgt) + "objdump", prog.user_objects, fw.sources,
                                  flags, [tgt.cc, *tgt.arch_flags, *flags, *_defs_incs(fw)], dtype,
                                  target, any(t.double for t in types), prog.workdir)
        _confirm(v.causes, lambda extra: _validate_target(
            fw, name, params, inputs, backend, dtype, target, timeout, False,
            [*flags, *extra]).bit_exact)
        cc = os.environ.get("CC", "cc")
        if shutil.which(cc) is not None:
            def rerun_sources(srcs, dirs):
                fixed = type(fw).__new__(type(fw))
                fixed.__dict__.update(fw.__dict__)
                fixed.sources, fixed.include_dirs, fixed._lib = list(srcs), list(dirs), None
                return _validate_target(fixed, name, params, inputs, backend, dtype, target,
                                        timeout, False, flags).bit_exact
            wd = Path(tempfile.mkdtemp(prefix="imf_fw_explain_"))
            try:
                _explain_source(v, fw, name, params, inputs, backend, dtype,
                                [cc, *_strip_arch(flags), *_defs_incs(fw)], wd, rerun_sources)
            finally:
                shutil.rmtree(wd, ignore_errors=True)
    return v


def _validate_port(fw, name, params, inputs, backend, dtype, target, timeout, explain, port,
                   baud):
    """validate() on a board over a serial port (imufuse.firmware.hil.Link)."""
    e = _filter_entry(name)
    names, (_, row) = _state_names(fw, name, e), fw._update_plan(e.kind)
    flags = tuple(fw.cflags_given or ())       # the board's build is the user's, unseen
    try:
        with Link(port, baud, timeout) as link:
            h = link.hello()
            dtype = link.expect(name, row, len(names), e.fixed, dtype)
            inputs, want, _ = _reference_run(name, params, inputs, backend, dtype)
            x = np.column_stack([np.asarray(a).reshape(len(a), -1) for a in inputs])
            run = link.run(x.astype(h.in_dtype))
    except TargetError as err:
        raise FirmwareError(str(err)) from None
    want = want[:, [e.state_names.index(n) for n in names]]
    got = np.column_stack(run.states) if run.states else np.zeros((len(x), 0))
    got, want = (got.astype(np.int64), want.astype(np.int64)) if e.fixed else (got.astype(dtype), want)
    notes = [f"link: {ev}" for ev in link.events]
    c = run.counts
    cost = BoardCost(h.count_unit, int(c.min()), float(np.median(c)), int(c.max()), None, 0, run.stack,
                     counts=c) if c is not None and c.size else None
    if c is None:
        notes.append("the board's runner has no counter: no cost per update")
    label = integer_label([(t & 0xFF, bool(t & 0x200)) for t in h.types]) if e.fixed else None
    cmp = compare_states(got, want, names, label)
    where = f"{target} board" if target != "host" else "board"
    v = Validation(name, backend, cmp, got, want, where, flags, notes=notes, cost=cost,
                   title=f"firmware {h.name!r} on the {where} at {port}, {baud} baud (flags "
                   f"{' '.join(flags) or 'of its build, not given'}) vs imufuse {name} "
                   f"({backend}, {cmp.dtype}):",
                   timing=dict(board=run.seconds, samples=float(len(x)), repeats=run.repeats))
    v.max_angle_deg = None if v.bit_exact else _angle(name, params, got, want, names)
    if explain and not v.bit_exact and target != "host":
        tv = _validate_target(fw, name, params, inputs, backend, dtype, target, timeout, True)
        v.causes = tv.causes
        same = not tv.bit_exact and np.array_equal(tv.got.view(np.uint8), got.view(np.uint8))
        v.notes.append(f"the same sources built with {' '.join(tv.cflags)} for the emulated "
                       f"{target} " + ("are bit-exact: the board's build differs (compiler, flags or "
                          "library)" if tv.bit_exact else "give the same states bit for bit"
                          if same else "diverge differently") + "; the causes are that build's")
    return v
