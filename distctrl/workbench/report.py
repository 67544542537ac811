"""An HTML report of a run: one self-contained page (``out_dir/index.html``).

:func:`write_report` documents a :class:`~distctrl.sim.runner.RunResult` with its scenario: the
scenario (name, cycle time, NC program, axes, surface, sensor, events), the axis parameter lists in
the kernel format (the values that differ from the defaults; the full list folded away), the result,
the metrics with units, the error/warning timeline (a table and a plot), the scope plot of the run
and a zoom around the largest distance error. :func:`report_from_trace` makes a smaller report from
a saved trace CSV (and its sidecar).

The page loads nothing: plots are PNG images embedded as ``data:`` URIs, the CSS is inline, there are
no fonts or external scripts, and a Content-Security-Policy allows nothing but inline styles, inline
script and ``data:`` images. A few lines of inline script mark each ``<img>`` with
``data-loaded="1"`` once it has decoded (used by the headless-browser test). All text is escaped.
The markup is jinja2 templates shipped with the package (``distctrl/workbench/templates/``, rendered
by :mod:`distctrl.workbench.pages`). See docs/workbench-report.md.
"""
from __future__ import annotations

import base64
import dataclasses
import datetime as _dt
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.states import HLI_STATE_NAMES
from ..params.channel import CHANNEL_LIST
from ..params.listfile import format_list
from ..sim.scenario import Scenario, load_scenario
from ..sim.signals import PLOT_3D
from ..trace import Trace
from ..trace.plot import (add_event_markers, distance_error, events_from_meta, figure_bytes, plot_trace,
                          slice_trace)
from .pages import fmt, render

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..sim.runner import RunResult
    from ..sim.scenario import Scenario

__all__ = ["write_report", "report_from_trace", "METRIC_UNITS", "REPORT_FILE"]

REPORT_FILE = "index.html"
#: units of the runner's metrics (others: guessed from the name's suffix)
METRIC_UNITS = {
    "distance_error_rms": "mm", "distance_error_max": "mm", "settle_time": "s", "tracking_cycles": "cycles",
    "settle_band_mm": "mm", "settle_hold_s": "s", "oscillation_frequency_hz": "Hz",
    "excluded_off_sheet_cycles": "cycles", "excluded_process_cycles": "cycles",
    "oscillation_amplitude_mm": "mm", "min_distance_mm": "mm", "time_below_zero_s": "s", "collisions": "",
}
METRIC_TEXT = {
    "distance_error_rms": "RMS of the distance error while distance control tracks over the sheet (not counted: "
                          "the excluded_* cycles; the run's notes say what and against what)",
    "distance_error_max": "largest |distance error| while distance control tracks over the sheet",
    "settle_time": "from the first tracking cycle to the last entry into the settle band (null: never settled)",
    "oscillation_frequency_hz": "oscillation of the distance error in the last second of tracking (null: none)",
    "oscillation_amplitude_mm": "half the peak-to-peak distance error in the last second of tracking",
    "min_distance_mm": "smallest true distance of the tool to the surface (negative: in the surface)",
    "time_below_zero_s": "time with the true distance at or below 0 mm",
    "collisions": "contacts beyond the collision depth (warning 900030 each)",
    "tracking_cycles": "cycles with distance control ACTIVE or ACTIVE_CONST_DIST",
    "settle_band_mm": "settle band (± this error)",
    "settle_hold_s": "time the error must stay in the band",
    "excluded_off_sheet_cycles": "active cycles off the sheet (a hole, past the edge: the surface beyond the "
                                 "sensor's reach), not in the distance error",
    "excluded_process_cycles": "active cycles in which a process function had the axis (touch-off, collision "
                               "retract, auto_set_value sampling), not in the distance error",
}
_PNG_DPI = 100
#: the zoom shows this fraction of the run around the largest error (clamped below)
_ZOOM_FRACTION = 0.05
_ZOOM_MIN_S, _ZOOM_MAX_S = 0.05, 0.5

