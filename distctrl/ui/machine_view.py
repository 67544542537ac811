"""The machine view of the live page: the head over the surface profile, side view X–Z.

The surface (the scenario's ``[surface]`` at Y of the head) around the head, the nozzle (the Z drive's
true nozzle), the true distance (nozzle to surface, green) and the measured distance (the sensor's
measured distance the CNC reports in ``state_r.actual_distance``, orange, drawn beside it), the head's path of
the last seconds, and the NC block being executed.
"""
from __future__ import annotations

import numpy as np
from bokeh.layouts import column
from bokeh.models import ColumnDataSource, Div, Range1d
from bokeh.plotting import figure

from .hub import MachineHub, state_name
from .live import STYLE, span

HALF_WIDTH = 40.0      # mm of surface shown left and right of the head
PATH_SECONDS = 5.0
#: the smallest Z range shown around the head and the surface under it (mm)
ZOOM_MIN = 2.0


class MachineView:
    """One page's machine view."""

    def __init__(self, hub: MachineHub):
        self.hub = hub
        m = hub.machine
        self.z_axis = m.sensor_axis or (m.dc_axes[0] if m.dc_axes else ("Z" if "Z" in m.axis_names else None))
        self.surface = ColumnDataSource({"x": [], "z": [], "zb": []})
        self.head = ColumnDataSource({"x": [], "z": []})
        self.true_d = ColumnDataSource({"x0": [], "z0": [], "x1": [], "z1": []})
        self.meas_d = ColumnDataSource({"x0": [], "z0": [], "x1": [], "z1": []})
        self.path = ColumnDataSource({"x": [], "z": []})
        p = figure(height=380, sizing_mode="stretch_width", match_aspect=False, x_axis_label="X (mm)",
                   y_range=Range1d(0.0, 1.0),
                   y_axis_label="Z (mm)", tools="pan,wheel_zoom,reset,save", css_classes=["machine-plot"])
        p.toolbar.logo = None
        p.varea("x", y1="z", y2="zb", source=self.surface, fill_color="lightsteelblue", fill_alpha=0.5)
        p.line("x", "z", source=self.surface, color="steelblue", line_width=2, legend_label="surface")
        p.line("x", "z", source=self.path, color="silver", line_width=1, legend_label="head path")
        p.segment("x0", "z0", "x1", "z1", source=self.true_d, color="green", line_width=3,
                  legend_label="true distance")
        p.segment("x0", "z0", "x1", "z1", source=self.meas_d, color="darkorange", line_width=3,
                  line_dash="dashed", legend_label="measured distance")
        p.scatter("x", "z", source=self.head, marker="inverted_triangle", size=18, color="black",
                  legend_label="nozzle")
        p.legend.location = "top_left"
        self.plot = p
        self.info = Div(text=(f"t = {span('mv.t')} s · NC {span('mv.nc')}, line {span('mv.line')}: "
                              f"<code class='nc-block'>{span('mv.block')}</code> · {self.z_axis} {span('mv.state')} · "
                              f"true distance {span('mv.true')} · measured {span('mv.meas')}"),
                        width=1250, height=22, css_classes=["machine-info"], stylesheets=[STYLE])
        self.layout = column(self.info, p, sizing_mode="stretch_width")
        self._cols = {}
        hub_cols = hub.columns
        for key, name in (("x", "X.act"), ("z", f"{self.z_axis}.act"), ("sensor", f"{self.z_axis}.dc.sensor")):
            if name in hub_cols:
                self._cols[key] = hub.column(name)
        self._surface_at = None
        self._nozzle = hub.column(f"{self.z_axis}.nozzle") if f"{self.z_axis}.nozzle" in hub_cols else None

    def update(self, plot: bool = True) -> dict:
        """The read-out's live values (every frame the tab is shown) and, with ``plot``, the plot's
        sources (only those that changed: the surface when the head has moved)."""
        if self.z_axis is None:
            return {}
        hub, m = self.hub, self.hub.machine
        snap = hub.snapshot
        x = snap["x"]
        distance = snap["true_distance"]
        z = snap["true_surface"] + distance
        u = snap["units"].get(self.z_axis, {})
        # state_r.actual_distance: the measured distance d as the CNC reports it (0.1 µm; only with
        # distance control on the axis, P-AXIS-00328)
        measured = u["actual_distance"] * 1e-4 if u.get("dc_on") else None
        ok = measured is not None and np.isfinite(measured)
        if plot:
            y = m.drives["Y"].nozzle if "Y" in m.drives else 0.0
            if self._surface_at != (round(x, 3), round(y, 3)):
                self._surface_at = (round(x, 3), round(y, 3))
                xs = np.linspace(x - HALF_WIDTH, x + HALF_WIDTH, 161)
                zs = [m.surface.height(float(v), y) for v in xs]
                bottom = min(zs) - 2.0
                self.surface.data = {"x": xs, "z": zs, "zb": [bottom] * len(zs)}
            self.head.data = {"x": [x], "z": [z]}
            self.true_d.data = {"x0": [x], "z0": [z], "x1": [x], "z1": [z - distance]}
            dx = HALF_WIDTH / 40
            self.meas_d.data = ({"x0": [x + dx], "z0": [z], "x1": [x + dx], "z1": [z - measured]} if ok else
                                {"x0": [], "z0": [], "x1": [], "z1": []})
            _, rows = hub.rows_since(max(0, hub.rows - int(PATH_SECONDS / hub.T)), 20)
            if len(rows) and "x" in self._cols:
                zc = self._nozzle if self._nozzle is not None else self._cols.get("z")
                self.path.data = {"x": rows[:, self._cols["x"]], "z": rows[:, zc]}
            self._range(z, snap["true_surface"])
        line = snap["line"]
        block = hub.program_lines.get(line, "") if line is not None else ""
        return {"mv.t": f"{snap['t']:.3f}", "mv.nc": snap["nc_state"], "mv.line": str(line if line is not None else "-"),
                "mv.block": block.strip(), "mv.state": state_name(u.get("state", 0)),
                "mv.true": f"{distance:.4f} mm", "mv.meas": f"{measured:.4f} mm" if ok else "-"}

    def _range(self, z: float, surface: float) -> None:
        """Z from a little under the surface to a little over the head, so that a distance of 1 mm is
        readable (holes and kerfs run off the bottom); moved only when the head leaves the middle."""
        lo, hi = min(surface, z), max(surface, z)
        margin = max(0.5 * ZOOM_MIN, 0.5 * (hi - lo))
        width = hi - lo + 2 * margin
        r = self.plot.y_range
        start, end = r.start, r.end
        inside = start is not None and end is not None and start + 0.1 * width <= lo and hi <= end - 0.1 * width
        if not inside or (end - start) > 2.0 * width:
            r.start, r.end = lo - margin, hi + margin
