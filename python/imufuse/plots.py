"""Plots of the command line (matplotlib, Agg backend, PNG files).

matplotlib is optional (the `plot` extra): check `available()` first.

Readability rules every plot follows:

- one fixed colour per filter in every panel of every plot (`colours`); lines
  drawn wide to narrow, each with its own dash pattern (`line_styles`), so a
  curve hidden under another one still shows at its edges; filters whose curves
  coincide are named in the legend ("B (= A)", "C (≈ A)"), per panel when they
  coincide in some panels only ("RobustIMU (tilt ≈ RobustAHRS)": an IMU filter
  has no heading to compare); the reference is drawn last, in black, dashed, on
  top;
- roll and yaw are angles in (-180, 180] (`wrap_deg`), the line broken where it
  wraps (`break_wraps`) instead of crossing the panel; every angle axis is
  scaled to its data (a roll within +-15° fills its panel), the full +-180°
  only when an angle wraps there, said in the panel ("wraps at ±180°") and
  marked at both ends of each break (◆); `plot_euler` names the earth frame of
  its angles (`frame`) in the labels and draws each filter from its own start
  (`starts`: FusionAHRS after its start-up from the identity, said in the
  legend), never a jump from an identity it was not started at;
- one error quantity per panel: `plot_euler`'s errors are one panel per
  quantity (inclination for every filter, heading and total for the AHRS
  filters), never two quantities on one axis;
- error axes hold every sample of the filters that behave (start-up transient
  included: nothing clipped); `robust_limits` leaves out a filter whose steady
  error (after the first 10% of the time) is far above the others'; such a
  filter is marked (legend label "KK (off scale, up to 175°)" and a triangle at
  the panel edge at its peak), never hidden silently;
- `plot_divergence` says "bit-exact" in words when nothing differs (no empty log
  frame) and lists the state variables that are equal;
- `plot_recordings` (compare over several recordings) gives each filter its bar
  in its colour in every recording's group, the mean over the recordings last,
  behind a dotted line; a metric a filter has not (an IMU filter's heading) has
  no bar;
- constrained layout (suptitle included), legends beside the panels: no label
  or title runs into another panel.

Each function returns the matplotlib Figure (already saved and closed: its
artists can still be inspected: tests read the panels' labels, limits, texts and
legends).
"""
import os
import textwrap

import numpy as np

from .shared.atomic import replacing
# the axes' helpers, unwrap_deg and steady_limits re-exported as imufuse.plots' own
from .shared.plotaxes import (_angle_axis, _coinciding, _coinciding_in, _fmt, break_wraps,  # noqa: F401
                        robust_limits, steady_limits, unwrap_deg, wrap_deg, wrap_marks)
from .shared.bits import UINT
from .catalogue import FILTERS, reference_class
from .rotations import heading_error, tilt_error

#: the reference line (drawn on top of the filters)
REF_STYLE = dict(color="black", lw=1.1, ls="--", zorder=10)

#: dash patterns given to the filters in turn (the first solid)
DASHES = ("-", (0, (5, 1.5)), (0, (1.5, 1)), (0, (7, 1.5, 1.5, 1.5)), (0, (3, 1)),
          (0, (8, 2, 1.5, 2, 1.5, 2)))

