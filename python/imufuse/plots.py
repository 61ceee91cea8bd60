"""Plots of the command line (matplotlib, Agg backend, PNG files).

matplotlib is optional (the `plot` extra): check `available()` first."""
import numpy as np

from .rotations import heading_error, tilt_error


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


def _save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    _plt().close(fig)


def plot_1d(path, t, truth, estimates, measured=None):
    """Angle estimates (rad, dict name -> (N,)) against the truth, and their errors."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    if measured is not None:
        a1.plot(t, np.degrees(measured), color="0.8", lw=0.6, label="accelerometer angle")
    if truth is not None:
        a1.plot(t, np.degrees(truth), "k", lw=1.5, label="truth")
    for name, ang in estimates.items():
        a1.plot(t, np.degrees(ang), lw=0.9, label=name)
        if truth is not None:
            a2.plot(t, np.degrees(ang - truth), lw=0.9, label=name)
    a1.set_ylabel("angle (deg)")
    a1.legend(fontsize=7, ncol=2)
    a2.set_ylabel("error (deg)")
    a2.set_xlabel("time (s)")
    a1.set_title("single-axis filters")
    _save(fig, path)


def plot_3d_errors(path, t, q_true, estimates):
    """Tilt and heading errors (deg) of quaternion estimates (dict name -> Estimate)."""

    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    for name, est in estimates.items():
        a1.plot(t, np.degrees(tilt_error(est.q, q_true)), lw=0.9, label=name)
        if est.heading:
            a2.plot(t, np.degrees(heading_error(est.q, q_true)), lw=0.9, label=name)
    a1.set_ylabel("tilt error (deg)")
    a1.set_yscale("log")
    a1.legend(fontsize=7, ncol=2)
    a2.set_ylabel("heading error (deg)")
    a2.set_xlabel("time (s)")
    a1.set_title("3D filters against ground truth")
    _save(fig, path)


def plot_euler(path, t, series, ref=None):
    """Roll, pitch, yaw (rad, dict name -> (N, 3), NaN where unknown) and an optional reference."""
    plt = _plt()
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    for i, (ax, lab) in enumerate(zip(axes, ("roll", "pitch", "yaw"))):
        if ref is not None:
            ax.plot(t, np.degrees(ref[:, i]), "k", lw=1.5, label="reference")
        for name, e in series.items():
            if not np.all(np.isnan(e[:, i])):
                ax.plot(t, np.degrees(e[:, i]), lw=0.9, label=name)
        ax.set_ylabel(f"{lab} (deg)")
    axes[0].legend(fontsize=7, ncol=2)
    axes[-1].set_xlabel("time (s)")
    _save(fig, path)


def plot_states(path, t, states, names, title=""):
    """Every state variable of one run against time."""
    plt = _plt()
    n = len(names)
    fig, axes = plt.subplots(n, 1, figsize=(10, min(2.0 * n + 1, 14)), sharex=True, squeeze=False)
    for i, ax in enumerate(axes[:, 0]):
        ax.plot(t, states[:, i], lw=0.9)
        ax.set_ylabel(names[i])
    axes[0, 0].set_title(title)
    axes[-1, 0].set_xlabel("time (s)")
    _save(fig, path)


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
    ax.set_title(title)
    ax.legend(fontsize=7)
    _save(fig, path)