# ------------------------------------------------------------------------------------------------------
# small helpers. The markup is in templates/ (distctrl.workbench.pages): report_page.html.j2 (the
# frame: CSP, report.css, nav, report.js), run_report.html.j2, trace_report.html.j2,
# report_sections.html.j2 (metrics, errors and warnings, plots), macros.html.j2 (table, figure, note).
# This module prepares the values (rows, texts, PNGs in base64); the templates escape all text.
# ------------------------------------------------------------------------------------------------------
def _b64(png: bytes) -> str:
    return base64.b64encode(png).decode("ascii")


def _now(now: _dt.datetime | None) -> str:
    return (now or _dt.datetime.now().astimezone()).isoformat(timespec="seconds")


# ------------------------------------------------------------------------------------------------------
# plots
# ------------------------------------------------------------------------------------------------------
def _png(fig: "Figure") -> bytes:
    return figure_bytes(fig, "png", _PNG_DPI)


def _scope_signals(trace: "Trace") -> list[str] | None:
    if "dc3d.offset" in trace:
        return [s for s in PLOT_3D if s in trace]
    return None


def _scope_png(trace: "Trace", title: str, events: list[dict]) -> bytes:
    fig = plot_trace(trace, signals=_scope_signals(trace), title=title)
    if trace.rows:
        add_event_markers(fig, events, float(trace.t[0]), float(trace.t[-1]))
    return _png(fig)


def _largest_error(trace: "Trace") -> tuple[int, float, str | None] | None:
    """(row, error, axis) of the largest |distance error|, or None when distance control never tracked."""
    err, axis = distance_error(trace)
    if err.size == 0 or not np.any(np.isfinite(err)):
        return None
    i = int(np.nanargmax(np.abs(err)))
    return i, float(err[i]), axis


def _zoom_png(trace: "Trace", title: str, events: list[dict]) -> tuple[bytes, str] | None:
    found = _largest_error(trace)
    if found is None:
        return None
    i, e_max, axis = found
    t = trace.t
    t_star = float(t[i])
    span = float(t[-1] - t[0]) if trace.rows > 1 else 0.0
    dt = float(np.median(np.diff(t))) if trace.rows > 1 else 0.001
    half = min(max(_ZOOM_FRACTION * span, _ZOOM_MIN_S, 20 * dt), _ZOOM_MAX_S)
    lo, hi = t_star - half, t_star + half          # kept inside the trace: shifted, not cut
    if lo < t[0]:
        lo, hi = float(t[0]), min(float(t[0]) + 2 * half, float(t[-1]))
    elif hi > t[-1]:
        lo, hi = max(float(t[-1]) - 2 * half, float(t[0])), float(t[-1])
    part = slice_trace(trace, lo, hi)
    err_part, _ = distance_error(part)
    sigs = _scope_signals(part)
    if sigs is not None and "true.distance_orth" in part:
        sigs.append("true.distance_orth")
    fig = plot_trace(part, signals=sigs, title=f"{title}: around the largest distance error")
    last = _mm_panel(fig)
    few = int(np.sum(np.isfinite(err_part))) < 50       # a handful of tracking cycles: show the points
    last.plot(part.t, err_part, color="black", linewidth=1.2, label="distance error",
              marker="." if few else None)
    last.legend(loc="upper right", fontsize="small")
    for ax in _panels(fig):
        ax.axvline(t_star, color="purple", linewidth=1.0, linestyle="-.")
    last.annotate(f"max |error| {abs(e_max):.4g} mm at t = {t_star:.4g} s", xy=(t_star, e_max),
                  xytext=(10, -16 if e_max >= 0 else 12), textcoords="offset points", fontsize="small",
                  color="purple", arrowprops={"arrowstyle": "->", "color": "purple"})
    add_event_markers(fig, events, float(part.t[0]), float(part.t[-1]))
    where = f"axis {axis}" if axis and axis != "3D" else "3D distance control"
    cap = (f"Zoom to t = {lo:.4g} … {hi:.4g} s around the largest distance error "
           f"({e_max:+.4g} mm at t = {t_star:.4g} s, {where}); black: distance error = true distance − "
           "wanted distance (docs/run.md).")
    return _png(fig), cap