_LEGEND = dict(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def available():
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _figure(nrows, height, **kw):
    return _plt().subplots(nrows, 1, figsize=(10, height), sharex=True, layout="constrained",
                           **kw)


def colours(names):
    """{filter name: colour}: one fixed colour per filter, from its place among
    imufuse's filters of its kind (single-axis or 3D), so a filter has the same
    colour in every panel of every plot; strong colours first (tab10)."""
    import matplotlib
    strong = matplotlib.colormaps["tab10"]
    light = matplotlib.colormaps["tab20"]

    def group(n):
        try:
            return "1d" if reference_class(n).kind == "1d" else "3d"
        except ValueError:
            return "other"
    order = {}
    for n in list(FILTERS) + [n for n in names if n not in FILTERS]:
        order.setdefault(group(n), []).append(n)
    out = {}
    for n in names:
        i = order[group(n)].index(n)
        c = strong(i % 10) if i < 10 else light((2 * (i - 10) + 1) % 20)
        out[n] = matplotlib.colors.to_hex(c)
    return out


def line_styles(names, widest=2.2, narrowest=0.7):
    """{name: plot keywords}: line widths decreasing from `widest` to `narrowest`
    in the order given (drawn in that order, so each line lies on the wider ones
    and two equal curves both stay visible), and a dash pattern each (DASHES)."""
    n = len(names)
    return {name: dict(lw=round(widest - (widest - narrowest) * i / max(n - 1, 1), 2),
                       ls=DASHES[i % len(DASHES)], zorder=2 + i / max(n, 1))
            for i, name in enumerate(names)}


def _save(fig, path, title=""):
    if title:
        fig.suptitle("\n".join(textwrap.wrap(title, 110)), fontsize=9)
    if fig.get_layout_engine() is None:         # a figure made elsewhere (vario)
        fig.set_layout_engine("constrained")
    fig.align_ylabels()
    fmt = os.path.splitext(os.fspath(path))[1].lstrip(".").lower() or "png"
    try:
        with replacing(path) as tmp:
            fig.savefig(tmp, dpi=100, format=fmt)
    finally:
        _plt().close(fig)
    return fig


def _ylabel(ax, text, width=26):
    """A y label wrapped to lines of `width` characters (after a colon first), so a
    long one does not run past its panel into the next."""
    head, sep, tail = text.partition(": ")
    parts = [head + sep.strip(), tail] if sep else [text]
    ax.set_ylabel("\n".join(line for p in parts for line in textwrap.wrap(p, width)))


def _error_panel(ax, t, errors, col, sty, skip=0.1):
    """Errors (dict name -> (N,) degrees) on `ax`, the axis holding every sample of
    the filters that behave (`robust_limits`); a filter left out is marked with a
    triangle at the panel edge at its peak. Returns {name: legend note}."""
    t = np.asarray(t, dtype=np.float64)
    names = list(errors)
    errs = [np.asarray(errors[n], dtype=np.float64) for n in names]
    for n, e in zip(names, errs):
        ax.plot(t, e, color=col.get(n), label=n, **sty.get(n, {}))
    lim, out = robust_limits(t, errs, skip)
    if not lim:
        return {}
    # every sample of the filters that behave, their start-up included: nothing clipped
    kept = np.concatenate([e[np.isfinite(e)] for i, e in enumerate(errs) if i not in out])
    lo, hi = min(float(np.min(kept)), 0.0), max(float(np.max(kept)), 0.0)
    span = max(hi - lo, 1e-6)
    lim = (lo - 0.05 * span if lo < 0 else 0.0, hi + 0.05 * span)
    ax.set_ylim(*lim)
    notes = {}
    for n, e in zip(names, errs):
        s = np.where(np.isfinite(e), e, np.nan)
        if not np.any(s > lim[1]) and not np.any(s < lim[0]):
            continue
        k = int(np.nanargmax(np.abs(s)))
        up = s[k] > 0
        notes[n] = f"off scale, up to {_fmt(s[k])}°"
        ax.plot(t[k], 1.0 if up else 0.0, "^" if up else "v", ms=9, color=col.get(n),
                mec="black", mew=0.6, transform=ax.get_xaxis_transform(), clip_on=False,
                zorder=20, label=f"_{n} off scale")
    return notes


def _legend(ax, handles, *notes, extra=()):
    """The legend beside `ax`: one entry per handle (dict name -> line), its label
    the name and the notes about it (dicts name -> str or list), then `extra`
    (handle, label) pairs."""
    labels = []
    for n in handles:
        said = [x for d in notes for x in ([d[n]] if isinstance(d.get(n), str) else d.get(n, []))]
        labels.append(f"{n} ({'; '.join(said)})" if said else n)
    ax.legend(list(handles.values()) + [h for h, _ in extra],
              labels + [lab for _, lab in extra], **_LEGEND)


def _prefix(word, notes):
    return {n: f"{word} {v}" for n, v in notes.items()}


def plot_1d(path, t, truth, estimates, measured=None, title="single-axis filters"):
    """Angle estimates (rad, dict name -> (N,)) against the truth, and their errors."""
    col, sty = colours(list(estimates)), line_styles(list(estimates))
    fig, (a1, a2) = _figure(2, 7)
    extra, notes = [], {}
    if measured is not None:
        extra.append(a1.plot(t, np.degrees(measured), color="0.8", lw=0.6, zorder=1,
                             label="accelerometer angle")[0])
    lines = {n: a1.plot(t, np.degrees(ang), color=col[n], label=n, **sty[n])[0]
             for n, ang in estimates.items()}
    if truth is not None:
        extra.insert(0, a1.plot(t, np.degrees(truth), label="reference", **REF_STYLE)[0])
        notes = _error_panel(a2, t, {n: np.degrees(a - truth) for n, a in estimates.items()},
                             col, sty)
    _legend(a1, lines, _prefix("error", notes),
            _coinciding({n: np.degrees(a) for n, a in estimates.items()}),
            extra=[(h, h.get_label()) for h in extra])
    a1.set_ylabel("angle (deg)")
    a2.set_ylabel("error (deg)")
    a2.set_xlabel("time (s)")
    return _save(fig, path, title)


def plot_3d_errors(path, t, q_true, estimates, title="3D filters against ground truth"):
    """Tilt and heading errors (deg) of quaternion estimates (dict name -> Estimate)."""
    col, sty = colours(list(estimates)), line_styles(list(estimates))
    fig, (a1, a2) = _figure(2, 7)
    tilts = {n: np.degrees(tilt_error(e.q, q_true)) for n, e in estimates.items()}
    heads = {n: np.degrees(heading_error(e.q, q_true)) for n, e in estimates.items() if e.heading}
    notes = _error_panel(a1, t, tilts, col, sty)
    hnotes = _error_panel(a2, t, heads, col, sty)
    same = _coinciding_in({"tilt": tilts, "heading": heads})
    handles = {ln.get_label(): ln for ln in a1.get_lines() if ln.get_label() in tilts}
    _legend(a1, handles, _prefix("tilt", notes), _prefix("heading", hnotes), same)
    a1.set_ylabel("tilt error (deg)")
    a2.set_ylabel("heading error (deg)")
    a2.set_xlabel("time (s)")
    if not heads:
        a2.text(0.5, 0.5, "no filter with a heading", transform=a2.transAxes, ha="center")
    return _save(fig, path, title)


def _from(e, k):
    e = np.array(e, dtype=np.float64)
    e[:k] = np.nan
    return e


def plot_euler(path, t, series, ref=None, title="", errors=None, error_label="error (deg)",
               frame="NWU", starts=None):
    """Roll, pitch, yaw (rad, dict name -> (N, 3), NaN where unknown, in the
    earth frame `frame`, named in the labels) and an optional reference (N, 3);
    roll and yaw in (-180, 180], broken where they wrap; each angle panel scaled to
    its data. starts: {name: first sample, or (first sample, what comes before it)} of
    filters drawn from their own start (FusionAHRS after its start-up from the identity;
    said in the legend: "from 3 s: its start-up not drawn"). errors: optional, either
    {quantity: {name: (N,) degrees}} (a panel per quantity, "inclination error (deg)",
    ...: one quantity on each axis) or {name: (N,) degrees} (one panel, error_label);
    each scaled to the filters that behave (the others marked off scale)."""
    errors = errors or {}
    if errors and not all(isinstance(v, dict) for v in errors.values()):
        errors = {None: errors}
    errors = {q: e for q, e in errors.items() if e}
    in_errors = [n for e in errors.values() for n in e if n not in series]
    col = colours(list(series) + list(dict.fromkeys(in_errors)))
    sty = line_styles(list(col))
    starts = {n: v if isinstance(v, tuple) else (v, "its start-up")
              for n, v in (starts or {}).items()}
    starts = {n: (int(k), why) for n, (k, why) in starts.items() if n in series and k > 0}
    shown = {n: _from(e, starts.get(n, (0,))[0]) for n, e in series.items()}
    n = 3 + len(errors)
    fig, axes = _figure(n, (2.6 if n <= 4 else 2.3) * n + 0.5)
    handles = {}
    for i, (ax, lab) in enumerate(zip(axes, ("roll", "pitch", "yaw"))):
        drawn, wrapped = [], []
        for name, e in list(shown.items()) + ([("reference", ref)] if ref is not None else []):
            if np.all(np.isnan(e[:, i])):
                continue
            y = np.degrees(e[:, 1]) if i == 1 else wrap_deg(e[:, i])
            kw = REF_STYLE if name == "reference" else dict(color=col[name], **sty[name])
            handles.setdefault(name, ax.plot(*break_wraps(t, y) if i != 1 else (t, y),
                                             label=name, **kw)[0])
            drawn.append(y)
            marks = wrap_marks(t, y) if i != 1 else ((), ())
            if len(marks[0]):
                wrapped.append((*marks, kw["color"]))
        ax.set_ylabel(f"{lab} (deg, {frame})")
        _angle_axis(ax, drawn, wrapped)
        if not drawn:
            ax.set_yticks([])
            ax.text(0.5, 0.5, f"no filter with a {'heading' if i == 2 else lab}",
                    transform=ax.transAxes, ha="center")
    same = _coinciding_in({lab: {k: wrap_deg(e[:, i]) for k, e in shown.items()
                                 if not np.all(np.isnan(e[:, i]))}
                           for i, lab in enumerate(("roll", "pitch", "yaw"))}, period=360.0)
    begun = {nm: f"from {t[min(k, len(t) - 1)] - t[0]:.3g} s: {why} not drawn"
             for nm, (k, why) in starts.items()}
    for nm in begun:             # a start-up as long as the log: in the legend all the same
        handles.setdefault(nm, axes[0].plot([], [], color=col[nm], label=nm, **sty[nm])[0])
    notes = {}
    for ax, (quantity, errs) in zip(axes[3:], errors.items()):
        said = _error_panel(ax, t, errs, col, sty)
        _ylabel(ax, error_label if quantity is None else f"{quantity} error (deg)")
        if said:
            _legend(ax, {ln.get_label(): ln for ln in ax.get_lines()
                         if ln.get_label() in said}, said)
        for nm, v in _prefix(quantity or "error", said).items():
            notes.setdefault(nm, []).append(v)
    ref_line = handles.pop("reference", None)
    _legend(axes[0], handles, begun, notes, same,
            extra=[(ref_line, "reference")] if ref_line else [])
    axes[-1].set_xlabel("time (s)")
    return _save(fig, path, title)


def plot_states(path, t, states, names, title=""):
    """Every state variable of one run against time."""
    n = len(names)
    fig, axes = _figure(n, min(2.0 * n + 1, 14), squeeze=False)
    for i, ax in enumerate(axes[:, 0]):
        ax.plot(t, states[:, i], lw=0.9)
        ax.set_ylabel(names[i])
    axes[-1, 0].set_xlabel("time (s)")
    return _save(fig, path, title)


def _same_bits(g, w):
    """Elementwise: equal bit patterns (floats of one dtype, as `bits`
    compares them) or equal values (both NaN counting as equal)."""
    if g.dtype == w.dtype and g.dtype in UINT:
        return g.view(UINT[g.dtype]) == w.view(UINT[g.dtype])
    with np.errstate(invalid="ignore"):
        return (g == w) | (np.isnan(g.astype(np.float64)) & np.isnan(w.astype(np.float64)))


def plot_divergence(path, t, got, want, names, first=None, title=""):
    """|got - want| per state variable (log scale), the first divergence marked;
    the variables equal after every sample listed; a run that is bit-exact
    throughout said so in words, on a linear axis."""
    fig, ax = _plt().subplots(figsize=(10, 5), layout="constrained")
    g, w = np.asarray(got), np.asarray(want)
    if g.ndim == 1:
        g, w = g[:, None], w[:, None]
    x = np.arange(len(g)) if t is None else np.asarray(t)
    same = _same_bits(g, w)
    equal = [nm for i, nm in enumerate(names) if same[:, i].all()]
    ax.set_xlabel("time (s)" if t is not None else "sample")
    ax.set_ylabel("|firmware - imufuse|")
    if len(equal) == len(names):
        ax.plot(x, np.zeros(len(x)), color="tab:green", lw=2)
        ax.set_ylim(-1, 1)
        ax.set_yticks([0])
        ax.text(0.5, 0.6, f"bit-exact: every state variable equal after every sample, "
                f"{len(g)} samples", transform=ax.transAxes, ha="center", va="center",
                fontsize=13, color="tab:green", weight="bold")
        ax.text(0.5, 0.4, "\n".join(textwrap.wrap(f"{len(names)} variables: {', '.join(names)}",
                                                  110)),
                transform=ax.transAxes, ha="center", va="center", fontsize=9)
        return _save(fig, path, title)
    with np.errstate(all="ignore"):
        d = np.abs(g.astype(np.float64) - w.astype(np.float64))
    for i, nm in enumerate(names):
        if nm in equal:
            continue
        odd = ~same[:, i] & ~(np.isfinite(d[:, i]) & (d[:, i] > 0))   # NaN/inf, or +-0
        k = int(odd.sum())
        note = f" ({k} sample{'s' * (k > 1)} differ as NaN/inf/±0: × at top)" if k else ""
        line, = ax.plot(x, np.where(d[:, i] > 0, d[:, i], np.nan), lw=0.9, label=nm + note)
        if k:
            ax.plot(x[odd], np.ones(odd.sum()), "x", color=line.get_color(), clip_on=False,
                    transform=ax.get_xaxis_transform(), label=f"_{nm} odd")
    if first is not None:
        ax.axvline(x[first], color="r", ls="--", lw=1, label=f"first divergence (sample {first})")
    ax.set_yscale("log")
    if not np.any(np.isfinite(d[~same]) & (d[~same] > 0)):
        ax.set_ylim(1e-16, 1)
    if equal:
        ax.plot([], [], ls="none", label="\n".join(textwrap.wrap(
            f"equal after every sample ({len(equal)}): {', '.join(equal)}", 60)))
    ax.legend(**_LEGEND)
    return _save(fig, path, title)


def plot_recordings(path, recordings, errors, means=None, title=""):
    """Each recording's RMS errors as bars, one group per recording (and one for the mean
    over them), one bar per filter in its colour: errors {metric: {filter: [deg per
    recording]}} (a panel per metric, in the order given; NaN: no bar, the filter has no such
    error there), means {metric: {filter: deg}}."""
    metrics = [m for m in errors if errors[m]]
    names = list(dict.fromkeys(n for m in metrics for n in errors[m]))
    col = colours(names)
    labels = [os.path.basename(os.fspath(r)) for r in recordings] + (["mean"] if means else [])
    fig, axes = _figure(max(len(metrics), 1), 2.6 * max(len(metrics), 1) + 1.0, squeeze=False)
    x = np.arange(len(labels))
    width = 0.8 / max(len(names), 1)
    for ax, m in zip(axes[:, 0], metrics):
        for i, n in enumerate(names):
            if n not in errors[m]:
                continue
            v = list(errors[m][n]) + ([means.get(m, {}).get(n, np.nan)] if means else [])
            ax.bar(x - 0.4 + width * (i + 0.5), np.asarray(v, dtype=np.float64), width,
                   color=col[n], label=n)
        if means:
            ax.axvline(len(recordings) - 0.5, color="0.6", lw=0.8, ls=":")
        _ylabel(ax, f"{m} RMS (deg)")
        ax.grid(axis="y", lw=0.4, alpha=0.5)
    axes[0, 0].legend(**_LEGEND)
    axes[-1, 0].set_xticks(x)
    axes[-1, 0].set_xticklabels(labels, rotation=30 if len(labels) > 6 else 0, ha="right"
                                if len(labels) > 6 else "center", fontsize=8)
    return _save(fig, path, title)
