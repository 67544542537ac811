"""One page (one Bokeh session) of the live page: a status line and four tabs (scope, object browser,
PLC panel, machine view), refreshed every frame from the shared :class:`~distctrl.ui.hub.MachineHub`."""
from __future__ import annotations

import html
from pathlib import Path

from bokeh.layouts import column
from bokeh.models import Div, TabPanel, Tabs

from .hub import MachineHub, state_name
from .machine_view import MachineView
from .objects_view import ObjectBrowser
from .plc_panel import PlcPanel
from .scope import Scope

TAB_SCOPE, TAB_OBJECTS, TAB_PLC, TAB_MACHINE = range(4)


def status_text(hub: MachineHub) -> str:
    snap = hub.snapshot
    m = hub.machine
    states = " · ".join(f"{n} <b class='state-{n}'>{state_name(snap['units'][n]['state'])}</b>" for n in m.dc_axes)
    last = hub.events[-1] if hub.events else None
    err = (f" · last {html.escape(last['severity'])} <b class='last-event'>{last['id']}</b>" if last else "")
    return (f"<b>{html.escape(hub.served.scenario.name)}</b> · t = <span class='machine-t'>{snap['t']:.3f}</span> s · "
            f"NC {snap['nc_state']} line {snap['line'] if snap['line'] is not None else '-'} · {states} · "
            f"override <span class='override'>{snap['override'] * 100:.0f}</span> %"
            + (" · <b>PLC STOP</b>" if snap["paused"] else "") + err)


def build_page(doc, hub: MachineHub, export_dir: Path, frame_ms: int) -> None:
    scope = Scope(hub, export_dir)
    objects = ObjectBrowser(hub)
    plc = PlcPanel(hub)
    machine = MachineView(hub)
    status = Div(text=status_text(hub), css_classes=["dc-status"], sizing_mode="stretch_width")
    tabs = Tabs(tabs=[TabPanel(child=scope.layout, title="Scope"),
                      TabPanel(child=objects.layout, title="Object browser"),
                      TabPanel(child=plc.layout, title="PLC panel"),
                      TabPanel(child=machine.layout, title="Machine view")],
                sizing_mode="stretch_width", css_classes=["dc-tabs"])

    def frame() -> None:
        text = status_text(hub)
        if status.text != text:
            status.text = text
        scope.update()
        active = tabs.active
        objects.update(active == TAB_OBJECTS)
        if active == TAB_PLC:
            plc.update()
        machine.update(active == TAB_MACHINE)

    plc.update()
    doc.add_root(column(status, tabs, sizing_mode="stretch_width"))
    doc.title = f"distctrl — {hub.served.scenario.name}"
    doc.add_periodic_callback(frame, frame_ms)