def _panels(fig: "Figure") -> list:
    return [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]


def _mm_panel(fig: "Figure"):
    """The last panel drawn in mm (where the distance error goes), else the last panel."""
    panels = _panels(fig)
    for ax in reversed(panels):
        if ax.get_ylabel().endswith("[mm]"):
            return ax
    return panels[-1]


def _timeline_png(trace: "Trace | None", events: list[dict], t_end: float) -> bytes:
    """The dc state over time as a step line, errors (red) and warnings (orange) as marked lines."""
    # matplotlib (about a second of import): only when a plot is drawn
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11.0, 2.6), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    state_col = None
    if trace is not None:
        state_col = next((c for c in trace.columns if c.endswith(".dc.state") or c == "dc3d.state"), None)
    used: list[int] = []
    if state_col is not None and trace is not None and trace.rows:
        st = trace[state_col]
        ax.step(trace.t, st, where="post", color="0.35", linewidth=1.2, label=state_col)
        used = sorted({int(v) for v in np.unique(st[np.isfinite(st)])})
    if used:
        ax.set_yticks(used, [HLI_STATE_NAMES.get(v, str(v)) for v in used], fontsize="small")
        lo, hi = min(used), max(used)
        ax.set_ylim(lo - 0.8, hi + 1.2)
    else:
        ax.set_yticks([])
        ax.set_ylim(0, 1)
    t0 = float(trace.t[0]) if trace is not None and trace.rows else 0.0
    t1 = max(t_end, t0 + 1e-3)
    ax.set_xlim(t0 - 0.02 * (t1 - t0), t1 + 0.02 * (t1 - t0))
    done = set()
    for ev in events:
        sev = ev.get("severity", "error")
        color = "tab:red" if sev == "error" else "darkorange"
        marker = "v" if sev == "error" else "^"
        label = sev if sev not in done else None
        done.add(sev)
        ax.axvline(ev["t"], color=color, linestyle="-" if sev == "error" else "--", linewidth=1.2)
        ax.plot([ev["t"]], [0.9], marker=marker, color=color, markersize=10, linestyle="none", label=label,
                transform=ax.get_xaxis_transform())
        ax.annotate(str(ev["id"]), xy=(ev["t"], 0.98), xycoords=("data", "axes fraction"), xytext=(8, 0),
                    textcoords="offset points", ha="left", va="top", color=color, fontweight="bold",
                    fontsize="small")
    if not events:
        ax.text(0.5, 0.5, "no errors or warnings", transform=ax.transAxes, ha="center", va="center",
                color="tab:green", fontsize="large")
    ax.set_xlabel("t [s]")
    ax.set_title("errors (red ▼), warnings (orange ▲) and the distance-control state", fontsize="medium")
    ax.grid(True, axis="x", alpha=0.4)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="lower right", fontsize="small")
    return _png(fig)


# ------------------------------------------------------------------------------------------------------
# sections
# ------------------------------------------------------------------------------------------------------
def _metric_unit(key: str) -> str:
    if key in METRIC_UNITS:
        return METRIC_UNITS[key]
    for suffix, unit in (("_mm", "mm"), ("_s", "s"), ("_time", "s"), ("_cycles", "cycles"), ("_deg", "deg")):
        if key.endswith(suffix):
            return unit
    return "–"


#: the meanings of the metrics a trace report recomputes: every tracking cycle of the trace counts (the
#: trace does not say which cycles a process function had or where the sheet was out of the sensor's reach)
TRACE_METRIC_TEXT = {
    **METRIC_TEXT,
    "distance_error_rms": "RMS of the distance error over every tracking cycle of the trace (distctrl run's "
                          "own figure leaves out the cycles off the sheet and those a process function had)",
    "distance_error_max": "largest |distance error| over every tracking cycle of the trace",
}


