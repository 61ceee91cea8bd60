"""Firmware tests in your own pytest suite: your C against imufuse, on the target it ships on.

    from imufuse.testing import validate_firmware

    def test_attitude_on_the_m4f():
        r = validate_firmware(["fw/cf.c"], headers=["cf.h"], include_dirs=["fw"],
                              init="cf_init", update="cf_update", state={"theta": "theta"},
                              filter="Complementary1D", params={"T": 0.5},
                              target="cortex-m4f", cflags="-O2 -ffp-contract=off")
        r.assert_bit_exact()             # every state variable after every sample
        r.assert_cost(max_per_update=400, max_stack=256)

    def test_gnu_defaults_within_a_tolerance():   # a variant not meant to be bit-exact
        r = validate_firmware(..., target="cortex-m4f", cflags="-O2", within=1e-3)
        r.assert_passed()                # bit-exact, or every sample within 1e-3 deg

`validate_firmware` builds the sources (for the host with cffi, or with the target's cross
compiler and your flags for "cortex-m4f", "cortex-m0", "atmega328p"), runs them and the imufuse
filter on the same inputs (simulated motion by default, or `inputs=`), and returns a
`FirmwareResult`. Its assertions fail with the whole report: the first divergent sample and
variable, the largest orientation difference in degrees, rounding or formula
(imufuse.firmware.report.classify), the likely cause and the flag that removes it. A
firmware that crashes, calls exit(), overflows its stack or hangs past `timeout` raises
`imufuse.firmware.FirmwareError` naming the sample.

Firmware of any shape, declared in a file (imufuse.firmware.declared: a C++ class, structs
passed by value, units), and firmware against firmware (no imufuse reference):

    def test_our_madgwick_class_on_the_m0():
        r = validate_declared("fw/madgwick.toml", target="cortex-m0", within=0.01)
        r.assert_passed()

    def test_new_version_against_old():
        old = validate_declared("fw_v1/attitude.toml")
        new = validate_declared("fw_v2/attitude.toml")
        against(old, new).assert_bit_exact()        # or within=DEG for an intended change

`target_missing(target)` says why a target cannot run here (its cross compiler or emulator is
not installed: Debian gcc-arm-none-eabi, libnewlib-arm-none-eabi, qemu-system-arm, gcc-avr,
avr-libc, simavr; for "host", cffi or the C compiler), or None.
"""
from __future__ import annotations

import shlex
from dataclasses import dataclass
from typing import Any, Mapping, Optional, Sequence, Union

import numpy as np

from . import sim
from .catalogue import FUSION_AHRS, entry, inputs_for, resolve_params
from .mcu import missing_tools
from .firmware import (Firmware, Validation, compare_firmware, counts_for, harness_target,
                       load_declaration, validate_isolated)
from .firmware.host import compiler_missing
from .firmware.report import Classification, Tolerance, tolerance

__all__ = ["validate_firmware", "validate_declared", "against", "FirmwareResult",
           "simulated_inputs", "target_missing"]


