"""`imufuse demo`: every filter on simulated data, C against reference bit for
bit, errors against ground truth, plots.

Also the filter catalogue shared by the command line: default parameters,
construction on either backend, and the adapters that turn a filter's state
trajectory into an angle (single-axis filters) or a quaternion (3D filters).

Adapters, by state names (a filter joins by the names of its state):
  1d, state "theta"                 -> angle (rad)
  q0, q1, q2, q3 first              -> quaternion [w, x, y, z] body -> earth
  9 names ending 11..33 or 00..22   -> rotation matrix R (body -> earth, row-major)
  3 names <p>x, <p>y, <p>z first    -> gravity direction in the body frame (what a
                                       level, resting accelerometer reads: +z);
                                       tilt only, no heading
  roll, pitch [, yaw] or phi, theta [, psi] -> ZYX Euler angles (rad); tilt only
                                       without yaw
Anything else: no estimate (the filter still runs and is checked bit for bit).
"""
import inspect
import math
import os
import re
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from . import rotations, sim
from . import reference as _reference

#: Parameters the demo and the command line use when the user gives none
#: (dt always comes from the sample rate). Tuned for 100-500 Hz MEMS data.
DEFAULT_PARAMS = {
    "Complementary1D": dict(T=0.5),
    "Kalman1D": dict(k0=0.01),
    "Mahony1D": dict(kp=2.0),
    "Kalman1DBias": dict(k0=0.01, k1=-0.02),
    "Mahony1DBias": dict(kp=2.0, ki=0.3),
    "Complementary1DBias": dict(kp=2.0, ki=0.3),
    # 3D filters whose constructors have no defaults for their gains
    "KK": dict(kp=0.01),
    "Mahony2D": dict(kp=2.0, ki=0.5),
    "DCM": dict(kp=2.0, ki=0.5),
    # the published Mahony defaults (kp 0.5, ki 0) leave a gyro bias uncorrected;
    # the demo and the command line use the gains of the other PI filters
    "MahonyIMU": dict(kp=2.0, ki=0.5),
    "MahonyAHRS": dict(kp=2.0, ki=0.5),
}

#: Seconds at the start of a run left out of the error statistics (the
#: filters start from zero / the identity and need time to converge).
SETTLE = 5.0


class FilterError(ValueError):
    """Unknown filter or parameter, or parameters the filter rejects."""


# ---------------------------------------------------------------------------
# catalogue

def filter_names(kinds=None):
    """Names of the float filters (imufuse.reference.FILTERS), optionally of some kinds."""
    return [n for n in _reference.FILTERS
            if kinds is None or getattr(_reference, n).kind in kinds]


def reference_class(name):
    if name not in _reference.FILTERS:
        import difflib
        close = difflib.get_close_matches(name, _reference.FILTERS, n=3, cutoff=0.5)
        hint = f" (did you mean {', '.join(close)}?)" if close else ""
        raise FilterError(f"unknown filter {name!r}{hint}; valid filters: "
                          f"{', '.join(_reference.FILTERS)}")
    return getattr(_reference, name)


def param_names(name):
    """Keyword parameters of a filter's constructor, dt included."""
    sig = inspect.signature(reference_class(name)._params)
    return [p.name for p in sig.parameters.values()
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]


def resolve_params(name, dt, overrides=None):
    """dt plus DEFAULT_PARAMS[name] updated by overrides; checks the names."""
    valid = param_names(name)
    overrides = dict(overrides or {})
    for k in overrides:
        if k == "dt":
            raise FilterError("dt: set by the sample rate (--rate or the log's time column)")
        if k not in valid:
            raise FilterError(f"{name}: unknown parameter {k!r}; valid parameters: "
                              f"{', '.join(v for v in valid if v != 'dt')}")
    params = dict(DEFAULT_PARAMS.get(name, {}))
    # a user's alternative parametrisation replaces the default one
    # (Complementary1D alpha vs T, Complementary1DBias kp/ki vs omega0/xi)
    alternatives = [{"alpha", "T"}, {"kp", "omega0"}, {"ki", "xi"}, {"kp", "xi"}, {"ki", "omega0"}]
    for k in overrides:
        for alt in alternatives:
            if k in alt:
                for other in alt - {k}:
                    params.pop(other, None)
    params.update(overrides)
    return {"dt": dt, **params}


def make_filter(name, backend, dtype, params):
    """A filter instance: backend "c" (imufuse_c) or "ref" (imufuse.reference)."""
    reference_class(name)
    if backend == "c":
        import imufuse_c
        cls = getattr(imufuse_c, name)
    elif backend == "ref":
        cls = getattr(_reference, name)
    else:
        raise FilterError(f"backend: must be 'c' or 'ref', got {backend!r}")
    try:
        return cls(**params, dtype=dtype)
    except TypeError as e:
        raise FilterError(f"{name}: {e}; valid parameters: "
                          f"{', '.join(v for v in param_names(name) if v != 'dt')}") from None
    except ValueError as e:
        raise FilterError(f"{name}: {e}") from None


