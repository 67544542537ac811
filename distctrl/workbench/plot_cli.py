"""``distctrl plot TRACE.csv``: a scope-style plot of a saved trace, with state bands and error markers.

The drawing itself is :func:`distctrl.trace.plot.plot_trace` (stacked panels sharing the time axis,
y labels with the units of the sidecar, legends, ``*.dc.state`` bands); this module adds what a
command line and the HTML report need around it: a time window (:func:`slice_trace`), signal names
checked against the columns with the closest column named on a typo (:func:`resolve_signals`),
error/warning markers read from the sidecar meta or a ``distctrl run --json`` file
(:func:`load_events`, :func:`add_event_markers`), and the distance error recomputed from a trace
(:func:`distance_error`). matplotlib is imported only when drawing. See docs/workbench-report.md.
"""
from __future__ import annotations

import difflib
import io
import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable

import click
import numpy as np

from ..cli.common import Finite
from ..errors import CATALOGUE, DistCtrlError

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..trace import Trace

__all__ = ["plot", "plot_command", "plot_trace_file", "slice_trace", "resolve_signals", "load_events",
           "events_from_meta", "add_event_markers", "distance_error", "figure_bytes", "closest_column",
           "PlotError"]

#: markers: colour and line style per severity
_MARK_STYLE = {"error": ("tab:red", "-"), "warning": ("darkorange", "--")}
_SAVE_DPI = 110


class PlotError(DistCtrlError):
    """A plot request that cannot be met (missing file, unknown signal, empty window)."""


# ------------------------------------------------------------------------------------------------------
# helpers (also used by distctrl.workbench.report)
# ------------------------------------------------------------------------------------------------------
def closest_column(name: str, columns: Iterable[str]) -> str | None:
    """The column most like ``name`` (difflib, case-insensitive), or None when nothing is close."""
    cols = list(columns)
    lower = {c.lower(): c for c in cols}
    near = difflib.get_close_matches(name.lower(), list(lower), n=1, cutoff=0.5)
    return lower[near[0]] if near else None


def resolve_signals(trace: "Trace", names: Iterable[str], source: str = "the trace") -> list[str]:
    """Check signal names against the trace's columns; :class:`PlotError` names the closest column."""
    out: list[str] = []
    for raw in names:
        name = raw.strip()
        if not name:
            continue
        if name not in trace:
            near = closest_column(name, trace.columns)
            hint = f"; closest column: {near}" if near else f"; columns: {', '.join(trace.columns)}"
            raise PlotError(f"unknown signal {name!r} in {source}{hint}")
        if name not in out:
            out.append(name)
    if not out:
        raise PlotError("--signals names no signal")
    return out


def slice_trace(trace: "Trace", t0: float | None = None, t1: float | None = None) -> "Trace":
    """The rows with ``t0 <= t <= t1`` as a new Trace (same columns, units, meta)."""
    from ..trace import Trace

    if t0 is None and t1 is None:
        return trace
    t = trace.t
    keep = np.ones(t.shape, dtype=bool)
    if t0 is not None:
        keep &= t >= t0
    if t1 is not None:
        keep &= t <= t1
    return Trace(trace.columns, trace.data[keep], units=trace.units, meta=trace.meta)


def _event_list(items: Any, severity: str, source: str) -> list[dict]:
    if items is None:
        return []
    if not isinstance(items, list):
        raise PlotError(f"{source}: {severity}s must be a list of {{id, t, line, message}} objects")
    out = []
    for n, item in enumerate(items):
        if not isinstance(item, dict) or "t" not in item or "id" not in item:
            raise PlotError(f"{source}: {severity}s[{n}] needs at least 'id' and 't' ({item!r})")
        try:
            t = float(item["t"])
        except (TypeError, ValueError):
            raise PlotError(f"{source}: {severity}s[{n}].t is not a number ({item['t']!r})") from None
        sev = item.get("severity") or severity
        out.append({"id": item["id"], "t": t, "line": item.get("line"),
                    "message": str(item.get("message", "")), "severity": sev})
    return out


def events_from_meta(doc: Any, source: str = "<meta>") -> list[dict]:
    """Errors and warnings (each with ``severity``) from a run's JSON object or a trace's meta.

    Accepts ``{"errors": [...], "warnings": [...]}`` (``distctrl run --json``, or the same keys in a
    trace sidecar's ``meta``) or a bare list of ``{id, t, ...}`` (taken as errors unless an item
    says its ``severity``). Sorted by time.
    """
    if doc is None:
        return []
    if isinstance(doc, list):
        events = _event_list(doc, "error", source)
    elif isinstance(doc, dict):
        events = _event_list(doc.get("errors"), "error", source) + _event_list(doc.get("warnings"), "warning",
                                                                               source)
    else:
        raise PlotError(f"{source}: expected a JSON object with 'errors'/'warnings' or a list")
    events.sort(key=lambda e: e["t"])
    return events


