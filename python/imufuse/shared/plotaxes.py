"""The axes of imufuse.plots: angles in (-180, 180] broken and marked where they wrap, angle
panels scaled to their data, error limits scaled to the filters that behave, and the
coinciding curves a legend names (see imufuse.plots for the rules they serve)."""
import numpy as np


def unwrap_deg(angle_rad):
    """Degrees, unwrapped (no +-180 jumps) over the finite stretches; the first
    finite value stays in [-180, 180]."""
    a = np.asarray(angle_rad, dtype=np.float64).copy()
    ok = np.isfinite(a)
    if ok.any():
        a[ok] = np.unwrap(a[ok])
    return np.degrees(a)


def wrap_deg(angle_rad):
    """Degrees in (-180, 180] (NaN stays NaN), whatever turn the angle is on."""
    d = 180.0 - np.mod(180.0 - np.degrees(np.asarray(angle_rad, dtype=np.float64)), 360.0)
    return np.where(d <= -180.0, d + 360.0, d)


def break_wraps(t, deg, jump=180.0):
    """(t, deg) with a NaN inserted between two samples more than `jump` degrees
    apart (a wrap at +-180), so a plotted line is broken there instead of
    drawing a vertical line across the panel."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(deg, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        i = np.flatnonzero(np.abs(np.diff(y)) > jump)
    if i.size == 0:
        return t, y
    return np.insert(t, i + 1, (t[i] + t[i + 1]) / 2), np.insert(y, i + 1, np.nan)


def wrap_marks(t, deg, jump=180.0):
    """(t, deg) of the samples on both sides of each wrap at +-180 (where `break_wraps`
    breaks the line); empty arrays when the angle does not wrap."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(deg, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        i = np.flatnonzero(np.abs(np.diff(y)) > jump)
    k = np.concatenate([i, i + 1])
    return t[k], y[k]


def steady_limits(t, errors, skip=0.1, pad=1.25):
    """(lo, hi) y-limits showing the errors after the first `skip` fraction of
    the time (the start-up transient), from their 0.5 and 99.5 percentiles."""
    t = np.asarray(t)
    if t.size == 0:
        return None
    t0 = t[0] + skip * (t[-1] - t[0])
    vals = np.concatenate([np.asarray(e)[(t >= t0) & np.isfinite(e)] for e in errors] or [[]])
    if vals.size == 0:
        return None
    lo, hi = np.percentile(vals, [0.5, 99.5])
    lo, hi = min(lo, 0.0), max(hi, 0.0)
    span = max(hi - lo, 1e-6)
    return lo - (pad - 1) * span * (lo < 0), hi + (pad - 1) * span


def robust_limits(t, errors, skip=0.1, ratio=8.0, floor=1.0):
    """(limits, excluded): `steady_limits` of the filters that behave, and the
    indices of the errors left out of them: those whose steady error (95th
    percentile of |error| after the transient) is above `ratio` times the lower
    median of all filters' and above `floor` (degrees)."""
    t = np.asarray(t)
    if t.size == 0:
        return None, set()
    steady = t >= t[0] + skip * (t[-1] - t[0])
    level = []
    for e in errors:
        v = np.abs(np.asarray(e, dtype=np.float64)[steady])
        v = v[np.isfinite(v)]
        level.append(np.percentile(v, 95) if v.size else np.nan)
    known = np.sort([v for v in level if np.isfinite(v)])
    if known.size == 0:
        return None, set()
    thr = max(ratio * known[(known.size - 1) // 2], floor)
    out = {i for i, v in enumerate(level) if v > thr}
    return steady_limits(t, [e for i, e in enumerate(errors) if i not in out], skip), out


def _span(curves):
    """The span of the middle 98% of every value of curves (dict name -> array)."""
    vals = np.concatenate([np.ravel(np.asarray(c, dtype=np.float64)) for c in curves.values()]
                          or [[]])
    vals = vals[np.isfinite(vals)]
    return float(np.ptp(np.percentile(vals, [1, 99]))) if vals.size else None


def _coinciding(curves, period=None, rel=0.003, span=None):
    """{name: ["= A", "≈ B"]}: curves (dict name -> array, degrees) equal to an
    earlier one (=) or following it within `rel` of the span of all curves (or the
    `span` given) (≈: 99th percentile of |difference|, modulo `period`), NaN in the
    same places."""
    flat = {n: np.ravel(np.asarray(c, dtype=np.float64)) for n, c in curves.items()}
    span = _span(flat) if span is None else span
    if span is None:
        return {}
    tol = rel * max(span, 1e-9)
    out, names = {}, list(flat)
    for j, b in enumerate(names):
        for a in names[:j]:
            if not np.array_equal(np.isfinite(flat[a]), np.isfinite(flat[b])):
                continue
            d = flat[b] - flat[a]
            d = d[np.isfinite(d)]
            if period:
                d = (d + period / 2) % period - period / 2
            if d.size and np.percentile(np.abs(d), 99) <= tol:
                out.setdefault(b, []).append(("= " if not d.any() else "≈ ") + a)
    return out


def _coinciding_in(parts, period=None):
    """{name: ["≈ A", "tilt ≈ B"]}: `_coinciding` of each pair over the parts they both are
    in (dict part name -> {name: curve}, e.g. the panels; their curves joined, one
    tolerance from the span of all parts): named plainly when both are in the same parts,
    else with the parts they share (an IMU filter has no heading: "RobustAHRS (tilt ≈
    RobustIMU)")."""
    have = {}
    for part, curves in parts.items():
        for n in curves:
            have.setdefault(n, []).append(part)
    span = _span({f"{p} {n}": c for p, curves in parts.items() for n, c in curves.items()})
    names, out = list(have), {}
    for j, b in enumerate(names):
        for a in names[:j]:
            shared = [p for p in have[b] if p in have[a]]
            if not shared or span is None:
                continue
            pair = {n: np.concatenate([np.ravel(parts[p][n]) for p in shared]) for n in (a, b)}
            where = "" if have[a] == have[b] else ", ".join(shared) + " "
            out.setdefault(b, []).extend(where + tag for tag in
                                         _coinciding(pair, period, span=span).get(b, []))
    return {n: tags for n, tags in out.items() if tags}


def _angle_axis(ax, curves, wrapped):
    """Scale an angle panel to its data (curves: the drawn (N,) degrees, NaN breaks);
    the full (-180, 180] when an angle wraps there (wrapped: [(t, y) pairs at both ends
    of each break]), said in the panel and marked at each break."""
    vals = np.concatenate([c[np.isfinite(c)] for c in curves] or [[]])
    if wrapped:
        ax.set_ylim(-195, 195)
        ax.set_yticks(range(-180, 181, 90))
        for x, y, c in wrapped:
            ax.plot(x, y, "D", ms=3.5, color=c, mec="black", mew=0.3, clip_on=False,
                    zorder=15, label="_wrap")
        ax.set_title("wraps at ±180° (◆: a line goes on at the other edge)", loc="right",
                     fontsize=7, color="0.3", pad=2)
    elif vals.size:
        lo, hi = float(vals.min()), float(vals.max())
        mid, half = (lo + hi) / 2, max((hi - lo) / 2 * 1.08, 2.5)
        ax.set_ylim(mid - half, mid + half)


def _fmt(v):
    return f"{v:.0f}" if abs(v) >= 10 else f"{v:.2g}"
