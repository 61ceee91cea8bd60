"""Firmware against firmware: two runs of the user's own code compared with the same report as
a validation, and no imufuse reference (``compare_firmware``).

The pairs firmware engineers need: the old version of a filter against the new one, a float
filter against its fixed-point port, the same build on the host and on the target, ``-O0``
against ``-O2``. Each side is a Validation (its ``got`` is the firmware's trajectory); side A
is the reference the other is compared with. When both have the same state names and C types
their states are compared bit for bit, every variable after every sample; otherwise (a float
filter against its fixed-point port) they are compared as orientations, the unit quaternions
of their q0..q3 (a fixed-point quaternion in any scale). The result is a Validation whose text
names both sides, with the classification (rounding or formula), the growth of the difference
and the largest orientation difference; ``imufuse.firmware.report.tolerance`` gives a
``--within`` verdict of it as of any validation.
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from ..shared.bits import compare_states
from .causes import quaternion_angles_deg
from .declaration import FirmwareError
from .results import Validation
from .targets import CORES

__all__ = ["compare_firmware", "pair_causes", "QUATERNION", "TRANSCENDENTALS"]

#: C library routines that are not correctly rounded: two C libraries (glibc on the host,
#: newlib, picolibc or avr-libc on a target) may differ in their last bit
TRANSCENDENTALS = frozenset(
    f + suffix for f in ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "exp", "log",
                         "pow", "sinh", "cosh", "tanh", "hypot", "cbrt", "sincos")
    for suffix in ("", "f"))

QUATERNION = ("q0", "q1", "q2", "q3")


def _unit_quaternions(v: Validation, label: str) -> np.ndarray:
    names = list(v.comparison.names)
    if not set(QUATERNION) <= set(names):
        raise FirmwareError(f"firmware {label} has no quaternion q0..q3 in its state "
                            f"({', '.join(names)}): the two cannot be compared as orientations")
    q = np.asarray(v.got[:, [names.index(n) for n in QUATERNION]], dtype=np.float64)
    with np.errstate(all="ignore"):
        return q / np.linalg.norm(q, axis=1, keepdims=True)


def _side(v: Validation, label: str) -> str:
    flags = " ".join(v.cflags) if v.cflags else "(none)"
    return f"firmware {label} on {v.target} (flags {flags}, {v.comparison.dtype})"


def compare_firmware(a: Validation, b: Validation, label_a: str = "A", label_b: str = "B",
                     notes: Sequence[str] = ()) -> Validation:
    """Firmware B's run against firmware A's (see the module's doc). Both ran on the same
    samples; FirmwareError when they cannot be compared."""
    if len(a.got) != len(b.got):
        raise FirmwareError(f"firmware {label_a} ran {len(a.got)} samples, {label_b} "
                            f"{len(b.got)}: give both the same inputs")
    names_a, names_b = tuple(a.comparison.names), tuple(b.comparison.names)
    notes_out = list(notes)
    orient = False              # states of different kinds: compared as orientations
    if names_a == names_b and a.got.dtype == b.got.dtype:
        names: Sequence[str] = names_a
        want, got = a.got, b.got
        how = "every state variable bit for bit"
    elif set(names_a) == set(names_b) and a.got.dtype == b.got.dtype:
        names = names_a
        want, got = a.got, b.got[:, [names_b.index(n) for n in names_a]]
        how = "every state variable bit for bit"
    else:
        want, got = _unit_quaternions(a, label_a), _unit_quaternions(b, label_b)
        names, orient = QUATERNION, True
        how = "as orientations (the unit quaternions of q0..q3)"
        notes_out.append(f"the states differ ({a.comparison.dtype} {', '.join(names_a)} against "
                         f"{b.comparison.dtype} {', '.join(names_b)}): compared {how}, in "
                         "degrees of orientation")
    comp = compare_states(got, want, list(names))
    if orient:
        comp.max_ulps = {}      # unit quaternions of states of different kinds: degrees
    if not comp.bit_exact:
        notes_out += pair_causes(a, b)
    title = f"{_side(b, label_b)} vs {_side(a, label_a)}, no imufuse reference, {how}:"
    v = Validation(a.filter, "firmware", comp, got, want, target=f"{b.target} vs {a.target}",
                   cflags=tuple(b.cflags), notes=notes_out, params=a.params, title=title,
                   as_orientations=orient)
    if not comp.bit_exact:
        v.max_angle_deg = _max_angle(got, want, names)
    return v


def _contracts(v: Validation) -> str:
    """The fused multiply-add a side's build may emit: its core's, under GCC's default
    -ffp-contract=fast (gnu standards; not under -ffp-contract=off or a strict -std=c..)."""
    core = CORES.get(v.target)
    flags = list(v.cflags)
    if core is None or not core.contraction or "-ffp-contract=off" in flags or \
            any(f.startswith("-std=c") and "gnu" not in f for f in flags):
        return ""
    return core.contraction


def pair_causes(a: Validation, b: Validation) -> list:
    """What can make two builds of one firmware differ, from what each was built with and
    linked: a fused multiply-add one side's core has and its flags allow, and the
    transcendental functions a target side takes from its own C library."""
    out = []
    for v, label in ((a, "A"), (b, "B")):
        fused = _contracts(v)
        if fused:
            out.append(f"cause: fused multiply-add: firmware {label} was built for the {v.target} "
                       f"with {' '.join(v.cflags) or 'no flags'}: GCC's default "
                       f"-ffp-contract=fast fuses a*b+c into {fused} (one rounding instead of "
                       "two); fix: -ffp-contract=off")
    if a.target != b.target:
        for v, label in ((a, "A"), (b, "B")):
            lib = sorted(TRANSCENDENTALS & set(v.cost.library)) if v.cost else []
            if lib:
                out.append(f"cause: libm: firmware {label} calls {', '.join(lib)} of the "
                           f"{v.target}'s C library, the other side its own: these functions "
                           "are not correctly rounded, and two C libraries may differ in the last "
                           "bit (no flag removes it: compare within a tolerance, --within)")
    return out


def _max_angle(got: np.ndarray, want: np.ndarray, names: Sequence[str]) -> Optional[float]:
    if not set(QUATERNION) <= set(names):
        return None
    cols = [list(names).index(n) for n in QUATERNION]
    ang = quaternion_angles_deg(got[:, cols], want[:, cols])
    return float(np.max(ang, initial=0.0))
