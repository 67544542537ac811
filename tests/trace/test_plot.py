"""Trace.plot: files written, panels, labels with units, legends, state marks."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from distctrl.trace import HLI_STATE_NAMES, Trace  # noqa: E402
from distctrl.trace.plot import envelope, default_groups, state_segments  # noqa: E402

COLS = ["t", "line", "Z.prog", "Z.cmd", "Z.act", "Z.dc.state", "Z.dc.offset", "Z.dc.filtered",
        "Z.dc.target_deviation", "X.act", "true.surface", "true.distance"]
UNITS = {"t": "s", "Z.prog": "mm", "Z.cmd": "mm", "Z.act": "mm", "Z.dc.offset": "mm",
         "Z.dc.filtered": "mm", "Z.dc.target_deviation": "mm", "X.act": "mm", "true.surface": "mm",
         "true.distance": "mm", "line": ""}


def make_trace(n: int = 3000) -> Trace:
    t = np.arange(n) * 0.001
    state = np.where(t < 0.5, 0, np.where(t < 2.0, 1, np.where(t < 2.4, 3, 0))).astype(float)
    off = np.where(state > 0, 0.3 * np.sin(4 * t), 0.0)
    surface = 18.0 + 0.2 * np.sin(3 * t)
    data = np.column_stack([t, t // 0.5, np.full(n, 20.0), 20.0 + off, 20.0 + off - 0.002, state, off,
                            0.9 * off, np.full(n, 1.0), 100 * t, surface, 20.0 + off - surface])
    return Trace(COLS, data, units=UNITS, meta={"program": "dist_1.nc"})


def test_png_and_svg_written(tmp_path):
    tr = make_trace()
    fig = tr.plot(tmp_path / "p.png")
    png = (tmp_path / "p.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    tr.plot(tmp_path / "sub" / "p.svg")
    svg = (tmp_path / "sub" / "p.svg").read_text()
    assert "<svg" in svg and len(svg) > 10_000
    assert fig is not None


def test_default_panels_labels_and_legends():
    fig = make_trace().plot(title="run 1")
    axes = fig.axes
    assert len(axes) == 3
    labels = [ax.get_ylabel() for ax in axes]
    assert labels == ["Z position [mm]", "Z distance control [mm]", "distance [mm]"]
    assert axes[-1].get_xlabel() == "t [s]"
    legends = [[t.get_text() for t in ax.get_legend().get_texts()] for ax in axes]
    assert legends[0] == ["Z.prog", "Z.cmd", "Z.act", "true.surface"]
    assert legends[1] == ["Z.dc.offset", "Z.dc.filtered", "Z.dc.target_deviation"]
    assert legends[2] == ["true.distance"]
    assert fig._suptitle.get_text() == "run 1"
    for ax in axes:
        assert ax.xaxis.get_gridlines()[0].get_visible()


def test_state_changes_marked_and_named():
    fig = make_trace().plot()
    top = fig.axes[0]
    names = [t.get_text() for t in top.texts]
    assert names == ["INACTIVE", "ACTIVE", "TURNING_OFF", "INACTIVE"]
    # shaded bands for the two non-INACTIVE runs, on every panel
    for ax in fig.axes:
        assert len(ax.patches) == 2
    fig_legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert fig_legend == ["Z.dc.state ACTIVE", "Z.dc.state TURNING_OFF"]


def test_title_from_meta():
    fig = make_trace().plot()
    assert fig._suptitle.get_text() == "dist_1.nc"


def test_signals_one_panel_per_unit():
    tr = make_trace()
    fig = tr.plot(signals=["Z.act", "X.act", "line", "Z.dc.state"])
    assert len(fig.axes) == 2
    leg = [[t.get_text() for t in ax.get_legend().get_texts()] for ax in fig.axes]
    assert leg == [["Z.act", "X.act"], ["line", "Z.dc.state"]]
    assert fig.axes[0].get_ylabel() == "Z.act, X.act [mm]"
    assert fig.axes[1].get_xlabel() == "t [s]"
    with pytest.raises(KeyError):
        tr.plot(signals=["Z.nope"])


def test_plot_after_csv_round_trip(tmp_path):
    tr = make_trace(500)
    tr.to_csv(tmp_path / "r.csv")
    fig = Trace.from_csv(tmp_path / "r.csv").plot(tmp_path / "r.png")
    assert fig.axes[0].get_ylabel() == "Z position [mm]"
    assert (tmp_path / "r.png").stat().st_size > 5_000


def test_non_dc_trace_plots_by_unit():
    tr = Trace(["t", "a", "b", "c"], np.random.default_rng(0).standard_normal((50, 4)),
               units={"t": "s", "a": "mm", "b": "mm", "c": "mm/s"})
    groups = default_groups(tr)
    assert groups == [("", ["a", "b"]), ("", ["c"])]
    fig = tr.plot()
    assert [ax.get_ylabel() for ax in fig.axes] == ["a, b [mm]", "c [mm/s]"]


def test_state_segments_and_names():
    assert state_segments(np.array([0, 0, 1, 1, 1, 3, 0.0])) == [(0, 2, 0), (2, 5, 1), (5, 6, 3), (6, 7, 0)]
    assert state_segments(np.array([])) == []
    assert HLI_STATE_NAMES[4] == "ACTIVE_CONST_DIST" and HLI_STATE_NAMES[7] == "DRYRUN_SETPOS"


def test_state_names_match_the_control_enum():
    states = pytest.importorskip("distctrl.base.states")
    assert HLI_STATE_NAMES == {int(s): s.name for s in states.HliState}


def test_envelope_keeps_peaks():
    x = np.arange(1_000_001, dtype=float)
    y = np.zeros_like(x)
    y[123_457] = 5.0
    y[987_654] = -3.0
    xs, ys = envelope(x, y, 10_000)
    assert xs.size <= 10_100 and ys.max() == 5.0 and ys.min() == -3.0
    assert np.all(np.diff(xs) >= 0)


def test_chattering_state_is_shaded_by_value(tmp_path):
    n = 20_000
    t = np.arange(n) * 0.001
    state = ((np.arange(n) // 3) % 3).astype(float)          # ~6700 runs
    tr = Trace(["t", "Z.act", "Z.dc.state"], np.column_stack([t, np.sin(t), state]),
               units={"t": "s", "Z.act": "mm"})
    fig = tr.plot(tmp_path / "c.png")
    assert len(fig.axes[0].texts) == 0
    assert len(fig.axes[0].collections) == 2                 # one shading per non-INACTIVE state
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["Z.dc.state ACTIVE", "Z.dc.state FREEZE"]


def _sheet_like_trace(n: int = 5000) -> Trace:
    """The demo's sheet: INACTIVE for 2 cycles (the filter runs on the surface position, 30 mm), then
    ACTIVE_CONST_DIST (the distance, 1 mm) and at the end TURNING_OFF for 2 cycles, INACTIVE."""
    t = np.arange(n) * 0.001
    state = np.full(n, 4.0)
    state[:2] = 0.0
    state[-4:-2] = 3.0
    state[-2:] = 0.0
    filtered = np.where(state == 0, 30.0, 1.0 + 0.01 * np.sin(20 * t))
    off = np.where(state > 0, 0.2 * np.sin(3 * t), 0.0)
    data = np.column_stack([t, t // 0.5, np.full(n, 31.0), 31.0 + off, 31.0 + off, state, off, filtered,
                            filtered - 1.0, 100 * t, np.full(n, 30.0), 1.0 + off])
    return Trace(COLS, data, units=UNITS, meta={"program": "sheet.nc"})


def test_filtered_is_not_drawn_while_inactive():
    """new-user audit R14: while INACTIVE the filter runs on the surface position (30 mm), once active on
    the distance (1 mm); drawing the INACTIVE cycles squashed the panel's scale to 30 mm."""
    fig = _sheet_like_trace().plot()
    (line,) = [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_label() == "Z.dc.filtered"]
    y = np.asarray(line.get_ydata(), dtype=float)
    assert np.nanmax(y) < 2.0 and np.isnan(y[:2]).all()


def test_state_names_do_not_overlap():
    """INACTIVE / ACTIVE_CONST_DIST 2 ms apart at the start, TURNING_OFF / INACTIVE at the end of 5 s: the
    names above the top panel must not be printed on top of each other."""
    fig = _sheet_like_trace().plot()
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    texts = [t for t in fig.axes[0].texts if t.get_text() in HLI_STATE_NAMES.values()]
    assert len(texts) >= 3
    boxes = [t.get_window_extent(r) for t in texts]
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            assert not boxes[i].overlaps(boxes[j]), (texts[i].get_text(), texts[j].get_text())
