"""The scope of the live page: any trace signal or CNC object of any axis, live, like TwinCAT Scope.

* Signals: the columns of ``distctrl run --trace`` (every cycle) and the CNC objects of every axis
  (``<axis>.obj.<name>``, sampled every 10 ms). One y axis per unit.
* Display: every ``DECIMATE``-th cycle (10 ms at 1 ms) streamed with rollover (``ColumnDataSource.stream``)
  over the last ``window`` seconds; the ring buffer of the last 60 s (every cycle) stays on the server.
* Pause loads the whole ring buffer into the page (the buffer keeps filling; Run goes live again), zoom and pan (Bokeh's tools), cursors (crosshair
  and hover), a trigger (rising or falling edge through a level, or any change of a state signal: the
  display stops half a window after it), markers for errors, warnings and state changes, and
  "Export CSV": the buffer at every cycle as a trace CSV with its .meta.json (``distctrl plot`` reads it).
"""
from __future__ import annotations

import html
from pathlib import Path

import numpy as np
from bokeh.layouts import column, row
from bokeh.models import (
    Button,
    BasicTickFormatter,
    ColumnDataSource,
    CrosshairTool,
    DataRange1d,
    Div,
    FixedTicker,
    HoverTool,
    LinearAxis,
    MultiChoice,
    NumericInput,
    Select,
    Spinner,
    Toggle,
)
from bokeh.palettes import Category10_10
from bokeh.plotting import figure

from ..sim.signals import SCOPE_DEFAULT
from ..trace.recorder import HLI_STATE_NAMES
from .hub import MachineHub, state_name

#: rows of the ring shown: every 10th cycle (100 samples/s at 1 ms)
DECIMATE = 10
TRIGGERS = ("off", "rising edge", "falling edge", "state change")
EVENT_COLOURS = {"error": "red", "warning": "darkorange", "state": "grey", "trigger": "purple"}


def default_signals(hub: MachineHub) -> list[str]:
    m = hub.machine
    ax = m.dc_axes[0] if m.dc_axes else m.axis_names[-1]
    wanted = [s.format(ax=ax) for s in SCOPE_DEFAULT]
    return [s for s in wanted if s in hub.columns] or [hub.columns[2]]