def _metrics_rows(metrics: dict, texts: dict = METRIC_TEXT) -> list[tuple]:
    return [(k, v, _metric_unit(k), texts.get(k, "")) for k, v in metrics.items()]


def _events_view(events: list[dict], timeline_png: bytes | None) -> dict:
    return {"rows": [(f"{ev['t']:.4f}", ev["id"], ev.get("line"), ev.get("message", ""),
                      ev.get("severity", "error")) for ev in events],
            "row_classes": [f"sev-{ev.get('severity', 'error')}" for ev in events],
            "timeline": None if timeline_png is None else _b64(timeline_png)}


def _value_text(v: Any) -> str:
    if isinstance(v, dict):
        return ", ".join(f"{k} = {_value_text(x)}" for k, x in v.items())
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value_text(x) for x in v) + "]"
    return fmt(v)


def _surface_view(cfg: dict) -> dict | None:
    """None without a [surface] table; else its scalar keys and its features as a table."""
    if not cfg:
        return None
    scalars = [(k, _value_text(v)) for k, v in cfg.items() if k != "features"]
    feats = cfg.get("features") or []
    keys: list[str] = []
    rows: list[list] = []
    if feats:
        for f in feats:
            for k in (f if isinstance(f, dict) else {}):
                if k not in keys and k != "type":
                    keys.append(k)
        rows = [[i, f.get("type", "?")] + [_value_text(f[k]) if k in f else "" for k in keys]
                for i, f in enumerate(feats) if isinstance(f, dict)]
    # an empty list of features (or one with no tables) shows the table's header only, as before
    return {"scalars": scalars, "feature_headers": ["#", "type"] + keys,
            "feature_rows": rows if feats else None}


def _sensor_view(sensor: Any) -> dict | None:
    """None without a [sensor] table; else its (key, value) pairs and its faults (one row each)."""
    if sensor is None:
        return None
    pairs = []
    faults = ()
    for f in dataclasses.fields(sensor):
        v = getattr(sensor, f.name)
        if f.name == "faults":
            faults = v
            continue
        pairs.append((f.name, _value_text(v)))
    rows = []
    for flt in faults or ():
        d = dataclasses.asdict(flt) if dataclasses.is_dataclass(flt) else {"fault": str(flt)}
        rows.append((_value_text(d),))
    return {"pairs": pairs, "faults": rows}


def _events_cfg_rows(events: list) -> list[tuple]:
    return [(f"{ev.t:g}", ev.kind, _value_text(ev.data), ev.index) for ev in events]


_AXIS_FIELDS = ("start", "kv", "v_max", "a_max", "v_rapid", "a_rapid", "bus_delay_cycles", "resolution",
                "feedforward")
_AXIS_UNITS = {"start": "mm", "kv": "1/s", "v_max": "mm/s", "a_max": "mm/s²", "v_rapid": "mm/s",
               "a_rapid": "mm/s²", "bus_delay_cycles": "cycles", "resolution": "mm", "feedforward": "–"}


def _axes_view(axes: dict) -> dict:
    headers = (["axis", "distance control", "parameter list"]
               + [f"{f} [{_AXIS_UNITS[f]}]" for f in _AXIS_FIELDS])
    rows = []
    for name, ax in axes.items():
        enabled = getattr(ax.params, "enabled", None)
        listed = ax.params_file.name if ax.params_file else "(defaults)"
        rows.append([name, "enabled" if enabled else "off", listed]
                    + [getattr(ax, f, None) for f in _AXIS_FIELDS])
    return {"headers": headers, "rows": rows, "numeric": range(3, 3 + len(_AXIS_FIELDS))}


def _parameters_view(scenario: "Scenario") -> dict:
    """Per axis (and the channel) the list in the kernel format: the changed values and the full list."""
    axes = []
    for name, ax in scenario.axes.items():
        source = f" ({ax.params_file})" if ax.params_file else " (no list: defaults)"
        axes.append({"name": name, "source": source,
                     "changed": format_list(ax.params, only_changed=True), "full": format_list(ax.params),
                     "warnings": list(getattr(ax, "params_warnings", ()) or ())})
    channel = None
    ch = getattr(scenario, "channel_params", None)
    if ch is not None:
        channel = {"source": f" ({scenario.channel_params_file})" if scenario.channel_params_file else "",
                   "changed": format_list(ch, only_changed=True, fmt=CHANNEL_LIST),
                   "full": format_list(ch, fmt=CHANNEL_LIST)}
    return {"axes": axes, "channel": channel}


