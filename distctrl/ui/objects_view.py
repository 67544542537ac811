"""The object browser of the live page: the CNC objects of every axis (FCT-M3 §7.6 / §9.4, docs/objects.md)
and, with 3D distance control, channel 1's 3D objects (index group 0x121301, FCT-M3 §12.6, docs/objects-3d.md).

Name, index group and offset (task GEO, ADS port 551), type, unit, the raw value in the object's unit
and the value in mm / mm/s / mm/s², live (five times a second). The read/write objects (kp, i_tn, d_tv,
DIST_CTRL_PARAM[0]::v_max / a_max and their DISTCTRL:: aliases) can be written here with the range
check of an ADS write; the write is "pending" until the controller adopts it on the next
INACTIVE→active or FREEZE→active transition, then "adopted".
"""
from __future__ import annotations

from bokeh.layouts import column, row
from bokeh.models import (
    Button,
    ColumnDataSource,
    DataTable,
    Div,
    NumericInput,
    Select,
    TableColumn,
)

from ..objects.registry import SERVED_OBJECTS
from .hub import MachineHub, object_table
from .live import STYLE, TABLE_NAME, Live, span

COLUMNS = (("axis", "Axis", 60), ("group", "Group", 80), ("offset", "Offset", 80), ("name", "Name", 260),
           ("type", "Type", 70), ("unit", "Unit", 80), ("raw", "Raw value", 130), ("value", "Value", 140),
           ("access", "Access", 80), ("pending", "Write", 140))
#: the table's row height (Bokeh's default, px) and the most rows shown without scrolling
ROW_PX = 25
MAX_ROWS = 40
#: frames between two refreshes of the table (at 20 frames/s: 5 per second)
EVERY = 4


class ObjectBrowser:
    """One page's object browser."""

    def __init__(self, hub: MachineHub, live: Live | None = None):
        self.hub = hub
        self.live = live or Live()
        # the source holds the shown rows only (one axis: 31 rows to compare and patch, not all axes')
        self.source = ColumnDataSource({f: [] for f, _, _ in COLUMNS})
        self.table = DataTable(source=self.source, columns=[TableColumn(field=f, title=t, width=w)
                                                            for f, t, w in COLUMNS],
                               height=ROW_PX * 10, sizing_mode="stretch_width", index_position=None,
                               css_classes=["obj-table"], name=TABLE_NAME)
        writable = [s.name for s in SERVED_OBJECTS if s.writable]
        self.writable = {"axis": writable, "channel": [s.name for s in hub.channel_objects if s.writable]}
        axes = [f"{i} {c.axis_name}" for i, c in hub.contexts.items()]
        if hub.channel_objects:
            axes.append("0 channel 1")
        dc = [f"{i} {c.axis_name}" for i, c in hub.contexts.items() if c.axis_name in hub.machine.dc_axes]
        self.axis = Select(title="Axis", options=axes, value=(dc or axes)[0], width=90, css_classes=["obj-axis"])
        # the table shows one axis (the first with distance control) or all of them
        self.show = Select(title="Show", options=["all axes", *axes], value=(dc or axes)[0], width=130,
                           css_classes=["obj-show"])
        self.show.on_change("value", lambda a, o, v: self._filter())
        self._filter()
        self.name = Select(title="Read/write object", options=writable, value=writable[0], width=240,
                           css_classes=["obj-name"])
        self.value = NumericInput(title="Value (object unit)", mode="float", width=150, css_classes=["obj-value"])
        self.write = Button(label="Write", button_type="primary", width=90, css_classes=["obj-write"])
        self.write.on_click(self._write)
        self.axis.on_change("value", lambda a, o, v: self._names(v))
        self.message = Div(text=span("obj.msg"), width=1200, height=22, css_classes=["obj-message"],
                           stylesheets=[STYLE])
        self.status = Div(text=span("obj.head") + span("obj.state", "", "obj-state", "b"), width=1200, height=22,
                          css_classes=["obj-status"], stylesheets=[STYLE])
        self.layout = column(row(self.axis, self.name, self.value, self.write, self.show), self.message, self.status,
                             self.table, sizing_mode="stretch_width")
        self._frame = 0

    def visible_rows(self, data: dict | None = None) -> list[int]:
        """The rows of :func:`object_table` shown (by the axis filter)."""
        axes = (data if data is not None else object_table(self.hub))["axis"]
        if self.show.value == "all axes":
            return list(range(len(axes)))
        return [i for i, a in enumerate(axes) if a == self.show.value]

    def _shown(self, data: dict) -> dict:
        """The table's columns for the shown rows."""
        rows = self.visible_rows(data)
        return {f: [data[f][i] for i in rows] for f, _, _ in COLUMNS}

    def _filter(self) -> None:
        """Show the chosen axis's objects (a user's choice: the table is filled and laid out anew, once)."""
        shown = self._shown(object_table(self.hub))
        self.source.data = shown
        self.table.height = ROW_PX * (min(len(shown["axis"]), MAX_ROWS) + 1) + 4

    def _names(self, axis: str) -> None:
        names = self.writable["channel" if axis.startswith("0 ") else "axis"]
        self.name.options = names
        if self.name.value not in names:
            self.name.value = names[0]

    def _write(self, _event=None) -> None:
        axis_id = int(self.axis.value.split()[0])
        if self.value.value is None:
            self._say(False, "enter a value first")
            return
        ok, msg = self.hub.write_object(axis_id, self.name.value, float(self.value.value))
        self._say(ok, msg)
        self._frame = EVERY                   # show the pending state at once

    def _say(self, ok: bool, message: str) -> None:
        self.live.stage({"obj.msg": [message, "ok" if ok else "err"]})

    def update(self, visible: bool = True) -> dict:
        """Every frame: the table's changed cells (five times a second, only while the tab is shown);
        the live values of the status line under the form."""
        self._frame += 1
        if not visible or self._frame < EVERY:
            return {}
        self._frame = 0
        data = object_table(self.hub)
        old = self.source.data
        shown = self._shown(data)
        # only the cells that changed (a table redrawn whole five times a second costs the browser); the
        # page script redraws the grid after a patch (PAGE_JS: Bokeh 3.9's table does not on its own)
        patches = {}
        for key in ("raw", "value", "pending"):
            changed = [(i, v) for i, (v, w) in enumerate(zip(shown[key], old[key])) if v != w]
            if changed:
                patches[key] = changed
        if patches:
            self.source.patch(patches)
        axis_id = int(self.axis.value.split()[0])
        i = next((k for k, (a, n) in enumerate(zip(data["axis_id"], data["name"]))
                  if a == axis_id and n == self.name.value), None)
        if i is None:
            return {}
        return {"obj.head": f"{self.name.value} of axis {self.axis.value}: raw {data['raw'][i]} {data['unit'][i]}, ",
                "obj.state": data["pending"][i]}
