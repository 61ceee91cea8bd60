"""State trajectory -> orientation estimate: the adapters a catalogue entry
names (imufuse.catalogue.Entry.estimate).

  "angle"       1d, state "theta"                   -> angle (rad)
  "quaternion"  q0, q1, q2, q3 first                -> quaternion [w, x, y, z] body -> earth
  "matrix"      9 names ending 11..33 or 00..22     -> rotation matrix R (body -> earth,
                                                       row-major)
  "gravity"     3 names <p>x, <p>y, <p>z first      -> gravity direction in the body frame
                                                       (what a level, resting accelerometer
                                                       reads: +z); tilt only, no heading
  "euler"       roll, pitch [, yaw] or phi, theta [, psi] -> ZYX Euler angles (rad); tilt
                                                       only without yaw
Heading is meaningful only for AHRS filters with a full attitude.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from .. import rotations


@dataclass
class Estimate:
    """What a state trajectory says about the orientation.

    angle: (N,) rad for single-axis filters; q: (N, 4) body -> earth for 3D
    filters; heading: whether q's yaw means anything (AHRS with a full
    attitude); source: how it was derived."""
    angle: Optional[np.ndarray] = None
    q: Optional[np.ndarray] = None
    heading: bool = False
    source: str = ""


def _angle(names: Sequence[str], kind: str, S: np.ndarray) -> Estimate:
    return Estimate(angle=S[:, list(names).index("theta")], source="theta")


def _quaternion(names: Sequence[str], kind: str, S: np.ndarray) -> Estimate:
    if tuple(names[:4]) != ("q0", "q1", "q2", "q3"):
        raise ValueError(f"quaternion adapter: state must start q0..q3, got {names}")
    # |q| summed in this order (the compiled run(..., outputs="q") does the same in C)
    a, b, c, d = S[:, 0], S[:, 1], S[:, 2], S[:, 3]
    with np.errstate(all="ignore"):
        q = S[:, :4] / np.sqrt(((a * a + b * b) + c * c) + d * d)[:, None]
    return Estimate(q=q, heading=kind == "ahrs", source="q0..q3")


_MATRIX = (("11", "12", "13", "21", "22", "23", "31", "32", "33"),
           ("00", "01", "02", "10", "11", "12", "20", "21", "22"))


def _matrix(names: Sequence[str], kind: str, S: np.ndarray) -> Estimate:
    if not any(len(names) >= 9 and all(n.endswith(s) and n[:-2] == names[0][:-2]
                                       for n, s in zip(names[:9], idx)) for idx in _MATRIX):
        raise ValueError(f"matrix adapter: state must start with a 3x3 matrix, got {names}")
    R = S[:, :9].reshape(-1, 3, 3)
    return Estimate(q=rotations.matrix_to_quat(R), heading=kind == "ahrs",
                    source=f"{names[0]}..{names[8]} (rotation matrix)")


def _up_to_quat(up: np.ndarray) -> np.ndarray:
    """Tilt-only quaternion (yaw 0) whose body-frame earth-up is `up`:
    R^T e_z = (-sin p, sin r cos p, cos r cos p) for ZYX."""
    roll = np.arctan2(up[:, 1], up[:, 2])
    pitch = np.arctan2(-up[:, 0], np.hypot(up[:, 1], up[:, 2]))
    return rotations.euler_to_quat(np.stack([roll, pitch, np.zeros_like(roll)], axis=-1))


def _gravity(names: Sequence[str], kind: str, S: np.ndarray) -> Estimate:
    if not (len(names) >= 3 and names[0][:-1] == names[1][:-1] == names[2][:-1]
            and tuple(n[-1] for n in names[:3]) == ("x", "y", "z")):
        raise ValueError(f"gravity adapter: state must start <p>x, <p>y, <p>z, got {names}")
    return Estimate(q=_up_to_quat(S[:, :3]), heading=False,
                    source=f"{names[0]}..{names[2]} (gravity vector)")


def _euler(names: Sequence[str], kind: str, S: np.ndarray) -> Estimate:
    for r, p, y in (("roll", "pitch", "yaw"), ("phi", "theta", "psi")):
        if r in names and p in names:
            yaw = S[:, names.index(y)] if y in names else np.zeros(len(S))
            e = np.stack([S[:, names.index(r)], S[:, names.index(p)], yaw], axis=-1)
            return Estimate(q=rotations.euler_to_quat(e), heading=y in names and kind == "ahrs",
                            source=f"{r}, {p}" + (f", {y}" if y in names else "") + " (Euler)")
    raise ValueError(f"euler adapter: state needs roll, pitch or phi, theta, got {names}")


Adapter = Callable[[Sequence[str], str, np.ndarray], Estimate]

#: adapter name (a catalogue entry's `estimate`) -> f(state_names, kind, states)
_RAW: Dict[str, Adapter] = {"angle": _angle, "quaternion": _quaternion, "matrix": _matrix,
                            "gravity": _gravity, "euler": _euler}


def _as_float(adapter: Adapter) -> Adapter:
    def f(names: Sequence[str], kind: str, states: np.ndarray) -> Estimate:
        return adapter(tuple(names), kind, np.asarray(states, dtype=np.float64))
    f.__doc__ = adapter.__doc__
    return f


ADAPTERS: Dict[str, Adapter] = {k: _as_float(v) for k, v in _RAW.items()}

#: run(..., outputs=...) of the 3-D filters
OUTPUTS = ("state", "q")


def detect(names: Sequence[str]) -> Optional[str]:
    """The adapter that reads an orientation from a state named ``names`` (quaternion,
    matrix, gravity, euler, tried in this order), or None."""
    empty = np.zeros((0, len(names)))
    for key in ("quaternion", "matrix", "gravity", "euler"):
        try:
            _RAW[key](tuple(names), "imu", empty)
        except ValueError:
            continue
        return key
    return None


def run_outputs(filt: Any, states: Any, outputs: str) -> np.ndarray:
    """What run(..., outputs=...) of a 3-D filter returns: "state" the (N, len(state))
    trajectory as it is; "q" the (N, 4) float64 quaternions [w, x, y, z] sensor -> earth
    read from it by name (a tilt-only quaternion, heading 0, for filters that estimate
    gravity or roll and pitch only), ready for imufuse.evaluation.evaluate."""
    if outputs == "state":
        return states
    names = tuple(filt.state_names)
    if outputs != "q":
        raise ValueError(f"outputs: must be one of {', '.join(map(repr, OUTPUTS))}, "
                         f"got {outputs!r}")
    key = detect(names)
    if key is None:
        raise ValueError(f"outputs='q': {type(filt).__name__} has no orientation in its state "
                         f"({', '.join(names)})")
    est = ADAPTERS[key](names, filt.kind, states)
    assert est.q is not None
    return np.ascontiguousarray(est.q)


def output_columns(filt: Any, outputs: str) -> Tuple[str, Tuple[int, ...]]:
    """(adapter, the state words it reads) for run(..., outputs=...) of ``filt`` other than
    "state": what the compiled run() keeps while the filter runs. ValueError as
    run_outputs raises it."""
    names = tuple(filt.state_names)
    if outputs != "q":
        run_outputs(filt, None, outputs)             # names the mistake
    key = detect(names)
    if key is None:
        run_outputs(filt, np.zeros((0, len(names))), outputs)
    assert key is not None
    if key == "quaternion":
        return key, (0, 1, 2, 3)
    if key == "matrix":
        return key, tuple(range(9))
    if key == "gravity":
        return key, (0, 1, 2)
    return key, tuple(i for i, n in enumerate(names)
                      if n in ("roll", "pitch", "yaw", "phi", "theta", "psi"))


def outputs_from_columns(filt: Any, key: str, cols: Sequence[int], sub: Any) -> np.ndarray:
    """run_outputs on the state words ``cols`` of a trajectory (output_columns): the same
    values as from the whole trajectory."""
    names = tuple(filt.state_names)
    est = ADAPTERS[key](tuple(names[c] for c in cols), filt.kind, sub)
    assert est.q is not None
    return np.ascontiguousarray(est.q)


def euler_of(est: Estimate) -> np.ndarray:
    """(N, 3) roll, pitch, yaw in rad of a quaternion estimate (yaw NaN without heading)."""
    e = rotations.quat_to_euler(est.q)
    if not est.heading:
        e[:, 2] = np.nan
    return e