# ---------------------------------------------------------------------------
# state -> estimate adapters

@dataclass
class Estimate:
    """What a state trajectory says about the orientation.

    angle: (N,) rad for single-axis filters; q: (N, 4) body -> earth for 3D
    filters; heading: whether q's yaw means anything (AHRS with a full
    attitude); source: how it was derived."""
    angle: np.ndarray = None
    q: np.ndarray = None
    heading: bool = False
    source: str = ""


_MATRIX = (("11", "12", "13", "21", "22", "23", "31", "32", "33"),
           ("00", "01", "02", "10", "11", "12", "20", "21", "22"))


def _up_to_quat(up):
    """Tilt-only quaternion (yaw 0) whose body-frame earth-up is `up`:
    R^T e_z = (-sin p, sin r cos p, cos r cos p) for ZYX."""
    roll = np.arctan2(up[:, 1], up[:, 2])
    pitch = np.arctan2(-up[:, 0], np.hypot(up[:, 1], up[:, 2]))
    return rotations.euler_to_quat(np.stack([roll, pitch, np.zeros_like(roll)], axis=-1))


def estimate(cls, states):
    """Estimate from the (N, len(state)) trajectory of a filter class (either
    backend), or None with the reason in `why_no_estimate(cls)`."""
    names = tuple(cls.state_names)
    S = np.asarray(states, dtype=np.float64)
    if cls.kind == "1d":
        if "theta" in names:
            return Estimate(angle=S[:, names.index("theta")], source="theta")
        return None
    if names[:4] == ("q0", "q1", "q2", "q3"):
        q = S[:, :4]
        with np.errstate(all="ignore"):
            q = q / np.linalg.norm(q, axis=1, keepdims=True)
        return Estimate(q=q, heading=cls.kind == "ahrs", source="q0..q3")
    for idx in _MATRIX:
        if len(names) >= 9 and all(n.endswith(s) and n[:-2] == names[0][:-2]
                                   for n, s in zip(names[:9], idx)):
            R = S[:, :9].reshape(-1, 3, 3)
            return Estimate(q=rotations.matrix_to_quat(R), heading=cls.kind == "ahrs",
                            source=f"{names[0]}..{names[8]} (rotation matrix)")
    if len(names) >= 3 and names[0][:-1] == names[1][:-1] == names[2][:-1] \
            and tuple(n[-1] for n in names[:3]) == ("x", "y", "z"):
        return Estimate(q=_up_to_quat(S[:, :3]), heading=False,
                        source=f"{names[0]}..{names[2]} (gravity vector)")
    for r, p, y in (("roll", "pitch", "yaw"), ("phi", "theta", "psi")):
        if r in names and p in names:
            yaw = S[:, names.index(y)] if y in names else np.zeros(len(S))
            e = np.stack([S[:, names.index(r)], S[:, names.index(p)], yaw], axis=-1)
            return Estimate(q=rotations.euler_to_quat(e), heading=y in names and cls.kind == "ahrs",
                            source=f"{r}, {p}" + (f", {y}" if y in names else "") + " (Euler)")
    return None


def why_no_estimate(cls):
    return (f"no orientation estimate derivable from state {', '.join(cls.state_names)} "
            "(see imufuse.demo adapters)")


def euler_of(est):
    """(N, 3) roll, pitch, yaw in rad of a quaternion estimate (yaw NaN without heading)."""
    e = rotations.quat_to_euler(est.q)
    if not est.heading:
        e[:, 2] = np.nan
    return e


# ---------------------------------------------------------------------------
# errors against ground truth

def _stats(err_rad, mask):
    e = np.degrees(np.abs(np.asarray(err_rad)[mask]))
    if e.size == 0:
        return (math.nan, math.nan)
    return (float(np.sqrt(np.mean(e * e))), float(np.max(e)))


def errors_1d(est, angle_true, mask):
    """{'angle': (rms, max)} in degrees."""
    return {"angle": _stats(est.angle - angle_true, mask)}


def errors_3d(est, q_true, mask):
    """{'tilt': (rms, max)[, 'heading': (rms, max)]} in degrees."""
    out = {"tilt": _stats(rotations.tilt_error(est.q, q_true), mask)}
    if est.heading:
        out["heading"] = _stats(rotations.heading_error(est.q, q_true), mask)
    return out


# ---------------------------------------------------------------------------
# bit patterns

def first_difference(got, want, names):
    """None when got and want have the same bit patterns everywhere; else
    (sample, variable name)."""
    from .firmware import compare_states
    rep = compare_states(got, want, names)
    return None if rep.bit_exact else (rep.first_sample, rep.first_variable)


# ---------------------------------------------------------------------------
# the demo

def inputs_for(kind, data):
    if kind == "1d":
        return (data.gyr, data.acc_angle)
    if kind == "imu":
        return (data.gyr, data.acc)
    return (data.gyr, data.acc, data.mag)