class Scope:
    """One page's scope (its own selection, pause and trigger; the data are the hub's)."""

    def __init__(self, hub: MachineHub, export_dir: Path):
        self.hub, self.export_dir = hub, export_dir
        self.step = DECIMATE
        options = [c for c in hub.columns if c not in ("t", "line")] + list(hub.object_signals)
        self.choice = MultiChoice(title="Signals (trace columns and CNC objects)", options=options,
                                  value=default_signals(hub), width=520, css_classes=["scope-signals"])
        self.window = Spinner(title="Window (s)", low=0.5, high=hub.capacity * hub.T, step=0.5, value=10.0,
                              width=100)
        self.pause = Toggle(label="Pause", button_type="default", width=90, css_classes=["scope-pause"])
        self.trig_mode = Select(title="Trigger", options=list(TRIGGERS), value="off", width=130,
                                css_classes=["scope-trigger"])
        self.trig_signal = Select(title="on signal", options=options, value=self.choice.value[0], width=200)
        self.trig_level = NumericInput(title="level", value=0.0, mode="float", width=90)
        self.export = Button(label="Export CSV", width=110, css_classes=["scope-export"])
        self.info = Div(text="", width=1200, height=22, css_classes=["scope-info"])
        self.markers = ColumnDataSource({"t": [], "color": [], "label": []})
        self._state_cols = {c: hub.column(c) for c in hub.columns if c.endswith(".dc.state")}
        self.plot = self._figure()
        self.layout = column(row(self.choice, self.window, self.pause, self.export),
                             row(self.trig_mode, self.trig_signal, self.trig_level), self.plot, self.info,
                             sizing_mode="stretch_width")
        self.choice.on_change("value", lambda a, o, n: self._rebuild())
        self.window.on_change("value", lambda a, o, n: self._set_window())
        self.pause.on_change("active", lambda a, o, n: self._on_pause(n))
        self.trig_mode.on_change("value", lambda a, o, n: self._arm())
        self.export.on_click(self._export)
        self._events_seen = 0
        self._trig_armed = False
        self._trig_prev = None
        self._trig_stop_at = None
        self._state_prev = {}
        self._pending: list[np.ndarray] = []
        self._stale = False
        self._fill()

    # ------------------------------------------------------------------ the figure
    def _figure(self):
        hub = self.hub
        signals = list(self.choice.value)
        fast = [s for s in signals if s not in hub.object_signals]
        slow = [s for s in signals if s in hub.object_signals]
        self.fast_cols = {f"c{i}": hub.column(s) for i, s in enumerate(fast)}
        self.slow_cols = {f"o{i}": hub.object_column(s) for i, s in enumerate(slow)}
        self.source = ColumnDataSource({"t": [], **{k: [] for k in self.fast_cols}})
        self.obj_source = ColumnDataSource({"t": [], **{k: [] for k in self.slow_cols}})
        self.x_range = DataRange1d(follow="end", follow_interval=float(self.window.value), range_padding=0)
        p = figure(height=430, sizing_mode="stretch_width", x_range=self.x_range, x_axis_label="t (s)",
                   tools="xpan,xwheel_zoom,box_zoom,reset,save", output_backend="canvas",
                   css_classes=["scope-plot"])
        p.toolbar.logo = None
        units: list[str] = []
        for s in signals:
            u = hub.signal_unit(s) or "-"
            if u not in units:
                units.append(u)
        p.yaxis.axis_label = units[0] if units else ""
        ranges = {}
        for i, u in enumerate(units):
            if i == 0:
                ranges[u] = "default"
                continue
            key = f"y{i}"
            p.extra_y_ranges[key] = DataRange1d()
            p.add_layout(LinearAxis(y_range_name=key, axis_label=u), "right" if i % 2 else "left")
            ranges[u] = key
        renderers = []
        for i, s in enumerate(signals):
            obj = s in hub.object_signals
            col = f"o{slow.index(s)}" if obj else f"c{fast.index(s)}"
            u = hub.signal_unit(s) or "-"
            kw = {} if ranges[u] == "default" else {"y_range_name": ranges[u]}
            r = p.line("t", col, source=self.obj_source if obj else self.source, legend_label=s,
                       color=Category10_10[i % 10], line_width=1.5, **kw)
            rng = p.y_range if ranges[u] == "default" else p.extra_y_ranges[ranges[u]]
            if isinstance(rng, DataRange1d):
                rng.renderers = list(rng.renderers) + [r]
            renderers.append(r)
            p.add_tools(HoverTool(renderers=[r], tooltips=[("t", "@t{0.000} s"), (s, f"@{col}{{0.0000}} {u}")],
                                  mode="vline"))
        p.vspan(x="t", source=self.markers, line_color="color", line_width=1, line_dash="dashed")
        p.add_tools(CrosshairTool())
        if renderers:
            p.legend.location = "top_left"
            p.legend.click_policy = "hide"
        for axis in p.yaxis:                   # 0.002, not 2.000e-3
            axis.formatter = BasicTickFormatter(use_scientific=False)
            names = [s for s in signals if (hub.signal_unit(s) or "-") == axis.axis_label]
            if names and all(s.endswith(".state") and s in self._state_cols for s in names):
                # an axis of HLI states only: its ticks are the states, by name
                axis.ticker = FixedTicker(ticks=sorted(HLI_STATE_NAMES))
                axis.major_label_overrides = {k: v for k, v in HLI_STATE_NAMES.items()}
        self.y_units = units
        return p

    def _rebuild(self) -> None:
        if not self.choice.value:
            return
        self.trig_signal.value = self.trig_signal.value if self.trig_signal.value else self.choice.value[0]
        self.plot = self._figure()
        self.layout.children[2] = self.plot
        self._fill()

    def _set_window(self) -> None:
        self.x_range.follow_interval = float(self.window.value)
        if not self.pause.active:
            self._fill()

    @property
    def rollover(self) -> int:
        """Rows the page keeps while running: the window (the browser redraws them every frame); the
        whole ring buffer is loaded when the scope is paused."""
        return max(2, int(float(self.window.value) / (self.hub.T * self.step)) + 1)

    def _fill(self, whole: bool = False) -> None:
        """Fill the sources from the ring buffer: the window (start, resume, a new selection) or,
        paused, the whole buffer (60 s) to zoom and pan in."""
        hub = self.hub
        back = hub.capacity if whole else self.rollover * self.step
        self.cursor, rows = hub.rows_since(max(0, hub.rows - back), self.step)
        self._pending = []
        self.source.data = self._fast_data(rows)
        oback = hub.obj_capacity if whole else int(float(self.window.value) / (hub.T * hub.snapshot_every)) + 1
        self.obj_cursor, orows = hub.object_rows_since(max(0, hub.obj_rows - oback))
        self.obj_source.data = self._slow_data(orows)

    def _fast_data(self, rows: np.ndarray) -> dict:
        return {"t": rows[:, 0], **{k: rows[:, j] for k, j in self.fast_cols.items()}}

    def _slow_data(self, rows: np.ndarray) -> dict:
        return {"t": rows[:, 0], **{k: rows[:, j] for k, j in self.slow_cols.items()}}

    # ------------------------------------------------------------------ controls
    def _on_pause(self, paused: bool) -> None:
        self.pause.label = "Run" if paused else "Pause"
        self.pause.button_type = "warning" if paused else "default"
        if not paused:
            self._trig_stop_at = None
        self._fill(whole=paused)

    def _arm(self) -> None:
        self._trig_armed = self.trig_mode.value != "off"
        self._trig_prev = None
        self._trig_stop_at = None
        if self._trig_armed:
            self.info.text = f"trigger armed: {self.trig_mode.value} of {self.trig_signal.value}"

    def _export(self) -> None:
        try:
            path = self.hub.export_csv(self.export_dir, list(self.choice.value))
        except OSError as exc:
            self.info.text = f"export failed: {exc.strerror or exc}"
            return
        self.info.text = (f'exported <a href="/export/{path.name}" download>{path.name}</a> '
                          f'(<a href="/export/{path.name}.meta.json" download>.meta.json</a>) '
                          f"to {html.escape(str(path.parent.resolve()))}: <code>distctrl plot {html.escape(str(path))}</code> "
                          "draws it")

    # ------------------------------------------------------------------ every frame
    def keep(self, visible: bool = True) -> None:
        """Every frame, on every tab and also when the page is behind: the new rows go through the
        state markers and the trigger; while the scope is shown they wait for :meth:`update` (at most
        a window of them), while it is hidden nothing is kept (it is filled anew when shown)."""
        hub = self.hub
        self._markers()
        cursor, rows = hub.rows_since(self.cursor, self.step)
        self.cursor = cursor
        if len(rows):
            self._states(rows)
            if self._trig_armed:
                self._trigger(rows)
            if visible and not self.pause.active and not self._stale:
                self._pending.append(rows)
                while sum(len(r) for r in self._pending) - len(self._pending[0]) >= self.rollover:
                    self._pending.pop(0)
            if self._trig_stop_at is not None and rows[-1, 0] >= self._trig_stop_at:
                self._trig_stop_at = None
                self.pause.active = True
        if not visible:
            self._stale = True
            self._pending = []

    def update(self, visible: bool = True) -> list:
        """A frame the page will draw: the rows kept since the last one, as ``[source id, columns,
        rollover]`` for each of the plot's sources (trace rows, CNC-object samples) that has new rows.
        They go with the frame's live values, one message (:meth:`distctrl.ui.live.Live.push`), and the
        page's script streams them into the plot's sources in the browser: a Bokeh ``stream`` of its
        own cost the page's thread about 1 ms and a second message per frame (issue 39)."""
        if not visible or self.pause.active:
            return []
        hub = self.hub
        if self._stale:                          # shown again: the window anew from the ring buffer
            self._stale = False
            self._pending = []
            self._fill()
            return []
        out = []
        if self._pending:
            rows = np.concatenate(self._pending)[-self.rollover:]
            self._pending = []
            out.append([self.source.id, _columns(self._fast_data(rows)), self.rollover])
        ocursor, orows = hub.object_rows_since(self.obj_cursor)
        self.obj_cursor = ocursor
        if len(orows) and self.slow_cols:
            out.append([self.obj_source.id, _columns(self._slow_data(orows)),
                        int(float(self.window.value) / (hub.T * hub.snapshot_every)) + 1])
        return out

    def _markers(self) -> None:
        events = self.hub.events
        if len(events) != self._events_seen:
            new = events[self._events_seen:]
            self._events_seen = len(events)
            self._add_markers([(e["t"], EVENT_COLOURS.get(e["severity"], "red"), f"{e['severity']} {e['id']}")
                               for e in new])

    def _add_markers(self, items) -> None:
        if items:
            t, c, lab = zip(*items)
            self.markers.stream({"t": list(t), "color": list(c), "label": list(lab)}, rollover=500)

    def _states(self, rows: np.ndarray) -> None:
        items = []
        for name, j in self._state_cols.items():
            col = rows[:, j]
            prev = self._state_prev.get(name, col[0])
            changes = np.flatnonzero(np.diff(np.concatenate([[prev], col])) != 0)
            for i in changes:
                items.append((float(rows[i, 0]), EVENT_COLOURS["state"],
                              f"{name.split('.')[0]} {state_name(int(col[i]))}"))
            self._state_prev[name] = col[-1]
        self._add_markers(items)

    def _trigger(self, rows: np.ndarray) -> None:
        hub, name = self.hub, self.trig_signal.value
        if name in hub.object_signals or name not in hub.columns:
            self.info.text = f"trigger: {name} is not a per-cycle trace signal"
            self._trig_armed = False
            return
        v = rows[:, hub.column(name)]
        prev = np.concatenate([[v[0] if self._trig_prev is None else self._trig_prev], v[:-1]])
        level, mode = float(self.trig_level.value or 0.0), self.trig_mode.value
        if mode == "rising edge":
            hit = np.flatnonzero((prev < level) & (v >= level))
        elif mode == "falling edge":
            hit = np.flatnonzero((prev > level) & (v <= level))
        else:
            hit = np.flatnonzero(prev != v)
        self._trig_prev = v[-1]
        if hit.size:
            t = float(rows[hit[0], 0])
            self._trig_armed = False
            self._trig_stop_at = t + 0.5 * float(self.window.value)
            self._add_markers([(t, EVENT_COLOURS["trigger"], "trigger")])
            self.info.text = (f"triggered at t = {t:.3f} s ({mode} of {name}"
                              + (f" through {level:g} {hub.signal_unit(name)}" if mode != "state change" else "")
                              + "); the display stops half a window later")


def _columns(data: dict) -> dict:
    """Columns as lists (a frame's few rows), NaN and inf as None: JSON has no NaN; the page's script
    turns None back into NaN (a gap in the line)."""
    return {k: np.where(np.isfinite(v), v, None).tolist() if not np.isfinite(v).all() else v.tolist()
            for k, v in data.items()}
