"""`distctrl plot TRACE.csv` (distctrl.cli.plot, distctrl.trace.plot): output files, signal selection, time
window, error markers and the exit-1 messages."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from distctrl.sim.runner import run
from distctrl.trace import Trace
from distctrl.cli.plot import plot
from distctrl.trace.plot import (
    PlotError,
    add_event_markers,
    closest_column,
    events_from_meta,
    load_events,
    resolve_signals,
    slice_trace,
)

ROOT = Path(__file__).resolve().parents[2]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def trace_csv(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("plot_cli") / "dist_1.csv"
    run(ROOT / "examples" / "scenarios" / "dist_1.toml", trace=out, keep_trace=False)
    return out


def _invoke(*args: str):
    return CliRunner().invoke(plot, [str(a) for a in args], catch_exceptions=False)


def test_default_output_is_a_png_beside_the_trace(trace_csv, tmp_path):
    csv = tmp_path / "t.csv"
    Trace.from_csv(trace_csv).to_csv(csv)
    res = _invoke(csv)
    assert res.exit_code == 0, res.output
    out = tmp_path / "t.png"
    assert out.read_bytes()[:8] == PNG_MAGIC
    assert f"wrote {out}" in res.output


def test_signals_window_and_svg(trace_csv, tmp_path):
    out = tmp_path / "sub" / "zoom.svg"
    res = _invoke(trace_csv, "--signals", "Z.act, Z.dc.offset,true.distance", "--from", "0.5", "--to", "1.0",
                  "-o", out)
    assert res.exit_code == 0, res.output
    text = out.read_text(encoding="utf-8")
    assert text.lstrip().startswith("<?xml") and "<svg" in text


def test_pdf_output(trace_csv, tmp_path):
    res = _invoke(trace_csv, "-o", tmp_path / "p.pdf")
    assert res.exit_code == 0 and (tmp_path / "p.pdf").read_bytes()[:5] == b"%PDF-"


def test_unknown_signal_names_the_closest_column(trace_csv, tmp_path):
    res = _invoke(trace_csv, "--signals", "Z.act,Z.dc.ofset", "-o", tmp_path / "x.png")
    assert res.exit_code == 1
    assert "unknown signal 'Z.dc.ofset'" in res.output and "closest column: Z.dc.offset" in res.output
    assert not (tmp_path / "x.png").exists()


def test_missing_file_exits_1(tmp_path):
    res = _invoke(tmp_path / "nope.csv")
    assert res.exit_code == 1 and "nope.csv: no such trace file" in res.output


def test_bad_window_and_format_exit_1(trace_csv, tmp_path):
    res = _invoke(trace_csv, "--from", "100", "-o", tmp_path / "a.png")
    assert res.exit_code == 1 and "no rows between" in res.output
    res = _invoke(trace_csv, "--from", "2", "--to", "1", "-o", tmp_path / "a.png")
    assert res.exit_code == 1 and "must be after --from" in res.output
    res = _invoke(trace_csv, "-o", tmp_path / "a.jpeg2000")
    assert res.exit_code == 1 and "allowed: .png, .svg, .pdf, .jpg, .jpeg" in res.output


def test_errors_json_is_marked(trace_csv, tmp_path):
    doc = {"completed": False, "errors": [{"id": 70331, "line": 3, "t": 1.2, "message": "too far"}],
           "warnings": [{"id": 70332, "line": 6, "t": 2.5, "message": "still active"}]}
    (tmp_path / "run.json").write_text(json.dumps(doc))
    res = _invoke(trace_csv, "--errors", tmp_path / "run.json", "-o", tmp_path / "m.png")
    assert res.exit_code == 0, res.output
    res = _invoke(trace_csv, "--errors", tmp_path / "missing.json", "-o", tmp_path / "m.png")
    assert res.exit_code == 1 and "missing.json: no such file" in res.output


def test_event_markers_on_every_panel(trace_csv):
    from distctrl.trace.plot import plot_trace

    trace = Trace.from_csv(trace_csv)
    events = events_from_meta({"errors": [{"id": 70331, "t": 1.2}], "warnings": [{"id": 70332, "t": 2.5}]})
    assert [e["severity"] for e in events] == ["error", "warning"]
    fig = plot_trace(trace)
    before = [len(ax.lines) for ax in fig.axes]
    assert add_event_markers(fig, events, 0.0, 2.0) == 1          # the warning is outside the window
    for ax, n in zip(fig.axes, before):
        assert len(ax.lines) == n + 1
        line = ax.lines[-1]
        assert list(line.get_xdata()) == [1.2, 1.2] and line.get_color() == "tab:red"
    assert any(t.get_text().strip() == "70331" for t in fig.axes[0].texts)


def test_events_from_the_sidecar_meta(trace_csv, tmp_path):
    trace = Trace.from_csv(trace_csv)
    errs = [{"id": 70335, "line": 1, "t": 0.0, "message": "no SET_POS"}]
    meta = dict(trace.meta, errors=errs)
    Trace(trace.columns, trace.data[:100], trace.units, meta).to_csv(tmp_path / "e.csv")
    loaded = Trace.from_csv(tmp_path / "e.csv")
    assert load_events(loaded) == [dict(errs[0], severity="error")]
    assert load_events(trace) == []
    res = _invoke(tmp_path / "e.csv")
    assert res.exit_code == 0, res.output
    with pytest.raises(PlotError, match="needs at least 'id' and 't'"):
        events_from_meta({"errors": [{"id": 1}]})


def test_helpers(trace_csv):
    trace = Trace.from_csv(trace_csv)
    assert closest_column("z.act", trace.columns) == "Z.act"
    assert closest_column("qqqqqqqq", trace.columns) is None
    assert resolve_signals(trace, ["Z.act", " true.distance", "Z.act"]) == ["Z.act", "true.distance"]
    part = slice_trace(trace, 0.5, 1.0)
    assert part.t[0] >= 0.5 and part.t[-1] <= 1.0 and part.rows == np.sum((trace.t >= 0.5) & (trace.t <= 1.0))
    assert part.units == trace.units and part.columns == trace.columns
    assert slice_trace(trace) is trace