def _scenario_view(scenario: "Scenario", hit_lines: set[int]) -> dict:
    src = scenario.program_file or (f"{scenario.path}: program_text" if scenario.path else "program_text")
    general = [("name", scenario.name), ("file", scenario.path or "(not from a file)"),
               ("cycle time", f"{scenario.cycle_time * 1000:g} ms"),
               ("duration", f"{scenario.duration:g} s" if scenario.duration is not None
                else "until the program ends"),
               ("settle time", f"{scenario.settle_time:g} s"), ("seed", scenario.seed),
               ("tool length", f"{scenario.tool_length:g} mm")]
    if getattr(scenario, "kinematics", None):
        general.append(("kinematics", scenario.kinematics))
    if scenario.variables:
        general.append(("V.E. variables", _value_text(scenario.variables)))
    return {"general": general, "program_source": src, "program_lines": scenario.program_text.splitlines(),
            "hit_lines": hit_lines, "axes": _axes_view(scenario.axes),
            "surface": _surface_view(scenario.surface_config), "sensor": _sensor_view(scenario.sensor),
            "events": _events_cfg_rows(scenario.events)}


def _result_view(result: "RunResult") -> dict:
    duration = result.cycles * result.cycle_time
    pairs = [("final state", result.final_state), ("cycles", result.cycles),
             ("duration", f"{duration:.4g} s"), ("cycle time", f"{result.cycle_time * 1000:g} ms"),
             ("errors", len(result.errors)), ("warnings", len(result.warnings)),
             ("exit code of distctrl run", result.exit_code)]
    if result.trace_path:
        pairs.append(("trace file", result.trace_path))
    metrics = result.metrics or {}
    return {"run": result, "pairs": pairs, "collisions": metrics.get("collisions") or 0,
            "oscillating": metrics.get("oscillation_frequency_hz") is not None}


def _plots_view(trace: "Trace | None", title: str, events: list[dict], why_none: str = "") -> dict:
    if trace is None or trace.rows == 0:
        return {"why": why_none or "No trace rows: nothing to plot."}
    scope = _b64(_scope_png(trace, title, events))
    zoom = _zoom_png(trace, title, events)
    return {"scope": scope, "zoom": None if zoom is None else (_b64(zoom[0]), zoom[1])}


def _events_of(result: "RunResult") -> list[dict]:
    events = [dict(e, severity="error") for e in result.errors] + \
             [dict(w, severity="warning") for w in result.warnings]
    events.sort(key=lambda e: (e.get("t") or 0.0))
    return events


def _trace_of(result: "RunResult") -> tuple["Trace | None", str]:
    if result.trace is not None:
        return result.trace, ""
    if result.trace_path and Path(result.trace_path).is_file():
        return Trace.from_csv(result.trace_path), ""
    return None, "The trace was not kept (keep_trace=False) and no trace file exists: no plots."


