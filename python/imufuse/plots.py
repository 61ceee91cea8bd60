"""Plots of the command line (matplotlib, Agg backend, PNG files).

matplotlib is optional (the `plot` extra): check `available()` first.

Every filter keeps one colour in every panel of every plot (`colours`), the
reference is drawn last, in black, on top; yaw is unwrapped; error axes are
scaled to the errors after the start-up transient (`steady_limits`), so the
steady state is visible. Each function returns the matplotlib Figure (already
saved and closed: its artists can still be inspected).
"""
import os

import numpy as np

from ._atomic import replacing

from .catalogue import FILTERS, reference_class
from .rotations import heading_error, tilt_error

#: the reference line (drawn on top of the filters)
REF_STYLE = dict(color="black", lw=1.1, ls="--", zorder=10)


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


def _save(fig, path, title=""):
    if title:
        import textwrap
        fig.suptitle("\n".join(textwrap.wrap(title, 110)), fontsize=9)
    fig.tight_layout()
    fmt = os.path.splitext(os.fspath(path))[1].lstrip(".").lower() or "png"
    try:
        with replacing(path) as tmp:
            fig.savefig(tmp, dpi=100, format=fmt)
    finally:
        _plt().close(fig)
    return fig


def unwrap_deg(angle_rad):
    """Degrees, unwrapped (no +-180 jumps) over the finite stretches; the first
    finite value stays in [-180, 180]."""
    a = np.asarray(angle_rad, dtype=np.float64).copy()
    ok = np.isfinite(a)
    if ok.any():
        a[ok] = np.unwrap(a[ok])
    return np.degrees(a)


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


def plot_1d(path, t, truth, estimates, measured=None, title="single-axis filters"):
    """Angle estimates (rad, dict name -> (N,)) against the truth, and their errors."""
    plt = _plt()
    col = colours(list(estimates))
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    if measured is not None:
        a1.plot(t, np.degrees(measured), color="0.8", lw=0.6, label="accelerometer angle")
    errs = []
    for name, ang in estimates.items():
        a1.plot(t, np.degrees(ang), lw=0.9, color=col[name], label=name)
        if truth is not None:
            e = np.degrees(ang - truth)
            errs.append(e)
            a2.plot(t, e, lw=0.9, color=col[name], label=name)
    if truth is not None:
        a1.plot(t, np.degrees(truth), label="reference", **REF_STYLE)
        lim = steady_limits(t, errs)
        if lim:
            a2.set_ylim(*lim)
    a1.set_ylabel("angle (deg)")
    a1.legend(fontsize=7, ncol=2)
    a2.set_ylabel("error (deg)")
    a2.set_xlabel("time (s)")
    return _save(fig, path, title)


def plot_3d_errors(path, t, q_true, estimates, title="3D filters against ground truth"):
    """Tilt and heading errors (deg) of quaternion estimates (dict name -> Estimate)."""
    plt = _plt()
    col = colours(list(estimates))
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    tilts, heads = [], []
    for name, est in estimates.items():
        e = np.degrees(tilt_error(est.q, q_true))
        tilts.append(e)
        a1.plot(t, e, lw=0.9, color=col[name], label=name)
        if est.heading:
            h = np.degrees(heading_error(est.q, q_true))
            heads.append(h)
            a2.plot(t, h, lw=0.9, color=col[name], label=name)
    for ax, es in ((a1, tilts), (a2, heads)):
        lim = steady_limits(t, es)
        if lim:
            ax.set_ylim(*lim)
    a1.set_ylabel("tilt error (deg)")
    a1.legend(fontsize=7, ncol=2)
    a2.set_ylabel("heading error (deg)")
    a2.set_xlabel("time (s)")
    if not heads:
        a2.text(0.5, 0.5, "no filter with a heading", transform=a2.transAxes, ha="center")
    return _save(fig, path, title)


def plot_euler(path, t, series, ref=None, title="", errors=None, error_label="error (deg)"):
    """Roll, pitch, yaw (rad, dict name -> (N, 3), NaN where unknown) and an
    optional reference (N, 3); roll and yaw unwrapped. errors: optional dict
    name -> (N,) degrees, drawn in a fourth panel scaled to the steady state."""
    plt = _plt()
    col = colours(list(series))
    n = 4 if errors else 3
    fig, axes = plt.subplots(n, 1, figsize=(10, 2.6 * n + 0.5), sharex=True)
    for i, (ax, lab) in enumerate(zip(axes, ("roll", "pitch", "yaw"))):
        conv = np.degrees if i == 1 else unwrap_deg
        for name, e in series.items():
            if not np.all(np.isnan(e[:, i])):
                ax.plot(t, conv(e[:, i]), lw=0.9, color=col[name], label=name)
        if ref is not None:
            ax.plot(t, conv(ref[:, i]), label="reference", **REF_STYLE)
        ax.set_ylabel(f"{lab} (deg)" + ("" if i == 1 else ", unwrapped"))
    if errors:
        ax = axes[3]
        for name, e in errors.items():
            ax.plot(t, e, lw=0.9, color=col.get(name), label=name)
        lim = steady_limits(t, list(errors.values()))
        if lim:
            ax.set_ylim(*lim)
        ax.set_ylabel(error_label)
    axes[0].legend(fontsize=7, ncol=3)
    axes[-1].set_xlabel("time (s)")
    return _save(fig, path, title)


def plot_states(path, t, states, names, title=""):
    """Every state variable of one run against time."""
    plt = _plt()
    n = len(names)
    fig, axes = plt.subplots(n, 1, figsize=(10, min(2.0 * n + 1, 14)), sharex=True, squeeze=False)
    for i, ax in enumerate(axes[:, 0]):
        ax.plot(t, states[:, i], lw=0.9)
        ax.set_ylabel(names[i])
    axes[-1, 0].set_xlabel("time (s)")
    return _save(fig, path, title)


def plot_divergence(path, t, got, want, names, first=None, title=""):
    """|got - want| per state variable (log scale), the first divergence marked."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(10, 5))
    d = np.abs(np.asarray(got, dtype=np.float64) - np.asarray(want, dtype=np.float64))
    for i, n in enumerate(names):
        y = np.where(d[:, i] > 0, d[:, i], np.nan)
        ax.plot(t, y, lw=0.9, label=n)
    if first is not None:
        ax.axvline(t[first], color="r", ls="--", lw=1, label=f"first divergence (sample {first})")
    ax.set_yscale("log")
    ax.set_xlabel("time (s)" if t is not None else "sample")
    ax.set_ylabel("|firmware - imufuse|")
    ax.legend(fontsize=7)
    return _save(fig, path, title)
