"""Plot a :class:`~distctrl.trace.recorder.Trace`: stacked subplots sharing the time axis.

The functions take any object with the few members of :class:`TraceLike` (a ``Trace`` has them), so
this module does not import the recorder: ``Trace.plot`` imports it, not the other way round.

matplotlib is imported lazily, and only its object-oriented API is used (a ``Figure`` on an Agg
canvas, no pyplot): nothing is displayed, no global backend or figure registry is touched, and it
works on machines without a display.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np

from ..base.states import HLI_STATE_NAMES

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_trace", "default_groups", "state_segments", "MAX_POINTS", "MAX_STATE_SEGMENTS"]

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

    @property
    def rows(self) -> int: ...

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
