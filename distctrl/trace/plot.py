"""Plot a :class:`~distctrl.trace.recorder.Trace`: stacked subplots sharing the time axis; and what a
plot of a saved trace needs around it (``distctrl plot``, the HTML report): a time window
(:func:`slice_trace`), signal names checked against the columns with the closest column named on a
typo (:func:`resolve_signals`), error/warning markers read from the sidecar meta or a
``distctrl run --json`` file (:func:`load_events`, :func:`add_event_markers`), the distance error
recomputed from a trace (:func:`distance_error`). :func:`~distctrl.trace.plot_file.plot_trace_file`
draws a trace file.

The functions take any object with the few members of :class:`TraceLike` (a ``Trace`` has them), so
this module does not import the recorder: ``Trace.plot`` imports it, not the other way round.

matplotlib is imported lazily, and only its object-oriented API is used (a ``Figure`` on an Agg
canvas, no pyplot): nothing is displayed, no global backend or figure registry is touched, and it
works on machines without a display.
"""
from __future__ import annotations

import difflib
import io
import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Protocol

import numpy as np

from ..base.states import HLI_STATE_NAMES
from ..errors import CATALOGUE, DistCtrlError

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_trace", "default_groups", "state_segments", "MAX_POINTS", "MAX_STATE_SEGMENTS", "PlotError",
           "slice_trace", "resolve_signals", "closest_column", "load_events", "events_from_meta",
           "add_event_markers", "distance_error", "figure_bytes", "OUTPUT_FORMATS"]

#: above this many rows a signal is drawn as a min/max envelope of about this many points
MAX_POINTS = 100_000
#: with more ``*.dc.state`` runs than this the states are shaded by value without marking each change
MAX_STATE_SEGMENTS = 400
#: with at most this many runs each is named above the top panel
MAX_STATE_LABELS = 40


class TraceLike(Protocol):
    """What the plot functions read of a trace (:class:`~distctrl.trace.recorder.Trace`)."""

    columns: list[str]
    meta: dict
    units: dict
    data: np.ndarray

    @property
    def rows(self) -> int: ...

    @property
    def t(self) -> np.ndarray: ...

    def unit(self, column: str) -> str: ...

    def __getitem__(self, column: str) -> np.ndarray: ...

    def __contains__(self, column: object) -> bool: ...


_POSITION_SUFFIXES = (".prog", ".cmd", ".act")
_DC_SUFFIXES = (".dc.offset", ".dc.filtered", ".dc.target_deviation")
_STATE_COLORS = {1: "tab:green", 2: "tab:blue", 3: "tab:orange", 4: "tab:olive", 5: "tab:red",
                 6: "tab:purple", 7: "tab:pink"}


def _dc_axes(columns: list[str]) -> list[str]:
    """Names of the distance-controlled axes: the prefixes of ``<axis>.dc.*`` columns, in column order."""
    axes: list[str] = []
    for c in columns:
        if ".dc." in c:
            ax = c.split(".dc.", 1)[0]
            if ax and ax not in axes:
                axes.append(ax)
    return axes


def default_groups(trace: TraceLike) -> list[tuple[str, list[str]]]:
    """The default panels: (title, columns) for positions, distance-control signals and distance."""
    cols = trace.columns
    have = set(cols)
    groups: list[tuple[str, list[str]]] = []
    for ax in _dc_axes(cols):
        pos = [ax + s for s in _POSITION_SUFFIXES if ax + s in have]
        if "true.surface" in have:
            pos.append("true.surface")
        if pos:
            groups.append((f"{ax} position", pos))
        dc = [ax + s for s in _DC_SUFFIXES if ax + s in have]
        if dc:
            groups.append((f"{ax} distance control", dc))
    dist = [c for c in cols if c.endswith("distance") and not c.endswith(".dc.target_deviation")]
    if dist:
        groups.append(("distance", dist))
    if not groups:  # not a distance-control trace: every signal, one panel per unit
        groups = _unit_groups(trace, [c for c in cols if c != "t"])
    return groups


def _unit_groups(trace: TraceLike, signals: list[str]) -> list[tuple[str, list[str]]]:
    by_unit: dict[str, list[str]] = {}
    for s in signals:
        by_unit.setdefault(trace.unit(s), []).append(s)
    return [("", sigs) for sigs in by_unit.values()]


def state_segments(state: np.ndarray) -> list[tuple[int, int, int]]:
    """Runs of equal state values as (start row, end row exclusive, state); NaN rows end a run."""
    s = np.asarray(state, dtype=np.float64)
    if s.size == 0:
        return []
    change = np.flatnonzero((s[1:] != s[:-1]) & ~(np.isnan(s[1:]) & np.isnan(s[:-1]))) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [s.size]))
    out = []
    for a, b in zip(starts.tolist(), ends.tolist()):
        v = s[a]
        if not np.isnan(v):
            out.append((a, b, int(v)))
    return out