@dataclass
class FirmwareResult:
    """A validation with assertions for tests; `.validation` has the arrays."""
    validation: Validation
    params: Mapping[str, Any]
    tolerance: Optional[Tolerance] = None     # validate_firmware(within=DEG)

    @property
    def report(self) -> str:
        t = self.tolerance
        return self.validation.text() + (f"\n{t.text()}" if t is not None and not self.bit_exact
                                         else "")

    @property
    def verdict(self) -> str:
        """"bit-exact", "within" (not bit-exact, within the tolerance of within=) or
        "differs" (imufuse validate's exit 0, 7, 1)."""
        if self.bit_exact:
            return "bit-exact"
        return "within" if self.tolerance is not None and self.tolerance.passed else "differs"

    @property
    def classification(self) -> Optional[Classification]:
        """Rounding or formula, and the error's growth (None when bit-exact)."""
        return self.validation.classification

    @property
    def bit_exact(self) -> bool:
        return self.validation.bit_exact

    @property
    def cost(self):
        """imufuse.firmware.Cost on an MCU target (per-update counts, flash, RAM, stack)."""
        return self.validation.cost

    @property
    def max_angle_deg(self) -> float:
        """Largest orientation difference over the run (0 when bit-exact)."""
        v = self.validation
        if v.bit_exact:
            return 0.0
        if v.max_angle_deg is None:
            raise AssertionError(f"{v.filter} has no orientation estimate to compare in degrees")
        return v.max_angle_deg

    def assert_bit_exact(self) -> None:
        if not self.bit_exact:
            raise AssertionError("firmware is not bit-exact with imufuse\n" + self.report)

    def assert_within(self, deg: float) -> None:
        """Every sample's orientation within `deg` degrees of imufuse's."""
        a = self.max_angle_deg
        if not a <= deg:
            raise AssertionError(f"firmware orientation differs by up to {a:.4g} deg "
                                 f"(allowed {deg:g} deg)\n" + self.report)

    def assert_passed(self) -> None:
        """Bit-exact, or (validate_firmware(within=DEG)) within the tolerance."""
        if self.verdict == "differs":
            raise AssertionError("firmware is not bit-exact with imufuse" +
                                 ("" if self.tolerance is None else " nor within the tolerance")
                                 + "\n" + self.report)

    def assert_cost(self, max_per_update: Optional[float] = None, max_stack: Optional[int] = None,
                    max_flash: Optional[int] = None, max_ram: Optional[int] = None) -> None:
        """Bounds on the target's cost: the slowest update (cycles on AVR, instructions on ARM),
        the deepest stack, the firmware's flash and static RAM in the linked image."""
        c = self.cost
        if c is None:
            raise AssertionError("cost is measured on an MCU target only (target='host')")
        bad = []
        if max_per_update is not None and not c.max <= max_per_update:
            bad.append(f"slowest update {c.max} {c.unit} > {max_per_update:g}")
        if max_stack is not None and (c.stack is None or not c.stack <= max_stack):
            bad.append(f"stack {c.stack} B > {max_stack} B")
        if max_flash is not None and (c.flash is None or not c.flash <= max_flash):
            bad.append(f"flash {c.flash} B > {max_flash} B")
        if max_ram is not None and not c.ram <= max_ram:
            bad.append(f"RAM {c.ram} B > {max_ram} B")
        if bad:
            raise AssertionError("; ".join(bad) + "\n" + self.report)


def simulated_inputs(filter: str, rate: float = 200.0, duration: float = 20.0, seed: int = 1,
                     motion: str = "slow", params: Optional[Mapping[str, Any]] = None):
    """(dt, inputs) of imufuse.sim motion for `filter`: (rate, angle) for single-axis
    filters, (gyr, acc[, mag]) for the others; int16 counts for a fixed-point filter, in the
    scale of its `params` (gyr_scale; see imufuse validate)."""
    e = entry(filter)
    data = (sim.axis1d(motion, rate=rate, duration=duration, seed=seed) if e.kind == "1d" else
            sim.imu(motion, rate=rate, duration=duration, seed=seed))
    ins = inputs_for(e.kind, data)
    if e.fixed:
        ins = tuple(counts_for(e.kind, resolve_params(filter, data.dt, params), ins))
    return data.dt, ins


def target_missing(target: str) -> Optional[str]:
    """None when `target` can run here, else what is missing."""
    if target == "host":
        try:
            import cffi  # noqa: F401
        except ImportError:
            return "cffi is not installed (pip install 'imufuse[firmware]')"
        return compiler_missing()
    miss = missing_tools(harness_target(target))
    return f"{target} needs {' '.join(miss)} (run tools/install-toolchains.sh)" if miss else None


