"""`imufuse demo`: every filter on simulated data, C against reference bit for
bit, errors against ground truth, plots.

The filters, their default parameters and their state -> estimate adapters
come from imufuse.catalogue.
"""
import math
import os
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence, TextIO

import numpy as np

from .. import plots, rotations, sim
from ..shared.bits import compare_states
from ..catalogue import (FilterError, estimate, filter_names, inputs_for, make_filter,
                        reference_class, resolve_params, why_no_estimate)
from ..shared.estimate import Estimate

__all__ = ["run_demo", "errors_1d", "errors_3d", "SETTLE"]

#: Seconds at the start of a run left out of the error statistics (the
#: filters start from zero / the identity and need time to converge).
SETTLE = 5.0


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
# the demo

def first_difference(got, want, names):
    """None when got and want have the same bit patterns everywhere; else
    (sample, variable name)."""
    rep = compare_states(got, want, names)
    return None if rep.bit_exact else (rep.first_sample, rep.first_variable)


@dataclass
class DemoRow:
    name: str
    kind: str
    checks: dict = field(default_factory=dict)   # dtype -> None | (sample, var) | "error..."
    errors: dict = field(default_factory=dict)   # 'angle'/'tilt'/'heading' -> (rms, max) deg
    note: str = ""
    estimate: Optional[Estimate] = None


def _fmt_check(c):
    if c is None:
        return "ok"
    if isinstance(c, str):
        return c
    return f"DIFF@{c[0]}:{c[1]}"


def _fmt_err(e):
    return "-" if e is None else f"{e[0]:7.3f} {e[1]:7.3f}"


def run_demo(out_dir: str = "imufuse-demo", rate: float = 200.0, duration: float = 20.0,
             seed: int = 1, plot: bool = True, stream: Optional[TextIO] = None,
             names: Optional[Sequence[str]] = None,
             say: Optional[Callable[[str], None]] = None) -> int:
    """Run the demo; return the process exit code (1 when a bit-exact check fails). The
    tables go to ``stream``; the messages about the plots ("plot: PATH", plots unavailable)
    to say(message) (the command line's "imufuse: " lines), else to ``stream`` too."""
    stream = stream or sys.stdout
    pr = lambda *a: print(*a, file=stream)  # noqa: E731
    say = say or pr
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
        data: Any = d1 if cls.kind == "1d" else d3
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
                    if "bu" in cls.state_names:
                        # the Robust filters: B3 learns the bias in motion within seconds
                        # (its Kalman filter, bp); bu, how unknown B1 and B2 take it to be
                        # (1 .. 0), falls over tau_bias in motion, in seconds at rest
                        bu = float(S_c[-1, list(cls.state_names).index("bu")])
                        if bu > 0.1:
                            row.note = (f"bias learnt in motion; B1's rest window still wide "
                                        f"(bu {bu:.2f}: over tau_bias in motion, seconds at rest)")
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
        if not plots.available():
            say("plots unavailable: matplotlib is not installed (pip install 'imufuse[plot]')")
        else:
            os.makedirs(out_dir, exist_ok=True)
            ests = {r.name: r.estimate for r in rows if r.estimate is not None}
            e1 = {n: e.angle for n, e in ests.items() if e.angle is not None}
            if e1:
                p = os.path.join(out_dir, "demo_1d.png")
                plots.plot_1d(p, d1.t, d1.angle, e1, d1.acc_angle,
                              title=f"single-axis filters (default gains) on simulated 'slow' "
                                    f"motion, {rate:g} Hz, {duration:g} s, seed {seed}")
                say(f"plot: {p}")
            e3 = {n: e for n, e in ests.items() if e.q is not None}
            if e3 and d3 is not None:
                p = os.path.join(out_dir, "demo_3d.png")
                plots.plot_3d_errors(p, d3.t, d3.q_true, e3,
                                     title=f"3D filters (default gains) against ground truth: "
                                           f"simulated 'slow' motion, {rate:g} Hz, "
                                           f"{len(d3) / rate:g} s, seed {seed}")
                say(f"plot: {p}")
    n_bad = sum(1 for r in rows for c in r.checks.values() if c is not None)
    pr(f"{'FAILED' if failed else 'ok'}: {n_bad} of {sum(len(r.checks) for r in rows)} "
       f"bit-exact checks failed ({time.perf_counter() - t0:.1f} s)")
    return 1 if failed else 0
