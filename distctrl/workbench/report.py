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
See docs/workbench-report.md.
"""
from __future__ import annotations

import base64
import dataclasses
import datetime as _dt
import html
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable

import numpy as np

from ..trace.recorder import HLI_STATE_NAMES
from .plot_cli import add_event_markers, distance_error, events_from_meta, figure_bytes, slice_trace

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..sim.runner import RunResult
    from ..sim.scenario import Scenario
    from ..trace import Trace

__all__ = ["write_report", "report_from_trace", "METRIC_UNITS", "REPORT_FILE"]

REPORT_FILE = "index.html"
#: units of the runner's metrics (others: guessed from the name's suffix)
METRIC_UNITS = {
    "distance_error_rms": "mm", "distance_error_max": "mm", "settle_time": "s", "tracking_cycles": "cycles",
    "settle_band_mm": "mm", "settle_hold_s": "s", "oscillation_frequency_hz": "Hz",
    "oscillation_amplitude_mm": "mm", "min_distance_mm": "mm", "time_below_zero_s": "s", "collisions": "",
}
METRIC_TEXT = {
    "distance_error_rms": "RMS of the distance error while distance control tracks",
    "distance_error_max": "largest |distance error| while distance control tracks",
    "settle_time": "from the first tracking cycle to the last entry into the settle band (null: never settled)",
    "oscillation_frequency_hz": "oscillation of the distance error in the last second of tracking (null: none)",
    "oscillation_amplitude_mm": "half the peak-to-peak distance error in the last second of tracking",
    "min_distance_mm": "smallest true distance of the tool to the surface (negative: in the surface)",
    "time_below_zero_s": "time with the true distance at or below 0 mm",
    "collisions": "contacts beyond the collision depth (warning 900030 each)",
    "tracking_cycles": "cycles with distance control ACTIVE or ACTIVE_CONST_DIST",
    "settle_band_mm": "settle band (± this error)",
    "settle_hold_s": "time the error must stay in the band",
}
_PNG_DPI = 100
#: the zoom shows this fraction of the run around the largest error (clamped below)
_ZOOM_FRACTION = 0.05
_ZOOM_MIN_S, _ZOOM_MAX_S = 0.05, 0.5
_PLOT_3D = ("dc3d.offset", "dc3d.delta", "dc3d.comp_x", "dc3d.comp_y", "dc3d.comp_z", "dc3d.inclination")

_CSS = """
:root { --fg:#1d232a; --muted:#5b6770; --line:#d5dbe0; --bg:#ffffff; --band:#f4f6f8;
        --ok:#1a7f37; --bad:#c62828; --warn:#b26a00; }
* { box-sizing: border-box; }
body { margin: 0; padding: 0 2rem 3rem; color: var(--fg); background: var(--bg);
       font: 15px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif; }
header { padding: 1.2rem 0 .6rem; border-bottom: 2px solid var(--line); margin-bottom: 1rem; }
h1 { font-size: 1.6rem; margin: 0 0 .2rem; }
h2 { font-size: 1.25rem; margin: 2rem 0 .6rem; padding-bottom: .2rem; border-bottom: 1px solid var(--line); }
h3 { font-size: 1.05rem; margin: 1.2rem 0 .4rem; }
.sub { color: var(--muted); margin: 0; }
nav { font-size: .92rem; margin: .5rem 0 0; }
nav a { margin-right: 1rem; color: #0b5cad; text-decoration: none; }
table { border-collapse: collapse; margin: .3rem 0 .8rem; font-size: .92rem; }
th, td { border: 1px solid var(--line); padding: .25rem .55rem; text-align: left; vertical-align: top; }
th { background: var(--band); font-weight: 600; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tr.sev-error td { background: #fdecea; }
tr.sev-warning td { background: #fff4e0; }
pre { background: var(--band); border: 1px solid var(--line); padding: .6rem .8rem; overflow-x: auto;
      font: 13px/1.4 ui-monospace, "DejaVu Sans Mono", Menlo, Consolas, monospace; margin: .3rem 0 .8rem; }
pre.program span.ln { color: var(--muted); user-select: none; display: inline-block; width: 3.2em; }
pre.program span.hit { background: #fdd; display: inline-block; width: 100%; }
details { margin: .2rem 0 .8rem; }
summary { cursor: pointer; color: #0b5cad; }
.badge { display: inline-block; padding: .15rem .6rem; border-radius: 1rem; font-weight: 600; color: #fff; }
.badge.ok { background: var(--ok); }
.badge.bad { background: var(--bad); }
.badge.warn { background: var(--warn); }
figure { margin: .4rem 0 1.2rem; }
figure img { max-width: 100%; height: auto; border: 1px solid var(--line); }
figcaption { color: var(--muted); font-size: .9rem; margin-top: .2rem; }
.note { color: var(--muted); font-style: italic; }
.cols { display: flex; flex-wrap: wrap; gap: 0 2.5rem; }
"""

# marks every image once it has decoded: data-loaded="1" and its natural size (headless-browser test)
_SCRIPT = """
(function () {
  function mark() {
    var imgs = document.querySelectorAll("img");
    var ok = 0;
    for (var i = 0; i < imgs.length; i++) {
      var im = imgs[i];
      var good = im.complete && im.naturalWidth > 0;
      im.setAttribute("data-loaded", good ? "1" : "0");
      im.setAttribute("data-natural-width", String(im.naturalWidth));
      if (good) { ok++; }
    }
    document.body.setAttribute("data-images-loaded", ok + "/" + imgs.length);
  }
  if (document.readyState === "complete") { mark(); } else { window.addEventListener("load", mark); }
})();
"""

_CSP = ("default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'; "
        "base-uri 'none'; form-action 'none'")


# ------------------------------------------------------------------------------------------------------
# small HTML helpers
# ------------------------------------------------------------------------------------------------------
def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _fmt(value: Any, digits: int = 6) -> str:
    """A value as text: floats with ``digits`` significant digits, None as an en dash."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if math.isnan(v):
            return "NaN"
        return f"{v:.{digits}g}"
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return str(value)


def _table(headers: Iterable[str], rows: Iterable[Iterable[Any]], cls: str = "",
           row_classes: Iterable[str] | None = None, numeric: Iterable[int] = ()) -> str:
    num = set(numeric)
    head = "".join(f"<th>{_e(h)}</th>" for h in headers)
    body = []
    rcls = list(row_classes) if row_classes is not None else None
    for i, row in enumerate(rows):
        tds = "".join(f'<td class="num">{_e(_fmt(c))}</td>' if j in num else f"<td>{_e(_fmt(c))}</td>"
                      for j, c in enumerate(row))
        rc = f' class="{_e(rcls[i])}"' if rcls and rcls[i] else ""
        body.append(f"<tr{rc}>{tds}</tr>")
    c = f' class="{_e(cls)}"' if cls else ""
    return f"<table{c}><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _img(png: bytes, alt: str, caption: str, ident: str) -> str:
    b64 = base64.b64encode(png).decode("ascii")
    return (f'<figure id="{_e(ident)}"><img src="data:image/png;base64,{b64}" alt="{_e(alt)}">'
            f"<figcaption>{_e(caption)}</figcaption></figure>")


def _kv_table(pairs: Iterable[tuple[str, Any]]) -> str:
    return _table(("key", "value"), [(k, v) for k, v in pairs])


def _page(title: str, subtitle: str, nav: list[tuple[str, str]], body: list[str]) -> str:
    links = "".join(f'<a href="#{_e(a)}">{_e(t)}</a>' for a, t in nav)
    return (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        f'<meta http-equiv="Content-Security-Policy" content="{_e(_CSP)}">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        '<meta name="generator" content="distctrl.workbench.report">\n'
        f"<title>{_e(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
        f"<header><h1>{_e(title)}</h1><p class=\"sub\">{_e(subtitle)}</p><nav>{links}</nav></header>\n"
        + "\n".join(body)
        + f"\n<script>{_SCRIPT}</script>\n</body>\n</html>\n"
    )


def _now(now: _dt.datetime | None) -> str:
    return (now or _dt.datetime.now().astimezone()).isoformat(timespec="seconds")


# ------------------------------------------------------------------------------------------------------
# plots
# ------------------------------------------------------------------------------------------------------
def _png(fig: "Figure") -> bytes:
    return figure_bytes(fig, "png", _PNG_DPI)


def _scope_signals(trace: "Trace") -> list[str] | None:
    if "dc3d.offset" in trace:
        return [s for s in _PLOT_3D if s in trace]
    return None


def _scope_png(trace: "Trace", title: str, events: list[dict]) -> bytes:
    from ..trace.plot import plot_trace

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
    from ..trace.plot import plot_trace

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


def _metrics_section(metrics: dict, extra_note: str = "") -> str:
    rows = [(k, v, _metric_unit(k), METRIC_TEXT.get(k, "")) for k, v in metrics.items()]
    note = f'<p class="note">{_e(extra_note)}</p>' if extra_note else ""
    return ('<section id="metrics"><h2>Metrics</h2>'
            + _table(("metric", "value", "unit", "meaning"), rows, cls="metrics", numeric=(1,))
            + '<p class="note">– : not reached or not measured (e.g. distance control never tracked).</p>'
            + note + "</section>")


def _events_section(events: list[dict], timeline_png: bytes | None) -> str:
    parts = ['<section id="events"><h2>Errors and warnings</h2>']
    if events:
        rows = [(f"{ev['t']:.4f}", ev["id"], ev.get("line"), ev.get("message", ""),
                 ev.get("severity", "error")) for ev in events]
        parts.append(_table(("t [s]", "ID", "line", "message", "severity"), rows, cls="events",
                            row_classes=[f"sev-{ev.get('severity', 'error')}" for ev in events],
                            numeric=(0, 1, 2)))
    else:
        parts.append('<p class="none">No errors or warnings.</p>')
    if timeline_png is not None:
        parts.append(_img(timeline_png, "error and warning timeline",
                          "Timeline: the distance-control state (step line) with errors (red, solid) and "
                          "warnings (orange, dashed) at their times, labelled with their IDs.", "timeline"))
    parts.append("</section>")
    return "".join(parts)


def _program_html(text: str, hit_lines: set[int]) -> str:
    out = []
    for n, line in enumerate(text.splitlines(), start=1):
        body = f'<span class="ln">{n}</span>{_e(line)}'
        out.append(f'<span class="hit" id="line-{n}">{body}</span>' if n in hit_lines
                   else f'<span id="line-{n}">{body}</span>')
    return '<pre class="program">' + "\n".join(out) + "</pre>"


def _value_text(v: Any) -> str:
    if isinstance(v, dict):
        return ", ".join(f"{k} = {_value_text(x)}" for k, x in v.items())
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value_text(x) for x in v) + "]"
    return _fmt(v)


def _surface_html(cfg: dict) -> str:
    if not cfg:
        return '<p class="note">No [surface] table: a flat surface at the default height.</p>'
    scalars = [(k, _value_text(v)) for k, v in cfg.items() if k != "features"]
    parts = [_kv_table(scalars)] if scalars else []
    feats = cfg.get("features") or []
    if feats:
        keys: list[str] = []
        for f in feats:
            for k in (f if isinstance(f, dict) else {}):
                if k not in keys and k != "type":
                    keys.append(k)
        rows = [[i, f.get("type", "?")] + [_value_text(f[k]) if k in f else "" for k in keys]
                for i, f in enumerate(feats) if isinstance(f, dict)]
        parts.append("<h3>Surface features</h3>" + _table(["#", "type"] + keys, rows, cls="features"))
    else:
        parts.append('<p class="note">No surface features: the base height only.</p>')
    return "".join(parts)


def _sensor_html(sensor: Any) -> str:
    if sensor is None:
        return '<p class="note">No [sensor] table.</p>'
    pairs = []
    faults = ()
    for f in dataclasses.fields(sensor):
        v = getattr(sensor, f.name)
        if f.name == "faults":
            faults = v
            continue
        pairs.append((f.name, _value_text(v)))
    parts = [_kv_table(pairs)]
    if faults:
        rows = []
        for flt in faults:
            d = dataclasses.asdict(flt) if dataclasses.is_dataclass(flt) else {"fault": str(flt)}
            rows.append((_value_text(d),))
        parts.append("<h3>Sensor faults</h3>" + _table(("fault",), rows))
    return "".join(parts)


def _events_cfg_html(events: list) -> str:
    if not events:
        return '<p class="note">No timed events.</p>'
    rows = [(f"{ev.t:g}", ev.kind, _value_text(ev.data), ev.index) for ev in events]
    return _table(("t [s]", "action", "data", "# in file"), rows, cls="scenario-events", numeric=(0, 3))


_AXIS_FIELDS = ("start", "kv", "v_max", "a_max", "v_rapid", "a_rapid", "bus_delay_cycles", "resolution",
                "feedforward")
_AXIS_UNITS = {"start": "mm", "kv": "1/s", "v_max": "mm/s", "a_max": "mm/s²", "v_rapid": "mm/s",
               "a_rapid": "mm/s²", "bus_delay_cycles": "cycles", "resolution": "mm", "feedforward": "–"}


def _axes_html(axes: dict) -> str:
    headers = (["axis", "distance control", "parameter list"]
               + [f"{f} [{_AXIS_UNITS[f]}]" for f in _AXIS_FIELDS])
    rows = []
    for name, ax in axes.items():
        enabled = getattr(ax.params, "enabled", None)
        listed = ax.params_file.name if ax.params_file else "(defaults)"
        rows.append([name, "enabled" if enabled else "off", listed]
                    + [getattr(ax, f, None) for f in _AXIS_FIELDS])
    return _table(headers, rows, cls="axes", numeric=range(3, 3 + len(_AXIS_FIELDS)))


def _params_section(scenario: "Scenario") -> str:
    from ..params.listfile import format_list

    parts = ['<section id="parameters"><h2>Parameter lists</h2>',
             '<p class="note">Kernel list format (loadable by <code>distctrl params</code>): the values that '
             "differ from the defaults; the full list below each.</p>"]
    for name, ax in scenario.axes.items():
        changed = format_list(ax.params, only_changed=True)
        src = f" ({ax.params_file})" if ax.params_file else " (no list: defaults)"
        parts.append(f'<h3 id="params-{_e(name)}">Axis {_e(name)}{_e(src)}</h3>')
        if changed.strip():
            parts.append(f'<pre class="params-changed">{_e(changed)}</pre>')
        else:
            parts.append('<p class="note">All values are the defaults.</p>')
        parts.append(f"<details><summary>Full list of axis {_e(name)}</summary>"
                     f'<pre class="params-full">{_e(format_list(ax.params))}</pre></details>')
        for w in getattr(ax, "params_warnings", ()) or ():
            parts.append(f'<p class="note">warning: {_e(w)}</p>')
    ch = getattr(scenario, "channel_params", None)
    if ch is not None:
        from ..params.channel import CHANNEL_LIST

        changed = format_list(ch, only_changed=True, fmt=CHANNEL_LIST)
        src = f" ({scenario.channel_params_file})" if scenario.channel_params_file else ""
        parts.append(f'<h3 id="params-channel">Channel{_e(src)}</h3>')
        parts.append(f'<pre class="params-changed">{_e(changed)}</pre>' if changed.strip()
                     else '<p class="note">All values are the defaults.</p>')
        parts.append("<details><summary>Full channel list</summary>"
                     f'<pre class="params-full">{_e(format_list(ch, fmt=CHANNEL_LIST))}</pre></details>')
    parts.append("</section>")
    return "".join(parts)


def _scenario_section(scenario: "Scenario", hit_lines: set[int]) -> str:
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
    return ('<section id="scenario"><h2>Scenario</h2>' + _kv_table(general)
            + f"<h3>NC program <small>({_e(src)})</small></h3>"
            + _program_html(scenario.program_text, hit_lines)
            + "<h3>Axes</h3>" + _axes_html(scenario.axes)
            + '<div class="cols"><div><h3>Surface</h3>' + _surface_html(scenario.surface_config) + "</div>"
            + "<div><h3>Sensor</h3>" + _sensor_html(scenario.sensor) + "</div></div>"
            + "<h3>Events</h3>" + _events_cfg_html(scenario.events) + "</section>")


def _result_section(result: "RunResult") -> str:
    if result.interrupted:
        badge = '<span class="badge warn">interrupted</span>'
    elif result.completed:
        badge = '<span class="badge ok">completed</span>'
    else:
        badge = '<span class="badge bad">aborted</span>' if result.aborted or result.errors \
            else f'<span class="badge warn">{_e(result.outcome_text)}</span>'
    hits = (result.metrics or {}).get("collisions") or 0
    if hits:
        badge += f' <span class="badge bad">{hits} collision{"s" if hits != 1 else ""}</span>'
    if (result.metrics or {}).get("oscillation_frequency_hz") is not None:
        badge += ' <span class="badge warn">oscillating</span>'
    duration = result.cycles * result.cycle_time
    pairs = [("final state", result.final_state), ("cycles", result.cycles),
             ("duration", f"{duration:.4g} s"), ("cycle time", f"{result.cycle_time * 1000:g} ms"),
             ("errors", len(result.errors)), ("warnings", len(result.warnings)),
             ("exit code of distctrl run", result.exit_code)]
    if result.trace_path:
        pairs.append(("trace file", result.trace_path))
    notes = "".join(f'<p class="note">note: {_e(n)}</p>' for n in (result.notes or []))
    return (f'<section id="result"><h2>Result</h2><p class="status">{badge}</p>' + _kv_table(pairs) + notes
            + "</section>")


def _plots_section(trace: "Trace | None", title: str, events: list[dict], why_none: str = "") -> str:
    parts = ['<section id="plots"><h2>Plots</h2>']
    if trace is None or trace.rows == 0:
        parts.append(f'<p class="note">{_e(why_none or "No trace rows: nothing to plot.")}</p></section>')
        return "".join(parts)
    parts.append(_img(_scope_png(trace, title, events), "scope plot of the run",
                      "Scope plot: positions, distance-control signals and the distance over time; "
                      "shaded: the distance-control state; vertical lines: errors (red) and warnings "
                      "(orange).", "scope"))
    zoom = _zoom_png(trace, title, events)
    if zoom is None:
        parts.append('<p class="note" id="zoom">No zoom: distance control never tracked, so there is no '
                     "distance error.</p>")
    else:
        parts.append(_img(zoom[0], "zoom around the largest distance error", zoom[1], "zoom"))
    parts.append("</section>")
    return "".join(parts)


def _events_of(result: "RunResult") -> list[dict]:
    events = [dict(e, severity="error") for e in result.errors] + \
             [dict(w, severity="warning") for w in result.warnings]
    events.sort(key=lambda e: (e.get("t") or 0.0))
    return events


def _trace_of(result: "RunResult") -> tuple["Trace | None", str]:
    if result.trace is not None:
        return result.trace, ""
    if result.trace_path and Path(result.trace_path).is_file():
        from ..trace import Trace

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
    from ..sim.scenario import Scenario, load_scenario

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
    body = [
        _scenario_section(scenario, hit_lines),
        _params_section(scenario),
        _result_section(result),
        _metrics_section(result.metrics),
        _events_section(events, _timeline_png(trace, events, duration)),
        _plots_section(trace, result.name, events, why),
    ]
    nav = [("scenario", "Scenario"), ("parameters", "Parameters"), ("result", "Result"),
           ("metrics", "Metrics"), ("events", "Errors & warnings"), ("plots", "Plots")]
    page = out / REPORT_FILE
    page.write_text(_page(heading, subtitle, nav, body), encoding="utf-8")
    return page


def _trace_metrics(trace: "Trace") -> dict:
    err, _ = distance_error(trace)
    finite = err[np.isfinite(err)]
    return {"distance_error_rms": float(np.sqrt(np.mean(finite ** 2))) if finite.size else None,
            "distance_error_max": float(np.max(np.abs(finite))) if finite.size else None,
            "tracking_cycles": int(finite.size)}


def _columns_section(trace: "Trace") -> str:
    rows = []
    for c in trace.columns:
        col = trace[c]
        fin = col[np.isfinite(col)]
        rows.append((c, trace.unit(c) or "–", float(fin.min()) if fin.size else None,
                     float(fin.max()) if fin.size else None))
    return ('<section id="columns"><h2>Columns</h2>'
            + _table(("column", "unit", "min", "max"), rows, cls="columns", numeric=(2, 3)) + "</section>")


def report_from_trace(trace_csv: str | os.PathLike, out_dir: str | os.PathLike, *,
                      errors: Any = None, title: str | None = None, now: _dt.datetime | None = None) -> Path:
    """Write ``out_dir/index.html``: a smaller report of a saved trace CSV (and its sidecar).

    Shows the trace's meta, its columns with units and ranges, distance-error metrics recomputed from
    the trace, the errors/warnings (``errors``: a ``distctrl run --json`` object or list; default:
    the sidecar meta's ``errors``/``warnings`` if any), the timeline, the scope plot and the zoom.
    """
    from ..trace import Trace

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
    body = [
        '<section id="trace"><h2>Trace</h2>' + _kv_table(info) + "</section>",
        _metrics_section(_trace_metrics(trace), "Recomputed from the trace (true distance − wanted "
                                               "distance while distance control tracks)."),
        _events_section(events, _timeline_png(trace, events, float(t[-1]) if trace.rows else 0.0)),
        _plots_section(trace, name, events),
        _columns_section(trace),
    ]
    nav = [("trace", "Trace"), ("metrics", "Metrics"), ("events", "Errors & warnings"), ("plots", "Plots"),
           ("columns", "Columns")]
    page = out / REPORT_FILE
    page.write_text(_page(heading, f"generated {_now(now)} by distctrl from {src.name}", nav, body),
                    encoding="utf-8")
    return page