def load_events(trace: "Trace", errors_path: str | os.PathLike | None = None) -> list[dict]:
    """Events from ``errors_path`` (a ``distctrl run --json`` file) if given, else from the trace meta."""
    if errors_path is not None:
        p = Path(errors_path)
        try:
            doc = json.loads(p.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise PlotError(f"{p}: no such file (--errors wants the JSON of 'distctrl run --json')") from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise PlotError(f"{p}: cannot read the errors JSON: {exc}") from None
        return events_from_meta(doc, str(p))
    return events_from_meta({k: trace.meta.get(k) for k in ("errors", "warnings")}, "trace meta")


def severity_of(event: dict) -> str:
    sev = event.get("severity")
    if sev:
        return str(sev)
    try:
        return CATALOGUE[int(event["id"])][0]
    except (KeyError, TypeError, ValueError):
        return "error"


def add_event_markers(fig: "Figure", events: list[dict], t0: float | None = None,
                      t1: float | None = None) -> int:
    """Vertical lines at each event's time on every panel of ``fig`` (red: error, orange dashed:
    warning), its ID written at the top of the first panel. Returns how many were drawn."""
    axes = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    if not axes or not events:
        return 0
    n = 0
    for ev in events:
        t = ev["t"]
        if (t0 is not None and t < t0) or (t1 is not None and t > t1):
            continue
        color, style = _MARK_STYLE.get(severity_of(ev), _MARK_STYLE["error"])
        for ax in axes:
            ax.axvline(t, color=color, linestyle=style, linewidth=1.3, alpha=0.9, zorder=5)
        axes[0].text(t, 0.97, f" {ev['id']}", transform=axes[0].get_xaxis_transform(), color=color,
                     fontsize="small", fontweight="bold", ha="left", va="top", zorder=6,
                     bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.7, "pad": 1.0})
        n += 1
    return n


def distance_error(trace: "Trace") -> tuple[np.ndarray, str | None]:
    """The distance error per row (NaN where distance control does not track) and its axis.

    As the runner's metrics (docs/run.md): ``true.distance - <A>.dc.set_dist`` in ACTIVE_CONST_DIST
    (state 4), ``true.distance - (<A>.prog - <A>.dc.set_pos)`` in ACTIVE (state 1), for the first
    axis with a ``<A>.dc.state`` column. 3D traces (``dc3d.state``): ``true.distance_orth -
    dc3d.set_dist_orth`` in CONST_DIST; the SURFACE mode's wanted height is not in the trace (NaN).
    """
    n = trace.rows
    err = np.full(n, np.nan)
    if "dc3d.state" in trace and "true.distance_orth" in trace and "dc3d.set_dist_orth" in trace:
        st = trace["dc3d.state"]
        m = st == 4
        err[m] = trace["true.distance_orth"][m] - trace["dc3d.set_dist_orth"][m]
        return err, "3D"
    axes = [c[:-len(".dc.state")] for c in trace.columns if c.endswith(".dc.state")]
    if not axes or "true.distance" not in trace:
        return err, None
    a = axes[0]
    st = trace[f"{a}.dc.state"]
    dist = trace["true.distance"]
    if f"{a}.dc.set_dist" in trace:
        m = st == 4
        err[m] = dist[m] - trace[f"{a}.dc.set_dist"][m]
    if f"{a}.prog" in trace and f"{a}.dc.set_pos" in trace:
        m = st == 1
        err[m] = dist[m] - (trace[f"{a}.prog"][m] - trace[f"{a}.dc.set_pos"][m])
    return err, a


def figure_bytes(fig: "Figure", fmt: str = "png", dpi: int = 100) -> bytes:
    """The figure rendered to bytes (``png`` or ``svg``)."""
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, dpi=dpi)
    return buf.getvalue()


#: what ``distctrl plot -o`` writes (matplotlib formats by suffix; .jpg is JPEG)
OUTPUT_FORMATS = ("png", "svg", "pdf", "jpeg")


