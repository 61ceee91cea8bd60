"""The command line's plots are readable: error axes scaled to the filters that
behave (a diverged one marked off scale), coinciding lines told apart, roll and
yaw shown as angles in (-180, 180], a bit-exact validation said in words, no
label or title running into another panel, the earth frame named."""
import itertools

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="matplotlib (the plot extra) not installed")

from imufuse import plots  # noqa: E402

T = np.linspace(0.0, 40.0, 4001)


def _errors():
    """Two filters at ~2 deg, KK wandering up to 175 deg."""
    return {"MahonyIMU": 2.0 + 0.5 * np.sin(T),
            "MadgwickIMU": 1.8 + 0.4 * np.cos(1.3 * T),
            "KK": 90.0 + 85.0 * np.sin(0.7 * T)}


def _euler(roll_deg, pitch_deg=0.0, yaw_deg=0.0):
    e = np.zeros((len(T), 3))
    e[:, 0], e[:, 1], e[:, 2] = np.radians(roll_deg), np.radians(pitch_deg), np.radians(yaw_deg)
    return e


def _legend_texts(fig):
    return [t.get_text() for ax in fig.axes if ax.get_legend()
            for t in ax.get_legend().get_texts()]


def _filter_lines(ax, names):
    return {ln.get_label(): ln for ln in ax.get_lines() if ln.get_label() in names}