def validate_firmware(sources: Sequence[str], *, filter: str, update: str,
                      init: Optional[str] = None, state: Optional[Mapping[str, str]] = None,
                      headers: Sequence[str] = (), include_dirs: Sequence[str] = (),
                      defines: Optional[Mapping[str, Any]] = None,
                      cflags: Union[str, Sequence[str], None] = None, target: str = "host",
                      params: Optional[Mapping[str, Any]] = None, inputs: Optional[Sequence] = None,
                      dt: Optional[float] = None, rate: float = 200.0, duration: float = 20.0,
                      seed: int = 1, dtype: Optional[str] = None, timeout: float = 60.0,
                      init_args: Optional[Mapping[str, float]] = None,
                      within: Optional[float] = None) -> FirmwareResult:
    """Build and validate firmware against imufuse filter `filter`; see the module doc.

    params: the filter's parameters beyond dt (defaults: the catalogue's); inputs: the
    run() arrays (then give dt too), else simulated motion at `rate` Hz for `duration` s;
    cflags: a string or a list (default: the contract's flags on the host, -O2 on an MCU);
    within: a tolerance in degrees for a variant not meant to be bit-exact (the result's
    `tolerance` and `verdict`, `assert_passed`)."""
    flags = shlex.split(cflags) if isinstance(cflags, str) else cflags
    fw = Firmware(list(sources), init=init, update=update, state=state,
                  state_names=None if state else entry(filter).state_names, headers=headers,
                  include_dirs=include_dirs, defines=defines, cflags=flags, init_args=init_args)
    if inputs is None:
        dt, inputs = simulated_inputs(filter, rate, duration, seed, params=params)
    elif dt is None:
        raise ValueError("inputs given: give dt (s) too")
    full = resolve_params(filter, float(dt), params)
    inputs = [np.asarray(a) for a in inputs]
    v = validate_isolated(fw, filter, full, inputs, dtype=dtype, timeout=timeout, target=target)
    v.params = dict(full)
    return FirmwareResult(v, full, None if within is None else tolerance(v, within))


def validate_declared(path: str, *, source_dir: Optional[str] = None, target: str = "host",
                      cflags: Union[str, Sequence[str], None] = None,
                      params: Optional[Mapping[str, Any]] = None,
                      inputs: Optional[Sequence] = None, dt: Optional[float] = None,
                      rate: float = 200.0, duration: float = 20.0, seed: int = 1,
                      dtype: Optional[str] = None, timeout: float = 60.0,
                      within: Optional[float] = None) -> FirmwareResult:
    """validate_firmware for a firmware declared in a file (imufuse validate --declaration):
    its sources, API and imufuse filter from the file; params on top of the file's.
    FusionAHRS takes its inputs in Fusion's units (the gyroscope in deg/s)."""
    d = load_declaration(path, source_dir=source_dir)
    fw = d.firmware
    if cflags is not None:
        fw.cflags = fw.cflags_given = shlex.split(cflags) if isinstance(cflags, str) \
            else list(cflags)
    fusion = d.filter in FUSION_AHRS
    over = {**d.params, **dict(params or {})}
    if inputs is None:
        kind = "ahrs" if fusion else entry(d.filter).kind
        data = (sim.axis1d("slow", rate=rate, duration=duration, seed=seed) if kind == "1d" else
                sim.imu("slow", rate=rate, duration=duration, seed=seed))
        dt, inputs = data.dt, list(inputs_for(kind, data))
        if fusion:
            inputs[0] = np.degrees(inputs[0])
        elif entry(d.filter).fixed:           # counts in the declared filter's own scale
            inputs = counts_for(kind, resolve_params(d.filter, data.dt, over), inputs)
    elif dt is None:
        raise ValueError("inputs given: give dt (s) too")
    full = {**over, "dt": float(dt)} if fusion else resolve_params(d.filter, float(dt), over)
    inputs = [np.asarray(a) for a in inputs]
    v = validate_isolated(fw, d.filter, full, inputs, dtype=dtype, timeout=timeout,
                          target=target)
    v.params = dict(full)
    return FirmwareResult(v, full, None if within is None else tolerance(v, within))


def against(a: FirmwareResult, b: FirmwareResult, within: Optional[float] = None
            ) -> FirmwareResult:
    """Firmware B's run against firmware A's, no imufuse reference
    (imufuse.firmware.compare_firmware): both validated on the same inputs."""
    v = compare_firmware(a.validation, b.validation)
    return FirmwareResult(v, a.params, None if within is None else tolerance(v, within))