def envelope(x: np.ndarray, y: np.ndarray, max_points: int) -> tuple[np.ndarray, np.ndarray]:
    """x, y thinned to about max_points points keeping each bucket's min and max (peaks stay visible)."""
    n = y.size
    if n <= max_points:
        return x, y
    bucket = -(-n // (max_points // 2))
    m = n // bucket
    yb = y[:m * bucket].reshape(m, bucket)
    xb = x[:m * bucket].reshape(m, bucket)
    with np.errstate(invalid="ignore"):
        imin = np.nanargmin(np.where(np.isnan(yb), np.inf, yb), axis=1)
        imax = np.nanargmax(np.where(np.isnan(yb), -np.inf, yb), axis=1)
    first = np.minimum(imin, imax)
    second = np.maximum(imin, imax)
    rows = np.arange(m)
    xs = np.column_stack((xb[rows, first], xb[rows, second])).ravel()
    ys = np.column_stack((yb[rows, first], yb[rows, second])).ravel()
    if m * bucket < n:
        xs = np.concatenate((xs, x[m * bucket:]))
        ys = np.concatenate((ys, y[m * bucket:]))
    return xs, ys


def _ylabel(trace: TraceLike, name: str, signals: list[str]) -> str:
    units: list[str] = []
    for s in signals:
        u = trace.unit(s)
        if u and u not in units:
            units.append(u)
    if not name:
        name = ", ".join(signals) if len(signals) <= 3 else f"{signals[0]}, ... ({len(signals)})"
    return f"{name} [{', '.join(units)}]" if units else name


#: signals that mean something else while distance control is INACTIVE (the filter runs on the axis's
#: surface position there, on the distance once active): not drawn in INACTIVE rows
_ACTIVE_ONLY = (".dc.filtered", ".dc.feedback")


def _active_only(trace: TraceLike, name: str) -> np.ndarray:
    """The column, NaN in the rows where its axis's distance control is INACTIVE (``_ACTIVE_ONLY``
    signals only; new-user audit R14: the 30 mm surface position of cycle 0 squashed the panel)."""
    y = trace[name]
    if name.endswith(_ACTIVE_ONLY):
        state_col = name.split(".dc.", 1)[0] + ".dc.state"
        if state_col in trace:
            y = np.where(np.asarray(trace[state_col]) == 0, np.nan, np.asarray(y, dtype=np.float64))
    return y


def _stack_labels(fig, ax, labels: list) -> None:
    """Lift a state name that would overlap an earlier one (two changes a few cycles apart) by one line
    until it is free (new-user audit R14: INACTIVE / ACTIVE_CONST_DIST were printed on top of each other)."""
    if len(labels) < 2:
        return
    renderer = fig.canvas.get_renderer()
    placed = []
    ax_h = max(ax.get_window_extent(renderer).height, 1.0)
    for text in labels:
        box = text.get_window_extent(renderer)
        step = 1.15 * box.height / ax_h
        for level in range(8):
            text.set_y(1.01 + level * step)
            box = text.get_window_extent(renderer)
            if not any(box.overlaps(b) for b in placed):
                break
        placed.append(box)


def plot_trace(trace: TraceLike, path: str | os.PathLike | None = None, signals: list[str] | None = None,
               title: str | None = None) -> "Figure":
    """Draw the trace as stacked subplots sharing the time axis and return the Figure.

    Default panels: positions of the distance-controlled axis (``*.prog``, ``*.cmd``, ``*.act``,
    ``true.surface``), its distance-control signals (``*.dc.offset``, ``*.dc.filtered``,
    ``*.dc.target_deviation``) and the distance (``true.distance``). With ``signals``, just those,
    one panel per unit. Changes of ``*.dc.state`` are shaded (every state but INACTIVE) and named.
    With ``path`` the figure is saved too; the format follows the suffix (.png, .svg, .pdf, ...).
    """
    # matplotlib loads only when a plot is drawn (import distctrl.trace stays light)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    if signals is not None:
        missing = [s for s in signals if s not in trace]
        if missing:
            raise KeyError(f"no such columns in the trace: {missing}")
        groups = _unit_groups(trace, list(signals))
    else:
        groups = default_groups(trace)
    if not groups:
        raise ValueError("nothing to plot: the trace has no signal columns")

    has_t = "t" in trace
    x = trace["t"] if has_t else np.arange(trace.rows, dtype=np.float64)
    xlabel = f"t [{trace.unit('t') or 's'}]" if has_t else "cycle"

    fig = Figure(figsize=(11.0, 0.8 + 2.6 * len(groups)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(groups), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (name, sigs) in zip(axes, groups):
        for s in sigs:
            xs, ys = envelope(x, _active_only(trace, s), MAX_POINTS)
            ax.plot(xs, ys, label=s, linewidth=1.0,
                    linestyle="--" if s.endswith((".prog", ".dc.target_deviation")) else "-")
        ax.set_ylabel(_ylabel(trace, name, sigs))
        ax.grid(True, alpha=0.4)
        ax.legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel(xlabel)

    state_cols = [f"{a}.dc.state" for a in _dc_axes(trace.columns) if f"{a}.dc.state" in trace]
    if state_cols and trace.rows:
        state = trace[state_cols[0]]
        segs = state_segments(state)
        seen: dict[int, str] = {}
        labels: list = []
        if len(segs) <= MAX_STATE_SEGMENTS:
            label_them = len(segs) <= MAX_STATE_LABELS
            for a, b, st in segs:
                x0 = x[a]
                x1 = x[b] if b < trace.rows else x[-1]
                if b > a and st != 0:
                    color = _STATE_COLORS.get(st, "tab:gray")
                    for ax in axes:
                        ax.axvspan(x0, x1, color=color, alpha=0.12, linewidth=0)
                    seen.setdefault(st, color)
                if a > 0:
                    for ax in axes:
                        ax.axvline(x0, color="0.35", linewidth=0.6, linestyle=":")
                if label_them:
                    labels.append(axes[0].text(x0, 1.01, HLI_STATE_NAMES.get(st, str(st)),
                                               transform=axes[0].get_xaxis_transform(), fontsize="x-small",
                                               ha="left", va="bottom"))
        else:  # a chattering state: shade by value, no per-change marks
            step = max(1, trace.rows // MAX_POINTS)
            xs, ss = x[::step], state[::step]
            for st in sorted({int(v) for _, _, v in segs} - {0}):
                color = _STATE_COLORS.get(st, "tab:gray")
                for ax in axes:
                    ax.fill_between(xs, 0, 1, where=ss == st, step="post", color=color, alpha=0.12,
                                    linewidth=0, transform=ax.get_xaxis_transform())
                seen.setdefault(st, color)
        _stack_labels(fig, axes[0], labels)
        if seen:
            handles = [Patch(color=c, alpha=0.3, label=f"{state_cols[0]} {HLI_STATE_NAMES.get(s, s)}")
                       for s, c in sorted(seen.items())]
            fig.legend(handles=handles, loc="outside lower center", ncols=min(4, len(handles)),
                       fontsize="small")

    heading = title if title is not None else trace.meta.get("title") or trace.meta.get("program")
    if heading:
        fig.suptitle(str(heading))
    if path is not None:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    return fig


# ------------------------------------------------------------------------------------------------------
# around the drawing: windows, signal names, event markers (distctrl plot, the HTML report)
# ------------------------------------------------------------------------------------------------------
#: markers: colour and line style per severity
_MARK_STYLE = {"error": ("tab:red", "-"), "warning": ("darkorange", "--")}
#: what ``distctrl plot -o`` writes (matplotlib formats by suffix; .jpg is JPEG)
OUTPUT_FORMATS = ("png", "svg", "pdf", "jpeg")


class PlotError(DistCtrlError):
    """A plot request that cannot be met (missing file, unknown signal, empty window)."""


def closest_column(name: str, columns: Iterable[str]) -> str | None:
    """The column most like ``name`` (difflib, case-insensitive), or None when nothing is close."""
    cols = list(columns)
    lower = {c.lower(): c for c in cols}
    near = difflib.get_close_matches(name.lower(), list(lower), n=1, cutoff=0.5)
    return lower[near[0]] if near else None


def resolve_signals(trace: TraceLike, names: Iterable[str], source: str = "the trace") -> list[str]:
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


def slice_trace(trace: TraceLike, t0: float | None = None, t1: float | None = None) -> TraceLike:
    """The rows with ``t0 <= t <= t1`` as a new trace of the same type (same columns, units, meta)."""
    if t0 is None and t1 is None:
        return trace
    t = trace.t
    keep = np.ones(t.shape, dtype=bool)
    if t0 is not None:
        keep &= t >= t0
    if t1 is not None:
        keep &= t <= t1
    return type(trace)(trace.columns, trace.data[keep], units=trace.units, meta=trace.meta)


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


def load_events(trace: TraceLike, errors_path: str | os.PathLike | None = None) -> list[dict]:
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


def distance_error(trace: TraceLike) -> tuple[np.ndarray, str | None]:
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