@dataclass
class DemoRow:
    name: str
    kind: str
    checks: dict = field(default_factory=dict)   # dtype -> None | (sample, var) | "error..."
    errors: dict = field(default_factory=dict)   # 'angle'/'tilt'/'heading' -> (rms, max) deg
    note: str = ""
    estimate: Estimate = None


def _fmt_check(c):
    if c is None:
        return "ok"
    if isinstance(c, str):
        return c
    return f"DIFF@{c[0]}:{c[1]}"


def _fmt_err(e):
    return "-" if e is None else f"{e[0]:7.3f} {e[1]:7.3f}"


def run_demo(out_dir="imufuse-demo", rate=200.0, duration=20.0, seed=1, plot=True,
             stream=None, names=None):
    """Run the demo; return the process exit code (1 when a bit-exact check fails)."""
    stream = stream or sys.stdout
    pr = lambda *a: print(*a, file=stream)  # noqa: E731
    t0 = time.perf_counter()
    names = filter_names() if names is None else names
    kinds = {reference_class(n).kind for n in names}
    d1 = sim.axis1d("slow", rate=rate, duration=duration, seed=seed)
    d3 = (sim.imu("slow", rate=rate, duration=duration, seed=seed)
          if kinds & {"imu", "ahrs"} else None)
    pr(f"imufuse demo: {len(names)} filters; single-axis data: axis1d('slow', {rate:g} Hz, "
       f"{duration:g} s, seed {seed}, gyro bias {d1.params['gyr_bias']:g} rad/s)")
    if d3 is not None:
        pr(f"3D data: imu('slow', {rate:g} Hz, {len(d3) / rate:g} s, seed {seed})")
    pr(f"bit-exact: C run() vs reference run(), bit patterns of every state variable after "
       f"every sample; errors: RMS and max in degrees after the first {SETTLE:g} s, float64")
    rows, failed = [], False
    for name in names:
        cls = reference_class(name)
        data = d1 if cls.kind == "1d" else d3
        row = DemoRow(name, cls.kind)
        rows.append(row)
        try:
            params = resolve_params(name, data.dt)
            make_filter(name, "ref", "float64", params)
        except FilterError as e:
            row.note = f"skipped: {e}"
            continue
        inputs = inputs_for(cls.kind, data)
        for dtype in ("float32", "float64"):
            try:
                S_c = make_filter(name, "c", dtype, params).run(*inputs)
            except (ImportError, AttributeError) as e:
                row.checks[dtype] = f"no C build ({e})"
                failed = True
                continue
            S_r = make_filter(name, "ref", dtype, params).run(*inputs)
            row.checks[dtype] = first_difference(S_c, S_r, cls.state_names)
            failed |= row.checks[dtype] is not None
            if dtype == "float64":
                est = estimate(cls, S_c)
                row.estimate = est
                mask = data.t > SETTLE
                if est is None:
                    row.note = why_no_estimate(cls)
                elif cls.kind == "1d":
                    row.errors = errors_1d(est, data.angle, mask)
                else:
                    row.errors = errors_3d(est, data.q_true, mask)
                    if not est.heading and cls.kind == "ahrs":
                        row.note = f"heading not derivable from {est.source}"
                    elif est.source != "q0..q3":
                        row.note = f"from {est.source}"
    head = f"{'filter':22s} {'kind':4s} {'float32':>14s} {'float64':>14s}  " \
           f"{'angle/tilt rms   max':>20s}  {'heading rms   max':>17s}  note"
    pr("")
    pr(head)
    pr("-" * len(head))
    for r in rows:
        main = r.errors.get("angle", r.errors.get("tilt"))
        pr(f"{r.name:22s} {r.kind:4s} {_fmt_check(r.checks.get('float32', '-')):>14s} "
           f"{_fmt_check(r.checks.get('float64', '-')):>14s}  {_fmt_err(main):>20s}  "
           f"{_fmt_err(r.errors.get('heading')):>17s}  {r.note}")
    pr("")
    if plot:
        from . import plots
        if not plots.available():
            pr("plots unavailable: matplotlib is not installed (pip install 'imufuse[plot]')")
        else:
            os.makedirs(out_dir, exist_ok=True)
            ests = {r.name: r.estimate for r in rows if r.estimate is not None}
            e1 = {n: e.angle for n, e in ests.items() if e.angle is not None}
            if e1:
                p = os.path.join(out_dir, "demo_1d.png")
                plots.plot_1d(p, d1.t, d1.angle, e1, d1.acc_angle)
                pr(f"plot: {p}")
            e3 = {n: e for n, e in ests.items() if e.q is not None}
            if e3 and d3 is not None:
                p = os.path.join(out_dir, "demo_3d.png")
                plots.plot_3d_errors(p, d3.t, d3.q_true, e3)
                pr(f"plot: {p}")
    n_bad = sum(1 for r in rows for c in r.checks.values() if c is not None)
    pr(f"{'FAILED' if failed else 'ok'}: {n_bad} of {sum(len(r.checks) for r in rows)} "
       f"bit-exact checks failed ({time.perf_counter() - t0:.1f} s)")
    return 1 if failed else 0