def _assert_no_overlap(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    if not hasattr(fig.canvas, "get_renderer"):     # closed: a bare canvas
        FigureCanvasAgg(fig)
    r = fig.canvas.get_renderer()
    boxes = [ax.get_tightbbox(r) for ax in fig.axes]
    for (i, a), (j, b) in itertools.combinations(enumerate(boxes), 2):
        w = min(a.x1, b.x1) - max(a.x0, b.x0)
        h = min(a.y1, b.y1) - max(a.y0, b.y0)
        assert w <= 0.5 or h <= 0.5, (f"axes {i} ({fig.axes[i].get_ylabel()!r}) and {j} "
                                      f"({fig.axes[j].get_ylabel()!r}) overlap: {a} {b}")
    if fig._suptitle is not None:
        s = fig._suptitle.get_window_extent(r)
        for i, a in enumerate(boxes):
            assert a.y1 <= s.y0 + 0.5 or s.x1 <= a.x0 or a.x1 <= s.x0, f"suptitle over axes {i}"


def test_error_axis_ignores_the_diverged_filter_and_marks_it(tmp_path):
    errs = _errors()
    series = {n: _euler(10 * np.sin(T)) for n in errs}
    fig = plots.plot_euler(tmp_path / "e.png", T, series, None, errors=errs,
                           error_label="error (deg): total (AHRS), inclination (IMU)")
    ax = fig.axes[3]
    lo, hi = ax.get_ylim()
    assert 2.5 <= hi < 10, (lo, hi)         # the two good filters fill the panel, KK clipped
    texts = _legend_texts(fig)
    assert any(t.startswith("KK (") and "off scale" in t and "175" in t for t in texts), texts
    assert not any("off scale" in t for t in texts if not t.startswith("KK")), texts
    # a marker at the top edge, in KK's colour
    col = plots.colours(list(errs))["KK"]
    marks = [ln for ln in ax.get_lines() if ln.get_marker() == "^"]
    assert marks and marks[0].get_color() == col
    assert (tmp_path / "e.png").stat().st_size > 0


@pytest.mark.parametrize("which", ["plot_1d", "plot_3d_errors"])
def test_other_error_panels_robust_too(tmp_path, which):
    if which == "plot_1d":
        truth = np.radians(20 * np.sin(T))
        est = {n: truth + np.radians(e) for n, e in _errors().items()}
        fig = plots.plot_1d(tmp_path / "a.png", T, truth, est)
        ax = fig.axes[1]
    else:
        from imufuse.shared.estimate import Estimate
        from imufuse.rotations import quat_from_rotvec
        q_true = np.tile([1.0, 0.0, 0.0, 0.0], (len(T), 1))
        ests = {n: Estimate(q=quat_from_rotvec(np.radians(e)[:, None] * [1.0, 0.0, 0.0]))
                for n, e in _errors().items()}
        fig = plots.plot_3d_errors(tmp_path / "b.png", T, q_true, ests)
        ax = fig.axes[0]
    assert ax.get_ylim()[1] < 10
    assert any(t.startswith("KK (") and "off scale" in t for t in _legend_texts(fig))


def test_identical_series_drawn_distinguishable(tmp_path):
    e = _euler(30 * np.sin(T), 10 * np.cos(T), 50 * np.sin(0.2 * T))
    series = {"MahonyIMU": e, "DCM": e.copy(), "MadgwickIMU": _euler(-20 + 0 * T)}
    fig = plots.plot_euler(tmp_path / "s.png", T, series)
    for ax in fig.axes[:3]:
        a, b = (_filter_lines(ax, series)[n] for n in ("MahonyIMU", "DCM"))
        assert (a.get_linestyle(), a.get_linewidth()) != (b.get_linestyle(), b.get_linewidth())
        # drawn wide to narrow: the one on top is the narrower
        top, under = (a, b) if a.get_zorder() > b.get_zorder() else (b, a)
        assert top.get_linewidth() < under.get_linewidth()
    texts = _legend_texts(fig)
    assert "DCM (= MahonyIMU)" in texts, texts
    assert "MadgwickIMU" in texts


def test_roll_and_yaw_wrapped_and_broken(tmp_path):
    roll = np.linspace(150.0, 250.0, len(T))     # crosses +180 (unwrapped: up to 250)
    yaw = np.linspace(-170.0, -400.0, len(T))    # crosses -180, turns on past -360
    series = {"MahonyAHRS": _euler(roll, 5.0, yaw)}
    ref = _euler(roll + 1, 5.0, yaw + 1)
    fig = plots.plot_euler(tmp_path / "w.png", T, series, ref, frame="ENU")
    for i in (0, 2):
        ax = fig.axes[i]
        for ln in ax.get_lines():
            if ln.get_linestyle() == "None":        # the marks at the wraps (◆)
                continue
            y = np.asarray(ln.get_ydata(), dtype=float)
            f = y[np.isfinite(y)]
            assert f.size and np.all((f > -180) & (f <= 180)), (ax.get_ylabel(), f.min(), f.max())
            assert np.isnan(y).any(), "no break where the angle wraps"
            assert np.nanmax(np.abs(np.diff(y))) < 10, "a line across the panel"
        assert "ENU" in ax.get_ylabel()
    assert "ENU" in fig.axes[1].get_ylabel()


def test_wrap_helpers():
    d = plots.wrap_deg(np.radians([-540.0, -180.0, 0.0, 180.0, 190.0, 359.0, 720.0, np.nan]))
    assert np.allclose(d[:-1], [180, 180, 0, 180, -170, -1, 0])
    assert np.isnan(d[-1])
    t, y = plots.break_wraps([0, 1, 2, 3], [170.0, 179.0, -178.0, -170.0])
    assert len(t) == 5 and np.isnan(y[2]) and t[2] == 1.5
    assert np.all(np.abs(np.diff(plots.unwrap_deg(np.radians([170, -170, -150])))) < 30)


def test_bit_exact_divergence_said_in_words(tmp_path):
    a = np.random.default_rng(1).normal(size=(300, 4)).astype(np.float32)
    fig = plots.plot_divergence(tmp_path / "d.png", np.arange(300) * 0.01, a, a.copy(),
                                ["q0", "q1", "q2", "q3"], None, "firmware vs imufuse")
    ax = fig.axes[0]
    assert ax.get_yscale() == "linear"
    text = " ".join(t.get_text() for t in ax.texts)
    assert "bit-exact" in text and "300 samples" in text
    _assert_no_overlap(fig)


def test_partial_divergence_lists_the_equal_variables(tmp_path):
    a = np.random.default_rng(2).normal(size=(300, 4)).astype(np.float32)
    b = a.copy()
    b[100:, 1] += np.float32(1e-3)
    b[150, 2] = -0.0 if a[150, 2] == 0 else np.nan          # differs, no plottable |diff|
    fig = plots.plot_divergence(tmp_path / "p.png", None, b, a, ["q0", "q1", "q2", "q3"], 100)
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    texts = " ".join(_legend_texts(fig))
    assert "equal after every sample" in texts and "q0" in texts and "q3" in texts
    assert "q2 (1 sample differ" in texts                          # not hidden silently
    # -0.0 vs +0.0 is not bit-exact (as bits.compare_states sees it)
    z = np.zeros((5, 1), np.float32)
    fig = plots.plot_divergence(tmp_path / "z.png", None, -z, z, ["x"])
    assert fig.axes[0].get_yscale() == "log"


def test_no_overlapping_labels(tmp_path):
    errs = _errors()
    series = {n: _euler(170 * np.sin(T), 30 * np.sin(T), 100 * np.cos(T)) for n in errs}
    long_title = "a long title, " * 20
    figs = [plots.plot_euler(tmp_path / "o.png", T, series, series["KK"], title=long_title,
                             errors=errs,
                             error_label="error (deg): total (AHRS), inclination (IMU)"),
            plots.plot_1d(tmp_path / "o1.png", T, np.zeros(len(T)),
                          {n: np.radians(e) for n, e in errs.items()}, np.zeros(len(T)),
                          title=long_title),
            plots.plot_states(tmp_path / "st.png", T, np.random.default_rng(0).normal(
                size=(len(T), 9)), [f"state_{i}" for i in range(9)], title=long_title)]
    for fig in figs:
        _assert_no_overlap(fig)