def plot_trace_file(trace_csv: str | os.PathLike, out: str | os.PathLike | None = None,
                    signals: list[str] | None = None, t0: float | None = None, t1: float | None = None,
                    errors_path: str | os.PathLike | None = None, title: str | None = None) -> Path:
    """Load a trace (a CSV with its sidecar, or the ``.parquet`` file ``distctrl run`` writes), draw it
    and save the figure; returns the output path.

    Default ``out``: the trace's path with the suffix ``.png``. Raises :class:`PlotError`.
    """
    from ..trace import load_trace
    from ..trace.plot import plot_trace

    src = Path(trace_csv)
    if not src.is_file():
        raise PlotError(f"{src}: no such trace file" if not src.exists() else f"{src}: not a file")
    try:
        trace = load_trace(src)               # CSV with its sidecar, or Parquet
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise PlotError(f"{src}: cannot read the trace: {exc}") from None
    sigs = resolve_signals(trace, signals, str(src)) if signals is not None else None
    if t0 is not None and t1 is not None and t1 <= t0:
        raise PlotError(f"--to ({t1:g}) must be after --from ({t0:g})")
    events = load_events(trace, errors_path)
    part = slice_trace(trace, t0, t1)
    if part.rows == 0:
        span = f"{trace.t[0]:g} .. {trace.t[-1]:g} s" if trace.rows else "no rows"
        raise PlotError(f"{src}: no rows between --from {t0} and --to {t1} (the trace covers {span})")
    out_path = Path(out) if out is not None else src.with_suffix(".png")
    fmt = out_path.suffix.lstrip(".").lower()
    fmt = "jpeg" if fmt == "jpg" else fmt
    if fmt not in OUTPUT_FORMATS:
        raise PlotError(f"{out_path}: the output must end in .png, .svg, .pdf, .jpg or .jpeg")
    heading = title
    if heading is None:
        heading = part.meta.get("title") or part.meta.get("program") or part.meta.get("scenario") or src.name
    fig = plot_trace(part, signals=sigs, title=str(heading))
    add_event_markers(fig, events, float(part.t[0]), float(part.t[-1]))
    out_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_path, dpi=_SAVE_DPI, format=fmt)
    return out_path


# ------------------------------------------------------------------------------------------------------
# the command
# ------------------------------------------------------------------------------------------------------
def _split_signals(value: str | None) -> list[str] | None:
    if value is None:
        return None
    return [s.strip() for s in value.split(",") if s.strip()]


@click.command("plot")
@click.argument("trace_csv", metavar="TRACE", type=click.Path(dir_okay=False))
@click.option("--signals", help="Comma-separated columns to plot (one panel per unit); default: the "
              "standard panels (positions, distance-control signals, distance).")
@click.option("--from", "t_from", type=Finite(min=0.0), default=None, help="Start of the time window [s].")
@click.option("--to", "t_to", type=Finite(min=0.0), default=None, help="End of the time window [s].")
@click.option("-o", "--output", "out", type=click.Path(dir_okay=False),
              help="Output file (.png, .svg, .pdf, .jpg); default: TRACE with the suffix .png.")
@click.option("--errors", "errors_path", type=click.Path(dir_okay=False),
              help="JSON of 'distctrl run --json' whose errors/warnings are marked (default: the "
              "trace sidecar's meta, if it lists them).")
@click.option("--title", default=None, help="Figure title (default: the trace's program/scenario).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object saying what was written (trace, output, format, bytes, signals, window).")
def plot(trace_csv: str, signals: str | None, t_from: float | None, t_to: float | None, out: str | None,
         errors_path: str | None, title: str | None, as_json: bool) -> None:
    """Plot a saved trace TRACE (.csv with its sidecar, or .parquet, as `distctrl run --trace` writes
    them) scope-style: signals over time, state bands, error markers.

    Exit code 0 when the plot was written, 1 for a missing file, an unknown signal (the message
    names the closest column), an empty time window, an unsupported output format or an output
    that cannot be written (the message names it and why).
    """
    from ..cli.common import emit_json, fail, output_error_text

    names = _split_signals(signals)
    try:
        path = plot_trace_file(trace_csv, out, names, t_from, t_to, errors_path, title)
    except DistCtrlError as exc:
        fail(str(exc))
    except OSError as exc:
        fail(output_error_text(exc, out if out is not None else str(Path(trace_csv).with_suffix(".png")), "plot"))
    if as_json:
        fmt = path.suffix.lstrip(".").lower()
        emit_json({"command": "plot", "trace": str(trace_csv), "output": str(path),
                   "format": "jpeg" if fmt == "jpg" else fmt, "bytes": path.stat().st_size,
                   "signals": names, "from_s": t_from, "to_s": t_to, "title": title})
        return
    click.echo(f"wrote {path}")


plot_command = plot