# ------------------------------------------------------------------------------------------------------
# entry points
# ------------------------------------------------------------------------------------------------------
def write_report(result: "RunResult", scenario: "Scenario | str | os.PathLike", out_dir: str | os.PathLike,
                 *, title: str | None = None, now: _dt.datetime | None = None) -> Path:
    """Write ``out_dir/index.html``, a self-contained report of ``result`` and its ``scenario``.

    ``scenario`` is the :class:`~distctrl.sim.scenario.Scenario` that was run (or the path of its
    TOML file). Returns the path of the page. ``now`` fixes the date shown (default: now).
    """

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    events = _events_of(result)
    trace, why = _trace_of(result)
    heading = title or f"Run report: {result.name}"
    duration = result.cycles * result.cycle_time
    status = "completed" if result.completed else ("interrupted" if result.interrupted else "aborted")
    subtitle = f"generated {_now(now)} by distctrl · scenario {scenario.name} · {status}"
    hit_lines = {int(e["line"]) for e in events if isinstance(e.get("line"), int)}
    nav = [("scenario", "Scenario"), ("parameters", "Parameters"), ("result", "Result"),
           ("metrics", "Metrics"), ("events", "Errors & warnings"), ("plots", "Plots")]
    text = render("run_report.html.j2", title=heading, subtitle=subtitle, nav=nav,
                  scenario=_scenario_view(scenario, hit_lines), parameters=_parameters_view(scenario),
                  result=_result_view(result), metrics=_metrics_rows(result.metrics),
                  events=_events_view(events, _timeline_png(trace, events, duration)),
                  plots=_plots_view(trace, result.name, events, why))
    page = out / REPORT_FILE
    page.write_text(text, encoding="utf-8")
    return page


def _trace_metrics(trace: "Trace") -> dict:
    err, _ = distance_error(trace)
    finite = err[np.isfinite(err)]
    return {"distance_error_rms": float(np.sqrt(np.mean(finite ** 2))) if finite.size else None,
            "distance_error_max": float(np.max(np.abs(finite))) if finite.size else None,
            "tracking_cycles": int(finite.size)}


def _columns_rows(trace: "Trace") -> list[tuple]:
    rows = []
    for c in trace.columns:
        col = trace[c]
        fin = col[np.isfinite(col)]
        rows.append((c, trace.unit(c) or "–", float(fin.min()) if fin.size else None,
                     float(fin.max()) if fin.size else None))
    return rows


def report_from_trace(trace_csv: str | os.PathLike, out_dir: str | os.PathLike, *,
                      errors: Any = None, title: str | None = None, now: _dt.datetime | None = None) -> Path:
    """Write ``out_dir/index.html``: a smaller report of a saved trace CSV (and its sidecar).

    Shows the trace's meta, its columns with units and ranges, distance-error metrics recomputed from
    the trace, the errors/warnings (``errors``: a ``distctrl run --json`` object or list; default:
    the sidecar meta's ``errors``/``warnings`` if any), the timeline, the scope plot and the zoom.
    """
    src = Path(trace_csv)
    trace = Trace.from_csv(src)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    events = events_from_meta(errors if errors is not None
                              else {k: trace.meta.get(k) for k in ("errors", "warnings")}, str(src))
    name = str(trace.meta.get("title") or trace.meta.get("scenario") or trace.meta.get("program") or src.name)
    heading = title or f"Trace report: {name}"
    t = trace.t
    span = float(t[-1] - t[0]) if trace.rows > 1 else 0.0
    info = [("file", src), ("rows", trace.rows), ("columns", len(trace.columns)),
            ("time span", f"{float(t[0]):.6g} … {float(t[-1]):.6g} s ({span:.6g} s)"
             if trace.rows else "–")]
    info += [(f"meta: {k}", _value_text(v)) for k, v in trace.meta.items() if k not in ("errors", "warnings")]
    nav = [("trace", "Trace"), ("metrics", "Metrics"), ("events", "Errors & warnings"), ("plots", "Plots"),
           ("columns", "Columns")]
    subtitle = f"generated {_now(now)} by distctrl from {src.name}"
    t_end = float(t[-1]) if trace.rows else 0.0
    text = render("trace_report.html.j2", title=heading, subtitle=subtitle, nav=nav, info=info,
                  metrics=_metrics_rows(_trace_metrics(trace), TRACE_METRIC_TEXT),
                  metrics_note="Recomputed from the trace (true distance − wanted distance while distance "
                               "control tracks).",
                  events=_events_view(events, _timeline_png(trace, events, t_end)),
                  plots=_plots_view(trace, name, events), columns=_columns_rows(trace))
    page = out / REPORT_FILE
    page.write_text(text, encoding="utf-8")
    return page
